"""The Monte Carlo's door (issue 33): the issue's bad specs are one error naming the file and key; the tasks of a
huge run are made one at a time; ``--resume`` redoes a chunk file that is not whole; a stage folder left by a
killed run is removed by the next run staging into the same target."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest

from firmware_model.flights.montecarlo.run import MAX_FLIGHTS, make_tasks, run_montecarlo
from firmware_model.flights.montecarlo.spec import draw, flight_rng, load_spec, read_spec_file
from firmware_model.runtime.errors import UserError
from firmware_model.runtime.output import STALE_STAGE_S, remove_stale_stages, staged_folder

BASE = 'scenario = "sub-k400-300m"\nk = 5\nmethods = ["rec_quarter"]\ntunings = ["default"]\nchunk_flights = 2\n' \
       'descent_s = 2.0\n'
ROCKET = 'k = 5\n[rocket]\nmotor = "K400C"\ndiameter_m = 0.1\n'


@pytest.mark.parametrize("text, message", [
    (BASE + '[launch]\nsite_altitude_m = "high"\n', "launch: site_altitude_m: 'high' is not a number; allowed: "),
    (BASE + '[launch]\ndrogue_delay_s = "late"\n', "launch: drogue_delay_s: 'late' is not a number"),
    ('launch = "x"\n' + BASE, "launch: 'x' is not a table"),
    ("rocket = 5\n", "rocket: 5 is not a table"),
    (ROCKET + "dry_mass_kg = 5\nmotor_scale = 5\n", "rocket: motor_scale: 5 is not a pair"),
    (ROCKET + 'dry_mass_kg = 5\nmotor_scale = "abc"\n', "rocket: motor_scale: 'abc' is not a pair"),
    (ROCKET + 'dry_mass_kg = "heavy"\n', "rocket: dry_mass_kg: 'heavy' is not a number"),
    ('[rocket]\nmotor = "Z9"\ndiameter_m = 0.1\ndry_mass_kg = 5\n', "rocket: motor: 'Z9' is not a shipped motor"),
    (BASE + "[dispersions]\nspike_rate = 1e12\n", "dispersions: spike_rate: 1000000000000.0 is out of range; "
                                                  "allowed: a number 0..1000 per flight"),
    (BASE + "[dispersions]\nspike_rate = -1\n", "dispersions: spike_rate: -1 is out of range"),
    (BASE + "[dispersions]\nwind_speed_mps = 1e6\n", "wind_speed_mps: 1000000.0 is out of range; allowed: a "
                                                     "number 0..50 m/s"),
    (BASE + "[dispersions]\nrail_inclination_deg = 180\n", "rail_inclination_deg: 180 is out of range"),
    (BASE + "[dispersions]\nbaro_gain = 0\n", "baro_gain: 0 is out of range; allowed: a number 0.5..2"),
    (BASE + "[dispersions]\nwind_speed_mps = {normal = [3.0, 1.0], min = 5.0, max = 1.0}\n",
     "wind_speed_mps: min 5 > max 1"),
    (BASE + "[dispersions]\nwind_speed_mps = {normal = [5.0, 10.0]}\n",
     r"wind_speed_mps: normal = [5.0, 10.0] reaches -55 (mean +- 6 sd after min/max), out of range"),
    (BASE + "[dispersions]\nwind_speed_mps = {uniform = [0.0, 1e6]}\n", "uniform = [0.0, 1000000.0] reaches 1e+06"),
    ('scenario = 7\n', "scenario: 7 is not a name"),
])
def test_issue_specs_are_one_error_naming_file_and_key(tmp_path: Path, text: str, message: str | None) -> None:
    p = tmp_path / "spec.toml"
    p.write_text(text)
    with pytest.raises(UserError) as exc:
        load_spec(read_spec_file(p), where=str(p))
    assert str(exc.value).startswith(f"{p}: "), exc.value
    if message is not None:
        assert message in str(exc.value), exc.value
    assert len(str(exc.value)) < 400


def test_a_normal_clipped_by_min_max_inside_the_range_passes_and_draws_stay_inside() -> None:
    spec = load_spec({"scenario": "sub-k400-300m", "dispersions": {
        "wind_speed_mps": {"normal": [5.0, 10.0], "min": 0.0, "max": 20.0},
        "rail_inclination_deg": {"normal": [5.0, 2.0], "min": 0.0}}})
    for f in range(200):
        v = draw(spec, flight_rng(3, f))
        assert 0.0 <= v["wind_speed_mps"] <= 20.0 and 0.0 <= v["rail_inclination_deg"] <= 30.0


def test_the_tasks_of_a_huge_run_are_made_one_at_a_time() -> None:
    spec = load_spec({"scenario": "sub-k400-300m", "chunk_flights": 250})
    t0 = time.perf_counter()
    tasks = make_tasks(spec, 0, MAX_FLIGHTS)
    assert len(tasks) == 4_000_000
    last = tasks[len(tasks) - 1]
    assert last["flights"][0] == MAX_FLIGHTS - 250 and len(last["flights"]) == 250
    assert time.perf_counter() - t0 < 0.5                 # nothing built up front
    with pytest.raises(UserError, match=r"-n 1000000001: allowed: an integer 1\.\.1,000,000,000"):
        run_montecarlo(spec, 0, MAX_FLIGHTS + 1, Path("unused"))


def test_resume_redoes_a_truncated_and_a_corrupt_chunk(tmp_path: Path) -> None:
    spec = load_spec({"scenario": "sub-k400-300m", "k": 5, "methods": ["rec_quarter"], "tunings": ["default"],
                      "chunk_flights": 2, "descent_s": 2.0})
    for fmt in ("csv", "parquet"):
        full = run_montecarlo(spec, 1, 6, tmp_path / f"full-{fmt}", fmt=fmt, figures=False)
        cut = tmp_path / f"cut-{fmt}"
        run_montecarlo(spec, 1, 6, cut, fmt=fmt, figures=False)
        c1, c2 = cut / "chunks" / f"chunk-000001.{fmt}", cut / "chunks" / f"chunk-000002.{fmt}"
        c1.write_bytes(c1.read_bytes()[: len(c1.read_bytes()) // 2])        # truncated
        c2.write_bytes(b"garbage\n")                                         # overwritten
        notes: list[str] = []
        res = run_montecarlo(spec, 1, 6, cut, fmt=fmt, resume=True, figures=False, note=notes.append)
        assert res.resumed_chunks == 1
        assert len(notes) == 1 and "2 chunk file(s) not whole" in notes[0], notes
        assert res.rows_path.read_bytes() == full.rows_path.read_bytes()


def test_stale_stage_folders_of_dead_runs_are_removed(tmp_path: Path) -> None:
    dead = tmp_path / ".fwemu-stage-out-999999-abcd"        # a PID no process has (pid_max is below it here)
    live = tmp_path / f".fwemu-stage-out-{os.getppid()}-efgh"
    other = tmp_path / ".fwemu-stage-out-2-1234-abcd"        # the stage of a target named "out-2"
    old = tmp_path / ".fwemu-stage-out-oldname"
    young = tmp_path / ".fwemu-stage-out-younger"
    for d in (dead, live, other, old, young):
        d.mkdir()
        (d / "f").write_bytes(b"x" * 1000)
    os.utime(old, (time.time() - STALE_STAGE_S - 60,) * 2)
    with staged_folder(tmp_path / "out") as stage:
        (stage / "a.txt").write_text("a")
    assert (tmp_path / "out" / "a.txt").read_text() == "a"
    assert not dead.exists() and not old.exists()
    assert live.exists() and other.exists() and young.exists()
    assert remove_stale_stages(tmp_path, "out") == []

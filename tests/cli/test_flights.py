"""End-to-end: ``fwemu simulate / run / plot / evaluate / sweep`` (real logs: skip without ../shared/flights)."""

from __future__ import annotations

import csv
import os
from pathlib import Path

import numpy as np
import pytest

from firmware_model.cli.main import main
from firmware_model.runtime.engine import dask_available

SHARED = Path(os.environ.get("FWEMU_SHARED_FLIGHTS")
              or Path(__file__).resolve().parents[2].parent / "shared" / "flights")
needs_shared = pytest.mark.skipif(not SHARED.is_dir(), reason="../shared/flights is absent")
PROMETHEUS = SHARED / "altosui" / "prometheus-2022-06-24-telemetrum.csv"
SHORT_LOG = SHARED / "altosui" / "2012-05-28-serial-319-flight-005.csv"
SHORT_SIM = "sim:sub-k400-300m"


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open() as f:
        return list(csv.DictReader(f))


def _one_line_error(capsys, argv: list[str], *needles: str) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("fwemu: error:"), err
    for n in needles:
        assert n in err, err


# ---------------------------------------------------------------------------------------------------- simulate
def test_simulate_scenario_round_trips_through_the_generic_reader(tmp_path, capsys):
    from firmware_model.flights.readers import read_flight
    from firmware_model.flights.simulate.scenarios import simulate_scenario

    out = tmp_path / "f.csv"
    assert main(["simulate", "--scenario", SHORT_SIM[4:], "-o", str(out)]) == 0
    assert "true apogee" in capsys.readouterr().out
    rec = read_flight(out)
    ref = simulate_scenario(SHORT_SIM[4:])
    assert rec.n == ref.n
    assert np.array_equal(rec.time_s, ref.time_s)
    assert np.allclose(rec.pressure_pa, ref.pressure_pa, rtol=1e-11, atol=0)
    assert np.allclose(rec.accel_mps2, ref.specific_force_mps2(), rtol=1e-11, atol=1e-9)
    assert rec.truth.apogee_time_s == ref.truth.apogee_time_s
    assert np.allclose(rec.truth.altitude_m, ref.truth.altitude_m, rtol=1e-11, atol=1e-9)
    first = out.read_bytes()
    assert main(["simulate", "--scenario", SHORT_SIM[4:], "-o", str(out)]) == 0
    assert out.read_bytes() == first                      # deterministic to the byte


def test_simulate_list_1dof_and_errors(tmp_path, capsys):
    from firmware_model.flights.simulate.scenarios import scenario_names

    assert main(["simulate", "--list"]) == 0
    listed = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in listed] == scenario_names()
    out = tmp_path / "one.csv"
    assert main(["simulate", "--motor", "K400C", "--dry-mass", "8", "--diameter", "0.1", "-o", str(out)]) == 0
    assert "true apogee" in capsys.readouterr().out and out.is_file()
    _one_line_error(capsys, ["simulate", "--motor", "K400C", "-o", str(out)], "missing --dry-mass, --diameter")
    _one_line_error(capsys, ["simulate", "--scenario", "nope", "-o", str(tmp_path / "x.csv")], "nope")
    assert not (tmp_path / "x.csv").exists()


# ---------------------------------------------------------------------------------------------------- run / plot
def test_run_reports_the_accelerometer_clip_and_when_the_speed_is_known_again(capsys):
    """A 51 g boost on the +-16 g accelerometer: `fwemu run` says when ACC_CLIP latched (CLIP_N rail samples after
    liftoff) and when CLIP_CLEAR came (before apogee); a flight that does not clip says nothing of it."""
    assert main(["run", "--firmware", "kalman_accel", "--input", "sim:rb-m6400-m167", "--k", "5", "--model"]) == 0
    lines = capsys.readouterr().out.splitlines()
    clip = next(line for line in lines if line.startswith("accelerometer clip:"))
    latched = float(clip.split("latched at ")[1].split()[0])
    clear = float(clip.split("speed known again at ")[1].split()[0])
    apogee = float(next(line for line in lines if line.startswith("apogee:")).split()[1])
    liftoff = float(next(line for line in lines if line.startswith("liftoff:")).split()[1])
    assert liftoff < latched < 1.0 < clear < apogee, (liftoff, latched, clear, apogee)
    assert main(["run", "--firmware", "kalman_accel", "--input", SHORT_SIM, "--k", "5", "--model"]) == 0
    out = capsys.readouterr().out
    assert "apogee:" in out and "accelerometer clip" not in out


def test_run_cpu_and_model_agree_on_a_simulated_flight(tmp_path, capsys):
    cpu, model = tmp_path / "cpu.csv", tmp_path / "model.csv"
    argv = ["run", "--firmware", "kalman_baro", "--input", SHORT_SIM, "--k", "5", "--quiet"]
    assert main(argv + ["--out", str(cpu)]) == 0
    out_cpu = capsys.readouterr().out
    assert main(argv + ["--model", "--out", str(model)]) == 0
    out_model = capsys.readouterr().out
    a, b = _rows(cpu), _rows(model)
    assert list(a[0])[:5] == ["time_s", "raw_altitude_m", "filtered_altitude_m", "velocity_mps", "accel_mps2"]
    assert len(a) == len(b)
    for ra, rb in zip(a, b):
        assert {k: v for k, v in ra.items() if k != "cycles"} == {k: v for k, v in rb.items() if k != "cycles"}
    assert all(int(r["cycles"]) > 0 for r in a) and all(r["cycles"] == "" for r in b)
    apo = [line for line in out_cpu.splitlines() if line.startswith("apogee:")]
    assert apo and apo == [line for line in out_model.splitlines() if line.startswith("apogee:")]
    assert "worst step:" in out_cpu and "truth:" in out_cpu and "error:" in out_cpu
    from firmware_model.flights.simulate.scenarios import simulate_scenario

    burn = float(next(line for line in out_cpu.splitlines() if line.startswith("burnout:")).split()[1])
    true_burn = simulate_scenario(SHORT_SIM[4:]).provenance["summary"]["burnout_s"]
    assert true_burn - 0.3 < burn <= true_burn + 0.05      # thrust falls below drag just before the motor's end


def test_run_errors_are_one_line(tmp_path, capsys):
    _one_line_error(capsys, ["run", "--firmware", "nope", "--input", SHORT_SIM], "--firmware 'nope'")
    _one_line_error(capsys, ["run", "--firmware", "kalman_baro", "--input", str(tmp_path / "none.csv")],
                    "none.csv")
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,pressure_pa\n0,101325\n0.01,abc\n")
    _one_line_error(capsys, ["run", "--firmware", "kalman_baro", "--input", str(bad), "--out",
                             str(tmp_path / "o.csv")], "bad.csv:3")
    assert not (tmp_path / "o.csv").exists()


@needs_shared
def test_run_on_a_generic_csv_of_prometheus_matches_the_table_and_the_cpu(tmp_path, capsys):
    """The must-show: ``fwemu run`` on ``time_s,pressure_pa,accel_mps2`` of a real flight prints the apogee of the
    apogee table's row (so within the reference's uncertainty + the method's error), the emulated CPU and the
    integer model give the same words on every sample."""
    from firmware_model.firmware.assemble import build_firmware
    from firmware_model.firmware.harness import run_firmware
    from firmware_model.flights.evaluation.evaluate import evaluate_flight
    from firmware_model.flights.evaluation.methods import METHODS
    from firmware_model.flights.evaluation.setup import FlightSpec, flight_inputs, sensor_config
    from firmware_model.flights.readers.generic import generic_csv
    from firmware_model.flights.readers import read_flight
    from firmware_model.model.run import run_model
    from firmware_model.spec.build_constants import build_constants

    log = read_flight(PROMETHEUS)
    generic = tmp_path / "prometheus.csv"
    generic.write_text(generic_csv(log, temperature=False))
    header = next(line for line in generic.read_text().splitlines() if not line.startswith("#"))
    assert header == "time_s,pressure_pa,accel_mps2"
    row = evaluate_flight(FlightSpec(str(PROMETHEUS), k=6, noise=False), [METHODS["kalman_baro"]])
    assert main(["run", "--firmware", "kalman_baro", "--input", str(generic), "--k", "6", "--quiet",
                 "--out", str(tmp_path / "run.csv")]) == 0
    out = capsys.readouterr().out
    apo = float(next(line for line in out.splitlines() if line.startswith("apogee:")).split()[1])
    assert abs(apo - row.detections["kalman_baro"].time_s) < 1e-6
    ref = row.reference
    assert abs(apo - ref.time_s) <= ref.uncertainty_s + abs(row.error("kalman_baro")) + 1e-9
    # the generic file carries no AltOS events, so its reference is the whole-window fit (rule 5, the deployment
    # cut, needs the log's deployment time); the two fits of the same flight agree within their uncertainties
    from firmware_model.flights.evaluation.setup import reference_for

    gen = reference_for(read_flight(generic))
    assert f"reference ({gen.source}, ±{gen.uncertainty_s:.3f} s): {gen.time_s:.3f} s" in out
    assert abs(gen.time_s - ref.time_s) <= gen.uncertainty_s + ref.uncertainty_s
    burn = float(next(line for line in out.splitlines() if line.startswith("burnout:")).split()[1])
    assert 4.0 < burn < 5.5          # not the ejection shock at apogee (the log's largest reading, 267 m/s^2)
    # the same words from the emulated 68000 and the model, on the generic file's inputs
    spec = FlightSpec(str(generic), k=6, noise=False)
    inputs = flight_inputs(read_flight(generic), spec)
    cfg = METHODS["kalman_baro"].config(6, sensor_config(inputs))
    cpu = run_firmware(build_firmware(cfg), inputs.adc, inputs.acc)
    model = run_model(build_constants(cfg), inputs.adc, inputs.acc)
    assert np.array_equal(cpu.words, model.words)
    assert cpu.first_event("APOGEE") == model.first_event("APOGEE") >= 0


def test_plot_run_csv_and_flight(tmp_path, capsys):
    run = tmp_path / "run.csv"
    assert main(["run", "--firmware", "rec_quarter", "--input", SHORT_SIM, "--k", "5", "--model", "--quiet",
                 "--out", str(run)]) == 0
    capsys.readouterr()
    for argv, name in ((["plot", str(run)], "a.png"), (["plot", str(run), "--zoom", "--reference", "9.19"], "b.png"),
                       (["plot", SHORT_SIM, "--k", "5", "--zoom"], "c.png")):
        png = tmp_path / name
        assert main(argv + ["-o", str(png)]) == 0
        data = png.read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000
    _one_line_error(capsys, ["plot", str(run), "-o", str(tmp_path / "x.jpg")], ".png")


# ---------------------------------------------------------------------------------------------------- evaluate
def test_evaluate_jobs_gives_identical_files(tmp_path, capsys):
    flights = [SHORT_SIM, "sim:sub-k400-900m"] + ([str(SHORT_LOG)] if SHORT_LOG.is_file() else [])
    base = ["evaluate", *flights, "--k", "5", "--methods", "kalman_baro,rec_quarter"]
    assert main(base + ["--out", str(tmp_path / "one")]) == 0
    md = capsys.readouterr().out
    assert main(base + ["--jobs", "2", "--out", str(tmp_path / "two")]) == 0
    capsys.readouterr()
    for name in ("apogee.md", "apogee.csv", "apogee.json"):
        assert (tmp_path / "one" / name).read_bytes() == (tmp_path / "two" / name).read_bytes().replace(
            b" --jobs 2", b""), name
    rows = _rows(tmp_path / "one" / "apogee.csv")
    assert [r["flight"] for r in rows][:2] == ["sub-k400-300m", "sub-k400-900m"]
    assert "| kalman_baro |" in md and "median abs error s" in md
    if SHORT_LOG.is_file():
        assert rows[2]["ref_source"] and rows[2]["altos_time_s"]          # AltOS's own detection is reported



@pytest.mark.skipif(not dask_available(), reason="Dask's distributed scheduler (the 'montecarlo' extra) not installed")
def test_evaluate_and_sweep_on_a_dask_cluster_give_the_local_bytes(tmp_path, capsys):
    """evaluate and sweep run their flights through the task engine: a 2-worker LocalCluster gives the same files
    as one process (issue 23: the task unit is plain data, the backend a thin layer)."""
    flights = [SHORT_SIM, "sim:sub-k400-900m"]
    for cmd, extra, names in (("evaluate", ["--methods", "kalman_baro,rec_quarter"], ("apogee.md", "apogee.csv")),
                              ("sweep", ["--what", "ratio", "--ratios", "1000,50000"], ("ratio.md", "ratio.csv"))):
        base = [cmd, *flights, "--k", "5", *extra]
        assert main(base + ["--out", str(tmp_path / cmd / "one")]) == 0
        assert main(base + ["--scheduler", "local:2", "--out", str(tmp_path / cmd / "dask")]) == 0
        capsys.readouterr()
        for name in names:
            one = (tmp_path / cmd / "one" / name).read_bytes()
            assert one == (tmp_path / cmd / "dask" / name).read_bytes().replace(b" --scheduler local:2", b""), name

def test_evaluate_errors(tmp_path, capsys):
    _one_line_error(capsys, ["evaluate", str(tmp_path / "missing.csv"), "--out", str(tmp_path / "o")],
                    "missing.csv")
    _one_line_error(capsys, ["evaluate", "sim:nope"], "sim:nope")
    _one_line_error(capsys, ["evaluate", SHORT_SIM, "--methods", "bogus"], "bogus")
    assert not (tmp_path / "o").exists()


def test_sweep_small(tmp_path, capsys):
    out = tmp_path / "sw"
    assert main(["sweep", SHORT_SIM, "--k", "5", "--ratios", "1e3,5e4,1e6", "--ks", "4,5",
                 "--methods", "kalman_baro,rec_quarter", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "R/q" in text and "| 5e+04 |" in text
    for name in ("ratio.md", "ratio.csv", "ratio.json", "ratio.png", "k.md", "k.csv", "k.json", "k.png"):
        assert (out / name).is_file(), name
    rows = _rows(out / "ratio.csv")
    assert [r["ratio"] for r in rows] == ["1000.0", "50000.0", "1000000.0"]


def test_harness_progress_callback_changes_nothing():
    from firmware_model.firmware.assemble import build_firmware
    from firmware_model.firmware.harness import run_firmware
    from firmware_model.model.streams import synthetic_flight
    from firmware_model.spec.config import BuildConfig

    s = synthetic_flight(5, 16, seed=3)
    build = build_firmware(BuildConfig(program="kalman_baro", k=5))
    calls: list[tuple[int, int]] = []
    with_cb = run_firmware(build, s.adc, s.acc, progress=lambda d, t: calls.append((d, t)))
    plain = run_firmware(build, s.adc, s.acc)
    n = len(s.adc)
    assert np.array_equal(with_cb.words, plain.words) and np.array_equal(with_cb.cycles, plain.cycles)
    assert calls[0] == (0, n) and calls[-1] == (n, n)
    assert [d for d, _ in calls[:-1]] == list(range(0, n, 4096))

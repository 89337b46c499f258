"""``fwemu inputs`` (issue 34): a flight as the firmware's integer input stream, the CSV ``fwemu vectors --input``
takes, and the build config that reads it."""

from __future__ import annotations

import csv
import json
import os
from pathlib import Path

import numpy as np
import pytest

from firmware_model.cli.main import main
from firmware_model.runtime.output import TEMP_PREFIX

SHARED = Path(os.environ.get("FWEMU_SHARED_FLIGHTS")
              or Path(__file__).resolve().parents[2].parent / "shared" / "flights")
EEPROM = SHARED / "euroc21" / "piccard-telemetrum-nosecone-serial-5877-flight-0002.eeprom"
SIM = "sim:sub-k400-300m"


def _read(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    lines = path.read_text().splitlines()
    comments = [line for line in lines if line.startswith("#")]
    rows = list(csv.DictReader(line for line in lines if not line.startswith("#")))
    return comments, rows


def _one_line_error(capsys, argv: list[str], *needles: str) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("fwemu: error:"), err
    for needle in needles:
        assert needle in err, err
    return err


def _pad_counts_telemetrum_v1(pressure_pa: float) -> int:
    """The TeleMetrum v1 barometer word, the formula of ../shared/flights/README.md (not the code's constants)."""
    return round((pressure_pa / 1000 * 0.009 - 0.095) * 2047 * 16)


def test_a_simulated_flight_becomes_the_stream_and_config_that_fwemu_vectors_takes(tmp_path, capsys):
    out, cfg_path = tmp_path / "inputs.csv", tmp_path / "config.json"
    assert main(["inputs", SIM, "--program", "kalman_accel", "--k", "6", "-o", str(out),
                 "--config-out", str(cfg_path)]) == 0
    comments, rows = _read(out)
    assert comments[0].startswith("# fwemu inputs sim:sub-k400-300m: program kalman_accel, k=6")
    assert list(rows[0]) == ["time_s", "adc", "acc"]
    t = np.array([float(r["time_s"]) for r in rows])
    adc = np.array([int(r["adc"]) for r in rows])
    acc = np.array([int(r["acc"]) for r in rows])
    assert np.all(np.diff(t) == 2.0 ** -6)                  # the firmware's grid, exactly
    assert t[0] < -1.5 and t[-1] > 10                       # from the pad (2 s before liftoff) past the apogee
    pad = t < -0.5
    # no --baro/--accel: noise-free TeleMetrum v1 barometer and the default 2048 counts/g accelerometer
    assert set(adc[pad].tolist()) == {_pad_counts_telemetrum_v1(101325.0)}
    assert set(acc[pad].tolist()) == {2048}
    assert adc.min() < adc[0] - 3.4 * 250                    # it climbs (>= 250 m: fewer counts)
    assert acc.max() > 3 * 2048                              # the boost (this heavy rocket: ~3.8 g)
    cfg = json.loads(cfg_path.read_text())
    assert (cfg["program"], cfg["k"], cfg["baro_bits"]) == ("kalman_accel", 6, 16)
    assert cfg["accel_counts_per_mps2"] == pytest.approx(2048 / 9.80665)
    assert cfg["baro_pa_per_count"] == pytest.approx(1 / (0.009e-3 * 2047 * 16))
    capsys.readouterr()
    vec = tmp_path / "vec"
    assert main(["vectors", "--firmware", "kalman_accel", "--input", str(out), "--config", str(cfg_path),
                 "--generator", "model", "--out", str(vec)]) == 0
    case = json.loads(next((vec / "cases").glob("*.json")).read_text())
    assert (case["adc"], case["acc"]) == (adc.tolist(), acc.tolist())
    # the filter on these words finds the apogee where the barometer is lowest (the highest point), within 2 s
    fired = case["events_first_sample"]["APOGEE"]
    assert fired is not None and abs(t[fired] - t[int(np.argmin(adc))]) < 2.0
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(TEMP_PREFIX)) == []


def test_the_port_config_gives_k_and_tuning_and_its_sensors_must_be_the_streams(tmp_path, capsys):
    mine = tmp_path / "port.json"
    mine.write_text(json.dumps({"program": "kalman_baro", "k": 5, "ratio": 123456.0}))
    out, cfg_path = tmp_path / "in.csv", tmp_path / "cfg.json"
    assert main(["inputs", SIM, "--program", "kalman_baro", "--config", str(mine), "-o", str(out),
                 "--config-out", str(cfg_path)]) == 0
    cfg = json.loads(cfg_path.read_text())
    assert (cfg["k"], cfg["ratio"]) == (5, 123456.0)          # the file's k and tuning
    capsys.readouterr()
    mine.write_text(json.dumps({"program": "kalman_baro", "baro_bits": 12}))
    _one_line_error(capsys, ["inputs", SIM, "--program", "kalman_baro", "--config", str(mine), "-o", str(out),
                             "--config-out", str(cfg_path)], str(mine), "baro_bits=12 (the stream: 16)")
    # a different program in the file than the flag: the one rule of every command
    _one_line_error(capsys, ["inputs", SIM, "--program", "kalman_accel", "--config", str(mine), "-o", str(out)],
                    "contradicts --program")
    # a 12-bit build without its own transfer function reads TeleMetrum v1's scaled to 12 bits (2047 x 2 counts
    # over the sensor's span, BuildConfig.baro_transfer), not an MPX4115 on a full 12-bit ADC (4095 counts)
    _one_line_error(capsys, ["inputs", SIM, "--program", "kalman_baro", "--config", str(mine), "--baro",
                             "mpx4115_12bit", "-o", str(out)], "baro_pa_per_count=54.28 (the stream: 27.13")
    # the port's config names its sensor's transfer function (0.009/kPa of 4095 counts, -0.095 offset): accepted
    mine.write_text(json.dumps({"program": "kalman_baro", "baro_bits": 12, "baro_pa_per_count": 1 / (0.009e-3 * 4095),
                                "baro_pa_at_zero": 0.095 / 0.009e-3}))
    assert main(["inputs", SIM, "--program", "kalman_baro", "--config", str(mine), "--baro", "mpx4115_12bit",
                 "-o", str(out)]) == 0
    adc = np.array([int(r["adc"]) for r in _read(out)[1]])
    assert 0 < adc.min() and adc.max() < 4096


def test_a_stream_the_build_would_misread_is_refused_without_config_out(tmp_path, capsys):
    out = tmp_path / "in.csv"
    out.write_text("previous\n")
    _one_line_error(capsys, ["inputs", SIM, "--program", "kalman_baro", "--baro", "ms5607", "-o", str(out)],
                    "the default build config", "baro_kind=adc (the stream: pascal)", "--config-out")
    assert out.read_text() == "previous\n"                    # the previous output is untouched
    assert [p.name for p in tmp_path.iterdir()] == ["in.csv"]  # and no temporary name is left


def test_bad_inputs_are_one_line_errors(tmp_path, capsys):
    out = tmp_path / "in.csv"
    _one_line_error(capsys, ["inputs", str(tmp_path / "nope.csv"), "--program", "kalman_baro", "-o", str(out)],
                    "nope.csv")
    baro_only = tmp_path / "baro.csv"
    baro_only.write_text("time_s,pressure_pa\n" + "".join(f"{i / 20},{101325 - (i > 40) * 3 * (i - 40)}\n"
                                                              for i in range(400)))
    _one_line_error(capsys, ["inputs", str(baro_only), "--program", "kalman_accel", "-o", str(out)],
                    "reads the accelerometer", "kalman_baro")
    assert main(["inputs", str(baro_only), "--program", "kalman_baro", "-o", str(out)]) == 0
    assert list(_read(out)[1][0]) == ["time_s", "adc"]        # no accelerometer: no acc column (not zeros)
    out.unlink()
    capsys.readouterr()
    _one_line_error(capsys, ["inputs", SIM, "--program", "kalman_baro", "--baro", "nosuch", "-o", str(out)],
                    "nosuch")
    _one_line_error(capsys, ["inputs", SIM, "--program", "kalman_baro", "-o", str(tmp_path)], str(tmp_path))
    assert not out.exists()
    with pytest.raises(SystemExit):                          # argparse: unknown program, usage error
        main(["inputs", SIM, "--program", "nosuch", "-o", str(out)])


@pytest.mark.skipif(not EEPROM.is_file(), reason="../shared/flights is absent")
def test_a_real_altos_log_gives_integer_pascals_and_a_pascal_config(tmp_path, capsys):
    out, cfg_path = tmp_path / "in.csv", tmp_path / "cfg.json"
    assert main(["inputs", str(EEPROM), "--program", "kalman_baro", "-o", str(out), "--config-out",
                 str(cfg_path)]) == 0
    comments, rows = _read(out)
    assert any("ms5607 (pascal)" in c for c in comments)
    assert any(c.startswith("# note:") for c in comments)      # the report's notes are carried along
    adc = np.array([int(r["adc"]) for r in rows[:200]])
    assert 90_000 < adc.min() <= adc.max() < 110_000          # pascals on the pad
    assert json.loads(cfg_path.read_text())["baro_kind"] == "pascal"

"""Flight-log readers: the shared real logs (skipped when ../shared/flights is absent) and bad files.

Every kind of bad file must be rejected with one UserError naming the file and the line at fault; the property
tests build a valid file, break it in one place they choose, and check the message names exactly that line."""

from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware_model.spec.atmosphere import G0, pressure_pa
from firmware_model.runtime.errors import UserError
from firmware_model.flights.readers import FORMATS, detect_format, read_flight
from tests.support.profiles import examples

#: <repo>/../shared/flights; FWEMU_SHARED_FLIGHTS overrides it (a git worktree lives elsewhere than its checkout).
SHARED = Path(os.environ.get("FWEMU_SHARED_FLIGHTS")
              or Path(__file__).resolve().parents[2].parent / "shared" / "flights")
needs_shared = pytest.mark.skipif(not SHARED.is_dir(), reason="../shared/flights is absent")
ALTOS = {
    "2012-04-07-serial-882-flight-001": "5", "2012-05-28-serial-319-flight-005": "5",
    "2012-10-20-serial-068-flight-004": "5", "prometheus-2022-06-24-telemega": "6",
    "prometheus-2022-06-24-telemetrum": "6",
}


def _raw_rows(path: Path) -> list[list[str]]:
    return [l.split(",") for l in path.read_text().splitlines() if l.strip() and not l.startswith("#")]


# ------------------------------------------------------------------------------------------------ shared logs
@needs_shared
@pytest.mark.parametrize("stem", sorted(ALTOS))
def test_altosui_shared_logs(stem: str) -> None:
    path = SHARED / "altosui" / f"{stem}.csv"
    assert detect_format(path) == "altosui"
    rec = read_flight(path)
    assert rec.provenance["csv_version"] == ALTOS[stem]
    assert rec.provenance["licence"] == ("MIT" if stem.startswith("prometheus") else "GPL-2.0-or-later")
    rows = _raw_rows(path)
    # independent count of what the reader must keep: rows whose time differs from the previous row's
    times = [float(r[4]) for r in rows]
    distinct = 1 + sum(1 for a, b in zip(times, times[1:]) if b != a)
    assert rec.n == distinct
    assert rec.provenance["repeated_timestamps_dropped"] == len(rows) - distinct
    assert np.all(np.diff(rec.time_s) > 0)
    # pressure is column 11 (v5) / 8 (v6) positionally in every row, state_name 9 / 6
    pcol, scol, acol = (11, 9, 10) if ALTOS[stem] == "5" else (8, 6, 7)
    first = {}
    for r in rows:
        first.setdefault(r[scol].strip(), float(r[4]))
    if "drogue" in first:
        assert rec.events["altos_apogee"] == first["drogue"]
    assert rec.events["altos_boost"] == first["boost"]
    assert float(rows[0][pcol]) == rec.pressure_pa[0]
    assert rec.accel_mps2[0] == pytest.approx(float(rows[0][acol]) + G0)


@needs_shared
def test_altosui_v5_quirk_and_repeats() -> None:
    rec = read_flight(SHARED / "altosui" / "2012-04-07-serial-882-flight-001.csv")
    assert "main_voltageaccel_x" in (SHARED / "altosui" / "2012-04-07-serial-882-flight-001.csv").read_text()
    assert any("IMU block" in n for n in rec.provenance["notes"])
    assert rec.provenance["baro_sensor_hint"] == "telemetrum_v1"
    rec6 = read_flight(SHARED / "altosui" / "prometheus-2022-06-24-telemetrum.csv")
    assert rec6.provenance["repeated_timestamps_dropped"] == 1369
    assert rec6.provenance["conflicting_repeats"] == 0
    # 319 never logs 'drogue': the first 'main' row stands in, and the provenance says so
    rec319 = read_flight(SHARED / "altosui" / "2012-05-28-serial-319-flight-005.csv")
    assert "altos_drogue" not in rec319.events and rec319.events["altos_apogee"] == rec319.events["altos_main"]
    assert any("straight to main" in n for n in rec319.provenance["notes"])


@needs_shared
@pytest.mark.parametrize("name", ["hedy-baro.csv", "hedy-imu.csv"])
def test_cats_pair_either_file(name: str) -> None:
    path = SHARED / "cats" / name
    assert detect_format(path) == "cats"
    rec = read_flight(path)
    assert rec.name == "hedy" and rec.provenance["licence"] == "MIT"
    assert rec.provenance["axial"]["axis"] == "-Ay"
    imu = np.genfromtxt(SHARED / "cats" / "hedy-imu.csv", delimiter=",", names=True, dtype=None, encoding=None)
    baro = np.genfromtxt(SHARED / "cats" / "hedy-baro.csv", delimiter=",", names=True, dtype=None, encoding=None)
    np.testing.assert_array_equal(rec.time_s, baro["ts"])
    np.testing.assert_array_equal(rec.pressure_pa, baro["P"])
    np.testing.assert_allclose(rec.accel_mps2, -imu["Ay"], rtol=0, atol=1e-12)
    assert np.median(rec.accel_mps2[:50]) == pytest.approx(G0, abs=0.3)       # +1 g on the pad
    assert rec.accel_mps2.max() > 5 * G0                                       # boost along +axis


@needs_shared
def test_cats_without_partner(tmp_path: Path) -> None:
    (tmp_path / "x-baro.csv").write_text((SHARED / "cats" / "hedy-baro.csv").read_text())
    rec = read_flight(tmp_path / "x-baro.csv")
    assert rec.accel_mps2 is None and any("no IMU partner" in n for n in rec.provenance["notes"])
    (tmp_path / "y-imu.csv").write_text("ts,id,Ax,Ay,Az,Gx,Gy,Gz\n0,IMU0,0,-9.8,0,0,0,0\n0.01,IMU0,0,-9.8,0,0,0,0\n")
    with pytest.raises(UserError, match=r"y-imu\.csv:1: CATS IMU file without its barometer partner"):
        read_flight(tmp_path / "y-imu.csv")


# ------------------------------------------------------------------------------------------------ formats
def test_generic_units_and_truth(tmp_path: Path) -> None:
    p = tmp_path / "g.csv"
    p.write_text("# licence: CC0\n# true_apogee_time_s: 1.25\n"
                 "time_s,altitude_m,accel_g,true_altitude_m,true_velocity_mps\n"
                 "0,100,1,0,10\n0.5,110,1,5,5\n1,,1,7,0.5\n1.5,112,,7,-4\n")
    rec = read_flight(p)
    assert detect_format(p) == "generic"
    np.testing.assert_allclose(rec.pressure_pa[[0, 1, 3]], pressure_pa(np.array([100.0, 110.0, 112.0])))
    assert math.isnan(rec.pressure_pa[2]) and math.isnan(rec.accel_mps2[3])
    assert rec.accel_mps2[0] == G0
    assert rec.truth.apogee_time_s == 1.25 and rec.provenance["licence"] == "CC0"
    p.write_text("time_s,pressure_hpa,true_velocity_mps,true_altitude_m\n0,1000,10,0\n1,999,2,6\n2,998,-6,4\n")
    rec = read_flight(p)
    assert rec.pressure_pa[0] == 100000.0 and rec.accel_mps2 is None
    assert rec.truth.apogee_time_s == pytest.approx(1.25)           # velocity crosses zero a quarter of the way


def test_rdas_raw_and_interpreted(tmp_path: Path) -> None:
    p = tmp_path / "flight.txt"
    lines = ["RDAS data export", "Flight 3 something"]
    for i in range(-20, 40):
        t = i * 0.05
        lines.append(f"{t:.3f} {512 + (40 if 0 <= t < 0.5 else 0)} {930 - max(0, i)} 0")
    p.write_text("\n".join(lines) + "\n")
    assert detect_format(p) == "rdas"
    rec = read_flight(p)
    assert rec.provenance["export"] == "raw" and rec.n == 60
    assert rec.pressure_pa[0] == pytest.approx(101325.0)
    assert np.median(rec.specific_force_mps2()[:20]) == pytest.approx(G0)
    p.write_text("\n".join(["hdr"] + [f"{i * 0.1:.2f} {32.2 if i < 5 else 200.5} {i * 10.5:.1f}" for i in range(30)]))
    rec = read_flight(p)
    assert rec.provenance["export"] == "interpreted"
    assert rec.pressure_pa[10] == pytest.approx(float(pressure_pa(105.0 * 0.3048)))


# ------------------------------------------------------------------------------------------------ bad files
def _generic_lines(n: int) -> list[str]:
    return ["# a comment", "time_s,pressure_pa,accel_mps2"] + [f"{i * 0.01:.2f},{90000 - i},{9.8}" for i in range(n)]


BREAKS = ("time_back", "time_repeat", "nan", "inf", "garbage", "short_row", "empty_time", "negative_p")


@settings(max_examples=examples(60))
@given(n=st.integers(3, 30), data=st.data(), kind=st.sampled_from(BREAKS))
def test_generic_bad_value_names_file_and_line(n: int, data: st.DataObject, kind: str) -> None:
    lines = _generic_lines(n)
    row = data.draw(st.integers(3, len(lines) - 1), label="row")       # 0-based index into lines; data rows >= 2
    fields = lines[row].split(",")
    col = data.draw(st.integers(0, 2), label="col")
    if kind == "time_back":
        fields[0] = "-5"
    elif kind == "time_repeat":
        fields[0] = lines[row - 1].split(",")[0]
    elif kind == "nan":
        fields[col] = "nan"
    elif kind == "inf":
        fields[col] = "-inf"
    elif kind == "garbage":
        fields[col] = data.draw(st.sampled_from(["1.2.3", "abc", "0x12", "--1", "1e"]))
    elif kind == "short_row":
        fields = fields[:2]
    elif kind == "empty_time":
        fields[0] = ""
    elif kind == "negative_p":
        fields[1] = "-3"
    lines[row] = ",".join(fields)
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "bad.csv"
        p.write_text("\n".join(lines) + "\n")
        with pytest.raises(UserError) as err:
            read_flight(p)
    assert str(err.value).startswith(f"{p}:{row + 1}:"), (kind, str(err.value))
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("header,line,what", [
    ("time_s,accel_mps2", 2, "barometer column"),
    ("pressure_pa,accel_mps2", 2, "missing column time_s"),
    ("time_s,pressure_pa,pressure_hpa", 2, "exactly one barometer"),
    ("time_s,pressure_pa,pressure_pa", 2, "named twice"),
])
def test_generic_bad_header(tmp_path: Path, header: str, line: int, what: str) -> None:
    p = tmp_path / "h.csv"
    p.write_text(f"# c\n{header}\n" + "\n".join(f"{i},{9e4},{9.8}" for i in range(3)) + "\n")
    with pytest.raises(UserError, match=rf"^{p}:{line}: .*{what}"):
        read_flight(p, format="generic")


def test_empty_and_unknown(tmp_path: Path) -> None:
    for text in ("", "\n\n  \n"):
        (tmp_path / "e.csv").write_text(text)
        with pytest.raises(UserError, match=rf"^{tmp_path / 'e.csv'}:1: empty file"):
            read_flight(tmp_path / "e.csv")
    (tmp_path / "u.csv").write_text("a,b,c\n1,2,3\n")
    with pytest.raises(UserError, match=r"u\.csv:1: unknown flight log format"):
        read_flight(tmp_path / "u.csv")
    with pytest.raises(UserError, match="unknown format 'xml'"):
        read_flight(tmp_path / "u.csv", format="xml")
    with pytest.raises(UserError, match="no such flight log"):
        read_flight(tmp_path / "missing.csv")
    (tmp_path / "b.csv").write_bytes(b"time_s,pressure_pa\n0,1\n\xff\xfe\n")
    with pytest.raises(UserError, match=r"b\.csv:3: not a text file"):
        read_flight(tmp_path / "b.csv")
    (tmp_path / "o.csv").write_text("time_s,pressure_pa\n")
    with pytest.raises(UserError, match=r"o\.csv:1: no data rows"):
        read_flight(tmp_path / "o.csv")
    assert set(FORMATS) >= {"altosui", "cats", "rdas", "generic", "eeprom", "cats_raw", "rrc3", "eggtimer", "raven",
                            "board", "columns"}


ALTOS_V6_HEAD = ("#version,serial,flight,call,time,state,state_name,acceleration,pressure,altitude,height,speed,"
                 "temperature")


@settings(max_examples=examples(40))
@given(n=st.integers(3, 20), data=st.data(), kind=st.sampled_from(("time_back", "nan", "garbage", "empty_pressure",
                                                                     "short_row", "empty_state")))
def test_altosui_bad_value_names_file_and_line(n: int, data: st.DataObject, kind: str) -> None:
    lines = [ALTOS_V6_HEAD] + [f"6, 1, 1,X, {i * 0.01 - 0.3:8.2f}, 2, pad, 0.00, {86000 + i:9.2f}, 1300, 0, 0, 30"
                               for i in range(n)]
    row = data.draw(st.integers(2, len(lines) - 1), label="row")
    f = lines[row].split(",")
    if kind == "time_back":
        f[4] = "-9"
    elif kind == "nan":
        f[8] = "NaN"
    elif kind == "garbage":
        f[data.draw(st.sampled_from([4, 7, 8]))] = " 12..5"
    elif kind == "empty_pressure":
        f[8] = " "
    elif kind == "short_row":
        f = f[:7]
    elif kind == "empty_state":
        f[6] = ""
    lines[row] = ",".join(f)
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "bad-altos.csv"
        p.write_text("\n".join(lines) + "\n")
        with pytest.raises(UserError) as err:
            read_flight(p)
    assert str(err.value).startswith(f"{p}:{row + 1}:"), (kind, str(err.value))


@settings(max_examples=examples(30))
@given(n=st.integers(3, 20), data=st.data(), kind=st.sampled_from(("time_back", "garbage", "short_row", "inf")))
def test_cats_bad_value_names_file_and_line(n: int, data: st.DataObject, kind: str) -> None:
    lines = ["ts,id,T,P"] + [f"{i * 0.01:.3f},BARO0,20.0,{99000 + i}" for i in range(n)]
    row = data.draw(st.integers(2, len(lines) - 1), label="row")
    f = lines[row].split(",")
    if kind == "time_back":
        f[0] = "-1"
    elif kind == "garbage":
        f[data.draw(st.sampled_from([0, 2, 3]))] = "x"
    elif kind == "short_row":
        f = f[:3]
    elif kind == "inf":
        f[3] = "inf"
    lines[row] = ",".join(f)
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "bad-baro.csv"
        p.write_text("\n".join(lines) + "\n")
        with pytest.raises(UserError) as err:
            read_flight(p)
    assert str(err.value).startswith(f"{p}:{row + 1}:"), (kind, str(err.value))


def test_rdas_bad_line(tmp_path: Path) -> None:
    lines = ["header"] + [f"{i * 0.05:.2f} 500 900 0" for i in range(20)]
    lines[12] = "0.55 500 nine 0"
    (tmp_path / "r.txt").write_text("\n".join(lines))
    with pytest.raises(UserError, match=r"r\.txt:13: not a data line"):
        read_flight(tmp_path / "r.txt", format="rdas")
    lines[12] = "0.10 500 900 0"
    (tmp_path / "r.txt").write_text("\n".join(lines))
    with pytest.raises(UserError, match=r"r\.txt:13: time does not increase"):
        read_flight(tmp_path / "r.txt", format="rdas")


# ------------------------------------------------------------------------------------------------ writer
finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)
#: Accelerations a record may hold (issue 33: at most 10,000 g either way, FlightRecord refuses more).
plausible_accel = st.floats(-9.8e4, 9.8e4, allow_nan=False, allow_infinity=False)


@settings(max_examples=examples(40))
@given(data=st.data(), n=st.integers(2, 40), with_acc=st.booleans(), with_truth=st.booleans(),
       gaps=st.booleans())
def test_generic_round_trip_bit_exact(data: st.DataObject, n: int, with_acc: bool, with_truth: bool,
                                      gaps: bool) -> None:
    from firmware_model.flights.readers import write_generic
    from firmware_model.flights.record import FlightRecord, Truth

    steps = np.array(data.draw(st.lists(st.floats(1e-6, 10.0), min_size=n - 1, max_size=n - 1)))
    t = np.concatenate([[data.draw(st.floats(-100, 100))], np.zeros(n - 1)])
    t[1:] = t[0] + np.cumsum(steps)
    if not np.all(np.diff(t) > 0):
        return
    p = np.array(data.draw(st.lists(st.floats(1.0, 2e5), min_size=n, max_size=n)))
    if gaps:
        p[data.draw(st.integers(1, n - 1))] = np.nan
    acc = np.array(data.draw(st.lists(plausible_accel, min_size=n, max_size=n))) if with_acc else None
    truth = None
    if with_truth:
        truth = Truth(altitude_m=np.array(data.draw(st.lists(finite, min_size=n, max_size=n))),
                      apogee_time_s=float(t[n // 2]), apogee_altitude_m=123.456789012345)
    rec = FlightRecord(name="rt case", time_s=t, pressure_pa=p, accel_mps2=acc, truth=truth,
                       ground_pressure_pa=98765.4321, provenance={"licence": "MIT", "source": "x"})
    with tempfile.TemporaryDirectory() as d:
        path = write_generic(rec, Path(d) / "rt.csv")
        assert sorted(os.listdir(d)) == ["rt.csv"]                       # no temporary left behind
        back = read_flight(path)
    np.testing.assert_array_equal(back.time_s, t)
    np.testing.assert_array_equal(back.pressure_pa, p)                  # NaN where NaN
    if with_acc:
        np.testing.assert_array_equal(back.accel_mps2, acc)
    else:
        assert back.accel_mps2 is None
    assert back.name == "rt case" and back.ground_pressure_pa == 98765.4321
    assert back.provenance["licence"] == "MIT"
    if with_truth:
        np.testing.assert_array_equal(back.truth.altitude_m, truth.altitude_m)
        assert back.truth.apogee_time_s == truth.apogee_time_s
        assert back.truth.apogee_altitude_m == truth.apogee_altitude_m
    else:
        assert back.truth is None


# ------------------------------------------------------------------------------------------------ fuzz
_tokens = st.sampled_from(["0", "1.5", "-2", "nan", "", " ", "abc", "1e3", "99999", "#", "time_s", "pressure_pa",
                           "accel_mps2", "ts", "id", "P", "T", "Ax", "Ay", "BARO0", "pad", "boost", "drogue"])
_line = st.lists(_tokens, min_size=0, max_size=8).map(",".join) | st.lists(_tokens, max_size=5).map(" ".join)
_headers = st.sampled_from(["", "time_s,pressure_pa,accel_mps2", "ts,id,T,P", ALTOS_V6_HEAD, "RDAS export"])


@settings(max_examples=examples(150))
@given(header=_headers, body=st.lists(_line, max_size=25), fmt=st.sampled_from([None, *FORMATS]))
def test_fuzz_only_user_errors(header: str, body: list[str], fmt: str | None) -> None:
    """Whatever the text, a reader returns a valid record or raises one UserError naming the file."""
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "fuzz-baro.csv"
        p.write_text("\n".join([header, *body]) + "\n")
        try:
            rec = read_flight(p, format=fmt)
        except UserError as exc:
            assert str(exc).startswith(str(p)) and "\n" not in str(exc)
            return
    assert rec.n >= 2 and np.all(np.diff(rec.time_s) > 0)

"""Issue 32: the hobby altimeters' own exports (PerfectFlite, Featherweight Raven FIP and Blue Raven, Entacore AIM,
AltimeterCloud): read with no format named, the device's stated apogee against the log's reference apogee, merging
per-channel time columns without inventing samples, and one ``file:line`` error per kind of bad input.

The stated apogees are typed in from ../shared/flights/README.md (the devices' own numbers), not from this code."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware_model.cli.main import main
from firmware_model.flights.reference.apogee_reference import reference_apogee
from firmware_model.flights.readers import _matches, detect_format, read_flight
from firmware_model.flights.readers._common import read_text
from firmware_model.runtime.errors import UserError
from firmware_model.spec.atmosphere import altitude_m, pressure_pa
from tests.support.mutate import damaged
from tests.support.profiles import examples

SHARED = Path(os.environ.get("FWEMU_SHARED_FLIGHTS")
              or Path(__file__).resolve().parents[2].parent / "shared" / "flights")
needs_shared = pytest.mark.skipif(not SHARED.is_dir(), reason="../shared/flights is absent")
FS = SHARED / "fusionspace"
FT = 0.3048

#: The six files whose device apogee ../shared/flights/README.md states: (format, apogee in m AGL).
STATED: dict[str, tuple[str, float]] = {
    "perfectflite-pnut.pf2": ("perfectflite", 1009 * FT),
    "featherweight-raven-fip.csv": ("raven_fip", 1009 * FT),       # the same flight as the Pnut
    "blueraven-app-lr.csv": ("blueraven", 4034.98 * FT),           # the summary's Max Altitude
    "aim-xtra.csv": ("aim", 643.0),
    "altimetercloud-mercury.csv": ("altimetercloud", 784.2 * FT),
    "altusmetrum-telemetrum.csv": ("altosui", 9322 * FT),
}


# ------------------------------------------------------------------------------------------------ shared samples
@needs_shared
@pytest.mark.parametrize("name", sorted(STATED))
def test_reference_apogee_within_3_percent_of_the_device(name: str) -> None:
    path = FS / name
    fmt, stated = STATED[name]
    assert detect_format(path) == fmt
    rec = read_flight(path)
    ref = reference_apogee(rec)
    assert abs(ref.altitude_m - stated) <= 0.03 * stated, (ref.altitude_m, stated)


@needs_shared
def test_device_statements_become_own_computer_and_site() -> None:
    """The Pnut's preamble (Apogee 1009' AGL, Ground Elevation 2486' MSL) and the Blue Raven summary (Max Altitude
    4034.98 feet, Pad altitude ASL 230.55 feet) are carried as the log's own apogee and site."""
    pnut = read_flight(FS / "perfectflite-pnut.pf2")
    assert pnut.provenance["own_apogee_m"] == pytest.approx(1009 * FT)
    assert pnut.provenance["site_altitude_m"] == pytest.approx(2486 * FT)
    who, when = pnut.own_apogee()
    assert who == "PerfectFlite Pnut"
    # the first data row at 1009 ft (the file's rows, read here without the reader)
    rows = [ln.split(",") for ln in read_text(FS / "perfectflite-pnut.pf2").splitlines()[12:]]
    first = next(float(r[0]) for r in rows if int(r[1]) >= 1009)
    assert when == first
    # the synthetic barometer sits on the stated ground elevation: the pad row reads the atmosphere there
    assert pnut.pressure_pa[0] == pytest.approx(float(pressure_pa(2486 * FT)), rel=1e-12)
    br = read_flight(FS / "blueraven-app-lr.csv")
    assert br.provenance["own_apogee_m"] == pytest.approx(4034.98 * FT)
    assert br.provenance["site_altitude_m"] == pytest.approx(230.55 * FT)
    assert br.own_apogee()[0] == "Blue Raven"
    # the AIM's site: Pressure MSL - Pressure AGL on its first row (643.192 - 0.360229 m)
    assert read_flight(FS / "aim-xtra.csv").provenance["site_altitude_m"] == pytest.approx(643.192 - 0.360229)
    # the Mercury's axis: acceleration_z reads about -1000 mG on the pad, so -z is the rocket's axis (+1 g)
    merc = read_flight(FS / "altimetercloud-mercury.csv")
    pad = merc.time_s < -5.0
    assert np.nanmedian(merc.accel_mps2[pad]) == pytest.approx(9.80665, rel=0.05)
    assert np.nanmax(merc.accel_mps2) > 5 * 9.80665                  # the boost, on the same axis


@needs_shared
def test_fip_merge_invents_no_sample() -> None:
    """Every finite pressure of the record is a Baro (Atm) sample of the file at its own time (x 101325), every
    finite acceleration an Axial Accel sample; their counts are the channels' counts."""
    rec = read_flight(FS / "featherweight-raven-fip.csv")
    baro, acc = {}, {}
    for line in read_text(FS / "featherweight-raven-fip.csv").splitlines()[1:]:
        f = line.split(",")
        if f[0].strip():
            acc[float(f[0])] = float(f[1])
        if len(f) > 4 and f[3].strip():
            baro[float(f[3])] = float(f[4])
    ok = np.isfinite(rec.pressure_pa)
    assert ok.sum() == len(baro) == 310
    assert all(rec.pressure_pa[i] == baro[rec.time_s[i]] * 101325.0 for i in np.nonzero(ok)[0])
    oka = np.isfinite(rec.accel_mps2)
    assert oka.sum() == len(acc)
    assert rec.n == len(set(baro) | set(acc))


@needs_shared
def test_blueraven_pair_of_different_flights_is_not_joined() -> None:
    rec = read_flight(FS / "blueraven-app-lr.csv")
    assert rec.accel_mps2 is None
    assert any("NOT joined" in n and "another flight" in n for n in rec.provenance["notes"])


# ------------------------------------------------------------------------------------------------ synthetic files
def _pf2(n: int = 60, apogee: str = "300' AGL", ground: str = "1000' MSL", data: str | None = None) -> str:
    head = (f"PerfectFlite StratoLoggerCF\r\nFirmware: 1.3\r\nApogee: {apogee}\r\nGround Elevation: {ground}\r\n"
            f"NumSamps: {n}\r\nMax Drogue Current: 2.1 A\r\n\r\n")
    rows = data if data is not None else "".join(
        f"{i * 0.05:.2f}, {round(300 - 0.5 * (i - 40) ** 2 * 0.1875)}, 0, 70.10, 9.10\r\n" for i in range(n))
    return head + "Data: (Time, Altitude, Velocity, Temperature (F), Voltage)\r\n" + rows


def _bare(n: int = 60, sep: str = "\t", header: str = "") -> str:
    return header + "".join(f"{i * 0.05:.2f}{sep}{i * 3}{sep}70.1F{sep}9.1\n" for i in range(n))


def _fip(n: int = 40) -> str:
    head = "Time@Axial Accel (Gs),Axial Accel (Gs),bILBA,Time@Baro (Atm),Baro (Atm),bILBA\n"
    rows = []
    for i in range(n):
        baro = f"{i * 0.05 + 0.01:.4f},{1 - i * 1e-4:.5f},b{'1111' if i > 30 else '1100'}" if i < n // 2 + 10 else ","
        rows.append(f"{i * 0.0125:.5f},1.00,b0000,{baro}\n")
    return head + "".join(rows)


def _blue(n: int = 40, day: int = 11, hr: bool = False) -> str:
    if hr:
        head = "Year,Month,Day,Time,Flight_Time_(s),Sync,Gyro_X,Gyro_Y,Gyro_Z,Accel_X,Accel_Y,Accel_Z\n"
        return head + "".join(f"2024,5,{day},14:09:{44 + (i * 4) // 1000}.{(i * 4) % 1000:03d},{-1.0 + i * 0.004:.3f},"
                              f"{i},0,0,0,{-1.0 if i < 10 else -5.0:.2f},0.01,0.02\n" for i in range(n))
    head = ("Year,Month,Day,Time,Flight_Time_(s),Sync,Temperature_(F),Baro_Press_(atm),Baro_Altitude_AGL_(feet),"
            "Apogee\n")
    return head + "".join(f"2024,5,{day},14:09:{44 + i // 25}.{(i * 40) % 1000:03d},{-1 + i * 0.04:.2f},{i},86.0,"
                          f"{0.99 - i * 1e-4:.4f},{i},{1 if i >= 30 else 0}\n" for i in range(n))


def _aim(n: int = 40) -> str:
    head = "time,pressure,Pressure MSL,Pressure AGL,time,acceleration,time,launch detect,apogee detect\n"
    return head + "".join(f"{i * 0.2 - 2:.3f},{93833 - i * 5},{643 + i * 0.4:.2f},{i * 0.4:.2f},{i * 0.2 - 1.99:.3f},"
                          f"{1.02 if i < 10 else 5.0},{i * 0.2 - 1.98:.3f},{int(i >= 10)},{int(i >= 30)}\n"
                          for i in range(n))


def _mercury(n: int = 40) -> str:
    head = ("time(ms),altitude(m),velocity_pressure(m/s),acceleration_x(mG),acceleration_y(mG),acceleration_z(mG),"
            "acceleration_total(mG),bmp_temp(x100),\n")
    return head + "".join(f"{-5000 + i * 250},{i * 0.5:.3f},0.00,80,120,{-975 if i < 20 else -3000},-20.0,"
                          f"{'3505' if i % 5 == 0 else ''},\n" for i in range(n))


VALID: dict[str, tuple[str, str]] = {     # format -> (file name, text)
    "perfectflite": ("f.pf2", _pf2()),
    "raven_fip": ("f-fip.csv", _fip()),
    "blueraven": ("f-lr.csv", _blue()),
    "aim": ("f-aim.csv", _aim()),
    "altimetercloud": ("f-mercury.csv", _mercury()),
}


def _write(tmp: Path, name: str, text: str) -> Path:
    p = tmp / name
    p.write_text(text)
    return p


@pytest.mark.parametrize("fmt", sorted(VALID))
def test_valid_synthetic_files_read_and_detect(fmt: str, tmp_path: Path) -> None:
    name, text = VALID[fmt]
    p = _write(tmp_path, name, text)
    assert _matches(read_text(p)) == [fmt]
    rec = read_flight(p)
    assert rec.n >= 20 and np.all(np.diff(rec.time_s) > 0)


def test_perfectflite_variants(tmp_path: Path) -> None:
    """The .pf2 preamble (feet, F), the serial download's bare tab rows, a CSV header, and the preamble then a CSV
    header: the same altitudes in m, the stated apogee as the own computer's, metres when the preamble says m."""
    pf2 = read_flight(_write(tmp_path, "a.pf2", _pf2()))
    assert pf2.provenance["own_apogee_m"] == pytest.approx(300 * FT)
    assert pf2.own_apogee() == ("PerfectFlite StratoLoggerCF", 1.9)           # rows 38..42 round to 300 ft
    assert pf2.temperature_c[0] == pytest.approx((70.10 - 32) / 1.8)
    h = np.asarray(altitude_m(pf2.pressure_pa)) - float(altitude_m(pressure_pa(1000 * FT)))
    assert h[40] == pytest.approx(300 * FT, abs=1e-6)
    bare = read_flight(_write(tmp_path, "b.txt", _bare()))
    assert bare.provenance["format"] == "perfectflite" and bare.n == 60
    hb = np.asarray(altitude_m(bare.pressure_pa)) - float(altitude_m(pressure_pa(0.0)))
    assert hb[10] == pytest.approx(30 * FT, abs=1e-6)
    assert bare.temperature_c[0] == pytest.approx((70.1 - 32) / 1.8)
    comma = read_flight(_write(tmp_path, "c.csv", _bare(sep=",", header="time_s,altitude_ft,temperature,voltage\n")))
    assert np.array_equal(comma.pressure_pa, bare.pressure_pa)
    both = _pf2().split("Data:")[0] + "Time (s),Altitude (ft),Temperature (F),Voltage (V)\n" + _bare(sep=",")
    rb = read_flight(_write(tmp_path, "d.csv", both))
    assert rb.n == 60 and rb.provenance["own_apogee_m"] == pytest.approx(300 * FT)
    metres = read_flight(_write(tmp_path, "e.pf2", _pf2(apogee="91.4 m AGL", ground="304.8 m MSL")))
    assert metres.provenance["own_apogee_m"] == pytest.approx(91.4)
    assert metres.provenance["site_altitude_m"] == pytest.approx(304.8)
    hm = np.asarray(altitude_m(metres.pressure_pa)) - float(altitude_m(pressure_pa(304.8)))
    assert hm[40] == pytest.approx(300.0, abs=1e-6)          # the unitless Altitude column is in the preamble's m
    datacap = read_flight(_write(tmp_path, "g.csv", _bare(sep=",", header="Time,Altitude,Temperature,Voltage\n")))
    assert np.array_equal(datacap.pressure_pa, bare.pressure_pa)          # unitless altitude: PerfectFlite's feet
    noted = _pf2().replace("Firmware: 1.3", "Firmware: 1.3\r\nComments: first flight\r\non the new motor")
    assert read_flight(_write(tmp_path, "h.pf2", noted.split("\r\n", 1)[1])).n == 60   # no device line, a comment
    metre_csv = _bare(sep=",", header="time_s,altitude_m,temperature,voltage\n")
    assert _matches(metre_csv) == ["generic"]
    # a site altitude given on the command line wins over the stated ground elevation
    given_site = read_flight(_write(tmp_path, "f.pf2", _pf2()), site_altitude_m=10.0)
    assert given_site.provenance["site_altitude_m"] == 10.0


def test_rdas_rows_are_not_perfectflite(tmp_path: Path) -> None:
    """Whitespace rows of three numbers and an integer (RDAS) stay RDAS: the bare-row test wants a decimal voltage
    or an F/C temperature."""
    text = "".join(f"{i * 0.05:.2f} {i * 3} {500 + i} 0\n" for i in range(40))
    assert _matches(text) == ["rdas"]


def test_blueraven_same_flight_pair_is_joined(tmp_path: Path) -> None:
    low = _write(tmp_path, "x-lr.csv", _blue())
    _write(tmp_path, "x-hr.csv", _blue(n=450, hr=True))            # -1.0 .. 0.796 s, past the peak at 0.56 s
    rec = read_flight(low)
    assert rec.accel_mps2 is not None
    ok = np.isfinite(rec.accel_mps2)
    assert ok.sum() == 450 and np.isfinite(rec.pressure_pa).sum() == 40
    assert rec.n == len(set(np.round(np.arange(40) * 0.04 - 1, 3)) | set(np.round(np.arange(450) * 0.004 - 1, 3)))
    # axis: Accel_X reads -1 g on the pad -> the rocket's axis is -X: +1 g, then +5 g
    assert rec.accel_mps2[ok][0] == pytest.approx(9.80665) and rec.accel_mps2[ok][-1] == pytest.approx(5 * 9.80665)
    assert read_flight(tmp_path / "x-hr.csv").n == rec.n          # the high-rate file reads its low-rate partner
    _write(tmp_path, "x-hr.csv", _blue(n=100, hr=True))            # ends at -0.6 s, before the peak: refused
    short = read_flight(low)
    assert short.accel_mps2 is None and any("accelerometer REFUSED" in n for n in short.provenance["notes"])
    _write(tmp_path, "x-hr.csv", _blue(n=450, hr=True, day=12))
    assert read_flight(low).accel_mps2 is None
    with pytest.raises(UserError, match=r"x-hr.csv:2: this high-rate file is another flight"):
        read_flight(tmp_path / "x-hr.csv")


def test_aim_out_of_order_row_is_put_in_order_and_named(tmp_path: Path) -> None:
    lines = _aim().splitlines(keepends=True)
    moved = lines[:20] + lines[21:] + [lines[20]]
    p = _write(tmp_path, "g.csv", "".join(moved))
    rec = read_flight(p)
    assert np.all(np.diff(rec.time_s) > 0)
    assert any(n.startswith("line 41: time 1.8 s after") for n in rec.provenance["notes"])
    twice = lines + [lines[20]]
    with pytest.raises(UserError, match=rf"^{tmp_path}/h.csv:42: time does not increase"):
        read_flight(_write(tmp_path, "h.csv", "".join(twice)))


#: (format, line to replace (1-based), replacement, message): a truncated record, a bad number, an unknown unit.
BREAKS: list[tuple[str, int, str, str]] = [
    ("perfectflite", 3, "Apogee: 300 yd AGL", "Apogee: unknown unit 'yd'"),
    ("perfectflite", 12, "0.20, 12, 0", "3 fields, the columns"),
    ("perfectflite", 8, "Data: (Time, Altitude (yd), Velocity, Temperature (F), Voltage)",
     "Altitude (yd): unknown unit 'yd'"),
    ("perfectflite", 12, "0.20, 1x2, 0, 70.10, 9.10", "Altitude: cannot parse '1x2'"),
    ("raven_fip", 1, "Time@Axial Accel (Gs),Axial Accel (Gs),bILBA,Time@Baro (mmHg),Baro (mmHg),bILBA",
     "Baro (mmHg): unknown unit 'mmhg'"),
    ("raven_fip", 5, "0.0375,1.00,b0000,0.16", "Baro (Atm): row ends after the time"),
    ("raven_fip", 5, "0.0375,1.00,b0000,0.16,zz,b1100", "Baro (Atm): cannot parse 'zz'"),
    ("blueraven", 1, "Year,Month,Day,Time,Flight_Time_(s),Sync,Temperature_(F),Baro_Press_(bar),"
                     "Baro_Altitude_AGL_(feet),Apogee", "Baro_Press_(bar): unknown unit 'bar'"),
    ("blueraven", 6, "2024,5,11,14:09:44.160,0.16", "5 fields, the header"),
    ("aim", 6, "-1.200,938.33,643.00,0.00,-1.190,1.02,-1.180,0,0", "pressure 938.33: not a pressure in Pa"),
    ("aim", 6, "-1.000,93833", "2 fields, the header"),
    ("altimetercloud", 1, "time(ms),altitude(yd),velocity_pressure(m/s),acceleration_x(mG),acceleration_y(mG),"
                          "acceleration_z(mG),acceleration_total(mG),bmp_temp(x100),", "altitude(yd): unknown unit"),
    ("altimetercloud", 6, "-3750,1.0", "2 fields, the header"),
]


@pytest.mark.parametrize("fmt,line,repl,msg", BREAKS)
def test_each_kind_of_bad_file_names_its_line(fmt: str, line: int, repl: str, msg: str, tmp_path: Path) -> None:
    name, text = VALID[fmt]
    lines = text.splitlines()
    lines[line - 1] = repl
    p = _write(tmp_path, name, "\n".join(lines) + "\n")
    with pytest.raises(UserError) as exc:
        read_flight(p, format=fmt)
    assert str(exc.value).startswith(f"{p}:{line}: ") and msg in str(exc.value), str(exc.value)


@pytest.mark.parametrize("fmt,text", [
    ("perfectflite", _pf2(data="")),
    ("raven_fip", _fip().splitlines(keepends=True)[0]),
    ("blueraven", _blue().splitlines(keepends=True)[0]),
    ("aim", _aim().splitlines(keepends=True)[0]),
    ("altimetercloud", _mercury().splitlines(keepends=True)[0]),
])
def test_a_preamble_or_header_with_no_data_is_one_error(fmt: str, text: str, tmp_path: Path) -> None:
    p = _write(tmp_path, VALID[fmt][0], text)
    with pytest.raises(UserError, match=rf"^{p}:\d+: "):
        read_flight(p, format=fmt)


def test_cli_bad_file_exits_2_and_writes_nothing(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    p = _write(tmp_path, "bad.pf2", _pf2(apogee="300 yd AGL"))
    out = tmp_path / "ev"
    assert main(["evaluate", str(p), "--methods", "kalman_baro", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{p}:3: Apogee: unknown unit 'yd'" in err and "Traceback" not in err
    assert not out.exists() and sorted(x.name for x in tmp_path.iterdir()) == ["bad.pf2"]


@settings(max_examples=examples(60, ci=30), deadline=None)
@given(fmt=st.sampled_from(sorted(VALID)), data=st.data())
def test_fuzz_no_traceback(fmt: str, data: st.DataObject) -> None:
    """Any damage to a valid file of each new format is read or refused with one UserError naming the file."""
    name, text = VALID[fmt]
    text = damaged(data, text, ";,.-e\n x0G\t\"():'F", ";,.-0123456789eE\n naAfi:()")
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / name
        p.write_text(text)
        try:
            rec = read_flight(p, format=fmt)
        except UserError as exc:
            assert str(exc).startswith(str(p)), str(exc)
            assert "np.float64" not in str(exc)
            return
        assert rec.n >= 2 and np.all(np.diff(rec.time_s) > 0)


def test_fip_accelerometer_that_stops_in_the_ascent_is_refused(tmp_path: Path) -> None:
    """The synthetic FIP file's accelerometer ends at 0.49 s, its barometer falls to 1.46 s: the record has no
    accelerometer (holding its last value would feed 1 g to the rest of the flight) and says why."""
    rec = read_flight(_write(tmp_path, "f-fip.csv", _fip()))
    assert rec.accel_mps2 is None and rec.n == 30
    assert any(n.startswith("accelerometer REFUSED: its series covers 0..0.4875 s") for n in rec.provenance["notes"])

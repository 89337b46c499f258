"""Issue 32: AltOS .eeprom files of every family (log formats 1, 5..25), JSON and old text style.

Records are built here with AltOS's checksum rule (0x5a + the sum of all the record's bytes = 0 mod 256) and the
struct layouts of src/kernel/ao_log.h; expected values come from the MS5607 datasheet compensation
(``eeprom.ms5607_pressure``, checked on the datasheet's worked example in test_formats.py), the shared README's
TeleMetrum v1 ADC formula, and AltosUI's own CSV of the shared TeleMega flight, not from the decoder under test."""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware_model.cli.main import main
from firmware_model.flights.readers import _matches, altos_eeprom, read_flight
from firmware_model.flights.readers._common import read_text
from firmware_model.flights.readers.eeprom import ms5607_pressure
from firmware_model.runtime.errors import UserError
from firmware_model.spec.atmosphere import G0
from tests.support.mutate import damaged
from tests.support.profiles import examples

SHARED = Path(os.environ.get("FWEMU_SHARED_FLIGHTS")
              or Path(__file__).resolve().parents[2].parent / "shared" / "flights")
needs_shared = pytest.mark.skipif(not SHARED.is_dir(), reason="../shared/flights is absent")
COEF = dict(sens=46372, off=43981, tcs=29059, tco=27842, tref=31553, tempsens=28165)   # the datasheet's C1..C6


def rec(kind: str, tick: int, data: bytes, size: int) -> bytes:
    """One record: type, checksum, tick (LE), data padded to ``size``; checksum by AltOS's rule."""
    body = bytes([ord(kind), 0]) + (tick & 0xFFFF).to_bytes(2, "little") + data.ljust(size - 4, b"\0")
    assert len(body) == size
    return bytes([body[0], (-(0x5A + sum(body))) & 0xFF]) + body[2:]


def le(value: int, n: int) -> bytes:
    return (value & ((1 << (8 * n)) - 1)).to_bytes(n, "little")


def json_file(cfg: dict, records: list[bytes], per_line: int = 8) -> str:
    data = b"".join(records)
    hexes = [f"{b:02x}" for b in data]
    return json.dumps(cfg, indent=1) + "\n" + "\n".join(" ".join(hexes[i:i + per_line])
                                                        for i in range(0, len(hexes), per_line)) + "\n"


def _d1s(n: int) -> list[int]:
    return [6465444 - 900 * i for i in range(n)]          # pressure falling (the rocket climbs)


def mega_records(fmt: int, n: int = 30, flight: int = 3, tick0: int = 65000, ground: int = -31, step: int = -39
                 ) -> list[bytes]:
    size = 32
    out = [rec("F", tick0, le(flight, 2) + le(ground, 2) + le(101000, 4) + le(2048, 2) + le(5, 2) + le(-7, 2), size)]
    out.append(rec("S", tick0, le(2, 2), size))
    for i, d1 in enumerate(_d1s(n)):
        imu = le(2048, 2) * 3 + bytes(12)
        accel = ground + step * (i % 3)                     # pad, +1 g over pad, +2 g over pad (19.5 counts/g)
        out.append(rec("A", tick0 + 10 * i, le(d1, 4) + le(8077636, 4) + imu + le(accel, 2), size))
        if i == 20:
            out.append(rec("S", tick0 + 10 * i, le(6, 2), size))      # drogue = AltOS's apogee
    return out


def mini_records(n: int = 30, flight: int = 2) -> list[bytes]:
    out = [rec("F", 100, le(flight, 2) + le(0, 2) + le(101000, 4), 16)]
    for i, d1 in enumerate(_d1s(n)):
        out.append(rec("A", 100 + 10 * i, le(d1, 3) + le(8077636, 3) + le(100, 2) * 3, 16))
    return out


def full_records(pressures: list[float], flight: int = 5, ground: int = 15801) -> list[bytes]:
    """Format 1: ADC words from the shared README's formula raw = round((P/1000*0.009 - 0.095)*2047*16)."""
    out = [rec("F", 500, le(ground, 2) + le(flight, 2), 8)]
    for i, p in enumerate(pressures):
        adc = round((p / 1000 * 0.009 - 0.095) * 2047 * 16)
        out.append(rec("A", 500 + 10 * i, le(ground - 262 * (i % 2), 2) + le(adc, 2), 8))
    return out


PRESSURES = [101325.0 - 37.5 * i for i in range(30)]


# ------------------------------------------------------------------------------------------------ round trips
@pytest.mark.parametrize("fmt", [5, 10, 15, 16, 19, 21, 22, 24, 25])
def test_mega_family_round_trip(fmt: int, tmp_path: Path) -> None:
    p = tmp_path / "m.eeprom"
    cfg = {"log_format": fmt, "product": "TeleMega", "serial": 9, "ms5607": COEF, "accel_cal_plus": -32,
           "accel_cal_minus": 7}
    p.write_text(json_file(cfg, mega_records(fmt)))
    assert _matches(read_text(p)) == ["eeprom"]
    r = read_flight(p)
    want = [ms5607_pressure(d1, 8077636, COEF)[0] for d1 in _d1s(30)]
    assert r.pressure_pa.tolist() == want and want[0] == 110002
    assert r.temperature_c[0] == 20.0
    # ticks wrap past 65535 (tick0 65000): time keeps rising in 0.1 s steps
    assert np.allclose(np.diff(r.time_s), 0.1) and r.time_s[0] == 0.0
    f = r.specific_force_mps2()
    assert f[:3] == pytest.approx([G0, 3 * G0, 5 * G0])        # 19.5 counts/g, counts fall as the rocket pushes
    assert r.events["altos_apogee"] == pytest.approx(2.0) and r.own_apogee() == ("AltOS", pytest.approx(2.0))
    # (JSON format 19 is read by eeprom.py, which reports no IMU: the family decoder is asked directly)
    own = altos_eeprom.decode(p, altos_eeprom.parse(p, read_text(p)))
    assert np.array_equal(own.pressure_pa, r.pressure_pa) and np.array_equal(own.accel_counts, r.accel_counts)
    assert own.provenance["imu"]["pad_along_g"] == pytest.approx(2048 / altos_eeprom.FAMILIES[fmt].imu[3])


def test_accelerometer_mounted_the_other_way(tmp_path: Path) -> None:
    """A calibration whose -1 g reading is below its +1 g one (counts rise with the specific force): same forces."""
    p = tmp_path / "inv.eeprom"
    cfg = {"log_format": 16, "ms5607": COEF, "accel_cal_plus": 7, "accel_cal_minus": -32}
    p.write_text(json_file(cfg, mega_records(16, ground=8, step=39)))
    assert read_flight(p).specific_force_mps2()[:3] == pytest.approx([G0, 3 * G0, 5 * G0])


@pytest.mark.parametrize("fmt", [6, 8, 12, 14])
def test_mini_family_round_trip(fmt: int, tmp_path: Path) -> None:
    p = tmp_path / "e.eeprom"
    p.write_text(json_file({"log_format": fmt, "ms5607": COEF, "serial": 4}, mini_records(), per_line=16))
    r = read_flight(p)
    assert r.pressure_pa.tolist() == [ms5607_pressure(d1, 8077636, COEF)[0] for d1 in _d1s(30)]
    assert not r.has_accel and r.provenance["flight"] == 2


def test_metrum_family_through_the_new_decoder_equals_the_old(tmp_path: Path) -> None:
    recs = [rec("F", 7, le(1, 2) + le(-22, 2) + le(101000, 4), 16)] + [
        rec("A", 7 + 10 * i, le(d1, 4) + le(8077636, 4) + le(-22 - 19 * (i % 2), 2), 16)
        for i, d1 in enumerate(_d1s(30))]
    p = tmp_path / "t.eeprom"
    p.write_text(json_file({"log_format": 7, "ms5607": COEF, "accel_cal_plus": -22, "accel_cal_minus": 16}, recs))
    old = read_flight(p)
    new = altos_eeprom.decode(p, altos_eeprom.parse(p, read_text(p)))
    assert np.array_equal(old.pressure_pa, new.pressure_pa) and np.array_equal(old.accel_counts, new.accel_counts)
    assert old.accel_calibration == new.accel_calibration


@pytest.mark.parametrize("style", ["json", "text", "text-padded"])
def test_full_family_round_trip(style: str, tmp_path: Path) -> None:
    """Log format 1: the MP3H6115A word back through the README's formula is the word written; the accelerometer
    with the text header's calibration (+1g 15801, -1g 16325: 262 counts/g)."""
    recs = full_records(PRESSURES)
    p = tmp_path / f"v1-{style}.eeprom"
    if style == "json":
        p.write_text(json_file({"log_format": 1, "serial": 882, "accel_cal_plus": 15801, "accel_cal_minus": 16325},
                               recs))
    else:
        lines = ["Config version: 1.3", "Main deploy: 250 meters", "Accel cal +1g: 15801 -1g: 16325",
                 "serial-number 882", "product TeleMetrum-v1.2"]
        for r in recs:
            a, b = int.from_bytes(r[4:6], "little"), int.from_bytes(r[6:8], "little")
            fmt = "4x" if style == "text-padded" else "04x"      # %4x pads with spaces
            lines.append(f"{chr(r[0])} {int.from_bytes(r[2:4], 'little'):{fmt}} {a:{fmt}} {b:{fmt}}")
        p.write_text("\n".join(lines) + "\n")
    assert _matches(read_text(p)) == ["eeprom"]
    r = read_flight(p)
    adc = [round((x / 1000 * 0.009 - 0.095) * 2047 * 16) for x in PRESSURES]
    assert [round((x / 1000 * 0.009 - 0.095) * 2047 * 16) for x in r.pressure_pa] == adc
    assert np.max(np.abs(r.pressure_pa - PRESSURES)) < 0.5 / (0.009 * 2047 * 16) * 1000
    assert r.specific_force_mps2()[:2] == pytest.approx([G0, 2 * G0])
    assert r.provenance["flight"] == 5 and r.provenance["style"] == style.split("-")[0]
    assert r.provenance["raw_baro_adc"] == adc


def test_bad_checksum_is_counted_not_fatal(tmp_path: Path) -> None:
    recs = mega_records(22)
    broken = bytearray(recs[5])
    broken[10] ^= 0x40
    recs[5] = bytes(broken)
    p = tmp_path / "b.eeprom"
    p.write_text(json_file({"log_format": 22, "ms5607": COEF}, recs))
    r = read_flight(p)
    assert r.n == 29 and r.provenance["bad_records"] == 1
    assert any("1 records failing their checksum skipped (first at line" in n for n in r.provenance["notes"])


def test_several_flights_select_by_flight(tmp_path: Path) -> None:
    p = tmp_path / "s.eeprom"
    p.write_text(json_file({"log_format": 14, "ms5607": COEF}, mini_records(20, flight=1) + mini_records(25, 2)))
    assert read_flight(p).provenance["flight"] == 2 and read_flight(p).n == 25
    assert read_flight(p, flight=1).n == 20
    with pytest.raises(UserError, match=r"s.eeprom:\d+: flight 7 is not in this file \(flights \[1, 2\]\)"):
        read_flight(p, flight=7)


@settings(max_examples=examples(200, ci=60), deadline=None)
@given(d1=st.lists(st.integers(0, (1 << 24) - 1), min_size=1, max_size=20), d2=st.integers(0, (1 << 24) - 1),
       c=st.tuples(*[st.integers(0, 65535)] * 6), ms5611=st.booleans())
def test_vectorised_ms5607_equals_the_scalar_one(d1: list[int], d2: int, c: tuple[int, ...], ms5611: bool) -> None:
    """Any 24-bit words and 16-bit coefficients (cold, very cold and warm temperatures all drawn)."""
    coef = dict(zip(("sens", "off", "tcs", "tco", "tref", "tempsens"), c))
    p, t = altos_eeprom.ms5607_vec(np.array(d1), np.full(len(d1), d2), coef, ms5611)
    want = [ms5607_pressure(x, d2, coef, ms5611) for x in d1]
    assert p.tolist() == [w[0] for w in want] and t.tolist() == [w[1] for w in want]


# ------------------------------------------------------------------------------------------------ shared logs
@needs_shared
def test_new_decoder_on_the_shared_telemega_equals_altosui_csv() -> None:
    """The 32-byte family decoder (not the format-19 reader it extends) on flight 4 of the Piccard TeleMega: the
    pressure equals AltosUI's CSV of the same flight on every common sample; the IMU's pad reading is 1 g."""
    path = SHARED / "euroc21/piccard-telemega-serial-6733-flight-0004.eeprom"
    e = altos_eeprom.decode(path, altos_eeprom.parse(path, read_text(path)))
    c = read_flight(SHARED / "euroc21/piccard-telemega.csv")
    common, i, j = np.intersect1d(np.round(c.time_s, 2), np.round(e.time_s, 2), return_indices=True)
    assert common.size > 3800
    assert np.array_equal(c.pressure_pa[i], e.pressure_pa[j])
    assert np.max(np.abs(c.accel_mps2[i] - e.specific_force_mps2()[j])) <= 0.0051
    assert e.provenance["imu"]["pad_along_g"] == pytest.approx(1.0, abs=0.03)


# ------------------------------------------------------------------------------------------------ bad input
def _text_v1(extra: list[str] | None = None) -> list[str]:
    lines = ["Config version: 1.3", "Accel cal +1g: 15801 -1g: 16325"]
    for r in full_records(PRESSURES[:12]):
        lines.append(f"{chr(r[0])} {int.from_bytes(r[2:4], 'little'):04x} {int.from_bytes(r[4:6], 'little'):04x} "
                     f"{int.from_bytes(r[6:8], 'little'):04x}")
    return lines + (extra or [])


@pytest.mark.parametrize("name,text,line,msg", [
    ("truncated text record", "\n".join(_text_v1()[:8] + ["A 0046 3dd8"] + _text_v1()[9:]), 9,
     "record A: 1 fields, a log-format 1 record has 2 words"),
    ("truncated mega record", "\n".join(_text_v1()[:1]) + "\nlog-format 22\nA 0010 01 02 03\nA 0020 01 02\n", 3,
     "record A: 3 fields, a log-format 22 record has 28 bytes"),
    ("config and no records", "Config version: 1.3\nAccel cal +1g: 15801 -1g: 16325\n", 2,
     "a configuration with no records"),
    ("bad calibration line", "\n".join(_text_v1()[:1] + ["Accel cal +1g: 15801 -1g: x"] + _text_v1()[2:]), 2,
     "want 'Accel cal +1g: N -1g: N'"),
    ("unknown log format", "\n".join(_text_v1()[:2] + ["log-format 9"] + _text_v1()[2:]), 1,
     "log-format 9: not a flight log format"),
])
def test_bad_eeprom_files_name_their_line(name: str, text: str, line: int, msg: str, tmp_path: Path) -> None:
    p = tmp_path / "x.eeprom"
    p.write_text(text + "\n")
    with pytest.raises(UserError) as exc:
        read_flight(p, format="eeprom")
    assert str(exc.value).startswith(f"{p}:{line}: ") and msg in str(exc.value), str(exc.value)


def test_every_record_failing_its_checksum_is_one_error(tmp_path: Path) -> None:
    recs = [bytes([r[0], r[1] ^ 1]) + r[2:] for r in mini_records()]
    p = tmp_path / "c.eeprom"
    p.write_text(json_file({"log_format": 14, "ms5607": COEF}, recs))
    with pytest.raises(UserError, match=rf"^{p}:\d+: no flight record \('F'\) in the log"):
        read_flight(p)


def test_cli_bad_eeprom_exits_2_and_writes_nothing(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    p = tmp_path / "bad.eeprom"
    p.write_text("\n".join(_text_v1()[:8] + ["A 0046 3dd8"] + _text_v1()[9:]) + "\n")
    out = tmp_path / "ev"
    assert main(["evaluate", str(p), "--methods", "kalman_baro", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{p}:9: record A: 1 fields" in err and "Traceback" not in err
    assert sorted(x.name for x in tmp_path.iterdir()) == ["bad.eeprom"]


SEEDS = {
    "text": "\n".join(_text_v1()) + "\n",
    "json": json_file({"log_format": 22, "ms5607": COEF, "accel_cal_plus": -32, "accel_cal_minus": 7},
                      mega_records(22, n=12)),
}


@settings(max_examples=examples(60, ci=30), deadline=None)
@given(style=st.sampled_from(sorted(SEEDS)), data=st.data())
def test_fuzz_no_traceback(style: str, data: st.DataObject) -> None:
    """Damage to a valid text-style or JSON-style file is read or refused with one UserError naming the file."""
    text = SEEDS[style]
    text = damaged(data, text, "0f9 \nAFSz:{}\"", "0123456789abcdefAFS :\n-")
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "f.eeprom"
        p.write_text(text)
        try:
            rec_ = read_flight(p, format="eeprom")
        except UserError as exc:
            assert str(exc).startswith(str(p)), str(exc)
            return
        assert rec_.n >= 2 and np.all(np.diff(rec_.time_s) > 0)

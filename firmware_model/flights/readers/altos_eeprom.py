"""AltOS ``.eeprom`` files of every flight-computer family: the device's flash log as AltosUI saves it.
docs/flights.md, "AltOS .eeprom". Samples: ``../shared/flights/euroc21/piccard-telemega-serial-6733-flight-0004.eeprom``
(format 19), ``piccard-telemetrum-nosecone-serial-5877-flight-0002.eeprom`` (format 7); the other families are
checked on records built from AltOS's structs (tests/flights/test_altos_eeprom.py).

Facts taken from AltOS (GPL-2+; our own code): the record structs of ``src/kernel/ao_log.h`` (``struct
ao_log_record`` 8 bytes, ``struct ao_log_mega`` 32 bytes, ``struct ao_log_metrum`` and ``struct ao_log_mini``
16 bytes, the ``AO_LOG_FORMAT_*`` numbers), the decoding of ``altoslib/AltosEepromRecordFull.java``,
``AltosEepromRecordMega.java``, ``AltosEepromRecordMetrum.java``, ``AltosEepromRecordMini.java``, ``AltosIMU.java``
(IMU axes and counts per g), ``AltosConvert.barometer_to_pressure`` (TeleMetrum v1's MP3H6115A on the CC1111's
ADC) and the MS5607 datasheet's compensation (``AltosMs5607``); the old text style as ``ao-tools``' parser reads it
(``cc_mega_parse``: ``Config version: %d.%d``, ``Accel cal +1g: %d -1g: %d``, records ``T tick b0 b1 ...``).

**Records**: byte 0 the type (``F`` flight, ``A`` sensor, ``S`` state, ``T`` temperature/voltage, ``D``
deploy, GPS types ...), byte 1 a checksum chosen so that 0x5a + the sum of all the record's bytes = 0 (mod 256),
bytes 2-3 the tick (100 Hz, little-endian, wraps at 65536: a tick more than 1000 below the last one wrapped), then
the data, little-endian. All-0xff records are erased flash; a record failing its checksum is skipped and counted
(reported in the notes, not fatal).

=========  ====================================  ======  ==============================================
log_format family                               bytes   sensor record (offsets in the record)
=========  ====================================  ======  ==============================================
1          TeleMetrum v0.1/v1.x (``full``)       8       accel s16 @4, pres s16 @6 (12-bit ADC x 16)
5 .. 25    TeleMega / EasyMega (``mega``)        32      pres u32 @4, temp u32 @8 (MS5607 D1/D2), IMU
           (5, 10, 15, 16, 19, 21, 22, 24, 25)           accel s16 @12,14,16, gyro @18.., mag @24..,
                                                         high-g axial accel s16 @30
7          TeleMetrum v2/v3 (``metrum``)         16      pres u32 @4, temp u32 @8, accel s16 @12
6, 8,      EasyMini v1 / TeleMini v2 / TeleMini  16      pres u24 @4, temp u24 @7 (MS5607 D1/D2), no
12, 14     v3 / EasyMini v2 (``mini``)                   accelerometer
=========  ====================================  ======  ==============================================

``F`` records: full: ground accel s16 @4, flight u16 @6; the others: flight u16 @4, (mega, metrum) ground accel
s16 @6, ground pressure s32 @8. ``S``: state u16 @4 (0 startup .. 6 drogue = AltOS's apogee .. 8 landed).

**Sensors**: MS5607 (every family but 1): the datasheet's integer first- and second-order compensation with the
file's factory coefficients, integer Pa. Format 1: ``P = ((adc / 16) / 2047 + 0.095) / 0.009 * 1000`` Pa. The
axial accelerometer (full, metrum, mega high-g @30): ``counts_per_g = (accel_cal_minus - accel_cal_plus) / 2``,
counts fall as the specific force rises, the ``F`` record's ground accel is the pad's 1 g; format 1 without a
calibration takes AltosUI's default 2 g = 16294 - 15758 counts. The IMU's along axis (mega; reported in the notes as
its pad reading, the record's accelerometer stays the high-g one the firmware reads): format 5, 10 (MPU6000), 15
(MPU9250): ``accel_y``; 16 (MPU9250 rotated), 19 (BMX160): ``accel_x``; 21 (MPU6000), 22, 24, 25 (BMI088):
normalised along @12. Counts per g: 2048 (MPU6000/MPU9250 at +-16 g, BMX160 at +-16 g: AltosIMU), BMI088 1365
(Bosch datasheet at +-24 g; not confirmed in AltosIMU).

**File styles**: (a) a JSON object (``log_format``, ``serial``, ``product``, ``ms5607{...}``,
``accel_cal_plus/minus``) then the flash as hex bytes; (b) the old text style: ``Key: value`` config lines
(``Config version: 1.3``, ``Accel cal +1g: 15801 -1g: 16325``, ``serial-number 1234``, ``log-format 1``,
``ms5607 sens: 46372`` ...) then one record per line: the type letter, the tick in hex, then either two 16-bit hex
words (8-byte records: ``A 03e8 3d98 6ae0``, or space-padded ``A  3e8 3d98 6ae0``; a negative word may be written
as 8 hex digits, its low 16 bits kept) or the record's data bytes in hex (no checksum: AltosUI checked it when
it downloaded the log). No ``log-format`` line: two words per record means format 1.

A file holds one or more flights (each starts at an ``F`` record); ``flight=N`` picks one (default the last).
Log formats 7 and 19 in the JSON style are read by :mod:`.eeprom` (the reader this module extends), the others here.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from firmware_model.flights.readers import eeprom
from firmware_model.flights.readers._common import check_time, fail, licence_of, read_text
from firmware_model.flights.record import FlightRecord
from firmware_model.spec.atmosphere import G0


@dataclass(frozen=True)
class Family:
    """One record layout: ``size`` bytes, ``kind`` (full / mega / metrum / mini), the board, the high-g axial
    accelerometer's offset in an ``A`` record (None: none), the IMU (chip, along-axis offset, sign, counts per g)."""

    size: int
    kind: str
    board: str
    accel_at: int | None
    imu: tuple[str, int, int, float] | None = None


FAMILIES: dict[int, Family] = {
    1: Family(8, "full", "TeleMetrum v0.1/v1.x", 4),
    5: Family(32, "mega", "TeleMega v1/v2 (old flight record)", 30, ("MPU6000", 14, 1, 2048.0)),
    6: Family(16, "mini", "EasyMini v1", None),
    7: Family(16, "metrum", "TeleMetrum v2/v3", 12),
    8: Family(16, "mini", "TeleMini v2", None),
    10: Family(32, "mega", "TeleMega v1/v2", 30, ("MPU6000", 14, 1, 2048.0)),
    12: Family(16, "mini", "TeleMini v3", None),
    14: Family(16, "mini", "EasyMini v2", None),
    15: Family(32, "mega", "TeleMega v3", 30, ("MPU9250", 14, 1, 2048.0)),
    16: Family(32, "mega", "EasyMega v2", 30, ("MPU9250", 12, 1, 2048.0)),
    19: Family(32, "mega", "TeleMega v4", 30, ("BMX160", 12, 1, 2048.0)),
    21: Family(32, "mega", "TeleMega v5", 30, ("MPU6000", 12, 1, 2048.0)),
    22: Family(32, "mega", "TeleMega v6", 30, ("BMI088", 12, 1, 1365.0)),
    24: Family(32, "mega", "EasyMega v3", 30, ("BMI088", 12, 1, 1365.0)),
    25: Family(32, "mega", "TeleMega v7", 30, ("BMI088", 12, 1, 1365.0)),
}
#: AltosUI's default 2 g span for a format-1 log with no calibration (AltosEepromRecordFull.two_g_default).
TWO_G_DEFAULT: int = 16294 - 15758
_RECORD = re.compile(r"^([A-Za-z])\s+([0-9a-fA-F]{1,8})((?:\s+[0-9a-fA-F]+)+)\s*$")
_TEXT_KEYS = ("Config version:", "Accel cal", "serial-number", "log-format", "ms5607 ", "Main deploy:", "Pad ",
              "Apogee delay:", "Radio channel:", "Callsign:", "product", "manufacturer", "software-version")


def looks_like(text: str) -> bool:
    """A JSON-config .eeprom (a JSON object naming ``log_format``), or the old text style: a ``Config version:``
    line and typed hex record lines."""
    head = text.lstrip()[:20000]
    if head.startswith("{"):
        return '"log_format"' in head
    lines = [ln.strip() for ln in head.splitlines()[:400] if ln.strip()]
    return _text_config(head) and sum(bool(_RECORD.match(ln)) for ln in lines) >= 3


def _text_config(text: str) -> bool:
    return any(ln.strip().startswith("Config version:") for ln in text.splitlines()[:60])


def barometer_to_pressure(adc: np.ndarray) -> np.ndarray:
    """TeleMetrum v1 (MP3H6115A on the CC1111's 12-bit ADC, stored x16): Pa (AltosConvert.barometer_to_pressure)."""
    return ((np.asarray(adc, dtype=np.float64) / 16.0) / 2047.0 + 0.095) / 0.009 * 1000.0


def ms5607_vec(d1: np.ndarray, d2: np.ndarray, c: dict[str, int], ms5611: bool = False
               ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`.eeprom.ms5607_pressure` over arrays (int64: every intermediate stays below 2^59 for 24-bit words and
    16-bit coefficients; numpy's >> floors like Python's). Returns (pressure Pa, temperature 0.01 degC), int64."""
    d1 = np.asarray(d1, dtype=np.int64)
    d2 = np.asarray(d2, dtype=np.int64)
    dt = d2 - (int(c["tref"]) << 8)
    temp = 2000 + ((dt * int(c["tempsens"])) >> 23)
    if ms5611:
        off = (int(c["off"]) << 16) + ((int(c["tco"]) * dt) >> 7)
        sens = (int(c["sens"]) << 15) + ((int(c["tcs"]) * dt) >> 8)
    else:
        off = (int(c["off"]) << 17) + ((int(c["tco"]) * dt) >> 6)
        sens = (int(c["sens"]) << 16) + ((int(c["tcs"]) * dt) >> 7)
    low = temp < 2000
    tm = temp - 2000
    t2 = np.where(low, (dt * dt) >> 31, 0)
    off2 = np.where(low, (61 * tm * tm) >> 4, 0)
    sens2 = np.where(low, 2 * tm * tm, 0)
    vlow = temp < -1500
    tp = temp + 1500
    off2 = off2 + np.where(vlow, 15 * tp * tp, 0)
    sens2 = sens2 + np.where(vlow, 8 * tp * tp, 0)
    temp = temp - t2
    off = off - off2
    sens = sens - sens2
    return (((d1 * sens) >> 21) - off) >> 15, temp


# ------------------------------------------------------------------------------------------------ the file
@dataclass
class Parsed:
    """A file taken apart: config, log_format, the records (n, size) uint8, the file line of each, whether each
    passed its checksum (text style: True), notes."""

    config: dict
    log_format: int
    style: str
    recs: np.ndarray
    lines: np.ndarray
    good: np.ndarray
    notes: list[str]
    body_line: int


def _json_style(path: Path, text: str) -> Parsed:
    start = text.index("{")
    try:
        cfg, end = json.JSONDecoder().raw_decode(text, start)
    except json.JSONDecodeError as exc:
        raise fail(path, exc.lineno, f"the configuration is not valid JSON ({exc.msg})") from None
    if not isinstance(cfg, dict):
        raise fail(path, 1, "the configuration is not a JSON object")
    body_line = text[:end].count("\n") + 1
    fmt = cfg.get("log_format")
    if not isinstance(fmt, int) or fmt not in FAMILIES:
        raise fail(path, 1, f"log_format {fmt!r} ({cfg.get('product', '?')}): not a flight log format this reader "
                            f"knows ({', '.join(str(k) for k in sorted(FAMILIES))})")
    size = FAMILIES[fmt].size
    out, ends = eeprom.hex_bytes(path, text[end:], body_line)   # ends: cumulative byte count at each line's end
    first = body_line
    notes: list[str] = []
    n = len(out) // size
    if n == 0:
        raise fail(path, body_line, f"no {size}-byte records after the configuration")
    cut = len(out) - n * size
    ends_a = np.asarray(ends)
    if cut:
        at = first + int(np.searchsorted(ends_a, n * size, side="right"))
        notes.append(f"the last {cut} bytes (line {at}) are a record cut short: ignored")
    recs = np.frombuffer(bytes(out[: n * size]), dtype=np.uint8).reshape(n, size)
    lines = first + np.searchsorted(ends_a, np.arange(n) * size, side="right")
    empty = np.all(recs == 0xFF, axis=1)
    good = (((recs.sum(axis=1, dtype=np.int64) + 0x5A) & 0xFF) == 0) & ~empty
    bad = int(np.sum(~good & ~empty))
    if bad:
        notes.append(f"{bad} records failing their checksum skipped (first at line {int(lines[~good & ~empty][0])})")
    return Parsed(cfg, fmt, "json", recs, lines, good, notes, body_line)


def _text_style(path: Path, text: str) -> Parsed:  # noqa: C901 - one branch per record line kind of the text .eeprom, each checked with its own message
    cfg: dict = {}
    ms: dict[str, int] = {}
    rows: list[tuple[int, str, int, list[str]]] = []
    for number, raw in enumerate(text.splitlines(), start=1):
        s = raw.strip()
        if not s:
            continue
        m = _RECORD.match(s)
        if m and not s.startswith(_TEXT_KEYS):
            rows.append((number, m.group(1), int(m.group(2), 16), m.group(3).split()))
            continue
        if rows and len(s) >= 2 and s[0].isalpha() and s[1] == " " and not s.startswith(_TEXT_KEYS):
            raise fail(path, number, f"a damaged record line: {s[:40]!r}")
        if s.startswith("Accel cal"):
            m2 = re.match(r"^Accel cal \+1g:\s*(-?\d+)\s+-1g:\s*(-?\d+)", s)
            if not m2:
                raise fail(path, number, f"cannot read {s!r} (want 'Accel cal +1g: N -1g: N')")
            cfg["accel_cal_plus"], cfg["accel_cal_minus"] = int(m2.group(1)), int(m2.group(2))
        elif s.startswith("ms5607 "):
            m2 = re.match(r"^ms5607 (\w+):\s*(-?\d+)\s*$", s)
            if not m2:
                raise fail(path, number, f"cannot read {s!r} (want 'ms5607 NAME: N')")
            ms[m2.group(1)] = int(m2.group(2))
        elif s.startswith(("serial-number", "log-format")):
            key, _, value = s.partition(" ")
            try:
                cfg[key.replace("-number", "").replace("-", "_")] = int(value.strip())
            except ValueError:
                raise fail(path, number, f"{key}: {value.strip()!r} is not a number") from None
        elif s.startswith("Pad orientation:"):
            m2 = re.match(r"^Pad orientation:\s*(\d+)", s)
            if not m2:
                raise fail(path, number, f"cannot read {s!r} (want 'Pad orientation: N')")
            cfg["pad_orientation"] = int(m2.group(1))
        elif s.startswith(("product", "Config version:")):
            key, _, value = s.partition(":" if s.startswith("Config") else " ")
            cfg["config_version" if key.startswith("Config") else "product"] = value.strip()
    if ms:
        cfg["ms5607"] = ms
    if not rows:
        last = max((i for i, ln in enumerate(text.splitlines(), start=1) if ln.strip()), default=1)
        raise fail(path, last, "a configuration with no records")
    first = rows[0][3]
    words = len(first) == 2 and all(len(x) <= 8 for x in first)
    fmt = cfg.get("log_format", 1 if words else None)
    if fmt is None:
        raise fail(path, rows[0][0], "no log-format line, and the first record is not two 16-bit words (log format 1)")
    if fmt not in FAMILIES:
        raise fail(path, 1, f"log-format {fmt!r}: not a flight log format this reader knows "
                            f"({', '.join(str(k) for k in sorted(FAMILIES))})")
    cfg["log_format"] = fmt
    size = FAMILIES[fmt].size
    recs = np.zeros((len(rows), size), dtype=np.uint8)
    for i, (number, kind, tick, fields) in enumerate(rows):
        if size == 8 and len(fields) == 2 and all(len(x) <= 8 for x in fields):
            # 16-bit words, written %4x (space padded) or, for a negative one, as Java's 32-bit two's complement
            data = (int(fields[0], 16) & 0xFFFF).to_bytes(2, "little") + \
                (int(fields[1], 16) & 0xFFFF).to_bytes(2, "little")
        elif all(len(x) == 2 for x in fields) and len(fields) == size - 4:
            data = bytes(int(x, 16) for x in fields)
        else:
            raise fail(path, number, f"record {kind}: {len(fields)} fields, a log-format {fmt} record has "
                                     + ("2 words" if size == 8 else f"{size - 4} bytes"))
        body = bytes([ord(kind), 0]) + (tick & 0xFFFF).to_bytes(2, "little") + data
        recs[i] = np.frombuffer(bytes([body[0], (-(0x5A + sum(body))) & 0xFF]) + body[2:], dtype=np.uint8)
    notes = ["old text style: no checksums in the file (AltosUI checked them when it downloaded the log)"]
    return Parsed(cfg, fmt, "text", recs, np.asarray([r[0] for r in rows]), np.ones(len(rows), dtype=bool), notes,
                  rows[0][0])


def parse(path: Path, text: str) -> Parsed:
    """The file's configuration and records, in either style."""
    return _json_style(path, text) if text.lstrip().startswith("{") else _text_style(path, text)


# ------------------------------------------------------------------------------------------------ decoding
def _u16(r: np.ndarray, at: int) -> np.ndarray:
    return r[:, at].astype(np.int64) | (r[:, at + 1].astype(np.int64) << 8)


def _s16(r: np.ndarray, at: int) -> np.ndarray:
    v = _u16(r, at)
    return v - ((v >= 32768) << 16)


def _u24(r: np.ndarray, at: int) -> np.ndarray:
    return _u16(r, at) | (r[:, at + 2].astype(np.int64) << 16)


def _u32(r: np.ndarray, at: int) -> np.ndarray:
    return _u16(r, at) | (_u16(r, at + 2) << 16)


def decode(path: Path, p: Parsed, flight: int | None = None) -> FlightRecord:
    """One flight of a parsed file as a record (module docstring)."""
    fam = FAMILIES[p.log_format]
    cfg = p.config
    ok = np.nonzero(p.good)[0]
    types = p.recs[ok, 0]
    starts = ok[types == ord("F")]
    if starts.size == 0:
        raise fail(path, p.body_line, "no flight record ('F') in the log")
    fnum_at = 6 if fam.kind == "full" else 4
    numbers = [int(v) for v in _u16(p.recs[starts], fnum_at)]
    if flight is None:
        pick = len(numbers) - 1
    elif flight in numbers:
        pick = numbers.index(flight)
    else:
        raise fail(path, p.body_line, f"flight {flight} is not in this file (flights {numbers})")
    lo = starts[pick]
    hi = starts[pick + 1] if pick + 1 < starts.size else p.recs.shape[0]
    idx = ok[(ok >= lo) & (ok < hi)]
    r = p.recs[idx]
    raw_tick = _u16(r, 2)
    wraps = np.concatenate([[0], np.cumsum(raw_tick[1:] < raw_tick[:-1] - 1000)])
    t = (raw_tick + 65536 * wraps - raw_tick[0]) / 100.0
    f = r[0:1]
    ground_accel = int(_s16(f, 4)[0]) if fam.kind == "full" else int(_s16(f, 6)[0]) if fam.kind != "mini" else None
    ground_pres = None if fam.kind == "full" else int(_u32(f, 8)[0])
    if ground_pres is not None and ground_pres >= 1 << 31:
        ground_pres -= 1 << 32
    sensor = r[:, 0] == ord("A")
    rs = r[sensor]
    ts = t[sensor]
    lines = p.lines[idx][sensor]
    if rs.shape[0] < 2:
        raise fail(path, int(p.lines[lo]), f"flight {numbers[pick]} has {rs.shape[0]} sensor records")
    notes = [f"{fam.board} (log_format {p.log_format}), {cfg.get('product', '?')} serial {cfg.get('serial', '?')}, "
             f"flight {numbers[pick]}" + (f" of flights {numbers} in the file" if len(numbers) > 1 else "")] + p.notes
    prov: dict = {}
    if fam.kind == "full":
        adc = _u16(rs, 6)
        pa = barometer_to_pressure(adc)
        temp = None
        prov.update(baro_preset="telemetrum_v1", raw_baro_adc=adc.tolist())
        notes.append("pressure: the MP3H6115A's 16-bit ADC word, ((adc / 16) / 2047 + 0.095) / 0.009 kPa")
    else:
        coef = cfg.get("ms5607")
        need = ("sens", "off", "tcs", "tco", "tref", "tempsens")
        if not isinstance(coef, dict) or not all(isinstance(coef.get(k), int) for k in need):
            raise fail(path, 1, "the configuration has no MS5607 coefficients (ms5607: sens, off, tcs, tco, tref, "
                                "tempsens)")
        d1, d2 = (_u24(rs, 4), _u24(rs, 7)) if fam.kind == "mini" else (_u32(rs, 4), _u32(rs, 8))
        pi, ti = ms5607_vec(d1, d2, coef, bool(coef.get("ms5611", False)))
        pa = pi.astype(np.float64)
        temp = ti / 100.0
        prov.update(baro_preset="ms5607", baro_sensor_hint="pascal", raw_baro_d1=d1.tolist())
        notes.append("pressure: MS5607 integer compensation (first and second order) of the raw words with the "
                     "file's coefficients (integer Pa)")
    bad = np.nonzero(~((pa > 0) & (pa < 200000)))[0]
    if bad.size:
        i = int(bad[0])
        raise fail(path, int(lines[i]), f"sensor record at {ts[i]:g} s: pressure {pa[i]:.0f} Pa is not a barometer "
                                        "reading (0 .. 200000 Pa)")
    keep, repeats = check_time(path, [int(x) for x in lines], ts, drop_repeats=True)
    if repeats:
        notes.append(f"{repeats} sensor records on an already used tick dropped")
    events: dict[str, float] = {}
    for tt, s in zip(t[r[:, 0] == ord("S")], _u16(r[r[:, 0] == ord("S")], 4)):
        name = eeprom.STATES[s] if s < len(eeprom.STATES) else f"state{s}"
        events.setdefault(f"altos_{name}", float(tt))
    if "altos_drogue" in events:
        events["altos_apogee"] = events["altos_drogue"]
    acc = cal = None
    if fam.accel_at is not None:
        plus, minus = cfg.get("accel_cal_plus"), cfg.get("accel_cal_minus")
        if fam.kind == "full" and (plus is None or minus is None):
            plus, minus = ground_accel, ground_accel + TWO_G_DEFAULT
            notes.append(f"no accelerometer calibration: AltosUI's default 2 g = {TWO_G_DEFAULT} counts")
        if isinstance(plus, int) and isinstance(minus, int) and minus != plus:
            cpg = (minus - plus) / 2.0      # negative for a sensor mounted the other way: the sign carries it
            cpm = -cpg / G0
            cal = {"counts_per_mps2": cpm, "offset_counts": ground_accel - G0 * cpm}
            acc = _s16(rs, fam.accel_at).astype(np.float64)[keep]
            notes.append(f"accelerometer: {cpg:g} counts/g from the calibration, pad 1 g = the flight record's "
                         f"ground accel {ground_accel}")
        else:
            notes.append("no accelerometer calibration (accel_cal_plus/minus): record without accelerometer")
    if fam.imu is not None:
        chip, at, sign, cpg_imu = fam.imu
        pad_g = sign * int(_s16(f, 12)[0]) / cpg_imu
        prov["imu"] = {"chip": chip, "along_record_byte": at, "counts_per_g": cpg_imu, "pad_along_g": pad_g}
        notes.append(f"IMU {chip}: along axis at record byte {at}, {cpg_imu:g} counts/g; the flight record's pad "
                     f"average ground_accel_along reads {pad_g:.3f} g")
    if cfg.get("pad_orientation") not in (None, 0):
        notes.append(f"pad_orientation {cfg.get('pad_orientation')}: the accelerometer is mounted the other way up")
    licence, origin = licence_of(path)
    provenance = {"source": str(path), "format": "eeprom", "licence": licence, "origin": origin,
                  "rows": int(keep.sum()), "product": cfg.get("product"), "serial": cfg.get("serial"),
                  "log_format": p.log_format, "style": p.style, "flight": numbers[pick], "flights_in_file": numbers,
                  "ground_pressure_pa": ground_pres, "bad_records": int(np.sum(~p.good & ~np.all(p.recs == 0xFF,
                                                                                                   axis=1))),
                  **{k: (np.asarray(v)[keep].tolist() if k.startswith("raw_") else v) for k, v in prov.items()},
                  "notes": notes}
    return FlightRecord(name=path.stem, time_s=ts[keep], pressure_pa=pa[keep],
                        temperature_c=None if temp is None else temp[keep], accel_counts=acc, accel_calibration=cal,
                        events=events, provenance=provenance, row_lines=lines[keep])


def read(path: Path, flight: int | None = None) -> FlightRecord:
    """Read one flight of an AltOS .eeprom file of any family, either style."""
    text = read_text(path)
    if text.lstrip().startswith("{"):
        try:
            cfg, _ = json.JSONDecoder().raw_decode(text, text.index("{"))
        except json.JSONDecodeError:
            cfg = {}
        if isinstance(cfg, dict) and cfg.get("log_format") in eeprom.LAYOUTS:
            return eeprom.read(path, flight=flight)
    elif not (looks_like(text) or _text_config(text)):
        raise fail(path, 1, "not an AltOS .eeprom (no JSON configuration, no 'Config version:' text configuration)")
    return decode(path, parse(path, text), flight)


__all__ = ["FAMILIES", "Parsed", "barometer_to_pressure", "decode", "looks_like", "ms5607_vec", "parse", "read"]

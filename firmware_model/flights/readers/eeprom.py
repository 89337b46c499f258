"""AltOS ``.eeprom`` files: the flight computer's own flash log as AltosUI saves it (TeleMetrum v2/v3, TeleMega
v4), i.e. the raw sensor words the firmware read. Record layouts are taken from AltOS's documentation and
source (altoslib, GPL) as facts; this is our own code. docs/flights.md, "AltOS .eeprom".

* The file: a JSON object (the device's configuration: ``product``, ``serial``, ``log_format``, the MS5607's
  factory coefficients ``ms5607{sens, off, tcs, tco, tref, tempsens, ...}``, ``accel_cal_plus``/``_minus``, ...)
  then the flash contents as hex bytes, whitespace separated. (Older AltOS wrote a text config instead of JSON:
  refused with a message saying so.)
* Records of a fixed length per ``log_format``: **7** (TeleMetrum v2/v3) 16 bytes, **19** (TeleMega v4)
  32 bytes. Byte 0 the type (ASCII), byte 1 a checksum (0x5a + the sum of all the record's bytes = 0 mod 256),
  bytes 2-3 the tick (100 Hz, little-endian, wraps at 65536), then data, little-endian. Erased records (all 0xff)
  and records failing the checksum are skipped and counted.
* ``F`` flight: flight number (u16 @0), ground accel (s16 @2), ground pressure (s32 @4, Pa). It starts a flight;
  a file can hold several (``flight=N`` chooses; default the only one, or the last).
* ``S`` state: state (u16 @0): 0 startup, 1 idle, 2 pad, 3 boost, 4 fast, 5 coast, **6 drogue** (AltOS's
  apogee), 7 main, 8 landed, 9 invalid.
* ``A`` sensor: raw MS5607 pressure D1 (u32 @0) and temperature D2 (u32 @4); the high-g axial accelerometer
  (s16 @8 for format 7, @26 for format 19).
* Pressure: the MS5607 datasheet's integer compensation (first and second order) with the config's
  coefficients, as AltOS computes it on the device: an **integer** in Pa (what AltosUI writes as ``pressure``).
* Acceleration: counts; ``counts_per_g = (accel_cal_minus - accel_cal_plus) / 2``, counts fall as the rocket
  accelerates up, the flight record's ground accel is the pad's 1 g. Kept as ``accel_counts`` with that calibration.
* Time: (tick - the ``F`` record's tick) / 100 s, ticks unwrapped (AltOS: boost time = 0).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from firmware_model.spec.atmosphere import G0
from firmware_model.flights.readers._common import check_time, fail, licence_of, read_text
from firmware_model.flights.record import FlightRecord

#: log_format -> (record length, byte offset of the axial accelerometer in an 'A' record's data, name)
LAYOUTS: dict[int, tuple[int, int, str]] = {7: (16, 8, "TeleMetrum v2/v3"), 19: (32, 26, "TeleMega v4")}
STATES: tuple[str, ...] = ("startup", "idle", "pad", "boost", "fast", "coast", "drogue", "main", "landed",
                           "invalid", "stateless")
TICKS_PER_S: float = 100.0


def looks_like(text: str) -> bool:
    """True when the text starts with a JSON object naming ``log_format`` and hex bytes follow."""
    head = text.lstrip()[:20000]
    return head.startswith("{") and '"log_format"' in head and '"ms5607"' in head


def ms5607_pressure(d1: int, d2: int, c: dict[str, int], ms5611: bool = False) -> tuple[int, int]:
    """(pressure Pa, temperature 0.01 degC) from the raw words: the MS5607 datasheet's integer compensation,
    including the second-order terms below 20 degC (and -15 degC). Python integers: exact, no overflow."""
    dt = d2 - (c["tref"] << 8)
    temp = 2000 + ((dt * c["tempsens"]) >> 23)
    if ms5611:
        off = (c["off"] << 16) + ((c["tco"] * dt) >> 7)
        sens = (c["sens"] << 15) + ((c["tcs"] * dt) >> 8)
    else:
        off = (c["off"] << 17) + ((c["tco"] * dt) >> 6)
        sens = (c["sens"] << 16) + ((c["tcs"] * dt) >> 7)
    if temp < 2000:
        t2 = (dt * dt) >> 31
        tm = temp - 2000
        off2 = (61 * tm * tm) >> 4
        sens2 = 2 * tm * tm
        if temp < -1500:
            tp = temp + 1500
            off2 += 15 * tp * tp
            sens2 += 8 * tp * tp
        temp -= t2
        off -= off2
        sens -= sens2
    return (((d1 * sens) >> 21) - off) >> 15, temp


def _config(path: Path, text: str) -> tuple[dict, str, int]:
    start = text.index("{")
    try:
        cfg, end = json.JSONDecoder().raw_decode(text, start)
    except json.JSONDecodeError as exc:
        raise fail(path, exc.lineno, f"the configuration is not valid JSON ({exc.msg})") from None
    return cfg, text[end:], text[:end].count("\n") + 1


def hex_bytes(path: Path, body: str, first_line: int) -> tuple[bytes, list[int]]:
    """The bytes of the hex-byte lines of ``body`` (line ``first_line`` of ``path`` onwards) and the cumulative byte
    count at the end of each line (which record a line holds); a token that is not a hex byte is a ``file:line``
    error."""
    out = bytearray()
    ends: list[int] = []
    for number, line in enumerate(body.splitlines(), start=first_line):
        for tok in line.split():
            if len(tok) != 2:
                raise fail(path, number, f"{tok!r} is not a hex byte")
            try:
                out.append(int(tok, 16))
            except ValueError:
                raise fail(path, number, f"{tok!r} is not a hex byte") from None
        ends.append(len(out))
    return bytes(out), ends


def _bytes(path: Path, body: str, first_line: int) -> bytes:
    return hex_bytes(path, body, first_line)[0]


def _format_and_coefficients(path: Path, cfg: dict) -> tuple[str, dict]:
    """The log format (a key of :data:`LAYOUTS`) and the MS5607 coefficients of the configuration ``cfg``, or the
    error that names the one missing."""
    fmt = cfg.get("log_format")
    if fmt not in LAYOUTS:
        raise fail(path, 1, f"log_format {fmt!r} ({cfg.get('product', '?')}): only "
                            + ", ".join(f"{k} ({v[2]})" for k, v in LAYOUTS.items()) + " are read")
    coef = cfg.get("ms5607")
    need = ("sens", "off", "tcs", "tco", "tref", "tempsens")
    if not isinstance(coef, dict) or not all(isinstance(coef.get(k), int) for k in need):
        raise fail(path, 1, "the configuration has no MS5607 coefficients (ms5607: sens, off, tcs, tco, tref, "
                            "tempsens)")
    return fmt, coef


# The little-endian fields of a record's payload (from byte 4 on): ``at`` is the offset in the payload.
def _u16(r: np.ndarray, at: int) -> int:
    return int(r[4 + at]) | int(r[5 + at]) << 8


def _s16(r: np.ndarray, at: int) -> int:
    v = _u16(r, at)
    return v - 65536 if v >= 32768 else v


def _u32(r: np.ndarray, at: int) -> int:
    return _u16(r, at) | _u16(r, at + 2) << 16


def read(path: Path, flight: int | None = None) -> FlightRecord:
    """Read one flight of an AltOS .eeprom file."""
    text = read_text(path)
    if not text.lstrip().startswith("{"):
        raise fail(path, 1, "not a JSON-config AltOS .eeprom (older text-config .eeprom files are not read)")
    cfg, body, body_line = _config(path, text)
    fmt, coef = _format_and_coefficients(path, cfg)
    size, acc_at, kind = LAYOUTS[fmt]
    data = _bytes(path, body, body_line)
    usable = len(data) - len(data) % size
    if usable == 0:
        raise fail(path, body_line, f"no {size}-byte records after the configuration")
    recs = np.frombuffer(data[:usable], dtype=np.uint8).reshape(-1, size)
    empty = np.all(recs == 0xFF, axis=1)
    good = ((recs.sum(axis=1, dtype=np.int64) + 0x5A) & 0xFF) == 0
    bad_sum = int(np.sum(~empty & ~good))
    flights: list[list[int]] = []          # record indices per flight
    for i in np.nonzero(~empty & good)[0]:
        kind_byte = chr(recs[i, 0])
        if kind_byte == "F":
            flights.append([])
        if flights:
            flights[-1].append(int(i))
    if not flights:
        raise fail(path, body_line, "no flight record ('F') in the log")
    numbers = [int(recs[f[0], 4]) | int(recs[f[0], 5]) << 8 for f in flights]
    if flight is None:
        pick = len(flights) - 1
    elif flight in numbers:
        pick = numbers.index(flight)
    else:
        raise fail(path, body_line, f"flight {flight} is not in this file (flights {numbers})")
    idx = flights[pick]
    u16, s16, u32 = _u16, _s16, _u32
    f = recs[idx[0]]
    ground_accel = s16(f, 2)
    ground_pres = u32(f, 4)
    ground_pres = ground_pres - (1 << 32) if ground_pres >= 1 << 31 else ground_pres
    tick0 = u16(f, -2)          # the header's tick: bytes 2-3
    prev = tick0
    wide = 0
    t_list, p_list, a_list, temp_list, raw_list, line_list = [], [], [], [], [], []
    events: dict[str, float] = {}
    ms5611 = bool(coef.get("ms5611", False))
    for i in idx:
        r = recs[i]
        tick = int(r[2]) | int(r[3]) << 8
        while tick + wide < prev - 1000:     # AltOS's unwrapping: a tick far below the last one wrapped
            wide += 65536
        tick += wide
        prev = tick
        t = (tick - tick0) / TICKS_PER_S
        c = chr(r[0])
        if c == "A":
            d1, d2 = u32(r, 0), u32(r, 4)
            p, temp = ms5607_pressure(d1, d2, coef, ms5611)
            t_list.append(t)
            p_list.append(p)
            temp_list.append(temp / 100.0)
            raw_list.append(d1)
            a_list.append(s16(r, acc_at))
            line_list.append(i)
        elif c == "S":
            s = u16(r, 0)
            name = STATES[s] if s < len(STATES) else f"state{s}"
            events.setdefault(f"altos_{name}", t)
    if len(t_list) < 2:
        raise fail(path, body_line, f"flight {numbers[pick]} has {len(t_list)} sensor records")
    tt = np.asarray(t_list)
    # the file's line of each record: the hex dump has a fixed number of bytes per line
    per_line = len(body.splitlines()[1].split()) if len(body.splitlines()) > 1 else 32
    lines = [body_line + 1 + (i * size) // max(per_line, 1) for i in line_list]
    pa = np.asarray(p_list, dtype=np.float64)
    bad = np.nonzero(~((pa > 0) & (pa < 200000)))[0]
    if bad.size:
        i = int(bad[0])
        raise fail(path, lines[i], f"sensor record at {tt[i]:g} s: D1 {raw_list[i]}, compensated pressure "
                                   f"{p_list[i]} Pa is not a barometer reading (0 .. 200000 Pa)")
    keep, repeats = check_time(path, lines, tt, drop_repeats=True)
    notes = [f"{kind} (log_format {fmt}), {cfg.get('product', '?')} serial {cfg.get('serial', '?')}, "
             f"flight {numbers[pick]}" + (f" of flights {numbers} in the file" if len(numbers) > 1 else ""),
             "pressure: MS5607 integer compensation of the raw words with the file's coefficients (integer Pa)"]
    if bad_sum:
        notes.append(f"{bad_sum} records failing their checksum skipped")
    if repeats:
        notes.append(f"{repeats} sensor records on an already used tick dropped")
    if "altos_drogue" in events:
        events["altos_apogee"] = events["altos_drogue"]
    counts_per_g = (cfg.get("accel_cal_minus", 0) - cfg.get("accel_cal_plus", 0)) / 2.0
    cal = None
    acc = None
    if counts_per_g > 0:
        cpm = -counts_per_g / G0                  # counts fall as the specific force rises
        cal = {"counts_per_mps2": cpm, "offset_counts": ground_accel - G0 * cpm}
        acc = np.asarray(a_list, dtype=np.float64)[keep]
        notes.append(f"accelerometer: {counts_per_g:g} counts/g from accel_cal_plus/minus, pad 1 g = the flight "
                     f"record's ground accel {ground_accel}")
    else:
        notes.append("no accelerometer calibration (accel_cal_plus/minus): record without accelerometer")
    licence, origin = licence_of(path)
    provenance = {"source": str(path), "format": "eeprom", "licence": licence, "origin": origin,
                  "rows": int(keep.sum()), "product": cfg.get("product"), "serial": cfg.get("serial"),
                  "log_format": fmt, "flight": numbers[pick], "flights_in_file": numbers,
                  "ground_pressure_pa": ground_pres, "baro_sensor_hint": "pascal", "baro_preset": "ms5607",
                  "raw_baro_d1": np.asarray(raw_list, dtype=np.int64)[keep].tolist(), "notes": notes}
    return FlightRecord(name=path.stem, time_s=tt[keep], pressure_pa=pa[keep],
                        temperature_c=np.asarray(temp_list)[keep], accel_counts=acc, accel_calibration=cal,
                        events=events, provenance=provenance, row_lines=np.asarray(lines)[keep])

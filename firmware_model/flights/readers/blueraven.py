"""Featherweight Blue Raven, the phone app's CSV export: a low-rate file (barometer, derived values, flags), a
high-rate file (IMU) and a summary, written side by side. docs/flights.md, "Featherweight". Samples:
``../shared/flights/fusionspace/blueraven-app-lr.csv``, ``-hr.csv`` (another flight: not joined), ``.summary.csv``.

What the reader relies on (Featherweight's Blue Raven manual and app export; the shared samples):

* Low rate: ``Year,Month,Day,Time,Flight_Time_(s),Sync,Temperature_(F),Baro_Press_(atm),Baro_Altitude_ASL_(feet),
  Baro_Altitude_AGL_(feet),...,Liftoff,Apogee,...`` (more unnamed fields than names: ignored). ``Flight_Time_(s)``
  s from liftoff; ``Baro_Press_(atm)`` the barometer in atmospheres (x 101325 Pa); the first row with ``Apogee`` = 1
  is the Blue Raven's own apogee.
* High rate: ``Year,Month,Day,Time,Flight_Time_(s),Sync,Gyro_X..Z,Accel_X..Z,Quat_1..4,...``: accelerations in g.
  The rocket's axis: the one of X, Y, Z reading +-1 g before liftoff (sign so that the pad reads +1 g).
* Joining: reading the low-rate file takes the high-rate file beside it (the same name with ``-hr``/``_hr`` for
  ``-lr``/``_lr``) and reading the high-rate file takes the low-rate one, **when both carry the same date and their
  wall-clock times overlap**; the acceleration is placed on the union of the two files' sample times (no sample
  invented: NaN where a file has none), when the high-rate series lasts from the low-rate file's first half second
  to its barometric peak (else it is refused, as :mod:`.raven` refuses a series that stops in the ascent). Files of
  different flights are not joined (a note, or an error when the high-rate file is the one read: it has no
  barometer).
* Summary (``<name>.summary.csv`` beside): ``Max Altitude,4034.98 feet`` is the device's own apogee height
  (``provenance["own_apogee_m"]``) and ``Pad altitude ASL,230.55 feet`` the site altitude; its units must be
  ``feet`` or ``m`` (another is an error naming the line).
* Units are read from the column names: ``(atm)`` (also ``(Pa)``, ``(kPa)``, ``(hPa)``, ``(psi)``), ``(s)``, ``(feet)``;
  any other is an error naming the header line.
"""

from __future__ import annotations

import re
from datetime import datetime
from pathlib import Path

import numpy as np

from firmware_model.flights.readers import _channels as ch
from firmware_model.flights.readers._common import (Table, check_time, fail, gaps_note, header_fields, licence_of,
                                                    read_text)
from firmware_model.flights.record import FlightRecord
from firmware_model.runtime.errors import UserError
from firmware_model.spec.atmosphere import G0

FT: float = 0.3048
_BARO = re.compile(r"^Baro_Press_\((.*)\)$")


def _kind(text: str) -> str | None:
    head = header_fields(text, ",")
    if head[:6] != ["Year", "Month", "Day", "Time", "Flight_Time_(s)", "Sync"]:
        return None
    if any(_BARO.match(h) for h in head):
        return "low"
    if {"Accel_X", "Accel_Y", "Accel_Z"} <= set(head):
        return "high"
    return None


def looks_like(text: str) -> bool:
    """A Blue Raven app export: ``Year,Month,Day,Time,Flight_Time_(s),Sync`` then a barometer (low rate) or
    ``Accel_X/Y/Z`` (high rate)."""
    return _kind(text) is not None


def companion_reason(text: str) -> str | None:
    first = text.lstrip().split("\n", 1)[0]
    if first.startswith("Rocket Name,") and "Max Altitude," in text:
        return "a Blue Raven flight summary (read the low-rate file beside it)"
    return None


def _partner(path: Path, kind: str) -> Path | None:
    a, b = ("lr", "hr") if kind == "low" else ("hr", "lr")
    for sep in ("-", "_"):
        if f"{sep}{a}" in path.stem:
            cand = path.with_name(path.stem[::-1].replace(f"{sep}{a}"[::-1], f"{sep}{b}"[::-1], 1)[::-1]
                                  + path.suffix)
            if cand.is_file():
                return cand
    return None


def _clock(table: Table, i: int) -> datetime:
    row = dict(zip(table.header, table.rows[i][1]))
    try:
        hh, mm, ss = row["Time"].strip().split(":")
        sec = float(ss)
        return datetime(int(row["Year"]), int(row["Month"]), int(row["Day"]), int(hh), int(mm), int(sec),
                        int(round((sec - int(sec)) * 1e6)) % 1000000)
    except (ValueError, KeyError):
        raise UserError(f"{table.path}:{table.rows[i][0]}: Year/Month/Day/Time {row.get('Year')}/{row.get('Month')}/"
                        f"{row.get('Day')} {row.get('Time')!r} is not a date and time") from None


def _summary(path: Path) -> tuple[dict[str, float], Path | None]:
    stem = re.sub(r"[-_](lr|hr)$", "", path.stem)
    s = path.with_name(stem + ".summary.csv")
    if not s.is_file():
        return {}, None
    out: dict[str, float] = {}
    for number, line in enumerate(read_text(s).splitlines(), start=1):
        key, _, value = line.partition(",")
        if key.strip() in ("Max Altitude", "Pad altitude ASL"):
            m = re.match(r"^\s*([-+]?\d+(?:\.\d*)?)\s*(\S*)\s*$", value)
            if not m:
                raise UserError(f"{s}:{number}: {key}: cannot read {value!r} as a height")
            unit = m.group(2).lower()
            if unit not in ("feet", "ft", "m"):
                raise UserError(f"{s}:{number}: {key}: unknown unit {m.group(2)!r} (know feet, m)")
            out[key.strip()] = float(m.group(1)) * (1.0 if unit == "m" else FT)
    return out, s


def _high(table: Table) -> tuple[np.ndarray, np.ndarray, str]:
    """The high-rate file: (time s, axial specific force m/s^2, note). The pad: the rows before the acceleration's
    magnitude first passes 2 g."""
    path = table.path
    t = table.floats("Flight_Time_(s)")
    check_time(path, table.lines, t, drop_repeats=False)
    vals = {k: table.floats(k, allow_empty=True) for k in ("Accel_X", "Accel_Y", "Accel_Z")}
    total = np.sqrt(sum(np.nan_to_num(v) ** 2 for v in vals.values()))
    moving = np.nonzero(total > 2.0)[0]
    pad = np.arange(t.size) < (int(moving[0]) if moving.size else t.size)
    if pad.sum() < 3:
        raise fail(path, table.lines[0], f"{int(pad.sum())} rows before the acceleration passes 2 g: cannot tell the "
                                         "rocket's axis from the pad")
    name, sign = ch.pad_axis(path, table.lines[0], {k: v[pad] for k, v in vals.items()})
    return t, sign * vals[name] * G0, f"accelerometer: {'-' if sign < 0 else '+'}{name} (1 g on the pad)"


def read(path: Path) -> FlightRecord:
    """Read a Blue Raven app export (the low-rate file, joined with its high-rate file when it is the same flight)."""
    text = read_text(path)
    kind = _kind(text)
    if kind is None:
        raise fail(path, 1, "not a Blue Raven app export (Year,Month,Day,Time,Flight_Time_(s),Sync,...)")
    low_path, high_path = (path, _partner(path, "low")) if kind == "low" else (_partner(path, "high"), path)
    if low_path is None:
        raise fail(path, 1, "a Blue Raven high-rate file has no barometer, and no low-rate file (-lr) is beside it")
    low_text = text if low_path == path else read_text(low_path)
    if _kind(low_text) != "low":
        raise fail(low_path, 1, "not a Blue Raven low-rate file")
    table = Table(low_path, low_text, ",", min_rows=2, allow_duplicates=True)
    hl = table.header_line
    bcol = next(h for h in table.header if _BARO.match(h))
    unit = _BARO.match(bcol).group(1).lower()        # type: ignore[union-attr]  # bcol was picked because it matches
    if unit not in ch.PRESSURE_UNITS:
        raise fail(low_path, hl, f"{bcol}: unknown unit {unit!r} (know {', '.join(ch.PRESSURE_UNITS)})")
    t = table.floats("Flight_Time_(s)")
    lines = table.lines
    check_time(low_path, lines, t, drop_repeats=False)
    p = table.floats(bcol) * ch.PRESSURE_UNITS[unit]
    bad = np.nonzero(~(p > 0))[0]
    if bad.size:
        raise fail(low_path, lines[int(bad[0])], f"{bcol}: {table.rows[int(bad[0])][1][table.index(bcol)].strip()} "
                                                 "is not a positive pressure")
    notes = list(table.notes)
    temp = None
    if "Temperature_(F)" in table.header:
        temp = (table.floats("Temperature_(F)", allow_empty=True) - 32.0) / 1.8
    axis, acc, row_lines = t, None, np.asarray(lines)
    if high_path is not None:
        htable = Table(high_path, read_text(high_path), ",", min_rows=2)
        lo0, lo1, hi0, hi1 = _clock(table, 0), _clock(table, len(lines) - 1), _clock(htable, 0), \
            _clock(htable, len(htable.rows) - 1)
        same = lo0.date() == hi0.date() and hi0 <= lo1 and lo0 <= hi1
        if not same and kind == "high":
            raise fail(path, htable.rows[0][0], f"this high-rate file is another flight ({hi0:%Y-%m-%d %H:%M:%S}) than "
                                               f"the low-rate file beside it ({low_path.name}, "
                                               f"{lo0:%Y-%m-%d %H:%M:%S}): nothing to join it with")
        if not same:
            notes.append(f"NOT joined with {high_path.name}: it is another flight ({hi0:%Y-%m-%d %H:%M:%S} .. "
                         f"{hi1:%H:%M:%S}, this file {lo0:%Y-%m-%d %H:%M:%S} .. {lo1:%H:%M:%S}): record without "
                         "accelerometer")
        else:
            th, fh, how = _high(htable)
            why = ch.refusal(th, t, p)
            if why is not None:
                notes.append(f"{high_path.name}: {why}")
            else:
                axis = ch.merge(t, th)
                acc = ch.place(axis, th, fh)
                temp = None if temp is None else ch.place(axis, t, temp)
                row_lines = ch.place_lines(axis, [(t, lines), (th, htable.lines)])
                notes.append(f"joined with {high_path.name}: {th.size} high-rate samples, {how}; merged on "
                             f"{axis.size} sample times, each NaN where it has no sample")
                p = ch.place(axis, t, p)
    else:
        notes.append("no high-rate file beside it: record without accelerometer")
    events: dict[str, float] = {}
    if "Apogee" in table.header:
        hit = np.nonzero(table.floats("Apogee", allow_empty=True) == 1)[0]
        if hit.size:
            events["own_apogee"] = events["blueraven_apogee"] = float(t[hit[0]])
    summary, spath = _summary(low_path)
    extra: dict[str, float | str] = {}
    if "Max Altitude" in summary:
        extra["own_apogee_m"] = summary["Max Altitude"]
    if "Pad altitude ASL" in summary:
        extra["site_altitude_m"] = summary["Pad altitude ASL"]
    if spath is not None:
        extra["summary"] = str(spath)
    notes += gaps_note(t, lines)
    licence, origin = licence_of(low_path)
    provenance = {"source": str(low_path), "format": "blueraven", "licence": licence, "origin": origin,
                  "rows": int(axis.size), "own_computer": "Blue Raven", "synthetic_baro": False, **extra,
                  "notes": notes}
    return FlightRecord(name=low_path.stem, time_s=axis, pressure_pa=p, accel_mps2=acc, temperature_c=temp,
                        events=events, provenance=provenance, row_lines=row_lines)


__all__ = ["companion_reason", "looks_like", "read"]

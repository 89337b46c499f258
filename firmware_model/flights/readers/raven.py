"""Featherweight Raven exports (FIPa "export to CSV"): several series side by side, each with its own time column.

What the reader relies on (docs/flights.md, "Raven"):

* Header ``Time-Axial Accel (Gs), Axial Accel (Gs), bILBA, Time (s), Altitude (Ft-AGL), bILBA`` (the shared
  NDRT 2020 export): two series, each ``time, value, flags``. The acceleration series runs at 400 Hz, the
  altitude series at 20 Hz; a column pair ends where its series ends (empty fields after), rows are not common
  sample times.
* ``Axial Accel (Gs)``: axial specific force in g (+1 on the pad). ``Altitude (Ft-AGL)``: the Raven's barometric
  altitude in feet above the pad; its pressure is not exported.
* ``bILBA``: ``b`` and four 0/1 flags; by the order in which they set on the shared log (the 4th at the altitude
  peak) they read I(nflight?), L(aunch), B(urnout), A(pogee). The Raven's own apogee is the first row of the
  altitude series whose 4th flag is 1.
* The record's time axis is the altitude series (the barometer, the firmware's main input). **Synthetic
  barometer**: pressure = standard atmosphere at altitude x 0.3048 + site altitude (given, else sea level).
* Accelerometer: interpolated onto that axis **only** when its series covers the altitude series' flight; on the
  shared log it stops at 4.55 s of 90.9 s, so it is **refused** (the record has no accelerometer) and the notes say
  why: holding the last value would feed the firmware -0.7 g for the rest of the flight.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from firmware_model.spec.atmosphere import G0
from firmware_model.flights.readers._common import (Table, check_time, fail, gaps_note, header_fields,
                                                    check_altitude, licence_of, parse_float, read_text,
                                                    synthetic_pressure)
from firmware_model.flights.record import FlightRecord

FT: float = 0.3048


def looks_like(text: str) -> bool:
    """True when the header names an ``Altitude (Ft-AGL)`` column and a ``Time`` column, Raven style."""
    head = header_fields(text, ",")
    return any(h.startswith("Altitude (Ft-AGL)") for h in head) and any(h.startswith("Time") for h in head) \
        and any(h == "bILBA" for h in head)


def _series(table: Table, time_col: int, value_col: int, flag_col: int | None, name: str
            ) -> tuple[np.ndarray, np.ndarray, list[str], list[int]]:
    """One series: rows until its time field is empty; rows after it must stay empty in its columns."""
    path = table.path
    t, v, flags, lines = [], [], [], []
    ended = None
    for num, fields in table.rows:
        ts = fields[time_col].strip()
        if not ts:
            if ended is None:
                ended = num
            continue
        if ended is not None:
            raise fail(path, num, f"{name}: a value after the series ended (empty time at line {ended})")
        t.append(parse_float(path, num, table.header[time_col], ts))
        v.append(parse_float(path, num, table.header[value_col], fields[value_col]))
        flags.append(fields[flag_col].strip() if flag_col is not None else "")
        lines.append(num)
    return np.asarray(t), np.asarray(v), flags, lines


def read(path: Path, site_altitude_m: float | None = None) -> FlightRecord:
    """Read a Raven export: the altitude series as the record (synthetic barometer), the accelerometer where it
    covers the flight."""
    text = read_text(path)
    if not looks_like(text):
        raise fail(path, 1, "not a Raven export (no 'Altitude (Ft-AGL)' / 'bILBA' columns)")
    table = Table(path, text, ",", min_rows=2, allow_duplicates=True)
    head = table.header
    alt_col = next(i for i, h in enumerate(head) if h.startswith("Altitude (Ft-AGL)"))
    if alt_col == 0 or not head[alt_col - 1].startswith("Time"):
        raise fail(path, table.header_line, "the altitude column has no time column before it")
    flag_col = alt_col + 1 if alt_col + 1 < len(head) and head[alt_col + 1] == "bILBA" else None
    t, alt_ft, flags, lines = _series(table, alt_col - 1, alt_col, flag_col, "altitude")
    check_time(path, lines, t, drop_repeats=False)
    notes = list(table.notes)
    check_altitude(path, lines, alt_ft * FT, "Altitude (Ft-AGL)", "ft", FT)
    p, how = synthetic_pressure(alt_ft * FT, site_altitude_m)
    notes.append(how)
    events: dict[str, float] = {}
    for i, f in enumerate(flags):
        if len(f) == 5 and f[0] == "b" and f[4] == "1":
            events["own_apogee"] = events["raven_apogee"] = float(t[i])
            break
    if "own_apogee" not in events:
        notes.append("no apogee flag (4th bILBA flag) set in the altitude series")
    accel = None
    acc_col = next((i for i, h in enumerate(head) if h.startswith("Axial Accel")), None)
    if acc_col is not None and acc_col > 0 and head[acc_col - 1].startswith("Time"):
        ta, g, _, alines = _series(table, acc_col - 1, acc_col, None, "acceleration")
        check_time(path, alines, ta, drop_repeats=False)
        rate = 1.0 / float(np.median(np.diff(ta)))
        end = events.get("own_apogee", float(t[-1]))
        if ta[0] <= t[0] + 0.5 and ta[-1] >= end:
            accel = np.interp(t, ta, g * G0, left=np.nan, right=np.nan)
            notes.append(f"accelerometer: {ta.size} samples at {rate:.0f} Hz, interpolated onto the altitude axis")
        else:
            notes.append(f"accelerometer REFUSED: its series ({ta.size} samples at {rate:.0f} Hz) covers "
                         f"{ta[0]:g}..{ta[-1]:g} s, the flight runs to {end:g} s (apogee) of {t[-1]:g} s")
    notes += gaps_note(t, lines)
    licence, origin = licence_of(path)
    provenance = {"source": str(path), "format": "raven", "licence": licence, "origin": origin, "rows": len(lines),
                  "own_computer": "Raven", "synthetic_baro": True, "notes": notes}
    return FlightRecord(name=path.stem, time_s=t, pressure_pa=p, accel_mps2=accel, events=events,
                        provenance=provenance, row_lines=np.asarray(lines))

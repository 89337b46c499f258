"""AltimeterCloud CSV (Rocketry Ltd Mercury and its siblings): unit-named columns, one row per sample.
docs/flights.md, "AltimeterCloud". Sample: ``../shared/flights/fusionspace/altimetercloud-mercury.csv``.

What the reader relies on (the AltimeterCloud export's column names, which carry their units; the shared sample):

* Header ``time(ms),altitude(m),velocity_pressure(m/s),acceleration_x(mG),acceleration_y(mG),acceleration_z(mG),
  acceleration_total(mG),gyro_x,gyro_y,gyro_z,bmp_temp(x100),...`` (each line ends with a comma).
* ``time(ms)``: ms, 0 = launch (negative on the pad). ``altitude(m)`` barometric altitude above the pad in m
  (``altitude(ft)`` in feet). Accelerations in mG (``(G)``/``(g)`` in g); the rocket's axis is the one of x, y, z
  reading +-1 g on the pad (its sign chosen so the pad reads +1 g), said in the notes. ``bmp_temp(x100)``: the
  barometer's temperature in 0.01 degC, empty on most rows (NaN there).
* Any other unit in ``time``/``altitude``/``acceleration`` names is an error naming the header line.
* **Synthetic barometer**: pressure = standard atmosphere at altitude + site altitude (``site_altitude_m`` given, else
  sea level); ``ground_pressure_pa`` that at the device's own zero.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from firmware_model.flights.readers import _channels as ch
from firmware_model.flights.readers._common import (Table, check_time, fail, gaps_note, header_fields, licence_of,
                                                    read_text, synthetic_pressure)
from firmware_model.flights.record import FlightRecord
from firmware_model.spec.atmosphere import G0, pressure_pa

TIME_UNITS: dict[str, float] = {"ms": 1e-3, "s": 1.0}
ALT_UNITS: dict[str, float] = {"m": 1.0, "ft": 0.3048}
ACC_UNITS: dict[str, float] = {"mg": 1e-3, "g": 1.0}
_UNIT = re.compile(r"^([a-z_]+)\((.*)\)$", re.I)


def _named(head: list[str]) -> dict[str, tuple[str, str]]:
    """base name -> (column as written, unit as written)."""
    out = {}
    for h in head:
        m = _UNIT.match(h.strip())
        if m:
            out[m.group(1).lower()] = (h, m.group(2))
    return out


def looks_like(text: str) -> bool:
    """A header with ``time(<unit>)``, ``altitude(<unit>)`` and ``acceleration_total(<unit>)`` columns."""
    named = _named(header_fields(text, ","))
    return {"time", "altitude", "acceleration_total"} <= set(named)


def _unit(path: Path, line: int, col: str, unit: str, units: dict[str, float]) -> float:
    if unit.lower() not in units:
        raise fail(path, line, f"{col}: unknown unit {unit!r} (know {', '.join(units)})")
    return units[unit.lower()]


def read(path: Path, site_altitude_m: float | None = None) -> FlightRecord:
    """Read an AltimeterCloud export (altitude: a synthetic barometer; the axis accelerometer)."""
    text = read_text(path)
    if not looks_like(text):
        raise fail(path, 1, "not an AltimeterCloud export (time(ms), altitude(m), acceleration_total(mG) columns)")
    table = Table(path, text, ",", min_rows=2)
    named = _named(table.header)
    hl = table.header_line
    tcol, tu = named["time"]
    acol, au = named["altitude"]
    t = table.floats(tcol) * _unit(path, hl, tcol, tu, TIME_UNITS)
    lines = table.lines
    check_time(path, lines, t, drop_repeats=False)
    alt = table.floats(acol, allow_empty=True) * _unit(path, hl, acol, au, ALT_UNITS)
    notes = list(table.notes)
    p, how = synthetic_pressure(alt, site_altitude_m)
    notes.append(how)
    acc = None
    axes = [k for k in ("acceleration_x", "acceleration_y", "acceleration_z") if k in named]
    if axes:
        vals = {}
        for k in axes:
            col, unit = named[k]
            vals[col] = table.floats(col, allow_empty=True) * _unit(path, hl, col, unit, ACC_UNITS)
        pad_rows = (t < 0) & np.any([np.abs(v) > 0 for v in vals.values()], axis=0)   # the first rows read 0 0 0
        if pad_rows.sum() >= 3:
            name, sign = ch.pad_axis(path, lines[0], {k: v[pad_rows] for k, v in vals.items()})
            acc = sign * vals[name] * G0
            notes.append(f"accelerometer: {'-' if sign < 0 else '+'}{name} (the axis at 1 g on the pad)")
        else:
            notes.append("accelerometer: too few pad rows to tell the rocket's axis: record without accelerometer")
    temp = None
    if "bmp_temp" in named:
        col, unit = named["bmp_temp"]
        if unit.lower() != "x100":
            raise fail(path, hl, f"{col}: unknown unit {unit!r} (know x100: 0.01 degC)")
        temp = table.floats(col, allow_empty=True) / 100.0
    notes += gaps_note(t, lines)
    licence, origin = licence_of(path)
    site = 0.0 if site_altitude_m is None else float(site_altitude_m)
    provenance = {"source": str(path), "format": "altimetercloud", "licence": licence, "origin": origin,
                  "rows": len(lines), "own_computer": "Mercury", "synthetic_baro": True, "site_altitude_m": site,
                  "notes": notes}
    return FlightRecord(name=path.stem, time_s=t, pressure_pa=p, accel_mps2=acc, temperature_c=temp,
                        ground_pressure_pa=float(pressure_pa(site)), events={}, provenance=provenance,
                        row_lines=np.asarray(lines))


__all__ = ["looks_like", "read"]

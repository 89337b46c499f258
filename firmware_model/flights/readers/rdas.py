"""RDAS text exports (AED Electronics RDAS; the data files of Schultz 2002 and Schultz n.d.).

No RDAS file is in ../shared/flights, so this reader follows what Schultz's programs read (Schultz 2002 Appendix A
``RDASfilter.c`` and Appendix B ``kapogee.c``: ``sscanf(buf, "%s %lf %lf %d")``) and documents every assumption
(docs/flights.md, "RDAS"):

* Free text first (the RDAS program's header), then data lines of whitespace-separated columns:
  ``time`` (s from first motion; the export starts ~2 s before, kapogee looks for ``-2.000``), ``acceleration``,
  ``pressure`` and optionally an integer ``digital`` (the RDAS event/IO bits, ignored). Once data starts, every
  non-blank line must be a data line.
* **raw** export (every acceleration and pressure value an integer in 0..1023): 10-bit ADC counts.
  Pressure: counts fall with pressure at 0.009/kPa of the 10-bit full scale (an MPX4115A-class sensor:
  0.0092 counts/Pa, 108.6 Pa = about 9 m = 30 ft per count at sea level, Schultz 2002's "1 count is about 30 feet");
  the export does not give the offset, so the pad (rows with time < 0, else the first 10 rows) is put at the
  standard sea-level pressure 101,325 Pa. Acceleration: counts, the pad mean is +1 g (Schultz 2002: "offset taken on
  the pad as 1 g"), scale **assumed** 1023 counts per 100 g (a +-50 g sensor); kept as ``accel_counts`` with that
  calibration so a user can replace it.
* **interpreted** export (otherwise): ``pressure`` is altitude in feet above the pad (Schultz n.d. plots it as
  "Altitude (feet)"), converted with the standard atmosphere from sea level; ``acceleration`` is ft/s^2 along the
  axis, re-based so the pad mean reads +1 g whatever offset the export used.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from firmware_model.flights.readers._common import check_time, fail, parse_float, read_text
from firmware_model.flights.record import FlightRecord
from firmware_model.spec.atmosphere import G0, P0_PA, pressure_pa

FT: float = 0.3048
#: Raw export: 10-bit ADC; pressure slope 0.009 of full scale per kPa (MPX4115A class); accelerometer +-50 g.
RAW_FULL: int = 1023
RAW_COUNTS_PER_PA: float = 0.009e-3 * RAW_FULL
RAW_ACCEL_COUNTS_PER_MPS2: float = RAW_FULL / (100.0 * G0)

_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_DATA = re.compile(rf"^\s*({_NUM})\s+({_NUM})\s+({_NUM})(?:\s+(-?\d+))?\s*$")


def looks_like(text: str) -> bool:
    """True when at least 10 lines are whitespace-separated data lines (3 or 4 numbers, no commas) and data lines
    are the majority of the non-blank lines."""
    lines = [l for l in text.splitlines()[:2000] if l.strip()]
    hits = sum(1 for l in lines if "," not in l and _DATA.match(l))
    return hits >= 10 and hits * 2 > len(lines)


def read(path: Path) -> FlightRecord:
    """Read an RDAS text export (raw or interpreted)."""
    text = read_text(path)
    header: list[str] = []
    t: list[float] = []
    a: list[float] = []
    p: list[float] = []
    line_of: list[int] = []
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        m = _DATA.match(line) if "," not in line else None
        if m is None:
            if line_of:
                raise fail(path, number,
                           f"not a data line (time acceleration pressure [digital]): {line.strip()[:60]!r}")
            header.append(line.strip())
            continue
        t.append(parse_float(path, number, "time", m.group(1)))
        a.append(parse_float(path, number, "acceleration", m.group(2)))
        p.append(parse_float(path, number, "pressure", m.group(3)))
        line_of.append(number)
    if not line_of:
        raise fail(path, max(1, len(text.splitlines())), "no data lines (time acceleration pressure [digital])")
    time = np.asarray(t)
    acc = np.asarray(a)
    pres = np.asarray(p)
    check_time(path, line_of, time, drop_repeats=False)
    pad = time < 0 if np.sum(time < 0) >= 3 else np.arange(time.shape[0]) < min(10, time.shape[0])
    raw = bool(np.all((acc == np.rint(acc)) & (acc >= 0) & (acc <= RAW_FULL)
                      & (pres == np.rint(pres)) & (pres >= 0) & (pres <= RAW_FULL)))
    notes: list[str] = []
    accel_counts = None
    accel_cal = None
    accel = None
    if raw:
        pad_counts = float(np.median(pres[pad]))
        pressure = P0_PA + (pres - pad_counts) / RAW_COUNTS_PER_PA
        accel_counts = acc
        accel_cal = {"counts_per_mps2": RAW_ACCEL_COUNTS_PER_MPS2,
                     "offset_counts": float(np.mean(acc[pad])) - G0 * RAW_ACCEL_COUNTS_PER_MPS2}
        notes += ["raw export: 10-bit counts", f"pressure slope {RAW_COUNTS_PER_PA:.6f} counts/Pa assumed, "
                  f"pad ({pad_counts:g} counts) put at {P0_PA:g} Pa",
                  "accelerometer scale assumed 1023 counts per 100 g, pad mean = +1 g"]
    else:
        pressure = np.asarray(pressure_pa(pres * FT), dtype=np.float64)
        accel = acc * FT - float(np.mean(acc[pad])) * FT + G0
        notes += ["interpreted export: altitude ft above the pad (standard atmosphere from sea level), "
                  "acceleration ft/s^2 re-based so the pad reads +1 g"]
    provenance = {"source": str(path), "format": "rdas", "export": "raw" if raw else "interpreted",
                  "licence": "unknown", "rows": len(line_of), "header_text": header[:20], "notes": notes}
    return FlightRecord(name=path.stem, time_s=time, pressure_pa=pressure, accel_mps2=accel,
                        accel_counts=accel_counts, accel_calibration=accel_cal, provenance=provenance)

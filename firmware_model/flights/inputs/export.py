"""Write a :class:`FlightRecord` as the generic flight CSV that :mod:`firmware_model.flights.readers.generic` reads
(``fwemu simulate``'s output; also how a real log becomes ``time_s,pressure_pa,accel_mps2`` for other tools).

Layout: ``# key: value`` comment lines (name, source, format, licence, ground_pressure_pa, true_apogee_time_s,
true_apogee_altitude_m), then the header ``time_s,pressure_pa[,accel_mps2][,temperature_c][,true_altitude_m,
true_velocity_mps,true_accel_mps2]`` and one row per sample. Values are written with enough digits to read back
the same float64 numbers to 1e-9 relative (``repr``-exact for time, 12 significant digits elsewhere). NaN is an
empty field.
"""

from __future__ import annotations

import io
import math
from typing import Any

import numpy as np

from firmware_model.flights.record import FlightRecord


def _num(x: float, digits: int = 12) -> str:
    x = float(x)
    if not math.isfinite(x):
        return ""
    return f"{x:.{digits}g}"


def generic_csv(record: FlightRecord, *, truth: bool = True, temperature: bool = True) -> str:
    """The generic-CSV text of ``record`` (truth columns when the record has them and ``truth``; temperature when
    it has one and ``temperature``)."""
    cols: list[tuple[str, Any]] = [("time_s", record.time_s), ("pressure_pa", record.pressure_pa)]
    force = record.specific_force_mps2()
    if force is not None:
        cols.append(("accel_mps2", force))
    if temperature and record.temperature_c is not None:
        cols.append(("temperature_c", record.temperature_c))
    tr = record.truth if truth else None
    if tr is not None:
        for name, arr in (("true_altitude_m", tr.altitude_m), ("true_velocity_mps", tr.velocity_mps),
                          ("true_accel_mps2", tr.accel_mps2)):
            if arr is not None:
                cols.append((name, arr))
    meta: dict[str, Any] = {"name": record.name}
    prov = record.provenance or {}
    for key in ("source", "format", "licence"):
        if prov.get(key) is not None:
            meta[key] = str(prov[key]).replace("\n", " ")
    if record.ground_pressure_pa is not None:
        meta["ground_pressure_pa"] = _num(record.ground_pressure_pa)
    if tr is not None and tr.apogee_time_s is not None:
        meta["true_apogee_time_s"] = repr(float(tr.apogee_time_s))
    if tr is not None and tr.apogee_altitude_m is not None:
        meta["true_apogee_altitude_m"] = _num(tr.apogee_altitude_m)
    out = io.StringIO()
    for key, value in meta.items():
        out.write(f"# {key}: {value}\n")
    out.write(",".join(name for name, _ in cols) + "\n")
    arrays = [np.asarray(a, dtype=np.float64) for _, a in cols]
    t = arrays[0]
    for i in range(t.shape[0]):
        out.write(",".join([repr(float(t[i]))] + [_num(a[i]) for a in arrays[1:]]) + "\n")
    return out.getvalue()


__all__ = ["generic_csv"]

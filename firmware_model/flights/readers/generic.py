"""The generic flight CSV: one header row of unit-named columns, then one row per sample.

Columns (names are case-sensitive; other columns are ignored):

* ``time_s`` (required): s, strictly increasing.
* barometer, exactly one of: ``pressure_pa``; ``pressure_hpa`` (x100); ``altitude_m``: standard-atmosphere
  (geopotential, MSL) altitude, converted to pressure with :func:`firmware_model.spec.atmosphere.pressure_pa` (an AGL
  log then flies as if launched from sea level).
* accelerometer, optional, at most one of: ``accel_mps2`` (axial specific force, +9.81 on the pad) or ``accel_g``
  (the same in g, x g0).
* ``temperature_c`` optional.
* truth, optional: ``true_altitude_m`` (AGL), ``true_velocity_mps``, ``true_accel_mps2``.

Lines starting with ``#`` before the header are comments; ``# key: value`` (or ``key = value``) comments are kept in
the provenance, and these keys mean something: ``name``, ``licence``, ``source``, ``ground_pressure_pa``,
``true_apogee_time_s``, ``true_apogee_altitude_m`` (the exact truth, e.g. from a simulator; without them the truth
apogee is where ``true_velocity_mps`` crosses zero, else the highest ``true_altitude_m`` sample). Fields are comma
separated. An empty field is a missing value (NaN in the record) except in ``time_s``; text that is not a finite
number is an error naming file, line and column.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from firmware_model.flights.readers._common import (check_time, fail, iter_lines, licence_of, parse_float,
                                                    read_text, show)
from firmware_model.flights.record import FlightRecord, Truth
from firmware_model.runtime.output import write_file
from firmware_model.spec.atmosphere import G0, pressure_pa

BARO_COLUMNS: tuple[str, ...] = ("pressure_pa", "pressure_hpa", "altitude_m")
ACCEL_COLUMNS: tuple[str, ...] = ("accel_mps2", "accel_g")
TRUTH_COLUMNS: tuple[str, ...] = ("true_altitude_m", "true_velocity_mps", "true_accel_mps2")
OPTIONAL: tuple[str, ...] = ("temperature_c",)
_META = re.compile(r"^#\s*([A-Za-z_][A-Za-z0-9_]*)\s*[:=]\s*(.*?)\s*$")


def looks_like(text: str) -> bool:
    """True when the first non-comment line is a header with ``time_s`` (and no ``altitude_ft``: a
    ``time_s,altitude_ft,...`` header is the PerfectFlite StratoLogger CSV, :mod:`.perfectflite`)."""
    for line in text.splitlines():
        if not line.strip() or line.startswith("#"):
            continue
        cols = [c.strip() for c in line.split(",")]
        return "time_s" in cols and "altitude_ft" not in cols     # time_s,altitude_ft: PerfectFlite's CSV
    return False


def truth_apogee(t: np.ndarray, h: np.ndarray | None, v: np.ndarray | None) -> tuple[float | None, float | None]:
    """Truth apogee from truth arrays: the first downward zero crossing of velocity after its maximum (linear
    interpolation), altitude interpolated there; else the highest altitude sample."""
    if v is not None and np.all(np.isfinite(v)):
        start = int(np.argmax(v))
        down = np.nonzero((v[start:-1] > 0) & (v[start + 1:] <= 0))[0]
        if down.size:
            i = start + int(down[0])
            f = v[i] / (v[i] - v[i + 1])
            ta = float(t[i] + f * (t[i + 1] - t[i]))
            ha = float(np.interp(ta, t, h)) if h is not None else None
            return ta, ha
    if h is not None and np.any(np.isfinite(h)):
        i = int(np.nanargmax(h))
        return float(t[i]), float(h[i])
    return None, None


def read(path: Path) -> FlightRecord:  # noqa: C901 - each optional column and its unit, checked with its own message
    """Read a generic flight CSV into a :class:`FlightRecord`."""
    text = read_text(path)
    meta: dict[str, str] = {}
    header: list[str] | None = None
    header_line = 0
    cap = text.count("\n") + 1
    values: dict[str, np.ndarray] = {}
    idx: dict[str, int] = {}
    used: list[str] = []
    baro: list[str] = []
    accel: list[str] = []
    line_of = np.empty(cap, dtype=np.int64)
    n = 0
    number = 0
    # one pass, each row parsed into the numeric arrays at once (no per-row field lists: issue 33)
    for number, line in enumerate(iter_lines(text), start=1):
        if not line.strip():
            continue
        if header is None:
            if line.startswith("#"):
                m = _META.match(line)
                if m:
                    meta[m.group(1)] = m.group(2)
                continue
            header, header_line = [c.strip() for c in line.split(",")], number
            dup = sorted({c for c in header if header.count(c) > 1 and c})
            if dup:
                raise fail(path, header_line, f"column(s) named twice: {', '.join(dup)}")
            if "time_s" not in header:
                raise fail(path, header_line, "missing column time_s")
            baro = [c for c in BARO_COLUMNS if c in header]
            if len(baro) != 1:
                raise fail(path, header_line, "need exactly one barometer column of " + ", ".join(BARO_COLUMNS)
                           + (f" (found {', '.join(baro)})" if baro else ""))
            accel = [c for c in ACCEL_COLUMNS if c in header]
            if len(accel) > 1:
                raise fail(path, header_line, f"at most one accelerometer column of {', '.join(ACCEL_COLUMNS)}")
            used = ["time_s", baro[0], *accel, *[c for c in TRUTH_COLUMNS + OPTIONAL if c in header]]
            idx = {c: header.index(c) for c in used}
            values = {c: np.empty(cap) for c in used}
            continue
        if line.startswith("#"):
            continue
        fields = line.split(",")
        if len(fields) != len(header):
            raise fail(path, number, f"{len(fields)} fields, the header has {len(header)}")
        for c in used:
            values[c][n] = parse_float(path, number, c, fields[idx[c]], allow_empty=c != "time_s")
        line_of[n] = number
        n += 1
    del text
    if header is None:
        raise fail(path, max(number, 1), "no header row")
    if not n:
        raise fail(path, header_line, "no data rows")
    values = {c: v[:n] for c, v in values.items()}
    line_of = line_of[:n]
    check_time(path, line_of, values["time_s"], drop_repeats=False)
    for c in used:
        if c != "time_s" and not np.any(np.isfinite(values[c])):
            raise fail(path, header_line, f"column {c} has no values")

    raw = values[baro[0]]
    if baro[0] == "pressure_pa":
        p = raw
    elif baro[0] == "pressure_hpa":
        with np.errstate(over="ignore"):   # 1e308 hPa: inf, refused with its line by the record
            p = raw * 100.0
    else:
        p = np.asarray(pressure_pa(raw), dtype=np.float64)
    bad = np.nonzero(~(p > 0) & np.isfinite(p))[0]
    if bad.size:
        raise fail(path, int(line_of[int(bad[0])]),
                   f"{baro[0]}: {show(float(raw[int(bad[0])]))} gives a pressure <= 0 Pa")
    acc = None
    if accel:
        with np.errstate(over="ignore"):   # as above: the record refuses an infinite acceleration
            acc = values[accel[0]] * (G0 if accel[0] == "accel_g" else 1.0)

    t = values["time_s"]
    truth = None
    if any(c in header for c in TRUTH_COLUMNS) or "true_apogee_time_s" in meta:
        h = values.get("true_altitude_m")
        v = values.get("true_velocity_mps")
        ta, ha = truth_apogee(t, h, v)
        for key in ("true_apogee_time_s", "true_apogee_altitude_m"):
            if key in meta:
                try:
                    val = float(meta[key])
                except ValueError:
                    raise fail(path, 1, f"comment {key}: cannot parse {meta[key]!r}") from None
                if key == "true_apogee_time_s":
                    ta = val
                else:
                    ha = val
        truth = Truth(altitude_m=h, velocity_mps=v, accel_mps2=values.get("true_accel_mps2"),
                      apogee_time_s=ta, apogee_altitude_m=ha)
    ground = None
    if "ground_pressure_pa" in meta:
        try:
            ground = float(meta["ground_pressure_pa"])
        except ValueError:
            raise fail(path, 1, f"comment ground_pressure_pa: cannot parse {meta['ground_pressure_pa']!r}") from None
        if not (math.isfinite(ground) and ground > 0):
            raise fail(path, 1, f"comment ground_pressure_pa: {ground!r} is not a positive pressure")
    licence, origin = licence_of(path)
    missing = {c: int(np.sum(~np.isfinite(values[c]))) for c in used if c != "time_s"}
    notes = [f"{c}: {m} empty fields (NaN)" for c, m in missing.items() if m]
    if baro[0] == "altitude_m":
        notes.append("pressure from altitude_m through the standard atmosphere")
    provenance = {
        "source": meta.get("source", str(path)), "file": str(path), "format": "generic",
        "licence": meta.get("licence", licence), "origin": origin, "rows": n,
        "columns": used, "meta": meta, "notes": notes,
    }
    return FlightRecord(name=meta.get("name", path.stem), time_s=t, pressure_pa=p, accel_mps2=acc,
                        temperature_c=values.get("temperature_c"), ground_pressure_pa=ground, truth=truth,
                        provenance=provenance, row_lines=np.asarray(line_of))


def _fmt(x: float) -> str:
    return "" if not np.isfinite(x) else repr(float(x))


def generic_csv(record: FlightRecord, *, truth: bool = True, temperature: bool = True) -> str:
    """The generic-CSV text of ``record``, which :func:`read` reads back to the same arrays, bit for bit (shortest
    round-trip float repr; NaN as an empty field). Columns: ``time_s``, ``pressure_pa``, then ``accel_mps2`` (the
    specific force, also for a record holding counts), ``temperature_c`` (when present and ``temperature``) and the
    truth columns (when present and ``truth``); ``# key: value`` comments carry name, source, format, licence (those
    the provenance has), ground pressure and the truth apogee."""
    cols: list[tuple[str, np.ndarray]] = [("time_s", np.asarray(record.time_s, dtype=np.float64)),
                                          ("pressure_pa", np.asarray(record.pressure_pa, dtype=np.float64))]
    f = record.specific_force_mps2()
    if f is not None:
        cols.append(("accel_mps2", np.asarray(f, dtype=np.float64)))
    if temperature and record.temperature_c is not None:
        cols.append(("temperature_c", np.asarray(record.temperature_c, dtype=np.float64)))
    tr = record.truth if truth else None
    meta: dict[str, str] = {"name": record.name}
    prov = record.provenance or {}
    for key in ("source", "format", "licence"):
        if prov.get(key) is not None:
            meta[key] = str(prov[key])
    if record.ground_pressure_pa is not None:
        meta["ground_pressure_pa"] = repr(float(record.ground_pressure_pa))
    if tr is not None:
        for name, col in (("altitude_m", "true_altitude_m"), ("velocity_mps", "true_velocity_mps"),
                          ("accel_mps2", "true_accel_mps2")):
            arr = getattr(tr, name)
            if arr is not None:
                cols.append((col, np.asarray(arr, dtype=np.float64)))
        if tr.apogee_time_s is not None:
            meta["true_apogee_time_s"] = repr(float(tr.apogee_time_s))
        if tr.apogee_altitude_m is not None:
            meta["true_apogee_altitude_m"] = repr(float(tr.apogee_altitude_m))
    lines = [f"# {k}: {' '.join(v.split())}" for k, v in meta.items()]
    lines.append(",".join(name for name, _ in cols))
    arrays = [a for _, a in cols]
    for i in range(record.n):
        lines.append(",".join(_fmt(a[i]) for a in arrays))
    return "\n".join(lines) + "\n"


def write_generic(record: FlightRecord, path: str | Path, *, truth: bool = True, temperature: bool = True) -> Path:
    """Write :func:`generic_csv` of ``record`` to ``path`` through :func:`firmware_model.runtime.output.write_file`
    (atomic: an interrupted write leaves the previous file, no partial one)."""
    return write_file(path, generic_csv(record, truth=truth, temperature=temperature))

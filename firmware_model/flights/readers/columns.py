"""Any delimited CSV read through a **column map**: which of the file's columns holds time, pressure (or
altitude), acceleration, temperature and the board's state, and in which unit, so nobody has to rewrite a file.

A map is ``target=source`` pairs, comma separated (``--columns``) or one per line in a small file (``#``
comments allowed), or a dict:

* ``time_s`` / ``time_ms`` (one, required): the time column in s or ms;
* one barometer: ``pressure_pa``, ``pressure_hpa``, ``altitude_m`` (AGL), ``altitude_ft`` (AGL); an altitude is a
  **synthetic barometer** (standard atmosphere from the site altitude), said in the notes;
* optional ``accel_mps2`` / ``accel_g`` (axial specific force, +1 g on the pad), ``temperature_c``;
* optional ``state=COLUMN:VALUE``: the board's state column and the value its computer enters at apogee; the first
  row with that value is the board's own apogee (a peer in ``run`` / ``evaluate``).

Built-in maps (:data:`PRESETS`) are detected by their columns, so those files need no map: ``firm`` (the NCSU
FIRM board, ``timestamp_seconds``, ``pressure_pascals``, ``raw_rotated_acceleration_z_gs`` (the board's axis
rotated onto the rocket's: 1.00 g on the pad, +7..+8.6 g in boost; ``raw_acceleration_z_gs`` reads 0.05 g on the
pad), ``state_letter`` ``F`` = their apogee state (S standby, M motor, C coast, F free fall, L landed)).

The delimiter is ``,`` unless the header line has more ``;`` than ``,``. An accelerometer that reads far from 1 g
on the pad (the first 0.5 s) is noted: it is probably not the rocket's axis.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from firmware_model.spec.atmosphere import G0
from firmware_model.runtime.errors import UserError
from firmware_model.flights.readers._common import (Table, check_time, fail, gaps_note, header_fields,
                                                    licence_of, read_text, show, synthetic_pressure)
from firmware_model.flights.record import FlightRecord

TIME: dict[str, float] = {"time_s": 1.0, "time_ms": 1e-3}
BARO: tuple[str, ...] = ("pressure_pa", "pressure_hpa", "altitude_m", "altitude_ft")
ACCEL: dict[str, float] = {"accel_mps2": 1.0, "accel_g": G0}
TARGETS: tuple[str, ...] = (*TIME, *BARO, *ACCEL, "temperature_c", "state")

#: Built-in maps, detected by their source columns: name -> (map, computer name).
PRESETS: dict[str, tuple[dict[str, str], str]] = {
    "firm": ({"time_s": "timestamp_seconds", "pressure_pa": "pressure_pascals",
              "accel_g": "raw_rotated_acceleration_z_gs", "temperature_c": "temperature_celsius",
              "state": "state_letter:F"}, "FIRM board"),
}


def parse_map(spec: str | dict[str, str] | Path, where: str = "--columns") -> dict[str, str]:
    """A column map from ``target=source,...``, a mapping file (one pair per line) or a dict; errors name the pair."""
    if isinstance(spec, dict):
        pairs = [(str(k), str(v)) for k, v in spec.items()]
    else:
        text = str(spec)
        path = Path(text)
        if "=" not in text:
            # a file name (no target=COL pair in it): a missing one is said so, not "is not target=source"
            where = str(path)
            if not path.exists():
                raise UserError(f"{path}: no such column map file (a map is a file of target=COL lines, or "
                                "target=COL pairs separated by commas)")
            text = read_text(path)
            items = [ln.split("#", 1)[0].strip() for ln in text.splitlines()]
        else:
            items = [s.strip() for s in text.split(",")]
        pairs = []
        for item in items:
            if not item:
                continue
            if "=" not in item:
                raise UserError(f"{where}: {item!r} is not target=source (targets: {', '.join(TARGETS)})")
            k, _, v = item.partition("=")
            pairs.append((k.strip(), v.strip()))
    out: dict[str, str] = {}
    for k, v in pairs:
        if k not in TARGETS:
            raise UserError(f"{where}: unknown target {k!r}; known: {', '.join(TARGETS)}")
        if not v:
            raise UserError(f"{where}: {k}= names no column")
        if k in out:
            raise UserError(f"{where}: {k} given twice")
        if k == "state" and ":" not in v:
            raise UserError(f"{where}: state={v} needs the apogee value: state=COLUMN:VALUE")
        out[k] = v
    if sum(k in out for k in TIME) != 1:
        raise UserError(f"{where}: give exactly one of {', '.join(TIME)}")
    if sum(k in out for k in BARO) != 1:
        raise UserError(f"{where}: give exactly one of {', '.join(BARO)}")
    if sum(k in out for k in ACCEL) > 1:
        raise UserError(f"{where}: give at most one of {', '.join(ACCEL)}")
    return out


def _delimiter(text: str) -> str:
    for line in text.splitlines():
        if line.strip() and not line.startswith("#"):
            return ";" if line.count(";") > line.count(",") else ","
    return ","


def _sources(cmap: dict[str, str]) -> list[str]:
    return [v.partition(":")[0] if k == "state" else v for k, v in cmap.items()]


def preset_of(text: str) -> str | None:
    """The built-in map whose source columns the file's header names, or None."""
    head = set(header_fields(text, _delimiter(text)))
    for name, (cmap, _) in PRESETS.items():
        if set(_sources(cmap)) <= head:
            return name
    return None


def looks_like(text: str) -> bool:
    return preset_of(text) is not None


def read(path: Path, columns: str | dict[str, str] | Path | None = None,
         site_altitude_m: float | None = None) -> FlightRecord:
    """Read ``path`` through the column map ``columns`` (None: the built-in map its header matches)."""
    text = read_text(path)
    computer = "board"
    if columns is None:
        preset = preset_of(text)
        if preset is None:
            raise fail(path, 1, "no column map given and the header matches no built-in map "
                                f"({', '.join(PRESETS)}): give one with --columns")
        cmap, computer = PRESETS[preset]
        how = f"built-in column map {preset!r}"
    else:
        cmap = parse_map(columns)
        how = "column map " + ",".join(f"{k}={v}" for k, v in cmap.items())
    table = Table(path, text, _delimiter(text), min_rows=2)
    missing = [c for c in _sources(cmap) if c not in table.header]
    if missing:
        raise fail(path, table.header_line, f"the column map names column(s) the header does not have: "
                                            f"{', '.join(missing)}")
    tkey = next(k for k in TIME if k in cmap)
    t = table.floats(cmap[tkey]) * TIME[tkey]
    lines = table.lines
    check_time(path, lines, t, drop_repeats=False)
    notes = list(table.notes) + [how]
    bkey = next(k for k in BARO if k in cmap)
    raw = table.floats(cmap[bkey], allow_empty=True)
    synthetic = bkey.startswith("altitude")
    if synthetic:
        p, note = synthetic_pressure(raw * (0.3048 if bkey == "altitude_ft" else 1.0), site_altitude_m)
        notes.append(note)
    else:
        p = raw * (100.0 if bkey == "pressure_hpa" else 1.0)
        bad = np.nonzero(~(p > 0) & np.isfinite(p))[0]
        if bad.size:
            i = int(bad[0])
            raise fail(path, lines[i], f"{cmap[bkey]}: {table.rows[i][1][table.index(cmap[bkey])].strip()} "
                                       "is not a positive pressure")
    accel = None
    akey = next((k for k in ACCEL if k in cmap), None)
    if akey:
        accel = table.floats(cmap[akey], allow_empty=True) * ACCEL[akey]
        pad = t < t[0] + 0.5
        pad_g = float(np.nanmedian(accel[pad])) / G0
        if not 0.8 <= pad_g <= 1.2:
            notes.append(f"WARNING: {cmap[akey]} reads {pad_g:.2f} g over the first 0.5 s, not about +1 g: is it "
                         "the rocket's axis, and does the log start on the pad?")
    temp = table.floats(cmap["temperature_c"], allow_empty=True) if "temperature_c" in cmap else None
    events: dict[str, float] = {}
    if "state" in cmap:
        col, _, value = cmap["state"].partition(":")
        states = table.strings(col)
        for ti, s in zip(t, states):
            events.setdefault(f"state_{s}", float(ti))
        if f"state_{value}" in events:
            events["own_apogee"] = events[f"state_{value}"]
            notes.append(f"the board's apogee: first row with {col} = {value}")
        else:
            notes.append(f"no row with {col} = {value}: the board's own apogee unknown")
    notes += gaps_note(t, lines)
    licence, origin = licence_of(path)
    provenance = {"source": str(path), "format": "columns", "licence": licence, "origin": origin,
                  "rows": len(lines), "columns": cmap, "own_computer": computer, "synthetic_baro": synthetic,
                  "notes": notes}
    return FlightRecord(name=path.stem, time_s=t, pressure_pa=p, accel_mps2=accel, temperature_c=temp,
                        events=events, provenance=provenance, row_lines=np.asarray(lines))


__all__ = ["PRESETS", "TARGETS", "looks_like", "parse_map", "preset_of", "read", "show"]

"""A team-built board's per-sensor files (the EuRoC 2021 "Lynx" computer): one CSV per sensor, each on its own
irregular clock, and the board's state machine in its own file.

What the reader relies on (docs/flights.md, "Team board"):

* a sensor file: header exactly ``time,pressure``: ``time`` s (the board's clock: 0 = its launch detection),
  ``pressure`` Pa; samples at irregular intervals (MS5803 ~67 Hz, the analog static-port sensor ~42 Hz on Lynx).
  One file is one sensor: the file read is the sensor chosen (the notes name it). A row repeated byte for byte
  (2,277 on lynx-pressure_ms5803) is dropped and counted; a repeated time with another pressure is an error.
* the state file ``<prefix>statemachine.csv`` beside it (the sensor file's name with its part after the last
  ``-`` replaced; ``statemachine.csv`` without a prefix): header ``time,state``, integer states. On Lynx (its
  README): 9 armed, 10 ascent, **11 drogue deployed** (the board's apogee), 12 main. The board's own apogee is the
  first row with state ``apogee_state`` (default 11). A state file alone is not a log.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from firmware_model.flights.readers._common import (Table, check_time, fail, gaps_note, header_fields,
                                                    licence_of, read_text)
from firmware_model.flights.record import FlightRecord

#: The state of the Lynx board's state machine that fires the drogue (its README).
APOGEE_STATE: int = 11


def looks_like(text: str) -> bool:
    return header_fields(text) == ["time", "pressure"]


def companion_reason(text: str) -> str | None:
    if header_fields(text) == ["time", "state"]:
        return "a board's state-machine file (read one of its time,pressure sensor files)"
    return None


def state_file(path: Path) -> Path:
    stem = path.stem
    prefix = stem[: stem.rfind("-") + 1] if "-" in stem else ""
    return path.with_name(f"{prefix}statemachine.csv")


def read(path: Path, apogee_state: int = APOGEE_STATE) -> FlightRecord:
    """Read one ``time,pressure`` sensor file and the board's state file beside it."""
    text = read_text(path)
    if not looks_like(text):
        why = companion_reason(text)
        raise fail(path, 1, why or "not a board sensor file (header time,pressure)")
    table = Table(path, text, ",", min_rows=2)
    t = table.floats("time")
    p = table.floats("pressure")
    lines = table.lines
    bad = np.nonzero(~(p > 0))[0]
    if bad.size:
        raise fail(path, lines[int(bad[0])], f"pressure: {table.rows[int(bad[0])][1][1].strip()} Pa is not positive")
    keep, repeats = check_time(path, lines, t, drop_repeats=True)
    notes = list(table.notes)
    if repeats:
        last = 0
        for i in range(t.size):
            if keep[i]:
                last = i
            elif p[i] != p[last]:
                raise fail(path, lines[i], f"time {table.rows[i][1][0].strip()} repeated with a different pressure "
                                           f"({table.rows[last][1][1].strip()} on line {lines[last]})")
        t, p = t[keep], p[keep]
        lines = [n for n, k in zip(lines, keep) if k]
        notes.append(f"{repeats} repeated rows (same time, same pressure) dropped")
    d = np.diff(t)
    notes.append(f"sensor: {path.stem} ({t.size} samples, intervals {d.min() * 1e3:.1f}..{d.max() * 1e3:.1f} ms, "
                 f"median {np.median(d) * 1e3:.1f} ms)")
    events: dict[str, float] = {}
    sf = state_file(path)
    if sf.exists() and sf != path:
        st = Table(sf, read_text(sf), ",", min_rows=1)
        ts = st.floats("time")
        states = st.floats("state")
        for ti, s in zip(ts, states):
            events.setdefault(f"board_state_{int(s)}", float(ti))
        if f"board_state_{apogee_state}" in events:
            events["own_apogee"] = events[f"board_state_{apogee_state}"]
            notes.append(f"the board's apogee: first state {apogee_state} in {sf.name}")
        else:
            notes.append(f"no state {apogee_state} in {sf.name}: the board's own apogee unknown")
    else:
        notes.append(f"no state file {sf.name}: the board's own apogee unknown")
    notes += gaps_note(t, lines)
    licence, origin = licence_of(path)
    provenance = {"source": str(path), "format": "board", "licence": licence, "origin": origin, "rows": len(lines),
                  "sensor": path.stem, "own_computer": "team board", "notes": notes}
    return FlightRecord(name=path.stem, time_s=t, pressure_pa=p, events=events, provenance=provenance,
                        row_lines=np.asarray(lines))

"""Eggtimer Rocketry flight computers (Eggtimer TRS / Quantum / Quark): the "flight data" CSV, 20 Hz.

What the reader relies on (docs/flights.md, "Eggtimer"):

* Header ``T, Alt, Veloc, Filt_Alt, FVeloc, LDA, LowV, Apogee, N-O, Drogue, Main``, ``;`` or ``,`` separated.
* ``T`` **milliseconds** from launch detect, ``Alt`` **feet AGL** (the board's barometric altitude; its pressure is
  not exported). ``Veloc``, ``Filt_Alt``, ``FVeloc`` are the board's own derived values, scaled integers on some
  firmware (sta-carl2: ``Filt_Alt`` x100): not used.
* Flag columns ``LDA`` (launch detect), ``LowV``, ``Apogee``, ``N-O`` (nose-over), ``Drogue``, ``Main``: 0, or the
  altitude at the sample where the event happened. The board's own apogee is the first row with ``Apogee`` != 0
  (sta-carl2 also has ``Drogue``/``Main`` set on the first row: a power-on self test, not an event).
* **Synthetic barometer**: pressure = standard atmosphere at ``Alt`` x 0.3048 + the site altitude. The site
  altitude: the ``site_altitude_m`` argument, else ``ASL Alt.: N ft`` from a ``<stem>-info.txt`` beside the log
  (the Eggtimer's summary), else sea level; which one is in the notes.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from firmware_model.flights.readers._common import (Table, check_time, fail, gaps_note, header_fields,
                                                    check_altitude, licence_of, read_text, synthetic_pressure)
from firmware_model.flights.record import FlightRecord

FT: float = 0.3048
REQUIRED: tuple[str, ...] = ("T", "Alt", "Apogee")
FLAGS: tuple[str, ...] = ("LDA", "LowV", "Apogee", "N-O", "Drogue", "Main")


def _delimiter(text: str) -> str | None:
    for delim in (";", ","):
        head = header_fields(text, delim)
        if head[:3] == ["T", "Alt", "Veloc"] and "Apogee" in head:
            return delim
    return None


def looks_like(text: str) -> bool:
    """True when the first line starts ``T, Alt, Veloc`` and names an ``Apogee`` flag column."""
    return _delimiter(text) is not None


def info_site_altitude(path: Path) -> float | None:
    """``ASL Alt.: N ft`` of the Eggtimer summary ``<stem>-info.txt`` beside ``path``, in metres, or None."""
    info = path.with_name(path.stem + "-info.txt")
    try:
        text = info.read_text(errors="replace")
    except OSError:
        return None
    m = re.search(r"^\s*ASL Alt\.?:\s*([-+]?\d+(?:\.\d*)?)\s*ft", text, re.M)
    return float(m.group(1)) * FT if m else None


def read(path: Path, site_altitude_m: float | None = None) -> FlightRecord:
    """Read one Eggtimer flight CSV (altitude only: a synthetic barometer)."""
    text = read_text(path)
    delim = _delimiter(text)
    if delim is None:
        raise fail(path, 1, "not an Eggtimer CSV (header T, Alt, Veloc, ..., Apogee, ...)")
    table = Table(path, text, delim, min_rows=2)
    t = table.floats("T") / 1000.0
    alt_ft = table.floats("Alt")
    lines = table.lines
    check_time(path, lines, t, drop_repeats=False)
    notes = list(table.notes)
    source = "given"
    if site_altitude_m is None:
        site_altitude_m = info_site_altitude(path)
        source = f"'ASL Alt.' of {path.stem}-info.txt"
    check_altitude(path, lines, alt_ft * FT, "Alt", "ft", FT)
    p, how = synthetic_pressure(alt_ft * FT, site_altitude_m, source)
    notes.append(how)
    events: dict[str, float] = {}
    for flag in FLAGS:
        if flag not in table.header:
            continue
        v = table.floats(flag)
        hit = np.nonzero(v != 0)[0]
        hit = hit[hit > 0] if flag in ("Drogue", "Main") else hit   # the first row's self test
        if hit.size:
            events[f"eggtimer_{flag.lower().replace('-', '_')}"] = float(t[hit[0]])
    if "eggtimer_apogee" in events:
        events["own_apogee"] = events["eggtimer_apogee"]
    else:
        notes.append("no Apogee flag set: the Eggtimer declared no apogee in this log")
    notes += gaps_note(t, lines)
    licence, origin = licence_of(path)
    provenance = {"source": str(path), "format": "eggtimer", "licence": licence, "origin": origin,
                  "rows": len(lines), "own_computer": "Eggtimer", "synthetic_baro": True, "notes": notes}
    return FlightRecord(name=path.stem, time_s=t, pressure_pa=p, events=events, provenance=provenance,
                        row_lines=np.asarray(lines))

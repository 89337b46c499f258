"""Missile Works RRC3 exports (mDACS "Export flight data"): one row per sample at 20 Hz.

What the reader relies on (docs/flights.md, "RRC3"):

* Header ``Time, Altitude, Pressure, Velocity, Temperature, Events, Voltages`` (case as exported: ``Time;...`` or
  ``time,...``), separated by ``;`` or ``,``. With ``;`` numbers use a **decimal comma** (``0,05``; ``2,04E-06``),
  as a European-locale export writes them; every line may end with a ``;``.
* ``Time`` s from launch detect, ``Altitude`` m AGL (the RRC3's own), ``Pressure`` **hPa** (mbar), ``Velocity``
  m/s, ``Temperature`` degC (or F, by the user's setting: not used), ``Events`` ``-`` or the name of what fired at
  that sample (``Drogue``, ``Main``, ...), ``Voltages`` battery V.
* The pressure column is the real barometer (record pressure = hPa x 100); the altitude is not used.
* The RRC3's own apogee: the first row whose event names ``Drogue`` or ``Apogee`` (the RRC3 fires the drogue at
  apogee unless a delay is set: a delay shows as a late peer, not hidden).
* Quirks seen on the shared logs: a row of empty fields at the end (skipped, noted); rows out of time order and a
  last rows without a temperature field, the event in its place, and impossible values at the end (juno3:
  30.45 s at 191 hPa, 30.50 s at 1159 hPa; left to the reference's spike rejection); rows sorted as text (sta-carl2:
  0, 0.05, ..., 1, 10, 100, ..., 11: sorted back by time and noted); other rows
  whose time does not increase are errors naming the line, as everywhere.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from firmware_model.flights.readers._common import (Table, check_time, fail, gaps_note, header_fields,
                                                    licence_of, read_text)
from firmware_model.flights.record import FlightRecord

COLUMNS: tuple[str, ...] = ("time", "altitude", "pressure", "velocity", "temperature", "events", "voltages")
APOGEE_EVENTS: tuple[str, ...] = ("drogue", "apogee")


def _delimiter(text: str) -> str | None:
    for delim in (";", ","):
        if [f.lower() for f in header_fields(text, delim)] == list(COLUMNS):
            return delim
    return None


def looks_like(text: str) -> bool:
    """True when the first line names exactly the RRC3 export's seven columns (``;`` or ``,`` separated)."""
    return _delimiter(text) is not None


def _number(text: str, comma: bool) -> bool:
    try:
        float(text.replace(",", ".") if comma else text)
    except ValueError:
        return False
    return True


def _text_sorted(table: Table, t: np.ndarray) -> bool:
    """True when the rows are sorted by the text of their time field (a spreadsheet's text sort) and the times are
    all distinct: then sorting by value restores the log."""
    if np.unique(t).size != t.size:
        return False
    texts = [fields[table.index("time")].strip() for _, fields in table.rows]
    return texts == sorted(texts)


def read(path: Path) -> FlightRecord:
    """Read one RRC3 export into a :class:`FlightRecord` (pressure from the hPa column)."""
    text = read_text(path)
    delim = _delimiter(text)
    if delim is None:
        raise fail(path, 1, "not an RRC3 export (header Time;Altitude;Pressure;Velocity;Temperature;Events;Voltages)")
    table = Table(path, text, delim, min_rows=2)
    table.header = [h.lower() for h in table.header]
    comma = delim == ";"
    t = table.floats("time", decimal_comma=comma)
    hpa = table.floats("pressure", decimal_comma=comma)
    lines = table.lines
    notes = list(table.notes)
    events_col = table.strings("events")
    temp_col = table.strings("temperature")
    shifted = []
    for i, (ev, temp) in enumerate(zip(events_col, temp_col)):
        if not ev and temp and not _number(temp, comma):
            # a row without its temperature field: the event sits in the temperature column (juno3's last rows)
            events_col[i] = temp
            shifted.append(lines[i])
    if shifted:
        notes.append(f"{len(shifted)} rows (lines {shifted[0]}..{shifted[-1]}) have no temperature field: their "
                     "event is read from the temperature column")
    bad = np.nonzero(~(hpa > 0) & np.isfinite(hpa))[0]
    if bad.size:
        field_text = table.rows[int(bad[0])][1][table.index("pressure")].strip()
        raise fail(path, lines[int(bad[0])], f"pressure: {field_text} hPa is not positive")
    bad = np.nonzero(hpa > 2000.0)[0]
    if bad.size:
        field_text = table.rows[int(bad[0])][1][table.index("pressure")].strip()[:40]
        raise fail(path, lines[int(bad[0])], f"pressure: {field_text} hPa is out of range; allowed: at most 2,000 hPa")
    if np.any(np.diff(t) <= 0) and np.all(t >= 0) and _text_sorted(table, t):
        # a spreadsheet's text sort of non-negative times; negative times in text order are not a log (issue 33:
        # negated times were sorted into an apogee at -21.9 s) and stay an error below
        order = np.argsort(t, kind="stable")
        t, hpa = t[order], hpa[order]
        lines = [lines[i] for i in order]
        events_col = [events_col[i] for i in order]
        notes.append("rows are in the text order of their times (0, 1, 10, 100, ..., 11, ...): sorted by time")
    check_time(path, lines, t, drop_repeats=False)
    events: dict[str, float] = {}
    fired: list[str] = []
    for ti, ev in zip(t, events_col):
        name = ev.strip()
        if name and name != "-":
            key = "rrc3_" + name.lower().replace(" ", "_")
            if key not in events:
                events[key] = float(ti)
                fired.append(f"{name} at {float(ti):g} s")
            if name.lower() in APOGEE_EVENTS and "own_apogee" not in events:
                events["own_apogee"] = float(ti)
    notes.append("pressure = Pressure column (hPa) x 100; the RRC3's altitude column is not used")
    notes.append("events: " + (", ".join(fired) if fired else "none"))
    if "own_apogee" not in events:
        notes.append("no Drogue/Apogee event: the RRC3's own apogee is unknown")
    notes += gaps_note(t, lines)
    licence, origin = licence_of(path)
    provenance = {"source": str(path), "format": "rrc3", "licence": licence, "origin": origin, "rows": len(lines),
                  "decimal_comma": comma, "own_computer": "RRC3", "notes": notes}
    return FlightRecord(name=path.stem, time_s=t, pressure_pa=hpa * 100.0, events=events, provenance=provenance,
                        row_lines=np.asarray(lines))

"""AltosUI CSV exports (Altus Metrum TeleMetrum / TeleMega), versions 5 and 6.

What the reader relies on (docs/flights.md, "AltosUI"):

* Without the comment lines (older or trimmed exports) the first line names the columns (``time,acceleration,
  pressure,altitude,height,speed,temperature,...``), possibly without ``state``/``state_name``: then the record has
  no AltOS events. Detected by a first line naming time, pressure, acceleration and one more AltosUI column.
* Lines starting with ``#`` are comments; ``# Key: value`` comments (config, serial, software version) are kept
  in ``provenance["altos_config"]``; the **last** comment line holds the column names (``#version,serial,...``).
* v5 header quirk: AltOS 1.0.x wrote ``main_voltageaccel_x`` (two names without the comma); the name is split.
  v5 data rows do not match the header past the voltage columns (70 fields for 74 names on two of the shared logs:
  the IMU block is one empty field; 78 for 75 on the third). Only columns before the IMU block are used and they
  are positionally identical in every row: ``time``, ``state_name``, ``acceleration``, ``pressure``,
  ``temperature``. Rows must have at least that many fields.
* v6 repeats timestamps (the whole row, byte for byte, once the log goes to 10 Hz): identical repeats are dropped
  and counted; a repeat with different values keeps the first row and is counted as conflicting.
* ``time`` is s from boost (negative on the pad); ``pressure`` Pa; ``acceleration`` m/s^2 along the axis with the
  pad reading removed (0 on the pad), so the record's specific force is ``acceleration + g0``.
* Events: the first row of each ``state_name`` gives ``events["altos_<state>"]``; the first ``drogue`` row is
  AltOS's own apogee detection, ``events["altos_apogee"]``. When a log has no ``drogue`` row and goes from
  ``coast`` straight to ``main`` (a flight below the main-deploy height: AltOS passes through drogue within one
  logged sample), the first ``main`` row is used and the provenance says so.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from firmware_model.flights.readers._common import check_time, fail, licence_of, parse_float, read_text
from firmware_model.flights.record import FlightRecord
from firmware_model.spec.atmosphere import G0

REQUIRED: tuple[str, ...] = ("time", "state_name", "pressure", "acceleration")
#: The v5 header quirk and its repair.
QUIRKS: dict[str, tuple[str, ...]] = {"main_voltageaccel_x": ("main_voltage", "accel_x")}


#: Columns of which a headerless export's first line must name at least two besides time and pressure.
HEADERLESS_MARKS: frozenset[str] = frozenset({"acceleration", "altitude", "height", "speed", "state_name",
                                              "accel_speed", "baro_speed"})


def looks_like(text: str) -> bool:
    """True when the text is an AltosUI CSV: a comment line naming the columns ``#version,serial,...`` with
    ``time``, ``state_name`` and ``pressure``, or (an export without the comment lines) a first line naming
    ``time``, ``pressure``, ``acceleration`` and one more AltosUI column (``altitude``, ``height``, ``speed``, ...)."""
    for line in text.splitlines()[:200]:
        if line.startswith("#version"):
            names = {n.strip() for n in line[1:].split(",")}
            return {"time", "state_name", "pressure"} <= names
    return _headerless(text) is not None


def _headerless(text: str) -> int | None:
    """Line number of a headerless export's column line, or None."""
    for number, line in enumerate(text.splitlines()[:200], start=1):
        if not line.strip() or line.startswith("#"):
            continue
        names = {n.strip() for n in line.split(",")}
        ok = {"time", "pressure", "acceleration"} <= names and len(names & HEADERLESS_MARKS) >= 2
        return number if ok else None
    return None


def header_names(line: str) -> list[str]:
    """Column names of a ``#version,...`` line, with the v5 quirk repaired."""
    names: list[str] = []
    for raw in line.lstrip("#").split(","):
        name = raw.strip()
        names.extend(QUIRKS.get(name, (name,)))
    return names


def read(path: Path) -> FlightRecord:  # noqa: C901 - the CSV v5/v6 variants and their optional columns, each checked with its own message
    """Read one AltosUI CSV (v5 or v6) into a :class:`FlightRecord`."""
    text = read_text(path)
    lines = text.splitlines()
    header: list[str] | None = None
    header_line = 0
    config: dict[str, str] = {}
    data: list[tuple[int, list[str]]] = []
    plain = None if any(ln.startswith("#version") for ln in lines[:200]) else _headerless(text)
    for number, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        if number == plain:
            header, header_line = header_names(line), number
            continue
        if line.startswith("#"):
            if data:
                raise fail(path, number, "comment line after the data started")
            if line.startswith("#version"):
                header, header_line = header_names(line), number
            elif ":" in line:
                key, _, value = line[1:].partition(":")
                config[key.strip()] = value.strip()
            continue
        if header is None:
            raise fail(path, number, "data before the '#version,...' header line (not an AltosUI CSV?)")
        data.append((number, line.split(",")))
    if header is None:
        raise fail(path, len(lines), "no '#version,...' header line (not an AltosUI CSV?)")
    required = REQUIRED if plain is None or "state_name" in header else tuple(c for c in REQUIRED
                                                                            if c != "state_name")
    missing = [c for c in required if c not in header]
    if missing:
        raise fail(path, header_line, f"missing column(s) {', '.join(missing)}")
    if not data:
        raise fail(path, header_line, "no data rows")
    col = {name: header.index(name) for name in REQUIRED + ("temperature", "version")
           if name in header}
    need = max(col[c] for c in required) + 1
    version = data[0][1][col["version"]].strip() if "version" in col else "?"

    n = len(data)
    t = np.empty(n)
    p = np.empty(n)
    acc = np.empty(n)
    temp = np.full(n, math.nan) if "temperature" in col else None
    states: list[str] = []
    line_of = [num for num, _ in data]
    widths = set()
    for i, (num, fields) in enumerate(data):
        widths.add(len(fields))
        if len(fields) < need:
            raise fail(path, num, f"{len(fields)} fields, the columns used need at least {need}")
        t[i] = parse_float(path, num, "time", fields[col["time"]])
        p[i] = parse_float(path, num, "pressure", fields[col["pressure"]])
        if not p[i] > 0:
            raise fail(path, num, f"pressure: {fields[col['pressure']].strip()} Pa is not positive")
        acc[i] = parse_float(path, num, "acceleration", fields[col["acceleration"]])
        if temp is not None and col["temperature"] < len(fields):
            temp[i] = parse_float(path, num, "temperature", fields[col["temperature"]], allow_empty=True)
        if "state_name" in col:
            state = fields[col["state_name"]].strip()
            if not state:
                raise fail(path, num, "state_name: empty field")
            states.append(state)
        else:
            states.append("")

    keep, repeats = check_time(path, line_of, t, drop_repeats=True)
    conflicting = 0
    last_kept = 0
    for i in range(n):
        if keep[i]:
            last_kept = i
        elif data[i][1] != data[last_kept][1]:
            conflicting += 1
    t, p, acc = t[keep], p[keep], acc[keep]
    temp = temp[keep] if temp is not None else None
    states = [s for s, k in zip(states, keep) if k]

    events: dict[str, float] = {}
    for ti, state in zip(t, states):
        if state:
            events.setdefault(f"altos_{state}", float(ti))
    notes: list[str] = []
    if plain is not None:
        notes.append("no '#version' comment line: the first line names the columns"
                     + ("" if "state_name" in col else "; no state_name column, so no AltOS events or apogee"))
    if "altos_drogue" in events:
        events["altos_apogee"] = events["altos_drogue"]
    elif "altos_main" in events:
        i_main = states.index("main")
        if i_main > 0 and states[i_main - 1] in ("coast", "fast"):
            events["altos_apogee"] = events["altos_main"]
            notes.append("no 'drogue' row: the state goes from coast straight to main, "
                         "altos_apogee is the first 'main' row")
    if repeats:
        notes.append(f"{repeats} repeated timestamps dropped ({conflicting} of them with different values; "
                     "the first row was kept)")
    if widths != {len(header)}:
        notes.append(f"rows have {sorted(widths)} fields, the header names {len(header)}: only the columns before "
                     "the IMU block are used (time, state_name, acceleration, pressure, temperature)")
    notes.append("accel_mps2 = acceleration + g0 (AltOS removes the pad reading)")
    licence, origin = licence_of(path)
    x = (p / 1000.0 * 0.009 - 0.095) * 2047 * 16
    if np.all(np.abs(x - np.rint(x)) <= 0.002):
        baro_hint = "telemetrum_v1"     # the README's exact MP3H6115A formula reproduces integer ADC counts
    elif np.all(p == np.rint(p)):
        baro_hint = "pascal"            # integer pascals: a digital (MS5607-like) sensor
    else:
        baro_hint = "unknown"
    provenance = {
        "source": str(path), "format": "altosui", "own_computer": "AltOS", "csv_version": version,
        "licence": licence, "origin": origin,
        "rows": n, "altos_config": config, "baro_sensor_hint": baro_hint, "notes": notes,
        "repeated_timestamps_dropped": int(repeats), "conflicting_repeats": int(conflicting),
    }
    return FlightRecord(name=path.stem, time_s=t, pressure_pa=p, accel_mps2=acc + G0, temperature_c=temp,
                        events=events, provenance=provenance, row_lines=np.asarray(line_of)[keep])

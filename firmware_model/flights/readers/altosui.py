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

from firmware_model.flights.readers._common import check_time, fail, iter_lines, licence_of, parse_float, read_text
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
    for line in iter_lines(text, 200):
        if line.startswith("#version"):
            names = {n.strip() for n in line[1:].split(",")}
            return {"time", "state_name", "pressure"} <= names
    return _headerless(text) is not None


def _headerless(text: str) -> int | None:
    """Line number of a headerless export's column line, or None."""
    for number, line in enumerate(iter_lines(text, 200), start=1):
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


def _events(t: np.ndarray, states: list[str]) -> tuple[dict[str, float], str]:
    """The first time of each AltOS state (``altos_<state>``) and ``altos_apogee`` (the first 'drogue' row, or
    the first 'main' row when the state goes from coast straight to main: then with the note that says so)."""
    events: dict[str, float] = {}
    for ti, state in zip(t, states):
        if state:
            events.setdefault(f"altos_{state}", float(ti))
    if "altos_drogue" in events:
        events["altos_apogee"] = events["altos_drogue"]
    elif "altos_main" in events:
        i_main = states.index("main")
        if i_main > 0 and states[i_main - 1] in ("coast", "fast"):
            events["altos_apogee"] = events["altos_main"]
            return events, ("no 'drogue' row: the state goes from coast straight to main, "
                            "altos_apogee is the first 'main' row")
    return events, ""


def _baro_hint(p: np.ndarray) -> str:
    """Which barometer the pressures ``p`` (Pa) look like they came from."""
    x = (p / 1000.0 * 0.009 - 0.095) * 2047 * 16
    if np.all(np.abs(x - np.rint(x)) <= 0.002):
        return "telemetrum_v1"     # the README's exact MP3H6115A formula reproduces integer ADC counts
    if np.all(p == np.rint(p)):
        return "pascal"            # integer pascals: a digital (MS5607-like) sensor
    return "unknown"


def read(path: Path) -> FlightRecord:  # noqa: C901 - one pass over the CSV v5/v6 variants and their optional columns, each checked with its own message
    """Read one AltosUI CSV (v5 or v6) into a :class:`FlightRecord`: one pass over the lines into numeric
    arrays (memory: the text and a few numbers per row; no per-row field lists)."""
    text = read_text(path)
    header: list[str] | None = None
    header_line = 0
    config: dict[str, str] = {}
    plain = None if any(ln.startswith("#version") for ln in iter_lines(text, 200)) else _headerless(text)
    cap = text.count("\n") + 1
    t, p, acc, temp_all = (np.empty(cap) for _ in range(4))
    state_code = np.empty(cap, dtype=np.int32)
    line_of = np.empty(cap, dtype=np.int64)
    codes: dict[str, int] = {}
    widths: set[int] = set()
    n = 0
    col: dict[str, int] = {}
    need = 0
    required: tuple[str, ...] = REQUIRED
    version = "?"
    last_t, last_kept, conflicting, repeats = -math.inf, "", 0, 0
    number = 0
    for number, line in enumerate(iter_lines(text), start=1):
        if not line.strip():
            continue
        if number == plain:
            header, header_line = header_names(line), number
            continue
        if line.startswith("#"):
            if n:
                raise fail(path, number, "comment line after the data started")
            if line.startswith("#version"):
                header, header_line = header_names(line), number
            elif ":" in line:
                key, _, value = line[1:].partition(":")
                config[key.strip()] = value.strip()
            continue
        if header is None:
            raise fail(path, number, "data before the '#version,...' header line (not an AltosUI CSV?)")
        if not n:       # the first data row: the header is settled
            required = REQUIRED if plain is None or "state_name" in header else tuple(
                c for c in REQUIRED if c != "state_name")
            missing = [c for c in required if c not in header]
            if missing:
                raise fail(path, header_line, f"missing column(s) {', '.join(missing)}")
            col = {name: header.index(name) for name in REQUIRED + ("temperature", "version") if name in header}
            need = max(col[c] for c in required) + 1
        fields = line.split(",")
        if not n and "version" in col and col["version"] < len(fields):
            version = fields[col["version"]].strip()
        widths.add(len(fields))
        if len(fields) < need:
            raise fail(path, number, f"{len(fields)} fields, the columns used need at least {need}")
        ti = parse_float(path, number, "time", fields[col["time"]])
        pi = parse_float(path, number, "pressure", fields[col["pressure"]])
        if not pi > 0:
            raise fail(path, number, f"pressure: {fields[col['pressure']].strip()} Pa is not positive")
        t[n], p[n] = ti, pi
        acc[n] = parse_float(path, number, "acceleration", fields[col["acceleration"]])
        temp_all[n] = (parse_float(path, number, "temperature", fields[col["temperature"]], allow_empty=True)
                       if "temperature" in col and col["temperature"] < len(fields) else math.nan)
        if "state_name" in col:
            state = fields[col["state_name"]].strip()
            if not state:
                raise fail(path, number, "state_name: empty field")
        else:
            state = ""
        state_code[n] = codes.setdefault(state, len(codes))
        line_of[n] = number
        if ti > last_t:
            last_t, last_kept = ti, line
        elif ti == last_t:     # a repeated timestamp (dropped below): a different row is a conflicting one
            conflicting += line != last_kept
        n += 1
    del text
    if header is None:
        raise fail(path, max(number, 1), "no '#version,...' header line (not an AltosUI CSV?)")
    if not n:
        missing = [c for c in REQUIRED if c not in header and (c != "state_name" or plain is None)]
        if missing:
            raise fail(path, header_line, f"missing column(s) {', '.join(missing)}")
        raise fail(path, header_line, "no data rows")
    t, p, acc, line_of = t[:n], p[:n], acc[:n], line_of[:n]
    temp = temp_all[:n] if "temperature" in col else None
    keep, repeats = check_time(path, line_of, t, drop_repeats=True)
    names_of = {c: name for name, c in codes.items()}
    t, p, acc = t[keep], p[keep], acc[keep]
    temp = temp[keep] if temp is not None else None
    states = [names_of[int(c)] for c in state_code[:n][keep]]

    events, apogee_note = _events(t, states)
    notes: list[str] = []
    if plain is not None:
        notes.append("no '#version' comment line: the first line names the columns"
                     + ("" if "state_name" in col else "; no state_name column, so no AltOS events or apogee"))
    if apogee_note:
        notes.append(apogee_note)
    if repeats:
        notes.append(f"{repeats} repeated timestamps dropped ({conflicting} of them with different values; "
                     "the first row was kept)")
    if widths != {len(header)}:
        notes.append(f"rows have {sorted(widths)} fields, the header names {len(header)}: only the columns before "
                     "the IMU block are used (time, state_name, acceleration, pressure, temperature)")
    notes.append("accel_mps2 = acceleration + g0 (AltOS removes the pad reading)")
    licence, origin = licence_of(path)
    provenance = {
        "source": str(path), "format": "altosui", "own_computer": "AltOS", "csv_version": version,
        "licence": licence, "origin": origin,
        "rows": n, "altos_config": config, "baro_sensor_hint": _baro_hint(p), "notes": notes,
        "repeated_timestamps_dropped": int(repeats), "conflicting_repeats": int(conflicting),
    }
    return FlightRecord(name=path.stem, time_s=t, pressure_pa=p, accel_mps2=acc + G0, temperature_c=temp,
                        events=events, provenance=provenance, row_lines=line_of[keep])

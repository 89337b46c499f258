"""PerfectFlite altimeters (Pnut, StratoLogger SL100, StratoLoggerCF): the ``.pf2`` text DataCap saves, its CSV
export, and the bare rows the StratoLogger sends down its serial port. docs/flights.md, "PerfectFlite".
Samples: ``../shared/flights/fusionspace/perfectflite-pnut.pf2`` (the ``.pf2``), ``perfectflite-stratologger.csv``
(the CSV).

What the reader relies on (PerfectFlite's DataCap manual and the devices' behaviour: the altimeters sample their
barometer at 20 samples/s and report altitude above the pad in feet; they do not keep pressure):

* **Preamble** (optional): ``Key: value`` lines (``PerfectFlite Pnut`` / ``StratoLogger`` name line, ``Firmware:``,
  ``Serial Number:``, ``Apogee: 1009' AGL``, ``Ground Elevation: 2486' MSL``, ``NumSamps: 1664``, ``Main At:``,
  ``Drogue At:``, the SLCF's ``Max Drogue Current:`` ...). Heights carry a unit: ``'``, ``ft`` or ``feet`` (feet), ``m``
  (metres); any other unit is an error naming the line. ``Apogee`` is the device's own apogee (its peak AGL):
  it becomes the log's own computer's apogee (``events["own_apogee"]``: the first row at or above it, and
  ``provenance["own_apogee_m"]``); ``Ground Elevation`` is the site altitude of the synthetic barometer.
* **Columns**: ``Data: (Time, Altitude, Velocity, Temperature (F), Voltage)`` after the preamble, or a CSV header
  line whose every column is one of PerfectFlite's (``time_s,altitude_ft,temperature,voltage``, DataCap's
  ``Time,Altitude,Velocity,Temperature,Voltage``, ``Time (s),Altitude (ft),...``; without a preamble, an altitude
  named in metres is the generic CSV's, not PerfectFlite's), or none: bare rows of 4 fields
  ``time altitude temperature volts`` (StratoLogger serial download) or 5 fields in the ``Data:`` order. Names are
  matched by their first letters (time, alt, vel, temp, volt); units from the name (``_ft``, ``(ft)``, ``(feet)``,
  ``_m``, ``(m)``; feet when none, metres when the preamble states its heights in m), temperature ``(F)``/``(C)``
  or a ``F``/``C`` suffix on the value (``76.7F``).
* Rows: comma, tab or space separated. Time s, altitude AGL. **Synthetic barometer**: pressure = standard
  atmosphere at altitude + site altitude (``site_altitude_m`` given, else the stated ground elevation, else sea
  level), said in the notes; ``ground_pressure_pa`` is that at the device's own zero.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from firmware_model.flights.readers._common import (check_time, fail, gaps_note, licence_of, parse_float, read_text,
                                                    show, synthetic_pressure)
from firmware_model.flights.record import FlightRecord
from firmware_model.spec.atmosphere import pressure_pa

FT: float = 0.3048
RATE_HZ: float = 20.0
_KEY = re.compile(r"^\s*([A-Za-z][A-Za-z .#/()]*?)\s*:\s*(.*?)\s*$")
_HEIGHT = re.compile(r"^([-+]?\d+(?:\.\d*)?)\s*(.*?)\s*(AGL|MSL|ASL)?\s*$", re.I)
_SPLIT = re.compile(r"\s*[,\t;]\s*|\s+")
_NUM = re.compile(r"^[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?[FC]?$")
#: Column kinds by the first word of their name.
_KINDS = (("time", "time"), ("alt", "altitude"), ("vel", "velocity"), ("temp", "temperature"), ("volt", "voltage"))
_BARE4 = ("time", "altitude", "temperature", "voltage")
_BARE5 = ("time", "altitude", "velocity", "temperature", "voltage")


def _kind(name: str) -> str | None:
    low = name.strip().lower()
    for prefix, kind in _KINDS:
        if low.startswith(prefix):
            return kind
    return None


def _fields(line: str) -> list[str]:
    return [f for f in _SPLIT.split(line.strip()) if f != ""]


def _header_kinds(line: str) -> list[str] | None:
    """The column kinds of a header line (comma/tab separated names), or None when it is not one."""
    names = _names(line)
    kinds = [_kind(n) for n in names]
    if len(names) < 2 or None in kinds or kinds[0] != "time" or "altitude" not in kinds \
            or len(set(kinds)) != len(kinds):
        return None
    return kinds  # type: ignore[return-value]  # no None left: refused above


def _is_row(line: str, n: tuple[int, ...] = (4, 5)) -> bool:
    f = _fields(line)
    return len(f) in n and all(_NUM.match(x) for x in f)


def _layout(text: str) -> tuple[dict[str, str], list[str], int, int] | None:
    """(preamble, column names, line of the column names (0: none), first data line), or None when the text is
    not a PerfectFlite log. A preamble must be PerfectFlite's: a first line naming the device or an ``Apogee:``
    key; lines in it that are not ``Key: value`` (a comment's continuation) are skipped."""
    lines = text.splitlines()
    pre: dict[str, str] = {}
    device = False
    for number, line in enumerate(lines[:80], start=1):
        s = line.strip()
        if not s:
            continue
        ours = device or "apogee" in pre
        m = re.match(r"^Data:\s*\((.*)\)\s*$", s)
        if m:
            names = [n.strip() for n in re.split(r",(?![^(]*\))", m.group(1))]
            return (pre, names, number, number + 1) if ours else None
        if _is_row(s):
            if pre and not ours:
                return None
            width = len(_fields(s))
            return (pre, list(_BARE4 if width == 4 else _BARE5), 0, number) if _bare_ok(lines[number - 1:]) \
                else None
        kinds = _header_kinds(s)
        if kinds is not None:
            if pre and not ours:
                return None
            names = _names(s)
            alt = re.sub(r"\s", "", names[kinds.index("altitude")].lower())
            if not pre and re.search(r"(_m|\(m\)|\(meters\)|\(metres\))$", alt):
                return None                   # time + altitude in metres, no preamble: the generic CSV's
            return pre, names, number, number + 1
        km = _KEY.match(s)
        if km:
            pre[km.group(1).strip().lower()] = km.group(2)
            continue
        if not pre and not device and s.lower().startswith(("perfectflite", "stratologger")):
            device = True
            continue
        if not (device or pre):
            return None
    return None


def _names(line: str) -> list[str]:
    names = [n.strip() for n in re.split(r"[,\t;]", line.strip())]
    while names and not names[-1]:
        names.pop()
    return names


def _bare_ok(lines: list[str]) -> bool:
    """Bare rows: at least 10, all of one width, time in 1/20 s steps, and a value a count never is (a decimal
    voltage or an F/C temperature): RDAS rows are three numbers and an integer."""
    rows = [_fields(l) for l in lines[:400] if l.strip()]
    if len(rows) < 10 or len({len(r) for r in rows}) != 1 or not all(all(_NUM.match(x) for x in r) for r in rows):
        return False
    try:
        t = np.array([float(r[0]) for r in rows])
    except ValueError:
        return False
    d = np.diff(t)
    if not (np.all(d > 0) and abs(float(np.median(d)) - 1.0 / RATE_HZ) < 1e-6):
        return False
    return any(("." in r[-1]) or r[-2][-1:] in "FC" for r in rows)


def looks_like(text: str) -> bool:
    """A ``Data: (...)`` table after a PerfectFlite preamble, a header of PerfectFlite columns (time, altitude in
    feet, velocity, temperature, voltage), or bare 20 Hz rows of 4-5 numbers with a decimal voltage."""
    return _layout(text) is not None


def _height(path: Path, line: int, key: str, value: str) -> float:
    """A preamble height (``1009' AGL``, ``2486 ft MSL``, ``310 m``) in metres."""
    m = _HEIGHT.match(value.strip())
    if not m:
        raise fail(path, line, f"{key}: cannot read {value!r} as a height")
    unit = m.group(2).strip().lower()
    if unit in ("'", "ft", "feet", "", "ft.", "foot"):
        return float(m.group(1)) * FT
    if unit in ("m", "meters", "metres"):
        return float(m.group(1))
    raise fail(path, line, f"{key}: unknown unit {m.group(2).strip()!r} in {value!r} (know ', ft, feet, m)")


def _unit_of(path: Path, line: int, name: str, kind: str) -> float | str:
    low = name.lower().replace(" ", "")
    if kind in ("altitude", "velocity"):
        if re.search(r"(_m$|\(m\)$|\(m/s\)$|_mps$|_m/s$|\(meters\)|\(metres\))", low):
            return 1.0
        if re.search(r"(ft|feet|')", low) or low in ("altitude", "velocity", "alt", "veloc"):
            return FT
        unit = re.search(r"[(_\[](.*?)[)\]]?$", low)
        raise fail(path, line, f"{name}: unknown unit {unit.group(1) if unit else low!r} (know ft, feet, m)")
    if kind == "temperature":
        if low.endswith(("(c)", "_c", "degc")):
            return "C"
        if low.endswith(("(f)", "_f", "degf")) or low in ("temperature", "temp"):
            return "F"
        raise fail(path, line, f"{name}: unknown temperature unit (know F, C)")
    if kind == "time":
        if low.endswith(("_ms", "(ms)")):
            return 1e-3
        if low in ("time",) or low.endswith(("_s", "(s)", "(sec)", "(secs)", "_sec")):
            return 1.0
        raise fail(path, line, f"{name}: unknown time unit (know s, ms)")
    return 1.0


def read(path: Path, site_altitude_m: float | None = None) -> FlightRecord:  # noqa: C901 - the three layouts (.pf2, DataCap CSV, bare rows), each checked with its own message
    """Read a PerfectFlite log (``.pf2``, DataCap CSV or bare rows): altitude only, a synthetic barometer."""
    text = read_text(path)
    lay = _layout(text)
    if lay is None:
        raise fail(path, 1, "not a PerfectFlite log (no 'Data: (...)' table after a PerfectFlite preamble, no "
                            "time/altitude(ft) header, no bare 20 Hz rows)")
    pre, names, names_line, data_line = lay
    lines = text.splitlines()
    pre_line = {}
    for number, line in enumerate(lines[: max(names_line, data_line) - 1], start=1):
        km = _KEY.match(line.strip())
        if km:
            pre_line[km.group(1).strip().lower()] = number
    kinds = [_kind(n) or n for n in names]
    if "time" not in kinds or "altitude" not in kinds:
        raise fail(path, names_line or data_line, f"the columns {names} name no time and altitude")
    scale = {k: _unit_of(path, names_line or data_line, n, k) for n, k in zip(names, kinds)
             if k in ("time", "altitude", "temperature")}
    stated = [_HEIGHT.match(pre[k].strip()) for k in ("apogee", "ground elevation") if k in pre]
    if names[kinds.index("altitude")].strip().lower() in ("altitude", "alt") and stated and \
            all(m is not None and m.group(2).strip().lower() in ("m", "meters", "metres") for m in stated):
        scale["altitude"] = 1.0     # a unitless altitude column in a log whose preamble states metres
    ti, ai = kinds.index("time"), kinds.index("altitude")
    tci = kinds.index("temperature") if "temperature" in kinds else None
    t_l, a_l, c_l, rows = [], [], [], []
    for number in range(data_line, len(lines) + 1):
        s = lines[number - 1].strip()
        if not s:
            continue
        f = _fields(s)
        if len(f) != len(names):
            if number == len(lines) and not text.endswith(("\n", "\r")) and len(f) < len(names):
                continue        # the last row cut short
            raise fail(path, number, f"{len(f)} fields, the columns ({', '.join(names)}) are {len(names)}")
        t_l.append(parse_float(path, number, names[ti], f[ti]))
        a_l.append(parse_float(path, number, names[ai], f[ai]))
        if tci is not None:
            v = f[tci]
            unit = scale["temperature"]
            if v[-1:] in ("F", "C"):
                unit, v = v[-1], v[:-1]
            c = parse_float(path, number, names[tci], v)
            c_l.append((c - 32.0) / 1.8 if unit == "F" else c)
        rows.append(number)
    if not rows:
        raise fail(path, max(names_line, data_line - 1, 1), "a preamble / header with no data rows")
    t = np.asarray(t_l) * float(scale["time"])
    alt_m = np.asarray(a_l) * float(scale["altitude"])
    check_time(path, rows, t, drop_repeats=False)
    notes: list[str] = []
    first = next((ln.strip() for ln in lines if ln.strip()), "")
    device = first if first.lower().startswith(("perfectflite", "stratologger")) else "PerfectFlite"
    if "numsamps" in pre:
        try:
            n_stated = int(pre["numsamps"])
        except ValueError:
            raise fail(path, pre_line.get("numsamps", 1), f"NumSamps: {pre['numsamps']!r} is not a count") from None
        if n_stated != len(rows):
            notes.append(f"NumSamps {n_stated} but {len(rows)} data rows")
    source = "given"
    ground_m = None
    if "ground elevation" in pre:
        ground_m = _height(path, pre_line["ground elevation"], "Ground Elevation", pre["ground elevation"])
    if site_altitude_m is None and ground_m is not None:
        site_altitude_m, source = ground_m, "the log's 'Ground Elevation'"
    p, how = synthetic_pressure(alt_m, site_altitude_m, source)
    notes.append(how)
    site = 0.0 if site_altitude_m is None else float(site_altitude_m)
    events: dict[str, float] = {}
    prov_extra: dict[str, float] = {}
    if "apogee" in pre:
        apo_m = _height(path, pre_line["apogee"], "Apogee", pre["apogee"])
        prov_extra["own_apogee_m"] = apo_m
        reach = np.nonzero(alt_m >= apo_m - 1e-9)[0]
        if reach.size:
            events["own_apogee"] = float(t[reach[0]])
        else:
            events["own_apogee"] = float(t[int(np.argmax(alt_m))])
            notes.append(f"the stated apogee {pre['apogee']} is above every row (highest {show(alt_m.max() / FT)} ft)"
                         ": its time is the highest row's")
    for key in ("drogue at", "main at"):
        if key in pre:
            notes.append(f"{key.title()}: {pre[key]}")
    notes += gaps_note(t, rows)
    licence, origin = licence_of(path)
    temp = np.asarray(c_l) if tci is not None else None
    provenance = {"source": str(path), "format": "perfectflite", "licence": licence, "origin": origin,
                  "rows": len(rows), "own_computer": device, "synthetic_baro": True,
                  "site_altitude_m": site, "preamble": pre, **prov_extra, "notes": notes}
    if ground_m is not None:
        provenance["ground_elevation_m"] = ground_m
    return FlightRecord(name=path.stem, time_s=t, pressure_pa=p, temperature_c=temp,
                        ground_pressure_pa=float(pressure_pa(site)), events=events, provenance=provenance,
                        row_lines=np.asarray(rows))


__all__ = ["looks_like", "read"]

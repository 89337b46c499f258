"""Featherweight Raven, the FIP ("Featherweight Interface Program") CSV export: every channel in its own group
``Time@NAME, NAME, bILBA`` side by side, each at the channel's own rate. docs/flights.md, "Featherweight". Sample:
``../shared/flights/fusionspace/featherweight-raven-fip.csv``.

What the reader relies on (Featherweight's Raven user manual and FIP export; the shared sample):

* Header: groups ``Time@<channel>``, ``<channel>``, ``bILBA``. Channels include ``Axial Accel (Gs)`` (the Raven's
  high-g axial accelerometer, ~400 samples/s, +1 on the pad), ``Baro (Atm)`` (the barometer, ~20 samples/s, in
  standard atmospheres), ``Temperature (F)``, voltages, currents and the FIP's derived channels in brackets
  (``[Altitude (Baro-Ft-AGL)]`` ...). A group's column ends where its series ends (empty fields after).
* ``bILBA``: ``b`` and four 0/1 flags; the 4th is the Raven's apogee flag (:mod:`.raven`); the Raven's own apogee is
  the first barometer sample with it set.
* The record: the union of the barometer's and the axial accelerometer's sample times (**no sample invented**:
  pressure is NaN at an accelerometer-only time and the acceleration NaN at a barometer-only time; the resampler
  holds each over its own samples), when the accelerometer's series lasts from the barometer's first half second to
  its peak (else it is refused and the notes say why, as :mod:`.raven` does). Pressure = atm x 101325 Pa (also
  ``Pa``, ``kPa``, ``hPa``/``mbar``, ``psi``); the acceleration in ``Gs``/``g`` x g0. Any other unit is an error
  naming the header line.
* Site altitude: ``[Altitude (Baro-Ft-ASL)]`` - ``[Altitude (Baro-Ft-AGL)]`` at their first common sample, when
  both are exported (``provenance["site_altitude_m"]``).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from firmware_model.flights.readers import _channels as ch
from firmware_model.flights.readers._common import (check_time, fail, gaps_note, header_fields, licence_of,
                                                    parse_float, read_text)
from firmware_model.flights.record import FlightRecord
from firmware_model.spec.atmosphere import G0

FT: float = 0.3048
ACCEL_UNITS: dict[str, float] = {"gs": G0, "g": G0, "m/s^2": 1.0, "m/s2": 1.0}


def _is_time(name: str) -> bool:
    return name.startswith("Time@")


def looks_like(text: str) -> bool:
    """A header of ``Time@<channel>`` groups with a ``Baro`` channel."""
    head = header_fields(text, ",")
    return bool(head) and head[0].startswith("Time@") and any(h.startswith("Time@Baro") for h in head)


def _unit(path: Path, line: int, name: str, units: dict[str, float]) -> float:
    m = re.search(r"\(([^()]*)\)\s*\]?$", name)
    unit = m.group(1).strip().lower() if m else ""
    if unit not in units:
        raise fail(path, line, f"{name}: unknown unit {unit!r} (know {', '.join(units)})")
    return units[unit]


_Channel = tuple[list[float], list[float], list[str], list[int]]


def _rows(path: Path, text: str) -> tuple[list[str], int, dict[str, _Channel]]:
    """(header, header line, channel -> (times, values, flags, lines)). A row is walked group by group: a group
    with a time is ``time, value, flags`` (3 fields); a group whose series has ended is two empty fields (FIP drops
    its flags field), so a row has 2 or 3 fields per group; a row with every group's 3 fields is read as it is."""
    lines = text.splitlines()
    number, head_text = next((i, ln) for i, ln in enumerate(lines, start=1) if ln.strip())
    head = [h.strip() for h in head_text.split(",")]
    while head and not head[-1]:
        head.pop()
    if len(head) % 3 or not all(head[j].startswith("Time@") and head[j + 1] == head[j][5:] and head[j + 2] == "bILBA"
                                 for j in range(0, len(head), 3)):
        raise fail(path, number, "the header is not Time@<channel>, <channel>, bILBA groups")
    names = [head[j + 1] for j in range(0, len(head), 3)]
    out: dict[str, _Channel] = {n: ([], [], [], []) for n in names}
    for num in range(number + 1, len(lines) + 1):
        fields = lines[num - 1].split(",")
        if not any(f.strip() for f in fields):
            continue
        full = len(fields) >= len(head)
        pos = 0
        for name in names:
            if pos >= len(fields):
                break
            ts = fields[pos].strip()
            if not ts:
                if pos + 1 < len(fields) and fields[pos + 1].strip():
                    raise fail(path, num, f"{name}: a value with no time")
                pos += 3 if full else 2
                continue
            if pos + 1 >= len(fields):
                raise fail(path, num, f"{name}: row ends after the time")
            t, v, f, ln = out[name]
            t.append(parse_float(path, num, "Time@" + name, ts))
            v.append(parse_float(path, num, name, fields[pos + 1]))
            f.append(fields[pos + 2].strip() if pos + 2 < len(fields) else "")
            ln.append(num)
            pos += 3
        if any(f.strip() for f in fields[pos:]):
            raise fail(path, num, f"{len(fields)} fields do not split into the header's {len(names)} channel groups")
    return head, number, out


def _channel(path: Path, name: str, got: _Channel) -> tuple[np.ndarray, np.ndarray, list[str], list[int]]:
    t, v, f, ln = got
    if len(t) < 2:
        raise fail(path, ln[-1] if ln else 1, f"channel {name!r}: {len(t)} samples (need 2)")
    tt = np.asarray(t)
    check_time(path, ln, tt, drop_repeats=False)
    return tt, np.asarray(v), f, ln


def read(path: Path) -> FlightRecord:
    """Read a Raven FIP export: barometer and axial accelerometer merged on their own sample times."""
    text = read_text(path)
    if not looks_like(text):
        raise fail(path, 1, "not a Raven FIP export (no Time@<channel> groups with a Baro channel)")
    head, head_line, found = _rows(path, text)
    baro = next(n for n in found if n.startswith("Baro"))
    p_scale = _unit(path, head_line, baro, ch.PRESSURE_UNITS)
    tb, pb, flags, lb = _channel(path, baro, found[baro])
    pb = pb * p_scale
    bad = np.nonzero(~(pb > 0))[0]
    if bad.size:
        raise fail(path, lb[int(bad[0])], f"{baro}: {pb[bad[0]] / p_scale:g} is not a positive pressure")
    notes: list[str] = []
    parts = [(tb, lb)]
    accel_name = next((n for n in found if n.startswith("Axial Accel")), None)
    axis = tb
    acc = None
    if accel_name is None:
        notes.append("no Axial Accel channel: barometer only")
    else:
        a_scale = _unit(path, head_line, accel_name, ACCEL_UNITS)
        ta, ga, _, la = _channel(path, accel_name, found[accel_name])
        why = ch.refusal(ta, tb, pb)
        if why is not None:
            notes.append(why)
        else:
            axis = ch.merge(tb, ta)
            acc = ch.place(axis, ta, ga * a_scale)
            parts.append((ta, la))
            notes.append(f"accelerometer {accel_name}: {ta.size} samples at "
                         f"{1.0 / float(np.median(np.diff(ta))):.0f} Hz, barometer {tb.size} samples at "
                         f"{1.0 / float(np.median(np.diff(tb))):.0f} Hz: merged on their {axis.size} sample times, "
                         "each NaN where it has no sample")
            if ta[-1] < tb[-1] - 1.0:
                notes.append(f"the accelerometer's series ends at {ta[-1]:g} s, the barometer's at {tb[-1]:g} s")
    p = ch.place(axis, tb, pb)
    temp = None
    tname = next((n for n in found if n.startswith("Temperature")), None)
    if tname is not None and tname.endswith(("(F)", "(C)")) and len(found[tname][0]) >= 2:
        tt, tv, _, _ = _channel(path, tname, found[tname])
        tv = (tv - 32.0) / 1.8 if tname.endswith("(F)") else tv
        temp = ch.place(axis, tt, tv) if np.all(np.isin(tt, axis)) else None
    events: dict[str, float] = {}
    for i, f in enumerate(flags):
        if len(f) == 5 and f[0] == "b" and f[4] == "1":
            events["own_apogee"] = events["raven_apogee"] = float(tb[i])
            break
    if "own_apogee" not in events:
        notes.append("no apogee flag (4th bILBA flag) set in the barometer series")
    prov_extra: dict[str, float] = {}
    asl, agl = "[Altitude (Baro-Ft-ASL)]", "[Altitude (Baro-Ft-AGL)]"
    if asl in found and agl in found and found[asl][0] and found[agl][0]:
        t1, h1, _, _ = _channel(path, asl, found[asl])
        t2, h2, _, _ = _channel(path, agl, found[agl])
        common, i1, i2 = np.intersect1d(t1, t2, return_indices=True)
        if common.size:
            prov_extra["site_altitude_m"] = float(h1[i1[0]] - h2[i2[0]]) * FT
    notes += gaps_note(tb, lb, limit_s=2.0)
    licence, origin = licence_of(path)
    provenance = {"source": str(path), "format": "raven_fip", "licence": licence, "origin": origin,
                  "rows": int(axis.size), "baro_rows": int(tb.size), "own_computer": "Raven", "synthetic_baro": False,
                  **prov_extra, "notes": notes}
    return FlightRecord(name=path.stem, time_s=axis, pressure_pa=p, accel_mps2=acc, temperature_c=temp,
                        events=events, provenance=provenance, row_lines=ch.place_lines(axis, parts))


__all__ = ["looks_like", "read"]

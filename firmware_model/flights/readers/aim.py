"""Entacore AIM (AIM USB / AIM XTRA) CSV export: each channel group has its own ``time`` column.
docs/flights.md, "Entacore AIM". Sample: ``../shared/flights/fusionspace/aim-xtra.csv``.

What the reader relies on (Entacore's AIM export and the shared sample):

* One header line; every column named ``time`` starts a channel group: ``time, Gyro X, Gyro Y, Gyro Z``,
  ``time, pressure, Pressure MSL, Pressure AGL``, ``time, acceleration``, ``time, lat. X accel., lat. Y accel.``,
  ``time, launch detect, apogee detect, A cont., ...``, ``time, temperature`` .... Every row fills every group
  (the groups' clocks differ: rows are not common sample times). Time in s, 0 = launch detect.
* ``pressure`` in Pa (the AIM's barometer), ``Pressure AGL`` / ``Pressure MSL`` its altitudes in m; ``acceleration``
  the axial accelerometer in g (+1 on the pad). The header names no units: a pressure outside 15-120 kPa or a pad
  acceleration outside 0.5-1.5 is refused as a unit the reader does not know, naming the line.
* A row whose times go back (the shared sample's last row: its peak sample appended after downsampling) is put in
  time order and named in the notes when its times are new and such rows are at most 1 % of the rows; more, or a
  repeated time, is an error naming the line.
* The record: the union of the pressure group's and the acceleration group's times, no sample invented (each NaN
  where it did not sample); an acceleration series that does not last from the first half second to the barometric
  peak is refused (noted). The AIM's own apogee: the first row of the flag group with ``apogee detect`` = 1. Site
  altitude: ``Pressure MSL - Pressure AGL`` at the first pressure sample (``provenance["site_altitude_m"]``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from firmware_model.flights.readers import _channels as ch
from firmware_model.flights.readers._common import Table, fail, gaps_note, header_fields, licence_of, read_text, show
from firmware_model.flights.record import FlightRecord
from firmware_model.spec.atmosphere import G0


def _is_time(name: str) -> bool:
    return name.strip().lower() == "time"


def looks_like(text: str) -> bool:
    """A header whose first column is ``time`` and that has ``time`` groups holding ``pressure`` and
    ``Pressure AGL``."""
    head = header_fields(text, ",")
    return bool(head) and _is_time(head[0]) and "pressure" in head and "Pressure AGL" in head \
        and sum(_is_time(h) for h in head) >= 2


def read(path: Path) -> FlightRecord:
    """Read an AIM export: pressure and axial acceleration merged on their own sample times."""
    text = read_text(path)
    if not looks_like(text):
        raise fail(path, 1, "not an AIM export (time groups with pressure and Pressure AGL)")
    table = Table(path, text, ",", min_rows=2, allow_duplicates=True)
    head = table.header
    found = {head[j]: (tc, vc) for tc, vc in ch.groups(head, _is_time) for j in vc}
    notes = list(table.notes)
    tc, vc = found["pressure"]
    tp, vals, _, lp = ch.series(table, tc, vc, reorder=notes)
    p = vals[vc.index(head.index("pressure"))]
    ok = np.isfinite(p)
    bad = np.nonzero(ok & ~((p > 15000) & (p < 120000)))[0]
    if bad.size:
        raise fail(path, lp[int(bad[0])], f"pressure {show(p[bad[0]])}: not a pressure in Pa (the AIM writes Pa; "
                                          "this unit is not known)")
    prov_extra: dict[str, float] = {}
    if "Pressure MSL" in head and head.index("Pressure MSL") in vc:
        msl = vals[vc.index(head.index("Pressure MSL"))]
        agl = vals[vc.index(head.index("Pressure AGL"))]
        both = np.nonzero(np.isfinite(msl) & np.isfinite(agl))[0]
        if both.size:
            prov_extra["site_altitude_m"] = float(msl[both[0]] - agl[both[0]])
    axis, acc, parts = tp, None, [(tp, lp)]
    if "acceleration" not in found:
        notes.append("no acceleration group: barometer only")
    else:
        tca, vca = found["acceleration"]
        ta, avals, _, la = ch.series(table, tca, vca, reorder=notes)
        g = avals[vca.index(head.index("acceleration"))]
        pad = g[ta < min(0.0, float(ta[0]) + 5.0)] if np.any(ta < 0) else g[:5]
        pad_g = float(np.nanmedian(pad)) if np.isfinite(pad).any() else float("nan")
        if not 0.5 <= pad_g <= 1.5:
            raise fail(path, la[0], f"acceleration reads {pad_g:.3g} on the pad: not in g (the AIM writes g; this "
                                    "unit is not known)")
        why = ch.refusal(ta, tp[ok], p[ok])
        if why is not None:
            notes.append(why)
        else:
            axis = ch.merge(tp, ta)
            acc = ch.place(axis, ta, g * G0)
            parts.append((ta, la))
            notes.append(f"pressure {tp.size} samples, acceleration {ta.size} samples: merged on their {axis.size} "
                         "sample times, each NaN where it has no sample")
    pressure = ch.place(axis, tp, p)
    events: dict[str, float] = {}
    if "apogee detect" in found:
        tce, vce = found["apogee detect"]
        te, evals, _, _ = ch.series(table, tce, vce, reorder=notes)
        names = [head[j] for j in vce]
        for key, name in (("own_apogee", "apogee detect"), ("aim_launch", "launch detect")):
            if name in names:
                hit = np.nonzero(evals[names.index(name)] == 1)[0]
                if hit.size:
                    events[key] = float(te[hit[0]])
        if "own_apogee" in events:
            events["aim_apogee"] = events["own_apogee"]
        else:
            notes.append("no row with apogee detect = 1: the AIM's own apogee unknown")
    notes += gaps_note(tp, lp, limit_s=2.5)
    licence, origin = licence_of(path)
    provenance = {"source": str(path), "format": "aim", "licence": licence, "origin": origin, "rows": int(axis.size),
                  "baro_rows": int(tp.size), "own_computer": "AIM", "synthetic_baro": False, **prov_extra,
                  "notes": notes}
    return FlightRecord(name=path.stem, time_s=axis, pressure_pa=pressure, accel_mps2=acc, events=events,
                        provenance=provenance, row_lines=ch.place_lines(axis, parts))


__all__ = ["looks_like", "read"]

"""Shared parts of the readers of exports that give **every channel its own time column** (Featherweight Raven FIP,
Entacore AIM): finding the channel groups, reading one group's rows, and merging several channels onto one time
axis **without inventing samples** (the union of their sample times; a channel is NaN at a time it did not sample),
plus choosing the accelerometer axis that reads +1 g on the pad.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from firmware_model.flights.readers._common import Table, check_time, fail, parse_float
from firmware_model.spec.atmosphere import G0

#: Pressure units the exports name, in Pa (1 atm = 101325 Pa; 1 psi = 6894.757 Pa).
PRESSURE_UNITS: dict[str, float] = {"atm": 101325.0, "pa": 1.0, "kpa": 1000.0, "hpa": 100.0, "mbar": 100.0,
                                    "psi": 6894.757293168}


def groups(header: list[str], is_time) -> list[tuple[int, list[int]]]:
    """(time column, its value columns) for every run of columns that starts with a time column."""
    out: list[tuple[int, list[int]]] = []
    for j, name in enumerate(header):
        if is_time(name):
            out.append((j, []))
        elif out:
            out[-1][1].append(j)
    return out


def series(table: Table, time_col: int, value_cols: list[int], *, scale: float = 1.0, reorder: list[str] | None = None
           ) -> tuple[np.ndarray, list[np.ndarray], list[str], list[int]]:
    """One channel group: its rows are those whose time field is filled (a group ends where its series ends,
    later rows leave it empty); returns (time s, [values], raw text of the last value column, file lines). An empty
    value in a filled row is NaN. Time must increase (an error naming the line otherwise) unless ``reorder`` (a
    list for notes) is given: then rows out of time order are put in order when their times are new and they are at
    most 1 % of the rows (each named in the notes); a repeated time or more such rows stay an error."""
    path = table.path
    t, lines, raw = [], [], []
    vals: list[list[float]] = [[] for _ in value_cols]
    for num, fields in table.rows:
        ts = fields[time_col].strip()
        if not ts:
            continue
        t.append(parse_float(path, num, table.header[time_col], ts) * scale)
        for k, j in enumerate(value_cols):
            vals[k].append(parse_float(path, num, table.header[j], fields[j], allow_empty=True))
        raw.append(fields[value_cols[-1]].strip() if value_cols else "")
        lines.append(num)
    if len(t) < 2:
        raise fail(path, table.header_line, f"channel {table.header[time_col]!r}: {len(t)} samples (need 2)")
    tt = np.asarray(t)
    if reorder is not None:
        back = [i for i in range(1, tt.size) if tt[i] <= np.max(tt[:i])]
        if back and len(back) <= max(1, tt.size // 100) and np.unique(tt).size == tt.size:
            order = np.argsort(tt, kind="stable")
            for i in back:
                reorder.append(f"line {lines[i]}: {table.header[time_col]} {tt[i]:g} s after {np.max(tt[:i]):g} s: "
                               "put in time order")
            tt = tt[order]
            vals = [list(np.asarray(v)[order]) for v in vals]
            raw = [raw[i] for i in order]
            lines = [lines[i] for i in order]
    check_time(path, lines, tt, drop_repeats=False)
    return tt, [np.asarray(v) for v in vals], raw, lines


def merge(*axes: np.ndarray) -> np.ndarray:
    """The union of the channels' sample times (sorted, each time once)."""
    return np.unique(np.concatenate(axes))


def place(axis: np.ndarray, t: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``values`` sampled at ``t`` on ``axis`` (a superset of ``t``): NaN at the times the channel did not sample."""
    out = np.full(axis.shape, np.nan)
    out[np.searchsorted(axis, t)] = values
    return out


def place_lines(axis: np.ndarray, parts: list[tuple[np.ndarray, list[int]]]) -> np.ndarray:
    """The file line of each time of ``axis``: the first channel (in ``parts`` order) that sampled it."""
    out = np.zeros(axis.shape, dtype=np.int64)
    for t, lines in reversed(parts):
        out[np.searchsorted(axis, t)] = lines
    return out


def refusal(ta: np.ndarray, tb: np.ndarray, pb: np.ndarray) -> str | None:
    """Why an accelerometer series sampled at ``ta`` must not be used with a barometer ``pb`` sampled at ``tb``
    (None when it may): it must start by the barometer's first half second and last to the barometer's peak (its
    lowest pressure); a series that stops in the ascent would be held at its last value for the rest of the flight
    (the Raven export of :mod:`.raven` stops at 4.55 s of a 17.4 s ascent)."""
    peak = float(tb[int(np.nanargmin(pb))])
    if ta[0] <= tb[0] + 0.5 and ta[-1] >= peak:
        return None
    return (f"accelerometer REFUSED: its series covers {ta[0]:g}..{ta[-1]:g} s, the barometer {tb[0]:g}..{tb[-1]:g} s "
            f"with its peak at {peak:g} s")


def pad_axis(path: Path, line: int, pad: dict[str, np.ndarray], tolerance_g: float = 0.25) -> tuple[str, float]:
    """The accelerometer axis that reads about 1 g (in g) on the pad and its sign (the axis along gravity is the
    rocket's on a vertical pad): (column name, +1 or -1). Error naming ``line`` when no axis or more than one does."""
    hits = []
    for name, v in pad.items():
        v = v[np.isfinite(v)]
        if v.size and abs(abs(float(np.median(v))) - 1.0) <= tolerance_g:
            hits.append((name, 1.0 if float(np.median(v)) > 0 else -1.0))
    if len(hits) != 1:
        seen = ", ".join(f"{k} {float(np.nanmedian(v)):.2f} g" for k, v in pad.items())
        raise fail(path, line, f"cannot tell the rocket's axis: on the pad {seen} (want exactly one axis at +-1 g)")
    return hits[0]


__all__ = ["G0", "PRESSURE_UNITS", "groups", "merge", "pad_axis", "place", "place_lines", "refusal", "series"]

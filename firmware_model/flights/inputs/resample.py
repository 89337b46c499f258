"""Resampling a log's irregular time axis onto the firmware's grid dt = 2^-k, explicitly and reported.

The grid: ``t_i = (n0 + i) * 2^-k`` with integers ``n0 = ceil(t_start / dt)`` and i = 0, 1, ...: every grid time
is an exact binary fraction computed from its index (no accumulated sum, so no drift), and the first grid time is
the first multiple of dt at or after ``t_start``.

Methods: ``hold`` (zero-order hold: the last input sample at or before the grid time, what a register updated by
the log would hold) and ``linear`` (linear interpolation between the input samples around the grid time). Missing
values (NaN) in a column are skipped: that column is held/interpolated over its valid samples only.

The :class:`ResampleReport` says what happened, defined the same way for both methods through each grid sample's
*source*, the last input row at or before it: ``repeated`` = grid samples whose source is the previous grid
sample's (the input was up-sampled), ``dropped`` = input rows inside the grid's span that are no grid sample's
source (down-sampled); ``gaps`` = input intervals longer than 2 input periods (the local period: the median
interval of the rate segment it lies in); ``rate_changes`` = where the log's median interval changes by more than
a factor 1.5 for at least 20 intervals (AltosUI: 100 -> 10 samples/s after apogee).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from firmware_model.runtime.errors import UserError

METHODS: tuple[str, ...] = ("hold", "linear")


@dataclass(frozen=True)
class RateChange:
    time_s: float          # time of the first interval at the new rate
    from_hz: float
    to_hz: float


@dataclass(frozen=True)
class Gap:
    start_s: float
    end_s: float
    periods: float         # length in local input periods


@dataclass
class ResampleReport:
    """What the resampling did (printed by the CLI: :meth:`summary`)."""

    method: str
    k: int
    dt_s: float
    t_start_s: float
    t_end_s: float
    input_rows: int                 # input rows inside [t_start, t_end]
    output_samples: int
    repeated: int                   # grid samples reusing the previous grid sample's source row
    dropped: int                    # input rows inside the span that are no grid sample's source
    gaps: list[Gap] = field(default_factory=list)
    rate_changes: list[RateChange] = field(default_factory=list)
    input_rate_hz: float = math.nan      # median input rate over the span
    missing: dict[str, int] = field(default_factory=dict)  # NaN values skipped per column
    before_log: int = 0             # grid samples before the log's first row (filled by the caller's rule)
    after_log: int = 0              # grid samples after the log's last row (held at the last value)
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def summary(self) -> str:
        """A few lines for the CLI."""
        out = [f"resampled {self.input_rows} log rows ({self.input_rate_hz:.4g} samples/s median) to "
               f"{self.output_samples} samples at dt = 2^-{self.k} s ({1 / self.dt_s:g}/s, {self.method}), "
               f"t = {self.t_start_s:.6g} .. {self.t_end_s:.6g} s",
               f"  {self.repeated} samples repeat an input row, {self.dropped} input rows dropped"]
        for rc in self.rate_changes:
            out.append(f"  log rate change at t = {rc.time_s:.3f} s: {rc.from_hz:.4g} -> {rc.to_hz:.4g} samples/s")
        if self.gaps:
            worst = max(self.gaps, key=lambda g: g.end_s - g.start_s)
            out.append(f"  {len(self.gaps)} gaps longer than 2 input periods "
                       f"(longest {worst.end_s - worst.start_s:.3f} s at t = {worst.start_s:.3f} s)")
        for name, n in self.missing.items():
            if n:
                out.append(f"  {name}: {n} missing values skipped")
        if self.before_log or self.after_log:
            out.append(f"  {self.before_log} samples before the log's first row, {self.after_log} after its last")
        out += [f"  {n}" for n in self.notes]
        return "\n".join(out)


def grid(k: int, t_start: float, t_end: float) -> np.ndarray:
    """The grid ``(n0 + i) * 2^-k`` covering [t_start, t_end] (first point >= t_start, last <= t_end)."""
    if not isinstance(k, (int, np.integer)) or not 0 <= k <= 16:
        raise UserError(f"resample: k={k!r} must be an integer 0..16 (dt = 2^-k s)")
    if not (math.isfinite(t_start) and math.isfinite(t_end)) or t_end < t_start:
        raise UserError(f"resample: empty or invalid span {float(t_start)!r} .. {float(t_end)!r} s")
    scale = float(1 << int(k))
    n0 = math.ceil(t_start * scale)
    n1 = math.floor(t_end * scale)
    if n1 < n0:
        raise UserError(f"resample: span {float(t_start)!r} .. {float(t_end)!r} s holds no multiple of 2^-{k} s")
    return np.arange(n0, n1 + 1, dtype=np.float64) / scale


def rate_segments(t: np.ndarray, window: int = 21, factor: float = 1.5, persist: int = 20
                  ) -> tuple[np.ndarray, list[RateChange]]:
    """Local input period per interval (rolling median over ``window`` intervals, constant within a segment) and
    the rate changes between segments."""
    d = np.diff(t)
    if d.size == 0:
        return d, []
    half = window // 2
    padded = np.pad(d, half, mode="edge")
    rolled = np.lib.stride_tricks.sliding_window_view(padded, window)
    local = np.median(rolled, axis=1)
    # segment: start a new one where the local period leaves [p/f, p*f] of the current segment's period
    starts = [0]
    period = local[0]
    i = 0
    while i < local.size:
        if not (period / factor <= local[i] <= period * factor):
            j = min(local.size, i + persist)
            seg = local[i:j]
            if j - i == persist and np.all((seg < period / factor) | (seg > period * factor)):
                new = float(np.median(seg))
                # the first interval at the new rate: the rolling median turns up to half a window early
                mid = math.sqrt(period * new)
                lo = max(starts[-1] + 1, i - half)
                cand = np.nonzero((d[lo:j] > mid) if new > period else (d[lo:j] < mid))[0]
                start = lo + int(cand[0]) if cand.size else i
                starts.append(start)
                period = new
                i = max(j, start + 1)
                continue
        i += 1
    bounds = starts + [d.size]
    period_of = np.empty_like(d)
    periods = []
    for a, b in zip(bounds[:-1], bounds[1:]):
        p = float(np.median(d[a:b]))
        period_of[a:b] = p
        periods.append(p)
    changes = [RateChange(time_s=float(t[s]), from_hz=1.0 / periods[n], to_hz=1.0 / periods[n + 1])
               for n, s in enumerate(starts[1:])]
    return period_of, changes


def resample(t: np.ndarray, columns: dict[str, np.ndarray | None], k: int, method: str = "linear",
             t_start: float | None = None, t_end: float | None = None
             ) -> tuple[np.ndarray, dict[str, np.ndarray | None], ResampleReport]:
    """Resample ``columns`` (each (n,) on the strictly increasing time axis ``t``, or None) onto the 2^-k grid
    over [t_start, t_end] (default: the log's span). Grid samples outside the log's span hold the first / last
    valid value (counted in the report as ``before_log`` / ``after_log``)."""
    if method not in METHODS:
        raise UserError(f"resample: method {method!r}: known: {', '.join(METHODS)}")
    t = np.asarray(t, dtype=np.float64)
    if t.ndim != 1 or t.size < 2 or not np.all(np.diff(t) > 0):
        raise UserError("resample: the input time axis must be strictly increasing with at least 2 rows")
    a = float(t[0]) if t_start is None else float(t_start)
    b = float(t[-1]) if t_end is None else float(t_end)
    g = grid(k, a, b)
    out: dict[str, np.ndarray | None] = {}
    missing: dict[str, int] = {}
    for name, col in columns.items():
        if col is None:
            out[name] = None
            continue
        y = np.asarray(col, dtype=np.float64)
        if y.shape != t.shape:
            raise UserError(f"resample: column {name} has shape {y.shape}, time has {t.shape}")
        ok = np.isfinite(y)
        missing[name] = int((~ok).sum())
        if ok.sum() == 0:
            raise UserError(f"resample: column {name} has no finite values")
        tv, yv = t[ok], y[ok]
        if method == "linear":
            out[name] = np.interp(g, tv, yv)
        else:
            idx = np.searchsorted(tv, g, side="right") - 1
            out[name] = yv[np.clip(idx, 0, tv.size - 1)]
    src = np.searchsorted(t, g, side="right") - 1          # last row at or before each grid time (-1: before)
    srcc = np.clip(src, 0, t.size - 1)
    repeated = int(np.sum(srcc[1:] == srcc[:-1]))
    lo = np.searchsorted(t, g[0], side="left")
    hi = np.searchsorted(t, g[-1], side="right")
    rows_in_span = int(hi - lo)
    used = np.unique(srcc[(src >= lo)])
    dropped = rows_in_span - int(used.size)
    period_of, changes = rate_segments(t)
    d = np.diff(t)
    gaps = [Gap(float(t[i]), float(t[i + 1]), float(d[i] / period_of[i]))
            for i in np.nonzero(d > 2.0 * period_of)[0] if t[i + 1] > g[0] and t[i] < g[-1]]
    changes = [c for c in changes if g[0] <= c.time_s <= g[-1]]
    span_d = d[(t[:-1] >= g[0]) & (t[1:] <= g[-1])]
    report = ResampleReport(
        method=method, k=int(k), dt_s=2.0 ** -int(k), t_start_s=float(g[0]), t_end_s=float(g[-1]),
        input_rows=rows_in_span, output_samples=int(g.size), repeated=repeated, dropped=dropped,
        gaps=gaps, rate_changes=changes, input_rate_hz=float(1.0 / np.median(span_d)) if span_d.size else math.nan,
        missing=missing, before_log=int(np.sum(g < t[0])), after_log=int(np.sum(g > t[-1])))
    return g, out, report

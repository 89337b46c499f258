"""PNG figures of runs and sweeps (matplotlib, imported lazily; the Agg backend, no display needed).

* :func:`plot_run`: Schultz n.d.'s favourite gnuplot view: raw and filtered altitude (left axis) with the velocity
  estimate on a second axis, event markers (liftoff, apogee, prediction, reference/truth apogee, AltOS), shaded
  Mach-lockout and barometer-invalid samples; ``zoom`` = a window around apogee.
* :func:`plot_ratio_sweep`: Schultz 2002 Figure 10: apogee error against R/q (log axis), one line per flight.
* :func:`plot_k_sweep`: apogee error against k, one panel per method.

Every function returns the PNG bytes; callers write them atomically.
"""

from __future__ import annotations

import io
from typing import Any, Sequence

import numpy as np

from firmware_model.model.trace import EVENT_BITS
from firmware_model.runtime.errors import UserError


def _pyplot() -> Any:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:  # pragma: no cover - matplotlib is an optional extra
        raise UserError("plot: matplotlib is not installed (pip install 'fwemu[plot]')") from None
    return plt


def _png(fig: Any) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=120)
    import matplotlib.pyplot as plt

    plt.close(fig)
    return buf.getvalue()


def _spans(t: np.ndarray, mask: np.ndarray) -> list[tuple[float, float]]:
    """(start, end) times of the runs of True in ``mask``."""
    out = []
    m = np.asarray(mask, dtype=bool)
    if not m.any():
        return out
    edges = np.diff(np.concatenate([[0], m.astype(np.int8), [0]]))
    starts, ends = np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0] - 1
    for a, b in zip(starts, ends):
        out.append((float(t[a]), float(t[b])))
    return out


def plot_run(run: Any, *, zoom: bool = False, title: str = "", reference_s: float | None = None,
             altos_s: float | None = None, zoom_halfwidth_s: float | None = None,
             own_computer: str = "AltOS") -> bytes:
    """PNG of a run (:class:`firmware_model.flights.inputs.runcsv.RunTable`: ``time_s``, ``raw_altitude_m``,
    ``filtered_altitude_m``, ``velocity_mps``, ``events``, ``event_times()``)."""

    plt = _pyplot()
    t = np.asarray(run.time_s, dtype=np.float64)
    ev = np.asarray(run.events, dtype=np.int64)
    marks = run.event_times()
    apogee = marks.get("APOGEE")
    centre = apogee if apogee is not None else reference_s
    if centre is None:
        centre = float(t[int(np.nanargmax(run.filtered_altitude_m))])
    sel = np.ones(t.shape, dtype=bool)
    if zoom:
        half = zoom_halfwidth_s or 5.0
        lo, hi = centre - half, centre + half
        for extra in (reference_s, altos_s):
            if extra is not None:
                lo, hi = min(lo, extra - 1.0), max(hi, extra + 1.0)
        sel = (t >= lo) & (t <= hi)
        if sel.sum() < 2:
            raise UserError(f"plot --zoom: fewer than 2 samples within {lo:.2f}..{hi:.2f} s")
    fig, ax = plt.subplots(figsize=(10, 5.6))
    ax2 = ax.twinx()
    l1, = ax.plot(t[sel], np.asarray(run.raw_altitude_m)[sel], color="0.6", lw=0.8, label="raw altitude")
    l2, = ax.plot(t[sel], np.asarray(run.filtered_altitude_m)[sel], color="C0", lw=1.4, label="filtered altitude")
    l3, = ax2.plot(t[sel], np.asarray(run.velocity_mps)[sel], color="C3", lw=1.0, label="velocity")
    handles = [l1, l2, l3]
    ax2.axhline(0.0, color="C3", lw=0.5, ls=":")
    for name, colour in (("MACH_LOCKOUT", "C1"), ("BARO_INVALID", "C4")):
        for i, (a, b) in enumerate(_spans(t[sel], (ev[sel] & EVENT_BITS[name]) != 0)):
            ax.axvspan(a, b, color=colour, alpha=0.15, lw=0, label=name.lower().replace("_", " ") if i == 0 else None)
    styles = {"LIFTOFF": ("C2", "--"), "ARMED": ("C8", ":"), "APOGEE": ("k", "-"), "APOGEE_PREDICTED": ("k", ":"),
              "ACC_CLIP": ("C6", "--"), "CLIP_CLEAR": ("C6", ":")}     # the clip latched / the speed known again
    lo_t, hi_t = float(t[sel][0]), float(t[sel][-1])
    for name, when in marks.items():
        if name in styles and when is not None and lo_t <= when <= hi_t:
            c, ls = styles[name]
            handles.append(ax.axvline(when, color=c, ls=ls, lw=1.2, label=f"{name.lower()} {when:.3f} s"))
    phase_times = run.phase_times() if callable(getattr(run, "phase_times", None)) else {}
    for name, when in phase_times.items():         # the firmware's PHASE word: a thin line where each phase begins
        if lo_t <= when <= hi_t and name in ("BOOST", "COAST", "DESCENT"):
            ax.axvline(when, color="0.35", ls=(0, (1, 3)), lw=0.9)
            ax.annotate(name.lower(), (when, 1.0), xycoords=("data", "axes fraction"), rotation=90, va="top",
                        ha="right", fontsize=7, color="0.35")
    for label, when, c in (("reference apogee", reference_s, "C2"), (f"{own_computer} apogee", altos_s, "C5")):
        if when is not None and lo_t <= when <= hi_t:
            handles.append(ax.axvline(when, color=c, ls="-.", lw=1.2, label=f"{label} {when:.3f} s"))
    ax.set_xlabel("time (s, the log's own origin)")
    ax.set_ylabel("altitude above the pad (m)")
    ax2.set_ylabel("velocity (m/s)")
    ax.grid(True, alpha=0.3)
    ax.set_title(title + (" (zoom around apogee)" if zoom else ""))
    spans = [h for h in ax.patches if h.get_label() and not h.get_label().startswith("_")]
    ax.legend(handles=handles + spans, loc="upper left", fontsize=8, framealpha=0.85)
    fig.tight_layout()
    return _png(fig)


def plot_ratio_sweep(res: Any, title: str = "") -> bytes:
    """PNG of a ratio sweep (Schultz 2002 Figure 10): error (s) against R/q, log x-axis, one line per flight."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8.5, 5))
    x = np.asarray(res.axis, dtype=np.float64)
    for f in res.flights:
        y = np.array([np.nan if e is None else e for e in res.errors[f]])
        ax.semilogx(x, y, marker="o", ms=3, label=f)
        miss = np.isnan(y)
        if miss.any():
            ax.semilogx(x[miss], np.zeros(miss.sum()), "x", color=ax.lines[-1].get_color(), ms=7)
        unc = res.reference.get(f, {}).get("uncertainty_s") or 0.0
        if unc:
            ax.fill_between(x, -unc, unc, color=ax.lines[-1].get_color(), alpha=0.08, lw=0)
    ax.axhline(0, color="k", lw=0.6)
    ax.set_xlabel("R/q (measurement variance / model variance)")
    ax.set_ylabel("apogee error (s, detection - reference; + late)")
    ax.set_title(title or f"{res.method}: apogee error against tuning ratio (x at 0: never fired)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return _png(fig)


def plot_k_sweep(res: Any, title: str = "") -> bytes:
    """PNG of a k sweep: error (s) against k, one panel per method, one line per flight."""
    plt = _pyplot()
    methods: Sequence[str] = list(res.per_method)
    n = len(methods)
    cols = min(3, n)
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.3 * rows), squeeze=False)
    x = np.asarray(res.axis)
    for ax, m in zip(axes.flat, methods):
        for f in res.flights:
            y = np.array([np.nan if e is None else e for e in res.per_method[m][f]])
            ax.plot(x, y, marker="o", ms=3, label=f)
        ax.axhline(0, color="k", lw=0.6)
        ax.set_title(m, fontsize=10)
        ax.set_xticks(x)
        ax.grid(True, alpha=0.3)
        ax.set_xlabel("k (dt = 2^-k s)")
        ax.set_ylabel("error (s)")
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    axes.flat[0].legend(fontsize=6)
    fig.suptitle(title or "apogee error against sample period")
    fig.tight_layout()
    return _png(fig)


__all__ = ["plot_run", "plot_ratio_sweep", "plot_k_sweep"]

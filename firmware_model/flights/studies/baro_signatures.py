"""Measure what a barometer really reads on a fast flight: the signatures of issue 20 on the shared logs
(docs/flights.md, "Barometer signatures of real flights").

For each log the **barometric altitude** (standard atmosphere, relative to the pad pressure) is compared with an
**accelerometer trajectory**: the axial acceleration integrated twice from liftoff (AltOS's ``acceleration``
column is the axial specific force minus the pad reading, i.e. the kinematic acceleration of a vertical flight),
then scaled (``z_cal = (1 + s) z``, least squares) on the slow coast before the accelerometer's apogee (Mach <
:data:`CAL_MACH`, where the pressure error is small). The scale (-3 to -8 %) is mostly the real atmosphere: a
barometric altitude is a standard-atmosphere altitude, and the air at Spaceport America was ~25 K warmer than
standard (plus the flight's tilt). The accelerometer speed is not scaled: it matches AltOS's own ``speed`` column
to 0.5-1.5 m/s. The residual ``r = baro - z_cal`` over the first :data:`WINDOW_S` s is the barometer's
error; Mach = accelerometer speed / standard speed
of sound at the pad altitude + z (warmer air would lower it by a few per cent).

Measured per log (:func:`measure`):

* **dip**: the most negative residual before the Mach peak + 3 s (pressure reads high), its depth, the time it
  stays below half its depth (``duration_s``), and the Mach number where it first passes 10 % of its depth
  (onset) and where it last is below 10 % of its depth inside the window (end; ``None`` when it never recovers
  in the window);
* **jump**: the largest rise of the residual within :data:`JUMP_WINDOW_S` (a shock passing the port), with the
  Mach number at its start;
* **noise**: the largest deviation of the residual from its 0.25 s running median (a burst), against the same
  on the pad;
* **ejection**: around each recovery event of the log (AltOS's first ``drogue`` and ``main`` rows, CATS's
  ``EV_APOGEE``) the largest deviation of the barometric altitude from a quadratic fitted over the 3 s before
  the event, within 1.5 s after it, and how long it stays above half of that; the rms of that deviation over the
  1.5 s is the noise at separation.

The CATS computer of the same piccard flight has no usable accelerometer trajectory of its own here (raw IMU
counts of three sensors); its barometers are compared with the TeleMega's calibrated trajectory after aligning
the two clocks by the lag that best matches the two barometric altitudes on the coast (12-30 s).

Also per barometer (:func:`boost_port_error`, issue 30): the port's error during the boost as a fraction of the
dynamic pressure, against the same trajectory, and the lowest barometric height it read in boost.

``python -m firmware_model.flights.studies.baro_signatures [--png FILE] [--model-png FILE]`` prints the Markdown tables
and
writes the figures (the second: the measured residuals beside the model's error on four scenarios).
AltOS is GPL: this reads the CSV columns (a format fact), nothing of its code.
"""

from __future__ import annotations

import argparse
import csv
import io
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from firmware_model.flights.evaluation.evalset import shared_dir
from firmware_model.flights.simulate.scenarios import scenario_mach, simulate_scenario
from firmware_model.runtime.errors import UserError
from firmware_model.runtime.output import write_file
from firmware_model.spec import atmosphere as atm

#: Residual window after liftoff (s).
WINDOW_S: float = 15.0
#: Calibration: coast samples below this Mach number ...
CAL_MACH: float = 0.3
#: A jump is a rise of the residual within this many seconds.
JUMP_WINDOW_S: float = 0.3
#: Running-median window of the noise measure (s).
NOISE_MEDIAN_S: float = 0.25

#: The logs measured (relative to the shared flights folder).
ALTOS_LOGS: tuple[str, ...] = ("altosui/prometheus-2022-06-24-telemega.csv",
                               "altosui/prometheus-2022-06-24-telemetrum.csv",
                               "euroc21/piccard-telemega.csv")
CATS_PICCARD: str = "euroc21/piccard-cats-baro_raw.csv"
CATS_PICCARD_EVENTS: str = "euroc21/piccard-cats-event_info_raw.csv"


@dataclass
class Trace:
    """One barometer of one flight on a time axis with 0 at liftoff."""

    name: str
    time_s: np.ndarray
    baro_m: np.ndarray                    # barometric altitude above the pad (m)
    accel: np.ndarray | None = None       # kinematic axial acceleration (m/s^2), AltOS logs only
    speed_altos: np.ndarray | None = None  # AltOS's own speed column (m/s), for the figure
    events: dict[str, float] = field(default_factory=dict)
    pad_m: float = 0.0                    # pad altitude (m, standard atmosphere of the pad pressure)


@dataclass
class Trajectory:
    """The calibrated accelerometer trajectory on a trace's time axis."""

    time_s: np.ndarray
    z_m: np.ndarray
    v_mps: np.ndarray
    mach: np.ndarray
    scale: float


@dataclass(frozen=True)
class Signature:
    """One measured event: ``magnitude_m`` signed (negative: the barometer reads low altitude = pressure high)."""

    log: str
    event: str
    time_s: float
    magnitude_m: float
    duration_s: float | None
    mach_start: float | None
    mach_end: float | None
    note: str = ""


# ---------------------------------------------------------------------------------------------------- reading
def _altos_columns(path: Path) -> dict[str, Any]:
    header: list[str] | None = None
    rows: list[list[str]] = []
    with open(path, newline="") as f:
        for number, line in enumerate(f, start=1):
            if line.startswith("#version"):
                header = [h.strip() for h in line[1:].split(",")]
            elif line.startswith("#") or not line.strip():
                continue
            elif header is None:
                raise UserError(f"{path}:{number}: data before the '#version' header")
            else:
                rows.append([x.strip() for x in line.split(",")])
    if header is None or not rows:
        raise UserError(f"{path}: not an AltosUI CSV with data")
    need = ("time", "state_name", "acceleration", "pressure", "speed")
    missing = [c for c in need if c not in header]
    if missing:
        raise UserError(f"{path}: missing column(s) {', '.join(missing)}")
    ix = {c: header.index(c) for c in need}
    out: dict[str, Any] = {c: np.array([float(r[ix[c]]) for r in rows]) for c in need if c != "state_name"}
    out["state"] = [r[ix["state_name"]] for r in rows]
    _, keep = np.unique(out["time"], return_index=True)   # repeated timestamps: keep the first
    for c in list(out):
        out[c] = out[c][keep] if c != "state" else [out[c][i] for i in keep]
    return out


def read_altos(path: Path) -> Trace:
    """An AltosUI CSV as a :class:`Trace` (time 0 = AltOS's boost; events: first row of each state)."""
    d = _altos_columns(path)
    t = d["time"]
    pad = t < 0
    p0 = float(np.median(d["pressure"][pad])) if pad.sum() >= 3 else float(d["pressure"][0])
    h0 = float(atm.altitude_m(p0))
    events: dict[str, float] = {}
    for ti, s in zip(t, d["state"]):
        events.setdefault(s, float(ti))
    return Trace(path.stem, t, np.asarray(atm.altitude_m(d["pressure"])) - h0, d["acceleration"], d["speed"],
                 events, h0)


def read_cats_baros(path: Path, events_path: Path | None = None) -> list[Trace]:
    """The CATS raw barometer CSV (``ts`` ms, ``id`` BARO0..2, ``P`` Pa) as one :class:`Trace` per barometer, time
    0 at CATS's ``EV_LIFTOFF`` (from ``events_path``) or at the first row."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    head = [h.strip() for h in rows[0]]
    try:
        its, iid, ip = head.index("ts"), head.index("id"), head.index("P")
    except ValueError:
        raise UserError(f"{path}:1: need columns ts, id, P; got {','.join(head)}") from None
    ev: dict[str, float] = {}
    if events_path is not None and events_path.is_file():
        with open(events_path, newline="") as f:
            er = list(csv.reader(f))
        eh = [h.strip() for h in er[0]]
        for r in er[1:]:
            ev.setdefault(r[eh.index("event")].strip(), float(r[eh.index("ts")]) / 1000.0)
    ts = np.array([float(r[its]) for r in rows[1:]]) / 1000.0
    ids = np.array([r[iid].strip() for r in rows[1:]])
    p = np.array([float(r[ip]) for r in rows[1:]])
    t0 = ev.get("EV_LIFTOFF", float(ts[0]))
    out = []
    for name in sorted(set(ids)):
        m = ids == name
        t, pp = ts[m] - t0, p[m]
        _, keep = np.unique(t, return_index=True)
        t, pp = t[keep], pp[keep]
        p0 = float(np.median(pp[t < 0])) if (t < 0).sum() >= 3 else float(pp[0])
        h0 = float(atm.altitude_m(p0))
        out.append(Trace(f"piccard-cats-{name}", t, np.asarray(atm.altitude_m(pp)) - h0,
                         events={k.replace("EV_", "").lower(): v - t0 for k, v in ev.items()}, pad_m=h0))
    return out


# ---------------------------------------------------------------------------------------------------- trajectory
def trajectory(tr: Trace) -> Trajectory:
    """The accelerometer trajectory of an AltOS trace, calibrated on the subsonic coast (see the module doc)."""
    if tr.accel is None:
        raise UserError(f"{tr.name}: no accelerometer")
    t, a = tr.time_s, np.where(np.isfinite(tr.accel), tr.accel, 0.0)
    pad = t < 0
    # start at the last pad sample that is still at rest (|a| < 2 m/s^2), else at the first sample
    rest = np.nonzero(pad & (np.abs(a) < 2.0))[0]
    i0 = int(rest[-1]) if rest.size else 0
    v = np.zeros_like(t)
    z = np.zeros_like(t)
    dt = np.diff(t)
    v[i0 + 1:] = np.cumsum(0.5 * (a[i0 + 1:] + a[i0:-1]) * dt[i0:])
    z[i0 + 1:] = np.cumsum(0.5 * (v[i0 + 1:] + v[i0:-1]) * dt[i0:])
    i_ap = int(np.nonzero((t > t[i0] + 1.0) & (v < 0))[0][0]) if np.any((t > t[i0] + 1.0) & (v < 0)) else t.size - 1
    # Mach from the accelerometer speed (it matches AltOS's own speed column to 0.5-1.5 m/s on these logs) and the
    # standard speed of sound at the pad + z
    mach = v / np.asarray(atm.speed_of_sound_mps(tr.pad_m + z))
    cal = ((np.arange(t.size) > int(np.argmax(v))) & (np.arange(t.size) < i_ap) & (mach < CAL_MACH)
           & np.isfinite(tr.baro_m))
    if cal.sum() < 20:
        raise UserError(f"{tr.name}: too few slow coast samples to calibrate the accelerometer trajectory")
    s = float(np.dot(z[cal], tr.baro_m[cal] - z[cal]) / np.dot(z[cal], z[cal]))
    zc = (1 + s) * z
    return Trajectory(t, zc, v, mach, s)


def on_axis(traj: Trajectory, t: np.ndarray, lag_s: float = 0.0) -> Trajectory:
    """``traj`` interpolated onto ``t + lag_s`` (another computer's clock)."""
    tt = np.asarray(t) + lag_s
    return Trajectory(np.asarray(t), np.interp(tt, traj.time_s, traj.z_m), np.interp(tt, traj.time_s, traj.v_mps),
                      np.interp(tt, traj.time_s, traj.mach), traj.scale)


def best_lag(ref: Trace, other: Trace, window: tuple[float, float] = (12.0, 30.0)) -> float:
    """The clock offset (s, other + lag = ref) that best matches two barometric altitudes on ``window``."""
    m = (other.time_s >= window[0]) & (other.time_s <= window[1])
    lags = np.arange(-1.0, 1.0001, 0.005)
    cost = [np.mean((np.interp(other.time_s[m] + L, ref.time_s, ref.baro_m) - other.baro_m[m]) ** 2) for L in lags]
    return float(lags[int(np.argmin(cost))])


# ---------------------------------------------------------------------------------------------------- measures
def _running_median(x: np.ndarray, n: int) -> np.ndarray:
    n = max(1, n | 1)
    pad = n // 2
    xp = np.pad(x, pad, mode="edge")
    win = np.lib.stride_tricks.sliding_window_view(xp, n)
    return np.median(win, axis=1)


def measure(tr: Trace, traj: Trajectory) -> list[Signature]:
    """The signatures of one barometer (see the module doc)."""
    t, m = tr.time_s, traj.mach
    w = (t >= 0) & (t <= WINDOW_S)
    r = tr.baro_m - traj.z_m
    tw, rw, mw = t[w], r[w], m[w]
    out: list[Signature] = []
    t_peak = float(tw[int(np.argmax(mw))])
    # dip
    sel = tw <= t_peak + 3.0
    i = int(np.argmin(np.where(sel, rw, np.inf)))
    depth = float(rw[i])
    below_half = rw <= depth / 2
    # contiguous run around the minimum
    a = i
    while a > 0 and below_half[a - 1]:
        a -= 1
    b = i
    while b < rw.size - 1 and below_half[b + 1]:
        b += 1
    ten = rw <= 0.1 * depth
    on = i
    while on > 0 and ten[on - 1]:
        on -= 1
    off = i
    while off < rw.size - 1 and ten[off + 1]:
        off += 1
    recovered = off < rw.size - 1
    out.append(Signature(tr.name, "transonic dip", float(tw[i]), depth, float(tw[b] - tw[a]), float(mw[on]),
                         float(mw[off]) if recovered else None,
                         f"below half depth {tw[a]:.2f}-{tw[b]:.2f} s; peak Mach {mw.max():.2f}"
                         + ("" if recovered else f"; not back within 10 % by {WINDOW_S:.0f} s")))
    # jump
    dt = float(np.median(np.diff(tw)))
    n = max(1, round(JUMP_WINDOW_S / dt))
    rise = rw[n:] - rw[:-n]
    j = int(np.argmax(rise))
    # the rise's own extent: from the local minimum to the local maximum inside the window
    seg = rw[j:j + n + 1]
    j0 = j + int(np.argmin(seg))
    j1 = j0 + int(np.argmax(rw[j0:j + n + 1]))
    out.append(Signature(tr.name, "jump", float(tw[j0]), float(rw[j1] - rw[j0]), float(tw[j1] - tw[j0]),
                         float(mw[j0]), float(mw[j1]), f"largest rise within {JUMP_WINDOW_S} s"))
    # noise bursts
    med = _running_median(rw, round(NOISE_MEDIAN_S / dt))
    dev = rw - med
    k = int(np.argmax(np.abs(dev)))
    pad = (t < 0) & (t > t[0])
    pad_dev = tr.baro_m[pad] - np.median(tr.baro_m[pad]) if pad.sum() > 5 else np.zeros(1)
    out.append(Signature(tr.name, "noise burst", float(tw[k]), float(dev[k]), None, float(mw[k]), None,
                         f"vs {NOISE_MEDIAN_S} s running median; pad: max |dev| {np.max(np.abs(pad_dev)):.1f} m, "
                         f"rms of boost+coast {np.sqrt(np.mean(dev ** 2)):.1f} m"))
    # ejection / recovery events
    for ev in ("drogue", "main", "apogee"):
        if ev not in tr.events:
            continue
        te = tr.events[ev]
        before = (t >= te - 3.0) & (t < te - 0.05)
        after = (t >= te) & (t <= te + 1.5)
        if before.sum() < 5 or after.sum() < 2:
            continue
        c = np.polyfit(t[before] - te, tr.baro_m[before], 2)
        d = tr.baro_m[after] - np.polyval(c, t[after] - te)
        q = int(np.argmax(np.abs(d)))
        big = np.abs(d) >= abs(d[q]) / 2
        a2 = q
        while a2 > 0 and big[a2 - 1]:
            a2 -= 1
        b2 = q
        while b2 < d.size - 1 and big[b2 + 1]:
            b2 += 1
        ta = t[after]
        rate = 1.0 / float(np.median(np.diff(ta))) if ta.size > 1 else float("nan")
        fit_rms = float(np.sqrt(np.mean((tr.baro_m[before] - np.polyval(c, t[before] - te)) ** 2)))
        out.append(Signature(tr.name, f"ejection ({ev})", float(ta[q]), float(d[q]),
                             float(ta[b2] - ta[a2]) + 1.0 / rate, None, None,
                             f"vs a quadratic over the 3 s before (fit rms {fit_rms:.1f} m); separation noise: rms "
                             f"{float(np.sqrt(np.mean(d ** 2))):.1f} m over 1.5 s; {rate:.0f} samples/s"))
    return out


#: Mach number above which :func:`boost_port_error` reads the port's pressure coefficient (below it q is too small
#: for a few pascals of the calibration to matter).
BOOST_MACH: float = 0.5


@dataclass(frozen=True)
class BoostPortError:
    """What a barometer read during the boost (issue 30), against the accelerometer trajectory: the port's error
    as a fraction of the dynamic pressure, ``(p_read - p_static) / q`` with ``p_static`` the standard pressure at
    the pad + the calibrated trajectory's altitude and ``q = 0.7 p_static M^2``, over the boost samples above
    :data:`BOOST_MACH` (median and largest), and the lowest barometric height above the pad during the boost."""

    log: str
    burnout_s: float
    mach_burnout: float
    cp_median: float | None
    cp_max: float | None
    mach_range: tuple[float, float] | None
    lowest_m: float
    lowest_time_s: float
    lowest_mach: float
    lowest_true_m: float


def boost_port_error(tr: Trace, traj: Trajectory) -> BoostPortError:
    """:class:`BoostPortError` of one barometer; the boost runs from liftoff (t = 0) to the trajectory's peak speed
    (burnout, within a sample or two of AltOS's ``coast`` state on these logs)."""
    t = tr.time_s
    ok = np.isfinite(tr.baro_m)
    ib = int(np.argmax(traj.v_mps))
    boost = (t >= 0) & (t <= t[ib]) & ok
    if not boost.any():
        raise UserError(f"{tr.name}: no barometer sample between liftoff and burnout")
    p_read = np.asarray(atm.pressure_pa(tr.pad_m + np.where(ok, tr.baro_m, 0.0)))
    p_static = np.asarray(atm.pressure_pa(tr.pad_m + traj.z_m))
    q = 0.7 * p_static * traj.mach ** 2
    fast = boost & (traj.mach >= BOOST_MACH)
    cp = (p_read - p_static)[fast] / q[fast]
    lo = int(np.argmin(np.where(boost, tr.baro_m, np.inf)))
    return BoostPortError(tr.name, float(t[ib]), float(traj.mach[ib]),
                          float(np.median(cp)) if cp.size else None, float(np.max(cp)) if cp.size else None,
                          (float(traj.mach[fast].min()), float(traj.mach[fast].max())) if cp.size else None,
                          float(tr.baro_m[lo]), float(t[lo]), float(traj.mach[lo]), float(traj.z_m[lo]))


def boost_table(rows: Sequence[BoostPortError]) -> str:
    """The boost port errors as a Markdown table."""
    lines = ["| log | burnout s (Mach) | port error / q in boost above Mach 0.5: median, max (Mach range) | "
             "lowest barometric height in boost m (at s, Mach; true height m) |", "|---|---|---|---|"]
    for r in rows:
        cp = "—" if r.cp_median is None else (f"{r.cp_median:+.3f}, {r.cp_max:+.3f} "
                                              f"({r.mach_range[0]:.2f}-{r.mach_range[1]:.2f})")
        lines.append(f"| {r.log} | {r.burnout_s:.2f} ({r.mach_burnout:.2f}) | {cp} | {r.lowest_m:+.0f} "
                     f"({r.lowest_time_s:.2f}, {r.lowest_mach:.2f}; {r.lowest_true_m:.0f}) |")
    return "\n".join(lines)


@dataclass
class Analysis:
    traces: list[Trace]
    trajectories: dict[str, Trajectory]
    signatures: list[Signature]
    notes: list[str]

    def boost(self) -> list[BoostPortError]:
        """:func:`boost_port_error` of every trace."""
        return [boost_port_error(tr, self.trajectories[tr.name]) for tr in self.traces]


def analyse(base: Path) -> Analysis:
    """Measure every log under the shared folder ``base`` that exists."""
    traces: list[Trace] = []
    trajs: dict[str, Trajectory] = {}
    sigs: list[Signature] = []
    notes: list[str] = []
    for rel in ALTOS_LOGS:
        p = base / rel
        if not p.is_file():
            continue
        tr = read_altos(p)
        traj = trajectory(tr)
        traces.append(tr)
        trajs[tr.name] = traj
        sigs += measure(tr, traj)
        notes.append(f"{tr.name}: accelerometer altitude scaled by {traj.scale:+.3f} (fitted on the coast below "
                     f"Mach {CAL_MACH}); peak Mach {traj.mach.max():.2f}")
    mega = next((tr for tr in traces if tr.name == "piccard-telemega"), None)
    cp = base / CATS_PICCARD
    if mega is not None and cp.is_file():
        for tr in read_cats_baros(cp, base / CATS_PICCARD_EVENTS):
            lag = best_lag(mega, tr)
            traj = on_axis(trajs[mega.name], tr.time_s, lag)
            traces.append(tr)
            trajs[tr.name] = traj
            sigs += measure(tr, traj)
            notes.append(f"{tr.name}: the TeleMega's trajectory at CATS time + {lag:+.3f} s (best coast match)")
    return Analysis(traces, trajs, sigs, notes)


def markdown_table(sigs: Sequence[Signature]) -> str:
    lines = ["| log | event | at s | magnitude m | duration s | Mach at start | Mach at end | how measured |",
             "|---|---|---|---|---|---|---|---|"]

    def f(x: float | None, d: int) -> str:
        return "—" if x is None else f"{x:.{d}f}"

    for s in sigs:
        lines.append(f"| {s.log} | {s.event} | {s.time_s:.2f} | {s.magnitude_m:+.0f} | {f(s.duration_s, 2)} | "
                     f"{f(s.mach_start, 2)} | {f(s.mach_end, 2)} | {s.note} |")
    return "\n".join(lines)


def figure(an: Analysis) -> bytes:
    """PNG: per AltOS log, barometric vs accelerometer altitude (0-15 s) with Mach, and the residual (all logs)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    altos = [tr for tr in an.traces if tr.accel is not None]
    fig, axes = plt.subplots(2, len(altos), figsize=(5.2 * len(altos), 7.5), squeeze=False)
    for col, tr in enumerate(altos):
        traj = an.trajectories[tr.name]
        w = (tr.time_s >= -0.5) & (tr.time_s <= WINDOW_S)
        ax = axes[0, col]
        ax.plot(tr.time_s[w], tr.baro_m[w], lw=1, label="barometric altitude")
        ax.plot(traj.time_s[w], traj.z_m[w], lw=1, ls="--", label="accelerometer trajectory (calibrated)")
        ax.set_title(tr.name, fontsize=9)
        ax.set_xlabel("s after liftoff")
        ax.set_ylabel("m above pad")
        ax2 = ax.twinx()
        ax2.plot(traj.time_s[w], traj.mach[w], color="grey", lw=0.8, label="Mach")
        ax2.axhline(1.0, color="grey", lw=0.5, ls=":")
        ax2.set_ylim(0, 1.6)
        ax2.set_ylabel("Mach", color="grey")
        ax.legend(loc="upper left", fontsize=7)
        ax = axes[1, col]
        ax.plot(tr.time_s[w], tr.baro_m[w] - traj.z_m[w], lw=1, label=f"{tr.name}")
        if tr.name == "piccard-telemega":
            for other in an.traces:
                if other.accel is None:
                    ot = an.trajectories[other.name]
                    ww = (other.time_s >= -0.5) & (other.time_s <= WINDOW_S)
                    ax.plot(other.time_s[ww], other.baro_m[ww] - ot.z_m[ww], lw=0.6, alpha=0.8,
                            label=other.name)
        for s in an.signatures:
            if s.log == tr.name and s.event in ("transonic dip", "jump"):
                ax.annotate(f"{s.event} {s.magnitude_m:+.0f} m", (s.time_s, 0), fontsize=7, rotation=90,
                            va="bottom")
        ax.axhline(0, color="k", lw=0.5)
        ax.set_xlabel("s after liftoff")
        ax.set_ylabel("barometric - accelerometer altitude, m")
        ax.legend(fontsize=7, loc="lower right")
    fig.suptitle("Barometer error of real fast flights (pressure reads high = altitude low)", fontsize=10)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return buf.getvalue()


#: Scenarios shown beside the measured residuals in :func:`model_figure`.
MODEL_FIGURE_SCENARIOS: tuple[str, ...] = ("rb-m1670-m105", "rb-m1670-m105-jumpdown", "rb-m6400-m167",
                                           "rb-m2245-m19-9400m")


def model_figure(an: Analysis, names: Sequence[str] = MODEL_FIGURE_SCENARIOS) -> bytes:
    """PNG: the measured residuals (left) beside the barometric-altitude error the model puts on some scenarios
    (right), 0-15 s, with Mach on a second axis."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12, 4.6), sharey=True)
    for tr in an.traces:
        if tr.name.startswith("piccard-cats"):
            continue
        traj = an.trajectories[tr.name]
        w = (tr.time_s >= -0.5) & (tr.time_s <= WINDOW_S)
        line, = ax.plot(tr.time_s[w], tr.baro_m[w] - traj.z_m[w], lw=1,
                        label=f"{tr.name} (peak Mach {traj.mach.max():.2f})")
    ax.set_title("measured: barometric - accelerometer altitude", fontsize=9)
    for name in names:
        rec = simulate_scenario(name)
        mach = scenario_mach(name)
        site = float(atm.altitude_m(rec.ground_pressure_pa))
        err = np.asarray(atm.altitude_m(rec.pressure_pa)) - site - rec.truth.altitude_m
        w = (rec.time_s >= -0.5) & (rec.time_s <= WINDOW_S)
        bx.plot(rec.time_s[w], err[w], lw=1, label=f"{name} (peak Mach {mach.max():.2f})")
    bx.set_title("model (pressure_errors.real_flight_errors) on scenarios", fontsize=9)
    for a in (ax, bx):
        a.axhline(0, color="k", lw=0.5)
        a.set_xlabel("s after liftoff / ignition")
        a.legend(fontsize=7, loc="lower right")
    ax.set_ylabel("barometric altitude error, m")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return buf.getvalue()


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--png", type=Path, help="write the figure here")
    ap.add_argument("--model-png", type=Path, help="write the measured-vs-model figure here")
    args = ap.parse_args(argv)
    base = shared_dir()
    if base is None:
        raise SystemExit("no shared flights folder (../shared/flights or $FWEMU_SHARED_FLIGHTS)")
    an = analyse(base)
    print(markdown_table(an.signatures))
    print()
    print(boost_table(an.boost()))
    print()
    for n in an.notes:
        print("- " + n)
    if args.png:
        write_file(args.png, figure(an))
        print(f"wrote {args.png}")
    if args.model_png:
        write_file(args.model_png, model_figure(an))
        print(f"wrote {args.model_png}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

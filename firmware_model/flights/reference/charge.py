"""The log's own recovery charge: when the flight stopped being free, and what says so (issue 31).

:func:`recovery_charge` is the one rule the reference apogee (:mod:`.apogee_reference`) and the reconstruction
(:mod:`.reconstruct.run`) both use. Evidence, in order:

1. **The log's own computer** (``state``): the earliest of the reader's recovery events (:data:`STATE_EVENTS`:
   AltOS's first ``drogue`` row, else its first ``main`` row on a main-only flight; ``own_apogee`` of the other
   readers: an RRC3's drogue event, an Eggtimer's apogee flag, Lynx state 11, CATS's EV_APOGEE, a Raven's
   apogee, NCSU's state letter F). It is the computer's decision to fire, whatever the log rate.
2. **An accelerometer shock** (``accelerometer``) in the flight's top (below): a sample with |f| above
   :data:`SHOCK_G` g and :data:`SHOCK_RATIO` times the median |f| of its neighbours, the samples within
   :data:`SHOCK_HALF_S` of it but at least :data:`SHOCK_NEIGHBOURS` on each side, the sample itself left out. A
   single sample counts: at the 5-10 samples/s a log drops to at apogee, a charge is one row. A shock before the
   log's own event is taken instead of it (another computer's charge, or a separation: the flight after it is not
   free either). Likewise a **pressure pulse** (rule 4's signature) in the flight's top that starts more than
   :data:`PULSE_BEFORE_STATE_S` before the log's own event: another charge fired first (a motor's backup ejection, a
   second computer: redundant altimeters are the rule in high-power rocketry), and the flight after it is not free.
   Measured: juno3-rrc3's RRC3 fired at 30.45 s, but a 60 m pulse of 0.2 s at 24.65 s, while the log still
   climbed at about 12 m/s, left a flat top and a second disturbance that the parabola through 30.45 s had fitted.
3. **The log's rate dropping** (``rate``) by :data:`RATE_DROP` times or more in the flight's top, without 1 (or
   a shock before it): AltOS logs at 100 (or 50) samples/s up to its apogee state and at 10 or 5 after it (the
   shared README), so the drop is its decision even where the CSV has no state column. A shock before it wins.
4. **The ejection's pressure signature** (``pressure``), only without 1-3: in the flight's top, the first
   barometric-altitude sample that, with the next ones for at least :data:`PULSE_MIN_S` and two samples, differs in the
   same direction from the line through the samples in the :data:`PULSE_BEFORE_S` before it (at least three; the
   flight's own climb or fall) by more than max(:data:`PULSE_SIGMAS` x the robust noise, :data:`PULSE_MIN_M`): a
   charge's pulse of tens to hundreds of metres lasting 0.1-0.5 s (the shared README, "What real supersonic barometers
   look like", (d)). Two samples and 50 ms, because a single-sample glitch (or two at 100 samples/s) is not a pulse; a
   pulse shorter than two intervals of a 5 samples/s tail is missed.

**The flight's top**: the contiguous run of samples around the highest point of the 7-sample running median of the
barometric altitude where that median stays within max(:data:`TOP_FRACTION` x the peak height, :data:`TOP_MIN_M`) of the
peak, bridging excursions shorter than :data:`TOP_GAP_S` (a charge's own pulse): a burn's peak, a staging shock or a
transonic jump lies far below it; an apogee charge, even a delayed one, inside it.

Pyro / igniter voltage columns (AltosUI ``drogue_voltage``, ``igniter_a`` ...) are not read by the readers and
are not used.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from firmware_model.flights.record import FlightRecord
from firmware_model.spec.atmosphere import G0, altitude_m

#: Reader events that are the log's own computer's recovery decision (rule 1), earliest first when several.
STATE_EVENTS: tuple[str, ...] = ("altos_drogue", "altos_apogee", "altos_main", "own_apogee")
SHOCK_G: float = 8.0
SHOCK_RATIO: float = 4.0
SHOCK_HALF_S: float = 0.1
SHOCK_NEIGHBOURS: int = 2
PULSE_BEFORE_S: float = 0.5
PULSE_MIN_S: float = 0.05
PULSE_SIGMAS: float = 10.0
PULSE_MIN_M: float = 15.0
TOP_FRACTION: float = 0.1
TOP_MIN_M: float = 30.0
TOP_GAP_S: float = 1.0
RATE_DROP: float = 3.0
#: A pressure pulse counts before the log's own event (rule 1) when it starts more than this (s) before the event's
#: row: the own charge's pulse can show one row early, and a log's slowest top is 5 samples/s (0.2 s a row).
PULSE_BEFORE_STATE_S: float = 0.25
MEDIAN_HALF: int = 3


@dataclass(frozen=True)
class RecoveryCharge:
    """``time_s`` on the record's axis; ``evidence``: ``state`` / ``accelerometer`` / ``rate`` / ``pressure``;
    ``detail``: readable (which event or how big a shock); ``rate_hz``: the log's sample rate just after it; ``own``:
    the log's own computer's event (else inferred from the data)."""

    time_s: float
    evidence: str
    detail: str
    rate_hz: float
    own: bool

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def describe(self) -> str:
        return f"{self.time_s:.2f} s ({self.evidence}: {self.detail}; log at {self.rate_hz:.0f} samples/s there)"


def _running_median(y: np.ndarray, half: int) -> np.ndarray:
    padded = np.pad(y, half, mode="edge")
    return np.median(np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1), axis=1)


def _rate_after(t: np.ndarray, tc: float) -> float:
    i = int(np.searchsorted(t, tc))
    d = np.diff(t[max(i - 1, 0): i + 5])
    d = d[d > 0]
    return float(1.0 / np.median(d)) if d.size else float("nan")


def _neighbour_median(t: np.ndarray, y: np.ndarray, i: int, half_s: float, k: int) -> float:
    """Median of y over the samples within half_s of t[i], at least k on each side, sample i left out."""
    lo = min(int(np.searchsorted(t, t[i] - half_s, side="left")), max(i - k, 0))
    hi = max(int(np.searchsorted(t, t[i] + half_s, side="right")), min(i + k + 1, t.size))
    nb = np.concatenate([y[lo:i], y[i + 1:hi]])
    return float(np.median(nb)) if nb.size else float("nan")


def top_of_flight(t: np.ndarray, h: np.ndarray) -> tuple[float, float, float] | None:
    """(start, end, peak time) of the flight's top (module docstring) from a barometric altitude ``h`` (NaN
    allowed), or None without finite samples."""
    ok = np.isfinite(h)
    if ok.sum() < 2 * MEDIAN_HALF + 1:
        return None
    tt, sm = t[ok], _running_median(h[ok], MEDIAN_HALF)
    base = float(np.median(sm[: max(5, min(100, sm.size // 20))]))
    ip = int(np.argmax(sm))
    peak = float(sm[ip]) - base
    idx = np.nonzero(sm >= sm[ip] - max(TOP_FRACTION * peak, TOP_MIN_M))[0]
    breaks = np.nonzero(np.diff(tt[idx]) > TOP_GAP_S)[0]          # runs of samples inside, gaps up to TOP_GAP_S
    starts = np.r_[0, breaks + 1]
    ends = np.r_[breaks, idx.size - 1]
    k = int(np.searchsorted(idx[starts], ip, side="right")) - 1
    return float(tt[idx[starts[k]]]), float(tt[idx[ends[k]]]), float(tt[ip])


def accelerometer_shock(t: np.ndarray, f: np.ndarray | None, start_s: float, end_s: float = np.inf
                        ) -> tuple[float, float] | None:
    """(time, |f| in g) of the first shock (rule 2) with start_s < t <= end_s, or None."""
    if f is None:
        return None
    a = np.abs(np.where(np.isfinite(f), f, 0.0))
    for i in np.nonzero((a > SHOCK_G * G0) & (t > start_s) & (t <= end_s))[0]:
        if a[i] > SHOCK_RATIO * _neighbour_median(t, a, int(i), SHOCK_HALF_S, SHOCK_NEIGHBOURS):
            return float(t[i]), float(a[i] / G0)
    return None


def pressure_pulse(t: np.ndarray, h: np.ndarray, start_s: float, end_s: float) -> tuple[float, float] | None:
    """(time, size in m) of the first pressure pulse (rule 4) with start_s <= t <= end_s, or None."""
    ok = np.isfinite(h)
    tt, hh = t[ok], h[ok]
    sel = np.nonzero((tt >= start_s) & (tt <= end_s))[0]
    if sel.size < 10:
        return None
    r = hh[sel] - _running_median(hh[sel], MEDIAN_HALF)
    noise = 1.4826 * float(np.median(np.abs(r - np.median(r))))
    limit = max(PULSE_SIGMAS * noise, PULSE_MIN_M)
    for i in sel[:-1]:
        lo = min(int(np.searchsorted(tt, tt[i] - PULSE_BEFORE_S)), max(int(i) - SHOCK_NEIGHBOURS - 1, 0))
        if i - lo < SHOCK_NEIGHBOURS + 1:
            continue
        base = float(np.median(hh[lo:i]))
        if abs(hh[i] - base) <= limit and abs(hh[i] - hh[i - 1]) <= limit:
            continue
        # the flight's own motion over the window: a line through the samples before, from the medians of its
        # two halves (a spike among them moves neither)
        tb, hb = tt[lo:i] - tt[i], hh[lo:i]
        m = tb.size // 2
        slope = (float(np.median(hb[m:])) - float(np.median(hb[:m]))) / max(
            float(np.median(tb[m:])) - float(np.median(tb[:m])), 1e-9)
        icpt = float(np.median(hb - slope * tb))
        d0 = hh[i] - icpt
        j = int(i)
        while j < tt.size and abs(hh[j] - icpt - slope * (tt[j] - tt[i])) > limit and \
                (hh[j] - icpt - slope * (tt[j] - tt[i])) * d0 > 0:
            j += 1
        if j - i >= 2 and (tt[j] if j < tt.size else tt[-1]) - tt[i] >= PULSE_MIN_S:
            return float(tt[i]), float(d0)
    return None


def rate_drop(t: np.ndarray, start_s: float, end_s: float) -> tuple[float, float, float] | None:
    """(time, rate before, rate after) of the first drop of the log's rate by :data:`RATE_DROP` times or more inside
    [start_s, end_s] (rule 3): the median interval of the 10 rows after a row against that of the 10 before. The
    time is one fast interval after the last fast row: the state changed between it and the first slow one, and
    nothing after the change is used."""
    sel = np.nonzero((t >= start_s) & (t <= end_s))[0]
    d = np.diff(t)
    for i in sel:
        if i < 10 or i + 10 >= t.size:
            continue
        if d[i] < RATE_DROP * float(np.median(d[i - 10:i])):
            continue
        fast, slow = float(np.median(d[i - 10:i])), float(np.median(d[i:i + 10]))
        if slow >= RATE_DROP * fast:
            return float(t[i]) + fast, 1.0 / fast, 1.0 / slow
    return None


def _baro_height(record: FlightRecord) -> np.ndarray:
    p = np.asarray(record.pressure_pa, dtype=np.float64)
    h = np.full(p.shape, np.nan)
    ok = np.isfinite(p) & (p > 0)
    h[ok] = np.asarray(altitude_m(p[ok]))
    return h


def recovery_charge(record: FlightRecord) -> RecoveryCharge | None:
    """The first recovery charge the log shows (module docstring), or None."""
    t = np.asarray(record.time_s, dtype=np.float64)
    ev = record.events or {}
    states = [(float(ev[k]), k) for k in STATE_EVENTS if ev.get(k) is not None]
    state = min(states) if states else None
    h = _baro_height(record)
    top = top_of_flight(t, h)
    shock = None
    if top is not None:
        shock = accelerometer_shock(t, record.specific_force_mps2(), top[0], top[1])
    if shock is not None and state is not None and shock[0] < state[0]:
        return RecoveryCharge(shock[0], "accelerometer", f"accelerometer shock {shock[1]:.1f} g, before the log's "
                              f"own {state[1]} at {state[0]:.2f} s", _rate_after(t, shock[0]), False)
    early = None if top is None or state is None else pressure_pulse(t, h, top[0], min(top[1], state[0]))
    if early is not None and early[0] < state[0] - PULSE_BEFORE_STATE_S:
        return RecoveryCharge(early[0], "pressure", f"barometric pulse {early[1]:+.0f} m, before the log's own "
                              f"{state[1]} at {state[0]:.2f} s", _rate_after(t, early[0]), False)
    if state is not None:
        who = record.provenance.get("own_computer", "AltOS" if state[1].startswith("altos_") else "own computer")
        return RecoveryCharge(state[0], "state", f"{who} {state[1]}", _rate_after(t, state[0]), True)
    drop = None if top is None else rate_drop(t, top[0], top[1])
    if drop is not None and (shock is None or drop[0] < shock[0]):
        return RecoveryCharge(drop[0], "rate", f"log rate {drop[1]:.0f} -> {drop[2]:.0f} samples/s (the computer's "
                              "apogee state: AltOS logs slower from it on)", drop[2], False)
    if shock is not None:
        return RecoveryCharge(shock[0], "accelerometer", f"accelerometer shock {shock[1]:.1f} g",
                              _rate_after(t, shock[0]), False)
    if top is not None:
        pulse = pressure_pulse(t, h, top[0], top[1])
        if pulse is not None:
            return RecoveryCharge(pulse[0], "pressure", f"barometric pulse {pulse[1]:+.0f} m",
                                  _rate_after(t, pulse[0]), False)
    return None

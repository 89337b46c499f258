"""Float64 references for the firmware programs.

Two kinds (docs/numerics.md): fixed vs **float mirror** isolates quantization; float mirror vs **ideal** isolates the
algorithm's own approximations (steady-state gains, flight logic).

* :func:`mirror`: the firmware's steps (docs/firmware-spec.md §5-§7) in float64, with the same flight logic and
  the same integer thresholds, the *design* gains (``FirmwareConstants.float_gains``) instead of the quantized
  ones (or the quantized ones with ``gains="quantized"``), no rounding (a shift by ``s`` is an exact division by
  ``2^s``) and no wrap-around.
* :func:`ideal_kalman`: the textbook Kalman filter with the design's F, H, Q, R, time-varying from ``P0`` or with
  the steady-state gain, no flight logic except liftoff/apogee flags from its own velocity.

Every float output is in the *word scale* of the integer state (Q24.8 LSB = 1, i.e. value x 256), so integer and
float traces subtract directly: X1 in 1/256 unit, X2 in 1/256 unit/s, X3 in 1/256 unit/s^2, EST/EXT in 1/256
unit, where "unit" = barometer count x BARO_SIGN (docs/firmware-spec.md §2).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from firmware_model.model.trace import EVENT_BITS, LATCHED_EVENTS, STATE_WORDS, word_names
from firmware_model.runtime.errors import UserError
from firmware_model.spec.alt_table import AltTable, table_of_config
from firmware_model.spec.build_constants import FirmwareConstants
from firmware_model.spec.config import BuildConfig
from firmware_model.spec.gain_design import design_config

_LIFTOFF = EVENT_BITS["LIFTOFF"]
_ARMED = EVENT_BITS["ARMED"]
_APOGEE = EVENT_BITS["APOGEE"]
_MACH = EVENT_BITS["MACH_LOCKOUT"]
_BARO_INVALID = EVENT_BITS["BARO_INVALID"]
_PREDICTED = EVENT_BITS["APOGEE_PREDICTED"]
_GATE_HIGH = EVENT_BITS["GATE_HIGH"]
_BARO_REJECT = EVENT_BITS["BARO_REJECT"]
_ACC_CLIP = EVENT_BITS["ACC_CLIP"]
_CLIP_CLEAR = EVENT_BITS["CLIP_CLEAR"]


def _clipped(ev: Any) -> Any:
    """ACC_CLIP and not CLIP_CLEAR (docs/firmware-spec.md §5, §6): ints or arrays of EVENTS words."""
    return (ev & (_ACC_CLIP | _CLIP_CLEAR)) == _ACC_CLIP


@dataclass
class FloatTrace:
    """Outputs of a float reference, shaped like :class:`firmware_model.model.trace.Trace`.

    ``words`` is float64 ``(n, n_words)`` or ``(streams, n, n_words)`` in word scale (Q24.8 LSB = 1); the
    ``EVENTS`` column holds exact small integers; ``init_words`` is the state after ``init``.
    """

    program: str
    names: tuple[str, ...]
    words: np.ndarray
    init_words: np.ndarray

    def column(self, name: str) -> np.ndarray:
        """Per-sample values of word ``name`` (shape ``words.shape[:-1]``), float64 in word scale."""
        return self.words[..., self.names.index(name)]

    def first_event(self, bit: str) -> np.ndarray | int:
        """Index of the first sample with event ``bit`` set, or -1 (per stream when many)."""
        if "EVENTS" not in self.names:
            raise UserError(f"{self.program}: this trace has no EVENTS word")
        hit = (self.column("EVENTS").astype(np.int64) & EVENT_BITS[bit]) != 0
        first = np.where(hit.any(axis=-1), hit.argmax(axis=-1), -1)
        return int(first) if first.ndim == 0 else first


def _streams(values: Any, name: str) -> np.ndarray:
    arr = np.asarray(values, dtype=np.float64)
    if arr.ndim not in (1, 2) or arr.shape[-1] < 1:
        raise UserError(f"{name}: expected a non-empty array of shape (n,) or (streams, n), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise UserError(f"{name}: non-finite sample(s)")
    return np.atleast_2d(arr)


def _inputs(adc: Any, acc: Any) -> tuple[np.ndarray, np.ndarray, bool]:
    one = np.ndim(adc) == 1
    a = _streams(adc, "adc")
    b = np.zeros_like(a) if acc is None else _streams(acc, "acc")
    if b.shape != a.shape:
        raise UserError(f"acc: shape {np.shape(acc)} differs from adc shape {np.shape(adc)}")
    return a, b, one


def _gain_values(consts: "FirmwareConstants", gains: str) -> dict[str, float]:
    if gains == "design":
        return dict(consts.float_gains)
    if gains == "quantized":
        return {name: g.value for name, g in consts.gains.items()}
    raise UserError(f"gains={gains!r}: must be 'design' or 'quantized'")


# ---------------------------------------------------------------------------------------------------- mirror
def mirror(consts: "FirmwareConstants", adc: np.ndarray, acc: np.ndarray | None = None,
           gains: str = "design") -> FloatTrace:
    """Float64 mirror of ``consts.program`` (docs/firmware-spec.md §5-§7 without quantization).

    Same inputs and sequencing as :func:`firmware_model.model.run.run_model` (``adc`` counts, ``acc`` counts,
    shape ``(n,)`` or ``(streams, n)``). ``gains``: ``"design"`` (unquantized ``float_gains``; default) or
    ``"quantized"`` (the 16-bit mantissa values ``m / 2^s``, to separate gain quantization from rounding).
    Outputs in word scale. APFRAC is the unrounded ``65536 * X2 / d`` (capped at 65535), no pre-shifts.
    ``recursive_seed_literal`` mirrors the literal (diverging) listing; the *intended* seed filter is the
    ``EST`` of ``mirror`` of ``recursive`` (identical to ``P[n+1] = x ADC + (1 - x) P[n]``, x = 2^-S).
    """
    program = consts.program
    if program not in STATE_WORDS:
        raise UserError(f"build constants: unknown program {program!r}")
    a, b, one = _inputs(adc, acc)
    if program in ("recursive", "recursive_seed_literal"):
        init, words = _mirror_recursive(consts, a, b, literal=program == "recursive_seed_literal")
    else:
        init, words = _mirror_kalman(consts, _gain_values(consts, gains), a, b)
    names = word_names(program)
    if one:
        return FloatTrace(program, names, words[0], init[0])
    return FloatTrace(program, names, words, init)


def _mirror_recursive(consts: "FirmwareConstants", adc: np.ndarray, acc: np.ndarray,
                      literal: bool) -> tuple[np.ndarray, np.ndarray]:
    n_streams, n = adc.shape
    x = 2.0 ** -int(consts.S)
    z = adc * float(consts.BARO_SIGN)
    est = z[:, 0] * 256.0
    if literal:
        out = np.empty((n_streams, n, 1))
        init = est[:, None].copy()
        with np.errstate(over="ignore", invalid="ignore"):
            for i in range(n):
                est = est + est * x - z[:, i] * 256.0 * x
                out[:, i, 0] = est
        return init, out
    ext = est.copy()
    vel = np.zeros(n_streams)
    acc0 = acc[:, 0].astype(float)
    ev = np.zeros(n_streams, dtype=np.int64)
    zl = z[:, 0].copy()
    suma = np.zeros(n_streams)
    cal = np.zeros(n_streams, dtype=np.int64)
    rej = np.zeros(n_streams, dtype=np.int64)
    neg = np.zeros(n_streams, dtype=np.int64)
    phase = np.zeros(n_streams, dtype=np.int64)
    cst = np.zeros(n_streams, dtype=np.int64)
    clp = np.zeros(n_streams, dtype=np.int64)
    ncal = 1 << int(consts.CAL_P)
    clear_n = 1 << int(consts.K)

    def row() -> np.ndarray:
        return np.stack([est, ext, vel, acc0, ev.astype(float), zl, suma, cal.astype(float), rej.astype(float),
                         neg.astype(float), phase.astype(float), cst.astype(float), clp.astype(float)], axis=-1)

    init = row()
    out = np.empty((n_streams, n, 13))
    for i in range(n):
        a = acc[:, i]
        ev = ev & LATCHED_EVENTS
        calib = cal < ncal
        run = ~calib
        # 1. pad calibration: ACC0 is the mean of the pad samples (no rounding)
        suma = np.where(calib, suma + a, suma)
        cal = np.where(calib, cal + 1, cal)
        acc0 = np.where(calib & (cal == ncal), suma / ncal, acc0)
        vel = np.where(run, vel + (a - acc0), vel)
        lifting = run & ((ev & _LIFTOFF) == 0) & (vel > consts.V_LIFT)
        ev = np.where(lifting, ev | _LIFTOFF, ev)
        phase = np.where(lifting, 1, phase)
        boost = run & (phase == 1)
        low = (a - acc0) < -consts.A_COAST
        cst = np.where(boost, np.where(low, cst + 1, 0), cst)
        phase = np.where(boost & low & (cst >= consts.COAST_N), 2, phase)
        dragc = run & ~boost & (phase == 2) & _clipped(ev)
        dlow = (a - acc0) >= -consts.A_DRAG
        clp = np.where(dragc, np.where(dlow, clp + 1, 0), clp)
        ev = np.where(dragc & dlow & (clp >= clear_n), ev | _CLIP_CLEAR, ev)
        phase = np.where(run & ~boost & (phase == 3) & (vel < -consts.V_DESC), 4, phase)
        railc = run & (phase == 1) & ((ev & _ACC_CLIP) == 0)
        clp = np.where(railc, np.where(a == 32767, clp + 1, 0), clp)
        clipped = railc & (a == 32767) & (clp >= consts.CLIP_N)
        ev = np.where(clipped, ev | _ACC_CLIP, ev)
        clp = np.where(clipped, 0, clp)
        ev = np.where(run & ((ev & _GATE_HIGH) != 0) & ((ev & _ARMED) == 0) & (vel < consts.V_GATE), ev | _ARMED,
                      ev)
        ev = np.where(run & ((ev & _LIFTOFF) != 0) & (vel > consts.V_GATE), ev | _GATE_HIGH, ev)
        # 5. the rate gate reads raw inputs only: the same decisions as the integer model
        d = z[:, i] - zl
        inside = (d >= -consts.E_GATE) & (d <= consts.E_GATE)
        reject = ~inside & (rej < consts.GATE_N)
        rebase = ~inside & ~reject
        rej = np.where(inside, 0, np.where(reject, rej + 1, rej))
        ev = np.where(reject, ev | _BARO_REJECT, ev)
        est = np.where(rebase, est + d * 256.0, est)
        ext = np.where(rebase, ext + d * 256.0, ext)
        use = ~reject
        zl = np.where(use, z[:, i], zl)
        est = np.where(use, est + z[:, i] * 256.0 * x - est * x, est)
        up = est > ext
        ext = np.where(up, est, ext)
        live = ~up & ((ev & _ARMED) != 0) & ((ev & _APOGEE) == 0)
        below = (ext - est >= consts.THR) & ~_clipped(ev)
        neg = np.where(up, 0, np.where(live, np.where(below, neg + 1, 0), neg))
        need = np.where((ev & _ACC_CLIP) != 0, int(consts.APO_N), 1)
        fire = live & below & (neg >= need)
        ev = np.where(fire, ev | _APOGEE, ev)
        phase = np.where(fire, 3, phase)
        out[:, i] = row()
    return init, out


def _alt_table_float(consts: "FirmwareConstants"):
    """The float interpolation of the build's altitude table (same nodes, no rounding), word scale."""

    bits = (len(consts.ALT_TABLE) - 1).bit_length() - 1 + int(consts.ALT_SHIFT)
    return AltTable(tuple(consts.ALT_TABLE), int(consts.ALT_SHIFT), bits).lookup_float


def _mirror_kalman(consts: "FirmwareConstants", g: dict[str, float], adc: np.ndarray,
                   acc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """docs/firmware-spec.md §6 in float64: the table interpolated without rounding, the calibration means and
    every shift exact; the same integer thresholds and counters (CAL, REJ, NEG) as the firmware. The table is
    looked up for every sample at once; the filter runs stream by stream (:func:`_mirror_kalman_one`)."""
    accel = consts.program == "kalman_accel"
    n_streams, n = adc.shape
    baro_ok_all = (adc >= consts.BARO_MIN) & (adc <= consts.BARO_MAX)
    lookup = _alt_table_float(consts)
    h_all = np.where(baro_ok_all, lookup(np.where(baro_ok_all, adc, 0.0)), 0.0)
    zeros = np.zeros(n_streams)
    x1 = h_all[:, 0]
    # the state before the first sample: X1 = GND = the first sample's altitude, ACC0 = the first acc, the rest 0
    cols = [x1, zeros, zeros] + ([acc[:, 0]] if accel else []) + [zeros, zeros, x1, zeros]
    init = np.stack(cols + ([zeros] if accel else []) + [zeros, zeros, zeros] + [zeros] * (7 if accel else 4)
                    + [x1, zeros] + ([x1] if accel else []), axis=-1)   # HMAX = X1, HT = 0 (kalman_accel HP = X1)
    out = np.empty((n_streams, n, init.shape[-1]))
    for s in range(n_streams):
        out[s] = _mirror_kalman_one(consts, g, accel, h_all[s], baro_ok_all[s], acc[s])
    return init, out


class _MirrorConsts:
    """The build constants one Kalman mirror step reads, as Python floats and ints (read once per stream)."""

    __slots__ = ("accel", "dt", "half_dt2", "ncal", "e_gate", "gate_n", "apo_n", "mach_vlo", "v_lift", "mach_n",
                 "dly_n", "dv", "du", "a_coast", "coast_n", "v_desc", "a_drag", "clip_n", "thrust_g", "gravity_g",
                 "floor_g", "descent_g", "dg", "v_fall", "h_floor", "desc_n", "h_step", "half_n", "win_n", "acc_g",
                 "g11", "g21", "g31", "g12", "g22", "g32")

    def __init__(self, consts: "FirmwareConstants", g: dict[str, float], accel: bool) -> None:
        self.accel = accel
        self.dt = 2.0 ** -int(consts.K)
        self.half_dt2 = 2.0 ** -(2 * int(consts.K) + 1)
        self.ncal = 1 << int(consts.CAL_P)
        self.e_gate, self.gate_n, self.apo_n = float(consts.E_GATE), int(consts.GATE_N), int(consts.APO_N)
        self.mach_vlo, self.v_lift = consts.MACH_VLO, consts.V_LIFT
        self.mach_n, self.dly_n = int(consts.MACH_N), int(consts.DLY_N)
        self.dv, self.du = float(consts.DV), float(consts.DU)
        self.a_coast, self.coast_n, self.v_desc = float(consts.A_COAST), int(consts.COAST_N), float(consts.V_DESC)
        self.a_drag, self.clip_n = float(consts.A_DRAG), int(consts.CLIP_N)
        guards = int(consts.GUARDS)
        self.thrust_g, self.gravity_g, self.floor_g, self.descent_g = (bool(guards & b) for b in (1, 2, 4, 8))
        self.dg, self.v_fall, self.h_floor = float(consts.DG), float(consts.V_FALL), float(consts.H_FLOOR)
        self.desc_n = int(consts.DESC_N)
        self.h_step = float(consts.H_STEP)
        self.half_n, self.win_n = 1 << int(consts.K), 2 << int(consts.K)
        self.acc_g = g["ACC_G"] if accel else 0.0
        self.g11, self.g21, self.g31 = (float(g[n]) for n in ("G11", "G21", "G31"))
        self.g12, self.g22, self.g32 = (float(g[n]) for n in ("G12", "G22", "G32")) if accel else (0.0, 0.0, 0.0)


def _mirror_calibrate(k: _MirrorConsts, h: float, a: float, sumz: float, suma: float, cal: int, x1: float,
                      hmax: float, gnd: float, acc0: float) -> tuple:
    """§6 step 1 on a valid pad sample: the ground (and 1 g) are the means of 2^CAL_P samples, here exact
    divisions. Returns (sumz, suma, cal, x1, hmax, gnd, acc0)."""
    sumz = sumz + h
    suma = suma + a
    cal = cal + 1
    if cal == k.ncal:
        gnd = sumz / k.ncal
        x1 = hmax = gnd
        if k.accel:
            acc0 = suma / k.ncal
    return sumz, suma, cal, x1, hmax, gnd, acc0


def _mirror_clip_window(k: _MirrorConsts, h: float, a: float, steady: bool, ev: int, phase: int, x1: float,
                        x2: float, vb: float, clp: int, e0: float, acc0: float) -> tuple:
    """§6 step 4, clip: locked until a drag-low window of 2^(K+1) samples in coast re-bases the velocity by the
    difference of its halves' innovations. Returns (lock, locked, rebase, ev, x2, vb, clp, e0)."""
    lock, locked, rebase = k.mach_n, True, False
    if phase == 2 and (a - acc0) * k.acc_g >= -k.a_drag and steady:
        e = h - x1
        clp = clp + 1
        e0 = e0 - e if clp <= k.half_n else e0 + e
        if clp == k.win_n:
            x2 = x2 + e0 * k.dt
            vb = x2
            lock, locked, rebase = 0, False, True
            ev = ev | _CLIP_CLEAR
    else:
        clp, e0 = 0, 0.0
    return lock, locked, rebase, ev, x2, vb, clp, e0


def _mirror_lockout(k: _MirrorConsts, h: float, a: float, steady: bool, ev: int, phase: int, x1: float,
                    x2: float, vb: float, lock: int, clp: int, e0: float, acc0: float) -> tuple:
    """§6 step 4 (kalman_accel): the barometer is out near Mach 1 or while the motor may push (thrust guard), then
    MACH_N samples more, and comes back with a re-base on a steady sample. Returns (lock, locked, rebase, ev, x2, vb,
    clp, e0)."""
    locked = rebase = False
    if _clipped(ev):
        lock, locked, rebase, ev, x2, vb, clp, e0 = _mirror_clip_window(k, h, a, steady, ev, phase, x1, x2, vb,
                                                                         clp, e0, acc0)
    elif ((ev & _LIFTOFF) != 0 and x2 > k.mach_vlo) or (
            k.thrust_g and (phase == 1 or (phase == 0 and (a - acc0) * k.acc_g > k.a_coast))):
        lock, locked = k.mach_n, True
    elif lock > 1:
        lock, locked = lock - 1, True
    elif lock == 1:
        if steady:
            lock, rebase = 0, True
        else:
            locked = True
    if locked:
        ev = ev | _MACH
    return lock, locked, rebase, ev, x2, vb, clp, e0


def _mirror_gate(k: _MirrorConsts, h: float, x1: float, rebase: bool, rej: int, ev: int) -> tuple:
    """§6 step 5 (valid, not locked): re-base X1 to the table value, or the innovation through the gate (a spike
    is rejected up to GATE_N samples in a row). Returns (x1, e1, use, rej, ev)."""
    use = False
    e1 = 0.0
    if rebase:
        x1 = h
        rej = 0
    else:
        e1 = h - x1
        if -k.e_gate <= e1 <= k.e_gate:
            rej = 0
            use = True
        elif rej < k.gate_n:
            rej = rej + 1
            ev = ev | _BARO_REJECT
        else:
            use = True
    return x1, e1, use, rej, ev


def _mirror_liftoff(k: _MirrorConsts, a: float, ev: int, x2: float, phase: int, dly: int, clp: int) -> tuple:
    """§6 step 7: liftoff starts the Mach delay; kalman_accel counts boost samples at the accelerometer's rail
    (ACC_CLIP after CLIP_N of them). Returns (ev, phase, dly, clp)."""
    if (ev & _LIFTOFF) != 0:
        if dly > 0:
            dly = dly - 1
    elif x2 > k.v_lift:
        ev = ev | _LIFTOFF
        phase = 1
        dly = k.dly_n
    if k.accel and phase == 1 and (ev & _ACC_CLIP) == 0:
        if a == 32767:
            clp = clp + 1
            if clp >= k.clip_n:
                ev = ev | _ACC_CLIP
                clp = 0
        else:
            clp = 0
    return ev, phase, dly, clp


def _mirror_phases(k: _MirrorConsts, h: float, baro_ok: bool, ev: int, x1: float, x2: float, x3: float,
                   vb: float, gnd: float, hmax: float, ht: int, phase: int, cst: int, neg: int, dly: int) -> tuple:
    """§6 step 9: BOOST -> COAST on COAST_N decelerating samples (one back per other sample), COAST -> APOGEE on
    APO_N samples of evidence the guards find physical, above the pad and descending (the descent guard pauses
    the count), APOGEE -> DESCENT. Returns (ev, phase, cst, neg)."""
    if phase == 1:
        if x3 < -k.a_coast:
            cst = cst + 1
            if cst >= k.coast_n:
                phase = 2
        elif cst > 0:
            cst = cst - 1
    if phase == 2:
        phys = not k.gravity_g or x2 - vb >= -k.v_fall
        high = not k.floor_g or (x1 >= gnd + k.h_floor and (not baro_ok or h >= gnd + k.h_floor))
        down = not k.descent_g or not baro_ok or h < hmax or ht >= k.desc_n
        if dly == 0 and vb < 0 and not _clipped(ev) and phys and high:
            if down:
                neg = neg + 1
                if neg >= k.apo_n:
                    ev = ev | _APOGEE
                    phase = 3
        else:
            neg = 0
    elif phase == 3 and x2 < -k.v_desc:
        phase = 4
    return ev, phase, cst, neg


def _mirror_kalman_one(consts: "FirmwareConstants", g: dict[str, float], accel: bool, h_all: np.ndarray,
                       baro_ok_all: np.ndarray, acc: np.ndarray) -> list[tuple[float, ...]]:
    """The Kalman mirror of ONE stream on Python floats (C doubles): the rows of the words in ``word_names`` order.

    Until 2026-12-02 (issue 10) the mirror ran every stream at once as numpy arrays, one ``np.where`` per step
    and sample; this loop does each step as the same IEEE double operation in the same order (``a if c else b``
    for ``np.where(c, a, b)``, ``min(x, 65535.0)`` for ``np.minimum(65535.0, x)``, NaN kept), ~50x faster on
    the tests' single streams. Every output was checked bit for bit against the array loop when it replaced it
    (sha256 of the words of every call the tests make, plus multi-stream, NaN/inf and edge inputs); numpy's
    overflow RuntimeWarnings are the only thing not reproduced. The branchy steps are the ``_mirror_*`` helpers
    above, named for the spec's steps as :func:`firmware_model.model.kernels.kalman_step`'s are."""
    k = _MirrorConsts(consts, g, accel)
    dt, half_dt2, acc_g = k.dt, k.half_dt2, k.acc_g
    hs, oks, accs = h_all.tolist(), baro_ok_all.tolist(), acc.tolist()
    x1 = gnd = hmax = hp = hs[0]
    ht = 0
    x2 = x3 = sumz = suma = apfrac = vb = 0.0
    acc0 = accs[0]
    cal = rej = neg = ev = phase = cst = dly = lock = clp = 0
    e0 = 0.0
    rows: list[tuple[float, ...]] = []
    for h, baro_ok, a in zip(hs, oks, accs):
        ev = ev & LATCHED_EVENTS                                    # 0. per-sample bits, barometer range
        if not baro_ok:
            ev = ev | _BARO_INVALID
        if cal < k.ncal:                                            # 1. pad calibration, nothing else
            if baro_ok:
                sumz, suma, cal, x1, hmax, gnd, acc0 = _mirror_calibrate(k, h, a, sumz, suma, cal, x1, hmax, gnd,
                                                                         acc0)
        else:
            x1 = x1 + x2 * dt + x3 * half_dt2                       # 2. predict
            x2 = x2 + x3 * dt
            e2 = (a - acc0) * acc_g - x3 if accel else 0.0          # 3. accelerometer innovation
            locked = rebase = False
            if accel:                                               # 4. Mach lockout, steady re-base
                steady = baro_ok and -k.h_step <= h - hp <= k.h_step
                lock, locked, rebase, ev, x2, vb, clp, e0 = _mirror_lockout(k, h, a, steady, ev, phase, x1, x2,
                                                                            vb, lock, clp, e0, acc0)
            use = False
            e1 = 0.0
            if baro_ok and not locked:                              # 5. innovation and gate
                x1, e1, use, rej, ev = _mirror_gate(k, h, x1, rebase, rej, ev)
            c1 = e1 if use else 0.0                                 # 6. correct (locked: X3 = the accelerometer)
            if locked:
                x3 = x3 + e2
            else:
                x1 = x1 + k.g11 * c1 + k.g12 * e2
                x2 = x2 + k.g21 * c1 + k.g22 * e2
                x3 = x3 + k.g31 * c1 + k.g32 * e2
            ev, phase, dly, clp = _mirror_liftoff(k, a, ev, x2, phase, dly, clp)       # 7. liftoff, rail clip
            vb = min(max(x2, vb - (k.dg if k.gravity_g and vb <= 0 else k.dv)), vb + k.du)   # 8. bound
            if baro_ok:                                             # 8b. descent record
                if h > hmax:
                    hmax, ht = h, 0
                elif ht < k.desc_n:
                    ht = ht + 1
                if accel:
                    hp = h
            ev, phase, cst, neg = _mirror_phases(k, h, baro_ok, ev, x1, x2, x3, vb, gnd, hmax, ht, phase, cst,
                                                 neg, dly)          # 9. phases and apogee
            d = -x3 * dt                                            # 10. low-rate prediction (in coast)
            if phase == 2 and (ev & _PREDICTED) == 0 and x2 > 0 and x2 < d and not _clipped(ev):
                apfrac = min(65536.0 * x2 / d, 65535.0)
                ev = ev | _PREDICTED
        if accel:
            rows.append((x1, x2, x3, acc0, ev, apfrac, gnd, sumz, suma, cal, rej, neg, phase, cst, dly, vb, lock,
                         clp, e0, hmax, ht, hp))
        else:
            rows.append((x1, x2, x3, ev, apfrac, gnd, sumz, cal, rej, neg, phase, cst, dly, vb, hmax, ht))
    return rows


# ---------------------------------------------------------------------------------------------------- ideal Kalman
def kalman_matrices(cfg: "BuildConfig") -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(F, H, Q, R)`` of the gain design (:func:`firmware_model.spec.gain_design.design_config`) in word scale (Q24.8
    m = 1: Q and R converted from barometer units with the pad's ``units_per_metre`` and multiplied by 256^2), so
    that the reference and the design cannot drift apart (the gains are invariant under that common scaling).

    State ``[alt, vel, acc]`` (1/256 m, 1/256 m/s, 1/256 m/s^2); ``F = [[1, dt, dt^2/2], [0, 1, dt],
    [0, 0, 1]]`` with ``dt = 2^-k`` s; ``H = [1 0 0]`` (kalman_baro) or ``[[1,0,0],[0,0,1]]`` (kalman_accel);
    R and Q as documented in :mod:`firmware_model.spec.gain_design`. Raises :class:`UserError` for a non-Kalman program.
    """

    ss = design_config(cfg)
    m2 = 65536.0 / cfg.units_per_metre**2    # units^2 -> (Q24.8 m)^2: the Kalman programs run in metres
    return ss.F.copy(), ss.H.copy(), ss.Q * m2, ss.R * m2


def riccati_iteration(cfg: BuildConfig, tol: float = 1e-13,
                      max_iter: int = 10_000_000) -> tuple[np.ndarray, np.ndarray]:
    """Steady-state filter-form gain ``K`` (3 x m) and a-priori covariance ``P`` (word scale^2) by iterating the
    Riccati recursion to convergence (relative change of K below ``tol``). ``K[i, j]`` is the design gain
    ``G(i+1)(j+1)`` (units 1, 1/s, 1/s^2 for the barometer column).

    Deliberately not :func:`firmware_model.spec.gain_design.steady_state` (which solves the DARE by doubling): the
    ideal float Kalman is a reference, so it reaches its steady state by the plain recursion, and the tests hold the
    design's gains against this independent computation (docs/architecture.md, "Written once")."""
    F, H, Q, R = kalman_matrices(cfg)
    P = np.eye(3) * R[0, 0]
    K = np.zeros((3, H.shape[0]))
    # Loop invariants (thousands of iterations near k = 8): the identity, and H.T / F.T as the same views.
    I3, HT, FT = np.eye(3), H.T, F.T
    k_old = K.ravel().tolist()
    for _ in range(max_iter):
        S = H @ P @ HT + R
        K_new = P @ HT @ np.linalg.inv(S)
        Pu = (I3 - K_new @ H) @ P
        P = F @ Pu @ FT + Q
        P = (P + P.T) / 2
        # max_ij(|K_new - K| / max(|K_new|, 1e-300)) < tol, on the 3 or 6 gains as Python floats: the same
        # elementwise operations, and all(x < tol) is max(x) < tol (a NaN fails both)
        k_new = K_new.ravel().tolist()
        if all(abs(a - b) / max(abs(a), 1e-300) < tol for a, b in zip(k_new, k_old)):
            return K_new, P
        k_old = k_new
    raise UserError(f"steady-state Riccati iteration did not converge in {max_iter} steps for {cfg}")


def ideal_kalman(cfg: "BuildConfig", adc: np.ndarray, acc: np.ndarray | None = None, *,
                 steady: bool = False, P0: np.ndarray | None = None) -> FloatTrace:
    """The ideal float64 Kalman filter for ``cfg`` (``kalman_baro`` or ``kalman_accel``), word scale.

    Metres, like the firmware since the altitude table: ``y = [alt(adc)]`` (the build's table interpolated in
    float, word scale) (+ ``(acc - acc0) * 256 / accel_counts_per_mps2`` for kalman_accel); ``x = [y0, 0, 0]``
    after ``init`` (no pad calibration); each sample: ``x = F x``, ``P = F P F^T + Q``, ``K = P H^T (H P H^T +
    R)^-1``, ``x += K (y - H x)``, ``P = (I - K H) P``. ``steady=True`` uses the steady-state gain every sample.
    ``P0`` (word scale^2) defaults to ``diag(R_baro, (256 * 1 m/s)^2, (256 * 1 m/s^2)^2)``: the pad state is
    known well. No barometer range check, no gate, no transonic gains; EVENTS carries LIFTOFF (X2 > liftoff
    threshold) and APOGEE (X2 < 0 after liftoff) only. Words ``X1, X2, X3, EVENTS``.
    """
    if cfg.program not in ("kalman_baro", "kalman_accel"):
        raise UserError(f"ideal_kalman: program {cfg.program!r} is not a Kalman program")
    a, b, one = _inputs(adc, acc)
    n_streams, n = a.shape
    F, H, Q, R = kalman_matrices(cfg)
    m = H.shape[0]

    table = table_of_config(cfg)
    y = np.empty((n_streams, n, m))
    y[..., 0] = table.lookup_float(np.clip(a, 0, (1 << cfg.table_bits) - 1))
    if m == 2:
        y[..., 1] = (b - b[:, :1]) * 256.0 / cfg.accel_counts_per_mps2
    v_lift = cfg.liftoff_mps * 256.0
    if steady:
        K_ss, _ = riccati_iteration(cfg)
    if P0 is None:
        P = np.diag([R[0, 0], 256.0 ** 2, 256.0 ** 2])
    else:
        P = np.asarray(P0, dtype=np.float64)
        if P.shape != (3, 3):
            raise UserError(f"ideal_kalman: P0 must be 3x3, got {P.shape}")
    x = np.zeros((n_streams, 3))
    x[:, 0] = y[:, 0, 0]
    ev = np.zeros(n_streams, dtype=np.int64)
    init = np.concatenate([x, ev[:, None].astype(float)], axis=1)
    out = np.empty((n_streams, n, 4))
    I3 = np.eye(3)
    for i in range(n):
        x = x @ F.T
        if steady:
            K = K_ss
        else:
            P = F @ P @ F.T + Q
            K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
            P = (I3 - K @ H) @ P
        x = x + (y[:, i, :] - x @ H.T) @ K.T
        ev = np.where(((ev & _LIFTOFF) == 0) & (x[:, 1] > v_lift), ev | _LIFTOFF, ev)
        ev = np.where(((ev & _LIFTOFF) != 0) & (x[:, 1] < 0), ev | _APOGEE, ev)
        out[:, i, :3] = x
        out[:, i, 3] = ev
    names = ("X1", "X2", "X3", "EVENTS")
    prog = cfg.program
    if one:
        return FloatTrace(prog, names, out[0], init[0])
    return FloatTrace(prog, names, out, init)


def ideal_recursive(consts: "FirmwareConstants", adc: np.ndarray) -> np.ndarray:
    """The intended recursive filter of Schultz 2002 ``P[n+1] = x * ADC + (1 - x) * P[n]`` (x = 2^-S) on ``z =
    BARO_SIGN * adc``, in word scale (x 256), starting from ``P = z0 * 256`` and seeing sample 0 again in the
    first step like the firmware. Returns float64 of the input's shape."""
    a, _, one = _inputs(adc, None)
    x = 2.0 ** -int(consts.S)
    z = a * float(consts.BARO_SIGN) * 256.0
    p = z[:, 0].copy()
    out = np.empty_like(z)
    for i in range(z.shape[1]):
        p = x * z[:, i] + (1.0 - x) * p
        out[:, i] = p
    return out[0] if one else out


# ---------------------------------------------------------------------------------------------------- error bounds
def rounding_error_bound(s: int, mode: str) -> float:
    """Largest ``|rs(x, s, mode) - x / 2^s|`` over all integers x (in LSB of the result): 0 for ``s == 0``,
    ``1 - 2^-s`` for ``floor`` (error in ``[-(1 - 2^-s), 0]``), ``1/2`` for ``half_up`` (``[-1/2 + 2^-s, 1/2]``)."""
    if s == 0:
        return 0.0
    return 1.0 - 2.0 ** -s if mode == "floor" else 0.5


def _l1_sums(A: np.ndarray, B: np.ndarray, rel_tol: float = 1e-16) -> np.ndarray:
    """Elementwise ``sum_t |A^t B|`` (t = 0..inf) for a stable A; stops when the terms are below ``rel_tol``
    relative to the sum and then adds the geometric tail bound with the spectral radius."""
    total = np.zeros_like(B, dtype=np.float64)
    M = np.asarray(B, dtype=np.float64).copy()
    rho = float(np.max(np.abs(np.linalg.eigvals(A))))
    if not rho < 1.0:
        raise UserError(f"closed-loop matrix is not stable (spectral radius {rho}); no error bound exists")
    for t in range(10_000_000):
        total += np.abs(M)
        M = A @ M
        if t > 8 and np.max(np.abs(M)) <= rel_tol * max(np.max(total), 1e-300):
            break
    # tail: |A^t B| decays at least like rho^t up to a modest constant; bound generously
    return total + np.abs(M) * (4.0 / (1.0 - rho))


@functools.lru_cache(maxsize=256)
def _closed_loop_sums(K: int, Kf_rows: tuple[tuple[float, ...], ...]) -> tuple[np.ndarray, np.ndarray]:
    """``(L_u, L_r)`` of :func:`kalman_error_bound` for shift K and design gain rows (cached: pure)."""
    dt = 2.0 ** -K
    F = np.array([[1.0, dt, dt * dt / 2], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
    Kf = np.array(Kf_rows)
    H = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])[: Kf.shape[1]]
    IKH = np.eye(3) - Kf @ H
    A = IKH @ F
    return _l1_sums(A, IKH), _l1_sums(A, np.eye(3))


def kalman_error_bound(consts: "FirmwareConstants", e1_max: float, e2_max: float = 0.0,
                       acc_dev_max: float = 0.0) -> np.ndarray:
    """Bound (word scale: Q24.8 LSB; X1 in 1/256 unit, X2 in 1/256 unit/s, X3 in 1/256 unit/s^2) on
    ``|X_int - X_mirror|`` for ``X1, X2, X3`` of a Kalman program, valid at every sample while both runs take the
    plain update (barometer valid, no Mach lockout). Derivation (docs/numerics.md, "Kalman bound"):

    ``delta' = A delta + (I - K H) u + r`` with ``A = (I - K H) F`` (design gain K, dt = 2^-K), ``u`` the predict
    rounding (``|u1| <= rho(K) + rho(2K+1)``, ``|u2| <= rho(K)``), ``r_i`` the gain-multiply rounding
    (``rho(s_Gij)`` per gain), the gain quantization ``|Kq - K|_ij * |e_j|`` and, for kalman_accel, ``K_i2 *
    (rho(s_ACC_G) + |ACC_Gq - ACC_G| * acc_dev_max)``; ``rho`` = :func:`rounding_error_bound`. Summing the
    impulse response: ``|delta| <= L_u u_bar + L_r r_bar`` with ``L_u = sum_t |A^t (I - K H)|``, ``L_r = sum_t
    |A^t|``. The integer innovations are bounded by the mirror's (``e1_max``, ``e2_max``, word scale) plus the
    bound itself (``|e1_int| <= e1_max + (|F| B + u_bar)_1``), solved by fixed-point iteration (a contraction:
    the gain errors are <= 2^-15 relative). ``acc_dev_max`` = max ``|acc - ACC0|`` (counts).
    """
    if consts.program not in ("kalman_baro", "kalman_accel"):
        raise UserError(f"kalman_error_bound: {consts.program!r} is not a Kalman program")
    mode = "half_up" if consts.ROUND else "floor"
    accel = consts.program == "kalman_accel"
    K = int(consts.K)
    dt = 2.0 ** -K
    F = np.array([[1.0, dt, dt * dt / 2], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
    cols = [("G11", "G21", "G31")] + ([("G12", "G22", "G32")] if accel else [])
    Kf = np.array([[consts.float_gains[c[i]] for c in cols] for i in range(3)])
    Kq = np.array([[consts.gains[c[i]].value for c in cols] for i in range(3)])
    Lu, Lr = _closed_loop_sums(K, tuple(map(tuple, Kf)))
    rho = lambda s: rounding_error_bound(s, mode)
    u_bar = np.array([rho(K) + rho(2 * K + 1), rho(K), 0.0])
    mul_round = np.array([sum(rho(consts.gains[c[i]].s) for c in cols) for i in range(3)])
    dK = np.abs(Kq - Kf)
    acc_term = np.zeros(3)
    if accel:
        g = consts.gains["ACC_G"]
        a_err = rho(g.s) + abs(g.value - consts.float_gains["ACC_G"]) * acc_dev_max
        acc_term = np.abs(Kf[:, 1]) * a_err
    B = np.zeros(3)
    for _ in range(200):
        e1 = e1_max + (np.abs(F) @ B + u_bar)[0]
        r_bar = mul_round + dK[:, 0] * e1 + acc_term
        if accel:
            e2 = e2_max + B[2] + a_err
            r_bar = r_bar + dK[:, 1] * e2
        B_new = Lu @ u_bar + Lr @ r_bar
        if np.all(np.abs(B_new - B) <= 1e-12 * np.maximum(B_new, 1.0)):
            return B_new
        B = B_new
    raise UserError("kalman_error_bound: the fixed-point iteration did not converge (gain errors too large)")


# ---------------------------------------------------------------------------------------------------- switched bound
@dataclass
class SwitchedBound:
    """Per-sample bound of :func:`kalman_switched_bound`: ``bound`` (n, 3) word scale for X1, X2, X3 (during pad
    calibration X1 = alt(adc0): the table rounding), ``e1_margin`` (n,) the bound on |e1_int - e1_mirror|
    before the gate decision of each sample, ``decided`` the number of leading samples covered."""

    bound: np.ndarray
    e1_margin: np.ndarray
    decided: int


class _StepMatrices:
    """The per-decision matrices of :func:`kalman_switched_bound`: ``(A, |IKH| @ u, barometer columns or None,
    accelerometer columns or None)`` of a (used, rebase, locked) combination, built at its first sample (so a gain
    is read, or found missing, where it was before) and kept."""

    def __init__(self, consts: "FirmwareConstants", F: np.ndarray, u: np.ndarray, rho: Any, accel: bool) -> None:
        self.F, self.u, self.accel = F, u, accel
        fg, qg = consts.float_gains, consts.gains
        self.col = lambda names: np.array([fg[n] for n in names])
        self.dcol = lambda names: np.array([abs(qg[n].value - fg[n]) for n in names])
        self.rcol = lambda names: np.array([rho(qg[n].s) for n in names])
        self.steps: dict[tuple, tuple] = {}

    def __call__(self, used: bool, rebase: bool, locked: bool = False) -> tuple:
        """A re-base sample (kalman_accel, §6 step 5) replaces X1 by the table value h: its X1 row of ``I - K H``
        loses the predicted X1 (the table's rounding enters w as rho_alt); locked out (§6 step 6), X1 and X2 are
        predicted only and X3 = a (its error enters w)."""
        steps, F, u = self.steps, self.F, self.u
        if locked:
            if (used, rebase, locked) not in steps:
                IKH = np.diag([1.0, 1.0, 0.0])
                steps[used, rebase, locked] = (IKH @ F, np.abs(IKH) @ u, None, None)
            return steps[used, rebase, locked]
        if (used, rebase) not in steps:
            col, dcol, rcol = self.col, self.dcol, self.rcol
            b1, b2 = ("G11", "G21", "G31"), ("G12", "G22", "G32")
            bcols = acols = None
            if used:
                Hs = [np.array([[1.0, 0.0, 0.0]])]
                Ks = [col(b1)]
                bcols = (rcol(b1), dcol(b1), np.abs(col(b1)))
            else:
                Hs, Ks = [], []
            if self.accel:
                Hs.append(np.array([[0.0, 0.0, 1.0]]))
                Ks.append(col(b2))
                acols = (rcol(b2), dcol(b2), np.abs(col(b2)))
            if Hs:
                H = np.vstack(Hs)
                Kt = np.stack(Ks, axis=1)
                IKH = np.eye(3) - Kt @ H
            else:
                IKH = np.eye(3)
            if rebase:
                IKH = IKH.copy()
                IKH[0, 0] = 0.0
            steps[used, rebase] = (IKH @ F, np.abs(IKH) @ u, bcols, acols)
        return steps[used, rebase]


class _PhiSum:
    """``B = sum_s |Phi(t, s+1)| w_s`` of :func:`kalman_switched_bound`, carried exactly from sample to sample.

    The terms live in preallocated buffers instead of arrays regrown every sample: ``phi[cur][:k]`` is the stack
    of products (oldest first, as the concatenations built it), ``ws[:k]`` the w_s, ``wmax[:k]`` their row maxima.
    Every array handed to matmul and einsum is a C-contiguous (k, 3, 3) / (k, 3) block at the start of its buffer,
    shaped and strided like the fresh arrays before: the same BLAS and einsum kernels run on the same numbers, so
    every float is unchanged."""

    def __init__(self, n: int) -> None:
        cap = n + 1
        self.phi = [np.empty((cap, 3, 3)), np.empty((cap, 3, 3))]
        self.cur = 0
        self.aphi = np.empty((cap, 3, 3))
        self.ws = np.empty((cap, 3))
        self.wmax = np.empty(cap)
        self.k = 0

    def start(self, w0: tuple[float, float, float]) -> np.ndarray:
        """The pad calibration completes: one term, Phi = I, w = the GND rounding ``w0``; returns B."""
        self.phi[self.cur][0] = np.eye(3)
        self.ws[0] = w0
        self.wmax[0] = self.ws[0].max()
        self.k = 1
        return self.ws[0].copy()

    def push(self, A: np.ndarray, wt: np.ndarray) -> np.ndarray:
        """One sample: every Phi is multiplied by its A, the sample's own term (I, wt) appended; returns B, the
        terms decayed below 1e-15 of it dropped (they only shrink further)."""
        phi, ws, wmax, k = self.phi, self.ws, self.wmax, self.k
        nxt = phi[1 - self.cur]
        if k:
            np.matmul(A, phi[self.cur][:k], out=nxt[:k])
        nxt[k] = np.eye(3)
        self.cur = cur = 1 - self.cur
        ws[k] = wt
        wmax[k] = wt.max()
        k += 1
        self.k = k
        absphis = np.abs(phi[cur][:k], out=self.aphi[:k])
        B = np.einsum("sij,sj->i", absphis, ws[:k])
        thr = 1e-15 * max(B.max(), 1e-300)
        # Shortcut, exact: a finite B means every entry of every |Phi| and w is finite (each enters B once), so a
        # term's maximum entry is >= its |Phi[0, 0]|, and rounding is monotone: |Phi[0, 0]| * wmax > thr > 0
        # (so wmax > 0) implies max|Phi| * wmax > thr. When that holds for every term, nothing is dropped.
        if all(map(math.isfinite, B.tolist())) and (absphis[:, 0, 0] * wmax[:k] > thr).all():
            return B
        # the per-term maximum of the 9 entries as a tree of elementwise maxima (exact, NaN-propagating: the same
        # values as .max(axis=(1, 2)), which reduces each short row separately and costs ~30 ns a term)
        a9 = absphis.reshape(k, 9)
        m4 = np.maximum(a9[:, :4], a9[:, 4:8])
        amax = np.maximum(np.maximum(np.maximum(m4[:, 0], m4[:, 1]), np.maximum(m4[:, 2], m4[:, 3])), a9[:, 8])
        keep = amax * wmax[:k] > thr
        keep[-1] = True
        if not keep.all():
            m = int(np.count_nonzero(keep))
            phi[cur][:m] = phi[cur][:k][keep]
            ws[:m] = ws[:k][keep]
            wmax[:m] = wmax[:k][keep]
            self.k = m
        return B


def kalman_switched_bound(consts: "FirmwareConstants", fm: FloatTrace, adc: np.ndarray,
                          acc: np.ndarray | None = None) -> SwitchedBound:
    """Bound on ``|X_int - X_mirror|`` (X1, X2, X3, word scale) for ONE stream, valid at every sample while the
    integer run takes the same decisions as the mirror ``fm`` (barometer used or not: valid / gated; transonic
    gains or not). Derivation (docs/numerics.md, "Switched bound"): with ``delta`` the state difference,

        delta_{t+1} = A_t delta_t + w_t,   A_t = (I - K_t H_t) F,   |w_t| <= (I - K_t H_t)|u| + r_t

    where ``H_t``/``K_t`` are the measurement rows and design gains applied at sample t (both rows; the
    accelerometer row only when the barometer was not used: gated, invalid, Mach lockout; on a re-base sample the
    predicted X1 is dropped and X1 carries the table's rounding; on the velocity re-base after an accelerometer
    clip X2 also carries the window's innovation error, sum of the margins times 2^-K, plus rho(K)), ``u`` the
    predict rounding, ``r_t`` the rounding of each gain multiply, the gain quantization times the
    integer innovation (|e1_int| <= |e1_mirror| + margin), the table interpolation's rounding times the
    barometer gains, and the accelerometer scale's rounding and quantization. Pad calibration leaves ``delta_0 =
    (rho(CAL_P) + rho(ALT_SHIFT), 0, 0)`` (GND) and an ACC0 error of rho(CAL_P) counts. Then ``|delta_t| <=
    sum_s |Phi(t, s+1)| |w_s| + |Phi(t, c0)| |delta_0|``, computed exactly by carrying every product ``Phi`` (no
    geometric tail, no stability assumption): :class:`_PhiSum`, with the matrices of :class:`_StepMatrices`."""
    if consts.program not in ("kalman_baro", "kalman_accel"):
        raise UserError(f"kalman_switched_bound: {consts.program!r} is not a Kalman program")
    mode = "half_up" if consts.ROUND else "floor"
    rho = lambda s: rounding_error_bound(s, mode)
    accel = consts.program == "kalman_accel"
    adc = np.asarray(adc, dtype=np.float64)
    acc = np.zeros_like(adc) if acc is None else np.asarray(acc, dtype=np.float64)
    K = int(consts.K)
    dt = 2.0 ** -K
    F = np.array([[1.0, dt, dt * dt / 2], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
    u = np.array([rho(K) + rho(2 * K + 1), rho(K), 0.0])
    rho_alt = rho(int(consts.ALT_SHIFT))
    names, w, init = fm.names, fm.words, fm.init_words
    prev = np.vstack([init[None, :], w[:-1]])
    ev = w[:, names.index("EVENTS")].astype(np.int64)
    cal_prev = prev[:, names.index("CAL")]
    if accel:
        lock_prev, lock_now = prev[:, names.index("LOCK")], w[:, names.index("LOCK")]
        ev_prev = prev[:, names.index("EVENTS")].astype(np.int64)
        # the velocity re-base after a clip (§6 step 4): CLIP_CLEAR set on this sample; its window is the 2^(K+1)
        # samples ending here
        clip_rebase = ((ev & _CLIP_CLEAR) != 0) & ((ev_prev & _CLIP_CLEAR) == 0)
        win_n = 2 << int(consts.K)
        g_acc = consts.gains["ACC_G"]
        acc0_f = prev[:, names.index("ACC0")]
        a_err_base = rho(g_acc.s) + abs(g_acc.value - consts.float_gains["ACC_G"]) * np.abs(acc - acc0_f)
        acc_g = consts.float_gains["ACC_G"]
    ncal = 1 << int(consts.CAL_P)
    n = len(adc)
    bound = np.zeros((n, 3))
    margin = np.zeros(n)
    ok = (adc >= consts.BARO_MIN) & (adc <= consts.BARO_MAX)
    absF = np.abs(F)
    rho_cal = rho(int(consts.CAL_P))
    acc_cal = abs(acc_g) * rho_cal if accel else 0.0
    step_consts = _StepMatrices(consts, F, u, rho, accel)
    # The barometer's table value at every valid sample in one call (elementwise: the same floats as one call per
    # sample). A table that fails on some valid sample falls back to the per-sample call, which raises where it did.
    h_all = None
    if adc.ndim == 1:
        try:
            h_all = _alt_table_float(consts)(np.where(ok, adc, 0.0))
        except Exception:  # noqa: BLE001 - re-raised by the per-sample lookup at the sample that needs it
            h_all = None
    terms = _PhiSum(n)
    B = np.zeros(3)
    for t in range(n):
        if cal_prev[t] < ncal:                          # §6 step 1: pad calibration
            if ok[t] and cal_prev[t] + 1 == ncal:       # calibration completes: the GND/ACC0 rounding
                B = terms.start((rho_cal + rho_alt, 0.0, 0.0))
            bound[t] = B if cal_prev[t] + 1 >= ncal and ok[t] else np.array([rho_alt, 0.0, 0.0])  # X1 = alt(adc0)
            continue
        x1p = prev[t, 0] + prev[t, 1] * dt + prev[t, 2] * dt * dt / 2      # step 2: predict
        pred_b = absF @ B + u
        margin[t] = pred_b[0] + rho_alt
        crebase = bool(accel and clip_rebase[t])                            # step 4: the decisions the mirror took
        rebase = crebase or bool(accel and lock_prev[t] == 1 and lock_now[t] == 0 and not ev[t] & _MACH)
        used = bool(ok[t] and not (ev[t] & (_BARO_REJECT | _MACH)) and not rebase)
        locked = bool(accel and ev[t] & _MACH)
        A, iku, bcols, acols = step_consts(used, rebase, locked)
        r = np.zeros(3)
        if rebase:                                                          # step 5: X1 = h
            r[0] += rho_alt
        if crebase:
            # X2 += rs(E0, K): E0 sums the window's innovations h - X1 (predicted), each within margin of the
            # mirror's (the X1 prediction's bound plus the table's rounding), so |dE0| <= sum of the margins and
            # the re-base adds |dE0| 2^-K + rho(K) to X2's error (column 1 of I - K H is e_1 on this sample)
            r[1] += float(margin[max(0, t - win_n + 1):t + 1].sum()) * dt + rho(K)
        if used:                                                            # step 6: the barometer's products
            e1 = h_all[t] - x1p if h_all is not None else _alt_mirror_e1(consts, adc[t], x1p)
            e1_int = abs(e1) + margin[t]
            rc, dc, ac = bcols
            r += rc + dc * e1_int + ac * rho_alt
        if locked:                                                          # X3 = a
            r[2] += a_err_base[t] + acc_cal
        elif accel:                                                         # the accelerometer's products
            e2_int = abs((acc[t] - acc0_f[t]) * acc_g - (prev[t, 2])) + pred_b[2] + a_err_base[t] + acc_cal
            a_err = a_err_base[t] + acc_cal
            rc, dc, ac = acols
            r += rc + dc * e2_int + ac * a_err
        B = terms.push(A, iku + r)
        bound[t] = B
    return SwitchedBound(bound, margin, n)


def _alt_mirror_e1(consts: "FirmwareConstants", adc: float, x1_pred: float) -> float:
    """The mirror's barometer innovation alt_float(adc) - x1_pred (word scale)."""
    return float(_alt_table_float(consts)(np.array([adc]))[0]) - x1_pred

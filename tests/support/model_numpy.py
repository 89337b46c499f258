"""The numpy integer model (vectorised over streams, one Python loop over samples): the implementation that
:mod:`firmware_model.model.run` used before the numba kernels (:mod:`firmware_model.model.kernels`), kept as an
independent second implementation of docs/firmware-spec.md §5-§7 for the cross-check test
(tests/model/test_kernels.py: same words, same first wrap and wrap word) and as the baseline of
bench/bench_model.py. Not used by any command.

It computes every ``.l`` value exactly in numpy ``int64`` and ``wrap32``s it (:mod:`firmware_model.spec.fixed`). It is
written differently from the kernels (whole-array ``np.where`` per step, a wrap tracker object), so a slip in one
is unlikely to be repeated in the other. **A change to the firmware algorithms must be made here too** (or this
module retired together with its cross-check), as for the 68000 assembly and the C port.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from firmware_model.model.run import ModelTrace, rounding_mode
from firmware_model.model.streams import as_input_streams
from firmware_model.model.trace import EVENT_BITS, LATCHED_EVENTS, STATE_WORDS, word_names
from firmware_model.runtime.errors import UserError
from firmware_model.spec.fixed import rs, wrap32, wrapped

if TYPE_CHECKING:  # pragma: no cover - typing only
    from firmware_model.spec.build_constants import FirmwareConstants, QGain

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
_PH_PAD, _PH_BOOST, _PH_COAST, _PH_APOGEE, _PH_DESCENT = (np.int64(v) for v in range(5))


def _clipped(ev: np.ndarray) -> np.ndarray:
    """ACC_CLIP and not CLIP_CLEAR, per stream (docs/firmware-spec.md §5, §6)."""
    return (ev & (_ACC_CLIP | _CLIP_CLEAR)) == _ACC_CLIP


def _rail_count(railc: np.ndarray, a: np.ndarray, ev: np.ndarray, clp: np.ndarray,
                clip_n: np.int64) -> tuple[np.ndarray, np.ndarray]:
    """Spec §5 step 3 / §6 step 7 where ``railc`` (in BOOST, before ACC_CLIP): CLP counts samples at the rail
    (32767), the CLIP_N-th sets ACC_CLIP and CLP = 0. Returns (EVENTS, CLP)."""
    rail = a == 32767
    clp = np.where(railc, np.where(rail, clp + 1, 0), clp)
    clipped = railc & rail & (clp >= clip_n)
    return np.where(clipped, ev | _ACC_CLIP, ev), np.where(clipped, 0, clp)


class _WrapTracker:
    """Records, per stream, the first sample and quantity at which an exact value left the int32 range."""

    def __init__(self, n_streams: int) -> None:
        self.first = np.full(n_streams, -1, dtype=np.int64)
        self.word = np.full(n_streams, "", dtype=object)

    def w32(self, exact: np.ndarray, sample: int, name: str) -> np.ndarray:
        """``wrap32(exact)``, noting streams for which the wrap changed the value."""
        hit = wrapped(exact)
        if hit.any():
            new = hit & (self.first < 0)
            self.first[new] = sample
            self.word[new] = name
            return wrap32(exact)
        return exact

    def mulg(self, e: np.ndarray, g: "QGain", mode: str, sample: int, name: str) -> np.ndarray:
        """``mulg(e, g, mode)`` (docs/firmware-spec.md §1) = ``wrap32(rs(e*m, s, mode))``, noting wraps."""
        return self.w32(rs(e * np.int64(g.m), g.s, mode), sample, name)


def run_model_numpy(consts: "FirmwareConstants", adc: np.ndarray, acc: np.ndarray | None = None) -> ModelTrace:
    """The numpy implementation of :func:`firmware_model.model.run.run_model` (same arguments, same result): run the
    integer model of ``consts.program`` over one or many input streams, bit-exact per
    docs/firmware-spec.md §5-§7.

    * ``adc``: barometer ADC counts (unsigned 16-bit register, 0..65535; a pascal build: the signed 32-bit pascal
      word), shape ``(n,)`` or ``(streams, n)``.
    * ``acc``: accelerometer counts (signed 16-bit register, -32768..32767), same shape, or ``None`` (all zero;
      only ``recursive`` and ``kalman_accel`` read it).

    Sequencing as the harness: sample 0 is seen by ``init`` and by the first ``step``. Returns a
    :class:`ModelTrace` whose ``words`` (int64; ``.l`` words signed int32, ``.w`` words unsigned 16-bit) are in
    the order of :data:`firmware_model.model.trace.STATE_WORDS`, shape ``(n, n_words)`` for 1-D input or ``(streams, n,
    n_words)`` for 2-D input; ``init_words`` likewise without the sample axis. Raises :class:`UserError` for
    inputs that the 16-bit input registers cannot hold or a bad program / rounding constant.
    """
    program = consts.program
    if program not in STATE_WORDS:
        raise UserError(f"build constants: unknown program {program!r}; known: {', '.join(STATE_WORDS)}")
    mode = rounding_mode(consts)
    one_stream = np.ndim(adc) == 1
    adc2, acc2 = as_input_streams(adc, acc, bool(getattr(consts, "PASCAL", 0)))
    if consts.BARO_SIGN not in (1, -1):
        raise UserError(f"build constants: BARO_SIGN={consts.BARO_SIGN!r} must be +1 or -1")
    runner = {"recursive": _run_recursive, "recursive_seed_literal": _run_seed_literal,
              "kalman_baro": _run_kalman, "kalman_accel": _run_kalman}[program]
    tracker = _WrapTracker(adc2.shape[0])
    init_words, words = runner(consts, mode, adc2, acc2, tracker)
    names = word_names(program)
    if one_stream:
        return ModelTrace(program, names, words[0], init_words[0], first_wrap=int(tracker.first[0]),
                          wrap_word=str(tracker.word[0]))
    return ModelTrace(program, names, words, init_words, first_wrap=tracker.first, wrap_word=tracker.word)


# ---------------------------------------------------------------------------------------------------- recursive
def _run_recursive(consts: "FirmwareConstants", mode: str, adc: np.ndarray, acc: np.ndarray,
                   tr: _WrapTracker) -> tuple[np.ndarray, np.ndarray]:
    """docs/firmware-spec.md §5 (EST, EXT, VEL, ACC0, EVENTS, ZL, SUMA, CAL, REJ, NEG, PHASE, CST, CLP)."""
    n_streams, n = adc.shape
    S = int(consts.S)
    z_all = adc * np.int64(consts.BARO_SIGN)
    zin = z_all << np.int64(8 - S)                  # exact: |z| <= 2^31 (pascal word), so |z << 7| <= 2^38
    est = wrap32(z_all[:, 0] << np.int64(8))        # exact for |z| < 2^23 (every ADC word, every sane pascal)
    ext = est.copy()
    vel = np.zeros(n_streams, dtype=np.int64)
    acc0 = acc[:, 0].copy()
    ev = np.zeros(n_streams, dtype=np.int64)
    zl = wrap32(z_all[:, 0])
    suma = np.zeros(n_streams, dtype=np.int64)
    cal = np.zeros(n_streams, dtype=np.int64)
    rej = np.zeros(n_streams, dtype=np.int64)
    neg = np.zeros(n_streams, dtype=np.int64)
    phase = np.zeros(n_streams, dtype=np.int64)
    cst = np.zeros(n_streams, dtype=np.int64)
    clp = np.zeros(n_streams, dtype=np.int64)
    init = np.stack([est, ext, vel, acc0, ev, zl, suma, cal, rej, neg, phase, cst, clp], axis=-1)
    out = np.empty((n_streams, n, 13), dtype=np.int64)
    a_drag, clip_n, clear_n = np.int64(consts.A_DRAG), np.int64(consts.CLIP_N), np.int64(1 << int(consts.K))
    a_coast, coast_n, v_desc = np.int64(consts.A_COAST), np.int64(consts.COAST_N), np.int64(consts.V_DESC)
    v_lift, v_gate, thr = np.int64(consts.V_LIFT), np.int64(consts.V_GATE), np.int64(consts.THR)
    cal_p = int(consts.CAL_P)
    ncal = np.int64(1 << cal_p)
    d_gate, gate_n, apo_n = np.int64(consts.E_GATE), np.int64(consts.GATE_N), np.int64(consts.APO_N)
    for i in range(n):
        a = acc[:, i]
        z = z_all[:, i]
        ev = ev & LATCHED_EVENTS                     # 0. per-sample bits
        calib = cal < ncal
        run = ~calib
        # 1. pad calibration of ACC0 (exact: |SUMA| <= 2^23)
        suma = np.where(calib, suma + a, suma)
        cal = np.where(calib, cal + 1, cal)
        done = calib & (cal == ncal)
        acc0 = np.where(done, rs(suma, cal_p, mode), acc0)
        # 2. velocity and liftoff (after calibration)
        if run.any():
            vel = np.where(run, vel + (a - acc0), vel)
            vel = tr.w32(vel, i, "VEL")
        lifting = run & ((ev & _LIFTOFF) == 0) & (vel > v_lift)
        ev = np.where(lifting, ev | _LIFTOFF, ev)
        phase = np.where(lifting, _PH_BOOST, phase)
        # phases: coast after COAST_N samples below -A_COAST (boost), descent after apogee
        boost = run & (phase == _PH_BOOST)
        low = (a - acc0) < -a_coast
        cst = np.where(boost, np.where(low, cst + 1, 0), cst)
        phase = np.where(boost & low & (cst >= coast_n), _PH_COAST, phase)
        # after a clip, in coast: 2^K consecutive samples with a drag reading at or below A_DRAG clear it
        dragc = run & ~boost & (phase == _PH_COAST) & _clipped(ev)
        dlow = (a - acc0) >= -a_drag
        clp = np.where(dragc, np.where(dlow, clp + 1, 0), clp)
        ev = np.where(dragc & dlow & (clp >= clear_n), ev | _CLIP_CLEAR, ev)
        phase = np.where(run & ~boost & (phase == _PH_APOGEE) & (vel < -v_desc), _PH_DESCENT, phase)
        # 3. accelerometer at its rail for CLIP_N samples in a row, in boost
        ev, clp = _rail_count(run & (phase == _PH_BOOST) & ((ev & _ACC_CLIP) == 0), a, ev, clp, clip_n)
        # 4a. armed once VEL is back below the gate, on a sample after the one that set GATE_HIGH (4b runs after)
        ev = np.where(run & ((ev & _GATE_HIGH) != 0) & ((ev & _ARMED) == 0) & (vel < v_gate), ev | _ARMED, ev)
        # 4b. the accelerometer velocity has exceeded the gate since liftoff
        ev = np.where(run & ((ev & _LIFTOFF) != 0) & (vel > v_gate), ev | _GATE_HIGH, ev)
        # 5. barometer rate gate, then the filter
        zw = wrap32(z)
        d = wrap32(zw - zl)                          # SUB.L
        inside = (d >= -d_gate) & (d <= d_gate)
        reject = ~inside & (rej < gate_n)
        rebase = ~inside & ~reject                   # the gate opens on a lasting shift: EST, EXT move with it
        rej = np.where(inside, 0, np.where(reject, rej + 1, rej))
        ev = np.where(reject, ev | _BARO_REJECT, ev)
        if rebase.any():
            est = np.where(rebase, tr.w32(np.where(rebase, est + (d << np.int64(8)), est), i, "EST"), est)
            ext = np.where(rebase, tr.w32(np.where(rebase, ext + (d << np.int64(8)), ext), i, "EXT"), ext)
        use = ~reject
        zl = np.where(use, zw, zl)
        est = np.where(use, tr.w32(np.where(use, est + zin[:, i] - rs(est, S, mode), est), i, "EST"), est)
        # 6. extreme and apogee (after a clip: APO_N samples of evidence)
        up = est > ext
        ext = np.where(up, est, ext)
        live = ~up & ((ev & _ARMED) != 0) & ((ev & _APOGEE) == 0)
        below = (ext - est >= thr) & ~_clipped(ev)
        neg = np.where(up, 0, np.where(live, np.where(below, neg + 1, 0), neg))
        need = np.where((ev & _ACC_CLIP) != 0, apo_n, np.int64(1))
        fire = live & below & (neg >= need)
        ev = np.where(fire, ev | _APOGEE, ev)
        phase = np.where(fire, _PH_APOGEE, phase)
        for j, col in enumerate((est, ext, vel, acc0, ev, zl, suma, cal, rej, neg, phase, cst, clp)):
            out[:, i, j] = col
    return init, out


def _run_seed_literal(consts: "FirmwareConstants", mode: str, adc: np.ndarray, acc: np.ndarray,
                      tr: _WrapTracker) -> tuple[np.ndarray, np.ndarray]:
    """The pseudo-listing of Schultz 2002 as written (step 4 with the subtraction backwards, no flight logic)."""
    n_streams, n = adc.shape
    S = int(consts.S)
    z = adc * np.int64(consts.BARO_SIGN)
    zin = z << np.int64(8 - S)
    est = wrap32(z[:, 0] << np.int64(8))
    init = est[:, None].copy()
    out = np.empty((n_streams, n, 1), dtype=np.int64)
    for i in range(n):
        est = tr.w32(est + rs(est, S, mode) - zin[:, i], i, "EST")
        out[:, i, 0] = est
    return init, out


# ---------------------------------------------------------------------------------------------------- Kalman
def _run_kalman(consts: "FirmwareConstants", mode: str, adc: np.ndarray, acc: np.ndarray,
                tr: _WrapTracker) -> tuple[np.ndarray, np.ndarray]:
    """docs/firmware-spec.md §6 (kalman_baro: X1 X2 X3 EVENTS APFRAC GND SUMZ CAL REJ NEG PHASE CST DLY VB HMAX HT;
    kalman_accel: X1 X2 X3 ACC0 EVENTS APFRAC GND SUMZ SUMA CAL REJ NEG PHASE CST DLY VB LOCK CLP E0 HMAX HT HP)."""
    accel = consts.program == "kalman_accel"
    n_streams, n = adc.shape
    K = int(consts.K)
    g = consts.gains
    g1 = [g["G11"], g["G21"], g["G31"]]
    g2 = [g["G12"], g["G22"], g["G32"]] if accel else None
    acc_g = g["ACC_G"] if accel else None
    table = np.asarray(consts.ALT_TABLE, dtype=np.int64)
    sh = int(consts.ALT_SHIFT)
    baro_ok_all = (adc >= consts.BARO_MIN) & (adc <= consts.BARO_MAX)
    a_safe = np.where(baro_ok_all, adc, 0)
    ii = a_safe >> np.int64(sh)
    ff = a_safe & np.int64((1 << sh) - 1)
    lo = table[ii]
    h_all = np.where(baro_ok_all, lo + rs((table[ii + 1] - lo) * ff, sh, mode), 0)   # alt(adc), exact
    ncal = 1 << int(consts.CAL_P)
    x1 = h_all[:, 0].copy()
    gnd = x1.copy()
    x2 = np.zeros(n_streams, dtype=np.int64)
    x3 = np.zeros(n_streams, dtype=np.int64)
    acc0 = acc[:, 0].copy()
    sumz = np.zeros(n_streams, dtype=np.int64)
    suma = np.zeros(n_streams, dtype=np.int64)
    cal = np.zeros(n_streams, dtype=np.int64)
    rej = np.zeros(n_streams, dtype=np.int64)
    neg = np.zeros(n_streams, dtype=np.int64)
    ev = np.zeros(n_streams, dtype=np.int64)
    apfrac = np.zeros(n_streams, dtype=np.int64)
    zero = np.zeros(n_streams, dtype=np.int64)
    phase = np.zeros(n_streams, dtype=np.int64)
    cst = np.zeros(n_streams, dtype=np.int64)
    dly = np.zeros(n_streams, dtype=np.int64)
    vb = np.zeros(n_streams, dtype=np.int64)
    lock = np.zeros(n_streams, dtype=np.int64)
    clp = np.zeros(n_streams, dtype=np.int64)
    e0 = np.zeros(n_streams, dtype=np.int64)
    hmax = x1.copy()
    ht = np.zeros(n_streams, dtype=np.int64)
    hp = x1.copy()

    def row():
        cols = [x1, x2, x3] + ([acc0] if accel else []) + [ev, apfrac, gnd, sumz] + ([suma] if accel else [])
        return (cols + [cal, rej, neg, phase, cst, dly, vb] + ([lock, clp, e0] if accel else []) + [hmax, ht]
                + ([hp] if accel else []))

    init = np.stack(row(), axis=-1)
    out = np.empty((n_streams, n, init.shape[-1]), dtype=np.int64)
    v_lift, vlo = np.int64(consts.V_LIFT), np.int64(consts.MACH_VLO)
    e_gate, gate_n, apo_n = np.int64(consts.E_GATE), np.int64(consts.GATE_N), np.int64(consts.APO_N)
    mach_n, dly_n, dv, du = (np.int64(v) for v in (consts.MACH_N, consts.DLY_N, consts.DV, consts.DU))
    a_coast, coast_n, v_desc = np.int64(consts.A_COAST), np.int64(consts.COAST_N), np.int64(consts.V_DESC)
    a_drag, clip_n = np.int64(consts.A_DRAG), np.int64(consts.CLIP_N)
    half_n, win_n = np.int64(1 << K), np.int64(2 << K)
    guards = int(consts.GUARDS)
    thrust_g, gravity_g, floor_g, descent_g = (bool(guards & b) for b in (1, 2, 4, 8))
    dg, v_fall, h_floor = np.int64(consts.DG), np.int64(consts.V_FALL), np.int64(consts.H_FLOOR)
    desc_n = np.int64(consts.DESC_N)
    h_step = np.int64(consts.H_STEP)
    for i in range(n):
        ev = ev & LATCHED_EVENTS
        baro_ok = baro_ok_all[:, i]
        ev = np.where(baro_ok, ev, ev | _BARO_INVALID)
        h = h_all[:, i]
        calib = cal < ncal
        run = ~calib
        count = calib & baro_ok
        if count.any():
            sumz = np.where(count, tr.w32(sumz + h, i, "SUMZ"), sumz)
            if accel:
                suma = np.where(count, tr.w32(suma + acc[:, i], i, "SUMA"), suma)
            cal = np.where(count, cal + 1, cal)
            done = count & (cal == ncal)
            gnd = np.where(done, rs(sumz, int(consts.CAL_P), mode), gnd)
            x1 = np.where(done, gnd, x1)
            hmax = np.where(done, gnd, hmax)
            if accel:
                acc0 = np.where(done, rs(suma, int(consts.CAL_P), mode), acc0)
        # 2. predict
        t1 = rs(x2, K, mode) + rs(x3, 2 * K + 1, mode)
        t2 = rs(x3, K, mode)
        x1 = np.where(run, tr.w32(np.where(run, x1 + t1, 0), i, "X1"), x1)
        x2 = np.where(run, tr.w32(np.where(run, x2 + t2, 0), i, "X2"), x2)
        # 3. accelerometer innovation (kalman_accel)
        if accel:
            a = tr.mulg(np.where(run, acc[:, i] - acc0, 0), acc_g, mode, i, "mulg(acc,ACC_G)")
            e2 = tr.w32(np.where(run, a - x3, 0), i, "e2")
        # 4. Mach lockout (kalman_accel): X2 above MACH_VLO, then MACH_N samples of settling, then a re-base
        locked = np.zeros(n_streams, dtype=bool)
        rebase = np.zeros(n_streams, dtype=bool)
        if accel:
            # after a clip: locked until a 2^(K+1)-sample window of drag-low coast samples re-bases the velocity
            # a re-base only on a steady sample: within H_STEP of the previous valid one
            steady = baro_ok & (h - hp >= -h_step) & (h - hp <= h_step)
            clipm = run & _clipped(ev)
            win = clipm & (phase == _PH_COAST) & (a >= -a_drag) & steady
            if win.any():
                e = tr.w32(np.where(win, h - x1, 0), i, "e1")
                clp = np.where(win, clp + 1, clp)
                s0 = np.where(clp <= half_n, e0 - e, e0 + e)
                e0 = np.where(win, tr.w32(np.where(win, s0, 0), i, "E0"), e0)
            clp = np.where(clipm & ~win, 0, clp)
            e0 = np.where(clipm & ~win, 0, e0)
            done = win & (clp == win_n)
            if done.any():
                x2 = np.where(done, tr.w32(np.where(done, x2 + rs(e0, K, mode), 0), i, "X2"), x2)
            vb = np.where(done, x2, vb)
            ev = np.where(done, ev | _CLIP_CLEAR, ev)
            # above the Mach threshold, or (thrust guard) PHASE still BOOST: the barometer stays out
            fast = run & ~clipm & ((((ev & _LIFTOFF) != 0) & (x2 > vlo))
                                   | (thrust_g & ((phase == _PH_BOOST) | ((phase == _PH_PAD) & (a > a_coast)))))
            settle = run & ~clipm & ~fast & (lock > 1)
            last = run & ~clipm & ~fast & (lock == 1)
            locked = (clipm & ~done) | fast | settle | (last & ~steady)
            rebase = (last & steady) | done
            lock = np.where(clipm, np.where(done, 0, mach_n),
                            np.where(fast, mach_n, np.where(settle, lock - 1, np.where(rebase, 0, lock))))
            ev = np.where(locked, ev | _MACH, ev)
        # 5. innovation and gate (a re-base sets X1 = h and uses no barometer correction)
        x1 = np.where(rebase, h, x1)
        rej = np.where(rebase, 0, rej)
        live = run & baro_ok & ~locked & ~rebase
        e1 = tr.w32(np.where(live, h - x1, 0), i, "e1")
        inside = (e1 >= -e_gate) & (e1 <= e_gate)
        reject = live & ~inside & (rej < gate_n)
        use = live & ~reject
        rej = np.where(live & inside, 0, np.where(reject, rej + 1, rej))
        ev = np.where(reject, ev | _BARO_REJECT, ev)
        # 6. correct (locked out: X1, X2 only predicted, X3 = a, the accelerometer alone)
        xs = [x1, x2, x3]
        corr = run & ~locked
        if accel:
            e2c = np.where(locked, 0, e2)
        for j in range(3):
            c1 = np.where(use, tr.mulg(e1, g1[j], mode, i, f"mulg(e1,G{j + 1}1)"), zero)
            c = xs[j] + c1
            if accel:
                c = c + tr.mulg(e2c, g2[j], mode, i, f"mulg(e2,G{j + 1}2)")
            xs[j] = np.where(corr, tr.w32(np.where(corr, c, 0), i, f"X{j + 1}"), xs[j])
        x1, x2, x3 = xs
        if accel:
            x3 = np.where(locked, a, x3)
        # 7. liftoff and Mach delay
        lift_before = (ev & _LIFTOFF) != 0
        dly = np.where(run & lift_before & (dly > 0), dly - 1, dly)
        lifting = run & ~lift_before & (x2 > v_lift)
        ev = np.where(lifting, ev | _LIFTOFF, ev)
        phase = np.where(lifting, _PH_BOOST, phase)
        dly = np.where(lifting, dly_n, dly)
        # accelerometer at its rail for CLIP_N samples in a row, in boost (kalman_accel)
        if accel:
            ev, clp = _rail_count(run & (phase == _PH_BOOST) & ((ev & _ACC_CLIP) == 0), acc[:, i], ev, clp, clip_n)
        # 8. plausibility bound
        fall = np.where(gravity_g & (vb <= 0), dg, dv)      # gravity guard: below zero VB falls at g only
        vb = np.where(run, np.minimum(np.maximum(x2, vb - fall), vb + du), vb)
        # 8b. descent record (valid samples)
        rec = run & baro_ok
        rise = rec & (h > hmax)
        ht = np.where(rise, 0, np.where(rec & (ht < desc_n), ht + 1, ht))
        hmax = np.where(rise, h, hmax)
        if accel:
            hp = np.where(rec, h, hp)
        # 9. phases and apogee
        boost = run & (phase == _PH_BOOST)
        low = x3 < -a_coast
        cst = np.where(boost, np.where(low, cst + 1, np.maximum(cst - 1, 0)), cst)   # issue 30: one back
        phase = np.where(boost & low & (cst >= coast_n), _PH_COAST, phase)
        coast = run & (phase == _PH_COAST)
        phys = (x2 - vb >= -v_fall) if gravity_g else np.ones(n_streams, dtype=bool)
        fl_h = gnd + h_floor
        high = ((x1 >= fl_h) & (~baro_ok | (h >= fl_h))) if floor_g else np.ones(n_streams, dtype=bool)
        down = (~baro_ok | (h < hmax) | (ht >= desc_n)) if descent_g else np.ones(n_streams, dtype=bool)
        evid = coast & (dly == 0) & (vb < 0) & ~_clipped(ev) & phys & high
        neg = np.where(coast, np.where(evid, np.where(down, neg + 1, neg), 0), neg)   # descent guard: a pause
        evid = evid & down
        fire = evid & (neg >= apo_n)
        ev = np.where(fire, ev | _APOGEE, ev)
        phase = np.where(fire, _PH_APOGEE, phase)
        phase = np.where(run & ~coast & (phase == _PH_APOGEE) & (x2 < -v_desc), _PH_DESCENT, phase)
        fl = run & (phase == _PH_COAST)
        # 10. low-rate apogee prediction
        cand = fl & ((ev & _PREDICTED) == 0) & (x2 > 0) & ~_clipped(ev)
        if cand.any():
            d = -rs(x3, K, mode)
            hit = cand & (x2 < d)
            if hit.any():
                dd = np.where(hit, d, 1)
                v = np.where(hit, x2, 0)
                while True:
                    big = dd >= 32768
                    if not big.any():
                        break
                    dd = np.where(big, dd >> 1, dd)
                    v = np.where(big, v >> 1, v)
                frac = np.minimum(65535, (v << np.int64(16)) // dd)
                apfrac = np.where(hit, frac, apfrac)
                ev = np.where(hit, ev | _PREDICTED, ev)
        out[:, i] = np.stack(row(), axis=-1)
    return init, out

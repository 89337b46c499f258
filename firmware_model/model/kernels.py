"""The integer model's kernels: one Python source, compiled with numba when it is importable, run as plain Python
(exact Python ints) when it is not or when ``FWEMU_NO_NUMBA=1``.

docs/firmware-spec.md §5-§7 bit for bit. :func:`firmware_model.model.run.run_model` packs the build constants
(:func:`pack_constants`), allocates the arrays and calls :func:`run_streams` (or :func:`run_streams_serial`
for small calls), which runs every stream (in parallel with ``prange`` when compiled) through the program's
``*_init`` once and its ``*_step`` per sample.

Layout, chosen so that a program is easy to change or add:

* **State**: a small 1-D integer array per stream, indices ``X1`` ... below (the Kalman programs share one
  layout; ``OUT_COLS[program]`` says which state entries are the output words, in
  :data:`firmware_model.model.trace.STATE_WORDS` order). Extra internal state goes after the output words
  (raise ``N_STATE``).
* **Constants**: one 1-D integer array, indices ``C_*`` below, filled by :func:`pack_constants` from a
  :class:`~firmware_model.spec.build_constants.FirmwareConstants`. A new constant: a new index + a line in
  :func:`pack_constants`.
* **Programs**: ``<program>_init(st, adc, acc, c)`` and ``<program>_step(st, adc, acc, c) -> wrap id`` for each
  program, dispatched on the program number ``P_*`` by :func:`_init` and :func:`run_stream` (which calls one
  sample loop per program, ``_stream_<program>``); :func:`run_streams` runs it over the streams in parallel,
  :func:`run_streams_serial` on one thread. A table (e.g. a lookup table of the firmware) can be appended
  to the constants array (its first index a ``C_*`` constant) without changing any signature.
* **Wrap detection**: every ``.l`` value is computed exactly, then :func:`_note` records the first quantity of
  the sample whose exact value is outside int32 (its id, an index into :data:`WRAP_NAMES`) and :func:`_w32`
  wraps it; ``step`` returns that id (0: none) and the driver keeps the first sample with a nonzero id.

Exactness. Compiled, every integer is an ``int64``; uncompiled, :func:`firmware_model.model.run.run_model` passes
object arrays, so every value is an exact Python ``int``. The int64 arithmetic is exact because no intermediate
leaves int64: state words and constants are int32, inputs 16-bit (or the pascal kind's signed 32-bit word, whose
``z << 8`` stays below 2^40 in the recursive programs), so sums of a few int32 values stay below 2^34,
the gain products ``e * m`` (``e`` a wrapped int32 or ``acc - ACC0`` with ``|.| <= 65535``, ``|m| <= 2^15``) below
2^46, and ``v << 16`` in the apogee prediction below 2^31 (``0 < v < d < 2^15`` there). Hence the exact values
used for wrap detection are the int64 values themselves. tests/model/test_kernels.py checks this by running the
compiled and the Python-int steps from states and constants at the int32 extremes. numba's ``>>`` on a signed
int64 is an arithmetic shift (LLVM ``ashr``), i.e. floor like Python's; shifts are clamped to 63 (a shift of an
int64 by 63 already gives the floor, 0 or -1; numba/LLVM shifts by >= 64 are undefined) - never reached by the
spec's shifts (``2K + 1 <= 21``, gain shifts <= 47).
"""

from __future__ import annotations

import os

import numpy as np

# ------------------------------------------------------------------------------------------- compiled or not
#: Set to True on the module object before executing it (firmware_model.model.run.pure_kernels) for a Python copy.
FORCE_PURE: bool = bool(globals().get("FORCE_PURE", False))


def _load_numba():
    if FORCE_PURE or os.environ.get("FWEMU_NO_NUMBA", "").strip() not in ("", "0"):
        return None
    try:
        import numba
    except ImportError:
        return None
    return numba


_numba = _load_numba()
#: True when the functions below are numba-compiled (dispatchers), False when they are plain Python.
COMPILED: bool = _numba is not None

if _numba is not None:
    njit = _numba.njit
    prange = _numba.prange
    if not os.environ.get("NUMBA_THREADING_LAYER"):
        # A fork-safe layer (tbb if installed, else numba's workqueue), not GNU OpenMP: with OpenMP, a process
        # that ran a parallel kernel and then forks workers that run one too (multiprocessing's default on
        # Linux, e.g. a --jobs pool) has them terminate ("fork() called from a process already using GNU
        # OpenMP") and the pool hangs (tests/model/test_kernels.py). workqueue is not thread-safe: run_model
        # holds a lock around the kernel call. Read by numba at the first parallel launch.
        _numba.config.THREADING_LAYER = "forksafe"
else:
    def njit(*args, **kwargs):  # type: ignore[no-redef, unused-ignore]  # redefined only where numba is absent
        """No numba: the decorated function stays plain Python."""
        if args and callable(args[0]):
            return args[0]
        return lambda f: f

    prange = range

# ------------------------------------------------------------------------------------------- numbering
#: Program numbers (the driver's dispatch), in the order of :data:`PROGRAMS`.
P_RECURSIVE = 0
P_SEED_LITERAL = 1
P_KALMAN_BARO = 2
P_KALMAN_ACCEL = 3
PROGRAMS: tuple[str, ...] = ("recursive", "recursive_seed_literal", "kalman_baro", "kalman_accel")

#: State indices. Recursive (and the Schultz 2002 listing, which uses EST only):
EST = 0
EXT = 1
VEL = 2
ACC0_R = 3
EVENTS_R = 4
ZL_R = 5
SUMA_R = 6
CAL_R = 7
REJ_R = 8
NEG_R = 9
PHASE_R = 10
CST_R = 11
CLP_R = 12
#: Kalman (both programs; kalman_baro leaves ACC0 and SUMA at 0 and does not output them):
X1 = 0
X2 = 1
X3 = 2
ACC0 = 3
EVENTS = 4
APFRAC = 5
GND = 6
SUMZ = 7
SUMA = 8
CAL = 9
REJ = 10
NEG = 11
PHASE = 12
CST = 13
DLY = 14
VB = 15
LOCK = 16
CLP = 17
E0 = 18
HMAX = 19
HT = 20
HP = 21
#: Length of the per-stream state array (the largest program's).
N_STATE = 22

#: PHASE values (docs/firmware-spec.md §4a; equal to firmware_model.trace.PHASES' indices, checked by a test).
PH_PAD = 0
PH_BOOST = 1
PH_COAST = 2
PH_APOGEE = 3
PH_DESCENT = 4

#: State entries output per program, in firmware_model.model.trace.STATE_WORDS order.
OUT_COLS: dict[str, tuple[int, ...]] = {
    "recursive": (EST, EXT, VEL, ACC0_R, EVENTS_R, ZL_R, SUMA_R, CAL_R, REJ_R, NEG_R, PHASE_R, CST_R, CLP_R),
    "recursive_seed_literal": (EST,),
    "kalman_baro": (X1, X2, X3, EVENTS, APFRAC, GND, SUMZ, CAL, REJ, NEG, PHASE, CST, DLY, VB, HMAX, HT),
    "kalman_accel": (X1, X2, X3, ACC0, EVENTS, APFRAC, GND, SUMZ, SUMA, CAL, REJ, NEG, PHASE, CST, DLY, VB, LOCK,
                     CLP, E0, HMAX, HT, HP),
}

#: Constant indices (docs/firmware-spec.md §3); gains as (mantissa, shift) pairs.
C_K = 0
C_ROUND = 1
C_BARO_SIGN = 2
C_S = 3
C_THR = 4
C_V_LIFT = 5
C_V_GATE = 6
C_MACH_VLO = 7
C_MACH_VHI = 8
C_MACH_E = 9
C_BARO_MIN = 10
C_BARO_MAX = 11
C_G11_M = 12
C_G11_S = 13
C_G21_M = 14
C_G21_S = 15
C_G31_M = 16
C_G31_S = 17
C_G12_M = 18
C_G12_S = 19
C_G22_M = 20
C_G22_S = 21
C_G32_M = 22
C_G32_S = 23
C_ACC_G_M = 24
C_ACC_G_S = 25
C_G11T_M = 26
C_G11T_S = 27
C_G21T_M = 28
C_G21T_S = 29
C_G31T_M = 30
C_G31T_S = 31
C_ALT_SHIFT = 32
C_CAL_P = 33
C_E_GATE = 34
C_GATE_N = 35
C_APO_N = 36
C_MACH_N = 37
C_DLY_N = 38
C_DV = 39
C_A_COAST = 40
C_COAST_N = 41
C_V_DESC = 42
C_DU = 43
C_A_DRAG = 44
C_CLIP_N = 45
C_GUARDS = 46
C_DG = 47
C_V_FALL = 48
C_H_FLOOR = 49
C_DESC_N = 50
C_H_STEP = 51
#: The altitude table's nodes follow the scalars: c[C_ALT + j] is node j (docs/firmware-spec.md §2a).
C_ALT = 52
N_CONST = 52
_SCALARS = ("K", "ROUND", "BARO_SIGN", "S", "THR", "V_LIFT", "V_GATE", "MACH_VLO", "MACH_VHI", "MACH_E",
            "BARO_MIN", "BARO_MAX")
_GAINS = ("G11", "G21", "G31", "G12", "G22", "G32", "ACC_G", "G11T", "G21T", "G31T")
_SCALARS2 = ("ALT_SHIFT", "CAL_P", "E_GATE", "GATE_N", "APO_N", "MACH_N", "DLY_N", "DV", "A_COAST", "COAST_N",
             "V_DESC", "DU", "A_DRAG", "CLIP_N", "GUARDS", "DG", "V_FALL", "H_FLOOR",
             "DESC_N", "H_STEP")

#: Wrap ids returned by the steps: the name of the quantity (as firmware_model.model.run.ModelTrace.wrap_word).
WRAP_NAMES: tuple[str, ...] = ("", "EST", "VEL", "X1", "X2", "X3", "e1", "e2", "mulg(acc,ACC_G)",
                               "mulg(e1,G11)", "mulg(e1,G21)", "mulg(e1,G31)",
                               "mulg(e2,G12)", "mulg(e2,G22)", "mulg(e2,G32)", "SUMZ", "SUMA",
                               "mulg(e1,G11T)", "mulg(e1,G21T)", "mulg(e1,G31T)", "EXT", "E0")
W_NONE = 0
W_EST = 1
W_VEL = 2
W_X1 = 3
W_X2 = 4
W_X3 = 5
W_E1 = 6
W_E2 = 7
W_ACC = 8
W_E1G11 = 9
W_E1G21 = 10
W_E1G31 = 11
W_E2G12 = 12
W_E2G22 = 13
W_E2G32 = 14
W_SUMZ = 15
W_SUMA = 16
W_E1G11T = 17
W_E1G21T = 18
W_E1G31T = 19
W_EXT = 20
W_E0 = 21

#: Event bits (docs/firmware-spec.md §4; equal to firmware_model.model.trace.EVENT_BITS, checked by a test).
LIFTOFF = 1
ARMED = 2
APOGEE = 4
MACH_LOCKOUT = 8
BARO_INVALID = 16
APOGEE_PREDICTED = 32
GATE_HIGH = 64
BARO_REJECT = 128
ACC_CLIP = 256
CLIP_CLEAR = 512
LATCHED = LIFTOFF | ARMED | APOGEE | APOGEE_PREDICTED | GATE_HIGH | ACC_CLIP | CLIP_CLEAR

#: GUARDS bits (docs/firmware-spec.md §3, §6): the physical guards of issue 30.
G_THRUST = 1
G_GRAVITY = 2
G_FLOOR = 4
G_DESCENT = 8

INT32_MIN = -2147483648
INT32_MAX = 2147483647


def pack_constants(consts, dtype=np.int64) -> np.ndarray:
    """The constants array of a :class:`~firmware_model.spec.build_constants.FirmwareConstants` (indices ``C_*``);
    gains a program does not have are (0, 0). ``dtype=object`` gives Python ints (the uncompiled path)."""
    values = [int(getattr(consts, name)) for name in _SCALARS]
    for name in _GAINS:
        g = consts.gains.get(name)
        values += [0, 0] if g is None else [int(g.m), int(g.s)]
    values += [int(getattr(consts, name)) for name in _SCALARS2]
    values += [int(v) for v in getattr(consts, "ALT_TABLE", ())]
    return np.array(values, dtype=dtype)


# ------------------------------------------------------------------------------------------- fixed point
@njit(cache=True)
def rs(x, s, rnd):
    """Rounding right shift (docs/firmware-spec.md §1): floor (``rnd == 0``) or half_up (``rnd == 1``),
    computed as ``(x >> s) + bit(s-1) of x`` (no intermediate value beyond x)."""
    if s <= 0:
        return x
    q = x >> min(s, 63)
    if rnd != 0:
        q += (x >> min(s - 1, 63)) & 1
    return q


@njit(cache=True)
def _w32(x):
    """wrap32: the exact integer reduced to signed 32-bit two's complement."""
    return ((x + 2147483648) & 4294967295) - 2147483648


@njit("int64(int64, int64, int64)", cache=True)
def _note(w, x, wid):
    """``wid`` if no wrap was noted yet in this sample (``w == 0``) and the exact ``x`` is outside int32.

    Compiled for this one signature at import (cached): its callers pass the wrap id as a constant (``W_X1``
    ...), which numba types as a distinct literal, so a lazily compiled ``_note`` was compiled again for each of
    the 22 (id, first-argument) literal combinations of the steps: ~2.5 CPU-s of a cold ~10.5 s. With the
    signature given, the literals convert to int64; LLVM inlines the call either way (same speed, measured)."""
    if w == 0 and (x < INT32_MIN or x > INT32_MAX):
        return wid
    return w


# ------------------------------------------------------------------------------------------- recursive (§5)
@njit(cache=True)
def recursive_init(st, adc, acc, c):
    """EST = EXT = wrap32(z << 8); VEL = 0; ACC0 = acc; EVENTS = 0; ZL = wrap32(z); SUMA = CAL = REJ = NEG = 0."""
    z = adc * c[C_BARO_SIGN]
    st[EST] = _w32(z << 8)       # exact for |z| < 2^23: every ADC word; a pascal word wraps as LSL.L does
    st[EXT] = _w32(z << 8)
    st[VEL] = 0
    st[ACC0_R] = acc
    st[EVENTS_R] = 0
    st[ZL_R] = _w32(z)
    st[SUMA_R] = 0
    st[CAL_R] = 0
    st[REJ_R] = 0
    st[NEG_R] = 0
    st[PHASE_R] = PH_PAD
    st[CST_R] = 0
    st[CLP_R] = 0


@njit(cache=True, inline="always")
def _clipped(ev):
    """ACC_CLIP and not CLIP_CLEAR: after an accelerometer clip, before the speed is known again (docs/firmware-spec.md
    §5, §6: no apogee evidence, no prediction; kalman_accel keeps the barometer out)."""
    return (ev & (ACC_CLIP | CLIP_CLEAR)) == ACC_CLIP


@njit(cache=True, inline="always")
def _rail_count(st, i_clp, phase, ev, acc, clip_n):
    """docs/firmware-spec.md §5 step 3 and §6 step 7 (the accelerometer programs): in BOOST and before ACC_CLIP,
    st[i_clp] counts consecutive samples at the accelerometer's rail (32767); the CLIP_N-th sets ACC_CLIP and
    CLP = 0. Returns EVENTS."""
    if phase == PH_BOOST and (ev & ACC_CLIP) == 0:
        if acc == 32767:
            st[i_clp] = st[i_clp] + 1
            if st[i_clp] >= clip_n:
                ev |= ACC_CLIP
                st[i_clp] = 0
        else:
            st[i_clp] = 0
    return ev


@njit(cache=True, inline="always")
def recursive_step(st, adc, acc, c):
    """docs/firmware-spec.md §5 steps 0-6; returns the first wrap id of the sample (0: none)."""
    rnd = c[C_ROUND]
    S = c[C_S]
    w = W_NONE
    z = adc * c[C_BARO_SIGN]
    # 0. per-sample bits
    ev = st[EVENTS_R] & LATCHED
    vel = st[VEL]
    cal_p = c[C_CAL_P]
    if st[CAL_R] < (1 << cal_p):
        # 1. pad calibration of ACC0 (steps 2-4 skipped; |SUMA| <= 2^23, exact)
        st[SUMA_R] = st[SUMA_R] + acc
        st[CAL_R] = st[CAL_R] + 1
        if st[CAL_R] == (1 << cal_p):
            st[ACC0_R] = rs(st[SUMA_R], cal_p, rnd)
    else:
        # 2. accelerometer velocity and liftoff
        vel = vel + (acc - st[ACC0_R])
        w = _note(w, vel, W_VEL)
        vel = _w32(vel)
        if (ev & LIFTOFF) == 0 and vel > c[C_V_LIFT]:
            ev |= LIFTOFF
            st[PHASE_R] = PH_BOOST
        # phases: coast after COAST_N samples below -A_COAST; descent after apogee
        if st[PHASE_R] == PH_BOOST:
            if acc - st[ACC0_R] < -c[C_A_COAST]:
                st[CST_R] = st[CST_R] + 1
                if st[CST_R] >= c[C_COAST_N]:
                    st[PHASE_R] = PH_COAST
            else:
                st[CST_R] = 0
        elif st[PHASE_R] == PH_COAST and _clipped(ev):
            if acc - st[ACC0_R] >= -c[C_A_DRAG]:
                st[CLP_R] = st[CLP_R] + 1
                if st[CLP_R] >= (1 << c[C_K]):
                    ev |= CLIP_CLEAR
            else:
                st[CLP_R] = 0
        elif st[PHASE_R] == PH_APOGEE and vel < -c[C_V_DESC]:
            st[PHASE_R] = PH_DESCENT
        # 3. accelerometer at its rail for CLIP_N samples in boost: VEL underestimates from now on
        ev = _rail_count(st, CLP_R, st[PHASE_R], ev, acc, c[C_CLIP_N])
        # 4a. armed once VEL is back below the gate, on a sample after the one that set GATE_HIGH (4b runs after)
        if (ev & GATE_HIGH) != 0 and (ev & ARMED) == 0 and vel < c[C_V_GATE]:
            ev |= ARMED
        # 4b. the accelerometer velocity has exceeded the gate since liftoff
        if (ev & LIFTOFF) != 0 and vel > c[C_V_GATE]:
            ev |= GATE_HIGH
    # 5. barometer rate gate, then the filter
    zw = _w32(z)
    d = _w32(zw - st[ZL_R])         # SUB.L: exact for every ADC word and sane pascal word
    use = True
    est = st[EST]
    ext = st[EXT]
    if -c[C_E_GATE] <= d <= c[C_E_GATE]:
        st[REJ_R] = 0
    elif st[REJ_R] < c[C_GATE_N]:
        st[REJ_R] = st[REJ_R] + 1
        ev |= BARO_REJECT
        use = False
    else:
        # the gate opens on a lasting shift: EST and EXT move with it (re-base)
        est = est + (d << 8)
        w = _note(w, est, W_EST)
        est = _w32(est)
        ext = ext + (d << 8)
        w = _note(w, ext, W_EXT)
        ext = _w32(ext)
    if use:
        st[ZL_R] = zw
        est = est + (z << (8 - S)) - rs(est, S, rnd)
        w = _note(w, est, W_EST)
        est = _w32(est)
    # 6. extreme and apogee (after an accelerometer clip, APO_N samples of evidence)
    if est > ext:
        ext = est
        st[NEG_R] = 0
    elif (ev & ARMED) != 0 and (ev & APOGEE) == 0:
        if ext - est >= c[C_THR] and not _clipped(ev):
            st[NEG_R] = st[NEG_R] + 1
            need = c[C_APO_N] if (ev & ACC_CLIP) != 0 else 1
            if st[NEG_R] >= need:
                ev |= APOGEE
                st[PHASE_R] = PH_APOGEE
        else:
            st[NEG_R] = 0
    st[EST] = est
    st[EXT] = ext
    st[VEL] = vel
    st[EVENTS_R] = ev
    return w


@njit(cache=True)
def seed_literal_init(st, adc, acc, c):
    """EST = z << 8."""
    st[EST] = _w32((adc * c[C_BARO_SIGN]) << 8)


@njit(cache=True, inline="always")
def seed_literal_step(st, adc, acc, c):
    """The Schultz 2002 listing as written: EST += rs(EST, S) - (z << (8 - S)); no flight logic."""
    S = c[C_S]
    est = st[EST]
    est = est + rs(est, S, c[C_ROUND]) - ((adc * c[C_BARO_SIGN]) << (8 - S))
    w = _note(W_NONE, est, W_EST)
    st[EST] = _w32(est)
    return w


# ------------------------------------------------------------------------------------------- Kalman (§6)
@njit(cache=True, inline="always")
def _alt(adc, c, rnd):
    """alt(adc) (docs/firmware-spec.md §2a): the table node below plus rs((next - node) * f, ALT_SHIFT). The
    result lies between two int32 nodes, so it never wraps; the product is below 2^46."""
    s = c[C_ALT_SHIFT]
    i = adc >> s
    f = adc & ((1 << s) - 1)
    lo = c[C_ALT + i]
    return lo + rs((c[C_ALT + i + 1] - lo) * f, s, rnd)


@njit(cache=True)
def kalman_init(st, adc, acc, c):
    """X1 = GND = alt(adc) (0 for an invalid sample); X2 = X3 = 0; ACC0 = acc (kalman_accel only); EVENTS =
    APFRAC = 0; SUMZ = SUMA = 0; CAL = REJ = NEG = 0; HMAX = X1; HT = 0; HP = X1 (kalman_accel's; kalman_baro
    keeps it unread)."""
    h = 0
    if c[C_BARO_MIN] <= adc and adc <= c[C_BARO_MAX]:
        h = _alt(adc, c, c[C_ROUND])
    st[X1] = h
    st[GND] = h
    st[HMAX] = h
    st[HT] = 0
    st[HP] = h
    st[X2] = 0
    st[X3] = 0
    st[ACC0] = acc
    st[EVENTS] = 0
    st[APFRAC] = 0
    st[SUMZ] = 0
    st[SUMA] = 0
    st[CAL] = 0
    st[REJ] = 0
    st[NEG] = 0
    st[PHASE] = PH_PAD
    st[CST] = 0
    st[DLY] = 0
    st[VB] = 0
    st[LOCK] = 0
    st[CLP] = 0
    st[E0] = 0


@njit(cache=True, inline="always")
def kalman_step(  # noqa: C901 - the spec's steps 0-10 in one body, see below
        st, adc, acc, c, accel):  # long: split into numba helpers 2x slower
    """docs/firmware-spec.md §6 steps 0-10 (``accel``: kalman_accel, else kalman_baro); returns the first wrap id.

    Wrap bookkeeping as the numpy model has it: SUMZ, SUMA (calibration); X1, X2 (predict), mulg(acc), e2, e1,
    then per state i mulg(e1, Gi1), mulg(e2, Gi2), Xi. Every barometer gain product is checked when the innovation
    exists (barometer valid, not locked out, not a re-base sample), also one whose correction is not applied
    (gated). VB = max(X2, VB - DV) never leaves int32 (X2 is an int32).

    Kept as one function with the spec's step numbers as comments (issue 34, measured): split into 18 inline numba
    helpers named for the steps it stayed bit-exact but ran at half the speed (kalman_accel 21.9 -> 11.3 M
    samples/s, kalman_baro 25.0 -> 13.2, one stream; numba passes the state and constant arrays between compiled
    functions with reference counting); helpers on plain numbers only were not tried."""
    rnd = c[C_ROUND]
    K = c[C_K]
    w = W_NONE
    ev = st[EVENTS] & LATCHED
    # 0. barometer range; h = alt(adc) for a valid sample
    baro_ok = c[C_BARO_MIN] <= adc and adc <= c[C_BARO_MAX]
    h = 0
    if baro_ok:
        h = _alt(adc, c, rnd)
    else:
        ev |= BARO_INVALID
    # 1. pad calibration
    ncal = 1 << c[C_CAL_P]
    if st[CAL] < ncal:
        if baro_ok:
            sz = st[SUMZ] + h
            w = _note(w, sz, W_SUMZ)
            st[SUMZ] = _w32(sz)
            if accel:
                sa = st[SUMA] + acc
                w = _note(w, sa, W_SUMA)
                st[SUMA] = _w32(sa)
            st[CAL] = st[CAL] + 1
            if st[CAL] == ncal:
                st[GND] = rs(st[SUMZ], c[C_CAL_P], rnd)
                st[X1] = st[GND]
                st[HMAX] = st[GND]
                if accel:
                    st[ACC0] = rs(st[SUMA], c[C_CAL_P], rnd)
        st[EVENTS] = ev
        return w
    x1 = st[X1]
    x2 = st[X2]
    x3 = st[X3]
    # 2. predict
    t1 = rs(x2, K, rnd) + rs(x3, 2 * K + 1, rnd)
    t2 = rs(x3, K, rnd)
    x1 = x1 + t1
    w = _note(w, x1, W_X1)
    x1 = _w32(x1)
    x2 = x2 + t2
    w = _note(w, x2, W_X2)
    x2 = _w32(x2)
    # 3. accelerometer innovation (kalman_accel)
    e2 = 0
    a = 0
    if accel:
        a = rs((acc - st[ACC0]) * c[C_ACC_G_M], c[C_ACC_G_S], rnd)
        w = _note(w, a, W_ACC)
        a = _w32(a)
        e2 = a - x3
        w = _note(w, e2, W_E2)
        e2 = _w32(e2)
    # 4. Mach lockout (kalman_accel): no barometer above MACH_VLO and MACH_N samples after; then re-base, on a steady
    #    sample only (within H_STEP of the previous valid one: a spike is not a reading to re-base on)
    locked = False
    rebase = False
    if accel:
        steady = baro_ok and -c[C_H_STEP] <= h - st[HP] and h - st[HP] <= c[C_H_STEP]
        if _clipped(ev):
            # after an accelerometer clip: the barometer stays out until the drag reading has been low for a
            # 2^(k+1)-sample window in coast, which then re-bases the velocity (§6 step 4, "clip")
            locked = True
            st[LOCK] = c[C_MACH_N]
            if st[PHASE] == PH_COAST and a >= -c[C_A_DRAG] and steady:
                e = h - x1
                w = _note(w, e, W_E1)
                e = _w32(e)
                st[CLP] = st[CLP] + 1
                if st[CLP] <= (1 << K):
                    s0 = st[E0] - e
                else:
                    s0 = st[E0] + e
                w = _note(w, s0, W_E0)
                st[E0] = _w32(s0)
                if st[CLP] == (2 << K):
                    x2 = x2 + rs(st[E0], K, rnd)
                    w = _note(w, x2, W_X2)
                    x2 = _w32(x2)
                    st[VB] = x2
                    st[LOCK] = 0
                    ev |= CLIP_CLEAR
                    locked = False
                    rebase = True
            else:
                st[CLP] = 0
                st[E0] = 0
        elif ((ev & LIFTOFF) != 0 and x2 > c[C_MACH_VLO]) or (
                (c[C_GUARDS] & G_THRUST) != 0
                and (st[PHASE] == PH_BOOST or (st[PHASE] == PH_PAD and a > c[C_A_COAST]))):
            # above the Mach threshold, or (thrust guard) the motor may be pushing: still in BOOST (the raw
            # accelerometer has not yet read below -A_COAST for COAST_N samples), or on the pad with the raw
            # accelerometer reading more than A_COAST above 1 g: the port may read ram pressure
            st[LOCK] = c[C_MACH_N]
            locked = True
        elif st[LOCK] > 1:
            st[LOCK] = st[LOCK] - 1
            locked = True
        elif st[LOCK] == 1:
            if steady:
                st[LOCK] = 0
                rebase = True
            else:
                locked = True
        if locked:
            ev |= MACH_LOCKOUT
    # 5. innovation and gate (re-base: X1 = h, no barometer correction)
    e1 = 0
    use = False
    if baro_ok and not locked:
        if rebase:
            x1 = h
            st[REJ] = 0
        else:
            e1 = h - x1
            w = _note(w, e1, W_E1)
            e1 = _w32(e1)
            eg = c[C_E_GATE]
            if -eg <= e1 and e1 <= eg:
                st[REJ] = 0
                use = True
            elif st[REJ] < c[C_GATE_N]:
                st[REJ] = st[REJ] + 1
                ev |= BARO_REJECT
            else:
                use = True
    # 6. correct (every barometer gain product is checked for a wrap when the innovation exists); locked out:
    #    X1, X2 only predicted, X3 = a (the accelerometer alone)
    if locked:
        x3 = a
    else:
        c11 = rs(e1 * c[C_G11_M], c[C_G11_S], rnd)
        w = _note(w, c11, W_E1G11)
        c1 = _w32(c11)
        if not use:
            c1 = 0
        if accel:
            c12 = rs(e2 * c[C_G12_M], c[C_G12_S], rnd)
            w = _note(w, c12, W_E2G12)
            c1 += _w32(c12)
        x1 = x1 + c1
        w = _note(w, x1, W_X1)
        x1 = _w32(x1)
        c21 = rs(e1 * c[C_G21_M], c[C_G21_S], rnd)
        w = _note(w, c21, W_E1G21)
        c2 = _w32(c21)
        if not use:
            c2 = 0
        if accel:
            c22 = rs(e2 * c[C_G22_M], c[C_G22_S], rnd)
            w = _note(w, c22, W_E2G22)
            c2 += _w32(c22)
        x2 = x2 + c2
        w = _note(w, x2, W_X2)
        x2 = _w32(x2)
        c31 = rs(e1 * c[C_G31_M], c[C_G31_S], rnd)
        w = _note(w, c31, W_E1G31)
        c3 = _w32(c31)
        if not use:
            c3 = 0
        if accel:
            c32 = rs(e2 * c[C_G32_M], c[C_G32_S], rnd)
            w = _note(w, c32, W_E2G32)
            c3 += _w32(c32)
        x3 = x3 + c3
        w = _note(w, x3, W_X3)
        x3 = _w32(x3)
    # 7. liftoff and Mach delay
    if (ev & LIFTOFF) != 0:
        if st[DLY] > 0:
            st[DLY] = st[DLY] - 1
    elif x2 > c[C_V_LIFT]:
        ev |= LIFTOFF
        st[PHASE] = PH_BOOST
        st[DLY] = c[C_DLY_N]
    # 7b. accelerometer at its rail for CLIP_N samples in boost: the integral underestimates the speed from now on
    if accel:
        ev = _rail_count(st, CLP, st[PHASE], ev, acc, c[C_CLIP_N])
    # 8. plausibility bound: VB follows X2, falling by at most DV (gravity guard: DG once VB <= 0) and rising by
    #    at most DU per sample
    if (c[C_GUARDS] & G_GRAVITY) != 0 and st[VB] <= 0:
        vb = st[VB] - c[C_DG]
    else:
        vb = st[VB] - c[C_DV]
    if vb < x2:
        vb = x2
    if vb > st[VB] + c[C_DU]:
        vb = st[VB] + c[C_DU]
    st[VB] = vb
    # 8b. descent record: the highest valid barometric altitude and how many valid samples it is old
    if baro_ok:
        if h > st[HMAX]:
            st[HMAX] = h
            st[HT] = 0
        elif st[HT] < c[C_DESC_N]:
            st[HT] = st[HT] + 1
        if accel:
            st[HP] = h
    # 9. phases and apogee
    if st[PHASE] == PH_BOOST:
        if x3 < -c[C_A_COAST]:
            st[CST] = st[CST] + 1
            if st[CST] >= c[C_COAST_N]:
                st[PHASE] = PH_COAST
        elif st[CST] > 0:
            # issue 30: a sample at or above -A_COAST takes one back (not all: a noisy accelerometer near the
            # threshold must still reach COAST)
            st[CST] = st[CST] - 1
    if st[PHASE] == PH_COAST:
        # gravity guard: the estimate is at most V_FALL below the free-fall bound; floor guard: the filtered and
        # (valid) barometric heights are at least H_FLOOR above the pad (GND + H_FLOOR: |GND| <= 2^30, exact)
        phys = (c[C_GUARDS] & G_GRAVITY) == 0 or x2 - vb >= -c[C_V_FALL]
        fl = st[GND] + c[C_H_FLOOR]
        high = (c[C_GUARDS] & G_FLOOR) == 0 or (x1 >= fl and (not baro_ok or h >= fl))
        # descent guard: the barometer reads below its highest, or that reading is DESC_N valid samples old
        #   (it pauses the evidence count, it does not restart it: a noisy reading returns to its highest count)
        down = (c[C_GUARDS] & G_DESCENT) == 0 or not baro_ok or h < st[HMAX] or st[HT] >= c[C_DESC_N]
        if st[DLY] == 0 and vb < 0 and not _clipped(ev) and phys and high:
            if down:
                st[NEG] = st[NEG] + 1
                if st[NEG] >= c[C_APO_N]:
                    ev |= APOGEE
                    st[PHASE] = PH_APOGEE
        else:
            st[NEG] = 0
    elif st[PHASE] == PH_APOGEE and x2 < -c[C_V_DESC]:
        st[PHASE] = PH_DESCENT
    # 10. low-rate apogee prediction (in coast)
    if st[PHASE] == PH_COAST and (ev & APOGEE_PREDICTED) == 0 and x2 > 0 and not _clipped(ev):
        d = -rs(x3, K, rnd)
        if x2 < d:
            v = x2
            while d >= 32768:
                d = d >> 1
                v = v >> 1
            st[APFRAC] = min(65535, (v << 16) // d)
            ev |= APOGEE_PREDICTED
    st[X1] = x1
    st[X2] = x2
    st[X3] = x3
    st[EVENTS] = ev
    return w


@njit(cache=True, inline="always")
def kalman_baro_step(st, adc, acc, c):
    """kalman_baro: :func:`kalman_step` without the accelerometer and the lockout."""
    return kalman_step(st, adc, acc, c, False)


@njit(cache=True, inline="always")
def kalman_accel_step(st, adc, acc, c):
    """kalman_accel: :func:`kalman_step` with the accelerometer innovation and the Mach lockout."""
    return kalman_step(st, adc, acc, c, True)


# ------------------------------------------------------------------------------------------- driver
@njit(cache=True)
def _init(prog, st, adc, acc, c):
    if prog == P_RECURSIVE:
        recursive_init(st, adc, acc, c)
    elif prog == P_SEED_LITERAL:
        seed_literal_init(st, adc, acc, c)
    else:
        kalman_init(st, adc, acc, c)


#: The output columns as module-level tuples: numba freezes them as constants, so the copy of the output words
#: compiles to fixed loads and stores (5-12 % faster than the ``cols`` array).
_OUT_RECURSIVE = OUT_COLS["recursive"]
_OUT_SEED_LITERAL = OUT_COLS["recursive_seed_literal"]
_OUT_KALMAN_BARO = OUT_COLS["kalman_baro"]
_OUT_KALMAN_ACCEL = OUT_COLS["kalman_accel"]


@njit(cache=True, inline="always")
def _copy_out(st, cols, row):
    """``row[j] = st[cols[j]]``: the output words of the state (``cols`` an array or a tuple)."""
    for j in range(len(cols)):
        row[j] = st[cols[j]]


@njit(cache=True)
def _stream_recursive(st, adc, acc, c, out):
    """Samples 0..n-1 of one stream through :func:`recursive_step`: (first wrap sample or -1, its wrap id)."""
    f = -1
    wid = 0
    for i in range(adc.shape[0]):
        w = recursive_step(st, adc[i], acc[i], c)
        if w != 0 and f < 0:
            f, wid = i, w
        _copy_out(st, _OUT_RECURSIVE, out[i])
    return f, wid


@njit(cache=True)
def _stream_seed_literal(st, adc, acc, c, out):
    """Samples 0..n-1 of one stream through :func:`seed_literal_step`: (first wrap sample or -1, its wrap id)."""
    f = -1
    wid = 0
    for i in range(adc.shape[0]):
        w = seed_literal_step(st, adc[i], acc[i], c)
        if w != 0 and f < 0:
            f, wid = i, w
        _copy_out(st, _OUT_SEED_LITERAL, out[i])
    return f, wid


@njit(cache=True)
def _stream_kalman_baro(st, adc, acc, c, out):
    """Samples 0..n-1 of one stream through :func:`kalman_baro_step`: (first wrap sample or -1, its wrap id)."""
    f = -1
    wid = 0
    for i in range(adc.shape[0]):
        w = kalman_baro_step(st, adc[i], acc[i], c)
        if w != 0 and f < 0:
            f, wid = i, w
        _copy_out(st, _OUT_KALMAN_BARO, out[i])
    return f, wid


@njit(cache=True)
def _stream_kalman_accel(st, adc, acc, c, out):
    """Samples 0..n-1 of one stream through :func:`kalman_accel_step`: (first wrap sample or -1, its wrap id)."""
    f = -1
    wid = 0
    for i in range(adc.shape[0]):
        w = kalman_accel_step(st, adc[i], acc[i], c)
        if w != 0 and f < 0:
            f, wid = i, w
        _copy_out(st, _OUT_KALMAN_ACCEL, out[i])
    return f, wid


@njit(cache=True)
def run_stream(prog, st, adc, acc, c, cols, init_row, out):
    """One stream (``adc``/``acc`` of shape ``(n,)``) through program ``prog``: ``init`` on sample 0 into
    ``init_row``, then ``step`` on samples 0..n-1 into ``out[i]`` (the state entries ``cols``); ``st`` is the
    state. Returns (first sample with a wrap or -1, its wrap id or 0).

    Speed notes (bench/bench_model.py, measured): numba does not inline a call between two jitted functions
    that pass arrays (each call costs a call plus atomic reference counts of every array argument), so the step
    functions are ``inline="always"`` into one sample loop per program (``_stream_*``), called once per stream:
    1.4x over the step called per sample, at the same compile time; inlining also the loops into the parallel
    driver was another 1.2x but quadrupled the cold compile (~20 s CPU). A program dispatch inside the sample
    loop cost ~30 %; passing the step function as an argument would stop numba from caching the driver."""
    _init(prog, st, adc[0], acc[0], c)
    _copy_out(st, cols, init_row)
    if prog == P_KALMAN_ACCEL:
        return _stream_kalman_accel(st, adc, acc, c, out)
    if prog == P_KALMAN_BARO:
        return _stream_kalman_baro(st, adc, acc, c, out)
    if prog == P_RECURSIVE:
        return _stream_recursive(st, adc, acc, c, out)
    return _stream_seed_literal(st, adc, acc, c, out)


@njit(cache=True, parallel=True)
def run_streams(prog, adc, acc, c, cols, state, init_out, out, first, word):
    """Run every stream ``s`` of ``adc``/``acc`` (shape ``(streams, n)``) through program ``prog``
    (:func:`run_stream`), the streams in parallel when compiled. Writes ``init_out[s, j]`` and ``out[s, i, j]``
    (the state entries ``cols[j]``), ``first[s]`` (first sample with a wrap, or -1) and ``word[s]`` (its wrap
    id, or 0); ``state`` (``(streams, N_STATE)``) is the work area."""
    for s in prange(adc.shape[0]):
        f, wid = run_stream(prog, state[s], adc[s], acc[s], c, cols, init_out[s], out[s])
        first[s] = f
        word[s] = wid


@njit(cache=True)
def run_streams_serial(prog, adc, acc, c, cols, state, init_out, out, first, word):
    """:func:`run_streams` on the calling thread only: for small calls, where waking the worker threads costs
    more than the work (0.02-0.2 ms per call on this loaded machine, against ~4 us for 100 samples). About half
    as fast per sample as the parallel driver even on one stream (numba marks the array arguments of a parallel
    loop body ``noalias``, not those of a plain function)."""
    for s in range(adc.shape[0]):
        f, wid = run_stream(prog, state[s], adc[s], acc[s], c, cols, init_out[s], out[s])
        first[s] = f
        word[s] = wid

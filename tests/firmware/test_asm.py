"""The arithmetic macros of firmware_model/firmware/asm/fwemu.inc, run on the emulated 68000, against exact integer
math.

* ``MULG m,s,src,dst,tmp`` must give ``wrap32(rs(e*m, s, mode))`` for ALL int32 ``e``, every signed 16-bit ``m``
  and every ``s`` in 0..47, both roundings; ``src`` preserved; clocks independent of ``e``.
* ``RSHIFT reg,n,tmp,zero`` must give ``rs(x, n, mode)`` for all int32 ``x`` and n in 0..40.

The oracle is written here from the definition in docs/firmware-spec.md §1 with Python's unbounded integers (its
``>>`` floors): ``rs(x, s) = floor(x / 2^s)`` or ``floor((x + 2^(s-1)) / 2^s)``; nothing is taken from the code
under test. Also: the whole firmware sources assemble for every program and both roundings.
"""

from __future__ import annotations

import functools

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from tests.support.profiles import examples

isa = pytest.importorskip("isa")
pytest.importorskip("isa.assembler")
pytest.importorskip("isa.cpu")

from firmware_model.firmware.assemble import ASM_DIR  # noqa: E402 - after pytest.importorskip of isa

INT32_MIN, INT32_MAX = -(1 << 31), (1 << 31) - 1
EDGE_E = (0, 1, -1, 2, -2, INT32_MAX, INT32_MIN, INT32_MIN + 1, INT32_MAX - 1, 0x7FFF, 0x8000, -0x8000, -0x8001,
          0xFFFF, 0x10000, -0x10000, 0x12345678, -0x12345678, 0x0000FFFF, 0x7FFF0000, -0x7FFF0000, 0x55555555,
          -0x55555556)
ORIGIN = 0x1000


def wrap32(x: int) -> int:
    """Two's complement reduction of an exact integer to int32 (as ADD.L does)."""
    return ((x + (1 << 31)) & 0xFFFFFFFF) - (1 << 31)


def rs_exact(x: int, s: int, half_up: bool) -> int:
    """docs/firmware-spec.md §1 rs(), straight from the definition (Python's >> is floor division by 2^s)."""
    if s == 0:
        return x
    return (x + (1 << (s - 1))) >> s if half_up else x >> s


def u32(x: int) -> int:
    return x & 0xFFFFFFFF


def s32(x: int) -> int:
    return x - (1 << 32) if x & 0x80000000 else x


EXTREME_M = (-32768, -32767, -1, 0, 1, 32767, 0x5555, -0x5556)


def _assemble(text: str, name: str, rnd: int) -> object:
    return isa.assemble(text, filename=name, origin=ORIGIN, include_paths=[str(ASM_DIR)], defines={"ROUND": rnd})


@functools.lru_cache(maxsize=None)
def _mulg_program(m: int, s: int, rnd: int) -> object:
    """A tiny program: ``t1: MULG m,s,d0,d1,d2 ; rts`` and ``t2:`` the same with other registers."""
    text = f' include "fwemu.inc"\nt1\n MULG {m},{s},d0,d1,d2\n rts\nt2\n MULG {m},{s},d5,d3,d7\n rts\n'
    return _assemble(text, f"<mulg m={m} s={s} round={rnd}>", rnd)


@functools.lru_cache(maxsize=None)
def _mulg_table_program(rnd: int) -> object:
    """One program with a routine ``t_<s>_<j>: MULG EXTREME_M[j],s,d0,d1,d2 ; rts`` per s in 0..47 (assembling
    costs more than running, so the extreme-operand sweep assembles once per rounding)."""
    lines = [' include "fwemu.inc"']
    for s in range(48):
        for j, m in enumerate(EXTREME_M):
            lines += [f"t_{s}_{j}", f" MULG {m},{s},d0,d1,d2", " rts"]
    return _assemble("\n".join(lines) + "\n", f"<mulg table round={rnd}>", rnd)


@functools.lru_cache(maxsize=None)
def _rshift_program(n: int, rnd: int) -> object:
    text = f' include "fwemu.inc"\nt1\n moveq #0,d4\n RSHIFT d0,{n},d5,d4\n rts\n'
    return _assemble(text, f"<rshift n={n} round={rnd}>", rnd)


_CPU: list[object] = []


def _cpu(program: object) -> object:
    """The shared emulated CPU (creating one costs more than a test), with ``program`` loaded."""
    if not _CPU:
        cpu = isa.CPU(mapped=False)
        cpu.map(0, 0x20000, "ram", writable=True)
        _CPU.append(cpu)
    cpu = _CPU[0]
    cpu.load(program)
    cpu.a[7] = 0x20000
    return cpu


def _check_mulg(cpu: object, address: int, m: int, s: int, rnd: int, values: list[int]) -> set[int]:
    """Call ``MULG m,s,d0,d1,d2`` at ``address`` for every e in ``values``; return the set of clock counts."""
    clocks = set()
    for e in values:
        want = wrap32(rs_exact(e * m, s, bool(rnd)))
        cpu.d[0] = u32(e)
        clocks.add(cpu.call(address, max_cycles=10_000))
        got = s32(cpu.d[1])
        assert got == want, f"MULG m={m} s={s} round={rnd} e={e}: cpu {got} != exact {want}"
        assert s32(cpu.d[0]) == e, f"MULG clobbered its source register (m={m} s={s} e={e})"
    return clocks


def _run_mulg(m: int, s: int, rnd: int, values: list[int]) -> None:
    prog = _mulg_program(m, s, rnd)
    cpu = _cpu(prog)
    clocks = _check_mulg(cpu, prog.symbol("t1").address, m, s, rnd, values)
    # The multiplier of MULS/MULU is the immediate m: one clock count per gain, whatever e is.
    assert len(clocks) == 1, f"MULG m={m} s={s}: clocks depend on e: {sorted(clocks)}"
    for e in values[:3]:  # other registers: same result
        cpu.d[5] = u32(e)
        cpu.call(prog.symbol("t2").address, max_cycles=10_000)
        assert s32(cpu.d[3]) == wrap32(rs_exact(e * m, s, bool(rnd))), f"MULG (d5,d3,d7) m={m} s={s} e={e}"


# ---------------------------------------------------------------------------------------------------- MULG
@pytest.mark.parametrize("rnd", [0, 1], ids=["floor", "half_up"])
@pytest.mark.parametrize("s", range(48))
def test_mulg_every_shift_extreme_operands(s: int, rnd: int) -> None:
    """Every s, extreme mantissas and extreme e (the corners of the 48-bit product and of the wrap)."""
    prog = _mulg_table_program(rnd)
    cpu = _cpu(prog)
    for j, m in enumerate(EXTREME_M):
        clocks = _check_mulg(cpu, prog.symbol(f"t_{s}_{j}").address, m, s, rnd, list(EDGE_E))
        assert len(clocks) == 1, f"MULG m={m} s={s}: clocks depend on e: {sorted(clocks)}"


@settings(max_examples=examples(60))
@given(m=st.integers(-32768, 32767), s=st.integers(0, 47), rnd=st.integers(0, 1),
       es=st.lists(st.integers(INT32_MIN, INT32_MAX), min_size=1, max_size=24))
@example(m=-32768, s=15, rnd=1, es=[INT32_MIN, INT32_MAX])
@example(m=-32768, s=0, rnd=0, es=[INT32_MIN])
def test_mulg_matches_exact_product(m: int, s: int, rnd: int, es: list[int]) -> None:
    _run_mulg(m, s, rnd, es + [INT32_MIN, INT32_MAX, -1])


@settings(max_examples=examples(40))
@given(m=st.integers(-32768, 32767), s=st.integers(1, 47), rnd=st.integers(0, 1), data=st.data())
def test_mulg_rounding_ties(m: int, s: int, rnd: int, data: st.DataObject) -> None:
    """Products that sit exactly on (or one off) a rounding tie: e*m = q*2^s + 2^(s-1) + {-1, 0, 1}."""
    if m == 0:
        return
    es = []
    for _ in range(8):
        q = data.draw(st.integers(-(1 << 30), 1 << 30))
        target = q * (1 << s) + (1 << (s - 1))
        # nearest multiples of m around the tie (the tie itself when m divides it)
        e = target // m
        for cand in (e - 1, e, e + 1):
            if INT32_MIN <= cand <= INT32_MAX:
                es.append(cand)
    if es:
        _run_mulg(m, s, rnd, es)


# ---------------------------------------------------------------------------------------------------- RSHIFT
@pytest.mark.parametrize("rnd", [0, 1], ids=["floor", "half_up"])
def test_rshift_every_count(rnd: int) -> None:
    for n in range(41):
        prog = _rshift_program(n, rnd)
        cpu = _cpu(prog)
        t1 = prog.symbol("t1").address
        for x in EDGE_E + (3, -3, 5, -5, 0x180, -0x180, (1 << n) if n < 31 else 7, -(1 << min(n, 31))):
            cpu.d[0] = u32(x)
            cpu.call(t1, max_cycles=10_000)
            got, want = s32(cpu.d[0]), rs_exact(x, n, bool(rnd))
            assert got == want, f"RSHIFT n={n} round={rnd} x={x}: cpu {got} != exact {want}"


@settings(max_examples=examples(60))
@given(x=st.integers(INT32_MIN, INT32_MAX), n=st.integers(0, 40), rnd=st.integers(0, 1))
def test_rshift_matches_exact(x: int, n: int, rnd: int) -> None:
    prog = _rshift_program(n, rnd)
    cpu = _cpu(prog)
    cpu.d[0] = u32(x)
    cpu.call(prog.symbol("t1").address, max_cycles=10_000)
    assert s32(cpu.d[0]) == rs_exact(x, n, bool(rnd))


# ---------------------------------------------------------------------------------------------------- sources
@pytest.mark.parametrize("rounding", ["floor", "half_up"])
@pytest.mark.parametrize("program", ["recursive", "recursive_seed_literal", "kalman_baro", "kalman_accel"])
def test_firmware_sources_assemble(program: str, rounding: str) -> None:
    """Every program assembles with its build constants, exports init/step and the spec's state words in RAM,
    and its code fits ROM; no assembler warnings (e.g. no seed-style shr/shl aliases)."""
    from firmware_model.firmware.assemble import RAM_START, ROM_SIZE, STACK_TOP, build_firmware
    from firmware_model.spec.config import BuildConfig
    from firmware_model.model.trace import STATE_WORDS

    build = build_firmware(BuildConfig(program=program, rounding=rounding))
    assert build.program.warnings == []
    assert 0 < build.rom_bytes <= ROM_SIZE
    assert build.init_address < build.rom_bytes and build.step_address < build.rom_bytes
    for name, size in STATE_WORDS[program]:
        address, got_size = build.variables[name]
        assert got_size == size and RAM_START <= address < STACK_TOP and address % 2 == 0
    assert build.ram_bytes == sum(size for _, size in STATE_WORDS[program])
    assert len(build.source_sha256) == 64


# ---------------------------------------------------------------------------------------------------- one step
# Boundary conditions of the flight logic (e1 == -MACH_E - 1, X2 == MACH_VHI - 1, v == d after the DIVU
# normalisation, EXT - EST == THR with an exact 33-bit difference, ...) are single values that input streams
# practically never hit, so these tests put the firmware into chosen states (writing its RAM variables), run ONE
# step on the emulated CPU and check it against docs/firmware-spec.md §5/§6 written out below as a one-step
# oracle with Python integers.

LIFTOFF, ARMED, APOGEE, MACH, INVALID, PRED, GATE_HIGH, REJECT, CLIP, CLEAR = 1, 2, 4, 8, 16, 32, 64, 128, 256, 512
LATCHED = LIFTOFF | ARMED | APOGEE | PRED | GATE_HIGH | CLIP | CLEAR


def _mulg_exact(e: int, m: int, s: int, half_up: bool) -> int:
    return wrap32(rs_exact(e * m, s, half_up))


def spec_alt(c: object, adc: int) -> int:
    """docs/firmware-spec.md §2a: ALT[i] + rs((ALT[i+1] - ALT[i]) * f, ALT_SHIFT), exact integers."""
    s = c.ALT_SHIFT
    i, f = adc >> s, adc & ((1 << s) - 1)
    lo, hi = c.ALT_TABLE[i], c.ALT_TABLE[i + 1]
    return wrap32(lo + rs_exact((hi - lo) * f, s, bool(c.ROUND)))


def spec_kalman_step(c: object, st: dict[str, int], adc: int, acc: int) -> dict[str, int]:  # noqa: C901 - spells out docs/firmware-spec.md §6 step by step, as the spec reads
    """docs/firmware-spec.md §6 step 0-10, one sample, exact integers (Mach lockout: kalman_accel only)."""
    h = bool(c.ROUND)
    K = c.K
    g = {name: (q.m, q.s) for name, q in c.gains.items()}
    accel = "ACC_G" in g
    st = dict(st)
    ev = st["EVENTS"] & LATCHED
    ok = c.BARO_MIN <= adc <= c.BARO_MAX
    if not ok:
        ev |= INVALID
    hh = spec_alt(c, adc) if ok else None
    ncal = 1 << c.CAL_P
    if st["CAL"] < ncal:                                              # 1. pad calibration
        if ok:
            st["SUMZ"] = wrap32(st["SUMZ"] + hh)
            if accel:
                st["SUMA"] = wrap32(st["SUMA"] + acc)
            st["CAL"] += 1
            if st["CAL"] == ncal:
                st["GND"] = st["X1"] = st["HMAX"] = wrap32(rs_exact(st["SUMZ"], c.CAL_P, h))
                if accel:
                    st["ACC0"] = wrap32(rs_exact(st["SUMA"], c.CAL_P, h))
        st["EVENTS"] = ev
        return st
    x1, x2, x3 = st["X1"], st["X2"], st["X3"]
    frac = st["APFRAC"]
    t1 = rs_exact(x2, K, h) + rs_exact(x3, 2 * K + 1, h)             # 2. predict
    t2 = rs_exact(x3, K, h)
    x1, x2 = wrap32(x1 + t1), wrap32(x2 + t2)
    a = _mulg_exact(acc - st["ACC0"], *g["ACC_G"], h) if accel else 0   # 3. accel innovation
    e2 = wrap32(a - x3) if accel else 0
    locked = rebase = False
    if accel:                                                         # 4. Mach lockout
        steady = ok and -c.H_STEP <= hh - st["HP"] <= c.H_STEP         # issue 30: re-base on a steady sample
        if ev & CLIP and not ev & CLEAR:                              # clip: barometer out until the window
            locked = True
            st["LOCK"] = c.MACH_N
            if st["PHASE"] == 2 and a >= -c.A_DRAG and steady:
                e = wrap32(hh - x1)
                st["CLP"] += 1
                st["E0"] = wrap32(st["E0"] - e if st["CLP"] <= 1 << K else st["E0"] + e)
                if st["CLP"] == 2 << K:                               # complete: re-base the velocity
                    x2 = wrap32(x2 + rs_exact(st["E0"], K, h))
                    st["VB"] = x2
                    st["LOCK"] = 0
                    ev |= CLEAR
                    locked, rebase = False, True
            else:
                st["CLP"] = st["E0"] = 0
        elif (ev & LIFTOFF and x2 > c.MACH_VLO) or (
                c.GUARDS & 1 and (st["PHASE"] == 1 or (st["PHASE"] == 0 and a > c.A_COAST))):   # issue 30: thrust
            st["LOCK"], locked = c.MACH_N, True
        elif st["LOCK"] > 1:
            st["LOCK"], locked = st["LOCK"] - 1, True
        elif st["LOCK"] == 1:
            if steady:
                st["LOCK"], rebase = 0, True
            else:
                locked = True
        if locked:
            ev |= MACH
    use = False
    e1 = 0
    if ok and not locked:                                             # 5. innovation, gate (or re-base)
        if rebase:
            x1 = hh
            st["REJ"] = 0
        else:
            e1 = wrap32(hh - x1)
            if -c.E_GATE <= e1 <= c.E_GATE:
                st["REJ"] = 0
                use = True
            elif st["REJ"] < c.GATE_N:
                st["REJ"] += 1
                ev |= REJECT
            else:
                use = True
    if locked:                                                        # 6. correct
        x3 = wrap32(x3 + e2)
    else:
        xs = [x1, x2, x3]
        for i in range(3):
            c1 = _mulg_exact(e1, *g[f"G{i + 1}1"], h) if use else 0
            c2 = _mulg_exact(e2, *g[f"G{i + 1}2"], h) if accel else 0
            xs[i] = wrap32(xs[i] + c1 + c2)
        x1, x2, x3 = xs
    if ev & LIFTOFF:                                                  # 7. liftoff, Mach delay
        if st["DLY"] > 0:
            st["DLY"] -= 1
    elif x2 > c.V_LIFT:
        ev |= LIFTOFF
        st["PHASE"], st["DLY"] = 1, c.DLY_N
    if accel and st["PHASE"] == 1 and not ev & CLIP:                  # 7b. accelerometer at its rail
        if acc == 32767:
            st["CLP"] += 1
            if st["CLP"] >= c.CLIP_N:
                ev |= CLIP
                st["CLP"] = 0
        else:
            st["CLP"] = 0
    fall = c.DG if c.GUARDS & 2 and st["VB"] <= 0 else c.DV           # issue 30: gravity
    st["VB"] = min(max(x2, st["VB"] - fall), st["VB"] + c.DU)         # 8. plausibility bound
    if ok:                                                            # 8b. descent record (issue 30)
        if hh > st["HMAX"]:
            st["HMAX"], st["HT"] = hh, 0
        elif st["HT"] < c.DESC_N:
            st["HT"] += 1
        if accel:
            st["HP"] = hh
    if st["PHASE"] == 1:                                              # 9. phases and apogee
        if x3 < -c.A_COAST:
            st["CST"] += 1
            if st["CST"] >= c.COAST_N:
                st["PHASE"] = 2
        elif st["CST"] > 0:                                           # issue 30: one count back
            st["CST"] -= 1
    if st["PHASE"] == 2:
        phys = not c.GUARDS & 2 or x2 - st["VB"] >= -c.V_FALL          # issue 30: gravity
        floor = st["GND"] + c.H_FLOOR                                   # issue 30: floor
        high = not c.GUARDS & 4 or (x1 >= floor and (not ok or hh >= floor))
        down = not c.GUARDS & 8 or not ok or hh < st["HMAX"] or st["HT"] >= c.DESC_N   # issue 30: descent
        if st["DLY"] == 0 and st["VB"] < 0 and (not ev & CLIP or ev & CLEAR) and phys and high:
            if down:                                                  # the descent guard pauses the count
                st["NEG"] += 1
                if st["NEG"] >= c.APO_N:
                    ev |= APOGEE
                    st["PHASE"] = 3
        else:
            st["NEG"] = 0
    elif st["PHASE"] == 3 and x2 < -c.V_DESC:
        st["PHASE"] = 4
    if st["PHASE"] == 2 and not ev & PRED and x2 > 0 and (not ev & CLIP or ev & CLEAR):   # 10. prediction
        d = -rs_exact(x3, K, h)
        if x2 < d:
            ev |= PRED
            v = x2
            while d >= 32768:
                d >>= 1
                v >>= 1
            frac = min(65535, (v << 16) // d)
    st.update(X1=x1, X2=x2, X3=x3, EVENTS=ev, APFRAC=frac)
    return st


def spec_recursive_step(c: object, st: dict[str, int], adc: int, acc: int) -> dict[str, int]:  # noqa: C901 - spells out docs/firmware-spec.md §5 step by step, as the spec reads
    """docs/firmware-spec.md §5 steps 0-6, one sample, exact integers."""
    h = bool(c.ROUND)
    ev = st["EVENTS"] & LATCHED                                      # 0. per-sample bits
    vel, acc0, suma, cal = st["VEL"], st["ACC0"], st["SUMA"], st["CAL"]
    phase, cst, clp = st["PHASE"], st["CST"], st["CLP"]
    if cal < (1 << c.CAL_P):                                         # 1. pad calibration
        suma, cal = suma + acc, cal + 1
        if cal == 1 << c.CAL_P:
            acc0 = rs_exact(suma, c.CAL_P, h)
    else:
        vel = wrap32(vel + (acc - acc0))                             # 2.
        if not ev & LIFTOFF and vel > c.V_LIFT:
            ev |= LIFTOFF
            phase = 1
        if phase == 1:                                               # phases
            if acc - acc0 < -c.A_COAST:
                cst += 1
                if cst >= c.COAST_N:
                    phase = 2
            else:
                cst = 0
        elif phase == 2 and ev & CLIP and not ev & CLEAR:            # drag-low coast samples after a clip
            if acc - acc0 >= -c.A_DRAG:
                clp += 1
                if clp >= 1 << c.K:
                    ev |= CLEAR
            else:
                clp = 0
        elif phase == 3 and vel < -c.V_DESC:
            phase = 4
        if phase == 1 and not ev & CLIP:                             # 3. the accelerometer at its rail
            if acc == 32767:
                clp += 1
                if clp >= c.CLIP_N:
                    ev |= CLIP
                    clp = 0
            else:
                clp = 0
        if ev & GATE_HIGH and not ev & ARMED and vel < c.V_GATE:     # 4a (GATE_HIGH from an earlier sample)
            ev |= ARMED
        if ev & LIFTOFF and vel > c.V_GATE:                          # 4b
            ev |= GATE_HIGH
    z = c.BARO_SIGN * adc
    est, ext, zl, rej = st["EST"], st["EXT"], st["ZL"], st["REJ"]
    use = True                                                       # 5. rate gate
    d = wrap32(wrap32(z) - zl)                                       # SUB.L
    if -c.E_GATE <= d <= c.E_GATE:
        rej = 0
    elif rej < c.GATE_N:
        rej, use = rej + 1, False
        ev |= REJECT
    else:                                                            # re-base on a lasting shift
        est, ext = wrap32(est + d * 256), wrap32(ext + d * 256)
    if use:
        zl = wrap32(z)
        est = wrap32(est + (z << (8 - c.S)) - rs_exact(est, c.S, h))
    neg = st["NEG"]
    if est > ext:                                                    # 6.
        ext, neg = est, 0
    elif ev & ARMED and not ev & APOGEE:
        if ext - est >= c.THR and (not ev & CLIP or ev & CLEAR):
            neg += 1
            if neg >= (c.APO_N if ev & CLIP else 1):
                ev |= APOGEE
                phase = 3
        else:
            neg = 0
    return dict(st, EST=est, EXT=ext, VEL=vel, ACC0=acc0, EVENTS=ev, ZL=zl, SUMA=suma, CAL=cal, REJ=rej, NEG=neg,
                PHASE=phase, CST=cst, CLP=clp)


class _Board:
    """The firmware build on the spec's memory map, with direct access to its state variables."""

    def __init__(self, build: object) -> None:
        from firmware_model.firmware.harness import _Machine

        self.build = build
        self.cpu = _Machine(build).cpu

    def step(self, state: dict[str, int], adc: int, acc: int) -> dict[str, int]:
        from firmware_model.firmware.assemble import ACCEL_ADC, BARO_ADC

        for name, (address, size) in self.build.variables.items():
            self.cpu.write(address, state[name] & ((1 << (8 * size)) - 1), size)
        self.cpu.write(BARO_ADC, adc, 2)
        self.cpu.write(ACCEL_ADC, acc & 0xFFFF, 2)
        self.cpu.call(self.build.step_address, max_cycles=100_000)
        out = {}
        for name, (address, size) in self.build.variables.items():
            v = self.cpu.read(address, size)
            out[name] = s32(v) if size == 4 else v
        return out


@functools.lru_cache(maxsize=None)
def _board(program: str, k: int, rounding: str) -> _Board:
    from firmware_model.firmware.assemble import build_firmware
    from firmware_model.spec.config import BuildConfig

    return _Board(build_firmware(BuildConfig(program=program, k=k, rounding=rounding, baro_min=100,
                                             baro_max=65000)))


def _near(*centres: int) -> st.SearchStrategy[int]:
    """Integers at or next to the given boundaries (clamped to int32), or anywhere in int32."""
    near = st.sampled_from(centres).flatmap(
        lambda c: st.integers(-2, 2).map(lambda d: max(INT32_MIN, min(INT32_MAX, c + d))))
    return st.one_of(near, near, st.integers(INT32_MIN, INT32_MAX))


def _kalman_state(board: _Board, **words: int) -> dict[str, int]:
    """A full Kalman state (calibrated unless CAL is given) restricted to the build's variables."""
    c = board.build.consts
    base = {"X1": 0, "X2": 0, "X3": 0, "ACC0": 0, "EVENTS": 0, "APFRAC": 0, "GND": 0, "SUMZ": 0, "SUMA": 0,
            "CAL": 1 << c.CAL_P, "REJ": 0, "NEG": 0, "PHASE": 0, "CST": 0, "DLY": 0, "VB": 0, "LOCK": 0,
            "CLP": 0, "E0": 0, "HMAX": 0, "HT": 0, "HP": 0}
    base.update(words)
    return {name: base[name] for name in board.build.variables}


def _clp_values(c: object) -> tuple[int, ...]:
    """The clip counter CLP at/next to its boundaries: CLIP_N (rail count in BOOST), 2^K (recursive: CLIP_CLEAR;
    kalman_accel: the window's half) and 2^(K+1) (kalman_accel: the window complete)."""
    return tuple(sorted({max(0, v) for v in (0, 1, c.CLIP_N - 2, c.CLIP_N - 1, c.CLIP_N, (1 << c.K) - 1, 1 << c.K,
                                               (1 << c.K) + 1, (2 << c.K) - 2, (2 << c.K) - 1)}))


def _acc_near_drag(c: object, acc0: int, step: int) -> int:
    """An accelerometer word whose a = mulg(acc - ACC0, ACC_G) (spec §6 step 3) is the step-th one at or above
    -A_DRAG (step >= 0) or below it (step < 0), clamped to the 16-bit range: a == -A_DRAG itself when a word
    gives it."""
    m, sh = c.gains["ACC_G"].m, c.gains["ACC_G"].s
    h = bool(c.ROUND)
    a = lambda x: _mulg_exact(x - acc0, m, sh, h)  # increasing in x (ACC_G > 0)
    x = acc0 - (c.A_DRAG << sh) // max(1, m)        # about where a crosses -A_DRAG
    x = max(-32768, min(32767, x))
    while x > -32768 and a(x) >= -c.A_DRAG:
        x -= 1
    while x < 32767 and a(x) < -c.A_DRAG:
        x += 1                                        # x: the first word with a >= -A_DRAG
    return max(-32768, min(32767, x + step))


@settings(max_examples=examples(150, ci=40), deadline=None)
@given(program=st.sampled_from(("kalman_baro", "kalman_accel")), k=st.sampled_from((4, 6, 8)),
       rounding=st.sampled_from(("floor", "half_up")), data=st.data())
def test_kalman_one_step_boundaries(program: str, k: int, rounding: str, data: st.DataObject) -> None:
    """Innovation at/next to +-E_GATE with the reject counter at/next to GATE_N, transonic speed MACH_VLO,
    liftoff threshold, X2 sign with the apogee counter at/next to APO_N, baro range edges, apogee prediction with
    DIVU overflow, the last pad-calibration sample: CPU == spec on all words after one step from a chosen state."""
    board = _board(program, k, rounding)
    c = board.build.consts
    h = bool(c.ROUND)
    adc = data.draw(st.one_of(st.sampled_from((0, 99, 100, 101, 64999, 65000, 65001, 65535)),
                              st.integers(0, 65535)), label="adc")
    acc0 = data.draw(st.integers(-32768, 32767), label="ACC0")
    acc = data.draw(st.one_of(st.just(acc0), st.integers(-32768, 32767)), label="acc")
    events = data.draw(st.sampled_from((0, LIFTOFF, LIFTOFF | APOGEE, LIFTOFF | PRED, LIFTOFF | MACH | INVALID,
                                        LIFTOFF | REJECT, LIFTOFF | GATE_HIGH, LIFTOFF | CLIP, LIFTOFF | CLIP,
                                        LIFTOFF | CLIP | CLEAR, LIFTOFF | CLEAR)),
                       label="EVENTS")
    # the clipped accelerometer: the rail, and a = mulg(acc - ACC0, ACC_G) at/next to -A_DRAG
    clip_acc = data.draw(st.sampled_from(("any", "rail", "drag")), label="clip_acc")
    if clip_acc == "rail":
        acc = 32767
    elif clip_acc == "drag" and program == "kalman_accel":
        acc = _acc_near_drag(c, acc0, data.draw(st.integers(-2, 2), label="drag_step"))
    x3 = data.draw(st.one_of(st.just(0), _near(0, -(1 << (15 + k)), -(1 << 30), INT32_MIN, INT32_MAX)), label="X3")
    mode = data.draw(st.sampled_from(("window", "predict", "free")), label="mode")
    if mode == "predict":
        # X2 after the step lands near 0 < X2 < d = -rs(X3, K), including v == d after the shifts (DIVU overflow)
        d = -rs_exact(x3, k, h)
        x2_target = data.draw(_near(1, 2, d - 1, d, d + 1, d // 2, (d + 1) // 2), label="x2_target")
        x2 = wrap32(x2_target - rs_exact(x3, k, h))
    else:
        x2_target = data.draw(_near(c.MACH_VLO, c.V_LIFT, 0), label="x2_target")
        x2 = wrap32(x2_target - rs_exact(x3, k, h))
    # X1 such that the innovation after the prediction is (near) +-E_GATE or 0
    e1 = data.draw(_near(c.E_GATE, -c.E_GATE, 0), label="e1")
    t1 = rs_exact(x2, k, h) + rs_exact(x3, 2 * k + 1, h)
    hh = spec_alt(c, adc) if c.BARO_MIN <= adc <= c.BARO_MAX else 0
    x1 = wrap32(hh - e1 - t1)
    ncal = 1 << c.CAL_P
    cal = data.draw(st.sampled_from((ncal, ncal, ncal, ncal - 1, 0)), label="CAL")
    rej = data.draw(st.sampled_from((0, c.GATE_N - 1, c.GATE_N)), label="REJ")
    neg = data.draw(st.sampled_from((0, max(0, c.APO_N - 1), c.APO_N - 2 if c.APO_N >= 2 else 0)), label="NEG")
    sumz = data.draw(st.integers(-(1 << 30), 1 << 30), label="SUMZ")
    suma = data.draw(st.integers(-(1 << 23), 1 << 23), label="SUMA")
    # issue 20: the phase, its coast counter at/next to COAST_N, X3 at/next to -A_COAST (in "free" mode), the Mach
    # delay at 0/1/2, VB at/next to X2 -+ DV / DU and to the int32 ends, the lockout counter at 0/1/2/MACH_N
    phase = data.draw(st.sampled_from((0, 1, 1, 2, 2, 3, 4)), label="PHASE")
    cstv = data.draw(st.sampled_from((0, max(0, c.COAST_N - 1), c.COAST_N - 2 if c.COAST_N >= 2 else 0)), label="CST")
    dly = data.draw(st.sampled_from((0, 0, 1, 2)), label="DLY")
    x2_new = x2_target
    vb = data.draw(st.one_of(_near(x2_new + c.DV, x2_new - c.DU, 0, INT32_MIN, INT32_MAX),
                             st.integers(INT32_MIN, INT32_MAX)), label="VB")
    lock = data.draw(st.sampled_from((0, 0, 1, 2, c.MACH_N)), label="LOCK")
    # the clip counter at/next to CLIP_N (rail) and to the window's half and end; its sum anywhere
    clp = data.draw(st.sampled_from(_clp_values(c)), label="CLP")
    e0 = data.draw(st.one_of(st.just(0), _near(0, INT32_MAX, INT32_MIN)), label="E0")
    # issue 30's descent record: HMAX at/next to this sample's altitude h (or anywhere), HT at/next to DESC_N
    hmax = data.draw(st.one_of(_near(hh, hh), st.integers(INT32_MIN, INT32_MAX)), label="HMAX")
    ht = data.draw(st.sampled_from(tuple(sorted({0, 1, max(0, c.DESC_N - 1), c.DESC_N, c.DESC_N + 1, 65535}))),
                   label="HT")
    # issue 30, third round: the previous valid altitude HP at/next to h -+ H_STEP (the steady test of the re-base),
    # or anywhere an altitude can be (|HP| <= 2^30, as the spec's exact difference assumes)
    hp = data.draw(st.one_of(st.sampled_from((hh - c.H_STEP, hh + c.H_STEP, hh)).flatmap(
        lambda v: st.integers(-2, 2).map(lambda d: max(-(1 << 30), min(1 << 30, v + d)))),
        st.integers(-(1 << 30), 1 << 30)), label="HP")
    if mode == "free":
        x3 = data.draw(st.one_of(st.just(x3), _near(-c.A_COAST)), label="X3_coast")
    state = _kalman_state(board, X1=x1, X2=x2, X3=x3, ACC0=acc0, EVENTS=events, CAL=cal, REJ=rej, NEG=neg,
                          SUMZ=sumz, SUMA=suma, GND=12345, PHASE=phase, CST=cstv, DLY=dly, VB=vb, LOCK=lock,
                          CLP=clp, E0=e0, HMAX=hmax, HT=ht, HP=hp)
    got = board.step(dict(state), adc, acc)
    want = spec_kalman_step(c, dict(state), adc, acc)
    want = {name: want[name] for name in board.build.variables}
    assert got == want, f"{program} k={k} {rounding} state={state} adc={adc} acc={acc}"


@settings(max_examples=examples(100))
@given(k=st.sampled_from((4, 6, 8)), rounding=st.sampled_from(("floor", "half_up")), data=st.data())
def test_recursive_one_step_boundaries(k: int, rounding: str, data: st.DataObject) -> None:
    """Liftoff and gate thresholds, EXT - EST == THR (also as an exact difference beyond 2^31), the accelerometer
    rail, the rate gate at/next to +-E_GATE with the reject counter at/next to GATE_N, the evidence counter at/next
    to APO_N, the last pad-calibration sample, from every reachable EVENTS state (GATE_HIGH implies LIFTOFF, ARMED
    implies GATE_HIGH, APOGEE implies ARMED) and from the unreachable ones that a corrupted RAM word could hold
    (the spec is total: each bit is tested as written)."""
    board = _board("recursive", k, rounding)
    c = board.build.consts
    h = bool(c.ROUND)
    adc = data.draw(st.integers(0, 65535), label="adc")
    z = c.BARO_SIGN * adc
    acc0 = data.draw(st.integers(-32768, 32767), label="ACC0")
    acc = data.draw(st.one_of(st.just(32767), st.just(32766), st.integers(-32768, 32767)), label="acc")
    vel_target = data.draw(_near(c.V_LIFT, c.V_GATE, 0, INT32_MAX, INT32_MIN), label="vel_target")
    vel = wrap32(vel_target - (acc - acc0))
    zl = data.draw(st.one_of(st.integers(-2, 2).flatmap(
        lambda d: st.sampled_from((z - c.E_GATE + d, z + c.E_GATE + d, z + d))), st.integers(-65535, 65535)),
        label="ZL")
    est = data.draw(_near(0, INT32_MIN, INT32_MAX, 1 << 20), label="EST")
    est_new = wrap32(est + (z << (8 - c.S)) - rs_exact(est, c.S, h))
    ext = data.draw(st.one_of(_near(est_new + c.THR, est_new, est + c.THR, est, INT32_MAX),
                              st.integers(INT32_MIN, INT32_MAX)), label="EXT")
    events = data.draw(st.one_of(
        st.sampled_from((0, LIFTOFF, LIFTOFF | GATE_HIGH, LIFTOFF | GATE_HIGH | ARMED,
                         LIFTOFF | GATE_HIGH | ARMED | APOGEE, LIFTOFF | CLIP | GATE_HIGH | ARMED,
                         LIFTOFF | CLIP, LIFTOFF | CLIP | GATE_HIGH, LIFTOFF | CLIP | CLEAR | GATE_HIGH | ARMED,
                         LIFTOFF | GATE_HIGH | REJECT)),
        st.sets(st.sampled_from((LIFTOFF, GATE_HIGH, ARMED, APOGEE, CLIP, CLEAR, REJECT))).map(sum)), label="EVENTS")
    ncal = 1 << c.CAL_P
    cal = data.draw(st.sampled_from((ncal, ncal, ncal, ncal - 1, 0)), label="CAL")
    suma = data.draw(st.integers(-(1 << 23), 1 << 23), label="SUMA")
    rej = data.draw(st.sampled_from((0, c.GATE_N - 1, c.GATE_N)), label="REJ")
    neg = data.draw(st.sampled_from((0, max(0, c.APO_N - 2), c.APO_N - 1)), label="NEG")
    # issue 20: the phase word and its coast counter at/next to COAST_N; acc - ACC0 at/next to -A_COAST and VEL
    # at/next to -V_DESC come from the draws above often enough through the "free" values
    phase = data.draw(st.sampled_from((0, 1, 1, 2, 3, 3, 4)), label="PHASE")
    cstv = data.draw(st.sampled_from((0, max(0, c.COAST_N - 1), c.COAST_N - 2 if c.COAST_N >= 2 else 0)), label="CST")
    if data.draw(st.booleans(), label="coast_edge"):
        bound = data.draw(st.sampled_from((c.A_COAST, c.A_DRAG)), label="bound")   # coast / drag-low after a clip
        acc = max(-32768, min(32767, acc0 - bound + data.draw(st.integers(-1, 1), label="da")))
        vel = wrap32(-c.V_DESC + data.draw(st.integers(-1, 1), label="dv") - (acc - acc0))
    clp = data.draw(st.sampled_from(_clp_values(c)), label="CLP")
    state = {"EST": est, "EXT": ext, "VEL": vel, "ACC0": acc0, "EVENTS": events, "ZL": zl, "SUMA": suma,
             "CAL": cal, "REJ": rej, "NEG": neg, "PHASE": phase, "CST": cstv, "CLP": clp}
    got = board.step(dict(state), adc, acc)
    assert got == spec_recursive_step(c, dict(state), adc, acc), f"k={k} {rounding} state={state} adc={adc}"


@pytest.mark.parametrize("rounding", ["floor", "half_up"])
@pytest.mark.parametrize("k", [4, 7])
@pytest.mark.parametrize("program", ["kalman_baro", "kalman_accel"])
def test_kalman_gate_transonic_and_liftoff_exact_boundaries(program: str, k: int, rounding: str) -> None:
    """Every combination of X2 at/next to MACH_VLO, V_LIFT, 0, e1 at/next to +-E_GATE and the reject counter
    below/at GATE_N, from the pad and after liftoff, with an accelerometer at rest (e2 = -X3 = 0). kalman_accel
    must use the transonic gains on some of them, kalman_baro on none; both must reject some samples and open the
    gate on others."""
    board = _board(program, k, rounding)
    c = board.build.consts
    h = bool(c.ROUND)
    adc = 30000
    hh = spec_alt(c, adc)
    trans = rejected = opened = 0
    for events in (0, LIFTOFF):
        for x2 in sorted({c.MACH_VLO + d for d in (-1, 0, 1)} | {c.V_LIFT + d for d in (-1, 0, 1)} | {-1, 0, 1}):
            for e1 in (c.E_GATE + 1, c.E_GATE, c.E_GATE - 1, 0, -c.E_GATE + 1, -c.E_GATE, -c.E_GATE - 1):
                for rej in (0, c.GATE_N - 1, c.GATE_N):
                    x1 = wrap32(hh - e1 - rs_exact(x2, k, h))
                    state = _kalman_state(board, X1=x1, X2=x2, ACC0=123, EVENTS=events, REJ=rej)
                    want = spec_kalman_step(c, dict(state), adc, 123)
                    want = {name: want[name] for name in board.build.variables}
                    got = board.step(dict(state), adc, 123)
                    assert got == want, f"{program} k={k} {rounding} state={state}"
                    trans += bool(got["EVENTS"] & MACH)
                    rejected += bool(got["EVENTS"] & REJECT)
                    opened += abs(e1) > c.E_GATE and rej == c.GATE_N and not got["EVENTS"] & REJECT
    assert (trans > 0) == (program == "kalman_accel"), f"{program}: {trans} transonic samples"
    assert rejected > 0 and opened > 0, (rejected, opened)


@pytest.mark.parametrize("rounding", ["floor", "half_up"])
@pytest.mark.parametrize("k", [4, 5, 8])
def test_kalman_apogee_prediction_exact_boundaries(k: int, rounding: str) -> None:
    """Step 10 with the barometer invalid (no correction, so the state after the step is known): X2 at/next to
    0, 1, d-1, d, d+1 for divisors d = -rs(X3, K) below and above 32768 (the normalisation loop), including
    v == d after the shifts (DIVU quotient overflow -> APFRAC = 65535) and d = 2^31 (X3 = INT32_MIN, K = 0 ..
    the unsigned compare)."""
    board = _board("kalman_baro", k, rounding)
    c = board.build.consts
    h = bool(c.ROUND)
    seen_overflow = False
    for d in (2, 3, 100, 32767, 32768, 32769, 65535, (1 << 20) + 1, (1 << 20) + 3, 3 << 20, (1 << 31) >> k):
        x3 = -(d << k) if -(d << k) >= INT32_MIN else INT32_MIN
        dd = -rs_exact(x3, k, h)
        for v in sorted({-1, 0, 1, 2, dd - 1, dd, dd + 1, dd // 2, (1 << 20) if dd == (1 << 20) + 1 else 1}):
            x2 = wrap32(v - rs_exact(x3, k, h))
            for events, phase in ((LIFTOFF, 2), (LIFTOFF | PRED, 2), (LIFTOFF | APOGEE, 3), (0, 0), (LIFTOFF, 1)):
                # (issue 20: the prediction runs in PHASE COAST only; VB = X2 + 1 keeps the evidence off the
                # counter when X2 >= 0 and lets it count when X2 < -1)
                state = _kalman_state(board, X2=x2, X3=x3, EVENTS=events, APFRAC=7, NEG=max(0, c.APO_N - 1),
                                      PHASE=phase, VB=wrap32(v + 1))
                want = spec_kalman_step(c, dict(state), 0, 0)      # adc 0 < BARO_MIN: BARO_INVALID
                got = board.step(dict(state), 0, 0)
                assert got == want, f"k={k} {rounding} d={dd} v={v} state={state}"
                seen_overflow |= want["APFRAC"] == 65535 and not events & PRED
    assert seen_overflow, "no case reached the DIVU overflow"


@pytest.mark.parametrize("rounding", ["floor", "half_up"])
@pytest.mark.parametrize("k", [4, 7])
@pytest.mark.parametrize("program", ["recursive", "kalman_baro", "kalman_accel"])
def test_clip_counter_and_window_exact_boundaries(program: str, k: int, rounding: str) -> None:
    """The clipped accelerometer (spec §5 steps 2, 3, 6; §6 steps 4, 7, 9b), every combination of: EVENTS with
    ACC_CLIP / CLIP_CLEAR (and without), PHASE BOOST or COAST, CLP at/next to CLIP_N, 2^K and 2^(K+1), the
    accelerometer at the rail / next to it / at-next to the drag bound -A_DRAG, the barometer valid or not
    (Kalman) and, valid, steady or one step beyond H_STEP from HP (kalman_accel: a spike resets the window), E0 at
    0 and the int32 ends (the re-base's wraps). CPU == spec after one step, and the branches are reached: ACC_CLIP
    set by the rail count, CLIP_CLEAR set (kalman_accel: with X2 re-based), a window reset, a spike's reset."""
    board = _board(program, k, rounding)
    c = board.build.consts
    seen = {"clip": 0, "clear": 0, "reset": 0, "rebase": 0, "spike": 0}
    if program == "recursive":
        acc0 = 2048
        accs = (32767, 32766, acc0 - c.A_DRAG - 1, acc0 - c.A_DRAG, acc0 - c.A_DRAG + 1)
        for events in (LIFTOFF | GATE_HIGH, LIFTOFF | CLIP | GATE_HIGH | ARMED, LIFTOFF | CLIP | CLEAR | ARMED):
            for phase in (1, 2):
                for clp in _clp_values(c):
                    for acc in accs:
                        for ext_minus in (0, c.THR):        # apogee evidence (ARMED) or not
                            state = {"EST": 1 << 20, "EXT": (1 << 20) + ext_minus, "VEL": 0, "ACC0": acc0,
                                     "EVENTS": events, "ZL": 0, "SUMA": 0, "CAL": 1 << c.CAL_P, "REJ": 0,
                                     "NEG": 0, "PHASE": phase, "CST": 0, "CLP": clp}
                            got = board.step(dict(state), 0, acc)
                            want = spec_recursive_step(c, dict(state), 0, acc)
                            assert got == want, f"k={k} {rounding} state={state} acc={acc}"
                            seen["clip"] += bool(got["EVENTS"] & CLIP and not events & CLIP)
                            seen["clear"] += bool(got["EVENTS"] & CLEAR and not events & CLEAR)
                            seen["reset"] += clp > 0 and got["CLP"] == 0
        assert seen["clip"] and seen["clear"] and seen["reset"], seen
        return
    h = bool(c.ROUND)
    adc = 30000
    hh = spec_alt(c, adc)
    accel = program == "kalman_accel"
    acc0 = 100
    accs = (32767, 32766) + ((tuple(_acc_near_drag(c, acc0, d) for d in (-1, 0, 1))) if accel else (acc0,))
    for events in (LIFTOFF, LIFTOFF | CLIP, LIFTOFF | CLIP | CLEAR):
        for phase in (1, 2):
            for clp in _clp_values(c):
                for acc in accs:
                    for e0 in (0, INT32_MAX, INT32_MIN, -12345):
                        # valid and steady, valid one step beyond H_STEP from HP (kalman_accel: not steady),
                        # invalid (below BARO_MIN)
                        for baro, hp in ((adc, hh), (adc, hh - c.H_STEP - 1), (0, hh)):
                            x2, x3 = -256, 0                       # X2 < 0: VB < 0, so 9b's evidence is tested
                            x1 = wrap32(hh - 1000 - rs_exact(x2, k, h))
                            state = _kalman_state(board, X1=x1, X2=x2, X3=x3, ACC0=acc0, EVENTS=events,
                                                  PHASE=phase, CLP=clp, E0=e0, VB=-256, NEG=max(0, c.APO_N - 1),
                                                  HP=hp)
                            got = board.step(dict(state), baro, acc)
                            want = spec_kalman_step(c, dict(state), baro, acc)
                            want = {name: want[name] for name in board.build.variables}
                            assert got == want, f"{program} k={k} {rounding} state={state} adc={baro} acc={acc}"
                            seen["clip"] += bool(got["EVENTS"] & CLIP and not events & CLIP)
                            seen["clear"] += bool(got["EVENTS"] & CLEAR and not events & CLEAR)
                            seen["reset"] += accel and clp > 0 and got["CLP"] == 0
                            seen["spike"] += bool(accel and hp != hh and events == LIFTOFF | CLIP and phase == 2
                                                  and clp == (2 << k) - 1 and got["CLP"] == 0
                                                  and not got["EVENTS"] & CLEAR)
                            seen["rebase"] += bool(got["EVENTS"] & CLEAR and not events & CLEAR
                                                   and got["X1"] != wrap32(x1 + rs_exact(x2, k, h)))
    if accel:
        assert all(seen.values()), seen
    else:
        assert not seen["clip"] and not seen["clear"], seen        # kalman_baro never sets either bit
        assert not seen["spike"]

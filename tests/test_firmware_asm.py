"""The arithmetic macros of firmware_model/asm/fwemu.inc, run on the emulated 68000, against exact integer math.

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

from profiles import examples

isa = pytest.importorskip("isa")
pytest.importorskip("isa.assembler")
pytest.importorskip("isa.cpu")

from firmware_model.build import ASM_DIR  # noqa: E402

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
    from firmware_model.build import RAM_START, ROM_SIZE, STACK_TOP, build_firmware
    from firmware_model.config import BuildConfig
    from firmware_model.trace import STATE_WORDS

    build = build_firmware(BuildConfig(program=program, rounding=rounding))
    assert build.program.warnings == []
    assert 0 < build.rom_bytes <= ROM_SIZE
    assert build.init_address < build.rom_bytes and build.step_address < build.rom_bytes
    for name, size in STATE_WORDS[program]:
        address, got_size = build.variables[name]
        assert got_size == size and RAM_START <= address < STACK_TOP and address % 2 == 0
    assert build.ram_bytes == sum(size for _, size in STATE_WORDS[program])
    assert len(build.source_sha256) == 64

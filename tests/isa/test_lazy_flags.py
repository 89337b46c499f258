"""Lazy ADD/SUB flags across a block's loop edge (isa/block_plan.py ``_lazy_kind``, docs/isa-internals.md).

In a compiled loop whose ADD/SUB flags only a block exit or a fault can see, the block keeps the ADD/SUB's
unmasked result and source (``lr``/``ls``) and computes the CCR from them only on the exits and on the slow
(possibly faulting) memory paths. These tests aim at the points where such skipped flags become visible:

* the loop's exits (the count runs out, an instruction or cycle limit inside the loop, ``until_pc`` at every
  instruction), a bus or address error in a later pass (MOVE's read or write, the ADD's own memory read, the
  ADD's write to memory), a slow path that does NOT fault (an I/O read, which must leave no stale lazy flags);
* against the per-instruction closures (everything: registers, SR, memory, counters, fault message, and a
  second run from where the first stopped) and against m68000-python (registers, CCR, memory, clocks).

Every hand-written case also checks that the lazy form was really generated (``lr`` among the block's locals).
"""

from __future__ import annotations

import random

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import isa
from isa.cpu import CPU
from isa.encoder import encode
from isa.errors import CPUFault
from isa.operands import Instruction, Mode, Operand, Size
from isa.strategies import instructions
from tests.support.profiles import examples

from tests.support import oracles
from tests.isa.test_blocks import _diff, _map_cpu, machine, ours_blocks, ref_run

M32 = 0xFFFFFFFF
CODE = 0x1000
EDGE = (0, 1, 2, 0x7F, 0x80, 0xFF, 0x7FFF, 0x8000, 0xFFFF, 0x7FFFFFFF, 0x80000000, 0xFFFFFFFF, 0xFFFF8000)
#: Address register values on the ROM/RAM/I-O map below: RAM inside and at its edges, ROM, I/O, holes, odd.
A_VALUES = [0x4000, 0x4100, 0x4102, 0x5000, 0x7FF0, 0x7FF8, 0x7FFC, 0x7FFE, 0x7FFF, 0x8000, 0x3FFC, 0x0800,
            0xFFF000, 0xFFEFFC, 0x4101, 0x4003, 0x9000]
ABS = st.sampled_from([0x4000, 0x4004, 0x4006, 0x7FFC, 0x7FFE, 0x0800, 0x8000, 0xFFF000, 0xFFF002, 0x4001])
MODES = frozenset({Mode.DREG, Mode.AREG, Mode.IMM, Mode.AIND, Mode.APOSTINC, Mode.APREDEC, Mode.ADISP,
                   Mode.ABSW, Mode.ABSL})


def _no_d7(ins: Instruction) -> bool:
    return not any((op.mode is Mode.DREG and op.reg == 7) or (op.index is not None and not op.index.is_areg
                                                              and op.index.num == 7) for op in ins.operands)


def _small(ins: Instruction) -> bool:
    return all(op.mode is not Mode.ADISP or -0x40 <= op.value <= 0x40 for op in ins.operands)


def _rows(rows: str) -> st.SearchStrategy[Instruction]:
    return instructions(rows=rows.split(), address=CODE, modes=MODES, absolute=ABS).filter(
        lambda i: _no_d7(i) and _small(i))


PRODUCERS = {"add": _rows("add addi addq"), "sub": _rows("sub subi subq")}
OTHERS = _rows("move movea lea adda suba exg nop")
#: Also allowed in a lazy loop when their flags are dead or deferred (DIVU/DIVS only by a nonzero immediate).
ARITH = _rows("muls mulu divu divs neg clr not tst swap ext")
#: Rows that usually undo the lazy form (their flags are written into sr in the loop): the fallback is tested too.
SPOILERS = _rows("and or eor cmp cmpi tst add sub")


def _loop_code(body: list[Instruction], count: int | None) -> bytes:
    """[MOVEQ #count,D7] body DBRA D7,body TRAP #0, from CODE."""
    code = b""
    if count is not None:
        code += encode(Instruction("moveq", None, (Operand(Mode.IMM, value=count), Operand(Mode.DREG, 7))), CODE)
    top = CODE + len(code)
    for ins in body:
        code += encode(ins, CODE + len(code))
    code += encode(Instruction("dbra", Size.W, (Operand(Mode.DREG, 7), Operand(Mode.ABSL, value=top))),
                   CODE + len(code))
    return code + b"\x4e\x40"  # trap #0


def _run(code: bytes, d: list[int], a: list[int], ccr: int, kwargs: dict[str, object], blocks: bool,
         written: bool = True) -> tuple[tuple[object, ...], bool]:
    """Everything observable after ``run(**kwargs)`` (and after a second run from there), and whether a block
    with lazy flags was compiled."""
    cpu = _map_cpu(blocks)
    cpu.write_bytes(CODE, code)
    cpu.write_bytes(0x4000, bytes(range(7, 256)) * 65 + bytes(range(0x4000 - 249 * 65)))
    if not written:  # a fresh RAM: the first-write paths
        cpu = _map_cpu(blocks)
        cpu.write_bytes(CODE, code)
    cpu.write(0xFFF000, 0x8001, 2)
    for i in range(8):
        cpu.d[i], cpu.a[i] = d[i], a[i]
    cpu.sr = 0x2700 | ccr
    cpu.pc = CODE
    cpu.reset_counters()
    try:
        res = cpu.run(**kwargs)  # type: ignore[arg-type]  # **kwargs of mixed run() argument types
        outcome: tuple[object, ...] = ("ok", res)
    except CPUFault as exc:
        outcome = (type(exc).__name__, str(exc), exc.pc, exc.instruction)
    state = (tuple(cpu.d), tuple(cpu.a), cpu.pc, cpu.sr, cpu.instructions, cpu.cycles, cpu.min_sp,
             cpu.ram_written, cpu.written_ranges(), cpu.read_bytes(0x4000, 0x4000), cpu.read_bytes(0xFFF000, 4))
    try:
        again: tuple[object, ...] = ("ok", cpu.run(max_instructions=25, stop_at_limit=True))
    except CPUFault as exc:
        again = (type(exc).__name__, str(exc), exc.pc)
    lazy = any("lr" in code_obj.co_varnames for code_obj in cpu._block_code)
    return outcome + state + again + (cpu.sr, tuple(cpu.d), tuple(cpu.a), cpu.cycles), lazy


def _both(code: bytes, d: list[int], a: list[int], ccr: int, kwargs: dict[str, object], written: bool = True
          ) -> bool:
    blocks, lazy = _run(code, d, a, ccr, kwargs, True, written)
    closures, _ = _run(code, d, a, ccr, kwargs, False, written)
    assert blocks == closures
    return lazy


@st.composite
def lazy_loops(draw: st.DrawFn) -> tuple[list[Instruction], int | None]:
    """A DBRA loop body: 1..3 ADD-kind or SUB-kind instructions of one size (the lazy candidates) among 0..4
    MOVE/MOVEA/LEA/ADDA/SUBA/EXG/NOP and sometimes 1..2 MULS/MULU/DIVU/DIVS/NEG/CLR/NOT/TST/SWAP/EXT, now and
    then an AND/OR/EOR/CMP/TST/ADD/SUB that may undo the lazy form;
    D7 = 0..6 passes (MOVEQ before the loop, or the loop at the block's start with D7 preset)."""
    kind = draw(st.sampled_from(["add", "sub"]))
    size = draw(st.sampled_from([Size.B, Size.W, Size.L]))
    prod = PRODUCERS[kind].filter(lambda i: i.size is size)
    body = [draw(prod) for _ in range(draw(st.integers(1, 3)))]
    for _ in range(draw(st.integers(0, 4))):
        body.insert(draw(st.integers(0, len(body))), draw(OTHERS))
    for _ in range(draw(st.integers(0, 2)) if draw(st.booleans()) else 0):
        body.insert(draw(st.integers(0, len(body))), draw(ARITH))
    if draw(st.integers(0, 5)) == 0:
        body.insert(draw(st.integers(0, len(body))), draw(SPOILERS))
    count = draw(st.integers(0, 6)) if draw(st.booleans()) else None
    return body, count


@settings(max_examples=examples(150, ci=40), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(lazy_loops(), st.lists(st.sampled_from(EDGE) | st.integers(0, M32), min_size=8, max_size=8),
       st.lists(st.sampled_from(A_VALUES), min_size=7, max_size=7), st.integers(0, 31), st.integers(0, 6),
       st.integers(1, 80), st.integers(1, 1500), st.integers(0, 40), st.booleans(), st.booleans())
def test_lazy_loops_equal_closures_on_a_rom_ram_io_map(loop: tuple[list[Instruction], int | None], d: list[int],
                                                       a: list[int], ccr: int, d7: int, max_n: int, max_c: int,
                                                       until_k: int, stop: bool, written: bool) -> None:
    """Lazy-flag loops over ROM, RAM, I/O, holes and odd addresses (faults in any pass, I/O slow paths that do
    not fault), stopped by the count, an instruction limit, a cycle limit or until_pc: blocks == closures."""
    body, count = loop
    code = _loop_code(body, count)
    d = list(d)
    d[7] = d[7] & 0xFFFF0000 | d7
    until = CODE + 2 * until_k if 2 * until_k < len(code) else None
    kwargs = dict(max_instructions=max_n, max_cycles=max_c, until_pc=until, stop_at_limit=stop)
    _both(code, d, a + [0x7F00], ccr, kwargs, written)


#: Rows for the m68000-python comparison (the oracle's RAM layout: data between DATA_LO and DATA_HI).
REF_PRODUCERS = {k: instructions(rows=r.split(), address=oracles.CODE,
                                 modes=frozenset({Mode.DREG, Mode.AREG, Mode.IMM, Mode.AIND, Mode.APOSTINC,
                                                  Mode.APREDEC, Mode.ADISP}),
                                 ).filter(lambda i: _no_d7(i) and _small(i))
                 for k, r in (("add", "add addi addq"), ("sub", "sub subi subq"))}
REF_OTHERS = instructions(rows="move lea nop exg muls mulu divu divs neg".split(), address=oracles.CODE,
                          modes=frozenset({Mode.DREG, Mode.IMM, Mode.AIND, Mode.APOSTINC, Mode.APREDEC, Mode.ADISP})
                          ).filter(lambda i: _no_d7(i) and _small(i) and not (i.operands and
                              i.operands[-1].mode is Mode.AREG and i.operands[-1].reg == 7))


@settings(max_examples=examples(60, ci=15), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(["add", "sub"]), st.sampled_from([Size.B, Size.W, Size.L]), st.data(),
       st.lists(st.sampled_from(EDGE) | st.integers(0, M32), min_size=8, max_size=8), st.integers(0, 31),
       st.integers(0, 1 << 30))
def test_lazy_loops_vs_m68000py(kind: str, size: Size, data: st.DataObject, d: list[int], ccr: int,
                                seed: int) -> None:
    """The same kind of loops on the oracle's RAM layout: registers, CCR (the last pass's skipped ADD/SUB flags),
    memory, clocks and instruction count equal to m68000-python's (or the same fault kind)."""
    prod = REF_PRODUCERS[kind].filter(lambda i: i.size is size)
    body = [data.draw(prod) for _ in range(data.draw(st.integers(1, 3)))]
    for _ in range(data.draw(st.integers(0, 3))):
        body.insert(data.draw(st.integers(0, len(body))), data.draw(REF_OTHERS))
    count = data.draw(st.integers(0, 5))
    items = [Instruction("moveq", None, (Operand(Mode.IMM, value=count), Operand(Mode.DREG, 7)))] + body
    code = b""
    for ins in items:
        code += encode(ins, oracles.CODE + len(code))
    code += encode(Instruction("dbra", Size.W, (Operand(Mode.DREG, 7), Operand(Mode.ABSL, value=oracles.CODE + 2))),
                   oracles.CODE + len(code))
    m = machine(code, seed, d, ccr)
    end = oracles.CODE + len(code)
    ours, ref = ours_blocks(m, end, 200), ref_run(m, end, 200)
    assert ours == ref, f"{_diff(ours, ref)}\n  code {code.hex(' ')} d={[hex(v) for v in d]} ccr={ccr:#x}"


# ---------------------------------------------------------------------------------------- hand-written points
#: (source of the loop body, A0, A1, A2, what it aims at). Each loop is MOVEQ #5,D7 / body / DBRA D7 / TRAP #0.
CASES = [
    ("move.l (a0)+,(a1)+\n add.l 8(a2),d0", 0x4000, 0x6000, 0x5000, "the bench loop: exit flags from the last ADD"),
    ("move.l (a0)+,(a1)+\n add.l 8(a2),d0", 0x7FF4, 0x6000, 0x5000, "MOVE's read faults (hole) in pass 4"),
    ("move.l (a0)+,(a1)+\n add.l 8(a2),d0", 0x4000, 0x7FF4, 0x5000, "MOVE's write faults (hole) in pass 4"),
    ("move.l (a0)+,(a1)+\n add.l 8(a2),d0", 0x4000, 0x6000, 0x7FFC, "ADD's read faults in pass 1 (MOVE deferred)"),
    ("move.l (a0)+,(a1)+\n add.l 4(a0),d0", 0x7FF0, 0x6000, 0, "ADD's read faults in pass 3"),
    ("move.w (a0)+,d2\n add.w d1,-(a1)", 0x4000, 0x4006, 0, "ADD's write to ROM faults in pass 4 (own flags)"),
    ("move.b d0,-(a1)\n sub.b (a0)+,d0", 0x4000, 0x4003, 0, "MOVE.B's write to ROM in pass 4, SUB.B"),
    ("move.w (a0),d1\n addq.w #3,d0\n movea.w (a0),a3", 0xFFF000, 0x6000, 0, "I/O reads: slow paths, no fault"),
    ("move.l (a0)+,d1\n subi.l #$7FFFFFFF,d0", 0x7FF0, 0, 0, "MOVE faults after SUBI.L overflow flags"),
    ("add.l d0,d0\n move.l d0,(a1)+\n add.l d1,d0", 0x4000, 0x7FF0, 0, "two ADDs, the write between faults"),
    ("move.l (a0)+,d1\n add.l d1,d0", 0x4001, 0x6000, 0, "odd address: address error in pass 1"),
    ("subq.w #1,d0\n move.w d0,(a1)+\n sub.w d1,d0", 0x4000, 0x7FF8, 0, "SUBQ.W/SUB.W borrows, write faults"),
    ("add.l d1,d0\n add.l d0,(a0)+", 0x7FF8, 0, 0, "ADD to memory whose destination read faults in pass 3"),
    ("muls.w d1,d2\n divu.w #7,d2\n add.l d2,d0\n move.l (a0)+,d3\n add.l d3,d0", 0x7FF0, 0, 0,
     "the bench's MUL/DIV kind of loop, MOVE faults in pass 5"),
]


@pytest.mark.parametrize("body,a0,a1,a2,what", CASES, ids=[c[4] for c in CASES])
def test_lazy_flags_at_exits_and_faults(body: str, a0: int, a1: int, a2: int, what: str) -> None:
    """Each case with several starting CCRs and D0/D1 values (carry, overflow, zero, negative results), run to its
    end, then with every instruction limit and every 11th cycle limit, and until_pc at every instruction."""
    src = f" moveq #5,d7\ntop: {body}\n dbra d7,top\n trap #0\n"
    code = isa.assemble(src, origin=CODE).code
    a = [a0, a1, a2, 0x4800, 0x4800, 0x4800, 0x4800, 0x7F00]
    engaged = False
    for d0, d1, ccr in ((0, 0, 0), (0x7FFFFFFF, 1, 0x1F), (0xFFFFFFFF, 0x80000000, 0x10), (0x80, 0x7F, 0x04)):
        d = [d0, d1, 0, 0, 0, 0, 0, 0]
        engaged = _both(code, d, a, ccr, {}) or engaged
        for n in range(1, 40):
            _both(code, d, a, ccr, {"max_instructions": n, "stop_at_limit": bool(n & 1)})
        for c in range(1, 700, 11):
            _both(code, d, a, ccr, {"max_cycles": c, "stop_at_limit": bool(c & 2)})
        for u in range(CODE, CODE + len(code), 2):
            _both(code, d, a, ccr, {"until_pc": u, "max_instructions": 60, "stop_at_limit": True})
    assert engaged, f"the lazy form was not generated for: {what}"


def test_lazy_form_is_undone_by_a_flag_reader() -> None:
    """Not every loop is lazy: a Bcc on the ADD's flags (or a CMP whose flags go into sr) keeps them computed;
    results stay equal to the closures'."""
    for body in ("add.l d1,d0\n bcc.s nx\n addq.l #1,d2\nnx: move.l d0,(a1)+",
                 "add.l d1,d0\n cmp.l d0,d2\n move.l d0,(a1)+"):
        code = isa.assemble(f" moveq #5,d7\ntop: {body}\n dbra d7,top\n trap #0\n", origin=CODE).code
        assert not _both(code, [0x7FFFFFF0, 0x10000000] + [0] * 6, [0x4000, 0x6000] + [0x4800] * 5 + [0x7F00], 0,
                         {})


def test_memory_bench_loop_is_lazy_and_exact_vs_m68000py() -> None:
    """The bench's memory loop (bench/bench_cpu.py): generated lazily, and equal to m68000-python at its end."""
    src = " move.w #40,d7\n lea $6000,a0\n lea $6400,a1\n lea $6800,a2\nl: move.l (a0)+,(a1)+\n" \
          " add.l 8(a2),d0\n dbra d7,l\n"
    code = isa.assemble(src, origin=oracles.CODE).code
    for seed in range(6):
        rng = random.Random(seed)
        m = machine(code, seed, [rng.randrange(1 << 32) for _ in range(8)], rng.randrange(32))
        end = oracles.CODE + len(code)
        ours, ref = ours_blocks(m, end, 400), ref_run(m, end, 400)
        assert ours == ref, _diff(ours, ref)
    cpu = oracles.make_cpu(isa)
    cpu.write_bytes(oracles.CODE, code + b"\x4e\x40")
    cpu.pc = oracles.CODE
    cpu.run(max_instructions=1000)
    assert any("lr" in c.co_varnames for c in cpu._block_code)


WRAPS = [
    ("move.l (a0)+,d1\n add.l d1,d0\n move.b -(a1),d2\n add.b d2,d0", (0xFFFFFFF0, 0x00000004, 0), True),
    ("move.w (a0)+,(a1)+\n sub.w -(a2),d0", (0xFFFFFFF8, 0xFFFFFFE0, 0x00000006), True),
    ("move.w (a0)+,(a1)+\n sub.w -(a2),d0", (0xFFFFFFF8, 0xFFFFFFF8, 0x00000006), False),  # writes reach ROM
    ("move.b -(a7),d1\n add.b d1,d0\n move.b -(a7),d2\n add.l d2,d0", (0, 0, 0), True),
]


@pytest.mark.parametrize("body,regs,ok", WRAPS)
def test_address_register_updates_that_wrap_at_2_32(body: str, regs: tuple[int, int, int], ok: bool) -> None:
    """(An)+ / -(An) (A7 byte steps of 2 included) across $FFFFFFFF <-> 0, compiled without a mask unless they
    wrap: blocks == closures, with high RAM at $FFFF00 (addresses >= 2^24 reach it through the 24-bit bus) and
    ROM at 0 (a write there faults after the wrap)."""
    code = isa.assemble(f" moveq #9,d7\ntop: {body}\n dbra d7,top\n trap #0\n", origin=CODE).code
    outs = []
    for blocks in (True, False):
        cpu = CPU(mapped=False)
        cpu.block_compile = blocks
        cpu.map(0, 0x4000, "rom", writable=False)
        cpu.map(0x4000, 0x4000, "ram")
        cpu.map(0xFFFF00, 0x100, "ram")
        cpu.write_bytes(CODE, code)
        cpu.write_bytes(0xFFFF00, bytes(range(0x100)))
        for i in range(3):
            cpu.a[i] = regs[i]
        cpu.a[7] = 0x00000008
        cpu.d[0] = 0x12345678
        cpu.pc = CODE
        try:
            outcome: tuple[object, ...] = ("ok", cpu.run(max_instructions=200))
        except CPUFault as exc:
            outcome = (type(exc).__name__, str(exc))
        outs.append(outcome + (tuple(cpu.d), tuple(cpu.a), cpu.sr, cpu.instructions, cpu.cycles,
                               cpu.read_bytes(0xFFFF00, 0x100)))
    assert outs[0] == outs[1]
    assert (outs[0][0] == "ok") == ok, outs[0][:2]
    wrapped = [(a0 - a) & M32 for a0, a in zip(list(regs) + [8], [outs[0][3][i] for i in (0, 1, 2, 7)])]
    assert any(r and (a0 >= 0xFFFFFF00) != (a >= 0xFFFFFF00) for r, a0, a in
               zip(wrapped, list(regs) + [8], [outs[0][3][i] for i in (0, 1, 2, 7)])), "no register crossed 2^32"


def test_loop_whose_head_branches_past_its_end() -> None:
    """``top: bra.s out / dbra d7,top / out:`` is planned as a loop whose only pass leaves at once: its cap on the
    pass count reads the clock local ``c``, which then has to exist (found by the thorough profile: NameError in
    the generated block). Blocks == closures at every limit."""
    code = isa.assemble("top: bra.s out\n dbra d7,top\nout: trap #0\n", origin=CODE).code
    for n, c in ((None, None), (1, None), (2, 15), (3, 9), (None, 11)):
        kwargs = {"max_instructions": n, "max_cycles": c, "stop_at_limit": True}
        _both(code, [0] * 7 + [3], [0x4000] * 7 + [0x7F00], 0, kwargs)

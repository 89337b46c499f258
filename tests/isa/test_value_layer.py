"""The block generator's value layer (pending register values, ``isa.block_codegen._BlockGen.symbolic``).

Register-only data instructions (MOVE/MOVEQ/SWAP/EXT/MULx #imm/shifts/ADD/SUB/AND/OR/EOR/CLR/NOT/NEG/EXG,
CMP/CMPI/TST) are not generated as statements: their results are expressions composed into the next
instruction's and assigned to the register locals only where something can observe them (an instruction that
may fault, a branch, an exit, the end of a straight line). These tests draw dense chains of them over four data
registers, so that values flow from one to the next, mixed with what must see the registers: memory accesses that
fault (odd, unmapped), DIVU by a register that may be zero, MUL by a register, forward branches, and random
instruction/cycle limits and ``until_pc``; and compare

* against the per-instruction closures: registers, SR, PC, memory, counters, fault class, message and PC;
* against m68000-python (the cycle oracle): registers, CCR, memory, clocks, instruction count, fault kind.

``test_value_layer_is_used`` checks that the chains really are composed (not vacuous).
"""

from __future__ import annotations

import dataclasses
import random

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import isa
from isa import block_codegen, codecache
from isa.operands import Instruction, Mode
from isa.strategies import instructions
from tests.support.profiles import examples

from tests.support import oracles
from tests.isa.test_blocks import EDGE, M32, _diff, _run_both, layout, machine, ours_blocks, ref_run

CHAIN_ROWS = ["move", "moveq", "add", "addi", "addq", "sub", "subi", "subq", "and", "andi", "or", "ori", "eor",
              "eori", "cmp", "cmpi", "tst", "clr", "not", "neg", "swap", "ext", "exg", "mulu", "muls", "asl", "asr",
              "lsl", "lsr"]
REG_IMM = frozenset({Mode.DREG, Mode.IMM})


def _four(ins: Instruction) -> Instruction:
    """The same instruction on D0-D3 and A0-A1 only (dense data flow between few registers)."""
    ops = []
    for op in ins.operands:
        if op.mode is Mode.DREG:
            op = dataclasses.replace(op, reg=op.reg & 3)
        elif op.mode in (Mode.AIND, Mode.APOSTINC, Mode.APREDEC, Mode.ADISP, Mode.AINDEX):
            op = dataclasses.replace(op, reg=op.reg & 1)
        if op.index is not None:
            op = dataclasses.replace(op, index=dataclasses.replace(op.index, num=op.index.num & 3))
        ops.append(op)
    return dataclasses.replace(ins, operands=tuple(ops))


#: Register-only chain instructions (the value layer's), shift counts by register included.
CHAIN = instructions(rows=CHAIN_ROWS, address=oracles.CODE, modes=REG_IMM).map(_four)
#: What observes the registers: memory accesses through A0/A1 (which may be odd or unmapped), DIVU/DIVS and
#: MULU/MULS by a register, ADDX.
OBSERVERS = instructions(rows=["move", "add", "and", "cmp", "tst", "clr", "swap", "ext", "divu", "divs", "mulu",
                               "muls", "addx"],
                         address=oracles.CODE,
                         modes=frozenset({Mode.DREG, Mode.AIND, Mode.APOSTINC, Mode.ADISP, Mode.AINDEX})).filter(
    lambda i: all(op.mode is not Mode.ADISP or -0x40 <= op.value <= 0x40 for op in i.operands)).map(_four)


@st.composite
def chains(draw: st.DrawFn, observers: bool = True) -> list[object]:
    """6..24 items: mostly chain instructions, now and then an observer or a forward Bcc.S over 1..3 items."""
    items: list[object] = []
    for _ in range(draw(st.integers(6, 24))):
        k = draw(st.integers(0, 11))
        if k == 0:
            items.append(("b", "b" + draw(st.sampled_from("hi ls cc cs ne eq vc vs pl mi ge lt gt le".split())),
                          draw(st.integers(1, 3))))
            items.append(draw(CHAIN))  # a Bcc.S needs at least one instruction to skip
        elif k <= 2 and observers:
            items.append(draw(OBSERVERS))
        else:
            items.append(draw(CHAIN))
    return items


def _two(ins: Instruction) -> Instruction:
    """The same instruction on D0 and D1 only (every instruction reads what the one before wrote)."""
    return dataclasses.replace(ins, operands=tuple(dataclasses.replace(op, reg=op.reg & 1) if op.mode is Mode.DREG
                                                   else op for op in ins.operands))


#: Value-layer instructions on D0/D1: those that leave values outside 0..2^32-1 (NEG, NOT, SUB, MULS, EXT.L, ASR,
#: LSL: kept modulo 2^32 with a range) next to those that read a value exactly (narrow writes, compares, SWAP,
#: LSR, logic ops, shifts of shifts).
FOCUS = instructions(rows=["neg", "not", "sub", "subq", "subi", "add", "addq", "muls", "mulu", "ext", "asr", "asl",
                           "lsl", "lsr", "swap", "move", "moveq", "and", "andi", "or", "eor", "cmp", "cmpi", "tst",
                           "clr", "exg"],
                     address=oracles.CODE, modes=REG_IMM).map(_two)
SHIFTS = instructions(rows=["asr", "asl", "lsl", "lsr"], address=oracles.CODE, modes=REG_IMM).map(_two)
#: Branches right after the instruction they test, every condition (compares of equal values included).
CONDS = "hi ls cc cs ne eq vc vs pl mi ge lt gt le".split()
VALUES = st.sampled_from([0, 1, 2, 0x7F, 0x80, 0xFF, 0x7FFF, 0x8000, 0xFFFF, 0x7FFFFFFF, 0x80000000, M32, M32 - 1])


@st.composite
def focused(draw: st.DrawFn) -> list[object]:
    items: list[object] = []
    for _ in range(draw(st.integers(3, 14))):
        items.append(draw(SHIFTS if draw(st.integers(0, 3)) == 0 else FOCUS))
        if draw(st.integers(0, 3)) == 0:
            items.append(("b", "b" + draw(st.sampled_from(CONDS)), 1))
            items.append(draw(FOCUS))
    return items


@settings(max_examples=examples(400, ci=80), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(focused(), VALUES | st.integers(0, M32), VALUES | st.integers(0, M32), st.integers(0, 31))
def test_value_ranges_equal_closures(items: list[object], d0: int, d1: int, ccr: int) -> None:
    """Dense two-register chains of the value layer's instructions (values kept modulo 2^32 and read exactly,
    shifts of shifts, compares of equal values followed by every branch): blocks equal closures."""
    code = layout(items, oracles.CODE) + bytes([0x4E, 0x40])
    image = bytes(oracles.base_image(0, [(oracles.CODE, code)]))
    d = [d0, d1, 0, 0, 0, 0, 0, 0]
    blocks, closures = _run_both(image, d, [0x6000] * 7 + [0x6F00], ccr, {})
    assert blocks == closures


@settings(max_examples=examples(50, ci=15), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(focused(), VALUES | st.integers(0, M32), VALUES | st.integers(0, M32), st.integers(0, 31),
       st.integers(0, 1 << 30))
def test_value_ranges_vs_m68000py(items: list[object], d0: int, d1: int, ccr: int, seed: int) -> None:
    """The same chains against m68000-python."""
    code = layout(items, oracles.CODE)
    m = machine(code, seed, [d0, d1, 0, 0, 0, 0, 0, 0], ccr)
    end = oracles.CODE + len(code)
    ours, ref = ours_blocks(m, end, 200), ref_run(m, end, 200)
    assert ours == ref, f"{_diff(ours, ref)}\n  code {code.hex(' ')} d0={d0:#x} d1={d1:#x} ccr={ccr:#x}"


@settings(max_examples=examples(300, ci=60), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(chains(), st.lists(st.sampled_from(EDGE) | st.integers(0, M32), min_size=8, max_size=8),
       st.integers(0, 31), st.integers(0, 1 << 30), st.integers(1, 40), st.integers(1, 900), st.integers(0, 40),
       st.sampled_from([0x6000, 0x6001, 0x6FFE, 0x1FFFE, 0x20000, 0xFFFFFE]))
def test_value_chains_equal_closures(items: list[object], d: list[int], ccr: int, seed: int, max_n: int,
                                     max_c: int, until_k: int, a0: int) -> None:
    """Chains with faulting observers (odd/unmapped A0, DIVU by zero), forward branches, random limits and
    until_pc: blocks (value layer on) and closures leave everything identical."""
    image, a = code_image(layout(items, oracles.CODE), seed, a0)
    blocks, closures = _run_both(image, d, a, ccr, random_limits(seed, max_n, max_c, until_k))
    assert blocks == closures


def code_image(code: bytes, seed: int, a0: int) -> tuple[bytes, list[int]]:
    """The memory image with ``code`` (and a TRAP #0 after it) at CODE and random data, and the address registers:
    A0 = ``a0``, A1 somewhere in the data, A2-A6 at its start, A7 near its top."""
    rng = random.Random(seed)
    image = bytes(oracles.base_image(seed, [(oracles.CODE, code + bytes([0x4E, 0x40]))]))
    return image, [a0, oracles.DATA_LO + 2 * rng.randrange(0, 0x400)] + [oracles.DATA_LO] * 5 + [0x6F00]


def random_limits(seed: int, max_n: int, max_c: int, until_k: int) -> dict[str, object]:
    """``run`` keywords: the instruction and clock limits, ``until_pc`` at the ``until_k``-th word of the code
    (none from 30 on), ``stop_at_limit`` from the seed's low bit."""
    until = oracles.CODE + 2 * until_k if until_k < 30 else None
    return dict(max_instructions=max_n, max_cycles=max_c, until_pc=until, stop_at_limit=bool(seed & 1))


@settings(max_examples=examples(50, ci=15), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(chains(), st.lists(st.sampled_from(EDGE) | st.integers(0, M32), min_size=8, max_size=8),
       st.integers(0, 31), st.integers(0, 1 << 30))
def test_value_chains_vs_m68000py(items: list[object], d: list[int], ccr: int, seed: int) -> None:
    """The same chains against m68000-python: registers, CCR, memory, clocks, instruction count, fault kind (fewer
    examples: m68000-python is the slow side; the closures test above draws more)."""
    code = layout(items, oracles.CODE)
    m = machine(code, seed, d, ccr)
    end = oracles.CODE + len(code)
    ours, ref = ours_blocks(m, end, 200), ref_run(m, end, 200)
    assert ours == ref, f"{_diff(ours, ref)}\n  code {code.hex(' ')} d={[hex(v) for v in d]} ccr={ccr:#x}"


def _block_text(src: str) -> str:
    """The generated source of the block at CODE for ``src`` (the value layer on)."""
    from isa import blocks

    seen: list[str] = []
    orig = blocks._block_source

    def spy(*args: object, **kw: object):
        r = orig(*args, **kw)  # type: ignore[arg-type]  # a spy forwards the arguments unchanged
        seen.append(r[0])
        return r

    prog = isa.assemble(src, filename="v.s", origin=oracles.CODE)
    cpu = oracles.make_cpu(isa)
    cpu.write_bytes(oracles.CODE, prog.code)
    cpu.pc = oracles.CODE
    codecache.clear()
    saved_disk = codecache.disk_dir  # another test in this process (the firmware harness) may have turned the disk
    codecache.use_disk(None)         # code cache on: a block found there is not generated, so the spy would not see it
    blocks._block_source = spy
    try:
        cpu.run(max_instructions=1000)
    finally:
        blocks._block_source = orig
        codecache.use_disk(saved_disk)
    return seen[0]


MULG = """
 move.l d6,d5
 swap d5
 muls #18879,d5
 move.l d6,d0
 mulu #18879,d0
 swap d0
 ext.l d0
 add.l d5,d0
 asr.l #6,d0
 add.l d0,d1
 move.l d1,$6000
 moveq #0,d0
 moveq #0,d5
 lsr.l #1,d7
 trap #0
"""


def test_value_layer_is_used() -> None:
    """Not vacuous: the firmware's gain multiply (10 register-only instructions; D0 and D5 overwritten after the
    write, the flags by the LSR) is one statement before the write (D1's value, which the write stores); with the
    layer off, one or more statements per instruction."""
    text = _block_text(MULG)
    body = [ln.strip() for ln in text.splitlines() if ln.startswith("        ") and "= R[" not in ln
            and not ln.strip().startswith(("R[", "return", "c = ", "ni = "))]
    before_write = body[: next(i for i, ln in enumerate(body) if "F32" in ln or "PL(" in ln or "wl(" in ln)]
    assert len(before_write) == 1 and "18879" in before_write[0], before_write
    block_codegen.SYMBOLIC = False
    try:
        plain = _block_text(MULG)
    finally:
        block_codegen.SYMBOLIC = True
    assert plain.count("\n") > text.count("\n") + 8


def test_fault_in_the_middle_of_a_chain_sees_every_register() -> None:
    """Pending values of D0, D1 and D2 (SWAP, EXT, shifts, MOVEQ, ADD) must be in the registers when the MOVE.W
    from an odd address faults, and the chain after it must not have run."""
    src = (" moveq #-3,d2\n move.l d3,d0\n swap d0\n ext.l d0\n lsl.l #3,d0\n add.l d2,d1\n move.w (a0),d3\n"
           " asr.l #2,d0\n moveq #1,d1\n trap #0\n")
    prog = isa.assemble(src, filename="f.s", origin=oracles.CODE)
    image = bytes(oracles.base_image(0, [(oracles.CODE, prog.code)]))
    d = [0x11111111, 0x22222222, 0, 0x8765ABCD, 0, 0, 0, 0]
    blocks, closures = _run_both(image, d, [0x6001] + [0x6000] * 6 + [0x6F00], 0, {})
    assert blocks == closures
    assert blocks[0] == "AddressError"
    regs = blocks[4]
    assert regs[0] == (((0x8765 - 0x10000) << 3) & M32) and regs[1] == 0x2222221F and regs[2] == M32 - 2


def test_exg_cycle_and_partial_writes() -> None:
    """EXG of two pending values (a cycle: one tuple assignment), byte/word merges into pending values, and a
    non-faulting instruction the layer does not take (MULU by a register) in the middle; then an exit."""
    src = (" move.l d1,d0\n add.l d2,d0\n move.l d2,d1\n eor.l d0,d1\n exg d0,d1\n move.b d3,d0\n add.w d0,d1\n"
           " mulu d1,d2\n not.b d2\n swap d2\n exg d2,d3\n trap #0\n")
    prog = isa.assemble(src, filename="e.s", origin=oracles.CODE)
    image = bytes(oracles.base_image(0, [(oracles.CODE, prog.code)]))
    for d in ([0x12345678, 0x9ABCDEF0, 0x0FEDCBA9, 0x80000001, 0, 0, 0, 0], [M32] * 8, [0] * 8):
        blocks, closures = _run_both(image, d, [0x6000] * 7 + [0x6F00], 0, {})
        assert blocks == closures
    text = _block_text(src)
    assert "d0, d1 = " in text or "d1, d0 = " in text or text.count("_y") > 0


def test_pending_values_at_a_write_into_other_compiled_code() -> None:
    """A constant write into code before the block (the block at CODE+2, compiled by the second run; the NOP at
    CODE decoded by the first) cannot fault and cannot rewrite the block, but its generated slow path leaves the
    block when it hits compiled code: D0's pending value (MOVE.B from a constant address, ADD) must be in D0 there.
    Found by test_isa_blocks.py::test_flow_blocks_equal_closures (D0 was left unassigned)."""
    src = f" nop\n move.b $6000,d0\n add.l d1,d0\n lsr.w ${oracles.CODE:X}\n moveq #1,d2\n trap #0\n"
    prog = isa.assemble(src, filename="w.s", origin=oracles.CODE)
    image = bytes(oracles.base_image(3, [(oracles.CODE, prog.code)]))
    d = [0x12345600, 0x100, 0, 0, 0, 0, 0, 0]
    blocks, closures = _run_both(image, d, [0x6000] * 7 + [0x6F00], 0, dict(max_instructions=1, stop_at_limit=True))
    assert blocks == closures


def test_compare_flags_before_every_branch() -> None:
    """CMP/CMPI of every size, each condition's branch right after it and an ADD that sets all flags after that (so
    only the flags the condition reads are live at the compare: C alone, Z alone, or more), over values with equal,
    adjacent and sign-edge pairs: blocks and closures take the same branches and leave the same registers."""
    values = [0, 1, 0x7F, 0x80, 0x7FFF, 0x8000, 0xFFFF, 0x7FFFFFFF, 0x80000000, M32]
    for size in "bwl":
        for cc in CONDS:
            for form in (f"cmp.{size} d1,d0", f"cmpi.{size} #$80,d0"):
                src = f" {form}\n b{cc}.s over\n moveq #1,d2\nover: add.l d3,d3\n trap #0\n"
                prog = isa.assemble(src, filename="c.s", origin=oracles.CODE)
                for d0 in values:
                    for d1 in (values if form.startswith("cmp.") else [0]):
                        out = []
                        for blocks in (True, False):
                            cpu = oracles.make_cpu(isa)
                            cpu.block_compile = blocks
                            cpu.write_bytes(oracles.CODE, prog.code)
                            cpu.d[0], cpu.d[1], cpu.d[3] = d0, d1, 0x80000000
                            cpu.pc = oracles.CODE
                            res = cpu.run(max_instructions=100)
                            out.append((tuple(cpu.d), cpu.sr, res.cycles, res.instructions))
                        assert out[0] == out[1], (form, cc, hex(d0), hex(d1))


#: Value-layer instructions on D0 that leave a value outside 0..2^32-1 or with a narrow range (kept modulo 2^32).
PRODUCERS = ["neg.l d0", "not.l d0", "sub.l d1,d0", "subq.l #1,d0", "add.l d1,d0", "muls #-3,d0", "muls d1,d0",
             "mulu #3,d0", "ext.l d0", "ext.w d0", "asr.l #3,d0", "lsl.l #4,d0", "lsr.l #5,d0", "swap d0",
             "andi.l #$7FFF,d0", "move.w d1,d0", "moveq #-2,d0", "clr.w d0", "eor.l d1,d0"]
#: ... and instructions that read D0 exactly, narrowly or by shifting it again.
READERS = ["move.w d1,d0", "move.b d1,d0", "add.w d1,d0", "sub.b d1,d0", "andi.w #$F0F0,d0", "or.w d1,d0",
           "eori.b #$81,d0", "ext.w d0", "ext.l d0", "swap d0", "lsr.l #3,d0", "asr.l #2,d0", "lsl.l #1,d0",
           "asl.l #2,d0", "cmp.w d1,d0", "cmpi.l #$80000000,d0", "tst.l d0", "tst.b d0", "clr.w d0", "not.w d0",
           "neg.b d0", "mulu #3,d0", "muls #-3,d0", "mulu d0,d1", "add.l d0,d1", "move.l d0,d1", "exg d0,d1"]


def twin_cpus() -> list[isa.CPU]:
    """Two CPUs with the oracles' RAM map: compiled blocks on (first) and the per-instruction closures (second)."""
    cpus = []
    for blocks in (True, False):
        cpu = oracles.make_cpu(isa)
        cpu.block_compile = blocks
        cpus.append(cpu)
    return cpus


def test_every_producer_before_every_reader() -> None:
    """Each range-producing instruction then each reader of the same register (plus shifts of shifts of every
    kind), with the flags after them dead (an ADD.L D2,D2 sets all five) and live (a TRAP right after: all live
    at the exit): blocks and closures leave the same registers, SR, clocks and counts, over sign-edge values."""
    values = [0, 1, 0x7FFF, 0x8000, 0xFFFF, 0x7FFFFFFF, 0x80000000, M32]
    shifts = [f"{k}.l #{n},d0" for k in ("asl", "asr", "lsl", "lsr") for n in (1, 3, 8)]
    pairs = [(p, q) for p in PRODUCERS for q in READERS] + [(p, q) for p in shifts for q in shifts]
    cpus = twin_cpus()
    at = oracles.CODE
    for p, q in pairs:
        for tail in (" add.l d2,d2\n", ""):
            at += 0x20  # each program at its own address (code rewritten in place twice is no longer compiled)
            prog = isa.assemble(f" {p}\n {q}\n{tail} trap #0\n", filename="p.s", origin=at)
            for cpu in cpus:
                cpu.write_bytes(at, prog.code)
            for d0 in values:
                for d1 in values[::3]:
                    out = []
                    for cpu in cpus:
                        cpu.d[0], cpu.d[1], cpu.d[2] = d0, d1, 0x80000000
                        cpu.sr = 0x2700
                        cpu.pc = at
                        res = cpu.run(max_instructions=100)
                        out.append((tuple(cpu.d), cpu.sr, res.cycles, res.instructions))
                    assert out[0] == out[1], (p, q, tail, hex(d0), hex(d1))
    compiled = sum(e[0] is not None for e in cpus[0]._blocks.values())
    assert at + 0x20 < oracles.EXCLUDED_LO and compiled >= 2 * len(pairs)  # every program ran as a block

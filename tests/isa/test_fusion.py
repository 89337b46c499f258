"""Flag/branch fusion in generated blocks (``isa.block_codegen._BlockGen.fuse_setup``).

When the N/Z/V/C an instruction sets are read only by the Bcc right after it (none of them live after the branch
on either path), the block assigns no flag: the branch tests the value or compares the operands itself
(``if not (d0 := (d7 & 16)):`` instead of ``sr = ...`` and ``if sr & 4:``). X and any flag live after the
branch must be what they were (X is kept by MOVE/TST/AND/CMP...; an ADD/SUB still assigns it when it is live).

These tests put every value-layer flag setter right before a Bcc of every condition, with what follows the branch
on either path observing the flags or not: nothing (an ADD.L that sets all five), X (ADDX/SUBX/NEGX/ROXL), other
flags (Scc, another Bcc), a fault (a read through an odd or unmapped A0), a block exit; with random instruction
and cycle limits and ``until_pc``; and compare with the per-instruction closures (everything, fault messages
included) and m68000-python (registers, CCR, memory, clocks, counts). Deterministic cases pin each fused pattern:
the flags at a fault after a fused compare, at every instruction limit, at ``until_pc``, across a loop's back
edge, X kept; and the generated text shows that fusion happens where it may and not where a flag is live.
"""

from __future__ import annotations

import dataclasses

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import isa
from isa.encoder import encode
from isa.operands import Instruction, Mode, Operand, Size
from isa.strategies import instructions
from tests.support.profiles import examples

from tests.support import oracles
from tests.isa.test_blocks import EDGE, M32, _diff, _run_both, layout, machine, ours_blocks, ref_run
from tests.isa.test_value_layer import OBSERVERS, _block_text, _four, code_image, random_limits, twin_cpus

REG_IMM = frozenset({Mode.DREG, Mode.IMM})
CONDS = "hi ls cc cs ne eq vc vs pl mi ge lt gt le".split()

#: Every value-layer instruction that sets N/Z/V/C from a register (or an immediate), on D0-D3.
SETTERS = instructions(rows=["move", "moveq", "add", "addi", "addq", "sub", "subi", "subq", "and", "andi", "or",
                             "ori", "eor", "eori", "cmp", "cmpi", "tst", "not", "neg", "clr", "ext", "swap", "mulu",
                             "muls", "asr", "lsr", "lsl"],
                       address=oracles.CODE, modes=REG_IMM).map(_four)
#: ... and the same from a constant address (MOVE/CMP/TST/ADD/AND of a word or long in the data region).
CONST_SETTERS = instructions(rows=["move", "cmp", "tst", "add", "sub", "and", "or"], address=oracles.CODE,
                             modes=frozenset({Mode.DREG, Mode.ABSW, Mode.ABSL}),
                             absolute=st.integers(oracles.DATA_LO // 2, (oracles.DATA_HI - 8) // 2).map(
                                 lambda v: 2 * v)).filter(
    lambda i: i.operands[-1].mode is Mode.DREG).map(_four)
#: What may follow a branch: flags overwritten (ADD.L D3,D3 sets all five), X read, other flags read, more setters.
KILL = instructions(rows=["add"], address=oracles.CODE, modes=frozenset({Mode.DREG})).map(
    lambda i: dataclasses.replace(i, size=isa.operands.Size.L,
                                  operands=tuple(dataclasses.replace(o, reg=3) for o in i.operands)))
X_READERS = instructions(rows=["addx", "subx", "negx", "roxl", "roxr"], address=oracles.CODE,
                         modes=frozenset({Mode.DREG, Mode.IMM})).map(_four)
FLAG_READERS = instructions(rows=["scc"], address=oracles.CODE, modes=frozenset({Mode.DREG})).map(_four)


def _layout(items: list[object], origin: int) -> bytes:
    """:func:`test_isa_blocks.layout`, plus ("back", cond): a Bcc.S back to the first item (a loop's back edge)."""
    if not items or not isinstance(items[-1], tuple) or items[-1][0] != "back":
        return layout(items, origin)
    body = layout(items[:-1], origin)
    at = origin + len(body)
    return body + encode(Instruction("b" + items[-1][1], Size.S, (Operand(Mode.ABSL, value=origin),)), at)


@st.composite
def fused_pairs(draw: st.DrawFn) -> list[object]:
    """4..12 units; most are a flag setter right before a forward Bcc.S (any condition) over 1..3 items, then
    whatever observes the flags or not on either path; a third of the programs end in a setter and a Bcc.S back
    to the start (a loop: every flag is live after its back edge)."""
    items: list[object] = []
    after = st.one_of(KILL, KILL, X_READERS, FLAG_READERS, SETTERS, OBSERVERS)
    for _ in range(draw(st.integers(4, 12))):
        k = draw(st.integers(0, 5))
        if k <= 3:
            items.append(draw(CONST_SETTERS if k == 3 else SETTERS))
            items.append(("b", "b" + draw(st.sampled_from(CONDS)), draw(st.integers(1, 3))))
            items.append(draw(after))
        else:
            items.append(draw(after))
    if draw(st.integers(0, 2)) == 0:
        items.append(draw(SETTERS))
        items.append(("back", draw(st.sampled_from(CONDS))))
    return items


@settings(max_examples=examples(300, ci=40), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(fused_pairs(), st.lists(st.sampled_from(EDGE) | st.integers(0, M32), min_size=8, max_size=8),
       st.integers(0, 31), st.integers(0, 1 << 30), st.integers(1, 40), st.integers(1, 900), st.integers(0, 40),
       st.sampled_from([0x6000, 0x6001, 0x6FFE, 0x1FFFE, 0x20000]))
def test_fused_branches_equal_closures(items: list[object], d: list[int], ccr: int, seed: int, max_n: int,
                                       max_c: int, until_k: int, a0: int) -> None:
    """Setters before branches, flags observed after them or not, faults, limits and until_pc: blocks (fusion on)
    and closures leave everything identical (registers, SR, PC, memory, counters, fault class, message, PC)."""
    image, a = code_image(_layout(items, oracles.CODE), seed, a0)
    blocks, closures = _run_both(image, d, a, ccr, random_limits(seed, max_n, max_c, until_k))
    assert blocks == closures
    if isinstance(items[-1], tuple) and items[-1][0] == "back":  # a loop: every instruction limit, so that some
        # run stops right where the block leaves at the head after its back edge (SR seen as it is there)
        for n in range(1, 41):
            blocks, closures = _run_both(image, d, a, ccr, dict(max_instructions=n, stop_at_limit=True))
            assert blocks == closures, n


@settings(max_examples=examples(60, ci=15), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(fused_pairs(), st.lists(st.sampled_from(EDGE) | st.integers(0, M32), min_size=8, max_size=8),
       st.integers(0, 31), st.integers(0, 1 << 30))
def test_fused_branches_vs_m68000py(items: list[object], d: list[int], ccr: int, seed: int) -> None:
    """The same programs against m68000-python: registers, CCR, memory, clocks, instruction count, fault kind."""
    code = _layout(items, oracles.CODE)
    m = machine(code, seed, d, ccr)
    end = oracles.CODE + len(code)
    ours, ref = ours_blocks(m, end, 150, upto=True), ref_run(m, end, 150, upto=True)
    assert ours == ref, f"{_diff(ours, ref)}\n  code {code.hex(' ')} d={[hex(v) for v in d]} ccr={ccr:#x}"


VALUES = [0, 1, 0x7F, 0x80, 0xFF, 0x7FFF, 0x8000, 0xFFFF, 0x7FFFFFFF, 0x80000000, M32]
#: Setters and the conditions they fuse with (every condition is run; these are the forms the generator fuses).
PAIRS = ["cmp.l d1,d0", "cmp.w d1,d0", "cmpi.b #$80,d0", "cmpi.l #-880,d0", "tst.l d0", "tst.w d0", "tst.b d0",
         "and.w d1,d0", "andi.l #$80000010,d0", "or.b d1,d0", "eor.l d1,d0", "move.l d1,d0", "move.w d1,d0",
         "not.w d0", "ext.l d0", "ext.w d0", "swap d0", "muls #-3,d0", "mulu d1,d0", "addq.l #1,d0", "add.w d1,d0",
         "sub.l d1,d0", "subq.b #1,d0", "addi.l #$7FFFFFFF,d0"]


def _run(src: str, d: list[int], ccr: int, blocks: bool, **kw: object) -> tuple[object, ...]:
    prog = isa.assemble(src, filename="f.s", origin=oracles.CODE)
    cpu = oracles.make_cpu(isa)
    cpu.block_compile = blocks
    cpu.write_bytes(oracles.CODE, prog.code)
    for i, v in enumerate(d):
        cpu.d[i] = v
    cpu.a[0] = 0x6001  # odd: a word read through A0 faults
    cpu.sr = 0x2700 | ccr
    cpu.pc = oracles.CODE
    try:
        res = cpu.run(**kw)  # type: ignore[arg-type]  # **kw of mixed run() argument types
        out: tuple[object, ...] = ("ok", res.instructions, res.cycles)
    except isa.errors.CPUFault as exc:
        out = (type(exc).__name__, str(exc), exc.pc)
    return out + (tuple(cpu.d), cpu.sr, cpu.pc, cpu.instructions, cpu.cycles)


def _both(src: str, d: list[int], ccr: int, **kw: object) -> tuple[object, ...]:
    a, b = _run(src, d, ccr, True, **kw), _run(src, d, ccr, False, **kw)
    assert a == b, (src, [hex(v) for v in d], ccr, kw)
    return a


@pytest.mark.parametrize("tail", ["kill", "x", "xz", "fault_taken", "fault_fall", "exit", "flags"])
def test_every_setter_before_every_branch(tail: str) -> None:
    """Each setter, each condition's branch right after it, and after the branch: flags overwritten on both paths
    (fused), X read on both paths (ROXL/ROXR: fused; X kept or assigned; ADDX/SUBX also read Z: not fused), a fault
    on the taken or the fall-through path (flags live: not fused, SR at the fault exact), an exit right after (not
    fused), other flags read (Scc, not fused), over sign-edge values and X set and clear: blocks equal closures
    (registers, SR, PC, counters, fault)."""
    after = {"kill": (" add.l d3,d3\n", " add.l d3,d3\n"),
             "x": (" roxl.l #1,d2\n", " roxr.w #1,d2\n"),
             "xz": (" addx.l d3,d2\n", " subx.b d3,d2\n"),
             "fault_taken": (" add.l d3,d3\n", " move.w (a0),d2\n"),
             "fault_fall": (" move.w (a0),d2\n", " add.l d3,d3\n"),
             "exit": ("", ""),
             "flags": (" sgt d2\n", " svs d2\n")}[tail]
    cpus = twin_cpus()
    at = oracles.CODE
    for p in PAIRS:
        for cc in CONDS:
            at += 0x20  # each program at its own address (code rewritten in place twice is no longer compiled)
            src = f" {p}\n b{cc}.s over\n{after[0]} moveq #1,d4\n bra.w out\nover:\n{after[1]}out: trap #0\n"
            prog = isa.assemble(src, filename="s.s", origin=at)
            for cpu in cpus:
                cpu.write_bytes(at, prog.code)
            for d0 in VALUES[::2] if tail != "kill" else VALUES:
                for d1 in VALUES[::3]:
                    for ccr in (0x00, 0x1F):
                        out = []
                        for cpu in cpus:
                            for i, v in enumerate((d0, d1, 0x5555, 0x80000000, 0, 0, 0, 0)):
                                cpu.d[i] = v
                            cpu.a[0] = 0x6001  # odd: a word read through A0 faults
                            cpu.sr = 0x2700 | ccr
                            cpu.pc = at
                            try:
                                res = cpu.run(max_instructions=100)
                                o: tuple[object, ...] = ("ok", res.instructions, res.cycles)
                            except isa.errors.CPUFault as exc:
                                o = (type(exc).__name__, str(exc), exc.pc)
                            out.append(o + (tuple(cpu.d), cpu.sr, cpu.pc))
                        assert out[0] == out[1], (src, hex(d0), hex(d1), ccr)
    compiled = sum(e[0] is not None for e in cpus[0]._blocks.values())
    assert at + 0x20 < oracles.EXCLUDED_LO and compiled >= len(PAIRS) * len(CONDS)  # every program ran as blocks


def test_fusion_happens_only_where_the_flags_are_dead() -> None:
    """Not vacuous, and the liveness is honoured: with the flags overwritten on both paths the compare, the AND,
    the TST and the SUBQ assign no N/Z/V/C (the branch tests the values); with a flag read after the branch, or a
    fault that may see SR, they do; an ADD/SUB whose X is read after the branch assigns X (and C) only."""
    text = _block_text(" cmp.l d1,d0\n bgt.s a\n add.l d3,d3\na: add.l d3,d3\n trap #0\n")
    assert text.count("sr = (") == 1 and "if sr" not in text and "if not sr" not in text, text  # only ADD.L's
    assert "- 2147483648) > ((d1 ^ 2147483648) - 2147483648)" in text or "- 2147483648) <= ((d1" in text, text
    text = _block_text(" moveq #16,d0\n and.w d7,d0\n bne.s a\n add.l d3,d3\na: add.l d3,d3\n trap #0\n")
    assert "(d0 := (d7 & 16))" in text and text.count("sr = (") == 1, text
    text = _block_text(" tst.w d2\n bmi.s a\n add.l d3,d3\na: add.l d3,d3\n trap #0\n")
    assert "if (d2 & 65535) < 32768:" in text and text.count("sr = (") == 1, text
    text = _block_text(" subq.w #1,d0\n bne.s a\n add.l d3,d3\na: add.l d3,d3\n trap #0\n")
    assert text.count("sr = (") == 1, text
    text = _block_text(" subq.w #1,d0\n bne.s a\n roxl.l #1,d3\na: roxr.l #1,d3\n trap #0\n")
    assert "sr = (sr & 0xFF0E) | (17 if" in text, text  # X and C only; Z tested by the branch
    text = _block_text(" subq.w #1,d0\n bne.s a\n addx.l d3,d3\na: add.l d3,d3\n trap #0\n")
    assert "sr = (sr & 0xFF02) | (17 if" in text, text  # ADDX reads Z too: X, C, N/Z assigned
    for live in (" cmp.l d1,d0\n bgt.s a\n scs d2\na: add.l d3,d3\n trap #0\n",  # C read on the fall-through
                 " cmp.l d1,d0\n bgt.s a\n add.l d3,d3\na: trap #0\n",  # every flag live at the exit
                 " and.w d7,d0\n bne.s a\n move.w (a0),d1\na: add.l d3,d3\n trap #0\n"):  # a fault sees SR
        text = _block_text(live)
        assert "sr = (sr & 0xFF10) |" in text or "sr = (sr & 0xFF1" in text, (live, text)
        assert "if sr" in text or "if not sr" in text or "if (sr" in text, (live, text)


def test_flags_at_a_fault_after_a_fused_compare() -> None:
    """A fused compare, then (with the flags dead) a read through an odd A0: SR at the fault is the one before the
    compare with the later ADD's flags not yet set; and a compare whose flags a fault on the taken path can see
    (not fused): SR there has the compare's flags. Checked by value, not only against the closures."""
    src = " cmp.l d1,d0\n beq.s a\n add.l d3,d3\na: moveq #0,d5\n add.l d3,d3\n move.w (a0),d2\n trap #0\n"
    out = _both(src, [5, 5, 0, 1, 0, 0, 0, 0], 0x1B)
    assert out[0] == "AddressError" and out[2] == oracles.CODE + 10 and out[-4] & 0x1F == 0x00  # ADD.L 1+1: clear
    src = " cmp.l d1,d0\n beq.s a\n add.l d3,d3\na: move.w (a0),d2\n trap #0\n"
    out = _both(src, [5, 5, 0, 1, 0, 0, 0, 0], 0x10)
    assert out[0] == "AddressError" and out[-4] & 0x1F == 0x14  # taken: the CMP's Z (X kept)
    out = _both(src, [6, 5, 0, 1, 0, 0, 0, 0], 0x11)
    assert out[0] == "AddressError" and out[-4] & 0x1F == 0x00  # not taken: the ADD.L's (1+1: all clear)


def test_fused_branches_at_every_limit_and_until_pc() -> None:
    """A straight block of fused pairs (CMP, AND, TST, SUBQ with X read later) stopped by every instruction limit,
    every 7th cycle limit and until_pc at every instruction: blocks equal closures (SR included)."""
    src = (" cmp.l d1,d0\n bls.s a\n addq.l #1,d2\na: moveq #8,d4\n and.w d7,d4\n beq.s b\n add.l d3,d3\n"
           "b: tst.l d2\n bpl.s c\n not.l d2\nc: subq.w #1,d7\n bne.s e\n moveq #3,d5\ne: roxl.l #1,d6\n"
           " add.l d3,d3\n trap #0\n")
    prog = isa.assemble(src, filename="l.s", origin=oracles.CODE)
    for d in ([7, 3, 0x80000000, 1, 0, 0, 0, 0x18], [3, 7, 5, 1, 0, 0, 0, 1], [0, 0, M32, 0x80000000, 0, 0, 0, 0]):
        for ccr in (0x00, 0x10, 0x1F):
            for n in range(1, 20):
                _both(src, d, ccr, max_instructions=n, stop_at_limit=True)
            for c in range(4, 200, 7):
                _both(src, d, ccr, max_cycles=c, stop_at_limit=True)
            for k in range(0, len(prog.code), 2):
                _both(src, d, ccr, until_pc=oracles.CODE + k, max_instructions=100)
    text = _block_text(src)
    assert text.count("sr = (") == 2 and "if sr" not in text and "if not sr" not in text, text  # the SUBQ's X
    # and C (ROXL reads X) and the last ADD's (before the exit); every branch tests a value


def test_fused_compare_inside_a_loop_and_at_its_back_edge() -> None:
    """A fused compare inside a loop (its flags dead: SUBQ sets them all before the back edge) and a compare at the
    back edge (every flag live there: the budget or until_pc may end the loop at the head and see SR): every
    instruction limit, until_pc at every instruction, X set and clear; blocks equal closures."""
    for src in (" moveq #5,d0\ntop: cmp.l d1,d2\n beq.s s\n addq.l #1,d3\ns: subq.l #1,d0\n bne.s top\n trap #0\n",
                " moveq #5,d0\ntop: addq.l #1,d3\n subq.l #1,d0\n cmp.l d1,d0\n bne.s top\n trap #0\n",
                " moveq #5,d0\ntop: tst.w d2\n bmi.s s\n addq.l #1,d3\ns: addq.l #1,d2\n dbra d0,top\n trap #0\n"):
        prog = isa.assemble(src, filename="p.s", origin=oracles.CODE)
        text = _block_text(src)
        assert "while True" in text, text
        for d in ([0, 2, 2, 0, 0, 0, 0, 0], [0, 1, 2, 0, 0, 0, 0, 0], [0, 0, 0xFFFE, 0, 0, 0, 0, 0]):
            for ccr in (0x00, 0x1F):
                for n in range(1, 40):
                    _both(src, d, ccr, max_instructions=n, stop_at_limit=True)
                for k in range(0, len(prog.code), 2):
                    _both(src, d, ccr, until_pc=oracles.CODE + k, max_instructions=200)


def test_x_is_kept_by_fused_setters() -> None:
    """X set by an ADD, then fused TST/CMP/AND/MOVE before branches, then ADDX reads X on both paths: X must be
    the ADD's (checked by value: D5 = D5 + D6 + X)."""
    for setter in ("tst.l d2", "cmp.l d1,d2", "and.w d1,d2", "move.l d1,d2", "ext.l d2", "swap d2"):
        for cc in ("eq", "ne", "mi", "pl", "gt", "le"):
            src = f" add.l d0,d0\n {setter}\n b{cc}.s a\n addx.l d6,d5\n bra.s b\na: addx.l d6,d5\nb: trap #0\n"
            for x in (0, 1):
                out = _both(src, [0x80000000 if x else 1, 0x8001, 0x7F, 0, 0, 10, 20, 0], 0)
                assert out[3][5] == 30 + x, (setter, cc, x, out)

"""Clock counts against the M68000 User's Manual (UM, section 8: Tables 8-1 .. 8-10; zero wait states).

Expected numbers are read off the manual's tables by hand (cited per case). Data-dependent DIVU/DIVS counts,
for which the manual gives only maxima, are checked against m68000-python (an independent implementation checked
against hardware-derived vectors) and against the manual's maxima.
"""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

import isa
from isa.cpu import CPU
from isa.decoder import decode_bytes
from isa.timing import cycle_range, cycles, divs_cycles, divu_cycles, muls_cycles, mulu_cycles

ORG = 0x1000


def instr(src: str) -> isa.Instruction:
    prog = isa.assemble(" " + src + "\n", origin=ORG)
    return decode_bytes(prog.code, ORG, ORG).instruction


def clocks(src: str, **regs: int) -> int:
    """Clocks of one instruction as the interpreter counts them (registers preset from ``regs``)."""
    cpu = CPU()
    cpu.load(isa.assemble(" " + src + "\n", origin=ORG))
    cpu.a[7] = 0x8000
    for name, value in regs.items():
        getattr(cpu, name[0])[int(name[1])] = value
    for i in range(7):
        if f"a{i}" not in regs:
            cpu.a[i] = 0x3000
    return cpu.step()


# UM Table 8-2 (MOVE.B/.W) and 8-3 (MOVE.L): rows = source, columns = destination.
MOVE_CASES = [
    ("move.w d0,d1", 4), ("move.w d0,(a1)", 8), ("move.w d0,-(a1)", 8), ("move.w d0,4(a1)", 12),
    ("move.w d0,4(a1,d2.w)", 14), ("move.w d0,$4000.w", 12), ("move.w d0,$12000", 16),
    ("move.w (a0),d1", 8), ("move.w (a0)+,(a1)+", 12), ("move.w -(a0),d1", 10), ("move.w 2(a0),4(a1)", 20),
    ("move.w 2(a0,d0.l),d1", 14), ("move.w $12000,$13000", 28), ("move.w #5,d1", 8), ("move.w #5,(a1)", 12),
    ("move.b 2(pc),d1", 12), ("move.l d0,d1", 4), ("move.l d0,(a1)", 12), ("move.l d0,-(a1)", 12),
    ("move.l (a0),d1", 12), ("move.l -(a0),-(a1)", 22), ("move.l 2(a0),4(a1)", 28), ("move.l #5,d1", 12),
    ("move.l $12000,$13000", 36), ("movea.w d0,a1", 4), ("movea.l (a0),a1", 12), ("movea.l #1,a1", 12),
]


@pytest.mark.parametrize(("src", "expected"), MOVE_CASES)
def test_move_table(src: str, expected: int) -> None:
    assert cycles(instr(src)) == expected
    assert clocks(src) == expected


# UM Table 8-4 (standard instructions; + EA time from Table 8-1; ** = 8 for register direct or immediate)
STANDARD = [
    ("add.l d0,d1", 8), ("add.l a0,d1", 8), ("add.w d0,d1", 4), ("add.l (a0),d1", 14), ("add.w (a0),d1", 8),
    ("add.l #1000,d1", 16), ("add.w d1,(a0)", 12), ("add.l d1,(a0)", 20), ("add.l d1,-(a0)", 22),
    ("sub.l d0,d1", 8), ("sub.b 4(a0),d1", 12), ("and.l d0,d1", 8), ("or.w d1,(a0)+", 12), ("eor.l d1,d2", 8),
    ("eor.w d1,d2", 4), ("eor.l d1,(a0)", 20), ("cmp.l d0,d1", 6), ("cmp.w d0,d1", 4), ("cmp.l (a0),d1", 14),
    ("cmpa.w d0,a1", 6), ("cmpa.l (a0),a1", 14), ("adda.w d0,a1", 8), ("adda.l d0,a1", 8), ("adda.l (a0),a1", 14),
    ("adda.w (a0),a1", 12), ("suba.l #4,a1", 16),
    # Table 8-5 immediate
    ("addi.w #1,d1", 8), ("addi.l #1,d1", 16), ("addi.w #1,(a0)", 16), ("addi.l #1,(a0)", 28),
    ("andi.l #1,d1", 16), ("cmpi.l #1,d1", 14), ("cmpi.w #1,(a0)", 12), ("cmpi.l #1,(a0)", 20),
    ("subi.b #1,d1", 8), ("eori.l #1,4(a0)", 32), ("ori.w #1,d1", 8),
    ("addq.w #1,d1", 4), ("addq.l #1,d1", 8), ("addq.w #1,a1", 8), ("addq.l #1,a1", 8), ("addq.w #1,(a0)", 12),
    ("subq.l #8,(a0)", 20), ("moveq #1,d1", 4),
    # Table 8-6 single operand
    ("clr.l d1", 6), ("clr.w d1", 4), ("clr.w (a0)", 12), ("clr.l (a0)", 20), ("neg.l d1", 6), ("negx.b (a0)+", 12),
    ("not.w d1", 4), ("tst.l d1", 4), ("tst.l (a0)", 12), ("tst.w -(a0)", 10),
    # Table 8-7 shifts: 6+2n / 8+2n; memory 8 + EA
    ("asl.w #1,d1", 8), ("asr.l #8,d1", 24), ("lsl.b #3,d1", 12), ("roxr.l #2,d1", 12), ("rol.w (a0)", 12),
    ("lsr.w 4(a0)", 16),
    # Table 8-9
    ("jmp (a0)", 8), ("jmp 4(a0)", 10), ("jmp $12000", 12), ("jsr (a0)", 16), ("jsr 2(pc)", 18), ("jsr $12000", 20),
    ("lea (a0),a1", 4), ("lea 4(a0,d0.w),a1", 12), ("lea $12000,a1", 12), ("pea (a0)", 12), ("pea $2000.w", 16),
    ("movem.l d0-d3,-(a7)", 8 + 8 * 4), ("movem.w d0/a0,(a1)", 8 + 4 * 2), ("movem.l (a7)+,d0-d3", 12 + 8 * 4),
    ("movem.w 4(a0),d0-d7", 16 + 4 * 8), ("movem.l $12000,d0/d1", 20 + 8 * 2),
    # Table 8-10 misc, 8-11 multiprecision
    ("ext.w d0", 4), ("ext.l d0", 4), ("swap d0", 4), ("exg d0,a0", 6), ("nop", 4),
    ("addx.l d0,d1", 8), ("addx.w d0,d1", 4), ("subx.b -(a0),-(a1)", 18), ("addx.l -(a0),-(a1)", 30),
    ("cmpm.b (a0)+,(a1)+", 12), ("cmpm.w (a0)+,(a1)+", 12), ("cmpm.l (a0)+,(a1)+", 20),  # Table 8-4: 12(3/0), 20(5/0)
]


@pytest.mark.parametrize(("src", "expected"), STANDARD)
def test_standard_tables(src: str, expected: int) -> None:
    assert cycles(instr(src)) == expected
    assert clocks(src) == expected


def test_register_shift_counts_modulo_64() -> None:
    # UM Table 8-7: 6+2n (.B/.W), 8+2n (.L), n = Dn mod 64
    assert clocks("lsl.w d0,d1", d0=3) == 6 + 6
    assert clocks("asr.l d0,d1", d0=63) == 8 + 126
    assert clocks("ror.l d0,d1", d0=64 + 5) == 8 + 10
    assert clocks("roxl.b d0,d1", d0=0) == 6
    assert cycle_range(instr("lsl.w d0,d1")) == (6, 6 + 126)


def test_branches() -> None:
    # UM Table 8-8: Bcc taken 10, not taken 8 (.S) 12 (.W); BRA 10; BSR 18; DBcc 12 / 10 / 14
    beq_s, beq_w = instr("beq.s *+4"), instr("beq.w *+4")
    assert (cycles(beq_s, taken=True), cycles(beq_s, taken=False)) == (10, 8)
    assert (cycles(beq_w, taken=True), cycles(beq_w, taken=False)) == (10, 12)
    assert cycle_range(beq_s) == (8, 10) and cycle_range(beq_w) == (10, 12)
    assert cycles(instr("bra.s *+4")) == 10 and cycles(instr("bsr.w *+4")) == 18
    db = instr("dbne d0,*")
    assert (cycles(db, taken=False), cycles(db, taken=True), cycles(db, expired=True)) == (12, 10, 14)
    assert cycle_range(db) == (10, 14)
    assert cycle_range(instr("seq d0")) == (4, 6) and cycles(instr("seq (a0)")) == 12
    assert cycles(instr("rts")) == 16


def test_mul_counts() -> None:
    # UM Table 8-4 note: MULU 38+2n, n = ones of the source; MULS 38+2n, n = 01/10 edges of source<<1
    assert mulu_cycles(0) == 38 and mulu_cycles(0xFFFF) == 70 and mulu_cycles(0x0101) == 42
    assert muls_cycles(0) == 38
    assert muls_cycles(0x5555) == 70  # 0_1010_1010_1010_1010 (17 bits): 16 edges
    assert muls_cycles(0xFFFF) == 40  # 1_1111_1111_1111_1110: one edge
    assert muls_cycles(0x8000) == 40  # 1_0000_0000_0000_0000: one edge
    assert clocks("mulu.w (a0),d1") == 38 + 4  # memory of zeros + (An) EA
    assert clocks("muls.w #$5555,d1") == 70 + 4
    assert cycle_range(instr("mulu.w d0,d1")) == (38, 70)


def test_div_counts_within_manual_bounds() -> None:
    # UM Table 8-4 gives maxima 140 (DIVU) / 158 (DIVS) for the register forms.
    assert divu_cycles(0x00100000, 1) == 10  # overflow is found first
    assert divu_cycles(0, 1) == 136 and divu_cycles(0xFFFE, 0xFFFF) <= 140
    assert divs_cycles(0x00100000, 1) == 16 and divs_cycles(-0x100000, 1) == 18  # overflow
    assert cycle_range(instr("divu.w d0,d1")) == (10, 136) and cycle_range(instr("divs.w (a0),d1")) == (20, 160)


@given(st.integers(0, 2**32 - 1), st.integers(1, 0xFFFF))
def test_div_ranges(dividend: int, divisor: int) -> None:
    u = divu_cycles(dividend, divisor)
    assert u == 10 or 76 <= u <= 136
    s = divs_cycles(dividend, divisor)
    assert s in (16, 18) or 120 <= s <= 156


try:
    from m68000_python._alu import divide_signed_clocks, divide_unsigned_clocks

    HAVE_REF = True
except ImportError:  # pragma: no cover
    HAVE_REF = False


@pytest.mark.skipif(not HAVE_REF, reason="m68000-python not installed")
@given(st.integers(0, 2**32 - 1), st.integers(1, 0xFFFF))
def test_div_counts_match_m68000_python(dividend: int, divisor: int) -> None:
    assert divu_cycles(dividend, divisor) == divide_unsigned_clocks(dividend, divisor)
    sd = dividend - (1 << 32) if dividend & 0x80000000 else dividend
    sv = divisor - 0x10000 if divisor & 0x8000 else divisor
    assert divs_cycles(dividend, divisor) == divide_signed_clocks(sd, sv)


def test_cycle_range_is_exact_for_fixed_instructions() -> None:
    assert cycle_range(instr("move.l (a0)+,4(a1)")) == (24, 24)  # UM Table 8-3: (An)+ row, d16(An) column
    assert cycle_range(instr("add.l d0,d1")) == (8, 8)

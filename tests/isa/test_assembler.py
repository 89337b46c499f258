"""Tests of :mod:`isa.assembler` (and the listing/S-record helpers of :mod:`isa.listing`).

Expected bytes are hand-assembled in the test from the opcode maps of the M68000 Programmer's Reference Manual
(section 8, instruction formats): each opcode word is written as its bit fields (``w("0011 000 000 111 001")``)
so the derivation can be checked against the manual, never by calling our encoder.
"""

from __future__ import annotations

import random
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from isa.assembler import assemble
from isa.errors import AssemblyError
from isa.listing import format_listing, to_binary, to_srec
from isa.operands import Mode
from tests.support.profiles import examples


def w(bits: str) -> bytes:
    """A 16-bit opcode word from its bit fields written MSB first (spaces separate fields)."""
    b = bits.replace(" ", "")
    assert len(b) == 16, bits
    return int(b, 2).to_bytes(2, "big")


def h(hexstr: str) -> bytes:
    """Extension words written in hex (spaces ignored)."""
    return bytes.fromhex(hexstr.replace(" ", ""))


def code(src: str, **kw: object) -> bytes:
    return assemble(src, **kw).code  # type: ignore[arg-type]  # **kw of mixed assemble() argument types


def err(src: str, **kw: object) -> AssemblyError:
    with pytest.raises(AssemblyError) as info:
        assemble(src, **kw)  # type: ignore[arg-type]  # **kw of mixed assemble() argument types
    return info.value


def where(e: AssemblyError) -> str:
    return f"{e.file}:{e.line}:{e.col}"


# --- the Schultz 2002 listing -----------------------------------------------------------------------------------------

SEED = """\
* Schultz 2002 pseudo-listing (with the EQUs it assumes)
ESTALT  equ $2000
ADCCNT  equ $2004
 move.l ESTALT, D0 ; Get a copy of the old altitude estimate
 shr.l #5, D0  ; divide it by 32
 move.l ADCCNT, D1 ; get a scratch copy of the new ADC count
 shl.l #3, D1  ;  shift it left 3 bits to line up the binary points
 sub.l D1, D0  ; subtract ADCCNT from ESTALT
 add.l D0, ESTALT ; update altitude estimate
"""


def test_seed_listing_encodes_with_alias_warnings() -> None:
    prog = assemble(SEED, filename="seed.s")
    expected = (
        w("00 10 000 000 111 001") + h("0000 2000")  # MOVE.L abs.L,D0 (size 10 = long, dest Dn mode 000)
        + w("1110 101 0 10 0 01 000")  # LSR.L #5,D0: count 5, dr=0 right, size 10, i/r=0, type 01 = LS
        + w("00 10 001 000 111 001") + h("0000 2004")  # MOVE.L abs.L,D1
        + w("1110 011 1 10 0 01 001")  # LSL.L #3,D1: dr=1 left
        + w("1001 000 0 10 000 001")  # SUB.L D1,D0: opmode 010 = <ea>-Dn -> Dn, long
        + w("1101 000 1 10 111 001") + h("0000 2000")  # ADD.L D0,abs.L: opmode 110 = Dn+<ea> -> <ea>
    )  # fmt: skip
    assert prog.code == expected
    assert prog.warnings == [
        "seed.s:5:2: warning: 'shr' is not a 68000 mnemonic; assembled as 'lsr'",
        "seed.s:7:2: warning: 'shl' is not a 68000 mnemonic; assembled as 'lsl'",
    ]


# --- no silent rewrites ---------------------------------------------------------------------------------------


def test_written_form_is_encoded() -> None:
    assert code(" move.l #1,d3") == w("00 10 011 000 111 100") + h("0000 0001")  # MOVE, not MOVEQ
    assert code(" moveq #1,d3") == w("0111 011 0 00000001")
    assert code(" moveq #-1,d0") == w("0111 000 0 11111111")
    assert code(" add.l #1,d0") == w("1101 000 0 10 111 100") + h("0000 0001")  # ADD <ea>,Dn with #imm
    assert code(" addq.l #1,d0") == w("0101 001 0 10 000 000")
    assert code(" addi.w #1,d0") == w("00000110 01 000 000") + h("0001")
    assert code(" cmp.l #0,d0") == w("1011 000 0 10 111 100") + h("0000 0000")
    # byte immediate: low byte of the extension word; the high byte is the sign extension as GNU as writes it
    assert code(" cmpi.b #-1,d0") == w("00001100 00 000 000") + h("FFFF")
    assert code(" cmpi.b #$FF,d0") == w("00001100 00 000 000") + h("00FF")


def test_address_register_destination_uses_the_a_form() -> None:
    assert code(" move.l d0,a1") == w("00 10 001 001 000 000")  # MOVEA.L
    assert code(" movea.w d0,a1") == w("00 11 001 001 000 000")
    assert code(" add.l d0,a0") == w("1101 000 1 11 000 000")  # ADDA.L: opmode 111
    assert code(" sub.w d1,a2") == w("1001 010 0 11 000 001")  # SUBA.W: opmode 011
    assert code(" cmp.l a0,a1") == w("1011 001 1 11 001 000")  # CMPA.L


def test_case_insensitive_and_default_word_size() -> None:
    assert code(" MOVE.W D0,D1") == code(" move.w d0,d1") == w("00 11 001 000 000 000")
    assert code(" move d0,d1") == w("00 11 001 000 000 000")  # no suffix: .W (Motorola default)
    assert code(" Clr.B (A0)") == w("01000010 00 010 000")


# --- numbers and expressions ------------------------------------------------------------------------------------


def test_number_bases_and_characters() -> None:
    assert code(" dc.b $1F,%101,@17,10,'A',0x7f") == h("1F 05 0F 0A 41 7F")
    assert code(" dc.w 'AB'") == b"AB"
    assert code(" dc.l 'ABCD',-1") == b"ABCD" + h("FFFF FFFF")
    assert code(" dc.b 'it''s',\"x\",0") == b"it's" + b"x\x00"


def test_expression_operators_and_precedence() -> None:
    src = " dc.w 2+3*4,(2+3)*4,1<<4|1,7/2,-7/2,-7%2,~0&$FF,6^3,-(-3),%1100>>2,5-2-1,3>2,2==3"
    expected = [14, 20, 17, 3, -3, -1, 255, 5, 3, 3, 2, 1, 0]
    assert code(src) == b"".join((v & 0xFFFF).to_bytes(2, "big") for v in expected)


def test_current_location() -> None:
    prog = assemble(" org $100\nhere equ *\n dc.l *,*+4\n dc.w *-here", origin=0)
    assert prog.symbol("here").address == 0x100
    assert prog.segments[0].origin == 0x100
    # '*' is the address of the start of the statement, for every item of a DC
    assert prog.segments[0].data == h("0000 0100 0000 0104 0008")


def test_forward_references_and_equ_chains() -> None:
    src = "A equ B+1\nB equ C*2\nC equ 5\n move.w #A,d0\n bra fwd\n nop\nfwd nop"
    assert code(src) == (
        w("00 11 000 000 111 100") + h("000B")  # MOVE.W #11,D0
        + w("0110 0000 00000000") + h("0004")  # BRA.W: disp = fwd - (pc+2) = 10 - 6
        + w("0100111001110001") * 2
    )  # fmt: skip


def test_set_is_redefinable_equ_is_not() -> None:
    assert code("X set 1\n dc.b X\nX set X+1\n dc.b X\nY = 7\n dc.b Y") == h("01 02 07")
    e = err("X equ 1\nX equ 2")
    assert where(e) == "<source>:2:1" and "duplicate symbol 'X'" in e.message


def test_defines_preset_symbols() -> None:
    assert code(" dc.w N*2", defines={"N": 21}) == h("002A")
    assert code(" ifd FAST\n dc.b 1\n else\n dc.b 2\n endif", defines={"FAST": 0}) == h("01")
    assert code(" ifnd FAST\n dc.b 1\n endif\n dc.b 3") == h("01 03")


# --- labels ---------------------------------------------------------------------------------------------------


def test_labels_with_and_without_colon_and_indented() -> None:
    prog = assemble("a nop\nb: nop\n   c: nop\nd\n nop")
    assert [prog.symbol(n).address for n in "abcd"] == [0, 2, 4, 6]


def test_local_labels_are_scoped_to_the_previous_global() -> None:
    src = "first: moveq #0,d0\n.loop bra.s .loop\nsecond: nop\n.loop bra.s .loop\n1$ bra.s 1$"
    prog = assemble(src)
    assert prog.code == (
        w("0111 000 0 00000000") + w("0110 0000 11111110")  # BRA.S to itself: disp -2
        + w("0100111001110001") + w("0110 0000 11111110") + w("0110 0000 11111110")
    )  # fmt: skip
    assert prog.symbol("first.loop").address == 2
    assert prog.symbol("second.loop").address == 6


def test_symbol_sizes_and_sections() -> None:
    src = """\
        section code
init:   nop
.x      nop
step:   rts
        section bss
est:    ds.l 1
flags:  ds.w 1
buf:    ds.b 3
"""
    prog = assemble(src, origin=0x400)
    assert prog.symbol("init").size == 4  # up to the next global label (locals do not cut it)
    assert prog.symbol("init.x").size == 2
    assert prog.symbol("step").size == 2
    est = prog.symbol("EST")  # case-insensitive lookup
    assert (est.address, est.section, est.size) == (0x406, "bss", 4)
    assert prog.symbol("flags").size == 2 and prog.symbol("buf").size == 3


# --- data and layout directives -----------------------------------------------------------------------------------


def test_dc_ds_dcb_even_align() -> None:
    src = " dc.b 1\n even\n dc.w $1234\n ds.b 3\n even\n dcb.w 2,$ABCD\n dc.b 9\n align 4\nend4 dc.l 1"
    prog = assemble(src)
    assert prog.code == h("01 00 1234 000000 00 ABCD ABCD 09 000000 00000001")
    assert prog.symbol("end4").address == 16


def test_sections_layout_data_after_code_bss_after_data() -> None:
    src = " section data\ndat1 dc.b 1,2,3\n section bss\nb1 ds.w 2\n text\nc1 nop\n data\ndat2 dc.b 4"
    prog = assemble(src, origin=0x1000)
    segs = {s.name: s for s in prog.segments}
    assert (segs["code"].origin, segs["code"].data) == (0x1000, w("0100111001110001"))
    assert (segs["data"].origin, segs["data"].data) == (0x1002, h("01020304"))
    assert (segs["bss"].origin, segs["bss"].data, segs["bss"].bss) == (0x1006, bytes(4), True)
    assert prog.symbol("b1").address == 0x1006 and prog.symbol("dat2").address == 0x1005


def test_org_places_code() -> None:
    prog = assemble(" org $2000\nstart nop\n bra.s start", origin=0x1000)
    assert prog.origin == 0x2000
    assert prog.code == w("0100111001110001") + w("0110 0000 11111100")
    assert prog.symbol("start").address == 0x2000


def test_overlapping_org_blocks_are_an_error() -> None:
    e = err(" nop\n nop\n org 2\n nop")
    assert "overlap" in e.message


# --- addressing modes -----------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("operand", "ea", "ext"),
    [
        ("d3", "000 011", ""),
        ("a3", "001 011", ""),
        ("(a3)", "010 011", ""),
        ("(a3)+", "011 011", ""),
        ("-(a3)", "100 011", ""),
        ("-4(a3)", "101 011", "FFFC"),
        ("(-4,a3)", "101 011", "FFFC"),
        ("2(a3,d1.w)", "110 011", "1002"),  # brief word: D/A=0 reg=001 W/L=0, disp 02
        ("2(a3,a1.l)", "110 011", "9802"),  # D/A=1 reg=001 W/L=1
        ("(a3,d1)", "110 011", "1000"),
        ("$1234", "111 001", "0000 1234"),  # abs.L unless written .w
        ("$1234.w", "111 000", "1234"),
        ("($1234).w", "111 000", "1234"),
        ("($FFFF8000).w", "111 000", "8000"),
        ("$1234.l", "111 001", "0000 1234"),
        ("#-2", "111 100", "FFFE"),
    ],
)
def test_source_addressing_modes(operand: str, ea: str, ext: str) -> None:
    # MOVE.W <ea>,D0: 00 11 000 000 <mode reg>
    assert code(f" move.w {operand},d0") == w("00 11 000 000 " + ea) + h(ext)


def test_pc_relative_and_sp() -> None:
    prog = assemble(" move.w tab(pc),d0\n move.w tab(pc,d1.w),d0\n lea (tab,pc),a0\ntab dc.w 0\n")
    assert prog.code == (
        w("00 11 000 000 111 010") + h("000A")  # d16(PC): tab(12) - ext word address(2)
        + w("00 11 000 000 111 011") + h("1006")  # d8(PC,D1.W): 12 - 6
        + w("0100 000 111 111 010") + h("0002")  # LEA d16(PC),A0: 12 - 10
        + h("0000")
    )  # fmt: skip
    assert code(" move.l d0,-(sp)") == w("00 10 111 100 000 000")  # SP = A7


def test_pc_relative_with_plain_number_is_target_with_warning() -> None:
    prog = assemble(" lea $10(pc),a0")
    assert prog.code == w("0100 000 111 111 010") + h("000E")
    assert prog.warnings and "target address $000010" in prog.warnings[0]


def test_movem_register_lists() -> None:
    assert code(" movem.l d0-d2/a0,-(sp)") == w("01001 0 001 1 100 111") + h("E080")  # reversed mask
    assert code(" movem.l (sp)+,d0-d2/a0") == w("01001 1 001 1 011 111") + h("0107")
    assert code(" movem.w d3,-(a1)") == w("01001 0 001 0 100 001") + h("1000")  # single register
    assert code(" movem.l a6/d7/a0-a1,(a2)") == w("01001 0 001 1 010 010") + h("4380")


# --- branches ---------------------------------------------------------------------------------------------------


def test_branch_sizes_and_aliases() -> None:
    src = "top nop\n bra top\n bra.s top\n bra.b top\n bhs.s top\n blo.w top\n dbf d1,top\n dbra d1,top\n bsr top"
    assert code(src) == (
        w("0100111001110001")
        + w("0110 0000 00000000") + h("FFFC")  # BRA.W at 2: 0 - 4
        + w("0110 0000 11111000")  # BRA.S at 6: 0 - 8
        + w("0110 0000 11110110")  # BRA.B = .S at 8: 0 - 10
        + w("0110 0100 11110100")  # BHS = BCC (0100) at 10: 0 - 12
        + w("0110 0101 00000000") + h("FFF2")  # BLO = BCS (0101) .W at 12: 0 - 14
        + w("0101 0001 11001 001") + h("FFEE")  # DBF = DBRA D1 at 16: 0 - 18
        + w("0101 0001 11001 001") + h("FFEA")
        + w("0110 0001 00000000") + h("FFE6")  # BSR.W at 24: 0 - 26
    )  # fmt: skip


def test_branch_errors() -> None:
    e = err(" bra.s next\nnext nop")
    assert where(e) == "<source>:1:8" and "displacement" in str(e).lower()
    far = " bra.s far\n dcb.b 200,0\nfar nop"
    e = err(far)
    assert where(e) == "<source>:1:8" and "away" in str(e).lower()
    e = err(" bra.w far\n dcb.b 40000,0\nfar nop")
    assert where(e) == "<source>:1:8" and "away" in str(e).lower()


# --- macros, conditionals, includes ---------------------------------------------------------------------------------


def test_macros_positional_named_size_and_unique_labels() -> None:
    src = """\
zero    macro
        moveq #0,\\1
        endm
        macro   addto, val, reg
        add.\\0 #\\val,\\reg
        endm
wait    macro
.w\\@   dbra \\1,.w\\@
        endm
start:  zero d2
        addto.w 3,d1
        wait d0
        wait d1
"""
    prog = assemble(src)
    assert prog.code == (
        w("0111 010 0 00000000")
        + w("1101 001 0 01 111 100") + h("0003")  # ADD.W #3,D1
        + w("0101 0001 11001 000") + h("FFFE")  # DBRA D0 to itself
        + w("0101 0001 11001 001") + h("FFFE")
    )  # fmt: skip
    locals_ = [n for n in prog.symbols if n.startswith("start.w_")]
    assert len(locals_) == 2 and locals_[0] != locals_[1]


def test_conditionals_nested_with_else() -> None:
    src = """\
MODE equ 2
 if MODE==1
  dc.b 1
 else
  ifeq MODE-2
   dc.b 2
   if 0
    dc.b 99
    garbage line that is never parsed ((
   endif
  else
   dc.b 3
  endif
 endif
 ifne MODE
  dc.b 4
 endc
"""
    assert code(src) == h("02 04")


def test_include_relative_then_include_paths(tmp_path: Path) -> None:
    (tmp_path / "src").mkdir()
    (tmp_path / "inc").mkdir()
    (tmp_path / "src" / "local.inc").write_text("LOCALV equ 7\n include 'deep.inc'\n")
    (tmp_path / "src" / "deep.inc").write_text(" dc.b LOCALV\n")
    (tmp_path / "inc" / "lib.inc").write_text("libfn: dc.b 9\n")
    main = tmp_path / "src" / "main.s"
    main.write_text(' include "local.inc"\n include <lib.inc>\n')
    prog = assemble(main.read_text(), filename=str(main), include_paths=[tmp_path / "inc"])
    assert prog.code == h("07 09")
    files = {ln.source.file for ln in prog.listing}
    assert str(tmp_path / "src" / "deep.inc") in files


def test_end_stops_and_include_path_may_be_a_single_directory(tmp_path: Path) -> None:
    (tmp_path / "one.inc").write_text(" dc.b 1\n")
    prog = assemble(' include "one.inc"\n dc.b 2\n end\n this is not assembled', include_paths=str(tmp_path))
    assert prog.code == h("01 02")


def test_align_and_even_rules() -> None:
    assert where(err(" align 3")) == "<source>:1:8"
    assert code(" dc.b 1\n align 1\n dc.b 2") == h("01 02")
    prog = assemble(" section bss\n ds.b 1\n even\nw ds.w 1")
    assert prog.symbol("w").address == 2 and prog.segments[0].data == bytes(4)


# --- errors with exact positions ----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("src", "pos", "fragment"),
    [
        (" nop\n fooz d0", "<source>:2:2", "unknown mnemonic 'fooz'"),
        (" lea d0,a0", "<source>:1:6", "cannot encode"),
        (" move.l d0,#3", "<source>:1:12", "operand 2 mode #imm not allowed"),
        (" lea 4(a0),d1", "<source>:1:12", "cannot encode"),
        (" move.w 40000(a0),d0", "<source>:1:9", "displacement 40000 out of range"),
        (" moveq #200,d0", "<source>:1:8", "cannot encode"),
        (" addq.w #9,d0", "<source>:1:9", "cannot encode"),
        (" move.l nothere,d0", "<source>:1:9", "undefined symbol 'nothere'"),
        ("x nop\nx nop", "<source>:2:1", "duplicate symbol 'x'"),
        ("m macro\n nop\n", "<source>:1:1", "unterminated MACRO"),
        (" nop\n if 1\n nop\n", "<source>:2:2", "unterminated IF"),
        (" endm", "<source>:1:2", "ENDM without MACRO"),
        (" endif", "<source>:1:2", "ENDIF without IF"),
        (" else", "<source>:1:2", "ELSE without IF"),
        (' include "nowhere.inc"', "<source>:1:10", "cannot find INCLUDE file 'nowhere.inc'"),
        (" dc.w 1+", "<source>:1:9", "expected an expression"),
        (" dc.w (1", "<source>:1:9", "expected ')'"),
        (" dc.w 4/(2-2)", "<source>:1:8", "division by zero"),
        (" move.q d0,d1", "<source>:1:7", "bad size suffix '.q'"),
        (" bra.l x\nx nop", "<source>:1:6", "bad size suffix '.l'"),
        (" lea.w x,a0\nx nop", "<source>:1:6", "bad size suffix '.w'"),
        (" dc.b 256", "<source>:1:7", "out of range"),
        (" dc.w -32769", "<source>:1:7", "out of range"),
        (" dc.b 1\n dc.w 2", "<source>:2:2", "odd address"),
        (" dc.b 1\n nop", "<source>:2:2", "odd address"),
        (" ds.w fwd\nfwd equ 2", "<source>:1:7", "must be defined before"),
        (" dc.b 'abc", "<source>:1:7", "unterminated string"),
        ("d0 nop", "<source>:1:1", "register name"),
        ("nop", "<source>:1:1", "taken as a label"),
        (" move.l d0,sr", "<source>:1:12", "not supported"),
        (" section rodata", "<source>:1:10", "unknown section"),
        (" section bss\n nop", "<source>:2:2", "bss"),
        (" section bss\n dc.b 1", "<source>:2:2", "bss"),
        ("x equ x+1\n dc.b x", "<source>:1:1", "does not converge"),
        (" fail too small", "<source>:1:2", "FAIL: too small"),
    ],
)
def test_error_positions(src: str, pos: str, fragment: str) -> None:
    e = err(src)
    assert where(e) == pos, str(e)
    assert fragment in e.message, str(e)
    # str(): "file:line:col: message", the line, and a caret under the column
    lines = str(e).splitlines()
    assert lines[0] == f"{pos}: {e.message}"
    assert lines[2].index("^") - 4 == e.col - 1


def test_error_in_macro_names_the_body_line_and_the_call() -> None:
    src = "m macro\n nop\n move.l \\1,d0\n endm\n nop\n m undefined_sym\n"
    e = err(src, filename="prog.s")
    assert where(e) == "prog.s:3:9"
    assert "undefined symbol 'undefined_sym'" in e.message and "called at prog.s:6" in e.message


def test_error_in_include_names_the_included_file(tmp_path: Path) -> None:
    (tmp_path / "bad.inc").write_text(" nop\n\n  bogus d0\n")
    main = tmp_path / "main.s"
    e = err(' include "bad.inc"', filename=str(main))
    assert (e.file, e.line, e.col) == (str(tmp_path / "bad.inc"), 3, 3)


def test_include_recursion(tmp_path: Path) -> None:
    (tmp_path / "a.inc").write_text(' include "b.inc"\n')
    (tmp_path / "b.inc").write_text(' include "a.inc"\n')
    e = err(' include "a.inc"', filename=str(tmp_path / "main.s"))
    assert (e.file, e.line) == (str(tmp_path / "b.inc"), 1) and "include recursion" in e.message


def test_recursive_macro_is_a_short_error_naming_macro_depth_and_first_call() -> None:
    e = err("m macro\n m\n endm\n nop\n m\n", filename="rec.s")
    assert where(e) == "rec.s:2:2"
    assert "macro 'm'" in e.message and "64 levels" in e.message and "rec.s:5" in e.message
    assert str(e).count("rec.s:2") <= 2 and len(str(e)) < 200, str(e)  # not the call repeated 64 times


def test_mutually_recursive_macros_name_the_outermost_call() -> None:
    e = err("a macro\n b\n endm\nb macro\n a\n endm\n nop\n a\n", filename="rec.s")
    assert "64 levels" in e.message and "'a' at rec.s:8" in e.message and len(str(e)) < 200, str(e)


def test_error_deep_in_nested_macros_names_few_calls() -> None:
    src = "".join(f"m{i} macro\n m{i + 1}\n endm\n" for i in range(10)) + "m10 macro\n bogus\n endm\n m0\n"
    e = err(src, filename="n.s")
    assert "unknown mnemonic 'bogus'" in e.message
    assert "in macro 'm10' called at n.s:29" in e.message and "in macro 'm0' called at n.s:34" in e.message
    assert "8 more macro levels" in e.message and e.message.count("called at") == 3


def test_non_utf8_byte_gives_file_line_col(tmp_path: Path) -> None:
    from isa.assembler import decode_source

    with pytest.raises(AssemblyError) as info:
        decode_source(b" nop\r\n nop ; caf\xe9 \xe0 la\n trap #0\n", "latin.s")
    e = info.value
    assert (e.file, e.line, e.col) == ("latin.s", 2, 11) and "$E9" in e.message and "UTF-8" in e.message
    # ... also inside an INCLUDE file
    (tmp_path / "l1.inc").write_bytes(b" nop\n\n ; \xa9 1987\n")
    e = err(' nop\n include "l1.inc"\n', filename=str(tmp_path / "main.s"))
    assert (e.file, e.line, e.col) == (str(tmp_path / "l1.inc"), 3, 4) and "$A9" in e.message


def test_line_numbers_count_only_real_line_ends() -> None:
    # A form feed (old listings' page break) or U+2028 inside a comment is not a line end for an editor.
    e = err(" nop ; page\x0c break\n nop ; \u2028\r\n bogus\n", filename="ff.s")
    assert where(e) == "ff.s:3:2" and "unknown mnemonic 'bogus'" in e.message
    assert assemble("\ufeff nop\n").code == w("0100 1110 0111 0001")  # a UTF-8 byte-order mark is dropped


def _calls_to_assemble(src: str) -> int:
    """Python and builtin function calls made while assembling ``src`` (a count of work, immune to load)."""
    import sys

    count = [0]

    def prof(frame: object, event: str, arg: object) -> None:
        if event in ("call", "c_call"):
            count[0] += 1

    sys.setprofile(prof)
    try:
        assemble(src)
    finally:
        sys.setprofile(None)
    return count[0]


def test_assembler_work_is_linear_in_labels() -> None:
    # Issue 8.5: symbol sizes compared every label with every other (5 k labels 6 s, 40 k over 300 s). Doubling
    # the number of labelled lines must about double the work, not quadruple it.
    one, two = (_calls_to_assemble("".join(f"l{i}: nop\n" for i in range(n))) for n in (1500, 3000))
    assert two / one < 2.3, (one, two)
    lots = "".join(f"l{i}: dc.w l{(i * 7) % 1000}\n" for i in range(1000)) + " section data\nd: dc.l l0\n"
    three, six = (_calls_to_assemble(lots.replace("1000", str(n))) for n in (1000, 2000))
    assert six / three < 2.3, (three, six)


def _symbols_and_segments(src: str) -> object:
    try:
        prog = assemble(src, origin=0x1000)
    except AssemblyError as e:
        return str(e)
    return (prog.segments, prog.symbols, prog.warnings, prog.listing, prog.source_map)


@pytest.mark.parametrize("src", [
    "a: bra.w b\n nop\nb: dc.w c-a\nc equ 5\n",
    " section data\nx: dc.l y\n section code\ny: lea x,a0\n bra y\n section bss\nz: ds.l 3\n",
    " move.l #u,d0\n",  # an error found only by the final pass
    " dc.b 300\n",
    "p: ds.w q\nq equ 2\n",
    "s set 1\ns set s+1\n dc.w s,t\nt equ s*2\n",
    " org $2000\nu: nop\n org $1000\nv: bra u\n dc.w v\n",
    " lea x(pc),a0\nx: nop\n lea 100(pc),a1\n",
])
def test_speculative_final_pass_gives_the_plain_result(src: str, monkeypatch: pytest.MonkeyPatch) -> None:
    import isa.assembler as asm

    fast = _symbols_and_segments(src)
    monkeypatch.setattr(asm, "_SPECULATE", False)
    assert _symbols_and_segments(src) == fast


# --- listing, source map, outputs ---------------------------------------------------------------------------------


def test_listing_cycles_and_source_map() -> None:
    src = "start: muls d1,d0 ; data-dependent\n moveq #3,d0\n section data\nv dc.w 5\n"
    prog = assemble(src, filename="l.s", origin=0x100)
    rows = [ln for ln in prog.listing if ln.address is not None]
    assert [(ln.address, ln.data, ln.cycles) for ln in rows] == [
        (0x100, w("1100 000 111 000 001"), (38, 70)),  # MULS: 38+2n, n = 0..16 (User's Manual 8.4)
        (0x102, w("0111 000 0 00000011"), (4, 4)),
        (0x104, h("0005"), None),
    ]
    assert prog.source_map[0x102].line == 2 and prog.source_map[0x102].file == "l.s"
    assert 0x104 not in prog.source_map
    text = format_listing(prog)
    assert "000100  C1C1" in text and "38-70" in text and "start:" in text
    assert "Symbols:" in text and "$000104" in text


def test_srec_records_and_checksum() -> None:
    prog = assemble(" nop\n rts", origin=0x1000)
    lines = to_srec(prog, header="HDR").splitlines()
    # S1: count = 2 address + 4 data + 1 checksum = 7; sum = 07+10+00+4E+71+4E+75 = 0x199 -> ~0x99 = 0x66
    assert lines[1] == "S107" + "1000" + "4E714E75" + "66"
    # S0 header: count 3+3=6, "HDR" = 48 44 52; sum = 06+00+00+48+44+52 = 0xE4 -> 0x1B
    assert lines[0] == "S006000048445" + "21B"
    # S9 entry 1000: count 3; sum = 03+10+00 = 0x13 -> 0xEC
    assert lines[-1] == "S9031000EC"
    wide = to_srec(assemble(" nop", origin=0x12340)).splitlines()
    assert wide[1].startswith("S206012340") and wide[-1].startswith("S804012340")
    for line in lines + wide:  # every record: the byte sum including the checksum is 0xFF
        body = bytes.fromhex(line[2:])
        assert sum(body) & 0xFF == 0xFF and body[0] == len(body) - 1


def test_binary_image_fills_gaps() -> None:
    prog = assemble(" nop\n section data\n dc.b 1\n org $1010\n dc.b 2", origin=0x1000)
    base, image = to_binary(prog)
    assert base == 0x1000 and image == w("0100111001110001") + h("01") + bytes(13) + h("02")


# --- round trip with the formatter (every instruction form) -----------------------------------------------------


def test_every_form_round_trips_through_the_formatter() -> None:
    from isa.encoder import encode
    from isa.formatter import format_instruction
    from isa.strategies import example, forms

    rng = random.Random(1234)
    lines = []
    expected = bytearray()
    addr = 0x1000
    for form in forms():
        instr = example(form, addr, rng)
        data = encode(instr, addr)
        lines.append(" " + format_instruction(instr))
        expected += data
        addr += len(data)
    prog = assemble("\n".join(lines), origin=0x1000)
    got = prog.code
    for i, line in enumerate(lines):  # find the first mismatch for a readable failure
        if got != bytes(expected):
            ln = prog.listing[i]
            off = ln.address - 0x1000
            assert ln.data == bytes(expected[off : off + len(ln.data)]), line
    assert got == bytes(expected)


@given(st.data())
@settings(max_examples=examples(150))
def test_random_instructions_round_trip(data: st.DataObject) -> None:
    from isa.encoder import encode
    from isa.formatter import format_instruction
    from isa.strategies import instructions

    instr = data.draw(instructions(address=0x2000))
    assert assemble(" " + format_instruction(instr), origin=0x2000).code == encode(instr, 0x2000)


# --- fuzz: nothing but AssemblyError, deterministically ---------------------------------------------------------

_PIECES = [
    "move.l", "moveq", "add.w", "bra", "bra.s", "beq", "dbra", "movem.l", "lea", "dc.b", "dc.w", "ds.l", "dcb.w",
    "equ", "set", "=", "org", "even", "align", "section", "macro", "endm", "if", "ifd", "else", "endif", "include",
    "shr.l", "trap", "rts", "nop", "muls", "fail", "end", "text", "bss", "\\1", "\\@",
    "d0", "a7", "sp", "pc", "-(a0)", "(a1)+", "4(a2)", "(a0,d1.w)", "#1", "#$FF", "#-129", "lbl", ".loc", "1$",
    "lbl(pc)", "$1234.w", "(x).l", "d0-d3/a1", "'a'", '"str"', "*", "*+2", "%101", "@17", "1/0", "1<<70",
    ",", "(", ")", ":", ";", "'", "\"", "\\", "$", ".", "+", "-", "*", "/", "~", "#", " ", "  ", "\t",
]  # fmt: skip


def _fuzz_line(draw: st.DrawFn) -> str:
    parts = draw(st.lists(st.sampled_from(_PIECES), max_size=6))
    seps = draw(st.lists(st.sampled_from(["", " ", ","]), min_size=len(parts), max_size=len(parts)))
    lead = draw(st.sampled_from(["", " ", "\t", "lbl ", "x: ", ".l "]))
    junk = draw(st.text(alphabet=st.characters(min_codepoint=32, max_codepoint=126), max_size=4))
    return lead + "".join(p + s for p, s in zip(parts, seps)) + junk


@st.composite
def _fuzz_source(draw: st.DrawFn) -> str:
    return "\n".join(_fuzz_line(draw) for _ in range(draw(st.integers(1, 8))))


def _outcome(src: str) -> tuple[str, object]:
    try:
        prog = assemble(src, origin=0x1000)
    except AssemblyError as e:
        assert e.line >= 0 and e.col >= 0
        return ("error", str(e))
    return ("ok", (tuple((s.name, s.origin, s.data) for s in prog.segments), tuple(prog.warnings)))


@given(_fuzz_source())
@settings(max_examples=examples(300, ci=75))
def test_fuzz_only_assembly_errors_and_deterministic(src: str) -> None:
    first = _outcome(src)
    assert _outcome(src) == first


def test_operand_modes_parse_into_the_contract_types() -> None:
    prog = assemble(" move.w 2(a3,a1.l),(a4)+")
    (line,) = [ln for ln in prog.listing if ln.address is not None]
    assert line.data == w("00 11 100 011 110 011") + h("9802")
    from isa.decoder import decode_bytes  # the decoder reads our bytes back into the same operand model

    instr = decode_bytes(prog.code, 0).instruction
    assert [op.mode for op in instr.operands] == [Mode.AINDEX, Mode.APOSTINC]


# ---------------------------------------------------------------------------------------------------- shared memo
def _clear_shared_memos() -> None:
    import isa.assembler as A

    A.clear_memos()


def test_process_wide_memo_gives_what_a_fresh_process_gives(tmp_path):
    """Assemblies share the per-line memos (fields, tokens, symbol-free operands and values, encodings) across
    define sets: each result equals the same assembly made with empty memos (a fresh process), whatever ran
    before; an INCLUDE file edited in place (same name and size) is read again; an error is never memoised (a
    line that failed raises again, and a line that failed under one define set still assembles under another)."""
    inc = tmp_path / "inc.s"
    inc.write_text("        IF FAST\n        moveq   #GAIN,d0\n        ELSE\n        move.l  #GAIN*3,d0\n"
                   "        ENDIF\n        add.l   #100,d0\nT       dc.w    1,2,-3,$7fff\n")
    src = (f"        include \"{inc}\"\n        lea     T(pc),a0\n        bra.s   *+4\n        nop\n"
           "        dc.l    GAIN,7\n")
    cases = [{"FAST": 1, "GAIN": 5}, {"FAST": 0, "GAIN": 70000}, {"FAST": 1, "GAIN": -8}, {"FAST": 1, "GAIN": 5}]
    fresh = []
    for d in cases:
        _clear_shared_memos()
        fresh.append(assemble(src, defines=d))
    _clear_shared_memos()
    shared = [assemble(src, defines=d) for d in cases]       # memos filled by the earlier define sets
    assert shared == fresh and shared[0].code != shared[1].code and shared[0].code != shared[2].code
    inc.write_text(inc.read_text().replace("#100,d0", "#101,d0"))
    edited = assemble(src, defines=cases[0])
    assert edited.code != shared[0].code and h("0000 0065") in edited.code
    with pytest.raises(AssemblyError, match="out of range"):
        assemble(src, defines={"FAST": 1, "GAIN": 200})       # moveq #200 does not fit
    with pytest.raises(AssemblyError, match="out of range"):
        assemble(src, defines={"FAST": 1, "GAIN": 200})
    assert assemble(src, defines={"FAST": 0, "GAIN": 200}).code == assemble(src, defines={"FAST": 0, "GAIN": 200}).code
    with pytest.raises(AssemblyError, match="undefined symbol 'GAIN'"):
        assemble(src, defines={"FAST": 1})


# ------------------------------------------------------------------------------------------------- compiled lines
def _outcome(src: str, filename: str = "c.s", defines: dict[str, int] | None = None,
             include_paths: tuple[str, ...] = ()) -> object:
    """Everything an assembly gives: the Program's fields (in order) or the error text."""
    try:
        p = assemble(src, filename=filename, origin=0x400, include_paths=include_paths, defines=defines)
    except AssemblyError as e:
        return str(e)
    return (p.segments, p.origin, p.code, list(p.symbols.items()), p.listing, list(p.source_map.items()), p.warnings)


_MAC = "M macro\n move.\\0 \\1,\\2\nl\\@: dc.w l\\@-*\n endm\n"
_COMPILED_CORPUS = [
    _MAC + "s: M.l #K*3,d0\n M.w #-1,d1\n lea 100(pc),a0\n lea s(pc),a1\n lea *+4(pc),a2\n shl.w #1,d0\n"
    " section data\nt: dc.b \"ab\",K,'c'\n even\nu: dc.w u-s,*-t\n dcb.w 2,K\n ds.l K+1\n section bss\n"
    " org $7000\nv: ds.w 2\n section code\n move.w (v).w,d0\n lea t,a0\n bra.s s\n",
    " move.l #1/K,d0\n",                     # division by zero when K = 0: an evaluation error
    " move.l #1<<K2,d0\n",                   # shift count out of range
    " moveq #K2,d0\n",                       # encoding error (out of range) in the final pass only
    " dc.b K2\n",                            # data out of range
    " ds.w L\nL equ 2\n",                    # a layout symbol defined too late
    " move.l #undef,d0\n",                   # undefined symbol
    _MAC + "x: M.l #1,d0\n M.l (a0,d0\n",    # a syntax error inside a macro expansion (macro note)
    "a: nop\n.l: bra.s .l\n1$: dbf d0,1$\nb: lea .m(pc),a0\n.m: rts\n IFD K\n nop\n ELSE\n illegal\n ENDIF\n",
    "s set 1\ns set s+K\n dc.w s,t\nt equ s*2\n movem.l d0,-(a7)\n movem.l (a7)+,a3\n cmp.w (a0)+,(a1)+\n",
    " lea $404(pc,d0.w),a0\n move.l #*,d0\n dc.l *\n",  # a plain number as a PC-relative target: a warning
    " dc.b 300\n",
    " move.l #(1,d0\n", " dc.w ,\n", " dc.w 1,\n", " move.l d0,\n", " dc.b 'a\n", " dcb.w\n", " ds.w 1,2\n",
    " add.w #1,sr\n", " move.l #1+,d0\n", " bra.x l\n", " frob d0\n", " dc.b \"\u0100\"\n",
]


@pytest.mark.parametrize("defines", [{"K": 1, "K2": 5}, {"K": 0, "K2": 200}, {"K": 3, "K2": 70000}])
def test_compiled_lines_give_the_plain_result(defines: dict[str, int], monkeypatch: pytest.MonkeyPatch) -> None:
    """Lines compiled once per process (fields, expressions, operand templates, data items, macro expansions),
    with only the values evaluated per pass, give what the plain path (every line parsed and evaluated in every
    pass) gives: the same Program fields, warnings and errors. Compiled with cold memos, then with memos warmed
    by other define sets."""
    import isa.assembler as A

    _clear_shared_memos()
    compiled = [_outcome(src, defines=defines) for src in _COMPILED_CORPUS]
    warm = [_outcome(src, defines=defines) for src in _COMPILED_CORPUS]
    monkeypatch.setattr(A, "_COMPILE", False)
    _clear_shared_memos()
    plain = [_outcome(src, defines=defines) for src in _COMPILED_CORPUS]
    assert compiled == plain and warm == plain
    assert sum(isinstance(x, str) for x in plain) >= 14 and sum(not isinstance(x, str) for x in plain) >= 3


def test_compiled_lines_give_the_plain_result_for_the_firmware(monkeypatch: pytest.MonkeyPatch) -> None:
    import isa.assembler as A
    from firmware_model.firmware.assemble import ASM_DIR, ROM_START
    from firmware_model.spec.config import BuildConfig
    from firmware_model.spec.build_constants import build_constants

    builds = []
    for program in ("kalman_baro", "kalman_accel", "recursive", "recursive_seed_literal"):
        consts = build_constants(BuildConfig(program=program))
        top = ASM_DIR / f"{program}.s"
        builds.append((top.read_text() + consts.data_source(), str(top), consts.equates()))
    demo = Path(__file__).resolve().parents[2] / "isa" / "demo" / "demo.s"
    builds.append((demo.read_text(), str(demo), {}))

    def run() -> list[object]:
        out = []
        for text, name, equates in builds:
            p = assemble(text, filename=name, origin=ROM_START, include_paths=[str(ASM_DIR)], defines=equates)
            out.append((p.segments, p.code, list(p.symbols.items()), p.listing, list(p.source_map.items()),
                        p.warnings))
        return out

    _clear_shared_memos()
    compiled = run()
    monkeypatch.setattr(A, "_COMPILE", False)
    _clear_shared_memos()
    assert run() == compiled


def test_line_memo_keeps_nothing_of_one_assembly_for_another(tmp_path: Path) -> None:
    """The process-wide memos are keyed by text: the same text under other macros, defines, files and lines
    gives what it gives alone. A macro of the same name with another body, or none; the same text with other
    defines (values are never baked in); the same macro call with another size suffix or arguments; errors the
    second time name the second file and line (and macro call)."""
    _clear_shared_memos()
    call = "        SCALE.w #K,d1\n"
    one = assemble("SCALE macro\n move.\\0 \\1,\\2\n endm\n" + call, defines={"K": 1})
    two = assemble("SCALE macro\n add.\\0 \\1,\\2\n endm\n" + call, defines={"K": 1})
    assert one.code == h("323C 0001") and two.code == h("D27C 0001")     # move.w #1,d1 / add.w #1,d1
    with pytest.raises(AssemblyError) as e:
        assemble("* no macro here\n" + call, filename="n.s", defines={"K": 1})
    assert e.value.message == "unknown mnemonic 'SCALE.w'" and (e.value.file, e.value.line) == ("n.s", 2)
    assert assemble("SCALE macro\n move.\\0 \\1,\\2\n endm\n" + call.replace(".w", ".l"),
                    defines={"K": 1}).code == h("223C 0000 0001")            # \0 = l: move.l #1,d1
    assert assemble("SCALE macro\n move.\\0 \\1,\\2\n endm\n" + call, defines={"K": 9}).code == h("323C 0009")
    assert assemble("SCALE macro\n move.\\0 \\1,\\2\n endm\n" + call.replace("#K,d1", "#7,d2"),
                    defines={"K": 1}).code == h("343C 0007")                 # other arguments: move.w #7,d2
    src = " nop\n dc.w 10/D\n"
    assert assemble(src, defines={"D": 5}).code == h("4E71 0002")
    for name, lead in (("a.s", ""), ("b.s", " nop\n nop\n")):
        with pytest.raises(AssemblyError) as e:
            assemble(lead + src, filename=name, defines={"D": 0})
        assert e.value.message == "division by zero in expression"
        assert (e.value.file, e.value.line, e.value.col) == (name, src.count("\n") + lead.count("\n"), 9)
    bad = "        move.l  #1+,d0\n"
    for name, lead in (("a.s", ""), ("b.s", "* two\n* lines\n")):
        with pytest.raises(AssemblyError) as e:
            assemble(lead + bad, filename=name)
        assert (e.value.file, e.value.line, e.value.col) == (name, lead.count("\n") + 1, 20)
    inc = tmp_path / "m.inc"
    inc.write_text("BAD macro\n move.l #\\1+,d0\n endm\n")
    for k in (3, 5):
        with pytest.raises(AssemblyError) as e:
            assemble(f' include "{inc}"\n' + " nop\n" * (k - 2) + " BAD 1\n", filename="c.s")
        assert (e.value.file, e.value.line) == (str(inc), 2)
        assert e.value.message.endswith(f"(in macro 'BAD' called at c.s:{k})")


def _passes(src: str, monkeypatch: pytest.MonkeyPatch) -> list[bool]:
    """Whether each pass of assembling ``src`` ran as the final one."""
    import isa.assembler as A

    finals: list[bool] = []
    run_pass = A._Assembler._pass

    def counting(self: object) -> None:
        finals.append(self.final)  # type: ignore[attr-defined]  # the patched pass runs on the assembler instance
        run_pass(self)  # type: ignore[arg-type]  # the patched pass runs on the assembler instance

    monkeypatch.setattr(A._Assembler, "_pass", counting)
    assemble(src, origin=0x400)
    monkeypatch.undo()
    return finals


def test_no_final_pass_while_data_labels_move(monkeypatch: pytest.MonkeyPatch) -> None:
    """Pass 1 places data at the origin (the code's end is not known yet): the data labels it defines are wrong,
    so pass 2 cannot be the last and runs as a plain pass; pass 3 is the final one. Labels after an ORG do not
    move, and code-only programs take two passes, as before. The Programs equal the unspeculated ones."""
    import isa.assembler as A

    data = " lea t,a0\n move.w (v).w,d0\n section data\nt: dc.w 1\n section bss\n org $7000\nv: ds.w 1\n"
    placed = " lea t,a0\n section data\n org $6000\nt: dc.w 1\n section bss\n org $7000\nv: ds.w 1\n"
    code = "a: bra b\nb: lea a,a0\n"
    assert _passes(data, monkeypatch) == [False, False, True]
    assert _passes(placed, monkeypatch) == [False, True]
    assert _passes(code, monkeypatch) == [False, True]
    fast = [_symbols_and_segments(src) for src in (data, placed, code)]
    monkeypatch.setattr(A, "_SPECULATE", False)
    assert [_symbols_and_segments(src) for src in (data, placed, code)] == fast

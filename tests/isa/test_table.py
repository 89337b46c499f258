"""The instruction table: rows are disjoint, every row decodes, handler and condition names follow the contract,
and spot checks against opcode words from the M68000 Programmer's Reference Manual."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import numpy as np
import pytest

from isa.decoder import OPCODE_MAP, row_for
from isa.operands import Mode, Size
from isa.table import (
    ALTERABLE,
    BY_MNEMONIC,
    CONDITIONS,
    CONTROL,
    DATA,
    DATA_ALT,
    HANDLER_NAMES,
    MEM_ALT,
    MEMORY,
    TABLE,
    matches,
)

WORDS = np.arange(65536, dtype=np.uint32)
DOCS = Path(__file__).resolve().parents[2] / "docs" / "isa-internals.md"


def _row_words(row) -> list[int]:
    """Every opcode word of ``row``: candidates by fixed bits (numpy), then the row's own validity predicate."""
    cand = WORDS[(WORDS & row.fixed_mask) == row.fixed_bits]
    return [int(w) for w in cand if matches(row, int(w))]


def test_no_two_rows_share_an_opcode_word() -> None:
    """All 65536 words: each is an instance of at most one row, and the decoder map agrees with the rows."""
    owner = np.full(65536, -1, dtype=np.int32)
    for k, row in enumerate(TABLE):
        for w in _row_words(row):
            assert owner[w] == -1, f"${w:04X} matches {TABLE[owner[w]]} and {row}"
            owner[w] = k
    for w in range(65536):
        expect = TABLE[owner[w]] if owner[w] >= 0 else None
        assert OPCODE_MAP[w] is expect, f"decoder map disagrees at ${w:04X}"
        assert row_for(w) is expect, f"the decoder's per-word lookup disagrees at ${w:04X}"


def test_every_row_decodes() -> None:
    """Every row owns at least one opcode word in the decoder map."""
    owned = {id(r) for r in OPCODE_MAP if r is not None}
    missing = [str(r) for r in TABLE if id(r) not in owned]
    assert not missing, f"rows with no opcode: {missing}"


def test_handlers_are_the_documented_set() -> None:
    """Handler names: exactly the list in docs/isa-internals.md, and TABLE uses every one of them."""
    text = DOCS.read_text()
    m = re.search(r"Handler names are the base mnemonic families: `([^`]+)`", text.replace("\n  ", " "))
    assert m, "handler list not found in docs/isa-internals.md"
    documented = set(m.group(1).split())
    assert HANDLER_NAMES == documented
    assert {row.handler for row in TABLE} == documented


def test_table_handlers_equal_cpu_handlers() -> None:
    if importlib.util.find_spec("isa.cpu") is None:
        pytest.skip("isa.cpu not written yet")
    from isa.cpu import HANDLERS

    assert {row.handler for row in TABLE} == set(HANDLERS)


def test_conditions_follow_the_manual() -> None:
    """PRM table 3-19: the 4-bit condition encodings (and the hs/lo aliases)."""
    prm = "t f hi ls cc cs ne eq vc vs pl mi ge lt gt le".split()
    assert {c: CONDITIONS[c] for c in prm} == {c: i for i, c in enumerate(prm)}
    assert CONDITIONS["hs"] == CONDITIONS["cc"] and CONDITIONS["lo"] == CONDITIONS["cs"]


def test_every_design_mnemonic_is_declared() -> None:
    names = ("move movea moveq movem lea pea clr ext swap exg add adda addi addq addx sub suba subi subq subx neg "
             "negx cmp cmpa cmpi cmpm tst and andi or ori eor eori not asl asr lsl lsr rol ror roxl roxr muls mulu "
             "divs divu bra bsr jmp jsr rts nop trap illegal dbra dbf").split()
    names += ["b" + c for c in CONDITIONS if c not in ("t", "f")] + ["db" + c for c in CONDITIONS]
    names += ["s" + c for c in CONDITIONS]
    assert [n for n in names if n not in BY_MNEMONIC] == []
    assert "bt" not in BY_MNEMONIC and "bf" not in BY_MNEMONIC  # those codes are BRA and BSR


def test_shifts_have_all_three_forms() -> None:
    for mn in ("asl", "asr", "lsl", "lsr", "rol", "ror", "roxl", "roxr"):
        kinds = sorted(tuple(s.kind for s in r.operands) for r in BY_MNEMONIC[mn])
        assert kinds == [("ea",), ("quick3", "reg"), ("reg", "reg")], mn


def test_addressing_categories() -> None:
    """PRM table 2-4 categories."""
    assert len(DATA) == 11 and Mode.AREG not in DATA
    assert MEMORY == DATA - {Mode.DREG}
    assert CONTROL == {Mode.AIND, Mode.ADISP, Mode.AINDEX, Mode.ABSW, Mode.ABSL, Mode.PCDISP, Mode.PCINDEX}
    assert ALTERABLE == {Mode.DREG, Mode.AREG, Mode.AIND, Mode.APOSTINC, Mode.APREDEC, Mode.ADISP, Mode.AINDEX,
                         Mode.ABSW, Mode.ABSL}
    assert DATA_ALT == ALTERABLE - {Mode.AREG} and MEM_ALT == DATA_ALT - {Mode.DREG}


# Opcode words from the PRM's encoding diagrams (worked by hand), with the row handler they must decode to.
PRM_WORDS = {
    0x4E75: "rts", 0x4E71: "nop", 0x4AFC: "illegal", 0x4E4F: "trap", 0x7001: "moveq", 0x22C0: "move",
    0x2040: "movea", 0x48E7: "movem", 0x4CDF: "movem", 0x41FA: "lea", 0x4879: "pea", 0x4280: "clr", 0x4880: "ext",
    0x48C0: "ext", 0x4840: "swap", 0xC141: "exg", 0xC34A: "exg", 0xC388: "exg", 0xD081: "add", 0xD1C0: "adda",
    0x0680: "addi", 0x5280: "addq", 0xD181: "addx", 0xD189: "addx", 0x9081: "sub", 0x5380: "subq", 0x4480: "neg",
    0x4080: "negx", 0xB081: "cmp", 0xB1C8: "cmpa", 0x0C80: "cmpi", 0x4A80: "tst", 0xC081: "and", 0x0280: "andi",
    0x8081: "or", 0x0080: "ori", 0xB181: "eor", 0x0A80: "eori", 0x4680: "not", 0xE380: "asl", 0xE280: "asr",
    0xE388: "lsl", 0xE288: "lsr", 0xE398: "rol", 0xE298: "ror", 0xE390: "roxl", 0xE290: "roxr", 0xE1D0: "asl",
    0xE2D0: "lsr", 0xE7D0: "rol", 0xE5D0: "roxl", 0xE3A0: "asl", 0xC1C1: "muls", 0xC0C1: "mulu", 0x81C1: "divs",
    0x80C1: "divu", 0x6000: "bra", 0x6002: "bra", 0x6100: "bsr", 0x6700: "bcc", 0x66FE: "bcc", 0x51C8: "dbcc",
    0x57C0: "scc", 0x4ED0: "jmp", 0x4EB9: "jsr",
    0xB148: "cmpm", 0xB308: "cmpm", 0xBF8F: "cmpm",  # cmpm.w (a0)+,(a0)+ / .b (a0)+,(a1)+ / .l (a7)+,(a7)+ (GNU as)
}  # fmt: skip
# Words of real 68000 instructions outside the subset (or invalid) that must not decode.
NOT_IN_SUBSET = [
    0x4E72,  # STOP
    0x4E73,  # RTE
    0x4E76,  # TRAPV
    0x003C,  # ORI to CCR
    0x46FC,  # MOVE to SR
    0x40C0,  # MOVE from SR
    0x4AC0,  # TAS
    0xC100,  # ABCD
    0x8100,  # SBCD
    0x0100,  # BTST Dn
    0x4180,  # CHK
    0x4E50,  # LINK
    0x4E58,  # UNLK
    0xA000, 0xF000,  # line A / line F
    0x4E7A,  # MOVEC (68010)
    0x2E3D,  # MOVE with mode 7 reg 5 (no such EA)
    0x4A3C,  # TST.B #imm (68020+ only)
    0x4A48,  # TST.W An (68020+ only)
    0x1008,  # MOVE.B A0,D0 (byte access to An)
    0x5208,  # ADDQ.B #1,A0
    0x61FF,  # would be BSR.L on 68020: on the 68000 it is BSR.S with an odd displacement -> decodes (see below)
]


def test_prm_opcode_words() -> None:
    for word, handler in PRM_WORDS.items():
        row = OPCODE_MAP[word]
        assert row is not None and row.handler == handler, f"${word:04X}: {row}"
    for word in NOT_IN_SUBSET[:-1]:
        assert OPCODE_MAP[word] is None, f"${word:04X} should not decode, got {OPCODE_MAP[word]}"
    assert OPCODE_MAP[0x61FF] is not None and OPCODE_MAP[0x61FF].sizes == (Size.S,)

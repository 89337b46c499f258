"""The one declaration of the supported MC68000 instruction subset.

Every other part of :mod:`isa` (encoder, decoder, formatter, assembler, interpreter, timing) derives what it needs
from :data:`TABLE`; nothing else lists opcodes.

Opcode patterns
---------------
``Row.pattern`` is a 16-character string, bit 15 first. ``0``/``1`` are fixed bits; letters name fields:

===== ==========================================================================================
``S``  size field (1 or 2 bits); ``Row.size_codes`` maps :class:`~isa.operands.Size` -> field value
``C``  4-bit condition code (conditional rows: Bcc, DBcc, Scc); ``Row.conditions`` lists the legal names
``m``  3-bit EA mode, bits 5..3 (source / single EA)        ``r``  3-bit register, bits 2..0
``M``  3-bit EA mode, bits 8..6 (MOVE destination)          ``R``  3-bit register, bits 11..9
``q``  3-bit quick data, bits 11..9 (ADDQ/SUBQ 1..8, shift count 1..8; 0 encodes 8)
``i``  8-bit signed immediate (MOVEQ)                       ``d``  8-bit signed branch displacement
``v``  4-bit TRAP vector
===== ==========================================================================================

Operands
--------
``Row.operands`` are :class:`OperandSpec` in source order. ``kind`` is one of

* ``"ea"``: an effective address; ``modes`` is the allowed set (one of the named 68000 categories below),
  ``mode_field``/``reg_field`` the pattern letters. Byte-sized operations never allow ``An`` (68000 rule; see
  :meth:`Row.allowed_modes`).
* ``"reg"``: a register in a fixed mode (``Dn``, ``An``, ``-(An)`` or ``(An)+``), ``reg_field`` the pattern
  letter.
* ``"imm"``: an immediate in extension words sized by the instruction size (byte: one word, low byte).
* ``"quick3"`` (1..8 in field ``q``), ``"quick8"`` (-128..127 in field ``i``), ``"vector"`` (0..15 in ``v``).
* ``"reglist"``: the MOVEM register mask extension word (``Operand(Mode.REGLIST, value=mask)``, canonical order).
* ``"branch"``: a branch target (``Operand(Mode.ABSL, value=target address)``); the displacement is the 8-bit
  ``d`` field for ``Size.S`` rows and a 16-bit extension word otherwise, relative to the opcode address + 2.

Extension words follow the opcode in ``Row.ext_order`` (operand indices; source order unless stated), each EA
contributing 0, 1 or 2 words (d16, brief index word, abs.W, abs.L, immediate).

Sizes
-----
``Row.sizes`` lists the legal sizes. Rows with ``size_codes == ()`` have one *implied* size (``LEA`` is long,
``MULS`` word, ``Scc`` byte, ...) or none (``None``: JMP, JSR, RTS, NOP, TRAP, ILLEGAL). The decoder reports the
implied size (``Size.L`` for LEA) and the branch size ``Size.S``/``Size.W``; the encoder also accepts ``None`` for
an implied-size row and ``Size.B`` for ``Size.S`` on branches. ``Row.suffix`` says whether the canonical text
form carries the size suffix (``lea`` and ``moveq`` are written without it).

Conditional rows
----------------
``Row.mnemonic`` is the prefix (``"b"``, ``"db"``, ``"s"``) and the instruction mnemonic is prefix + condition
name (``beq``, ``dbne``, ``sgt``; ``dbra`` = ``dbf``). ``BRA`` and ``BSR`` are separate rows (conditions 0 and 1
of the branch group). Use :func:`match_mnemonic` to map a mnemonic to ``(row, condition code)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

from isa.operands import Mode, Size

#: Condition name -> 4-bit code (M68000 PRM table 3-19). ``hs``/``lo`` are aliases of ``cc``/``cs``.
CONDITIONS: dict[str, int] = {
    "t": 0, "f": 1, "hi": 2, "ls": 3, "cc": 4, "cs": 5, "ne": 6, "eq": 7,
    "vc": 8, "vs": 9, "pl": 10, "mi": 11, "ge": 12, "lt": 13, "gt": 14, "le": 15,
    "hs": 4, "lo": 5,
}  # fmt: skip

#: Canonical condition name per code (the decoder's spelling).
CONDITION_NAMES: tuple[str, ...] = ("t", "f", "hi", "ls", "cc", "cs", "ne", "eq",
                                    "vc", "vs", "pl", "mi", "ge", "lt", "gt", "le")  # fmt: skip

#: Handler names (docs/isa-internals.md); every ``Row.handler`` is one of these.
HANDLER_NAMES: frozenset[str] = frozenset(
    "move movea moveq movem lea pea clr ext swap exg add adda addi addq addx sub suba subi subq subx neg negx cmp "
    "cmpa cmpi cmpm tst and andi or ori eor eori not asl asr lsl lsr rol ror roxl roxr muls mulu divs divu bcc bra bsr "
    "dbcc scc jmp jsr rts nop trap illegal".split()
)

# --- Effective-address categories (M68000 PRM section 2.2.1 / table 2-4) -------------------------------------
_M = Mode
ALL: frozenset[Mode] = frozenset({
    _M.DREG, _M.AREG, _M.AIND, _M.APOSTINC, _M.APREDEC, _M.ADISP, _M.AINDEX,
    _M.ABSW, _M.ABSL, _M.PCDISP, _M.PCINDEX, _M.IMM,
})  # fmt: skip
#: Data addressing modes: all but An.
DATA: frozenset[Mode] = ALL - {_M.AREG}
#: Memory addressing modes: all but Dn, An.
MEMORY: frozenset[Mode] = ALL - {_M.DREG, _M.AREG}
#: Control addressing modes: no register direct, no (An)+ / -(An), no immediate.
CONTROL: frozenset[Mode] = frozenset({_M.AIND, _M.ADISP, _M.AINDEX, _M.ABSW, _M.ABSL, _M.PCDISP, _M.PCINDEX})
#: Alterable modes: all but PC-relative and immediate.
ALTERABLE: frozenset[Mode] = ALL - {_M.PCDISP, _M.PCINDEX, _M.IMM}
#: Data alterable: alterable without An.
DATA_ALT: frozenset[Mode] = ALTERABLE - {_M.AREG}
#: Memory alterable: alterable without Dn, An.
MEM_ALT: frozenset[Mode] = ALTERABLE - {_M.DREG, _M.AREG}
#: Control alterable.
CONTROL_ALT: frozenset[Mode] = CONTROL - {_M.PCDISP, _M.PCINDEX}
#: MOVEM registers -> memory: control alterable plus -(An).
MOVEM_TO_MEM: frozenset[Mode] = CONTROL_ALT | {_M.APREDEC}
#: MOVEM memory -> registers: control plus (An)+.
MOVEM_FROM_MEM: frozenset[Mode] = CONTROL | {_M.APOSTINC}

#: 3-bit EA mode field value per mode (mode 7 modes carry their register-field value in :data:`MODE7_REG`).
MODE_FIELD: dict[Mode, int] = {
    _M.DREG: 0, _M.AREG: 1, _M.AIND: 2, _M.APOSTINC: 3, _M.APREDEC: 4, _M.ADISP: 5, _M.AINDEX: 6,
    _M.ABSW: 7, _M.ABSL: 7, _M.PCDISP: 7, _M.PCINDEX: 7, _M.IMM: 7,
}  # fmt: skip
#: Register-field value of the mode-7 addressing modes.
MODE7_REG: dict[Mode, int] = {_M.ABSW: 0, _M.ABSL: 1, _M.PCDISP: 2, _M.PCINDEX: 3, _M.IMM: 4}

# Standard size encodings.
_STD = ((Size.B, 0), (Size.W, 1), (Size.L, 2))  # bits 7..6 of most instructions
_MOVE = ((Size.B, 1), (Size.W, 3), (Size.L, 2))  # bits 13..12 of MOVE/MOVEA
_WL = ((Size.W, 0), (Size.L, 1))  # one bit: MOVEM, EXT, ADDA/SUBA/CMPA


@dataclass(frozen=True)
class OperandSpec:
    """One operand slot of a row; see the module docstring for ``kind``."""

    kind: str
    modes: frozenset[Mode] = frozenset()
    mode_field: str | None = None  #: pattern letter of the EA mode field ("ea" only)
    reg_field: str | None = None  #: pattern letter of the register field ("ea", "reg")
    data_field: str | None = None  #: pattern letter of quick data / vector / 8-bit displacement


def ea(modes: frozenset[Mode], mode_field: str = "m", reg_field: str = "r") -> OperandSpec:
    """An effective-address operand allowing ``modes``, encoded in the given pattern fields."""
    return OperandSpec("ea", frozenset(modes), mode_field, reg_field)


def reg(mode: Mode, reg_field: str) -> OperandSpec:
    """A register operand in fixed ``mode`` (``DREG``, ``AREG``, ``APREDEC``, ``APOSTINC``), number in ``reg_field``."""
    return OperandSpec("reg", frozenset({mode}), None, reg_field)


IMM = OperandSpec("imm", frozenset({Mode.IMM}))
QUICK3 = OperandSpec("quick3", frozenset({Mode.IMM}), data_field="q")
QUICK8 = OperandSpec("quick8", frozenset({Mode.IMM}), data_field="i")
VECTOR = OperandSpec("vector", frozenset({Mode.IMM}), data_field="v")
REGLIST = OperandSpec("reglist", frozenset({Mode.REGLIST}))
BRANCH8 = OperandSpec("branch", frozenset({Mode.ABSL}), data_field="d")
BRANCH16 = OperandSpec("branch", frozenset({Mode.ABSL}))
DN_R = reg(Mode.DREG, "R")
DN_r = reg(Mode.DREG, "r")
AN_R = reg(Mode.AREG, "R")
AN_r = reg(Mode.AREG, "r")


@dataclass(frozen=True)
class Row:
    """One instruction form: mnemonic, opcode pattern, sizes, operands, extension-word order and handler name."""

    mnemonic: str  #: canonical lower-case mnemonic; for conditional rows the prefix "b", "db" or "s"
    pattern: str  #: 16 characters, bit 15 first (see module docstring)
    sizes: tuple[Size | None, ...]  #: legal sizes (``(None,)`` for unsized instructions)
    operands: tuple[OperandSpec, ...]
    handler: str  #: semantic function name in ``isa.cpu.HANDLERS``
    size_codes: tuple[tuple[Size, int], ...] = ()  #: value of the ``S`` field per size; () when implied
    conditions: tuple[str, ...] = ()  #: legal condition names of the ``C`` field (conditional rows)
    ext_order: tuple[int, ...] | None = None  #: operand indices in extension-word order (None: source order)
    suffix: bool = True  #: canonical text carries the size suffix
    swappable: bool = False  #: the two operands may be written in either order (EXG Dn,An)
    note: str = ""

    def __post_init__(self) -> None:
        if len(self.pattern) != 16:
            raise ValueError(f"row {self.mnemonic}: pattern {self.pattern!r} is not 16 characters")
        if self.handler not in HANDLER_NAMES:
            raise ValueError(f"row {self.mnemonic}: unknown handler {self.handler!r}")

    # --- derived pattern data ----------------------------------------------------------------------------------
    @cached_property
    def fixed_mask(self) -> int:
        """Mask of the fixed (``0``/``1``) bits of the opcode word."""
        return sum(1 << (15 - i) for i, ch in enumerate(self.pattern) if ch in "01")

    @cached_property
    def fixed_bits(self) -> int:
        """Value of the fixed bits of the opcode word."""
        return sum(1 << (15 - i) for i, ch in enumerate(self.pattern) if ch == "1")

    @cached_property
    def fields(self) -> dict[str, tuple[int, int]]:
        """Field letter -> (shift, width) in the opcode word. Fields are contiguous."""
        out: dict[str, tuple[int, int]] = {}
        for letter in sorted(set(self.pattern) - {"0", "1"}):
            first = self.pattern.index(letter)
            last = self.pattern.rindex(letter)
            if self.pattern[first : last + 1] != letter * (last - first + 1):
                raise ValueError(f"row {self.mnemonic}: field {letter!r} not contiguous in {self.pattern!r}")
            out[letter] = (15 - last, last - first + 1)
        return out

    def get(self, word: int, letter: str) -> int:
        """Value of field ``letter`` in opcode ``word``."""
        shift, width = self.fields[letter]
        return (word >> shift) & ((1 << width) - 1)

    def put(self, letter: str, value: int) -> int:
        """Opcode bits for ``value`` in field ``letter`` (value must fit the field)."""
        shift, width = self.fields[letter]
        if not 0 <= value < (1 << width):
            raise ValueError(f"row {self.mnemonic}: value {value} does not fit field {letter!r}")
        return value << shift

    @property
    def is_branch(self) -> bool:
        """True for Bcc/BRA/BSR rows (size S or W)."""
        return self.handler in ("bcc", "bra", "bsr")

    @property
    def conditional(self) -> bool:
        """True for rows whose mnemonic is a prefix + condition name."""
        return bool(self.conditions)

    @property
    def implied_size(self) -> bool:
        """True when the size is not encoded (one legal size or none)."""
        return not self.size_codes

    @property
    def size_code_map(self) -> dict[Size, int]:
        """``size_codes`` as a dict."""
        return dict(self.size_codes)

    @property
    def extension_order(self) -> tuple[int, ...]:
        """Operand indices in the order their extension words follow the opcode."""
        return self.ext_order if self.ext_order is not None else tuple(range(len(self.operands)))

    def allowed_modes(self, index: int, size: Size | None) -> frozenset[Mode]:
        """Modes allowed for operand ``index`` at ``size`` (byte operations never address An)."""
        modes = self.operands[index].modes
        if size is Size.B and self.operands[index].kind == "ea":
            modes = modes - {Mode.AREG}
        return modes

    def mnemonics(self) -> tuple[str, ...]:
        """Every mnemonic this row accepts (conditional rows: prefix + each condition name and alias)."""
        if not self.conditional:
            return (self.mnemonic,)
        names = [self.mnemonic + c for c in CONDITIONS if CONDITIONS[c] in self.condition_codes]
        if self.mnemonic == "db" and 1 in self.condition_codes:
            names.append("dbra")
        return tuple(names)

    @property
    def condition_codes(self) -> frozenset[int]:
        """4-bit codes of ``conditions``."""
        return frozenset(CONDITIONS[c] for c in self.conditions)

    def canonical_mnemonic(self, cond: int | None) -> str:
        """Mnemonic the decoder reports (``dbra`` for DBF; ``bcc``/``bcs`` rather than ``bhs``/``blo``)."""
        if not self.conditional:
            return self.mnemonic
        assert cond is not None
        if self.mnemonic == "db" and cond == 1:
            return "dbra"
        return self.mnemonic + CONDITION_NAMES[cond]

    def __str__(self) -> str:
        return f"{self.mnemonic}[{self.pattern}]"


def _std(mn: str, pattern: str, operands: tuple[OperandSpec, ...], handler: str | None = None, **kw: object) -> Row:
    """A B/W/L row with the size in the standard 2-bit field."""
    return Row(mn, pattern, (Size.B, Size.W, Size.L), operands, handler or mn, size_codes=_STD, **kw)  # type: ignore[arg-type]  # **kw carries the optional Row fields


_BCC_CONDS = tuple(CONDITION_NAMES[2:])
_ALL_CONDS = CONDITION_NAMES


def _rows() -> tuple[Row, ...]:
    rows: list[Row] = []
    add = rows.append
    # --- data movement ---------------------------------------------------------------------------------------
    add(Row("move", "00SSRRRMMMmmmrrr", (Size.B, Size.W, Size.L), (ea(ALL), ea(DATA_ALT, "M", "R")), "move",
            size_codes=_MOVE))
    add(Row("movea", "00SSRRR001mmmrrr", (Size.W, Size.L), (ea(ALL), AN_R), "movea",
            size_codes=((Size.W, 3), (Size.L, 2))))
    add(Row("moveq", "0111RRR0iiiiiiii", (Size.L,), (QUICK8, DN_R), "moveq", suffix=False))
    add(Row("movem", "010010001Smmmrrr", (Size.W, Size.L), (REGLIST, ea(MOVEM_TO_MEM)), "movem", size_codes=_WL))
    add(Row("movem", "010011001Smmmrrr", (Size.W, Size.L), (ea(MOVEM_FROM_MEM), REGLIST), "movem", size_codes=_WL,
            ext_order=(1, 0)))
    add(Row("lea", "0100RRR111mmmrrr", (Size.L,), (ea(CONTROL), AN_R), "lea", suffix=False))
    add(Row("pea", "0100100001mmmrrr", (Size.L,), (ea(CONTROL),), "pea", suffix=False))
    add(_std("clr", "01000010SSmmmrrr", (ea(DATA_ALT),)))
    add(Row("ext", "010010001S000rrr", (Size.W, Size.L), (DN_r,), "ext", size_codes=_WL))
    add(Row("swap", "0100100001000rrr", (Size.W,), (DN_r,), "swap", suffix=False))
    add(Row("exg", "1100RRR101000rrr", (Size.L,), (DN_R, DN_r), "exg", suffix=False))
    add(Row("exg", "1100RRR101001rrr", (Size.L,), (AN_R, AN_r), "exg", suffix=False))
    add(Row("exg", "1100RRR110001rrr", (Size.L,), (DN_R, AN_r), "exg", suffix=False, swappable=True))
    # --- arithmetic ------------------------------------------------------------------------------------------
    for mn, hi in (("add", "1101"), ("sub", "1001")):
        add(_std(mn, hi + "RRR0SSmmmrrr", (ea(ALL), DN_R)))
        add(_std(mn, hi + "RRR1SSmmmrrr", (DN_R, ea(MEM_ALT))))
        add(Row(mn + "a", hi + "RRRS11mmmrrr", (Size.W, Size.L), (ea(ALL), AN_R), mn + "a", size_codes=_WL))
        add(_std(mn + "x", hi + "RRR1SS000rrr", (DN_r, DN_R)))
        add(_std(mn + "x", hi + "RRR1SS001rrr", (reg(Mode.APREDEC, "r"), reg(Mode.APREDEC, "R"))))
    add(_std("addi", "00000110SSmmmrrr", (IMM, ea(DATA_ALT))))
    add(_std("subi", "00000100SSmmmrrr", (IMM, ea(DATA_ALT))))
    add(_std("addq", "0101qqq0SSmmmrrr", (QUICK3, ea(ALTERABLE))))
    add(_std("subq", "0101qqq1SSmmmrrr", (QUICK3, ea(ALTERABLE))))
    add(_std("neg", "01000100SSmmmrrr", (ea(DATA_ALT),)))
    add(_std("negx", "01000000SSmmmrrr", (ea(DATA_ALT),)))
    add(_std("cmp", "1011RRR0SSmmmrrr", (ea(ALL), DN_R)))
    add(Row("cmpa", "1011RRRS11mmmrrr", (Size.W, Size.L), (ea(ALL), AN_R), "cmpa", size_codes=_WL))
    add(_std("cmpi", "00001100SSmmmrrr", (IMM, ea(DATA_ALT))))
    add(_std("cmpm", "1011RRR1SS001rrr", (reg(Mode.APOSTINC, "r"), reg(Mode.APOSTINC, "R"))))  # (Ay)+,(Ax)+
    add(_std("tst", "01001010SSmmmrrr", (ea(DATA_ALT),)))
    for mn, hi in (("muls", "1100RRR111"), ("mulu", "1100RRR011"), ("divs", "1000RRR111"), ("divu", "1000RRR011")):
        add(Row(mn, hi + "mmmrrr", (Size.W,), (ea(DATA), DN_R), mn))
    # --- logic -----------------------------------------------------------------------------------------------
    for mn, hi, imm in (("and", "1100", "00000010"), ("or", "1000", "00000000")):
        add(_std(mn, hi + "RRR0SSmmmrrr", (ea(DATA), DN_R)))
        add(_std(mn, hi + "RRR1SSmmmrrr", (DN_R, ea(MEM_ALT))))
        add(_std(mn + "i", imm + "SSmmmrrr", (IMM, ea(DATA_ALT))))
    add(_std("eor", "1011RRR1SSmmmrrr", (DN_R, ea(DATA_ALT))))
    add(_std("eori", "00001010SSmmmrrr", (IMM, ea(DATA_ALT))))
    add(_std("not", "01000110SSmmmrrr", (ea(DATA_ALT),)))
    # --- shifts and rotates: register by immediate count, register by register count, memory by one -----------
    for mn, tt in (("as", "00"), ("ls", "01"), ("rox", "10"), ("ro", "11")):
        for d, dirbit in (("r", "0"), ("l", "1")):
            add(_std(mn + d, "1110qqq" + dirbit + "SS0" + tt + "rrr", (QUICK3, DN_r)))
            add(_std(mn + d, "1110RRR" + dirbit + "SS1" + tt + "rrr", (DN_R, DN_r)))
            add(Row(mn + d, "11100" + tt + dirbit + "11mmmrrr", (Size.W,), (ea(MEM_ALT),), mn + d))
    # --- program control ---------------------------------------------------------------------------------------
    add(Row("bra", "01100000dddddddd", (Size.S,), (BRANCH8,), "bra"))
    add(Row("bra", "0110000000000000", (Size.W,), (BRANCH16,), "bra"))
    add(Row("bsr", "01100001dddddddd", (Size.S,), (BRANCH8,), "bsr"))
    add(Row("bsr", "0110000100000000", (Size.W,), (BRANCH16,), "bsr"))
    add(Row("b", "0110CCCCdddddddd", (Size.S,), (BRANCH8,), "bcc", conditions=_BCC_CONDS))
    add(Row("b", "0110CCCC00000000", (Size.W,), (BRANCH16,), "bcc", conditions=_BCC_CONDS))
    add(Row("db", "0101CCCC11001rrr", (Size.W,), (DN_r, BRANCH16), "dbcc", conditions=_ALL_CONDS, suffix=False))
    add(Row("s", "0101CCCC11mmmrrr", (Size.B,), (ea(DATA_ALT),), "scc", conditions=_ALL_CONDS, suffix=False))
    add(Row("jmp", "0100111011mmmrrr", (None,), (ea(CONTROL),), "jmp"))
    add(Row("jsr", "0100111010mmmrrr", (None,), (ea(CONTROL),), "jsr"))
    add(Row("rts", "0100111001110101", (None,), (), "rts"))
    add(Row("nop", "0100111001110001", (None,), (), "nop"))
    add(Row("trap", "010011100100vvvv", (None,), (VECTOR,), "trap"))
    add(Row("illegal", "0100101011111100", (None,), (), "illegal"))
    return tuple(rows)


#: Every supported instruction form.
TABLE: tuple[Row, ...] = _rows()

#: Mnemonic (every accepted spelling, lower case) -> rows accepting it, in TABLE order.
BY_MNEMONIC: dict[str, tuple[Row, ...]] = {}
for _row in TABLE:
    for _mn in _row.mnemonics():
        BY_MNEMONIC[_mn] = BY_MNEMONIC.get(_mn, ()) + (_row,)
del _row, _mn


def match_mnemonic(mnemonic: str) -> list[tuple[Row, int | None]]:
    """Rows accepting ``mnemonic`` (case-insensitive) with the condition code it selects (None if unconditional).

    Returns an empty list for an unknown mnemonic."""
    mn = mnemonic.lower()
    out: list[tuple[Row, int | None]] = []
    for row in BY_MNEMONIC.get(mn, ()):
        if row.conditional:
            cond = 1 if mn == "dbra" else CONDITIONS[mn[len(row.mnemonic) :]]
            out.append((row, cond))
        else:
            out.append((row, None))
    return out


#: EA mode per 3-bit mode-field value 0..6 (value 7 selects by the register field, see :data:`MODE7_REG`).
MODES_BY_FIELD: tuple[Mode, ...] = (Mode.DREG, Mode.AREG, Mode.AIND, Mode.APOSTINC, Mode.APREDEC, Mode.ADISP,
                                    Mode.AINDEX)  # fmt: skip
#: Mode-7 addressing mode per register-field value 0..4.
MODE7_BY_REG: tuple[Mode, ...] = (Mode.ABSW, Mode.ABSL, Mode.PCDISP, Mode.PCINDEX, Mode.IMM)


def ea_mode(mode_field: int, reg_field: int) -> Mode | None:
    """The addressing mode of a 6-bit EA (mode field 0..7, register field 0..7); None for mode 7 reg 5..7."""
    if mode_field < 7:
        return MODES_BY_FIELD[mode_field]
    return MODE7_BY_REG[reg_field] if reg_field < 5 else None


def row_size(row: Row, word: int) -> Size | None | bool:
    """The size an opcode ``word`` selects in ``row`` (False when the size field holds an invalid code)."""
    if not row.size_codes:
        return row.sizes[0]
    code = row.get(word, "S")
    for size, value in row.size_codes:
        if value == code:
            return size
    return False


def matches(row: Row, word: int) -> bool:
    """True when the 16-bit opcode ``word`` is an instance of ``row``: fixed bits, size code, condition code,
    every EA in its allowed set for that size, and (Bcc.S) a nonzero 8-bit displacement."""
    if word & row.fixed_mask != row.fixed_bits:
        return False
    size = row_size(row, word)
    if size is False:
        return False
    if row.conditional and row.get(word, "C") not in row.condition_codes:
        return False
    for i, spec in enumerate(row.operands):
        if spec.kind == "ea":
            assert spec.mode_field and spec.reg_field
            mode = ea_mode(row.get(word, spec.mode_field), row.get(word, spec.reg_field))
            if mode is None or mode not in row.allowed_modes(i, size):  # type: ignore[arg-type]  # size None is accepted by allowed_modes for unsized rows
                return False
        elif spec.kind == "branch" and spec.data_field and row.get(word, spec.data_field) == 0:
            return False
    return True

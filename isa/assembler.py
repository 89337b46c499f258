"""Two-pass (fixed-point) assembler for the MC68000 subset of :mod:`isa`, Motorola syntax.

``assemble(text, filename, origin, include_paths, defines) -> Program``. The accepted language:

* Lines: ``[label[:]] [operation[.size] [operands]] [; comment]``. A label starts in column 1 (colon optional) or
  anywhere when followed by ``:``. ``*`` or ``;`` as the first non-blank character makes a comment line. Only
  ``;`` starts a comment after the operation; spaces are allowed inside the operand field (``move.l X, D0``).
* Mnemonics, registers, directives and symbols are case-insensitive (symbols keep their spelling in
  :attr:`Program.symbols`). Local labels ``.name`` and ``1$`` are scoped to the previous global label.
* Expressions: see :mod:`isa.expr` (C precedence, ``$hex %bin @oct 'c'``); ``*`` is the address of the start
  of the current statement (for every item of a ``DC``).
* Directives: ``EQU`` / ``=`` (constant), ``SET`` (redefinable), ``DC.B/W/L`` (strings allowed in ``DC.B``),
  ``DS.B/W/L n``, ``DCB.B/W/L n,value``, ``ORG addr``, ``EVEN``, ``ALIGN n`` (n bytes, a power of two),
  ``SECTION code|text|data|bss``, ``TEXT``/``CODE``/``DATA``/``BSS``, ``INCLUDE "file"``, ``MACRO``/``ENDM``
  (``name MACRO [p1,p2..]`` or ``MACRO name``; ``\\1``..``\\9``, ``\\0`` = size suffix of the call, ``\\name`` for
  named parameters, ``\\@`` = unique ``_NNN`` per expansion), ``IF/IFNE expr``, ``IFEQ/IFGT/IFGE/IFLT/IFLE expr``,
  ``IFD/IFND symbol``, ``ELSE``, ``ENDIF``/``ENDC`` (nested), ``FAIL message``, ``END``.
* Layout: each of the sections code, data, bss has its own location counter. Code starts at ``origin``; data
  follows the highest code address (rounded up to even), bss follows data (even). ``ORG`` starts a new block of
  the current section at an absolute address. Word/long data and instructions at odd addresses are errors (use
  ``EVEN``; nothing is padded silently). Blocks that overlap are an error. ``Program.code`` is the first code
  block; every block is a :class:`~isa.program.Segment` (``code``, ``code.1``, ..., ``data``, ``bss``).
* Symbols: a global label's size runs to the next global label of its section (local labels do not cut it), a
  local label's to the next label of any kind, both bounded by the end of their block. Local labels appear in
  :attr:`Program.symbols` as ``global.local`` (``step.loop``, ``step.1$``). Register names are not symbols.
* Expressions that decide the layout (``DS``/``DCB`` counts, ``ORG``, ``ALIGN``, ``IF`` conditions) may only use
  symbols defined earlier in the source, and ``IFD``/``IFND`` see only those; everything else may reference
  forward.
* Encoding is what is written: no MOVE->MOVEQ or ADD->ADDQ rewrites. Absolute operands are ``abs.L`` unless
  written ``x.w`` / ``(x).w``; branches without a size are ``.W``, ``.s``/``.b`` select the 8-bit form.
  ``MOVE``/``ADD``/``SUB``/``CMP`` with an address-register destination assemble as ``MOVEA``/``ADDA``/``SUBA``/
  ``CMPA`` (their only encoding, as every Motorola assembler does); ``CMP (Ay)+,(Ax)+`` assembles as ``CMPM``.
  ``x(PC)`` / ``(x,PC)``: ``x`` is the target address (a warning when ``x`` is a plain number, which GNU as
  would read as the displacement). Aliases:
  ``shl``/``shr`` = ``lsl``/``lsr`` (with a warning), ``dbf`` = ``dbra``, ``bhs``/``blo`` = ``bcc``/``bcs`` (also
  for ``DBcc``/``Scc``). Shifts need an explicit count (``lsl.w #1,d0``); ``asl (a0)`` is the memory form.
"""

from __future__ import annotations

import bisect
import os
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

from isa.encoder import encode, length
from isa.errors import AssemblyError, EncodingError
from isa.expr import ExprParser, Token, Where, compile_parser, constant_value, tokenize
from isa.listing import format_listing
from isa.operands import IndexReg, Instruction, Mode, Operand, Size
from isa.program import ListingLine, Program, Segment, SourceLine, Symbol
from isa.table import BY_MNEMONIC

__all__ = ["assemble", "decode_source", "format_listing"]

#: Highest address + 1 of the 24-bit address space.
ADDRESS_LIMIT = 1 << 24
_MAX_PASSES = 12
#: Run passes after the first as the final one (see ``_Assembler.run``); a test switches it off to compare.
_SPECULATE = True
_MAX_INCLUDE_DEPTH = 32
_MAX_MACRO_DEPTH = 64
_MAX_EXPANDED_LINES = 1_000_000

_SECTIONS = ("code", "data", "bss")
_SECTION_NAMES = {"code": "code", "text": "code", "data": "data", "bss": "bss"}

_ALIASES: dict[str, tuple[str, bool]] = {  # alias -> (canonical mnemonic, warn)
    "shl": ("lsl", True),
    "shr": ("lsr", True),
    "dbf": ("dbra", False),
    "bhs": ("bcc", False),
    "blo": ("bcs", False),
    "dbhs": ("dbcc", False),
    "dblo": ("dbcs", False),
    "shs": ("scc", False),
    "slo": ("scs", False),
}
_TO_A_FORM = {"move": "movea", "add": "adda", "sub": "suba", "cmp": "cmpa"}

_DIRECTIVES = frozenset(
    "equ set dc ds dcb org even align section text code data bss include macro endm if ifne ifeq ifgt ifge iflt "
    "ifle ifd ifnd else endif endc end fail".split()
)
_IF_OPS = frozenset("if ifne ifeq ifgt ifge iflt ifle ifd ifnd".split())
_REGISTERS = {f"d{i}": (Mode.DREG, i) for i in range(8)} | {f"a{i}": (Mode.AREG, i) for i in range(8)}
_REGISTERS["sp"] = (Mode.AREG, 7)
_UNSUPPORTED_REGS = frozenset({"sr", "ccr", "usp", "ssp"})
_RESERVED = frozenset(_REGISTERS) | _UNSUPPORTED_REGS | {"pc"}

_LABEL_RE = re.compile(r"(\.?[A-Za-z_][A-Za-z0-9_]*|\.[0-9]+|[0-9]+\$)")
_INDENTED_LABEL_RE = re.compile(r" *" + _LABEL_RE.pattern + ":")
_OP_RE = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)(?:\.([A-Za-z0-9_]*))?")
_NEWLINE_RE = re.compile(r"\r\n|\r|\n")
_MACRO_ARG_RE = re.compile(r"\\(@|[0-9]|[A-Za-z_][A-Za-z0-9_]*)")
_DATA_RANGE = {1: (-0x80, 0xFF), 2: (-0x8000, 0xFFFF), 4: (-0x8000_0000, 0xFFFF_FFFF)}


class _Rec(NamedTuple):
    """One source line to process: where it really comes from, its text, and a macro-expansion note. (A tuple:
    made for every macro-expanded line of every pass, and hashed by C code where a key holds it.)"""

    file: str
    line: int
    text: str
    note: str = ""

    def where(self, text: str | None = None) -> Where:
        return Where(self.file, self.line, self.text if text is None else text, self.note)


@dataclass
class _Parsed:
    """The fields of one statement; columns are 1-based."""

    label: str | None = None
    label_col: int = 1
    label_colon: bool = False
    op: str | None = None  # lower case
    op_text: str = ""
    op_col: int = 1
    size: str | None = None  # lower case size letter(s) as written
    size_col: int = 1
    operands: str = ""
    operand_col: int = 1
    kind: int = 0  # what _line does with it: _K_NONE, _K_COND, ... (from ``op``)
    #: The compiled instruction or DC/DS/DCB item template (None: not looked up yet; False: the plain way). It is
    #: a function of op, size, operand field and its column, so it is shared by every line holding those.
    template: object = field(default=None, compare=False, repr=False)


_K_NONE, _K_COND, _K_MACRO, _K_ENDM, _K_EQU, _K_DIRECTIVE, _K_OTHER = range(7)


def _kind(op: str | None) -> int:
    if op is None:
        return _K_NONE
    if op in _IF_OPS or op in ("else", "endif", "endc"):
        return _K_COND
    if op == "macro":
        return _K_MACRO
    if op == "endm":
        return _K_ENDM
    if op in ("equ", "set", "="):
        return _K_EQU
    if op in _DIRECTIVES:
        return _K_DIRECTIVE
    return _K_OTHER  # an instruction or a macro call (macro names cannot be directives or mnemonics)


@dataclass
class _Macro:
    name: str
    params: list[str]
    body: list[_Rec]
    rec: _Rec


@dataclass
class _Chunk:
    start: int
    data: bytearray
    size: int = 0


@dataclass
class _Section:
    name: str
    chunks: list[_Chunk] = field(default_factory=list)
    pending: int | None = None  # start of the next chunk, set by ORG
    org_seen: bool = False  # an ORG was seen: every later address of this section is independent of its base
    based_label: bool = False  # a label was defined before any ORG: its value is the base plus an offset


@dataclass
class _Sym:
    name: str
    value: int
    section: str  # code/data/bss for labels, "absolute" otherwise
    kind: str  # label, equ, set, define
    local: bool
    order: int
    rec: _Rec | None


@dataclass
class _Cond:
    active: bool  # lines in this branch are assembled
    parent_active: bool
    taken: bool  # some branch of this IF was already active
    seen_else: bool
    rec: _Rec
    col: int


class _End(Exception):
    """The END directive: stop reading source."""


def _find_comment(text: str) -> int:
    """Index of the ``;`` starting the comment (outside quotes), or ``len(text)``."""
    quote = ""
    for i, ch in enumerate(text):
        if quote:
            if ch == quote:
                quote = ""
        elif ch in "'\"":
            quote = ch
        elif ch == ";":
            return i
    return len(text)


def _split_args(text: str) -> list[tuple[str, int]]:
    """Split a macro argument field at top-level commas: (argument, offset) pairs; ``<a,b>`` groups one argument."""
    out: list[tuple[str, int]] = []
    depth = 0
    quote = ""
    start = 0
    for i, ch in enumerate(text):
        if quote:
            if ch == quote:
                quote = ""
        elif ch in "'\"":
            quote = ch
        elif ch in "(<":
            depth += 1
        elif ch in ")>":
            depth = max(depth - 1, 0)
        elif ch == "," and depth == 0:
            out.append((text[start:i], start))
            start = i + 1
    out.append((text[start:], start))
    result = []
    for arg, off in out:
        stripped = arg.strip()
        if len(stripped) >= 2 and stripped[0] == "<" and stripped[-1] == ">":
            stripped = stripped[1:-1]
        result.append((stripped, off))
    return result


def _split_commas(tokens: list[Token]) -> list[list[Token]]:
    """Split tokens (without the trailing ``end``) at commas outside parentheses."""
    groups: list[list[Token]] = [[]]
    depth = 0
    for t in tokens:
        if t.kind == "lparen":
            depth += 1
        elif t.kind == "rparen":
            depth -= 1
        if t.kind == "comma" and depth == 0:
            groups.append([])
        else:
            groups[-1].append(t)
    return groups


#: Process-wide memos of the pure per-line work, shared by every assembly in the process (the firmware's 98
#: builds of one handful of sources differ only in their defines and a data table). Every value is a function of
#: its key alone, and a key holds everything the value depends on: a line's fields, its tokens and the compiled
#: form of its expressions, operands and data items depend on its text only (and a field's starting column),
#: never on the file, line number or macro note, which only go into error messages -- and errors are never
#: memoised: a line that cannot be compiled is marked so and assembled the plain way every time, which raises
#: with the current line's file:line. Symbol values and ``*`` are never part of a compiled form: a compiled
#: expression is evaluated afresh in every pass (:mod:`isa.expr` ``compile_parser``). Cleared past
#: _SHARED_LIMIT keys (the include files past _SHARED_FILES_LIMIT).
_SHARED_FILES: dict[tuple[str, bytes], list["_Rec"]] = {}
_SHARED_PARSE: dict[str, "_Parsed"] = {}  # line text -> fields (strict)
_SHARED_LENIENT: dict[str, "_Parsed"] = {}  # line text -> fields (lenient: inactive IF branches, macro bodies)
_SHARED_TOKENS: dict[tuple[str, int], list[Token]] = {}  # (field, column) -> tokens
_SHARED_EXPRS: dict[tuple[str, int], "_Expr | None"] = {}  # (field, column) -> one expression, None: plain way
#: (op, size, operand field, its column) -> instruction template / DC/DS/DCB template (False: the plain way)
_SHARED_INSNS: dict[tuple[str, str | None, str, int], "_Insn | bool"] = {}
_SHARED_DATA: dict[tuple[str, str | None, str, int], "_DataT | bool"] = {}
_SHARED_ARGS: dict[str, list[str]] = {}  # macro call's operand field -> arguments
_SHARED_EXPANSIONS: dict[tuple, tuple[str, ...]] = {}  # type: ignore[type-arg]  # (body, params, args, size, \@)
#: ... and of the encoder and the timing table (the plain path), pure functions of a (frozen) Instruction:
#: (instruction, address) -> its bytes; instruction -> its length; instruction -> its cycle range.
_SHARED_CODE: dict[tuple[Instruction, int], bytes] = {}
_SHARED_LENGTH: dict[Instruction, int] = {}
_SHARED_CYCLES: dict[Instruction, "tuple[int, int] | None"] = {}
_SHARED_LIMIT = 200_000
_SHARED_FILES_LIMIT = 256
#: Entries kept per instruction template (operand values -> length / bytes / cycles) before it is cleared.
_TEMPLATE_LIMIT = 256
_MISSING = object()
#: Use the compiled forms (False: every line the plain way, the reference a test compares against).
_COMPILE = True


def _shared(memo: dict) -> dict:  # type: ignore[type-arg]
    if len(memo) > _SHARED_LIMIT:
        memo.clear()
    return memo


def clear_memos() -> None:
    """Empty every process-wide memo (what a fresh process starts with)."""
    for memo in (_SHARED_FILES, _SHARED_PARSE, _SHARED_LENIENT, _SHARED_TOKENS, _SHARED_EXPRS, _SHARED_INSNS,
                 _SHARED_DATA, _SHARED_ARGS, _SHARED_EXPANSIONS, _SHARED_CODE, _SHARED_LENGTH, _SHARED_CYCLES):
        memo.clear()


class _Expr:
    """A compiled expression: ``const`` its value when it uses no symbol and no ``*`` and evaluates without
    error, else ``f(assembler)`` evaluates it (see :mod:`isa.expr`)."""

    __slots__ = ("f", "const", "here")

    def __init__(self, f: Callable[[object], int], pure: bool, here: bool) -> None:
        self.f = f
        self.const = constant_value(f) if pure else None
        self.here = here  # the text holds '*'


class _Op:
    """A compiled operand: ``const`` the Operand when it has no expression (a register, a register list) or a
    pure non-PC-relative one; else mode, register and index fixed and the value ``f`` evaluated per use."""

    __slots__ = ("mode", "reg", "index", "f", "const", "pc", "here", "col")

    def __init__(self, template: Operand, f: "_Expr | None", here: bool, col: int) -> None:
        self.mode = template.mode
        self.reg = template.reg
        self.index = template.index
        self.pc = template.mode in (Mode.PCDISP, Mode.PCINDEX)
        self.f = f.f if f is not None else None
        self.here = here
        self.col = col
        self.const: Operand | None = None
        if f is None:
            self.const = template
        elif f.const is not None and not self.pc:  # a PC-relative operand may warn: evaluated in each pass
            self.const = Operand(template.mode, template.reg, f.const, template.index)


class _Insn:
    """A compiled instruction line: mnemonic after aliases and the A-form/CMPM/MOVEM choices (which depend on
    the operands' modes only), size, compiled operands and the operand columns; per tuple of the values of its
    non-constant operands: the Instruction and its length, its cycle range, and its bytes at an address."""

    __slots__ = ("mn", "size", "alias", "ops", "cols", "lens", "codes", "cycles")

    def __init__(self, mn: str, size: Size | None, alias: str | None, ops: list[_Op], cols: list[int]) -> None:
        self.mn = mn
        self.size = size
        self.alias = alias  # the alias written, when it warns
        self.ops = ops
        self.cols = cols
        self.lens: dict[tuple[int, ...], tuple[Instruction, int]] = {}
        self.codes: dict[tuple[tuple[int, ...], int], bytes] = {}
        self.cycles: dict[tuple[int, ...], tuple[int, int] | None] = {}

    def instruction(self, values: tuple[int, ...]) -> Instruction:
        it = iter(values)
        ops = tuple(o.const if o.const is not None else Operand(o.mode, o.reg, next(it), o.index) for o in self.ops)
        return Instruction(self.mn, self.size, ops)


class _DataT:
    """A compiled DC/DS/DCB line: the width, the count and value expressions, the DC items (bytes of a string,
    or an expression and its column) and, when every DC item is a constant in range, the bytes."""

    __slots__ = ("width", "count", "value", "value_col", "items", "const")

    def __init__(self, width: int) -> None:
        self.width = width
        self.count: _Expr | None = None
        self.value: _Expr | None = None
        self.value_col = 0
        self.items: list[tuple[bytes | None, _Expr | None, int]] = []
        self.const: bytes | None = None


class _Assembler:
    """State of one assembly (all passes)."""

    def __init__(
        self,
        text: str,
        filename: str,
        origin: int,
        include_paths: Sequence[str | Path],
        defines: Mapping[str, int] | None,
    ) -> None:
        self.filename = filename
        self.origin = origin
        if isinstance(include_paths, (str, Path)):  # one directory given bare: not a sequence of characters
            include_paths = [include_paths]
        self.include_paths = [Path(p) for p in include_paths]
        self.defines = dict(defines or {})
        self.main_recs = self._recs_of(text, filename)
        self.file_cache: dict[str, list[_Rec]] = {}
        for memo in (_SHARED_PARSE, _SHARED_LENIENT, _SHARED_TOKENS, _SHARED_EXPRS, _SHARED_INSNS, _SHARED_DATA,
                     _SHARED_ARGS, _SHARED_EXPANSIONS, _SHARED_CODE, _SHARED_LENGTH, _SHARED_CYCLES):
            _shared(memo)
        self.compiling = False  # the operand parser is building a compiled operand (no warning, no values)
        self._rec = _Rec("", 0, "")  # the line and mode a compiled expression is evaluated for (sym, where)
        self._strict = False
        self.prev: dict[str, _Sym] = {}
        self.prev_bases: dict[str, int] = {"code": origin, "data": origin, "bss": origin}
        self.final = False
        self.label_ref = False  # set by the resolver when an expression used a label

    # --- driver -----------------------------------------------------------------------------------------------
    @staticmethod
    def _recs_of(text: str, filename: str) -> list[_Rec]:
        # Lines end at \n, \r\n or \r only (str.splitlines also breaks at \f, \v, \x1c.. and U+2028, which
        # would put every later line number off from what an editor shows).
        lines = _NEWLINE_RE.split(text[1:] if text.startswith("\ufeff") else text)
        if lines and lines[-1] == "":
            lines.pop()
        return [_Rec(filename, i + 1, line) for i, line in enumerate(lines)]

    def run(self) -> Program:
        """Run passes until symbol values and section bases are stable, then a final encoding pass."""
        if not isinstance(self.origin, int) or not 0 <= self.origin < ADDRESS_LIMIT:
            raise AssemblyError(f"origin {self.origin!r} outside the 24-bit address space", self.filename, 0, 0)
        if self.origin & 1:
            raise AssemblyError(f"origin ${self.origin:X} is odd", self.filename, 0, 0)
        for name, value in self.defines.items():
            if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name):
                raise AssemblyError(f"bad define name {name!r}", self.filename, 0, 0)
            if name.lower() in _RESERVED:
                raise AssemblyError(f"define name {name!r} is a register name", self.filename, 0, 0)
            if isinstance(value, bool) or not isinstance(value, int):
                raise AssemblyError(f"define {name} = {value!r} is not an integer", self.filename, 0, 0)
        snapshot: tuple[dict[str, int], dict[str, int]] | None = None
        changing: list[str] = []
        speculate = _SPECULATE
        for _ in range(_MAX_PASSES):
            # From the second pass on, run each pass as the final one: when it completes and its symbols and
            # bases equal the previous pass's, it had exactly the inputs the final pass would have (the same
            # ``prev``), so it IS the final pass and one pass is saved. A final pass differs from a non-final one
            # only by raising where the other substitutes 0 (undefined symbol, range, encoding), so when it
            # completes its symbols are those of the non-final pass. After one speculative pass fails, passes
            # run the plain way (an erroneous program costs at most one extra pass). Nor is a pass run as the
            # final one when the previous pass defined a label in a section whose base has moved since it started
            # (data and bss follow the code, which pass 1 does not know yet): that label's value changes, so this
            # pass cannot be the last, and its encoding and listing would be thrown away. (Either way its symbols
            # are the same; a wrong guess costs one pass, never a different result.)
            self.final = speculate and snapshot is not None and not self._labels_moved()
            try:
                self._pass()
            except AssemblyError:
                if not self.final:
                    raise
                self.final = speculate = False
                self._pass()
            new = (self._snapshot(), dict(self.bases))
            if new == snapshot:
                if self.final:
                    return self._program()
                break
            if snapshot is not None:
                changing = [k for k, v in new[0].items() if snapshot[0].get(k) != v]
            snapshot = new
            self.prev = self.cur
            self.prev_bases = dict(self.bases)
        else:
            sym = self.cur.get(changing[0]) if changing else None
            if sym is not None and sym.rec is not None:
                raise sym.rec.where().error(f"value of '{sym.name}' does not converge (circular definition?)", 1)
            raise AssemblyError("symbol values do not converge (circular definition?)", self.filename, 0, 0)
        self.final = True
        self._pass()
        return self._program()

    def _labels_moved(self) -> bool:
        """Whether the last pass defined a label relative to a section base that differs now from the one it
        used."""
        return any(self.sections[name].based_label and self.pass_bases[name] != self.bases[name]
                   for name in ("data", "bss"))

    def _snapshot(self) -> dict[str, int]:
        return {k: s.value for k, s in self.cur.items() if s.kind != "set"}

    def _pass(self) -> None:
        self.cur: dict[str, _Sym] = {}
        for name, value in self.defines.items():
            self.cur[name.lower()] = _Sym(name, value, "absolute", "define", False, len(self.cur), None)
        self.sections = {name: _Section(name) for name in _SECTIONS}
        self.section = self.sections["code"]
        self.bases = {"code": self.origin, "data": self.prev_bases["data"], "bss": self.prev_bases["bss"]}
        self.pass_bases = dict(self.bases)
        self.macros: dict[str, _Macro] = {}
        self.conds: list[_Cond] = []
        self.scope = ""
        self.unique = 0
        self.listing: list[ListingLine] = []
        self.source_map: dict[int, SourceLine] = {}
        self.warnings: list[str] = []
        self.include_stack: list[str] = [os.path.abspath(self.filename)]
        self.macro_calls: list[tuple[str, str]] = []  # (macro name, "file:line" of its call), outermost first
        self.lines_done = 0
        self.defining: _Macro | None = None
        try:
            self._unit(self.main_recs, "file")
        except _End:
            pass
        # Data follows code, bss follows data (each rounded up to even) unless placed by ORG.
        code_end = self._section_end("code", self.origin)
        self.bases["data"] = (code_end + 1) & ~1
        data_end = self._section_end("data", self.bases["data"])
        self.bases["bss"] = (data_end + 1) & ~1

    def _section_end(self, name: str, default: int) -> int:
        chunks = self.sections[name].chunks
        return max((c.start + c.size for c in chunks), default=default)

    # --- line processing --------------------------------------------------------------------------------------
    def _unit(self, recs: list[_Rec], kind: str) -> None:
        """Process the lines of one file or macro expansion; IF and MACRO blocks must close within it."""
        cond_base = len(self.conds)
        for rec in recs:
            self.lines_done += 1
            if self.lines_done > _MAX_EXPANDED_LINES:
                raise rec.where().error("too many lines after macro expansion (runaway recursion?)", 1)
            self._line(rec, cond_base)
        if self.defining is not None:  # a definition cannot span units (nothing nests while defining)
            mac = self.defining
            self.defining = None
            raise mac.rec.where().error(f"unterminated MACRO '{mac.name}' (missing ENDM)", 1)
        if len(self.conds) > cond_base:
            cond = self.conds[-1]
            raise cond.rec.where().error("unterminated IF (missing ENDIF)", cond.col)

    def _active(self) -> bool:
        return not self.conds or self.conds[-1].active

    def _line(self, rec: _Rec, cond_base: int) -> None:
        # Macro body collection: only ENDM (and a nested MACRO, which is refused) are looked at.
        if self.defining is not None:
            p = self._parse_fields(rec, lenient=True)
            if p.op == "endm":
                self.macros[self.defining.name.lower()] = self.defining
                self.defining = None
                self._list(rec, None)
            elif p.op == "macro":
                raise rec.where().error("nested MACRO definitions are not supported", p.op_col)
            else:
                self.defining.body.append(rec)
                self._list(rec, None)
            return
        conds = self.conds
        if conds and not conds[-1].active:
            p = self._parse_fields(rec, lenient=True)
            if p.op in _IF_OPS:
                self.conds.append(_Cond(False, False, True, False, rec, p.op_col))
            elif p.op in ("else", "endif", "endc"):
                self._cond_op(rec, p, cond_base)
            return
        p = _SHARED_PARSE.get(rec.text)  # type: ignore[assignment]
        if p is None:
            p = self._parse_fields(rec, lenient=False)
        kind = p.kind
        if kind == _K_OTHER:
            if p.label is not None:
                self._define_label(rec, p)
            if p.op in self.macros:
                self._list(rec, None)
                self._expand(rec, p)
            else:
                self._instruction(rec, p)
            return
        if kind == _K_NONE:
            if p.label is not None:
                self._define_label(rec, p)
                if self.final:
                    self._list(rec, self._here())
            elif self.final:
                self._list(rec, None)
            return
        if kind == _K_COND:
            if p.label is not None:
                raise rec.where().error("a label is not allowed on a conditional directive", p.label_col)
            self._cond_op(rec, p, cond_base)
            self._list(rec, None)
            return
        if kind == _K_MACRO:
            self._macro_def(rec, p)
            self._list(rec, None)
            return
        if kind == _K_ENDM:
            raise rec.where().error("ENDM without MACRO", p.op_col)
        if kind == _K_EQU:
            self._equ(rec, p)
            return
        if p.label is not None:
            self._define_label(rec, p)
        self._directive(rec, p)

    def _parse_fields(self, rec: _Rec, lenient: bool) -> _Parsed:
        """Split a line into label, operation, size and operand field (a pure function of the line's text:
        memoised; errors are not, they recur)."""
        memo = _SHARED_LENIENT if lenient else _SHARED_PARSE
        p = memo.get(rec.text)
        if p is None:
            p = self._parse_fields_uncached(rec, lenient)
            p.kind = _kind(p.op)
            memo[rec.text] = p
        return p

    def _parse_fields_uncached(self, rec: _Rec, lenient: bool) -> _Parsed:
        text = rec.text.replace("\t", " ") if "\t" in rec.text else rec.text
        p = _Parsed()
        stripped = text.lstrip()
        if not stripped or stripped[0] in "*;":
            return p
        body = text[: _find_comment(text)].rstrip()
        i = 0
        if body and body[0] != " ":
            m = _LABEL_RE.match(body)
            if m is None:
                if lenient:
                    return p
                raise rec.where().error(f"bad label or statement starting with {body[0]!r}", 1)
            p.label = m.group(1)
            p.label_col = 1
            i = m.end()
            if i < len(body) and body[i] == ":":
                p.label_colon = True
                i += 1
            elif i < len(body) and body[i] not in " =":
                if lenient:
                    return p
                raise rec.where().error(f"bad character {body[i]!r} in label", i + 1)
        else:
            m = _INDENTED_LABEL_RE.match(body)
            if m is not None:
                p.label = m.group(1)
                p.label_col = m.start(1) + 1
                p.label_colon = True
                i = m.end()
        while i < len(body) and body[i] == " ":
            i += 1
        if i >= len(body):
            low = (p.label or "").lower()
            if not lenient and not p.label_colon and (low in BY_MNEMONIC or low in _DIRECTIVES or low in _ALIASES):
                raise rec.where().error(
                    f"'{p.label}' in column 1 is taken as a label; indent instructions and directives", 1
                )
            return p
        if body[i] == "=":
            p.op, p.op_text, p.op_col = "=", "=", i + 1
            i += 1
        else:
            m = _OP_RE.match(body, i)
            if m is None:
                if lenient:
                    return p
                raise rec.where().error(f"expected an instruction or directive, found {body[i]!r}", i + 1)
            p.op = m.group(1).lower()
            p.op_text = m.group(0)
            p.op_col = i + 1
            if m.group(2) is not None:
                p.size = m.group(2).lower()
                p.size_col = m.start(2) + 1
            i = m.end()
            if i < len(body) and body[i] != " ":
                if lenient:
                    return p
                raise rec.where().error(f"unexpected {body[i]!r} after '{p.op_text}'", i + 1)
        while i < len(body) and body[i] == " ":
            i += 1
        p.operands = body[i:]
        p.operand_col = i + 1
        return p

    def _list(self, rec: _Rec, address: int | None, data: bytes = b"", cycles: tuple[int, int] | None = None) -> None:
        if self.final:
            self.listing.append(ListingLine(address, bytes(data), cycles, SourceLine(rec.file, rec.line, rec.text)))

    # --- symbols ------------------------------------------------------------------------------------------------
    def _qualify(self, name: str) -> tuple[str, bool]:
        """Full name of a (possibly local) symbol and whether it is local."""
        if name.startswith(".") or name.endswith("$"):
            return self.scope + (name if name.startswith(".") else "." + name), True
        return name, False

    def _check_name(self, rec: _Rec, name: str, col: int) -> None:
        if name.lower() in _RESERVED:
            raise rec.where().error(f"'{name}' is a register name and cannot be a symbol", col)

    def _define(self, rec: _Rec, name: str, col: int, value: int, section: str, kind: str) -> None:
        self._check_name(rec, name, col)
        full, local = self._qualify(name)
        key = full.lower()
        old = self.cur.get(key)
        if old is not None and not (old.kind == "set" and kind == "set"):
            where = f" (first defined at {old.rec.file}:{old.rec.line})" if old.rec else " (a define)"
            raise rec.where().error(f"duplicate symbol '{full}'{where}", col)
        self.cur[key] = _Sym(full, value, section, kind, local, len(self.cur), rec)

    def _define_label(self, rec: _Rec, p: _Parsed) -> None:
        assert p.label is not None
        self._define(rec, p.label, p.label_col, self._here(), self.section.name, "label")
        if not self.section.org_seen:
            self.section.based_label = True
        if not (p.label.startswith(".") or p.label.endswith("$")):
            self.scope = p.label

    def _resolver(self, rec: _Rec, strict: bool):
        """A symbol resolver for :class:`ExprParser`; ``strict`` allows only symbols defined earlier."""

        def resolve(name: str, tok: Token) -> int:
            return self._resolve(rec, strict, name, tok)

        return resolve

    def sym(self, name: str, tok: Token) -> int:
        """The resolver of a compiled expression (:mod:`isa.expr`): for the line and mode of ``_value``."""
        return self._resolve(self._rec, self._strict, name, tok)

    def sym_global(self, name: str, low: str, tok: Token) -> int:
        """:meth:`sym` for a name that is not local and not a register (``low`` = its lower case)."""
        sym = self.cur.get(low)
        if sym is not None:
            if sym.kind == "label":
                self.label_ref = True
            return sym.value
        return self._resolve(self._rec, self._strict, name, tok)

    def star(self) -> int:
        """``*`` in a compiled expression."""
        return self._here()

    def where(self) -> Where:
        """Error context of a compiled expression: the line it is evaluated for."""
        return self._rec.where()

    def _resolve(self, rec: _Rec, strict: bool, name: str, tok: Token) -> int:
        """The resolver: ``strict`` allows only symbols defined earlier (on ``rec``, for errors)."""
        low = name.lower()
        if low in _RESERVED:
            raise rec.where().error(f"register '{name}' is not allowed in an expression", tok.col)
        full, _ = self._qualify(name)
        key = full.lower()
        sym = self.cur.get(key)
        if sym is not None:
            self.label_ref |= sym.kind == "label"
            return sym.value
        if strict:
            raise rec.where().error(
                f"symbol '{full}' must be defined before this line (it decides the layout)", tok.col
            )
        sym = self.prev.get(key)
        if sym is not None and sym.kind != "set":
            self.label_ref |= sym.kind == "label"
            return sym.value
        if self.final:
            raise rec.where().error(f"undefined symbol '{full}'", tok.col)
        self.label_ref = True  # unknown yet: do not refuse a PC-relative form before the final pass
        return 0

    # --- expressions ----------------------------------------------------------------------------------------------
    def _tokens(self, rec: _Rec, text: str, col: int) -> list[Token]:
        """``tokenize`` (memoised by field text and column; callers never mutate the list)."""
        key = (text, col)
        toks = _SHARED_TOKENS.get(key)
        if toks is None:
            toks = _SHARED_TOKENS[key] = tokenize(text, col, rec.where())
        return toks

    def _eval_tokens(self, rec: _Rec, toks: list[Token], strict: bool = False, what: str = "expression") -> int:
        """Evaluate a complete token list (must be one expression): the plain way, parsing as it evaluates."""
        if not toks or toks[0].kind == "end":
            col = toks[0].col if toks else 1
            raise rec.where().error(f"missing {what}", col)
        if toks[-1].kind != "end":
            toks = toks + [Token("end", "", toks[-1].col + len(toks[-1].text))]
        parser = ExprParser(toks, rec.where(), self._resolver(rec, strict), self._here())
        value = parser.parse()
        if parser.tok.kind != "end":
            raise parser.error(f"unexpected '{parser.tok.text}' in {what}")
        return value

    @staticmethod
    def _compile_tokens(rec: _Rec, toks: list[Token]) -> _Expr | None:
        """The compiled form of what :meth:`_eval_tokens` evaluates, or None where it raises whatever the
        symbols (a syntax error: that line goes the plain way, which raises it)."""
        if not toks or toks[0].kind == "end":
            return None
        if toks[-1].kind != "end":
            toks = toks + [Token("end", "", toks[-1].col + len(toks[-1].text))]
        try:
            parser = compile_parser(toks, rec.where(), _symbol_node)
            f = parser.parse()
        except AssemblyError:
            return None
        if parser.tok.kind != "end":
            return None
        return _Expr(f, parser.pure, parser.used_here)  # type: ignore[arg-type,attr-defined]

    def _value(self, rec: _Rec, ex: _Expr, strict: bool = False) -> int:
        """Evaluate a compiled expression for ``rec`` (what :meth:`_eval_tokens` returns or raises)."""
        if ex.const is not None:
            return ex.const
        self._rec = rec
        self._strict = strict
        return ex.f(self)

    def _eval(self, rec: _Rec, text: str, col: int, strict: bool = False, what: str = "expression") -> int:
        key = (text, col)
        ex = _SHARED_EXPRS.get(key, _MISSING)
        if ex is _MISSING:
            try:
                toks = self._tokens(rec, text, col)
            except AssemblyError:
                ex = None
            else:
                ex = self._compile_tokens(rec, toks)
            _SHARED_EXPRS[key] = ex  # type: ignore[assignment]
        if ex is None or not _COMPILE:
            return self._eval_tokens(rec, self._tokens(rec, text, col), strict, what)
        return self._value(rec, ex, strict)  # type: ignore[arg-type]

    # --- location counter -------------------------------------------------------------------------------------------
    def _here(self) -> int:
        sec = self.section
        if sec.pending is not None:
            return sec.pending
        if sec.chunks:
            c = sec.chunks[-1]
            return c.start + c.size
        return self.bases[sec.name]

    def _emit(self, rec: _Rec, data: bytes, col: int, reserve: int = 0) -> int:
        """Append ``data`` (or reserve ``reserve`` zero bytes) to the current section; return its address."""
        sec = self.section
        addr = self._here()
        n = len(data) + reserve
        if addr + n > ADDRESS_LIMIT:
            raise rec.where().error(f"address ${addr + n:X} beyond the 24-bit address space", col)
        if sec.pending is not None or not sec.chunks:
            sec.chunks.append(_Chunk(addr, bytearray()))
            sec.pending = None
        chunk = sec.chunks[-1]
        if sec.name != "bss":
            chunk.data += data
            if reserve:
                chunk.data += bytes(reserve)
        chunk.size += n
        return addr

    def _require_even(self, rec: _Rec, what: str, col: int) -> None:
        addr = self._here()
        if addr & 1:
            raise rec.where().error(f"{what} at odd address ${addr:X} (insert EVEN)", col)

    # --- directives ---------------------------------------------------------------------------------------------
    def _equ(self, rec: _Rec, p: _Parsed) -> None:
        if p.label is None:
            raise rec.where().error(f"'{p.op_text}' needs a symbol name in the label field", p.op_col)
        if p.size is not None:
            raise rec.where().error(f"bad size suffix '.{p.size}' on '{p.op}'", p.size_col)
        value = self._eval(rec, p.operands, p.operand_col)
        kind = "set" if p.op == "set" else "equ"
        self._define(rec, p.label, p.label_col, value, "absolute", kind)
        self._list(rec, None)

    def _directive(self, rec: _Rec, p: _Parsed) -> None:
        op = p.op
        assert op is not None
        sized = op in ("dc", "ds", "dcb")
        if p.size is not None and (not sized or p.size not in ("b", "w", "l")):
            raise rec.where().error(f"bad size suffix '.{p.size}' on '{op}'", p.size_col)
        no_operands = op in ("even", "text", "code", "data", "bss", "end")
        if no_operands and p.operands:
            raise rec.where().error(f"'{op}' takes no operands", p.operand_col)
        if op in ("dc", "ds", "dcb"):
            self._data(rec, p)
        elif op == "org":
            addr = self._eval(rec, p.operands, p.operand_col, strict=True, what="address")
            if not 0 <= addr < ADDRESS_LIMIT:
                raise rec.where().error(f"ORG address {addr} outside the 24-bit address space", p.operand_col)
            self.section.pending = addr
            self.section.org_seen = True
            self._list(rec, addr)
        elif op in ("even", "align"):
            n = 2
            if op == "align":
                n = self._eval(rec, p.operands, p.operand_col, strict=True, what="alignment")
                if n < 1 or n & (n - 1) or n > 0x10000:
                    raise rec.where().error(f"alignment {n} is not a power of two in 1..65536", p.operand_col)
            pad = -self._here() % n
            addr = self._emit(rec, b"", p.op_col, reserve=pad) if pad else self._here()
            self._list(rec, addr, bytes(pad) if self.section.name != "bss" else b"")
        elif op == "section":
            self._section(rec, p)
        elif op in ("text", "code", "data", "bss"):
            self.section = self.sections[_SECTION_NAMES.get(op, op)]
            self._list(rec, None)
        elif op == "include":
            self._include(rec, p)
        elif op == "fail":
            raise rec.where().error(f"FAIL: {p.operands}" if p.operands else "FAIL", p.op_col)
        elif op == "end":
            self._list(rec, None)
            raise _End
        else:  # pragma: no cover - every directive is handled above
            raise rec.where().error(f"directive '{op}' not handled", p.op_col)

    def _section(self, rec: _Rec, p: _Parsed) -> None:
        parts = [s.strip().lower() for s in p.operands.split(",")]
        name = None
        for part in reversed(parts):
            part = part.lstrip(".")
            if part in _SECTION_NAMES:
                name = _SECTION_NAMES[part]
                break
        if name is None:
            col = p.operand_col if p.operands else p.op_col
            raise rec.where().error(f"unknown section '{p.operands}' (use code/text, data or bss)", col)
        self.section = self.sections[name]
        self._list(rec, None)

    def _data(self, rec: _Rec, p: _Parsed) -> None:
        t = p.template
        if t is None:
            key = (p.op, p.size, p.operands, p.operand_col)
            t = _SHARED_DATA.get(key)
            if t is None:
                t = _SHARED_DATA[key] = self._compile_data(rec, p) or False
            p.template = t
        if t is False or not _COMPILE:
            self._data_plain(rec, p)
            return
        assert isinstance(t, _DataT)
        # What _data_plain does, in the same order, with the line's expressions compiled.
        op = p.op
        width = t.width
        bss = self.section.name == "bss"
        if width > 1:
            self._require_even(rec, f"{op}.{'wl'[width == 4]}", p.op_col)
        if op == "ds":
            count = self._value(rec, t.count, strict=True)
            if count < 0 or count * width >= ADDRESS_LIMIT:
                raise rec.where().error(f"DS count {count} out of range", p.operand_col)
            addr = self._emit(rec, b"", p.op_col, reserve=count * width)
            self._list(rec, addr, b"" if bss else bytes(count * width))
            return
        if bss:
            raise rec.where().error("initialized data (DC/DCB) in the bss section", p.op_col)
        if op == "dcb":
            count = self._value(rec, t.count, strict=True)
            if count < 0 or count * width >= ADDRESS_LIMIT:
                raise rec.where().error(f"DCB count {count} out of range", p.operand_col)
            value = self._value(rec, t.value) if t.value is not None else 0
            data = self._pack(rec, value, width, t.value_col) * count
        elif t.const is not None:
            data = t.const
        else:
            buf = bytearray()
            for raw, ex, col in t.items:
                if raw is not None:
                    buf += raw
                else:
                    buf += self._pack(rec, self._value(rec, ex), width, col)  # type: ignore[arg-type]
            data = bytes(buf)
        addr = self._emit(rec, data, p.op_col)
        self._list(rec, addr, data)

    def _compile_data(self, rec: _Rec, p: _Parsed) -> _DataT | None:
        """The compiled form of a DC/DS/DCB line (a function of its text), or None where :meth:`_data_plain`
        raises for its text whatever the symbols and the state."""
        t = _DataT({"b": 1, "w": 2, "l": 4}[p.size or "w"])
        try:
            toks = self._tokens(rec, p.operands, p.operand_col)
        except AssemblyError:
            return None
        groups = _split_commas(toks[:-1])
        if p.op in ("ds", "dcb"):
            if len(groups) not in ((1,) if p.op == "ds" else (1, 2)):
                return None
            t.count = self._compile_tokens(rec, groups[0])
            if t.count is None:
                return None
            if len(groups) == 2:
                t.value = self._compile_tokens(rec, groups[1])
                if t.value is None:
                    return None
                t.value_col = groups[1][0].col
            else:
                t.value_col = p.operand_col
            return t
        lo, hi = _DATA_RANGE[t.width]
        const = bytearray()
        for g in groups:
            if not g:
                return None
            if t.width == 1 and len(g) == 1 and g[0].kind == "str":
                s = str(g[0].value)
                if any(ord(ch) > 255 for ch in s):
                    return None
                raw = s.encode("latin-1")
                t.items.append((raw, None, g[0].col))
                if const is not None:
                    const += raw
                continue
            ex = self._compile_tokens(rec, g)
            if ex is None:
                return None
            t.items.append((None, ex, g[0].col))
            if const is not None and ex.const is not None and lo <= ex.const <= hi:
                const += (ex.const & ((1 << (8 * t.width)) - 1)).to_bytes(t.width, "big")
            else:
                const = None  # type: ignore[assignment]
        t.const = bytes(const) if const is not None else None
        return t

    def _data_plain(self, rec: _Rec, p: _Parsed) -> None:
        op = p.op
        width = {"b": 1, "w": 2, "l": 4}[p.size or "w"]
        bss = self.section.name == "bss"
        if width > 1:
            self._require_even(rec, f"{op}.{'wl'[width == 4]}", p.op_col)
        toks = self._tokens(rec, p.operands, p.operand_col)
        groups = _split_commas(toks[:-1])
        if op == "ds":
            if len(groups) != 1:
                raise rec.where().error("DS takes one operand (the count)", p.operand_col)
            count = self._eval_tokens(rec, groups[0], strict=True, what="count")
            if count < 0 or count * width >= ADDRESS_LIMIT:
                raise rec.where().error(f"DS count {count} out of range", p.operand_col)
            addr = self._emit(rec, b"", p.op_col, reserve=count * width)
            self._list(rec, addr, b"" if bss else bytes(count * width))
            return
        if bss:
            raise rec.where().error("initialized data (DC/DCB) in the bss section", p.op_col)
        if op == "dcb":
            if len(groups) not in (1, 2):
                raise rec.where().error("DCB takes a count and an optional value", p.operand_col)
            count = self._eval_tokens(rec, groups[0], strict=True, what="count")
            if count < 0 or count * width >= ADDRESS_LIMIT:
                raise rec.where().error(f"DCB count {count} out of range", p.operand_col)
            value = self._eval_tokens(rec, groups[1]) if len(groups) == 2 else 0
            item = self._pack(rec, value, width, groups[1][0].col if len(groups) == 2 else p.operand_col)
            data = item * count
        else:
            data = bytearray()
            for g in groups:
                if not g:
                    col = toks[0].col if toks else p.operand_col
                    raise rec.where().error("missing value in DC", col)
                if width == 1 and len(g) == 1 and g[0].kind == "str":
                    s = str(g[0].value)
                    if any(ord(ch) > 255 for ch in s):
                        raise rec.where().error("string holds a character outside 8 bits", g[0].col)
                    data += s.encode("latin-1")
                    continue
                data += self._pack(rec, self._eval_tokens(rec, g), width, g[0].col)
        addr = self._emit(rec, bytes(data), p.op_col)
        self._list(rec, addr, bytes(data))

    def _pack(self, rec: _Rec, value: int, width: int, col: int) -> bytes:
        lo, hi = _DATA_RANGE[width]
        if not lo <= value <= hi:
            if not self.final:
                value = 0
            else:
                raise rec.where().error(f"value {value} out of range {lo}..{hi} for {width}-byte data", col)
        return (value & ((1 << (8 * width)) - 1)).to_bytes(width, "big")

    def _include(self, rec: _Rec, p: _Parsed) -> None:
        name = p.operands.strip()
        if len(name) >= 2 and name[0] == name[-1] and name[0] in "'\"" or (name[:1] == "<" and name[-1:] == ">"):
            name = name[1:-1]
        if not name:
            raise rec.where().error("INCLUDE needs a file name", p.op_col)
        base = Path(rec.file).parent if rec.file and not rec.file.startswith("<") else Path(".")
        candidates = [Path(name)] if os.path.isabs(name) else [base / name] + [d / name for d in self.include_paths]
        path = next((c for c in candidates if c.is_file()), None)
        if path is None:
            tried = ", ".join(str(c) for c in candidates)
            raise rec.where().error(f"cannot find INCLUDE file '{name}' (tried {tried})", p.operand_col)
        key = os.path.abspath(path)
        if key in self.include_stack:
            chain = " -> ".join(self.include_stack + [key])
            raise rec.where().error(f"include recursion: {chain}", p.operand_col)
        if len(self.include_stack) > _MAX_INCLUDE_DEPTH:
            raise rec.where().error("INCLUDE nested too deeply", p.operand_col)
        recs = self.file_cache.get(key)
        if recs is None:
            try:
                data = path.read_bytes()
            except OSError as exc:
                raise rec.where().error(f"cannot read INCLUDE file '{path}': {exc.strerror or exc}",
                                        p.operand_col) from None
            if len(_SHARED_FILES) > _SHARED_FILES_LIMIT:  # keys hold whole files: a smaller bound
                _SHARED_FILES.clear()
            recs = _SHARED_FILES.get((str(path), data))
            if recs is None:
                text = decode_source(data, str(path))
                recs = _SHARED_FILES[(str(path), data)] = self._recs_of(text, str(path))
            self.file_cache[key] = recs
        self._list(rec, None)
        self.include_stack.append(key)
        saved_calls, self.macro_calls = self.macro_calls, []
        try:
            self._unit(recs, "file")
        finally:
            self.include_stack.pop()
            self.macro_calls = saved_calls

    # --- conditionals ----------------------------------------------------------------------------------------------
    def _cond_op(self, rec: _Rec, p: _Parsed, cond_base: int) -> None:
        op = p.op
        if op in _IF_OPS:
            parent = self._active()
            value = False
            if parent:
                if op in ("ifd", "ifnd"):
                    toks = self._tokens(rec, p.operands, p.operand_col)
                    if len(toks) != 2 or toks[0].kind != "ident":
                        raise rec.where().error(f"{op.upper()} needs one symbol name", p.operand_col)
                    full, _ = self._qualify(toks[0].text)
                    defined = full.lower() in self.cur
                    value = defined if op == "ifd" else not defined
                else:
                    v = self._eval(rec, p.operands, p.operand_col, strict=True, what="condition")
                    value = {
                        "if": v != 0,
                        "ifne": v != 0,
                        "ifeq": v == 0,
                        "ifgt": v > 0,
                        "ifge": v >= 0,
                        "iflt": v < 0,
                        "ifle": v <= 0,
                    }[op]
            self.conds.append(_Cond(parent and value, parent, value, False, rec, p.op_col))
            return
        if len(self.conds) <= cond_base:
            raise rec.where().error(f"{op.upper()} without IF", p.op_col)
        if p.operands:
            raise rec.where().error(f"'{op}' takes no operands", p.operand_col)
        cond = self.conds[-1]
        if op == "else":
            if cond.seen_else:
                raise rec.where().error("second ELSE for the same IF", p.op_col)
            cond.seen_else = True
            cond.active = cond.parent_active and not cond.taken
            cond.taken = True
        else:
            self.conds.pop()

    # --- macros ----------------------------------------------------------------------------------------------------
    def _macro_def(self, rec: _Rec, p: _Parsed) -> None:
        if p.size is not None:
            raise rec.where().error(f"bad size suffix '.{p.size}' on 'macro'", p.size_col)
        params_text = p.operands
        if p.label is not None:
            name, col = p.label, p.label_col
        else:
            m = re.match(r"([A-Za-z_][A-Za-z0-9_]*)\s*,?\s*", params_text)
            if m is None:
                raise rec.where().error("MACRO needs a name", p.operand_col)
            name, col = m.group(1), p.operand_col
            params_text = params_text[m.end() :]
        low = name.lower()
        if low in BY_MNEMONIC or low in _DIRECTIVES or low in _ALIASES or low in _RESERVED:
            raise rec.where().error(f"macro name '{name}' is a reserved word", col)
        if low in self.macros:
            raise rec.where().error(f"macro '{name}' already defined", col)
        params = [a.strip() for a in params_text.split(",")] if params_text.strip() else []
        for prm in params:
            if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", prm):
                raise rec.where().error(f"bad macro parameter name '{prm}'", p.operand_col)
        self.defining = _Macro(name, [x.lower() for x in params], [], rec)

    def _expand(self, rec: _Rec, p: _Parsed) -> None:
        mac = self.macros[p.op or ""]
        args = _SHARED_ARGS.get(p.operands)
        if args is None:
            args = _SHARED_ARGS[p.operands] = [a for a, _ in _split_args(p.operands)] if p.operands.strip() else []
        if len(args) > 9 and not mac.params:
            raise rec.where().error("more than 9 macro arguments", p.operand_col)
        calls = self.macro_calls
        if len(calls) >= _MAX_MACRO_DEPTH:
            first_name, first_at = calls[0]
            raise Where(rec.file, rec.line, rec.text).error(
                f"macro '{mac.name}' nested {len(calls)} levels deep (recursive macro?); the outermost call is "
                f"'{first_name}' at {first_at}", p.op_col)
        self.unique += 1
        unique = f"_{self.unique:03d}"
        named = {prm: (args[i] if i < len(args) else "") for i, prm in enumerate(mac.params)}

        def sub(m: re.Match[str]) -> str:
            key = m.group(1)
            if key == "@":
                return unique
            if key.isdigit():
                n = int(key)
                if n == 0:
                    return p.size or ""
                return args[n - 1] if n <= len(args) else ""
            return named.get(key.lower(), m.group(0))

        calls.append((mac.name, f"{rec.file}:{rec.line}"))
        note = _macro_note(calls)
        # The expanded texts are a function of the body's texts, the parameter names, the arguments, the size
        # suffix and the \@ number: memoised on exactly those.
        key = (tuple(r.text for r in mac.body), tuple(mac.params), tuple(args), p.size, unique)
        texts = _SHARED_EXPANSIONS.get(key)
        if texts is None:
            texts = _SHARED_EXPANSIONS[key] = tuple(_MACRO_ARG_RE.sub(sub, r.text) for r in mac.body)
        body = [_Rec(r.file, r.line, text, note) for r, text in zip(mac.body, texts)]
        try:
            self._unit(body, "macro")
        finally:
            calls.pop()

    # --- instructions ----------------------------------------------------------------------------------------------
    def _instruction(self, rec: _Rec, p: _Parsed) -> None:
        t = p.template
        if t is None:
            key = (p.op, p.size, p.operands, p.operand_col)
            t = _SHARED_INSNS.get(key)
            if t is None:
                t = _SHARED_INSNS[key] = self._compile_instruction(rec, p) or False
            p.template = t
        if t is False or not _COMPILE:
            self._instruction_plain(rec, p)
            return
        assert isinstance(t, _Insn)
        # What _instruction_plain does, in the same order, with the mnemonic, size and operands compiled.
        final = self.final
        if t.alias is not None and final:
            self.warnings.append(
                f"{rec.file}:{rec.line}:{p.op_col}: warning: '{t.alias}' is not a 68000 mnemonic; assembled as "
                f"'{_ALIASES[t.alias][0]}'"
            )
        if self.section.name == "bss":
            raise rec.where().error("instruction in the bss section", p.op_col)
        addr = self._here()
        if addr & 1:
            raise rec.where().error(f"instruction at odd address ${addr:X} (insert EVEN)", p.op_col)
        values = []
        for o in t.ops:
            if o.const is None:
                self._rec = rec
                self._strict = False
                self.label_ref = False
                values.append(o.f(self))
                if o.pc and final and not (o.here or self.label_ref):
                    self._pc_warning(rec, o.col, values[-1])
        key = tuple(values)
        if final:
            data = t.codes.get((key, addr))
            cycles = t.cycles.get(key, _MISSING)
            if data is None or cycles is _MISSING:
                instr = t.instruction(key)
                if data is None:
                    try:
                        data = encode(instr, addr)
                    except EncodingError as exc:
                        raise self._encoding_error(rec, p, exc, t.cols) from None
                    if len(t.codes) > _TEMPLATE_LIMIT:
                        t.codes.clear()
                    t.codes[(key, addr)] = data
                if cycles is _MISSING:
                    if len(t.cycles) > _TEMPLATE_LIMIT:
                        t.cycles.clear()
                    cycles = t.cycles[key] = _cycle_range(instr)
            self.source_map[addr] = SourceLine(rec.file, rec.line, rec.text)
        else:
            n = t.lens.get(key)
            if n is None:
                try:
                    n = length(t.instruction(key))
                except EncodingError as exc:
                    raise self._encoding_error(rec, p, exc, t.cols) from None
                if len(t.lens) > _TEMPLATE_LIMIT:
                    t.lens.clear()
                t.lens[key] = n
            data = bytes(n)
            cycles = None
        self._emit(rec, data, p.op_col)
        self._list(rec, addr, data, cycles)  # type: ignore[arg-type]

    def _compile_instruction(self, rec: _Rec, p: _Parsed) -> _Insn | None:
        """The compiled form of an instruction line (a function of its text), or None where
        :meth:`_instruction_plain` raises for its text whatever the symbols and the state (unknown mnemonic, bad
        size, an operand's syntax)."""
        mn = p.op or ""
        alias = None
        if mn in _ALIASES:
            canon, warn = _ALIASES[mn]
            alias = mn if warn else None
            mn = canon
        rows = BY_MNEMONIC.get(mn)
        if rows is None:
            return None
        size = self._size_of(rec, p, mn, rows, raising=False)
        if size is _MISSING:
            return None
        ops: list[_Op] = []
        cols: list[int] = []
        if p.operands:
            try:
                toks = self._tokens(rec, p.operands, p.operand_col)
            except AssemblyError:
                return None
            for g in _split_commas(toks[:-1]):
                if not g:
                    return None
                cols.append(g[0].col)
                self.compiling = True
                try:
                    template = self._operand_uncached(rec, g, _no_symbols)
                except AssemblyError:
                    return None
                finally:
                    self.compiling = False
                ps = self.operand_parser
                f = template.value if callable(template.value) else None
                ex = _Expr(f, ps.pure, ps.used_here) if f is not None else None  # type: ignore[attr-defined]
                ops.append(_Op(template, ex, ps.used_here, cols[-1]))
        modes = [o.mode for o in ops]
        if mn in _TO_A_FORM and len(ops) == 2 and modes[1] is Mode.AREG:
            mn = _TO_A_FORM[mn]
        if mn == "cmp" and len(ops) == 2 and all(m is Mode.APOSTINC for m in modes):
            mn = "cmpm"
        if mn == "movem" and len(ops) == 2:
            regs = (Mode.DREG, Mode.AREG)
            for k in (0, 1):
                if modes[k] in regs and modes[1 - k] not in regs:
                    r = ops[k].const
                    assert r is not None
                    mask = Operand(Mode.REGLIST, value=1 << (r.reg + (8 if r.mode is Mode.AREG else 0)))
                    ops[k] = _Op(mask, None, False, ops[k].col)
        return _Insn(mn, size, alias, ops, cols)  # type: ignore[arg-type]

    def _size_of(self, rec: _Rec, p: _Parsed, mn: str, rows: object, raising: bool = True) -> object:
        """The instruction's size from its suffix (branches: .W unless .s/.b); a bad suffix raises, or returns
        ``_MISSING`` when not ``raising``."""
        is_branch = any(r.is_branch for r in rows)  # type: ignore[attr-defined]
        size: Size | None = None
        if p.size is not None:
            legal = {s for r in rows for s in r.sizes if s is not None}  # type: ignore[attr-defined]
            if is_branch:
                legal |= {Size.B} if Size.S in legal else set()
            letter = p.size
            if letter not in ("b", "w", "l", "s") or Size(letter) not in legal:
                if not raising:
                    return _MISSING
                allowed = "/".join("." + s.value for s in sorted(legal, key=lambda s: "bwls".index(s.value)))
                raise rec.where().error(
                    f"bad size suffix '.{p.size}' for '{mn}' (allowed: {allowed or 'none'})", p.size_col
                )
            size = Size(letter)
            if is_branch and size is Size.B:
                size = Size.S
        elif is_branch:
            size = Size.W
        return size

    def _encoding_error(self, rec: _Rec, p: _Parsed, exc: EncodingError, cols: list[int]) -> AssemblyError:
        col = p.operand_col if p.operands else p.op_col
        m = re.search(r"\boperand (\d+)\b", str(exc))
        if m is not None and 1 <= int(m.group(1)) <= len(cols):
            col = cols[int(m.group(1)) - 1]  # point at the operand the encoder names
        written = f"{p.op_text} {p.operands}".strip()
        return rec.where().error(f"cannot encode '{written}': {exc}", col)

    def _pc_warning(self, rec: _Rec, col: int, disp: int) -> None:
        self.warnings.append(
            f"{rec.file}:{rec.line}:{col}: warning: the number in x(pc) is taken as the target address "
            f"${disp & 0xFFFFFF:06X} (GNU as would take a plain number as the displacement)"
        )

    def _instruction_plain(self, rec: _Rec, p: _Parsed) -> None:
        mn = p.op or ""
        if mn in _ALIASES:
            canon, warn = _ALIASES[mn]
            if warn and self.final:
                self.warnings.append(
                    f"{rec.file}:{rec.line}:{p.op_col}: warning: '{mn}' is not a 68000 mnemonic; assembled as "
                    f"'{canon}'"
                )
            mn = canon
        rows = BY_MNEMONIC.get(mn)
        if rows is None:
            raise rec.where().error(f"unknown mnemonic '{p.op_text}'", p.op_col)
        size = self._size_of(rec, p, mn, rows)
        if self.section.name == "bss":
            raise rec.where().error("instruction in the bss section", p.op_col)
        self._require_even(rec, "instruction", p.op_col)
        operands = self._operands(rec, p)
        if mn in _TO_A_FORM and len(operands) == 2 and operands[1].mode is Mode.AREG:
            mn = _TO_A_FORM[mn]
        if mn == "cmp" and len(operands) == 2 and all(op.mode is Mode.APOSTINC for op in operands):
            mn = "cmpm"  # CMP (Ay)+,(Ax)+ has one encoding, CMPM (as GNU as and Motorola assemblers do)
        if mn == "movem" and len(operands) == 2:  # a one-register list written as a plain register
            regs = (Mode.DREG, Mode.AREG)
            for k in (0, 1):
                if operands[k].mode in regs and operands[1 - k].mode not in regs:
                    r = operands[k]
                    operands[k] = Operand(Mode.REGLIST, value=1 << (r.reg + (8 if r.mode is Mode.AREG else 0)))
        instr = Instruction(mn, size, tuple(operands))
        addr = self._here()
        try:
            if self.final:  # len(encode(i)) == length(i): tests/test_isa_codec.py checks it for every form
                data = _SHARED_CODE.get((instr, addr))  # type: ignore[assignment]
                if data is None:
                    data = _shared(_SHARED_CODE)[(instr, addr)] = encode(instr, addr)
                n = len(data)
            else:
                n = _SHARED_LENGTH.get(instr)  # type: ignore[assignment]
                if n is None:
                    n = _shared(_SHARED_LENGTH)[instr] = length(instr)
                data = bytes(n)
        except EncodingError as exc:
            raise self._encoding_error(rec, p, exc, self.operand_cols) from None
        cycles = None
        if self.final:
            self.source_map[addr] = SourceLine(rec.file, rec.line, rec.text)
            cycles = _SHARED_CYCLES.get(instr, _MISSING)  # type: ignore[assignment]
            if cycles is _MISSING:
                cycles = _shared(_SHARED_CYCLES)[instr] = _cycle_range(instr)
        self._emit(rec, data, p.op_col)
        self._list(rec, addr, data, cycles)

    def _operands(self, rec: _Rec, p: _Parsed) -> list[Operand]:
        self.operand_cols: list[int] = []
        if not p.operands:
            return []
        toks = self._tokens(rec, p.operands, p.operand_col)
        groups = _split_commas(toks[:-1])
        out = []
        for g in groups:
            if not g:
                raise rec.where().error("missing operand", toks[0].col if toks else p.operand_col)
            self.operand_cols.append(g[0].col)
            out.append(self._operand(rec, g))
        return out

    def _operand(self, rec: _Rec, toks: list[Token]) -> Operand:
        return self._operand_uncached(rec, toks, self._resolver(rec, strict=False))

    def _operand_uncached(self, rec: _Rec, toks: list[Token], resolve: Callable[[str, Token], int]) -> Operand:
        """Parse one operand (evaluating its expression; while ``self.compiling``, building its evaluator,
        which takes the place of the value in the returned template)."""
        end = Token("end", "", toks[-1].col + len(toks[-1].text))
        t = toks + [end]
        where = rec.where()
        ps = self.operand_parser = (compile_parser(t, where, _symbol_node) if self.compiling
                                    else ExprParser(t, where, resolve, self._here()))
        self.label_ref = False

        def reg_at(i: int) -> tuple[Mode, int] | None:
            tok = t[i]
            return _REGISTERS.get(tok.text.lower()) if tok.kind == "ident" else None

        def is_pc(i: int) -> bool:
            return t[i].kind == "ident" and t[i].text.lower() == "pc"

        def finish() -> None:
            if ps.tok.kind != "end":
                raise ps.error(f"unexpected '{ps.tok.text}' in operand")

        first = t[0]
        if first.kind == "ident" and first.text.lower() in _UNSUPPORTED_REGS:
            raise where.error(f"register '{first.text}' is not supported by this 68000 subset", first.col)
        # #immediate
        if first.kind == "hash":
            ps.next()
            value = ps.parse()
            finish()
            return Operand(Mode.IMM, value=value)
        # Dn, An, register list
        r = reg_at(0)
        if r is not None:
            if t[1].kind == "end":
                return Operand(r[0], reg=r[1])
            if t[1].kind == "op" and t[1].text in ("-", "/"):
                return Operand(Mode.REGLIST, value=self._reglist(rec, t))
            raise where.error(f"unexpected '{t[1].text}' after register '{first.text}'", t[1].col)
        if is_pc(0):
            raise where.error("'pc' is only allowed as a base register: write label(pc)", first.col)
        # -(An)
        if first.kind == "op" and first.text == "-" and t[1].kind == "lparen" and reg_at(2) and t[3].kind == "rparen":
            mode, num = reg_at(2)  # type: ignore[misc]
            if mode is not Mode.AREG:
                raise where.error("predecrement needs an address register", t[2].col)
            if t[4].kind != "end":
                raise where.error(f"unexpected '{t[4].text}' after -(An)", t[4].col)
            return Operand(Mode.APREDEC, reg=num)
        # (An) (An)+ (An,Xn) (PC...) (d,An) (d,An,Xn) (d,PC) (d,PC,Xn)
        if first.kind == "lparen":
            if reg_at(1) is not None or is_pc(1):
                ps.next()
                return self._indirect(rec, ps, None, first.col)
            save = ps.pos
            ps.next()
            disp = ps.parse()
            if ps.tok.kind == "comma":
                ps.next()
                return self._indirect(rec, ps, disp, first.col)
            ps.pos = save  # a parenthesized expression: (expr), (expr).w, (a+b)*2 ...
        value = ps.parse()
        if ps.tok.kind == "lparen":
            ps.next()
            return self._indirect(rec, ps, value, first.col)
        if ps.tok.kind == "size":
            size_tok = ps.next()
            finish()
            if size_tok.value == "w":
                return Operand(Mode.ABSW, value=value)
            if size_tok.value == "l":
                return Operand(Mode.ABSL, value=value)
            raise where.error(f"bad size suffix '{size_tok.text}' on an absolute address (use .w or .l)", size_tok.col)
        finish()
        return Operand(Mode.ABSL, value=value)

    def _indirect(self, rec: _Rec, ps: ExprParser, disp: int | None, col: int) -> Operand:
        """Parse after ``(`` [or ``d(`` / ``(d,``]: base register, optional index, ``)``, optional ``+``."""
        where = rec.where()
        base = ps.next()
        low = base.text.lower() if base.kind == "ident" else ""
        if low == "pc":
            pc = True
            num = 0
        elif low in _REGISTERS and _REGISTERS[low][0] is Mode.AREG:
            pc = False
            num = _REGISTERS[low][1]
        else:
            raise where.error(f"expected an address register or PC, found '{base.text or 'end of line'}'", base.col)
        index: IndexReg | None = None
        if ps.tok.kind == "comma":
            ps.next()
            xt = ps.next()
            xr = _REGISTERS.get(xt.text.lower()) if xt.kind == "ident" else None
            if xr is None:
                raise where.error(f"expected an index register, found '{xt.text or 'end of line'}'", xt.col)
            long = False
            if ps.tok.kind == "size":
                st = ps.next()
                if st.value not in ("w", "l"):
                    raise where.error(f"bad index size '{st.text}' (use .w or .l)", st.col)
                long = st.value == "l"
            index = IndexReg(xr[0] is Mode.AREG, xr[1], long)
        ps.expect("rparen", "')'")
        postinc = False
        if ps.tok.kind == "op" and ps.tok.text == "+":
            if disp is not None or index is not None or pc:
                raise ps.error("postincrement only applies to (An)")
            ps.next()
            postinc = True
        if ps.tok.kind != "end":
            raise ps.error(f"unexpected '{ps.tok.text}' in operand")
        if pc:
            if disp is None:
                raise where.error("PC-relative operand needs a target: write label(pc)", col)
            if not (ps.used_here or self.label_ref) and self.final and not self.compiling:
                self._pc_warning(rec, col, disp)
            return Operand(Mode.PCINDEX if index else Mode.PCDISP, value=disp, index=index)
        if postinc:
            return Operand(Mode.APOSTINC, reg=num)
        if index is not None:
            return Operand(Mode.AINDEX, reg=num, value=disp or 0, index=index)
        if disp is None:
            return Operand(Mode.AIND, reg=num)
        return Operand(Mode.ADISP, reg=num, value=disp)

    def _reglist(self, rec: _Rec, t: list[Token]) -> int:
        where = rec.where()
        mask = 0
        i = 0

        def reg_index(tok: Token) -> int:
            r = _REGISTERS.get(tok.text.lower()) if tok.kind == "ident" else None
            if r is None:
                raise where.error(f"expected a register in register list, found '{tok.text or 'end of line'}'", tok.col)
            return r[1] + (8 if r[0] is Mode.AREG else 0)

        while True:
            lo = reg_index(t[i])
            i += 1
            hi = lo
            if t[i].kind == "op" and t[i].text == "-":
                hi_tok = t[i + 1]
                hi = reg_index(hi_tok)
                if hi < lo:
                    raise where.error("register range must go upwards (e.g. d0-d3)", hi_tok.col)
                i += 2
            for k in range(lo, hi + 1):
                mask |= 1 << k
            if t[i].kind == "end":
                return mask
            if t[i].kind == "op" and t[i].text == "/":
                i += 1
                continue
            raise where.error(f"unexpected '{t[i].text}' in register list", t[i].col)

    # --- result ----------------------------------------------------------------------------------------------------
    def _program(self) -> Program:
        blocks: list[tuple[str, int, _Chunk]] = []
        segments: list[Segment] = []
        for name in _SECTIONS:
            for k, c in enumerate(self.sections[name].chunks):
                if c.size == 0:
                    continue
                seg_name = name if k == 0 else f"{name}.{k}"
                data = bytes(c.size) if name == "bss" else bytes(c.data)
                segments.append(Segment(seg_name, c.start, data, bss=name == "bss"))
                blocks.append((seg_name, k, c))
        ordered = sorted(segments, key=lambda s: s.origin)
        for a, b in zip(ordered, ordered[1:]):
            if a.origin + len(a.data) > b.origin:
                raise AssemblyError(
                    f"segments '{a.name}' (${a.origin:06X}-${a.origin + len(a.data) - 1:06X}) and '{b.name}' "
                    f"(${b.origin:06X}-${b.origin + len(b.data) - 1:06X}) overlap",
                    self.filename,
                    0,
                    0,
                )
        code_chunks = [c for c in self.sections["code"].chunks if c.size]
        origin = code_chunks[0].start if code_chunks else self.origin
        code = bytes(code_chunks[0].data) if code_chunks else b""
        symbols: dict[str, Symbol] = {}
        sizes = self._label_sizes()
        for s in sorted(self.cur.values(), key=lambda s: s.order):
            symbols[s.name] = Symbol(s.name, s.value, s.section, sizes.get(id(s), 0))
        return Program(segments, origin, code, symbols, self.listing, self.source_map, self.warnings)

    def _label_sizes(self) -> dict[int, int]:
        """Size of every label (keyed by ``id`` of its ``_Sym``), in O(n log n) for n labels.

        A label ends at the next label after it in (address, definition order) -- the next global label for a
        global one, the next label of any kind for a local one -- in its section, or at the end of its block
        (the last-created chunk of its section whose closed range holds its address), whichever comes first."""
        out: dict[int, int] = {}
        for name in _SECTIONS:
            labels = sorted((s for s in self.cur.values() if s.kind == "label" and s.section == name),
                            key=lambda s: (s.value, s.order))
            if not labels:
                continue
            values = [s.value for s in labels]
            # Block end per label: later chunks overwrite earlier ones (a label on the boundary of two blocks
            # belongs to the one created last). Each chunk touches only the labels inside its range.
            block_end = values[:]
            for c in self.sections[name].chunks:
                end = c.start + c.size
                for k in range(bisect.bisect_left(values, c.start), bisect.bisect_right(values, end)):
                    block_end[k] = end
            next_any: int | None = None
            next_global: int | None = None
            for k in range(len(labels) - 1, -1, -1):
                s = labels[k]
                end = block_end[k]
                nxt = next_any if s.local else next_global
                if nxt is not None and nxt <= end:
                    end = nxt
                out[id(s)] = max(end - s.value, 0)
                next_any = s.value
                if not s.local:
                    next_global = s.value
        return out


def decode_source(data: bytes, filename: str) -> str:
    """The text of a source file's bytes: UTF-8 (a leading byte-order mark is dropped). A byte sequence that is
    not UTF-8 (say one Latin-1 byte in a comment) raises :class:`~isa.errors.AssemblyError` at its
    ``file:line:col``, naming the byte, rather than a byte offset into the file."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        start = exc.start
        before = _NEWLINE_RE.split(data[:start].decode("utf-8"))
        line, col = len(before), len(before[-1]) + 1
        text = _NEWLINE_RE.split(data.decode("utf-8", errors="replace"))[line - 1]
        if line == 1 and text.startswith("\ufeff"):
            text, col = text[1:], col - 1
        raise AssemblyError(f"byte ${data[start]:02X} is not UTF-8 (save the file as UTF-8)", filename, line, col,
                            text) from None


def _symbol_node(name: str, tok: Token) -> Callable[[_Assembler], int]:
    """The evaluator of a symbol in a compiled expression (what the plain resolver does, its dictionary key
    worked out once)."""
    low = name.lower()
    if low in _RESERVED or name.startswith(".") or name.endswith("$"):
        return lambda ev: ev.sym(name, tok)
    return lambda ev: ev.sym_global(name, low, tok)


def _no_symbols(name: str, tok: Token) -> int:  # pragma: no cover - a compiling parser resolves nothing
    raise AssertionError(name)


def _macro_note(calls: list[tuple[str, str]]) -> str:
    """Where an expanded line comes from: the macro calls innermost first; beyond three levels only the two
    innermost and the outermost are named (a runaway recursion does not repeat the same call 64 times)."""
    parts = [f"in macro '{name}' called at {at}" for name, at in reversed(calls)]
    if len(parts) > 3:
        parts = parts[:2] + [f"{len(parts) - 3} more macro levels"] + parts[-1:]
    return "; ".join(parts)


def _cycle_range(instr: Instruction) -> tuple[int, int] | None:
    """``isa.timing.cycle_range(instr)``; None if timing cannot price this instruction."""
    from isa.timing import cycle_range  # noqa: PLC0415

    return cycle_range(instr)


def assemble(
    text: str,
    filename: str = "<source>",
    origin: int = 0,
    include_paths: Sequence[str | Path] = (),
    defines: Mapping[str, int] | None = None,
) -> Program:
    """Assemble Motorola-syntax 68000 source ``text`` into a :class:`~isa.program.Program`.

    ``filename`` names the source in errors, the listing and the source map, and INCLUDE paths are relative to
    its directory (then to each of ``include_paths``, in order). ``origin`` is the byte address of the first code
    byte (even, 24-bit). ``defines`` pre-sets EQU symbols (integers). Raises :class:`~isa.errors.AssemblyError`
    (``file:line:col: message`` plus the line and a caret) for any error in the source."""
    if not isinstance(text, str):
        raise AssemblyError(f"source must be text, not {type(text).__name__}", filename, 0, 0)
    return _Assembler(text, filename, origin, include_paths, defines).run()

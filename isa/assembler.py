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

Modules (no cycles; each docstring states its side of the contract): this module keeps ``assemble``, the
driver and its passes, line dispatch, symbols, expressions, the location counter, data (``DC``/``DS``/``DCB``),
instructions (compiled and plain) and the resulting Program; :mod:`isa.asm_lex` the source text (decoding,
lines, statement fields, the vocabulary); :mod:`isa.asm_compiled` the compiled forms of lines and the
process-wide memos (``clear_memos``); :mod:`isa.asm_operands` the operand syntax and :mod:`isa.asm_directives`
the other directives, conditionals and macros, both mixins of ``_Assembler``. They import each other only in
that order (lex <- compiled <- operands, directives <- assembler); none imports this module.
"""

from __future__ import annotations

import bisect
import os
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from isa.asm_compiled import (
    _MISSING,
    _SHARED_ARGS,
    _SHARED_CODE,
    _SHARED_CYCLES,
    _SHARED_DATA,
    _SHARED_EXPANSIONS,
    _SHARED_EXPRS,
    _SHARED_INSNS,
    _SHARED_LENGTH,
    _SHARED_LENIENT,
    _SHARED_PARSE,
    _SHARED_TOKENS,
    _TEMPLATE_LIMIT,
    _DataT,
    _Expr,
    _Insn,
    _Op,
    _no_symbols,
    _shared,
    _symbol_node,
    clear_memos,
)
from isa.asm_directives import _Cond, _Directives, _End, _Macro
from isa.asm_lex import (
    _ALIASES,
    _K_COND,
    _K_ENDM,
    _K_EQU,
    _K_MACRO,
    _K_NONE,
    _K_OTHER,
    _IF_OPS,
    _RESERVED,
    ADDRESS_LIMIT,
    _Parsed,
    _Rec,
    _kind,
    _parse_fields_uncached,
    _recs_of,
    _split_commas,
    decode_source,
)
from isa.asm_operands import _OperandSyntax
from isa.encoder import encode, length
from isa.errors import AssemblyError, EncodingError
from isa.expr import ExprParser, Token, Where, compile_parser, tokenize
from isa.listing import format_listing
from isa.operands import Instruction, Mode, Operand, Size
from isa.program import ListingLine, Program, Segment, SourceLine, Symbol
from isa.table import BY_MNEMONIC

__all__ = ["ADDRESS_LIMIT", "AssemblyError", "assemble", "clear_memos", "decode_source", "format_listing"]

_MAX_PASSES = 12
#: Run passes after the first as the final one (see ``_Assembler.run``); a test switches it off to compare.
_SPECULATE = True
_MAX_EXPANDED_LINES = 1_000_000

_SECTIONS = ("code", "data", "bss")

_TO_A_FORM = {"move": "movea", "add": "adda", "sub": "suba", "cmp": "cmpa"}
_DATA_RANGE = {1: (-0x80, 0xFF), 2: (-0x8000, 0xFFFF), 4: (-0x8000_0000, 0xFFFF_FFFF)}


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


#: Use the compiled forms (False: every line the plain way, the reference a test compares against).
_COMPILE = True


class _Assembler(_Directives, _OperandSyntax):
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
        self.main_recs = _recs_of(text, filename)
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

    def _line(self, rec: _Rec, cond_base: int) -> None:  # noqa: C901 - one branch per kind of source line (macro body, conditional, label, directive, instruction)
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
        p = _SHARED_PARSE.get(rec.text)
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
            p = _parse_fields_uncached(rec, lenient)
            p.kind = _kind(p.op)
            memo[rec.text] = p
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
        return _Expr(f, parser.pure, parser.used_here)

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
            _SHARED_EXPRS[key] = ex
        if ex is None or not _COMPILE:
            return self._eval_tokens(rec, self._tokens(rec, text, col), strict, what)
        return self._value(rec, ex, strict)

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

    @staticmethod
    def _template_or_plain(rec: _Rec, p: _Parsed, shared: dict[Any, Any], make: Callable[[_Rec, _Parsed], Any],
                           plain: Callable[[_Rec, _Parsed], None]) -> Any:
        """The compiled template of an instruction or data line, shared by every line of the same (op, size,
        operand field, column), which is all it depends on, and kept on the line's fields; or None after running
        the line the plain way (``plain``) when it does not compile or compiling is off."""
        t = p.template
        if t is None:
            key = (p.op, p.size, p.operands, p.operand_col)
            t = shared.get(key)
            if t is None:
                t = shared[key] = make(rec, p) or False
            p.template = t
        if t is False or not _COMPILE:
            plain(rec, p)
            return None
        return t

    # --- data (DC, DS, DCB) ---------------------------------------------------------------------------------------
    def _data(self, rec: _Rec, p: _Parsed) -> None:
        t = p.template
        if t is None or t is False or not _COMPILE:
            t = self._template_or_plain(rec, p, _SHARED_DATA, self._compile_data, self._data_plain)
            if t is None:
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
                    buf += self._pack(rec, self._value(rec, ex), width, col)
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
                const = None
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

    # --- instructions ----------------------------------------------------------------------------------------------
    def _instruction(self, rec: _Rec, p: _Parsed) -> None:
        t = p.template
        if t is None or t is False or not _COMPILE:
            t = self._template_or_plain(rec, p, _SHARED_INSNS, self._compile_instruction, self._instruction_plain)
            if t is None:
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
        self._list(rec, addr, data, cycles)

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
                ex = _Expr(f, ps.pure, ps.used_here) if f is not None else None
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
        return _Insn(mn, size, alias, ops, cols)

    def _size_of(self, rec: _Rec, p: _Parsed, mn: str, rows: object, raising: bool = True) -> object:
        """The instruction's size from its suffix (branches: .W unless .s/.b); a bad suffix raises, or returns
        ``_MISSING`` when not ``raising``."""
        is_branch = any(r.is_branch for r in rows)
        size: Size | None = None
        if p.size is not None:
            legal = {s for r in rows for s in r.sizes if s is not None}
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
            if self.final:  # len(encode(i)) == length(i): tests/isa/test_codec.py checks it for every form
                data = _SHARED_CODE.get((instr, addr))
                if data is None:
                    data = _shared(_SHARED_CODE)[(instr, addr)] = encode(instr, addr)
                n = len(data)
            else:
                n = _SHARED_LENGTH.get(instr)
                if n is None:
                    n = _shared(_SHARED_LENGTH)[instr] = length(instr)
                data = bytes(n)
        except EncodingError as exc:
            raise self._encoding_error(rec, p, exc, self.operand_cols) from None
        cycles = None
        if self.final:
            self.source_map[addr] = SourceLine(rec.file, rec.line, rec.text)
            cycles = _SHARED_CYCLES.get(instr, _MISSING)
            if cycles is _MISSING:
                cycles = _shared(_SHARED_CYCLES)[instr] = _cycle_range(instr)
        self._emit(rec, data, p.op_col)
        self._list(rec, addr, data, cycles)

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


def _cycle_range(instr: Instruction) -> tuple[int, int] | None:
    """``isa.timing.cycle_range(instr)``; None if timing cannot price this instruction."""
    from isa.timing import cycle_range

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

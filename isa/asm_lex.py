"""Source text of the assembler (:mod:`isa.assembler`): decoding, lines, statement fields and the vocabulary.

Contract: pure functions of text; no assembly state, no memo (the assembler memoises what it calls here, in
:mod:`isa.asm_compiled`). Errors are :class:`~isa.errors.AssemblyError` at the line's ``file:line:col``.

* ``decode_source(data, filename) -> str``: a source file's bytes as text (UTF-8, a byte-order mark dropped).
* ``_recs_of(text, filename) -> list[_Rec]``: the lines (ending at ``\\n``, ``\\r\\n`` or ``\\r`` only), numbered
  from 1. A :class:`_Rec` is one line to process: file, line, text and the macro-expansion note of its errors.
* ``_parse_fields_uncached(rec, lenient) -> _Parsed``: one line split into label, operation, size and operand
  field with their 1-based columns (a function of ``rec.text`` alone; ``rec`` only names the line in errors).
  ``lenient`` (inactive IF branches, macro bodies) returns what was recognised instead of raising. The caller
  sets ``_Parsed.kind`` from the operation (``_kind``: one of the ``_K_*`` statement kinds).
* ``_find_comment`` (where the ``;`` comment starts, outside quotes), ``_split_args`` (a macro call's arguments,
  ``<a,b>`` grouping one), ``_split_commas`` (a token list at top-level commas: operands, DC items).
* The vocabulary the other parts check names against: ``_DIRECTIVES``, ``_IF_OPS``, the mnemonic ``_ALIASES``,
  ``_REGISTERS`` (name -> mode and number), ``_UNSUPPORTED_REGS``, ``_RESERVED`` (no symbol or macro may be named
  so), and ``ADDRESS_LIMIT`` (the 24-bit address space).

Imports only :mod:`isa.errors`, :mod:`isa.expr`, :mod:`isa.operands` and :mod:`isa.table`.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import NamedTuple

from isa.errors import AssemblyError
from isa.expr import Token, Where
from isa.operands import Mode
from isa.table import BY_MNEMONIC

#: Highest address + 1 of the 24-bit address space.
ADDRESS_LIMIT = 1 << 24

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


def _unquoted(text: str) -> Iterator[tuple[int, str]]:
    """``(index, character)`` of each character of ``text`` that is neither a quote nor inside '...' or "..."."""
    quote = ""
    for i, ch in enumerate(text):
        if quote:
            if ch == quote:
                quote = ""
        elif ch in "'\"":
            quote = ch
        else:
            yield i, ch


def _find_comment(text: str) -> int:
    """Index of the ``;`` starting the comment (outside quotes), or ``len(text)``."""
    for i, ch in _unquoted(text):
        if ch == ";":
            return i
    return len(text)


def _split_args(text: str) -> list[tuple[str, int]]:
    """Split a macro argument field at top-level commas: (argument, offset) pairs; ``<a,b>`` groups one argument."""
    out: list[tuple[str, int]] = []
    depth = 0
    start = 0
    for i, ch in _unquoted(text):
        if ch in "(<":
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


def _recs_of(text: str, filename: str) -> list[_Rec]:
    # Lines end at \n, \r\n or \r only (str.splitlines also breaks at \f, \v, \x1c.. and U+2028, which
    # would put every later line number off from what an editor shows).
    lines = _NEWLINE_RE.split(text[1:] if text.startswith("\ufeff") else text)
    if lines and lines[-1] == "":
        lines.pop()
    return [_Rec(filename, i + 1, line) for i, line in enumerate(lines)]



def _parse_fields_uncached(rec: _Rec, lenient: bool) -> _Parsed:
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

"""Compiled lines of the assembler and the process-wide memos of its per-line work (:mod:`isa.assembler`).

What a line *is* depends on its text only (and a field's starting column), so it is compiled once per process
and shared by every pass and every assembly; only values are evaluated per pass:

* ``_Expr``: an expression compiled by :func:`isa.expr.compile_parser` (``const`` its value when it uses no
  symbol and no ``*``). Its evaluator ``f(ev)`` takes the assembler as ``ev``: ``*`` calls ``ev.star()``, errors
  ``ev.where()``, and the symbol nodes made by ``_symbol_node`` call ``ev.sym(name, tok)`` or, for a plain global
  name, ``ev.sym_global(name, low, tok)``.
* ``_Op``: an operand with mode, registers and index fixed and its value an evaluator (``const`` when fixed).
* ``_Insn``: an instruction line after aliases and the A-form/CMPM/MOVEM choices; it memoises its Instruction and
  length, its bytes at an address and its cycle range per tuple of its non-constant operand values (each dict
  cleared past ``_TEMPLATE_LIMIT``).
* ``_DataT``: a DC/DS/DCB line (width, count/value expressions, items; the bytes when all are constant).

The ``_SHARED_*`` memos below are filled by :mod:`isa.assembler` and :mod:`isa.asm_directives` (what each key
holds is documented at each); ``_shared(memo)`` bounds one, ``clear_memos()`` empties all, ``_MISSING`` is the
"not memoised" sentinel. No assembly state is kept here. Imports only :mod:`isa.asm_lex`, :mod:`isa.expr` and
:mod:`isa.operands`.
"""

from __future__ import annotations

from collections.abc import Callable

from isa.asm_lex import _RESERVED, _Parsed, _Rec
from isa.expr import Evaluator, Token, constant_value
from isa.operands import Instruction, Mode, Operand, Size

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
_SHARED_EXPANSIONS: dict[tuple, tuple[str, ...]] = {}  # (body, params, args, size, \@)
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


def _shared(memo: dict) -> dict:
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


def _symbol_node(name: str, tok: Token) -> Evaluator:
    """The evaluator of a symbol in a compiled expression (what the plain resolver does, its dictionary key
    worked out once)."""
    low = name.lower()
    if low in _RESERVED or name.startswith(".") or name.endswith("$"):
        return lambda ev: ev.sym(name, tok)
    return lambda ev: ev.sym_global(name, low, tok)


def _no_symbols(name: str, tok: Token) -> int:  # pragma: no cover - a compiling parser resolves nothing
    raise AssertionError(name)

"""Lexer and expression evaluator of the assembler (private to :mod:`isa.assembler`).

Expressions are integer-valued (Python ints, no wrap-around; the consumer range-checks). Operators, highest
precedence first (C-like, all left-associative)::

    unary  - + ~ !
    *  /  %          ( / and % truncate toward zero, as C and GNU as do; division by zero is an error )
    +  -
    <<  >>           ( >> is arithmetic )
    &
    ^
    |
    == != <> < <= > >=   ( 1 when true, 0 when false )

Primaries: decimal ``123``, ``$7F`` / ``0x7F`` hex, ``%1010`` binary, ``@17`` octal, ``'c'`` / ``'ab'`` character
constants (up to 4 characters, big-endian), symbols, local labels ``.name`` and ``1$``, ``*`` (the current
location, where an operand is expected), and parentheses.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from isa.errors import AssemblyError

SIZE_LETTERS = frozenset("bwls")


@dataclass(frozen=True)
class Token:
    """One lexical token: ``kind`` is ``num ident str op size hash comma lparen rparen end``; ``col`` is the 1-based
    column in the source line; ``value`` holds the number (``num``), the size letter (``size``) or the string
    contents (``str``)."""

    kind: str
    text: str
    col: int
    value: object = None


class Where:
    """Error context of one source line: raises :class:`AssemblyError` with file, line, column and text."""

    def __init__(self, file: str, line: int, text: str, note: str = "") -> None:
        self.file = file
        self.line = line
        self.text = text
        self.note = note

    def error(self, message: str, col: int) -> AssemblyError:
        """Build an :class:`AssemblyError` for ``message`` at 1-based column ``col`` of this line."""
        if self.note:
            message = f"{message} ({self.note})"
        return AssemblyError(message, self.file, self.line, max(col, 1), self.text)


_TERM_END = frozenset({"num", "ident", "str", "rparen", "size"})
_TWO_CHAR_OPS = ("<<", ">>", "<=", ">=", "==", "!=", "<>")
_ONE_CHAR_OPS = "+-*/%&|^~!<>"


def _is_ident_start(ch: str) -> bool:
    return ch.isascii() and (ch.isalpha() or ch == "_")


def _is_ident_char(ch: str) -> bool:
    return ch.isascii() and (ch.isalnum() or ch == "_")


#: One-character punctuation tokens: character -> kind.
_PUNCT: dict[str, str] = {"#": "hash", ",": "comma", "(": "lparen", ")": "rparen"}


def tokenize(text: str, col0: int, where: Where) -> list[Token]:
    """Split an operand field into tokens. ``col0`` is the 1-based column of ``text[0]`` in the source line.

    Raises :class:`AssemblyError` for characters that cannot start a token, bad numbers and unterminated
    strings."""
    tokens: list[Token] = []
    i = 0
    n = len(text)
    while i < n:
        ch = text[i]
        col = col0 + i
        if ch in " \t":
            i += 1
            continue
        if ch.isdigit():
            tok, i = _decimal(text, i, col, where)
        elif ch == "$" or (ch in "%@" and not _ends_term(tokens)):
            tok, i = _based(text, i, col, where)
        elif _is_ident_start(ch):
            j = i + 1
            while j < n and _is_ident_char(text[j]):
                j += 1
            tok, i = Token("ident", text[i:j], col), j
        elif ch == ".":
            tok, i = _dotted(text, i, col, where, _ends_term(tokens))
        elif ch in "'\"":
            tok, i = _string(text, i, col, where)
        elif ch in _PUNCT:
            tok, i = Token(_PUNCT[ch], ch, col), i + 1
        elif text[i : i + 2] in _TWO_CHAR_OPS:
            tok, i = Token("op", text[i : i + 2], col), i + 2
        elif ch in _ONE_CHAR_OPS:
            tok, i = Token("op", ch, col), i + 1
        elif ch == "=":
            tok, i = Token("op", "==", col), i + 1
        else:
            raise where.error(f"unexpected character {ch!r}", col)
        tokens.append(tok)
    tokens.append(Token("end", "", col0 + n))
    return tokens


def _ends_term(tokens: list[Token]) -> bool:
    """Whether the last token so far ends a term (then '%' is the modulo operator and '.' may be a size suffix)."""
    return bool(tokens) and tokens[-1].kind in _TERM_END


def _word_end(text: str, j: int) -> int:
    """The index after the identifier characters of ``text`` from ``j`` on."""
    n = len(text)
    while j < n and _is_ident_char(text[j]):
        j += 1
    return j


def _decimal(text: str, i: int, col: int, where: Where) -> tuple[Token, int]:
    """The token at ``text[i]`` (a digit): a decimal or 0x number, or a numeric local label ``1$``; and the index
    after it."""
    j = _word_end(text, i)
    word = text[i:j]
    if j < len(text) and text[j] == "$" and word.isdigit():
        return Token("ident", word + "$", col), j + 1
    try:
        if word[:2].lower() == "0x":
            value = int(word[2:], 16)
        else:
            value = int(word, 10)
    except ValueError:
        raise where.error(f"bad number '{word}'", col) from None
    return Token("num", word, col, value), j


def _based(text: str, i: int, col: int, where: Where) -> tuple[Token, int]:
    """The number at ``text[i]`` written with a base prefix ($ hex, % binary, @ octal), and the index after it."""
    base = {"$": 16, "%": 2, "@": 8}[text[i]]
    j = _word_end(text, i + 1)
    word = text[i + 1 : j]
    try:
        if not word:
            raise ValueError
        value = int(word, base)
    except ValueError:
        raise where.error(f"bad number '{text[i:j]}'", col) from None
    return Token("num", text[i:j], col, value), j


def _dotted(text: str, i: int, col: int, where: Where, term: bool) -> tuple[Token, int]:
    """The token at ``text[i]`` (a '.'): a size suffix glued to the term before (``term``), else a local label or
    a dotted identifier; and the index after it."""
    j = _word_end(text, i + 1)
    word = text[i + 1 : j]
    if not word:
        raise where.error("stray '.'", col)
    glued = i > 0 and text[i - 1] not in " \t"
    if glued and term and word.lower() in SIZE_LETTERS:
        return Token("size", text[i:j], col, word.lower()), j
    if word[0].isdigit() and not word.isdigit():
        raise where.error(f"bad local label '.{word}'", col)
    return Token("ident", text[i:j], col), j


def _string(text: str, i: int, col: int, where: Where) -> tuple[Token, int]:
    """The quoted string at ``text[i]`` (a doubled quote stands for one quote character), and the index after it."""
    ch = text[i]
    n = len(text)
    j = i + 1
    chars: list[str] = []
    while True:
        if j >= n:
            raise where.error("unterminated string", col)
        if text[j] == ch:
            if j + 1 < n and text[j + 1] == ch:  # doubled quote = one quote character
                chars.append(ch)
                j += 2
                continue
            break
        chars.append(text[j])
        j += 1
    return Token("str", text[i : j + 1], col, "".join(chars)), j + 1


#: Binary operator precedence levels, lowest first.
_LEVELS: tuple[frozenset[str], ...] = (
    frozenset({"==", "!=", "<>", "<", "<=", ">", ">="}),
    frozenset({"|"}),
    frozenset({"^"}),
    frozenset({"&"}),
    frozenset({"<<", ">>"}),
    frozenset({"+", "-"}),
    frozenset({"*", "/", "%"}),
)

#: Largest shift count accepted in an expression (keeps a fuzzer from building huge ints).
_MAX_SHIFT = 64
#: Deepest nesting of parentheses and unary operators accepted (keeps recursion far from Python's limit).
_MAX_DEPTH = 40


def _c_div(a: int, b: int) -> int:
    q = abs(a) // abs(b)
    return q if (a >= 0) == (b >= 0) else -q


class ExprParser:
    """Recursive-descent evaluator over a token list.

    ``resolve(name, token)`` returns a symbol's value (it raises or returns a placeholder for undefined symbols);
    ``here`` is the current location for ``*``."""

    def __init__(
        self, tokens: list[Token], where: Where, resolve: Callable[[str, Token], int], here: int | None
    ) -> None:
        self.tokens = tokens
        self.pos = 0
        self.where = where
        self.resolve = resolve
        self.here = here
        self.depth = 0
        self.used_here = False  #: set when ``*`` was evaluated

    @property
    def tok(self) -> Token:
        """The current token."""
        return self.tokens[self.pos]

    def next(self) -> Token:
        """Consume and return the current token."""
        t = self.tokens[self.pos]
        if t.kind != "end":
            self.pos += 1
        return t

    def error(self, message: str, tok: Token | None = None) -> AssemblyError:
        """An :class:`AssemblyError` at ``tok`` (default: the current token)."""
        return self.where.error(message, (tok or self.tok).col)

    def expect(self, kind: str, what: str) -> Token:
        """Consume a token of ``kind`` or raise naming ``what`` was expected."""
        if self.tok.kind != kind:
            raise self.error(f"expected {what}, found {self._describe(self.tok)}")
        return self.next()

    @staticmethod
    def _describe(tok: Token) -> str:
        return "end of line" if tok.kind == "end" else f"'{tok.text}'"

    def parse(self, level: int = 0) -> int:
        """Parse and evaluate an expression starting at the current token (binary level ``level``)."""
        if level == len(_LEVELS):
            return self.unary()
        if level == 0:
            self.depth += 1
            if self.depth > _MAX_DEPTH:
                raise self.error("expression nested too deeply")
            try:
                return self._binary(0)
            finally:
                self.depth -= 1
        return self._binary(level)

    def _binary(self, level: int) -> int:
        left = self.parse(level + 1)
        ops = _LEVELS[level]
        while self.tok.kind == "op" and self.tok.text in ops:
            op_tok = self.next()
            right = self.parse(level + 1)
            left = self._apply(op_tok, left, right)
        return left

    def _apply(self, op_tok: Token, a: int, b: int) -> int:
        op = op_tok.text
        if op == "+":
            return a + b
        if op == "-":
            return a - b
        if op == "*":
            r = a * b
            if abs(r) >= 1 << 128:
                raise self.error("expression value too large", op_tok)
            return r
        if op in ("/", "%"):
            if b == 0:
                raise self.error("division by zero in expression", op_tok)
            q = _c_div(a, b)
            return q if op == "/" else a - q * b
        if op in ("<<", ">>"):
            if b < 0 or b > _MAX_SHIFT:
                raise self.error(f"shift count {b} out of range 0..{_MAX_SHIFT}", op_tok)
            return a << b if op == "<<" else a >> b
        if op == "&":
            return a & b
        if op == "|":
            return a | b
        if op == "^":
            return a ^ b
        return int(
            {
                "==": a == b,
                "!=": a != b,
                "<>": a != b,
                "<": a < b,
                "<=": a <= b,
                ">": a > b,
                ">=": a >= b,
            }[op]
        )

    def unary(self) -> int:
        """Parse a unary expression."""
        t = self.tok
        if t.kind == "op" and t.text in ("-", "+", "~", "!"):
            self.next()
            self.depth += 1
            if self.depth > _MAX_DEPTH:
                raise self.error("expression nested too deeply")
            v = self.unary()
            self.depth -= 1
            return self._apply_unary(t.text, v)
        return self.primary()

    def _apply_unary(self, op: str, v: int) -> int:
        """The value of unary ``op`` applied to ``v`` (a compiling parser combines nodes instead)."""
        return {"-": -v, "+": v, "~": ~v, "!": int(v == 0)}[op]

    def primary(self) -> int:
        """Parse a number, symbol, character constant, ``*`` or parenthesized expression."""
        t = self.next()
        if t.kind == "num":
            return int(t.value)
        if t.kind == "ident":
            return self.resolve(t.text, t)
        if t.kind == "str":
            s = str(t.value)
            if not 1 <= len(s) <= 4:
                raise self.error(f"character constant {t.text} must hold 1 to 4 characters", t)
            v = 0
            for ch in s:
                if ord(ch) > 255:
                    raise self.error(f"character {ch!r} is not an 8-bit character", t)
                v = (v << 8) | ord(ch)
            return v
        if t.kind == "op" and t.text == "*":
            if self.here is None:
                raise self.error("'*' (current location) is not available here", t)
            self.used_here = True
            return self.here
        if t.kind == "lparen":
            v = self.parse()
            self.expect("rparen", "')'")
            return v
        raise self.error(f"expected an expression, found {self._describe(t)}", t)


# --- compiled expressions --------------------------------------------------------------------------------------------
#: An evaluator built by :func:`compile_expr`: ``f(ev) -> int`` where ``ev`` provides ``ev.sym(name, token) -> int``
#: (the symbol resolver), ``ev.star() -> int`` (the current location) and ``ev.where() -> Where`` (for errors).
Evaluator = Callable[[object], int]


def _raise_at(ev: object, message: str, tok: Token) -> int:
    raise ev.where().error(message, tok.col)


def _node_binary(op_tok: Token, a: Evaluator, b: Evaluator) -> Evaluator:  # one case per operator
    """``a op b`` evaluated left operand first, raising exactly what :meth:`ExprParser._apply` raises."""
    op = op_tok.text
    if op == "+":
        return lambda ev: a(ev) + b(ev)
    if op == "-":
        return lambda ev: a(ev) - b(ev)
    if op == "&":
        return lambda ev: a(ev) & b(ev)
    if op == "|":
        return lambda ev: a(ev) | b(ev)
    if op == "^":
        return lambda ev: a(ev) ^ b(ev)
    if op == "*":
        def mul(ev: object) -> int:
            r = a(ev) * b(ev)
            if abs(r) >= 1 << 128:
                return _raise_at(ev, "expression value too large", op_tok)
            return r
        return mul
    if op in ("/", "%"):
        def div(ev: object) -> int:
            x = a(ev)
            y = b(ev)
            if y == 0:
                return _raise_at(ev, "division by zero in expression", op_tok)
            q = _c_div(x, y)
            return q if op == "/" else x - q * y
        return div
    if op in ("<<", ">>"):
        def shift(ev: object) -> int:
            x = a(ev)
            y = b(ev)
            if y < 0 or y > _MAX_SHIFT:
                return _raise_at(ev, f"shift count {y} out of range 0..{_MAX_SHIFT}", op_tok)
            return x << y if op == "<<" else x >> y
        return shift
    compare = {"==": int.__eq__, "!=": int.__ne__, "<>": int.__ne__, "<": int.__lt__, "<=": int.__le__,
               ">": int.__gt__, ">=": int.__ge__}[op]
    return lambda ev: int(compare(a(ev), b(ev)))


def _node_unary(op: str, v: Evaluator) -> Evaluator:
    if op == "-":
        return lambda ev: -v(ev)
    if op == "+":
        return v
    if op == "~":
        return lambda ev: ~v(ev)
    return lambda ev: int(v(ev) == 0)


class _Compiler(ExprParser):
    """:class:`ExprParser`'s grammar (``parse``, ``_binary``, ``expect``, the depth limit: inherited, so it accepts
    exactly the token lists the interpreter accepts) building an evaluator instead of a value. Everything the
    interpreter checks while parsing raises here (as :class:`AssemblyError`: the caller then evaluates that
    text the interpreter's way, which raises it at its place); what it checks while evaluating (division by
    zero, shift counts, size, the resolver's errors) the evaluator checks, in the same order (left to right,
    operands before their operator)."""

    def __init__(self, tokens: list[Token], where: Where,
                 symbol: Callable[[str, Token], Evaluator] | None = None) -> None:
        super().__init__(tokens, where, _no_resolve, 0)
        self.pure = True  #: no symbol and no ``*`` in what was compiled
        self.symbol = symbol or _symbol_node

    def _apply(self, op_tok: Token, a: int, b: int) -> int:
        return _node_binary(op_tok, a, b)  # type: ignore[return-value]  # an evaluator is a Callable[[ev], int]; the node builders are typed as such closures

    def _apply_unary(self, op: str, v: int) -> int:
        return _node_unary(op, v)  # type: ignore[return-value]  # as above: a node closure

    def primary(self) -> int:
        t = self.tok
        if t.kind == "ident":
            self.next()
            self.pure = False
            return self.symbol(t.text, t)  # type: ignore[return-value]  # as above: a node closure
        if t.kind == "op" and t.text == "*":
            self.next()
            self.pure = False
            self.used_here = True
            return (lambda ev: ev.star())  # type: ignore[return-value]  # a lambda is the node closure
        if t.kind == "lparen":
            self.next()
            v = self.parse()
            self.expect("rparen", "')'")
            return v
        value = super().primary()  # a number or a character constant (its checks), or the interpreter's error
        return (lambda ev: value)  # type: ignore[return-value]  # a lambda is the node closure


def _symbol_node(name: str, tok: Token) -> Evaluator:
    return lambda ev: ev.sym(name, tok)


def _no_resolve(name: str, tok: Token) -> int:  # pragma: no cover - the compiler never resolves
    raise AssertionError(name)


def compile_parser(tokens: list[Token], where: Where,
                   symbol: Callable[[str, Token], Evaluator] | None = None) -> ExprParser:
    """A parser over ``tokens`` whose :meth:`~ExprParser.parse` returns an evaluator (see :data:`Evaluator`)
    rather than a value; ``used_here`` is set when the parsed text holds ``*``, ``pure`` stays True when it holds
    neither ``*`` nor a symbol. ``symbol(name, token)`` makes the evaluator of a symbol (default: one calling
    ``ev.sym(name, token)``)."""
    return _Compiler(tokens, where, symbol)


class _ConstEv:
    """The evaluation context of a pure expression: anything it would need is a bug; errors are signalled."""

    def where(self) -> Where:
        return Where("", 0, "")

    def sym(self, name: str, tok: Token) -> int:  # pragma: no cover - pure expressions resolve nothing
        raise AssertionError(name)

    star = sym


def constant_value(f: Evaluator) -> int | None:
    """The value of a pure evaluator, or None if evaluating it raises (then it raises each time it runs)."""
    try:
        return f(_ConstEv())
    except AssemblyError:
        return None

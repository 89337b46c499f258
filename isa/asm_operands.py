"""Operand syntax of the assembler: an operand's tokens -> :class:`~isa.operands.Operand` (:mod:`isa.assembler`).

``_OperandSyntax`` is a mixin of ``isa.assembler._Assembler`` (the host):

* ``_operands(rec, p) -> list[Operand]``: the operand field of an instruction line, each operand's column kept
  in the host's ``operand_cols`` (the encoder's "operand N" errors point there). ``_operand(rec, toks)``: one
  operand, its expression evaluated with the host's resolver.
* ``_operand_uncached(rec, toks, resolve)``: the syntax: ``#imm``, ``Dn``/``An``, register lists (``_reglist``),
  ``-(An)``, ``(An)``, ``(An)+``, ``d(An)``/``(d,An)``, ``d(An,Xn)``, ``d(PC)``, ``d(PC,Xn)`` (``_indirect``),
  absolute ``x``/``x.w``/``x.l``. While the host's ``compiling`` is set it evaluates nothing: it builds the
  expression's evaluator with :func:`isa.expr.compile_parser` (symbols via
  :func:`isa.asm_compiled._symbol_node`), which takes the place of the value in the returned Operand, and leaves
  the parser in ``operand_parser`` (its ``pure`` and ``used_here``) for the caller; no warning then.
* ``_pc_warning(rec, col, disp)``: the warning for a plain number in ``x(pc)`` (also given by the host's compiled
  instruction path).

It uses from the host: ``_tokens``, ``_resolver``, ``_here`` and the attributes ``final``, ``compiling``,
``label_ref`` (cleared here per operand, set by the resolver when an expression uses a label or an unknown
symbol) and ``warnings``. Errors are :class:`~isa.errors.AssemblyError` at the offending token's column.
Imports only :mod:`isa.asm_compiled`, :mod:`isa.asm_lex`, :mod:`isa.expr` and :mod:`isa.operands`.
"""

from __future__ import annotations

from collections.abc import Callable

from isa.asm_compiled import _symbol_node
from isa.asm_lex import _REGISTERS, _UNSUPPORTED_REGS, _Parsed, _Rec, _split_commas
from isa.expr import ExprParser, Token, compile_parser
from isa.operands import IndexReg, Mode, Operand


class _OperandSyntax:
    """Operand parsing of :class:`isa.assembler._Assembler` (a mixin; see the module docstring)."""

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

    def _operand_uncached(self, rec: _Rec, toks: list[Token], resolve: Callable[[str, Token], int]) -> Operand:  # noqa: C901 - one branch per 68000 addressing-mode syntax
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
            mode, num = reg_at(2)  # type: ignore[misc]  # reg_at returns a pair here (a register token was matched)
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

    def _pc_warning(self, rec: _Rec, col: int, disp: int) -> None:
        self.warnings.append(
            f"{rec.file}:{rec.line}:{col}: warning: the number in x(pc) is taken as the target address "
            f"${disp & 0xFFFFFF:06X} (GNU as would take a plain number as the displacement)"
        )

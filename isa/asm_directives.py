"""Directives of the assembler (:mod:`isa.assembler`) other than the data ones: ``EQU``/``SET``/``=``, ``ORG``,
``EVEN``, ``ALIGN``, sections, ``INCLUDE``, ``FAIL``, ``END``, the conditionals and the macros.

``_Directives`` is a mixin of ``isa.assembler._Assembler`` (the host). The host's ``_line`` calls
``_equ(rec, p)``, ``_directive(rec, p)`` (which hands ``DC``/``DS``/``DCB`` back to the host's ``_data``),
``_cond_op(rec, p, cond_base)``, ``_macro_def(rec, p)`` and ``_expand(rec, p)``; ``END`` raises ``_End``, which
the host's ``_pass`` catches. Per-pass state kept on the host (reset by its ``_pass``): ``conds`` (the stack of
``_Cond``), ``macros`` (lower-case name -> ``_Macro``), ``defining`` (the macro being collected; the host's
``_line`` appends its body and closes it at ``ENDM``), ``unique`` (the ``\\@`` counter), ``macro_calls`` and
``include_stack``; per assembly ``file_cache`` (INCLUDE path -> lines) and ``include_paths``. It uses from the
host: ``_eval``/``_tokens`` (expressions), ``_define``/``_qualify``/``cur`` (symbols), ``_here``/``_emit``/
``section``/``sections`` (location counter), ``_list``, ``_active`` and ``_unit`` (to process an included file
or a macro expansion, which recurses into the host's line processing). INCLUDE files and expansion texts are
memoised in :mod:`isa.asm_compiled`. Imports only :mod:`isa.asm_compiled`, :mod:`isa.asm_lex`, :mod:`isa.expr`
and :mod:`isa.table`.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

from isa.asm_compiled import _SHARED_ARGS, _SHARED_EXPANSIONS, _SHARED_FILES, _SHARED_FILES_LIMIT
from isa.asm_lex import (
    _ALIASES,
    _DIRECTIVES,
    _IF_OPS,
    _RESERVED,
    ADDRESS_LIMIT,
    _Parsed,
    _Rec,
    _recs_of,
    _split_args,
    decode_source,
)
from isa.expr import Where
from isa.table import BY_MNEMONIC

_MAX_INCLUDE_DEPTH = 32
_MAX_MACRO_DEPTH = 64

_SECTION_NAMES = {"code": "code", "text": "code", "data": "data", "bss": "bss"}
_MACRO_ARG_RE = re.compile(r"\\(@|[0-9]|[A-Za-z_][A-Za-z0-9_]*)")


@dataclass
class _Macro:
    name: str
    params: list[str]
    body: list[_Rec]
    rec: _Rec


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


class _Directives:
    """Directives, conditionals and macros of :class:`isa.assembler._Assembler` (a mixin; see the module
    docstring)."""

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
                recs = _SHARED_FILES[(str(path), data)] = _recs_of(text, str(path))
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

def _macro_note(calls: list[tuple[str, str]]) -> str:
    """Where an expanded line comes from: the macro calls innermost first; beyond three levels only the two
    innermost and the outermost are named (a runaway recursion does not repeat the same call 64 times)."""
    parts = [f"in macro '{name}' called at {at}" for name, at in reversed(calls)]
    if len(parts) > 3:
        parts = parts[:2] + [f"{len(parts) - 3} more macro levels"] + parts[-1:]
    return "; ".join(parts)

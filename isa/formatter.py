"""Instruction -> text: Motorola syntax for people and the assembler, GNU as syntax for the encoding oracle.

Motorola form (:func:`format_instruction`), read back by :mod:`isa.assembler`::

    move.l d0,(a1)+        addq.w #1,d3           lea $1234(a0),a1      moveq #-1,d0
    move.w 8(a0,d1.w),d2   cmpi.l #$12345,($FF8000).w                 movem.l d0-d2/a0,-(a7)
    add.l ($00123456).l,d0                        lea $001234(pc),a0    beq.s $001040

* numbers: decimal when |v| < 1024, else ``$`` hex (``-$8000``); addresses always ``$`` hex;
* ``abs.W``/``abs.L`` are written ``($addr).w`` / ``($addr).l`` (explicit, never left to the assembler);
* PC-relative operands and branch targets are written as the *absolute target address*
  (``$001234(pc)``, ``bra.s $001040``), the Motorola convention ``label(pc)``;
* the size suffix is written when the row encodes a size (``Row.suffix``), so ``lea``, ``moveq``, ``swap``,
  ``exg``, ``dbcc`` and ``scc`` carry none; branches carry ``.s``/``.w``.

GNU form (:func:`format_gnu`) is what ``m68k-linux-gnu-as -m68000`` accepts: ``%`` register prefixes,
``(d,%an)`` / ``(d,%an,%xn.w)`` / ``(d,%pc)`` operands, ``0x`` hex, and targets written relative to a label so
that GNU as computes the same displacements (``(L7+0x2,%pc)``, ``bra.s L9``).
"""

from __future__ import annotations

from collections.abc import Callable

from isa.errors import EncodingError
from isa.operands import IndexReg, Instruction, Mode, Operand
from isa.table import Row


def _row(instr: Instruction) -> Row | None:
    from isa.encoder import select

    try:
        return select(instr).row
    except EncodingError:
        return None


def _num(v: int, prefix: str = "$") -> str:
    """A signed number: decimal when small, hex (``$`` or ``0x`` prefix) otherwise."""
    if -1024 < v < 1024:
        return str(v)
    return ("-" if v < 0 else "") + prefix + f"{abs(v):X}"


def _reglist(mask: int, pct: str = "") -> str:
    """``d0-d2/a0`` form of a canonical MOVEM mask (bit i = Di, bit 8+i = Ai)."""
    parts: list[str] = []
    for bank, letter in ((0, "d"), (8, "a")):
        i = 0
        while i < 8:
            if mask >> (bank + i) & 1:
                j = i
                while j + 1 < 8 and mask >> (bank + j + 1) & 1:
                    j += 1
                first = f"{pct}{letter}{i}"
                parts.append(first if j == i else f"{first}-{pct}{letter}{j}")
                i = j + 1
            else:
                i += 1
    return "/".join(parts) if parts else "#0"


def _index(idx: IndexReg | None, pct: str = "") -> str:
    if idx is None:
        return f"{pct}d0.w"
    return f"{pct}{'a' if idx.is_areg else 'd'}{idx.num}.{'l' if idx.long else 'w'}"


def _suffix(instr: Instruction, row: Row | None) -> str:
    if instr.size is None:
        return ""
    if row is not None and not row.suffix and not row.is_branch:
        return ""
    return "." + instr.size.value


def format_operand(op: Operand) -> str:
    """One operand in Motorola syntax (PC-relative operands and branch targets as absolute target addresses)."""
    m = op.mode
    if m is Mode.DREG:
        return f"d{op.reg}"
    if m is Mode.AREG:
        return f"a{op.reg}"
    if m is Mode.AIND:
        return f"(a{op.reg})"
    if m is Mode.APOSTINC:
        return f"(a{op.reg})+"
    if m is Mode.APREDEC:
        return f"-(a{op.reg})"
    if m is Mode.ADISP:
        return f"{_num(op.value)}(a{op.reg})"
    if m is Mode.AINDEX:
        return f"{_num(op.value)}(a{op.reg},{_index(op.index)})"
    if m is Mode.ABSW:
        return f"(${op.value & 0xFFFFFF:06X}).w"
    if m is Mode.ABSL:
        return f"(${op.value & 0xFFFFFFFF:06X}).l"
    if m is Mode.PCDISP:
        return f"${op.value & 0xFFFFFF:06X}(pc)"
    if m is Mode.PCINDEX:
        return f"${op.value & 0xFFFFFF:06X}(pc,{_index(op.index)})"
    if m is Mode.IMM:
        return "#" + _num(op.value)
    if m is Mode.REGLIST:
        return _reglist(op.value)
    raise EncodingError(f"cannot format operand mode {m}")


def format_instruction(instr: Instruction) -> str:
    """``instr`` in Motorola syntax, e.g. ``move.l d0,(a1)+`` (see the module docstring for the conventions)."""
    row = _row(instr)
    text = instr.mnemonic + _suffix(instr, row)
    ops = []
    for op in instr.operands:
        if row is not None and row.handler in ("bcc", "bra", "bsr", "dbcc") and op.mode in (Mode.ABSL, Mode.ABSW):
            ops.append(f"${op.value & 0xFFFFFF:06X}")  # branch target
        else:
            ops.append(format_operand(op))
    return text + (" " + ",".join(ops) if ops else "")


def _gnu_target(value: int, symbolize: Callable[[int], str] | None) -> str:
    if symbolize is None:
        return _num(value, "0x")
    return symbolize(value)


def format_gnu_operand(op: Operand, symbolize: Callable[[int], str] | None = None) -> str:
    """One operand in GNU as syntax; PC-relative targets through ``symbolize`` (see :func:`format_gnu`)."""
    m = op.mode
    if m is Mode.DREG:
        return f"%d{op.reg}"
    if m is Mode.AREG:
        return f"%a{op.reg}"
    if m is Mode.AIND:
        return f"(%a{op.reg})"
    if m is Mode.APOSTINC:
        return f"(%a{op.reg})+"
    if m is Mode.APREDEC:
        return f"-(%a{op.reg})"
    if m is Mode.ADISP:
        return f"({_num(op.value, '0x')},%a{op.reg})"
    if m is Mode.AINDEX:
        return f"({_num(op.value, '0x')},%a{op.reg},{_index(op.index, '%')})"
    if m is Mode.ABSW:
        v = op.value & 0xFFFF
        return f"({v - 0x10000 if v & 0x8000 else v}).w"
    if m is Mode.ABSL:
        return f"(0x{op.value & 0xFFFFFFFF:x}).l"
    if m is Mode.PCDISP:
        return f"({_gnu_target(op.value, symbolize)},%pc)"
    if m is Mode.PCINDEX:
        return f"({_gnu_target(op.value, symbolize)},%pc,{_index(op.index, '%')})"
    if m is Mode.IMM:
        return "#" + _num(op.value, "0x")
    if m is Mode.REGLIST:
        return _reglist(op.value, "%")
    raise EncodingError(f"cannot format operand mode {m}")


def format_gnu(instr: Instruction, symbolize: Callable[[int], str] | None = None, address: int | None = None) -> str:
    """``instr`` in ``m68k-linux-gnu-as -m68000`` syntax (``move.l %d0,(%a1)+``).

    Branch and PC-relative targets are written ``symbolize(target_address)`` (e.g. ``L12+0x4`` for a label GNU as
    knows, so that it computes the displacement itself; keep the addend small: GNU as rejects a PC-relative
    ``sym+addend`` whose addend does not fit 16 bits, and silently wraps an out-of-range forward displacement).
    Without ``symbolize`` targets are plain numbers, which GNU as treats as absolute symbols.

    GNU as rejects ``(sym,%pc,%xn)`` whose displacement comes out 0 ("invalid byte branch offset"); when the
    instruction's ``address`` is given, such an operand is written ``(%pc,%xn)``."""
    from isa.encoder import extension_offsets

    row = _row(instr)
    text = instr.mnemonic + _suffix(instr, row)
    ops = []
    offsets = extension_offsets(instr) if address is not None and row is not None else None
    for i, op in enumerate(instr.operands):
        off = offsets[i] if offsets is not None else None
        if op.mode is Mode.PCINDEX and address is not None and off is not None and op.value == address + off:
            ops.append(f"(%pc,{_index(op.index, '%')})")
        elif row is not None and row.handler in ("bcc", "bra", "bsr", "dbcc") and op.mode in (Mode.ABSL, Mode.ABSW):
            ops.append(_gnu_target(op.value, symbolize))
        else:
            ops.append(format_gnu_operand(op, symbolize))
    return text + (" " + ",".join(ops) if ops else "")


__all__ = ["format_instruction", "format_operand", "format_gnu", "format_gnu_operand"]

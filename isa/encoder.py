"""Instruction -> machine code, derived from :data:`isa.table.TABLE` (no second opcode table).

``encode(instr, address)`` returns the big-endian bytes of one instruction placed at ``address`` (needed for
PC-relative operands and branches). ``length(instr)`` is the byte length; it depends only on the mnemonic, size
and operand modes, never on operand values, so an assembler can size forward references in pass 1.

Operand conventions are those of :mod:`isa.operands` (PC-relative operands and branch targets hold the *target
address*). Every violation raises :class:`isa.errors.EncodingError` with a message naming the instruction and the
offending operand/value.
"""

from __future__ import annotations

from dataclasses import dataclass

from isa.errors import EncodingError
from isa.operands import Instruction, Mode, Operand, Size
from isa.table import MODE7_REG, MODE_FIELD, OperandSpec, Row, match_mnemonic

#: Extension words per EA mode (immediates depend on the size; see :func:`ea_words`).
_EA_WORDS: dict[Mode, int] = {
    Mode.DREG: 0, Mode.AREG: 0, Mode.AIND: 0, Mode.APOSTINC: 0, Mode.APREDEC: 0, Mode.ADISP: 1, Mode.AINDEX: 1,
    Mode.ABSW: 1, Mode.ABSL: 2, Mode.PCDISP: 1, Mode.PCINDEX: 1,
}  # fmt: skip


def ea_words(mode: Mode, size: Size | None) -> int:
    """Number of 16-bit extension words of an EA in ``mode`` for an operation of ``size`` (immediates: .L = 2)."""
    if mode is Mode.IMM:
        return 2 if size is Size.L else 1
    return _EA_WORDS.get(mode, 0)


@dataclass(frozen=True)
class Selected:
    """The row an instruction encodes with: row, condition code (or None), effective size, operands in row order."""

    row: Row
    cond: int | None
    size: Size | None
    operands: tuple[Operand, ...]


def _describe(instr: Instruction) -> str:
    suffix = f".{instr.size.value}" if instr.size is not None else ""
    modes = ",".join(op.mode.value for op in instr.operands)
    return f"{instr.mnemonic}{suffix} {modes}".rstrip()


def _effective_size(row: Row, size: Size | None) -> Size | None | str:
    """The row size an instruction size means, or an error string."""
    if row.is_branch:
        if size is None:
            size = Size.W
        elif size is Size.B:
            size = Size.S
    elif size is None:
        if len(row.sizes) == 1:
            return row.sizes[0]
        if Size.W in row.sizes:
            return Size.W  # Motorola default size
    if size not in row.sizes:
        legal = "/".join("." + s.value for s in row.sizes if s is not None) or "no size suffix"
        return f"size .{size.value if size else '?'} not allowed (allowed: {legal})"
    return size


def _match_operand(row: Row, i: int, spec: OperandSpec, op: Operand, size: Size | None) -> Operand | str:
    """``op`` normalized for slot ``spec`` (reglist from a single register), or an error string."""
    kind = spec.kind
    if kind == "reglist":
        if op.mode is Mode.REGLIST:
            return op
        if op.mode in (Mode.DREG, Mode.AREG):  # a one-register list written as a plain register
            return Operand(Mode.REGLIST, value=1 << (op.reg + (8 if op.mode is Mode.AREG else 0)))
        return f"operand {i + 1} must be a register list, not {op.mode.value}"
    if kind == "branch":
        if op.mode in (Mode.ABSL, Mode.ABSW):
            return op
        return f"operand {i + 1} must be a branch target, not {op.mode.value}"
    allowed = row.allowed_modes(i, size)
    if op.mode not in allowed:
        names = ", ".join(m.value for m in sorted(allowed, key=lambda m: list(Mode).index(m)))
        return f"operand {i + 1} mode {op.mode.value} not allowed (allowed: {names})"
    if op.mode in (Mode.DREG, Mode.AREG, Mode.AIND, Mode.APOSTINC, Mode.APREDEC, Mode.ADISP, Mode.AINDEX):
        if not 0 <= op.reg <= 7:
            return f"operand {i + 1}: register number {op.reg} out of range 0..7"
    return op


def select(instr: Instruction) -> Selected:
    """Choose the :data:`~isa.table.TABLE` row for ``instr`` (by mnemonic, size and operand modes, never values).

    Raises :class:`EncodingError` for an unknown mnemonic, an illegal size, a wrong operand count or a mode the
    instruction does not allow."""
    candidates = match_mnemonic(instr.mnemonic)
    if not candidates:
        raise EncodingError(f"unknown mnemonic {instr.mnemonic!r}")
    # Report the failure of the row that came closest: right operand count first, then how far matching got.
    best: tuple[int, str] = (-1, "")
    for row, cond in candidates:
        count_ok = 100 if len(instr.operands) == len(row.operands) else 0
        size = _effective_size(row, instr.size)
        if isinstance(size, str):
            best = max(best, (count_ok + 1, size))
            continue
        orders = [instr.operands]
        if row.swappable and len(instr.operands) == 2:
            orders.append(instr.operands[::-1])
        for ops in orders:
            if len(ops) != len(row.operands):
                best = max(best, (0, f"expects {len(row.operands)} operand(s), got {len(ops)}"))
                continue
            matched: list[Operand] = []
            for i, (spec, op) in enumerate(zip(row.operands, ops)):
                res = _match_operand(row, i, spec, op, size)
                if isinstance(res, str):
                    best = max(best, (count_ok + 2 + i, res))
                    break
                matched.append(res)
            else:
                return Selected(row, cond, size, tuple(matched))
    raise EncodingError(f"{_describe(instr)}: {best[1]}")


def _op_words(spec: OperandSpec, op: Operand, size: Size | None) -> int:
    if spec.kind in ("ea", "imm"):
        return ea_words(op.mode, size)
    if spec.kind == "reglist":
        return 1
    if spec.kind == "branch":
        return 0 if spec.data_field else 1
    return 0


def length(instr: Instruction) -> int:
    """Byte length of ``instr`` (2 + 2 per extension word); independent of operand values.

    Raises :class:`EncodingError` when no row accepts the instruction's mnemonic/size/modes."""
    sel = select(instr)
    return 2 + 2 * sum(_op_words(spec, op, sel.size) for spec, op in zip(sel.row.operands, sel.operands))


def extension_offsets(instr: Instruction) -> tuple[int | None, ...]:
    """Per operand (source order), the byte offset from the opcode of its first extension word, or None when the
    operand has none (PC-relative displacements are relative to that word)."""
    sel = select(instr)
    row = sel.row
    offsets: list[int | None] = [None] * len(row.operands)
    off = 2
    for i in row.extension_order:
        n = _op_words(row.operands[i], sel.operands[i], sel.size)
        if n:
            offsets[i] = off
        off += 2 * n
    if row.swappable and sel.operands != instr.operands:
        offsets.reverse()
    return tuple(offsets)


def _check(cond: bool, instr: Instruction, msg: str) -> None:
    if not cond:
        raise EncodingError(f"{_describe(instr)}: {msg}")


def _imm_words(instr: Instruction, value: int, size: Size | None) -> list[int]:
    if size is Size.L:
        _check(-(1 << 31) <= value <= 0xFFFFFFFF, instr, f"immediate {value} out of range for .l")
        v = value & 0xFFFFFFFF
        return [v >> 16, v & 0xFFFF]
    if size is Size.B:
        _check(-128 <= value <= 255, instr, f"immediate {value} out of range -128..255 for .b")
        return [value & 0xFFFF]  # as GNU as: a negative byte immediate is sign-extended into the word
    _check(-32768 <= value <= 65535, instr, f"immediate {value} out of range -32768..65535 for .w")
    return [value & 0xFFFF]


def _pc_disp(instr: Instruction, target: int, ext_address: int, bits: int, what: str) -> int:
    disp = target - ext_address
    lo, hi = -(1 << (bits - 1)), (1 << (bits - 1)) - 1
    if not lo <= disp <= hi:
        # Targets may be written as 24-bit addresses: retry modulo the 24-bit address space.
        wrapped = ((disp + (1 << 23)) & 0xFFFFFF) - (1 << 23)
        _check(lo <= wrapped <= hi, instr,
               f"{what} target ${target & 0xFFFFFFFF:X} is {disp} bytes away from ${ext_address & 0xFFFFFF:X}; "
               f"does not fit {bits} bits ({lo}..{hi})")
        disp = wrapped
    return disp & ((1 << bits) - 1)


def _ea_ext(instr: Instruction, op: Operand, size: Size | None, ext_address: int, i: int) -> list[int]:
    mode = op.mode
    if mode is Mode.ADISP:
        _check(-32768 <= op.value <= 32767, instr,
               f"operand {i + 1}: displacement {op.value} out of range -32768..32767")
        return [op.value & 0xFFFF]
    if mode in (Mode.AINDEX, Mode.PCINDEX):
        idx = op.index
        _check(idx is not None and 0 <= idx.num <= 7, instr, f"operand {i + 1}: missing or bad index register")
        assert idx is not None
        if mode is Mode.AINDEX:
            _check(-128 <= op.value <= 127, instr, f"operand {i + 1}: displacement {op.value} out of range -128..127")
            d8 = op.value & 0xFF
        else:
            d8 = _pc_disp(instr, op.value, ext_address, 8, f"operand {i + 1} PC-relative")
        return [(0x8000 if idx.is_areg else 0) | (idx.num << 12) | (0x800 if idx.long else 0) | d8]
    if mode is Mode.ABSW:
        v = op.value
        ok = -0x8000 <= v <= 0x7FFF or 0xFF8000 <= v <= 0xFFFFFF or 0xFFFF8000 <= v <= 0xFFFFFFFF
        _check(ok, instr, f"operand {i + 1}: address ${v & 0xFFFFFFFF:X} does not fit abs.w (sign-extended 16 bits)")
        return [v & 0xFFFF]
    if mode is Mode.ABSL:
        _check(-(1 << 31) <= op.value <= 0xFFFFFFFF, instr, f"operand {i + 1}: address {op.value} out of range")
        v = op.value & 0xFFFFFFFF
        return [v >> 16, v & 0xFFFF]
    if mode is Mode.PCDISP:
        return [_pc_disp(instr, op.value, ext_address, 16, f"operand {i + 1} PC-relative")]
    if mode is Mode.IMM:
        return _imm_words(instr, op.value, size)
    return []


def _reverse16(mask: int) -> int:
    return int(f"{mask:016b}"[::-1], 2)


def encode(instr: Instruction, address: int) -> bytes:
    """Machine code of ``instr`` placed at ``address`` (big-endian bytes, 2..10 long).

    Raises :class:`EncodingError` for an unknown mnemonic, illegal size or mode, immediate/quick value out of
    range for the size (ADDQ/SUBQ/shift count 1..8, MOVEQ -128..127, TRAP 0..15, .b -128..255, .w
    -32768..65535), a displacement that does not fit, an odd branch target or a ``Bcc.S`` whose displacement
    would be 0."""
    sel = select(instr)
    row, size = sel.row, sel.size
    word = row.fixed_bits
    if row.size_codes:
        assert isinstance(size, Size)
        word |= row.put("S", row.size_code_map[size])
    if row.conditional:
        assert sel.cond is not None
        word |= row.put("C", sel.cond)
    predec = any(op.mode is Mode.APREDEC for op in sel.operands)
    # Opcode fields first.
    for i, (spec, op) in enumerate(zip(row.operands, sel.operands)):
        kind = spec.kind
        if kind == "ea":
            assert spec.mode_field and spec.reg_field
            word |= row.put(spec.mode_field, MODE_FIELD[op.mode])
            word |= row.put(spec.reg_field, MODE7_REG[op.mode] if op.mode in MODE7_REG else op.reg)
        elif kind == "reg":
            assert spec.reg_field
            _check(0 <= op.reg <= 7, instr, f"operand {i + 1}: register number {op.reg} out of range 0..7")
            word |= row.put(spec.reg_field, op.reg)
        elif kind == "quick3":
            _check(1 <= op.value <= 8, instr, f"operand {i + 1}: quick value {op.value} out of range 1..8")
            word |= row.put("q", op.value & 7)
        elif kind == "quick8":
            _check(-128 <= op.value <= 127, instr, f"operand {i + 1}: moveq value {op.value} out of range -128..127")
            word |= row.put("i", op.value & 0xFF)
        elif kind == "vector":
            _check(0 <= op.value <= 15, instr, f"trap vector {op.value} out of range 0..15")
            word |= row.put("v", op.value)
    # Extension words in row order; PC-relative displacements are relative to their own extension word.
    pc = address + 2
    words: list[int] = []
    for i in row.extension_order:
        spec, op = row.operands[i], sel.operands[i]
        kind = spec.kind
        if kind in ("ea", "imm"):
            out = _ea_ext(instr, op, size, pc, i)
        elif kind == "reglist":
            _check(0 <= op.value <= 0xFFFF, instr, f"register mask ${op.value:X} out of range")
            out = [_reverse16(op.value) if predec else op.value]
        elif kind == "branch":
            target = op.value
            _check(target % 2 == 0, instr, f"branch target ${target & 0xFFFFFFFF:X} is odd")
            if spec.data_field:  # Bcc.S: 8-bit displacement in the opcode, relative to address + 2
                disp = target - (address + 2)
                wrapped = ((disp + (1 << 23)) & 0xFFFFFF) - (1 << 23)
                _check(-128 <= wrapped <= 127, instr,
                       f"branch target ${target & 0xFFFFFF:X} is {disp} bytes away; .s reaches -128..126")
                _check(wrapped != 0, instr, "branch .s to the next instruction (displacement 0) is not encodable;"
                       " use .w")
                word |= row.put("d", wrapped & 0xFF)
                out = []
            else:
                out = [_pc_disp(instr, target, address + 2, 16, "branch")]
        else:
            out = []
        words.extend(out)
        pc += 2 * len(out)
    return b"".join(w.to_bytes(2, "big") for w in [word, *words])

"""Machine code -> :class:`~isa.operands.Instruction`, derived from :data:`isa.table.TABLE`.

The opcode -> row relation is resolved per opcode word on first use (:func:`row_for`: among the rows whose fixed
bits agree with the word's top four bits, the one whose fixed bits and operand rules accept it; two such rows
are a table error and raise), so importing the decoder costs nothing: building all 65536 entries at import took
~0.2 s in every process that decoded anything. :data:`OPCODE_MAP`, the whole 65536-entry list, is built on first
access (tests, sweeps) from the same lookup, which raises for a word two rows claim. :func:`decode` reads the
opcode and its extension words through a caller-supplied
``fetch_word(address) -> int`` (16-bit, big-endian word at an even address) and returns a :class:`Decoded`.

Canonical form of decoded operands (what :func:`isa.encoder.encode` accepts back to the same bytes):

* immediates signed for their size (``addi.b #$FF`` decodes as ``#-1``), ADDQ/SUBQ/shift counts 1..8;
* ``d16(An)``/``d8(An,Xn)`` signed displacements; ``abs.W`` the sign-extended 24-bit address
  (``$8000.w`` -> ``$FF8000``); ``abs.L`` the full 32-bit extension value (the CPU ignores bits 31..24);
* PC-relative operands and branch targets as absolute 24-bit target addresses;
* brief extension words (``d8(An,Xn)``, ``d8(PC,Xn)``) as the 68000 reads them: bits 10..8 are ignored (the
  68020's scale and full-format bits), so such an instruction decodes to what the chip executes and re-encodes
  with those bits 0;
* MOVEM register masks in canonical order (bit i = Di, bit 8+i = Ai) whatever the addressing mode;
* sizes: the encoded size, the implied size of one-size rows (``lea`` -> ``Size.L``, ``muls`` -> ``Size.W``,
  ``scc`` -> ``Size.B``, ``dbcc`` -> ``Size.W``), ``Size.S``/``Size.W`` for branches, ``None`` for JMP, JSR, RTS,
  NOP, TRAP, ILLEGAL;
* mnemonics as :meth:`isa.table.Row.canonical_mnemonic` (``dbra``, ``bcc``/``bcs``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from isa.errors import IllegalInstruction
from isa.operands import IndexReg, Instruction, Mode, Operand, Size
from isa.table import TABLE, Row, ea_mode, matches, row_size


@dataclass(frozen=True)
class Decoded:
    """One decoded instruction: the instruction, its table row, its byte length, and the condition code (0..15)
    of conditional rows (Bcc/DBcc/Scc; BRA=0, BSR=1), else None."""

    instruction: Instruction
    row: Row
    length: int
    cond: int | None = None


#: The rows an opcode with these top four bits can belong to (those whose fixed bits there agree).
_BUCKETS: list[list[Row]] = [[r for r in TABLE if (n << 12 ^ r.fixed_bits) & r.fixed_mask & 0xF000 == 0]
                             for n in range(16)]

_UNSET = object()
#: Opcode word -> row or None, filled on first use by :func:`row_for`.
_ROWS: list[Any] = [_UNSET] * 65536  # a Row, None (not in the subset) or _UNSET (not looked up yet)


def row_for(word: int) -> Row | None:
    """The table row of opcode ``word`` (0..0xFFFF), or None if the word is not in the subset. Raises
    RuntimeError if two rows claim the word (a table error; building :data:`OPCODE_MAP` finds it for every
    word)."""
    word &= 0xFFFF
    row = _ROWS[word]
    if row is _UNSET:
        found = [r for r in _BUCKETS[word >> 12] if matches(r, word)]
        if len(found) > 1:
            raise RuntimeError(f"opcode ${word:04X} matches both {found[0]} and {found[1]}")
        row = _ROWS[word] = found[0] if found else None
    return row


OPCODE_MAP: list[Row | None]   # declared only: built by the module __getattr__ below on first access


def __getattr__(name: str) -> object:
    """``OPCODE_MAP``: opcode word -> row (None: not in the supported subset), all 65536 words, built on first
    access from :func:`row_for`, so with its one-row-per-word check on every word."""
    if name == "OPCODE_MAP":
        global OPCODE_MAP
        OPCODE_MAP = [row_for(w) for w in range(65536)]
        return OPCODE_MAP
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _s8(v: int) -> int:
    return v - 0x100 if v & 0x80 else v


def _s16(v: int) -> int:
    return v - 0x10000 if v & 0x8000 else v


def _s32(v: int) -> int:
    return v - 0x100000000 if v & 0x80000000 else v


def decode(fetch_word: Callable[[int], int], address: int) -> Decoded:  # noqa: C901 - one branch per extension-word and operand kind of the table's rows
    """Decode the instruction at ``address`` (even, 24-bit), reading words via ``fetch_word(addr) -> 0..0xFFFF``.

    Raises :class:`~isa.errors.IllegalInstruction` (with ``pc=address``) for an opcode word outside the subset.
    Errors raised by ``fetch_word`` (e.g. bus errors) propagate unchanged."""
    opcode = fetch_word(address) & 0xFFFF
    row = _ROWS[opcode]
    if row is _UNSET:
        row = row_for(opcode)
    if row is None:
        raise IllegalInstruction(f"illegal instruction ${opcode:04X}", pc=address, instruction=f"dc.w ${opcode:04X}")
    size = row_size(row, opcode)
    assert size is not False
    cond = row.get(opcode, "C") if row.conditional else None
    if row.handler == "bra":
        cond = 0
    elif row.handler == "bsr":
        cond = 1
    operands: list[Operand | None] = [None] * len(row.operands)
    pc = address + 2
    predec = False
    # Opcode-only operands first (and the EA modes, so MOVEM knows whether its mask is reversed).
    modes: dict[int, tuple[Mode, int]] = {}
    for i, spec in enumerate(row.operands):
        kind = spec.kind
        if kind == "ea":
            assert spec.mode_field and spec.reg_field
            r = row.get(opcode, spec.reg_field)
            mode = ea_mode(row.get(opcode, spec.mode_field), r)
            assert mode is not None
            modes[i] = (mode, r)
            predec = predec or mode is Mode.APREDEC
        elif kind == "reg":
            assert spec.reg_field
            (mode,) = spec.modes
            operands[i] = Operand(mode, row.get(opcode, spec.reg_field))
        elif kind == "quick3":
            operands[i] = Operand(Mode.IMM, value=row.get(opcode, "q") or 8)
        elif kind == "quick8":
            operands[i] = Operand(Mode.IMM, value=_s8(row.get(opcode, "i")))
        elif kind == "vector":
            operands[i] = Operand(Mode.IMM, value=row.get(opcode, "v"))
        elif kind == "branch" and spec.data_field:
            operands[i] = Operand(Mode.ABSL, value=(address + 2 + _s8(row.get(opcode, "d"))) & 0xFFFFFF)
    for i in row.extension_order:
        spec = row.operands[i]
        kind = spec.kind
        if kind == "reglist":
            mask = fetch_word(pc) & 0xFFFF
            pc += 2
            if predec:
                mask = int(f"{mask:016b}"[::-1], 2)
            operands[i] = Operand(Mode.REGLIST, value=mask)
        elif kind == "branch" and not spec.data_field:
            operands[i] = Operand(Mode.ABSL, value=(address + 2 + _s16(fetch_word(pc) & 0xFFFF)) & 0xFFFFFF)
            pc += 2
        elif kind == "imm" or kind == "ea":
            mode, r = modes[i] if kind == "ea" else (Mode.IMM, 0)
            if mode in (Mode.DREG, Mode.AREG, Mode.AIND, Mode.APOSTINC, Mode.APREDEC):
                operands[i] = Operand(mode, r)
            elif mode is Mode.ADISP:
                operands[i] = Operand(mode, r, _s16(fetch_word(pc) & 0xFFFF))
                pc += 2
            elif mode in (Mode.AINDEX, Mode.PCINDEX):
                # Brief extension word: D/A, register, W/L, bits 10..8, d8. The 68000 ignores bits 10..8 (the
                # 68020 reads them as scale and the full-format flag), so they are ignored here too: the
                # instruction is what the chip executes (re-encoding it gives those bits as 0).
                brief = fetch_word(pc) & 0xFFFF
                idx = IndexReg(bool(brief & 0x8000), (brief >> 12) & 7, bool(brief & 0x800))
                if mode is Mode.AINDEX:
                    operands[i] = Operand(mode, r, _s8(brief & 0xFF), idx)
                else:
                    operands[i] = Operand(mode, 0, (pc + _s8(brief & 0xFF)) & 0xFFFFFF, idx)
                pc += 2
            elif mode is Mode.ABSW:
                operands[i] = Operand(mode, 0, _s16(fetch_word(pc) & 0xFFFF) & 0xFFFFFF)
                pc += 2
            elif mode is Mode.ABSL:
                operands[i] = Operand(mode, 0, ((fetch_word(pc) & 0xFFFF) << 16) | (fetch_word(pc + 2) & 0xFFFF))
                pc += 4
            elif mode is Mode.PCDISP:
                operands[i] = Operand(mode, 0, (pc + _s16(fetch_word(pc) & 0xFFFF)) & 0xFFFFFF)
                pc += 2
            elif mode is Mode.IMM:
                if size is Size.L:
                    value = _s32(((fetch_word(pc) & 0xFFFF) << 16) | (fetch_word(pc + 2) & 0xFFFF))
                    pc += 4
                elif size is Size.B:
                    value = _s8(fetch_word(pc) & 0xFF)
                    pc += 2
                else:
                    value = _s16(fetch_word(pc) & 0xFFFF)
                    pc += 2
                operands[i] = Operand(mode, 0, value)
    assert all(op is not None for op in operands)
    instr = Instruction(row.canonical_mnemonic(cond if row.conditional else None), size,  # type: ignore[arg-type]  # size/operands are complete here for the row (checked by the table's tests)
                        tuple(operands))  # type: ignore[arg-type]  # the operand tuple is complete for the row
    return Decoded(instr, row, pc - address, cond)


def decode_bytes(data: bytes, address: int = 0, base: int = 0) -> Decoded:
    """Decode the instruction at ``address`` in ``data`` (``data[0]`` is at address ``base``).

    Raises :class:`~isa.errors.IllegalInstruction` for an illegal opcode or when the instruction runs past the
    end of ``data``."""

    def fetch(a: int) -> int:
        off = a - base
        if off < 0 or off + 2 > len(data):
            raise IllegalInstruction("instruction runs past the end of the code", pc=address)
        return int.from_bytes(data[off : off + 2], "big")

    return decode(fetch, address)

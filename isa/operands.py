"""Operand and instruction model shared by the assembler, encoder, decoder and interpreter.

This module is the contract between the parts of :mod:`isa`: the assembler parses source text into
:class:`Instruction` objects, the encoder turns them into bytes, the decoder turns bytes back into them, and the
formatter prints them in Motorola syntax that the assembler reads again. Nothing here knows about any program.

Conventions
-----------
* All values are Python ints. Addresses are 24-bit (0 .. 0xFFFFFF) once resolved; the encoder masks them.
* ``Operand.value`` means, by mode:
  - ``IMM``: the immediate value (may be negative; the encoder checks the range for the size).
  - ``ADISP``/``AINDEX``: the signed displacement (d16 / d8).
  - ``ABSW``/``ABSL``: the absolute address (``ABSW`` must fit a sign-extended 16-bit word).
  - ``PCDISP``/``PCINDEX``: the *target address* (the encoder computes the displacement from the extension-word
    address, as the 68000 does); the decoder reports the target address too.
  - ``REGLIST``: a 16-bit mask, bit i = Di for i in 0..7, bit 8+i = Ai (canonical order; the encoder reverses it
    for MOVEM with predecrement).
  - Branch targets (Bcc, BRA, BSR, DBcc): written as a bare expression, parsed as ``ABSL`` (or ``ABSW`` when written
    ``label.w``/``(label).w``); the encoder reads ``value`` as the target address.
* ``Operand.reg`` is the register number 0..7 for register modes and the base register for indirect modes.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field


class Mode(enum.Enum):
    """68000 effective-address modes (plus the register list used by MOVEM)."""

    DREG = "Dn"  #: data register direct
    AREG = "An"  #: address register direct
    AIND = "(An)"  #: address register indirect
    APOSTINC = "(An)+"  #: indirect with postincrement
    APREDEC = "-(An)"  #: indirect with predecrement
    ADISP = "d16(An)"  #: indirect with 16-bit displacement
    AINDEX = "d8(An,Xn)"  #: indirect with index and 8-bit displacement
    ABSW = "abs.W"  #: absolute short (sign-extended 16-bit address)
    ABSL = "abs.L"  #: absolute long
    PCDISP = "d16(PC)"  #: program counter with 16-bit displacement
    PCINDEX = "d8(PC,Xn)"  #: program counter with index and 8-bit displacement
    IMM = "#imm"  #: immediate
    REGLIST = "reglist"  #: MOVEM register list (not an effective address)


class Size(enum.Enum):
    """Operation size. ``S`` is the short (8-bit displacement) branch form written ``.s`` or ``.b``."""

    B = "b"
    W = "w"
    L = "l"
    S = "s"

    @property
    def bytes(self) -> int:
        """Operand width in bytes (1, 2 or 4); ``S`` counts as a byte displacement."""
        return {"b": 1, "w": 2, "l": 4, "s": 1}[self.value]


@dataclass(frozen=True)
class IndexReg:
    """Index register of the ``d8(An,Xn.size)`` / ``d8(PC,Xn.size)`` modes (the 68000 has no scale factor)."""

    is_areg: bool
    num: int
    long: bool = False  #: True for ``Xn.L``; False for ``Xn.W`` (sign-extended word, the default)


@dataclass(frozen=True)
class Operand:
    """One operand of an instruction; see the module docstring for what ``value`` holds per mode."""

    mode: Mode
    reg: int = 0
    value: int = 0
    index: IndexReg | None = None


@dataclass(frozen=True)
class Instruction:
    """A parsed or decoded instruction: canonical lower-case mnemonic (``"move"``, ``"beq"``, ``"dbra"``), size or
    ``None`` where the instruction has no size suffix, and operands in source order."""

    mnemonic: str
    size: Size | None
    operands: tuple[Operand, ...] = field(default_factory=tuple)

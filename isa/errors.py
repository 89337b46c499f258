"""Error types of :mod:`isa`. Every error the package raises for bad input or a faulting program is one of these."""

from __future__ import annotations


class IsaError(Exception):
    """Base class of every error :mod:`isa` raises on purpose."""


class EncodingError(IsaError):
    """An instruction cannot be encoded (operand not allowed, value out of range, unknown mnemonic/size).

    Raised by the encoder without source position; the assembler re-raises it as :class:`AssemblyError`."""


class AssemblyError(IsaError):
    """Bad assembly source. ``str()`` is ``file:line:col: message`` followed by the source line and a caret."""

    def __init__(self, message: str, file: str = "<source>", line: int = 0, col: int = 0, text: str = "") -> None:
        self.message = message
        self.file = file
        self.line = line
        self.col = col
        self.text = text
        where = f"{file}:{line}:{col}: {message}"
        if text:
            where += "\n    " + text.rstrip("\n") + "\n    " + " " * max(col - 1, 0) + "^"
        super().__init__(where)


class CPUFault(IsaError):
    """The emulated program faulted. ``pc`` is the address of the faulting instruction, ``instruction`` its
    disassembly (or ``"?"``), ``source`` ``"file:line"`` when known. Subclasses name the fault kind."""

    def __init__(self, message: str, pc: int, instruction: str = "?", source: str | None = None) -> None:
        self.pc = pc
        self.instruction = instruction
        self.source = source
        text = f"{message} at PC=${pc:06X} ({instruction})"
        if source:
            text += f" [{source}]"
        super().__init__(text)


class AddressError(CPUFault):
    """Word or long access at an odd address (or an odd PC)."""


class IllegalInstruction(CPUFault):
    """An opcode word that is not an instruction of the supported subset, or ILLEGAL."""


class DivideByZero(CPUFault):
    """DIVS/DIVU with a zero divisor."""


class BusError(CPUFault):
    """Access to an address outside mapped memory, or a write to read-only memory."""


class LimitExceeded(CPUFault):
    """A run went past its instruction or cycle limit."""

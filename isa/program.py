"""The result of assembling a source file: bytes per section, symbols, a listing and a source map.

Produced by :func:`isa.assemble`, consumed by :meth:`isa.CPU.load`, the CLI and anything that needs symbol
addresses (for example a harness reading named RAM variables).
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class Symbol:
    """A label or EQU/SET symbol.

    ``address`` is the value (an address for labels, any integer for EQU/SET); ``section`` is ``"code"``,
    ``"data"``, ``"bss"`` or ``"absolute"`` (EQU/SET); ``size`` is the number of bytes from the label to the next
    label in the same section (or to the end of the section), 0 for EQU/SET.
    """

    name: str
    address: int
    section: str
    size: int = 0


@dataclass(frozen=True)
class Segment:
    """A contiguous run of bytes to place at ``origin`` (bss segments carry ``bytes`` of zeros and ``bss=True``)."""

    name: str
    origin: int
    data: bytes
    bss: bool = False


@dataclass(frozen=True)
class SourceLine:
    """Where an instruction or data item came from: file name, 1-based line, and the source text."""

    file: str
    line: int
    text: str


@dataclass(frozen=True)
class ListingLine:
    """One line of the listing: address (None for lines that emit nothing), bytes emitted, cycle range
    ``(min, max)`` in 68000 clocks for instructions (None otherwise), and the source line."""

    address: int | None
    data: bytes
    cycles: tuple[int, int] | None
    source: SourceLine


@dataclass
class Program:
    """An assembled program.

    * ``segments``: what to load, one per section that emitted anything (code, data, bss).
    * ``origin``: the address of the first code byte; ``code`` is the code section's bytes.
    * ``symbols``: name -> :class:`Symbol` (names as written; lookups via :meth:`symbol` are case-insensitive).
    * ``listing``: one :class:`ListingLine` per source line, after macro and INCLUDE expansion.
    * ``source_map``: instruction address -> :class:`SourceLine`, used by the CPU to name source lines in faults.
    * ``warnings``: assembler warnings as ``file:line:col: warning: message`` strings.
    """

    segments: list[Segment]
    origin: int
    code: bytes
    symbols: dict[str, Symbol]
    listing: list[ListingLine] = field(default_factory=list)
    source_map: dict[int, SourceLine] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    def symbol(self, name: str) -> Symbol:
        """Return the symbol ``name`` (case-insensitive); raise ``KeyError`` naming it when absent."""
        key = name.lower()
        for sym_name, sym in self.symbols.items():
            if sym_name.lower() == key:
                return sym
        raise KeyError(f"no symbol {name!r} in program")

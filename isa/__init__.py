"""A true subset of the Motorola MC68000: instruction table, assembler, encoder, disassembler and a cycle-exact
interpreter. Nothing here knows about any particular program.

Public API (imported lazily so that ``import isa`` stays cheap)::

    program = isa.assemble(text, filename="prog.s", origin=0x1000)   # -> isa.program.Program
    cpu = isa.CPU(); cpu.load(program); cycles = cpu.step()
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS: dict[str, str] = {
    "assemble": "isa.assembler",
    "CPU": "isa.cpu",
    "RunResult": "isa.cpu",
    "encode": "isa.encoder",
    "decode": "isa.decoder",
    "format_instruction": "isa.formatter",
    "TABLE": "isa.table",
    "Program": "isa.program",
    "Symbol": "isa.program",
    "Instruction": "isa.operands",
    "Operand": "isa.operands",
    "Mode": "isa.operands",
    "Size": "isa.operands",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    """Import the public names on first use (PEP 562)."""
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'isa' has no attribute {name!r}")
    return getattr(importlib.import_module(module), name)

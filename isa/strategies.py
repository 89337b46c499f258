"""Hypothesis strategies (and a deterministic enumerator) for valid instructions of every :data:`~isa.table.TABLE`
row, size and addressing mode.

Every generated :class:`~isa.operands.Instruction` is in the decoder's *canonical* form (see
:mod:`isa.decoder`), so ``decode(encode(i, address)) == i`` holds, and it is encodable at the given address
(PC-relative operands and branch targets are in reach).

Typical use::

    from hypothesis import given
    from isa.strategies import instructions

    @given(instructions(address=0x1000))                         # any instruction
    @given(instructions(rows=["add", "addx"], modes=REGS_ONLY))   # rows by handler or mnemonic, EAs restricted

``forms()`` lists every (row, size, operand modes) combination; ``example(form, address, rng)`` builds one
concrete instruction for a form from a :class:`random.Random` (used by the GNU as corpus).
"""

from __future__ import annotations

import itertools
import random
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass

from hypothesis import strategies as st

from isa.encoder import ea_words
from isa.operands import IndexReg, Instruction, Mode, Operand, Size
from isa.table import TABLE, Row

#: Mode order used for deterministic enumeration.
MODE_ORDER: tuple[Mode, ...] = tuple(Mode)
#: Register-only EA modes (no memory access): handy for CPU differential tests without a memory model.
REGS_ONLY: frozenset[Mode] = frozenset({Mode.DREG, Mode.AREG, Mode.IMM})


@dataclass(frozen=True)
class Form:
    """One encodable shape: a row, a size, a condition code (conditional rows) and the mode of each operand."""

    row: Row
    size: Size | None
    cond: int | None
    modes: tuple[Mode, ...]


def _operand_modes(row: Row, i: int, size: Size | None, restrict: frozenset[Mode] | None) -> list[Mode]:
    spec = row.operands[i]
    if spec.kind != "ea":
        return sorted(spec.modes, key=MODE_ORDER.index)
    allowed = row.allowed_modes(i, size)
    if restrict is not None:
        allowed = allowed & restrict
    return sorted(allowed, key=MODE_ORDER.index)


def _select_rows(rows: Iterable[Row | str] | None) -> list[Row]:
    if rows is None:
        return list(TABLE)
    out: list[Row] = []
    for r in rows:
        if isinstance(r, Row):
            out.append(r)
        else:
            name = r.lower()
            found = [row for row in TABLE if row.handler == name or row.mnemonic == name or name in row.mnemonics()]
            if not found:
                raise ValueError(f"no TABLE row has handler or mnemonic {r!r}")
            out.extend(x for x in found if x not in out)
    return out


def forms(rows: Iterable[Row | str] | None = None, modes: frozenset[Mode] | None = None,
          all_conditions: bool = False) -> Iterator[Form]:
    """Every (row, size, operand-mode) combination of the selected rows (all rows by default).

    Conditional rows yield each condition when ``all_conditions`` is true, else one per row (codes cycle through
    the legal ones). ``modes`` restricts the EA operands (rows with an EA operand left without modes are
    skipped)."""
    counter = 0
    for row in _select_rows(rows):
        for size in row.sizes:
            per_op = [_operand_modes(row, i, size, modes) for i in range(len(row.operands))]
            if any(not m for m in per_op):
                continue
            combos = list(itertools.product(*per_op))
            conds: list[int | None]
            if row.conditional:
                legal = sorted(row.condition_codes)
                conds = (list(legal) if all_conditions
                         else [legal[(counter + k) % len(legal)] for k in range(len(combos))])
            else:
                conds = [None]
            for k, combo in enumerate(combos):
                if all_conditions or not row.conditional:
                    for c in conds:
                        yield Form(row, size, c, combo)
                else:
                    yield Form(row, size, conds[k], combo)
                counter += 1


def _ext_words(form: Form, i: int) -> int:
    spec = form.row.operands[i]
    if spec.kind in ("ea", "imm"):
        return ea_words(form.modes[i], form.size)
    if spec.kind == "reglist":
        return 1
    if spec.kind == "branch":
        return 0 if spec.data_field else 1
    return 0


def _s(bits: int) -> tuple[int, int]:
    return -(1 << (bits - 1)), (1 << (bits - 1)) - 1


def build(form: Form, address: int, draw: Callable[[int, int], int],
          absolute: Callable[[bool], int] | None = None) -> Instruction:
    """A canonical instruction of ``form`` at ``address``, with values from ``draw(lo, hi)`` (inclusive).

    ``absolute(short)`` may supply abs.W/abs.L addresses (``short``: must fit a sign-extended word)."""
    row, size = form.row, form.size
    ext_at: dict[int, int] = {}
    pc = address + 2
    for i in row.extension_order:
        ext_at[i] = pc
        pc += 2 * _ext_words(form, i)
    ops: list[Operand] = []
    for i, (spec, mode) in enumerate(zip(row.operands, form.modes)):
        kind = spec.kind
        if kind == "quick3":
            ops.append(Operand(Mode.IMM, value=draw(1, 8)))
        elif kind == "quick8":
            ops.append(Operand(Mode.IMM, value=draw(-128, 127)))
        elif kind == "vector":
            ops.append(Operand(Mode.IMM, value=draw(0, 15)))
        elif kind == "reglist":
            ops.append(Operand(Mode.REGLIST, value=draw(1, 0xFFFF)))
        elif kind == "branch":
            if spec.data_field:  # .s: even, nonzero, -128..126
                disp = 2 * draw(-64, 62)
                disp = disp if disp != 0 else 2
            else:
                disp = 2 * draw(-16384, 16383)
            ops.append(Operand(Mode.ABSL, value=(address + 2 + disp) & 0xFFFFFF))
        elif kind == "reg":
            ops.append(Operand(mode, draw(0, 7)))
        else:  # ea / imm
            ops.append(_ea(mode, size, ext_at[i], draw, absolute))
    mnemonic = row.canonical_mnemonic(form.cond)
    return Instruction(mnemonic, size, tuple(ops))


def _index(draw: Callable[[int, int], int]) -> IndexReg:
    return IndexReg(bool(draw(0, 1)), draw(0, 7), bool(draw(0, 1)))


def _ea(mode: Mode, size: Size | None, ext: int, draw: Callable[[int, int], int],
        absolute: Callable[[bool], int] | None) -> Operand:
    if mode in (Mode.DREG, Mode.AREG, Mode.AIND, Mode.APOSTINC, Mode.APREDEC):
        return Operand(mode, draw(0, 7))
    if mode is Mode.ADISP:
        return Operand(mode, draw(0, 7), draw(*_s(16)))
    if mode is Mode.AINDEX:
        return Operand(mode, draw(0, 7), draw(*_s(8)), _index(draw))
    if mode is Mode.ABSW:
        v = absolute(True) if absolute else draw(*_s(16))
        return Operand(mode, 0, v & 0xFFFFFF)
    if mode is Mode.ABSL:
        v = absolute(False) if absolute else draw(0, 0xFFFFFFFF)
        return Operand(mode, 0, v & 0xFFFFFFFF)
    if mode is Mode.PCDISP:
        return Operand(mode, 0, (ext + draw(*_s(16))) & 0xFFFFFF)
    if mode is Mode.PCINDEX:
        return Operand(mode, 0, (ext + draw(*_s(8))) & 0xFFFFFF, _index(draw))
    if mode is Mode.IMM:
        bits = {Size.B: 8, Size.W: 16, Size.L: 32}.get(size, 16)  # type: ignore[arg-type]  # size None (unsized) falls to the default 16
        return Operand(mode, 0, draw(*_s(bits)))
    raise ValueError(f"mode {mode} is not an EA mode")


def example(form: Form, address: int, rng: random.Random) -> Instruction:
    """One concrete canonical instruction of ``form`` at ``address`` with values from ``rng`` (edge-biased)."""

    def draw(lo: int, hi: int) -> int:
        r = rng.random()
        if r < 0.15:
            return lo
        if r < 0.3:
            return hi
        if r < 0.4 and lo <= 0 <= hi:
            return 0 if lo < 0 or hi > 8 else lo
        return rng.randint(lo, hi)

    return build(form, address, draw)


@st.composite
def _instr(draw_: st.DrawFn, by_row: list[list[Form]], address: st.SearchStrategy[int],
           absolute: st.SearchStrategy[int] | None) -> Instruction:
    form = draw_(st.sampled_from(draw_(st.sampled_from(by_row))))  # row first: rare rows are not drowned out
    addr = draw_(address)

    def draw(lo: int, hi: int) -> int:
        return draw_(st.integers(lo, hi))

    def abs_from_strategy(short: bool) -> int:
        assert absolute is not None
        if short:
            return draw_(absolute.filter(lambda a: a <= 0x7FFF or a >= 0xFF8000))
        return draw_(absolute)

    abs_fn = abs_from_strategy if absolute is not None else None

    return build(form, addr, draw, abs_fn)


def instructions(rows: Iterable[Row | str] | None = None, address: int | st.SearchStrategy[int] = 0x1000,
                 modes: frozenset[Mode] | None = None,
                 absolute: st.SearchStrategy[int] | None = None) -> st.SearchStrategy[Instruction]:
    """Strategy for canonical, encodable instructions.

    * ``rows``: Rows, handler names (``"add"``, ``"bcc"``) or mnemonics (``"beq"``, ``"movem"``); default all.
    * ``address``: where the instruction will be placed (int or strategy of even ints); PC-relative operands and
      branch targets are generated within reach of it.
    * ``modes``: restrict EA operands to these modes (rows with no remaining mode are dropped).
    * ``absolute``: strategy for abs.W/abs.L addresses (e.g. inside your RAM); default any encodable value.
      abs.W operands only use values that fit a sign-extended word (0..$7FFF, $FF8000..$FFFFFF): if yours
      never do, leave ``Mode.ABSW`` out of ``modes``.

    Conditional rows draw every legal condition."""
    fs = list(forms(rows, modes, all_conditions=True))
    if not fs:
        raise ValueError("no instruction form matches the given rows/modes")
    addr = st.just(address) if isinstance(address, int) else address
    by_row: dict[int, list[Form]] = {}
    for f in fs:
        by_row.setdefault(id(f.row), []).append(f)
    return _instr(list(by_row.values()), addr, absolute)


__all__ = ["Form", "forms", "build", "example", "instructions", "REGS_ONLY", "MODE_ORDER"]

"""Differential tests: our interpreter against Musashi (through machine68k; trusted for data and flags, NOT for
cycles, which are never compared here: m68000-python is the cycle oracle). One instruction per example from
identical states; registers, PC, all five CCR flags and every RAM byte must agree.

Known Musashi faults excluded (docs/isa-oracles.md), exactly and nothing wider:
* DIVS/DIVU overflow (V set): N and Z are "undefined" in the PRM; Musashi's values differ from the chip's
  (which m68000-python and ours reproduce), so those two flags are not compared when V is set after a divide.
  C: the PRM says "always cleared" and m68000-python (hardware-checked) and ours clear it, but Musashi leaves
  C as it was on an overflow, so C is not compared there either (found by the thorough profile, which drew an
  overflow with C set beforehand).
* DIVS of $80000000 by -1: Musashi special-cases it to quotient 0 with Z set and no overflow; the chip overflows
  (V set, register unchanged), as m68000-python (hardware-checked) and ours do. That exact case is skipped against
  Musashi (`test_divs_min_by_minus_one_exclusion_is_real` keeps the evidence live).
* machine68k builds Musashi without address-error emulation: odd accesses are recognised from its memory trace
  (the first odd word/long access, or an odd PC after a jump), which is what the 68000 would fault on.
"""

from __future__ import annotations

import pytest

pytest.importorskip("machine68k", reason="machine68k (Musashi) is not installed")

from hypothesis import given, settings
from hypothesis import strategies as st

from tests.support import oracles
from tests.support.profiles import examples


def _dst(case: oracles.Case) -> int:
    return case.instruction.operands[1].reg


def check(case: oracles.Case) -> oracles.State:
    """Run ``case`` on ours and Musashi and assert they agree (minus the documented exclusions)."""
    ours = oracles.ours_run(case.machine)
    theirs = oracles.musashi().run(case.machine)
    if (case.instruction.mnemonic == "divs" and theirs.fault is None and case.machine.d[_dst(case)] == 0x80000000
            and ours.ccr & 0x02 and theirs.d[_dst(case)] == 0 and theirs.ccr & 0x0F == 0x04):
        return theirs  # Musashi's special case for $80000000 / -1 (quotient 0, Z); the chip overflows (see below)
    if case.instruction.mnemonic in ("divs", "divu") and theirs.fault is None and theirs.ccr & 0x02:
        theirs.ccr = (theirs.ccr & ~0x0D) | (ours.ccr & 0x0D)  # overflow: N, Z undefined; Musashi keeps C
    diffs = oracles.compare(ours, theirs, cycles=False)
    assert not diffs, oracles.failure(case, "Musashi", diffs, ours, theirs)
    return theirs


COMBOS = oracles.combos()
HALF = len(COMBOS) // 2  # hypothesis 6.170 (derandomized) overflows the stack past ~950 parametrizations


@pytest.mark.seed_per_case
@pytest.mark.parametrize("combo", COMBOS[:HALF], ids=oracles.combo_id)
@settings(max_examples=examples(1))
@given(data=st.data())
def test_every_row_size_mode_a(combo, data) -> None:
    """Each (row, size, first-EA mode), first half of the table."""
    row, size, mode = combo
    check(oracles.random_case(data, row, size, mode))


@pytest.mark.seed_per_case
@pytest.mark.parametrize("combo", COMBOS[HALF:], ids=oracles.combo_id)
@settings(max_examples=examples(1))
@given(data=st.data())
def test_every_row_size_mode_b(combo, data) -> None:
    """Each (row, size, first-EA mode), second half of the table."""
    row, size, mode = combo
    check(oracles.random_case(data, row, size, mode))


@pytest.mark.seed_per_case
@pytest.mark.parametrize("combo", oracles.row_sizes(), ids=oracles.combo_id)
# ci: 2 random states per (row, size); before oracles.random_case the first of 3 was hypothesis's all-zero one
@settings(max_examples=examples(3, ci=2))
@given(data=st.data())
def test_every_row_size_any_modes(combo, data) -> None:
    """Each (row, size) with its operand modes drawn."""
    row, size = combo
    eas = [i for i, spec in enumerate(row.operands) if spec.kind == "ea"]
    mode = None
    if eas:
        mode = data.draw(st.sampled_from(sorted(row.allowed_modes(eas[0], size), key=oracles._MODE_ORDER.index)))
    check(oracles.random_case(data, row, size, mode))


@pytest.mark.seed_per_case
@pytest.mark.parametrize("combo", oracles.odd_combos(), ids=oracles.combo_id)
@settings(max_examples=examples(1))
@given(data=st.data())
def test_odd_addresses_are_address_errors(combo, data) -> None:
    """Odd word/long accesses and jump targets: ours raises AddressError exactly where Musashi's trace shows the
    access the 68000 would fault on."""
    row, size, mode = combo
    theirs = check(oracles.random_case(data, row, size, mode, odd=True))
    if row.handler not in ("bcc", "dbcc"):
        assert theirs.fault == "address", f"no odd access in Musashi's trace ({theirs.fault}): test is vacuous"


def test_divide_overflow_exclusion_is_real() -> None:
    """The N/Z exclusion above is needed: Musashi's N/Z after a DIVU overflow differ from ours (PRM: undefined)
    for this state, while the quotient register and V agree. If Musashi ever matches, drop the exclusion."""
    from isa.encoder import encode
    from isa.operands import Instruction, Mode, Operand, Size

    code = encode(Instruction("divu", Size.W, (Operand(Mode.IMM, 0, 1), Operand(Mode.DREG, 0))), oracles.CODE)
    image = bytes(oracles.base_image(1, [(oracles.CODE, code)]))
    machine = oracles.Machine([0xFFFFFFFF] + [0] * 7, [oracles.DATA_LO] * 8, 0, oracles.CODE, image)
    ours, theirs = oracles.ours_run(machine), oracles.musashi().run(machine)
    assert ours.d == theirs.d and ours.ccr & 0x13 == theirs.ccr & 0x13 == 0x02
    assert ours.ccr & 0x0C != theirs.ccr & 0x0C


def test_divide_overflow_carry_exclusion_is_real() -> None:
    """The C exclusion above is needed: after a DIVS overflow with C set beforehand, Musashi keeps C while the PRM
    ("C: always cleared"), m68000-python and ours clear it. If Musashi ever clears it, drop the exclusion."""
    from isa.encoder import encode
    from isa.operands import Instruction, Mode, Operand, Size

    code = encode(Instruction("divs", Size.W, (Operand(Mode.DREG, 0), Operand(Mode.DREG, 0))), oracles.CODE)
    image = bytes(oracles.base_image(1, [(oracles.CODE, code)]))
    machine = oracles.Machine([0x80000001] + [0] * 7, [oracles.DATA_LO] * 8, 0x01, oracles.CODE, image)
    ours, theirs = oracles.ours_run(machine), oracles.musashi().run(machine)
    reference = oracles.M68000PyRef().run(machine)
    assert ours.d == theirs.d == reference.d and ours.ccr & 0x02 == theirs.ccr & 0x02 == 0x02   # V: overflow
    assert ours.ccr & 0x01 == reference.ccr & 0x01 == 0 and theirs.ccr & 0x01 == 0x01


def test_divs_min_by_minus_one_exclusion_is_real() -> None:
    """DIVS.W #-1 with D0 = $80000000: m68000-python and ours overflow (V, D0 unchanged); Musashi returns 0 with Z.
    If Musashi ever overflows here too, drop the exclusion in check()."""
    from isa.encoder import encode
    from isa.operands import Instruction, Mode, Operand, Size

    code = encode(Instruction("divs", Size.W, (Operand(Mode.IMM, 0, -1), Operand(Mode.DREG, 0))), oracles.CODE)
    image = bytes(oracles.base_image(1, [(oracles.CODE, code)]))
    machine = oracles.Machine([0x80000000] + [0] * 7, [oracles.DATA_LO] * 8, 0, oracles.CODE, image)
    ours, theirs = oracles.ours_run(machine), oracles.musashi().run(machine)
    reference = oracles.M68000PyRef().run(machine)
    assert ours.d[0] == reference.d[0] == 0x80000000 and ours.ccr & 0x02 and reference.ccr & 0x02
    assert theirs.d[0] == 0 and theirs.ccr & 0x0F == 0x04


@settings(max_examples=examples(60))
@given(case=oracles.cmpm_cases())
def test_cmpm_same_register_and_a7(case: oracles.Case) -> None:
    """CMPM (issue 8.2) with Ay = Ax, A7 and edge-valued operands against Musashi."""
    check(case)

"""Budget reports: the static worst-case bound, measured cycles against it, and the report files.

The static bound is checked two ways: on hand-written programs whose exact clock counts are summed here from the
M68000 User's Manual tables (8.x, zero wait states), and on the firmware, where every measured ``step`` on
hypothesis-generated streams must stay at or under it.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import isa
from firmware_model.budget import cpu68k as budget
from firmware_model.firmware.assemble import build_firmware
from firmware_model.cli.main import main
from firmware_model.spec.config import BuildConfig
from firmware_model.runtime.errors import UserError
from firmware_model.firmware.harness import run_firmware
from tests.support.profiles import examples


def _bound(text: str) -> budget.StaticBound:
    prog = isa.assemble(text, filename="t.s", origin=0x1000)
    return budget.static_bound(prog, prog.symbol("sub").address)


def test_straight_line_bound_is_the_manual_sum() -> None:
    # User's Manual: MOVEQ 4; ADD.L Dn,Dn 8; LSL.L #2,Dn 8+2*2 = 12; MOVE.W Dn,(An) 8; RTS 16.
    b = _bound("sub: moveq #1,d0\n add.l d0,d1\n lsl.l #2,d1\n move.w d1,(a0)\n rts\n")
    assert b.cycles == 4 + 8 + 12 + 8 + 16
    assert b.instructions == 5 and b.loops == ()


def test_the_longer_arm_of_a_branch_is_the_bound() -> None:
    # TST.L Dn 4; BEQ.S charged at its max 10 (taken 10 / not taken 8); paths: NOT.L Dn 6 + RTS 16 or RTS 16.
    b = _bound("sub: tst.l d0\n beq.s .z\n not.l d0\n rts\n.z: rts\n")
    assert b.cycles == 4 + 10 + max(6 + 16, 16)
    # the longer arm on the taken side: MULU #$FFFF,D0 = 38 + 2*16 + 4 (immediate) = 74
    b = _bound("sub: tst.l d0\n beq.s .z\n not.l d0\n rts\n.z: mulu #$ffff,d0\n rts\n")
    assert b.cycles == 4 + 10 + max(6 + 16, 74 + 16)


def test_loop_with_a_branch_inside_charges_its_longest_iteration() -> None:
    # per iteration: BTST-free body: TST.W D1 4; BNE.S 10; either ADDQ.L #1,D2 8 or nothing; SUBQ.W #1,D0 4; BNE.S 10
    b = _bound("sub: moveq #3,d0\n.l: tst.w d1\n bne.s .s\n addq.l #1,d2\n.s: subq.w #1,d0\n bne.s .l ; @bound 3\n"
               " rts\n")
    assert b.cycles == 4 + 3 * (4 + 10 + 8 + 4 + 10) + 16


def test_nested_loops_multiply() -> None:
    # inner: SUBQ.W #1,D1 4 + BNE.S 10, at most 4 head runs; outer body: MOVEQ 4 + inner + SUBQ.W #1,D0 4 + BNE.S 10
    b = _bound("sub: moveq #2,d0\n.o: moveq #4,d1\n.i: subq.w #1,d1\n bne.s .i ; @bound 4\n subq.w #1,d0\n"
               " bne.s .o ; @bound 2\n rts\n")
    assert b.cycles == 4 + 2 * (4 + 4 * (4 + 10) + 4 + 10) + 16
    assert len(b.loops) == 2


def test_loop_entered_in_the_middle_is_refused() -> None:
    with pytest.raises(UserError, match="entered other than at its head"):
        _bound("sub: tst.l d0\n beq.s .m\n.l: addq.l #1,d1\n.m: subq.l #1,d0\n bne.s .l ; @bound 9\n rts\n")


def test_annotated_loop_is_charged_bound_times() -> None:
    # loop body: SUBQ.L #1,Dn 8 + BNE.S 10 (max), 5 times; MOVEQ 4 and RTS 16 once.
    b = _bound("sub: moveq #5,d0\n.l: subq.l #1,d0\n bne.s .l ; @bound 5\n rts\n")
    assert b.cycles == 4 + 5 * (8 + 10) + 16
    assert len(b.loops) == 1 and b.loops[0][2] == 5


def test_loop_without_annotation_is_refused() -> None:
    with pytest.raises(UserError, match="@bound"):
        _bound("sub: moveq #5,d0\n.l: subq.l #1,d0\n bne.s .l\n rts\n")


def test_calls_add_the_callee_bound() -> None:
    # BSR.W 18 + callee (MOVEQ 4 + RTS 16) + RTS 16
    b = _bound("sub: bsr.w f\n rts\nf: moveq #0,d0\n rts\n")
    assert b.cycles == 18 + 4 + 16 + 16


def test_indirect_jump_is_refused() -> None:
    with pytest.raises(UserError, match="indirect"):
        _bound("sub: jmp (a0)\n")


@pytest.mark.parametrize("program", ["recursive", "kalman_baro", "kalman_accel"])
@pytest.mark.parametrize("rounding", ["floor", "half_up"])
def test_measured_steps_stay_under_the_static_bound(program: str, rounding: str) -> None:
    build = build_firmware(BuildConfig(program=program, k=6, rounding=rounding))
    report = budget.measure(build, budget.default_streams(6, 16, edge_samples=128))
    assert report.cycles_min <= report.cycles_median <= report.cycles_max <= report.static_bound
    assert report.stack_peak_bytes >= 4  # at least the return address of the call
    assert 0 < report.load_measured <= report.load_static


@settings(max_examples=examples(15))
@given(data=st.data(), program=st.sampled_from(["kalman_baro", "kalman_accel", "recursive"]),
       k=st.integers(4, 8))
def test_random_streams_never_exceed_the_static_bound(data: st.DataObject, program: str, k: int) -> None:
    n = data.draw(st.integers(2, 200))
    adc = np.array(data.draw(st.lists(st.integers(0, 65535), min_size=n, max_size=n)))
    acc = np.array(data.draw(st.lists(st.integers(-32768, 32767), min_size=n, max_size=n)))
    build = build_firmware(BuildConfig(program=program, k=k))
    trace = run_firmware(build, adc, acc)
    assert int(np.max(trace.cycles)) <= budget.static_step_bound(build).cycles


def test_budget_cli_writes_every_report(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "budget"
    assert main(["budget", "--program", "kalman_baro", "--k", "5", "--out", str(out)]) == 0
    names = sorted(p.name for p in out.iterdir())
    assert {"budget.md", "budget.json", "cycles.csv"} <= set(names)
    data = json.loads((out / "budget.json").read_text())
    assert data[0]["program"] == "kalman_baro" and data[0]["config"]["k"] == 5
    assert data[0]["cycles_max"] <= data[0]["static_bound"]
    assert "| kalman_baro | 5 |" in capsys.readouterr().out
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".budget-")]  # no temp dir left


def test_budget_cli_bad_config_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfg = tmp_path / "c.json"
    cfg.write_text('{"k": 11}')
    assert main(["budget", "--config", str(cfg), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "k: 11" in err and "c.json" in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()

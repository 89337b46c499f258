"""Interrupts that land inside library code: a signal whose exception a finalizer swallows still ends the run, a
kernel compile is not torn apart (the interrupt waits for it), and a Ctrl-C on a cold numba cache (a fresh
checkout) still ends in one line. The CI run of a fresh clone once printed llvmlite's "Exception ignored ..."
traceback after the interrupt line, and an interrupt during the compile once surfaced as numba's
"RuntimeError: no compiled object yet" with a 261-line traceback."""

from __future__ import annotations

import gc
import os
import signal
import subprocess
import sys
import time
import types
from pathlib import Path

import pytest

from firmware_model.runtime import output

ROOT = Path(__file__).resolve().parents[2]
LOGS = Path(os.environ.get("FWEMU_SHARED_FLIGHTS", ROOT.parent / "shared" / "flights"))


class _KillsInDel:
    def __del__(self) -> None:
        os.kill(os.getpid(), signal.SIGINT)
        for _ in range(1000):   # bytecodes: the Python-level handler runs here, inside __del__
            pass


def test_a_swallowed_interrupt_is_still_seen(monkeypatch: pytest.MonkeyPatch) -> None:
    reported: list[type] = []
    monkeypatch.setattr(sys, "unraisablehook", lambda u: reported.append(u.exc_type))
    output.reset_run_state()
    with output.interruptible():
        obj = _KillsInDel()
        del obj                     # the handler's Interrupted is raised inside __del__: Python cannot raise it
        gc.collect()
        assert output.pending_signal() == signal.SIGINT   # ... but it is recorded
        with pytest.raises(output.Interrupted):
            output.raise_if_interrupted()
        # other unraisable exceptions still reach the hook that was there before
        sys.unraisablehook(types.SimpleNamespace(exc_type=ValueError))
    # the swallowed Interrupted went to no hook: nothing printed "Exception ignored in ..." before the one line
    # (a CLI run printed importlib's "_get_module_lock.<locals>.cb" traceback when a SIGINT landed there)
    assert reported == [ValueError]
    assert sys.unraisablehook.__name__ == "<lambda>"   # the previous hook is back
    output.reset_run_state()


def test_an_unraisable_interrupt_prints_nothing(capfd: pytest.CaptureFixture[str]) -> None:
    """The same, through Python's own reporting: with the default hook, the Interrupted raised in ``__del__``
    would be printed to stderr as "Exception ignored in: <function _KillsInDel.__del__ ...>" and a traceback."""
    output.reset_run_state()
    saved = sys.unraisablehook
    sys.unraisablehook = sys.__unraisablehook__   # Python's printing hook (pytest installs its own)
    try:
        with output.interruptible():
            obj = _KillsInDel()
            del obj
            gc.collect()
            assert output.pending_signal() == signal.SIGINT
    finally:
        sys.unraisablehook = saved
        output.reset_run_state()
    assert capfd.readouterr().err == ""


def test_interrupts_deferred_waits_for_the_block() -> None:
    output.reset_run_state()
    reached = []
    with output.interruptible():
        with pytest.raises(output.Interrupted):
            with output.interrupts_deferred():
                os.kill(os.getpid(), signal.SIGINT)
                for _ in range(100_000):
                    pass
                reached.append("end of the block")
    assert reached == ["end of the block"]
    output.reset_run_state()


@pytest.mark.skipif(not LOGS.is_dir(), reason="needs ../shared/flights (vectors --all builds flight cases)")
@pytest.mark.parametrize("delay", [2.0, 4.0])
def test_ctrl_c_on_a_cold_numba_cache_is_one_line(delay: float, tmp_path: Path) -> None:
    env = dict(os.environ, PYTHONPATH=str(ROOT), NUMBA_CACHE_DIR=str(tmp_path / "numba"),
               FWEMU_SHARED_FLIGHTS=str(LOGS))
    out = tmp_path / "v"
    proc = subprocess.Popen([sys.executable, "-m", "firmware_model.cli.main", "vectors", "--all", "--generator",
                             "model", "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    time.sleep(delay)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=300)
    lines = [line for line in err.splitlines() if line.strip()]
    if proc.returncode == 0:
        pytest.skip("the run finished before the signal")
    assert proc.returncode == 130, err
    assert lines == [f"fwemu: interrupted; previous outputs in {out} left intact"], err
    assert not out.exists()

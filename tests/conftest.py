"""pytest configuration: load the hypothesis profile named by ``HYPOTHESIS_PROFILE`` (default ``ci``), and keep
hypothesis's per-test overhead constant (docs/testing.md "How the suite is kept fast").

Two overheads of hypothesis 6.1xx grow with the suite, not with what a test checks:

* For every parametrized invocation its pytest plugin wraps the test function's settings in a new
  ``settings(parent=<the previous wrapper>, suppress_health_check=...)``, so the wrappers chain up (one level per
  invocation: 675 levels by the end of ``test_bus_errors_name_the_faulting_access``), and ``settings.database``
  walks the whole chain twice per test. :func:`pytest_runtest_call` below puts the function's own settings back
  after each test, so every invocation gets the same one-level wrapper that the first one got: the same
  effective settings, the same derandomized examples.
* With ``derandomize`` the seed is a digest of the test's cleaned source, and hypothesis re-tokenizes the source
  for every test (about 3 ms); the cleaning is a pure function of the source text, memoized here, and so is the
  ``inspect.getsource`` read before it (:func:`_memo_inspect`; every digest logged identical with and without).

It also prints the closing lines tests record (the Cortex-M runs', :func:`pytest_terminal_summary`) and loads
the compiled model kernels in every test process (below).
"""

from __future__ import annotations

import functools
import inspect
import types

import pytest
from hypothesis import settings

from profiles import PROFILE

settings.load_profile(PROFILE)

# Load the model's compiled kernels in every test process, whatever files are selected: run_model's "auto" engine
# runs a process's first 20,000 samples in plain Python while they are not loaded (firmware_model/model.py
# AUTO_PURE_MAX_SAMPLES), and the in-process model tests are meant to exercise what a long run uses. (The two
# engines are compared in tests/test_model_kernels.py; tests/test_model_engine_auto.py checks the rule itself in
# fresh interpreters.)
from firmware_model import model_kernels as _model_kernels  # noqa: E402,F401


def _memo_inspect() -> types.ModuleType:
    """``inspect`` as hypothesis's reflection module sees it, with ``getsource`` memoized per object.
    ``function_digest`` (the derandomized seed, twice per test) reads the test function's source with
    ``inspect.getsource``, which re-tokenizes the whole function each time (~1 ms; 4,150 single-example ISA tests).
    The source files do not change during a run, so the memo returns the very string ``getsource`` would: same
    digests, same seeds, same examples. Errors are not memoized (raised again as before)."""
    memo: dict[object, str] = {}

    def getsource(obj: object) -> str:
        try:
            return memo[obj]
        except (KeyError, TypeError):
            pass
        src = inspect.getsource(obj)  # type: ignore[arg-type]
        try:
            memo[obj] = src
        except TypeError:  # unhashable: not memoized
            pass
        return src

    proxy = types.ModuleType("inspect")
    proxy.__dict__.update(inspect.__dict__)
    proxy.getsource = getsource  # type: ignore[attr-defined]
    return proxy


try:  # a private helper of hypothesis: memoize it only where it is what we expect (a pure str -> bytes function)
    from hypothesis.internal import reflection as _reflection

    if callable(getattr(_reflection, "_clean_source", None)) and callable(getattr(_reflection, "function_digest",
                                                                                  None)):
        _reflection._clean_source = functools.lru_cache(maxsize=4096)(_reflection._clean_source)
        if getattr(_reflection, "inspect", None) is inspect:
            _reflection.inspect = _memo_inspect()
except ImportError:  # pragma: no cover - another hypothesis layout: nothing to memoize
    pass


@pytest.hookimpl(hookwrapper=True, tryfirst=True)
def pytest_runtest_call(item: pytest.Item):  # type: ignore[no-untyped-def]
    fn = getattr(getattr(item, "obj", None), "__func__", getattr(item, "obj", None))
    own = getattr(fn, "_hypothesis_internal_use_settings", None)
    try:
        yield
    finally:
        if own is not None:
            fn._hypothesis_internal_use_settings = own


def pytest_terminal_summary(terminalreporter, exitstatus, config):  # type: ignore[no-untyped-def]
    """Print the closing lines that tests recorded (``record_property("closing_line", ...)``: the Cortex-M runs'
    ``cortex-m0-Os: 673 passed, 0 failed``), in test order, passed or failed; xdist carries them to this process."""
    lines = []
    for key in ("passed", "failed"):
        for rep in terminalreporter.stats.get(key, []):
            if getattr(rep, "when", "call") == "call":
                lines += [(rep.nodeid, v) for k, v in getattr(rep, "user_properties", ()) if k == "closing_line"]
    if lines:
        terminalreporter.section("closing lines")
        for _, line in sorted(lines, key=lambda nl: nl[0]):   # stable: a test's own order kept
            terminalreporter.write_line(line)

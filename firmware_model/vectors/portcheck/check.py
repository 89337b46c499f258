"""The differential search: the port and the integer model on hypothesis streams, every word of every sample,
until a difference (shrunk by hypothesis to a short stream, then cut after its first differing sample) or the
budget (examples, seconds) runs out.

The search runs in rounds of :data:`ROUND_EXAMPLES` examples, round ``r`` with the hypothesis seed
``seed * 1_000_003 + r``: the same ``seed`` replays the same streams in the same order (so ``--seed`` reproduces a
run, whatever ``--time`` cut it short), and a time budget is checked between rounds.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from hypothesis import HealthCheck, Phase, Verbosity, given, settings
from hypothesis import seed as hyp_seed

from firmware_model.model.run import run_model
from firmware_model.model.trace import word_names
from firmware_model.spec.build_constants import build_constants
from firmware_model.spec.config import BuildConfig
from firmware_model.vectors.portcheck.build import Port
from firmware_model.vectors.portcheck.isolate import PortCrash
from firmware_model.vectors.portcheck.streams import port_streams

#: Examples per round (the granularity of the time budget and of the progress report).
ROUND_EXAMPLES: int = 25


@dataclass
class Difference:
    """The first word where the port and the model differ on one stream (``sample`` -1: after init)."""

    sample: int
    word: str
    column: int
    expected: int
    actual: int


@dataclass
class Mismatch:
    """A stream on which the port differs from the model, cut after the first differing sample."""

    cfg: BuildConfig
    consts: Any
    adc: np.ndarray
    acc: np.ndarray
    diff: Difference
    names: tuple[str, ...]
    expected_init: np.ndarray
    expected: np.ndarray
    actual_init: np.ndarray
    actual: np.ndarray
    #: Length of the stream hypothesis first failed on, and after hypothesis shrank it (before the cut).
    first_len: int = 0
    shrunk_len: int = 0
    #: "hypothesis" (found and shrunk by the search) or "given" (a stream passed in, e.g. a case's; cut only).
    source: str = "hypothesis"
    #: the port crashed or hung on this stream (its ``actual`` words are unknown: zeros)
    crash: PortCrash | None = None


@dataclass
class CheckResult:
    """Outcome of :func:`check_port`: the mismatch (or ``None``), what ran, how long it took."""

    cfg: BuildConfig
    seed: int
    mismatch: Mismatch | None
    examples: int = 0
    samples: int = 0
    seconds: float = 0.0
    #: Streams, samples and seconds until the first failing stream; then the seconds spent shrinking.
    examples_to_failure: int = 0
    samples_to_failure: int = 0
    seconds_to_failure: float = 0.0
    shrink_seconds: float = 0.0
    rounds: int = 0
    stopped_by: str = ""
    notes: list[str] = field(default_factory=list)


def first_difference(names: tuple[str, ...], exp_init: np.ndarray, exp: np.ndarray, got_init: np.ndarray,
                     got: np.ndarray) -> Difference | None:
    """The first (sample, word) where ``got`` differs from ``exp``, init (sample -1) first; ``None`` if none."""
    bad = np.nonzero(exp_init != got_init)[0]
    if bad.size:
        j = int(bad[0])
        return Difference(-1, names[j], j, int(exp_init[j]), int(got_init[j]))
    rows = np.nonzero(np.any(exp != got, axis=1))[0]
    if not rows.size:
        return None
    i = int(rows[0])
    j = int(np.nonzero(exp[i] != got[i])[0][0])
    return Difference(i, names[j], j, int(exp[i, j]), int(got[i, j]))


def compare(port: Port, cfg: BuildConfig, consts: Any, adc: np.ndarray, acc: np.ndarray
            ) -> tuple[Difference | None, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """Run ``(adc, acc)`` through the port and the model; the first difference and the four word arrays."""
    got_init, got = port.run(cfg.program, consts, adc, acc)
    m = run_model(consts, adc, acc)
    exp_init = np.asarray(m.init_words, dtype=np.int64)
    exp = np.asarray(m.words, dtype=np.int64)
    return first_difference(tuple(m.names), exp_init, exp, got_init, got), (exp_init, exp, got_init, got)


class _PortDiffers(AssertionError):
    pass


def mismatch_of(port: Port, cfg: BuildConfig, consts: Any, adc: np.ndarray, acc: np.ndarray,
                first_len: int = 0, shrunk_len: int = 0) -> Mismatch | None:
    """The :class:`Mismatch` of one stream, cut after its first differing sample (the port and the model are
    causal: the words up to a sample depend only on the inputs up to it; the cut stream is run again and must
    differ at the same place, else the uncut stream is kept)."""
    diff, _ = compare(port, cfg, consts, adc, acc)
    if diff is None:
        return None
    cut = max(1, diff.sample + 1)
    a2, c2 = np.asarray(adc[:cut], dtype=np.int64), np.asarray(acc[:cut], dtype=np.int64)
    diff2, arrays = compare(port, cfg, consts, a2, c2)
    if diff2 is None or (diff2.sample, diff2.column) != (diff.sample, diff.column):
        a2, c2 = np.asarray(adc, dtype=np.int64), np.asarray(acc, dtype=np.int64)
        diff2, arrays = compare(port, cfg, consts, a2, c2)
        assert diff2 is not None
    exp_init, exp, got_init, got = arrays
    return Mismatch(cfg=cfg, consts=consts, adc=a2, acc=c2, diff=diff2, names=word_names(cfg.program),
                    expected_init=exp_init, expected=exp, actual_init=got_init, actual=got,
                    first_len=first_len or len(adc), shrunk_len=shrunk_len or len(adc))


#: At most this many seconds and port runs for :func:`cut_chunks` after hypothesis's shrink.
CUT_CHUNKS_S: float = 10.0
CUT_CHUNKS_TRIES: int = 400


def cut_chunks(port: Port, cfg: BuildConfig, consts: Any, adc: np.ndarray, acc: np.ndarray,
               seconds: float = CUT_CHUNKS_S, tries: int = CUT_CHUNKS_TRIES) -> tuple[np.ndarray, np.ndarray]:
    """A shorter stream on which the port still differs from the model: hypothesis shrinks the draws of the
    stream strategy, which can stall on a long stream whose difference needs a long history (a gate's reject
    counter after hundreds of samples); this pass removes whole runs of samples, halves first, then quarters and
    so on down to single samples (the delta-debugging idea of Zeller & Hildebrandt 2002), keeping each removal
    after which a difference remains, within ``seconds`` and ``tries`` port runs. A removal that makes the port
    crash is not kept (that is another failure)."""
    a, c = np.asarray(adc, dtype=np.int64), np.asarray(acc, dtype=np.int64)
    t0, n_runs = time.perf_counter(), 0
    size = len(a) // 2
    while size >= 1:
        i = 0
        while i < len(a) and len(a) > 1:
            if time.perf_counter() - t0 > seconds or n_runs >= tries:
                return a, c
            a2, c2 = np.concatenate([a[:i], a[i + size:]]), np.concatenate([c[:i], c[i + size:]])
            n_runs += 1
            try:
                diff, _ = compare(port, cfg, consts, a2, c2) if len(a2) else (None, None)
            except PortCrash:
                diff = None
            if diff is not None:
                cut = diff.sample + 1 if diff.sample >= 0 else 1
                a, c = a2[:cut], c2[:cut]
            else:
                i += size
        size //= 2
    return a, c


#: Seconds hypothesis may spend shrinking a crash (a hang: this many stream time-outs, each a killed child).
CRASH_SHRINK_S: float = 20.0
HANG_SHRINK_TRIES: int = 3


def crash_of(port: Port, cfg: BuildConfig, consts: Any, adc: np.ndarray, acc: np.ndarray, crash: PortCrash,
             first_len: int = 0, shrunk_len: int = 0) -> Mismatch:
    """The :class:`Mismatch` of a stream the port crashed or hung on: cut after the sample it was stepping
    (``crash.samples_done``; the whole stream when the cut one does not end the same way), with the model's
    words as the expected ones."""
    a2, c2 = np.asarray(adc, dtype=np.int64), np.asarray(acc, dtype=np.int64)
    cut = max(1, crash.samples_done + 1)
    if cut < len(a2) and "answer" in crash.kind:
        a2, c2 = a2[:cut], c2[:cut]      # a hang: the progress word says where (no second time-out to confirm)
    elif cut < len(a2):
        try:
            port.run(cfg.program, consts, a2[:cut], c2[:cut])
        except PortCrash as again:
            if again.kind == crash.kind:
                a2, c2, crash = a2[:cut], c2[:cut], again
    m = run_model(consts, a2, c2)
    exp_init = np.asarray(m.init_words, dtype=np.int64)
    exp = np.asarray(m.words, dtype=np.int64).reshape(len(a2), -1)
    sample = min(max(crash.samples_done, -1), len(a2) - 1)
    diff = Difference(sample, "(crash)", -1, 0, 0)
    return Mismatch(cfg=cfg, consts=consts, adc=a2, acc=c2, diff=diff, names=word_names(cfg.program),
                    expected_init=exp_init, expected=exp, actual_init=np.zeros_like(exp_init),
                    actual=np.zeros_like(exp), first_len=first_len or len(adc), shrunk_len=shrunk_len or len(adc),
                    crash=crash)


def check_port(port: Port, cfg: BuildConfig, *, examples: int | None = 1000, seconds: float | None = None,  # noqa: C901 - the check loop with its crash, hang, time and shrink outcomes in one place
               seed: int = 0, progress: Callable[[CheckResult], None] | None = None,
               extra_streams: list[tuple[np.ndarray, np.ndarray]] = (), consts: Any = None) -> CheckResult:
    """Search for a stream on which ``port`` differs from the model for build ``cfg``.

    ``examples``: at most this many hypothesis streams (None: no limit); ``seconds``: stop starting new rounds
    after this long (None: no limit); at least one limit must be given. ``extra_streams`` (e.g. a golden
    vector's stream) are checked first, cut but not shrunk. ``progress`` is called after every round."""
    if examples is None and seconds is None:
        raise ValueError("check_port needs examples or seconds")
    consts = consts if consts is not None else build_constants(cfg)
    port.check_words(cfg.program)
    res = CheckResult(cfg=cfg, seed=seed, mismatch=None)
    t0 = time.perf_counter()
    for adc, acc in extra_streams:
        try:
            mm = mismatch_of(port, cfg, consts, np.asarray(adc), np.asarray(acc))
        except PortCrash as crash:
            mm = crash_of(port, cfg, consts, np.asarray(adc), np.asarray(acc), crash)
        if mm is not None:
            mm.source = "given"
        res.examples += 1
        res.samples += len(adc)
        if mm is not None:
            res.mismatch = mm
            res.examples_to_failure, res.samples_to_failure = res.examples, res.samples
            res.seconds = res.seconds_to_failure = time.perf_counter() - t0
            res.stopped_by = "difference (given stream)"
            return res
    strategy = port_streams(cfg, consts)
    state: dict[str, Any] = {"last": None, "failed_at": None, "first_len": 0, "crash": None, "hangs": 0}

    def test(stream: tuple[np.ndarray, np.ndarray]) -> None:
        adc, acc = stream
        if state["failed_at"] is None:
            res.examples += 1
            res.samples += len(adc)
        elif state["crash"] is not None:
            # shrinking a crash costs a child process per try, a hang a whole time-out: within the budget
            # (CRASH_SHRINK_S, or what is left of --time) and at most HANG_SHRINK_TRIES more time-outs
            spent = time.perf_counter() - state["failed_at"]
            budget = CRASH_SHRINK_S if seconds is None else min(CRASH_SHRINK_S, max(0.0, seconds - (
                state["failed_at"] - t0)))
            hang_cost = port.child.timeout_s if state["hangs"] else 0.0
            if spent + hang_cost > budget or state["hangs"] > HANG_SHRINK_TRIES:
                return
        try:
            diff, _ = compare(port, cfg, consts, adc, acc)
        except PortCrash as crash:
            if state["crash"] is not None and crash.kind != state["crash"].kind:
                return  # another failure than the one being shrunk
            if state["failed_at"] is None:
                state["failed_at"] = time.perf_counter()
                state["first_len"] = len(adc)
            state["hangs"] += "answer" in crash.kind
            state["crash"] = crash
            state["last"] = (adc, acc)
            raise _PortDiffers(f"crash: {crash.kind}") from None
        if diff is not None and state["crash"] is not None:
            return      # shrinking a crash: a plain difference is another failure
        if diff is not None:
            if state["failed_at"] is None:
                state["failed_at"] = time.perf_counter()
                state["first_len"] = len(adc)
            state["last"] = (adc, acc)
            raise _PortDiffers(f"sample {diff.sample} word {diff.word}")

    r = 0
    given_n = res.examples
    while True:
        if examples is not None and res.examples - given_n >= examples:
            res.stopped_by = "examples"
            break
        if seconds is not None and time.perf_counter() - t0 >= seconds:
            res.stopped_by = "time"
            break
        n = ROUND_EXAMPLES if examples is None else min(ROUND_EXAMPLES, examples - (res.examples - given_n))
        s = settings(max_examples=n, database=None, deadline=None, derandomize=False,
                     suppress_health_check=list(HealthCheck), phases=(Phase.generate, Phase.shrink),
                     report_multiple_bugs=False, verbosity=Verbosity.quiet, print_blob=False)
        run = hyp_seed(seed * 1_000_003 + r)(s(given(strategy)(test)))
        r += 1
        res.rounds = r
        try:
            run()
        except _PortDiffers:
            pass
        except Exception as exc:  # hypothesis wraps a failure it cannot reproduce (a port that is not
            if state["last"] is None:  # deterministic); anything before a difference is a real error
                raise
            res.notes.append(f"hypothesis: {type(exc).__name__}: {exc}".splitlines()[0])
        if state["last"] is not None:
            adc, acc = state["last"]
            t_fail = state["failed_at"]
            res.examples_to_failure, res.samples_to_failure = res.examples, res.samples
            res.seconds_to_failure = t_fail - t0
            if state["crash"] is not None:
                res.mismatch = crash_of(port, cfg, consts, adc, acc, state["crash"], state["first_len"], len(adc))
            else:
                shrunk_len = len(adc)
                adc, acc = cut_chunks(port, cfg, consts, adc, acc, seconds=CUT_CHUNKS_S if seconds is None else
                                      min(CUT_CHUNKS_S, max(0.0, seconds - (time.perf_counter() - t0))))
                try:
                    res.mismatch = mismatch_of(port, cfg, consts, adc, acc, state["first_len"], shrunk_len)
                except PortCrash as crash:
                    res.mismatch = crash_of(port, cfg, consts, adc, acc, crash, state["first_len"], len(adc))
            res.shrink_seconds = time.perf_counter() - t_fail
            res.stopped_by = "difference"
            break
        res.seconds = time.perf_counter() - t0
        if progress is not None:
            progress(res)
    res.seconds = time.perf_counter() - t0
    return res


__all__ = ["CheckResult", "Difference", "Mismatch", "check_port", "compare", "crash_of", "cut_chunks",
           "first_difference", "mismatch_of"]

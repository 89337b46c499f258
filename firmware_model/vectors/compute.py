"""Computing one golden-vector case: the firmware on the emulated 68000 (or the integer model), cross-checked
word for word against the integer model."""

from __future__ import annotations

import functools
import hashlib
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from firmware_model.firmware.assemble import build_firmware, source_path_text, source_sha256
from firmware_model.firmware.harness import run_firmware
from firmware_model.model.run import run_model
from firmware_model.runtime import diskcache
from firmware_model.runtime.errors import UserError
from firmware_model.spec.build_constants import FirmwareConstants, build_constants
from firmware_model.spec.config import BuildConfig
from firmware_model.vectors.cases import CaseSpec

#: Generator labels written into every case.
GENERATOR_EMULATION: str = "68000 emulation (isa), cross-checked against the numpy model"
GENERATOR_MODEL: str = "model"


# ------------------------------------------------------------------------------------------- running a case
@dataclass
class CaseResult:
    """Expected outputs of one case: words (n, n_words) and init words as Python ints, plus run metadata."""

    spec: CaseSpec
    generator: str
    source: str | None
    source_sha256: str | None
    consts: Any
    init: list[int]
    words: list[list[int]]
    cycles: dict[str, Any] | None
    first_wrap: int
    wrap_word: str
    #: First sample of each event, when computed while streaming (None: derived from ``words``).
    events_first: dict[str, int] | None = None
    #: The case's JSON and C header bytes, when a ``--jobs`` worker rendered them already (:func:`render_set`
    #: renders the rest; the same functions, so the same bytes).
    rendered: tuple[bytes, bytes] | None = field(default=None, compare=False, repr=False)


@functools.lru_cache(maxsize=256)
def _constants(cfg: BuildConfig) -> Any:
    """:func:`firmware_model.spec.build_constants.build_constants` of ``cfg``, once per process (a pure function of the
    frozen config) and kept in the disk cache (:func:`firmware_model.runtime.diskcache.cache_dir`,
    ``constants/<key>.pickle``) under the config's ``repr`` and :func:`firmware_model.runtime.diskcache.source_digest`:
    the gain designs and the altitude table fits of the committed matrix's 98 builds cost about 1 CPU-s in every run."""

    return diskcache.memo("constants",
                          lambda: hashlib.sha256(repr((1, repr(cfg), diskcache.source_digest())).encode()).hexdigest(),
                          lambda obj: isinstance(obj, FirmwareConstants) and obj.program == cfg.program,
                          lambda: build_constants(cfg))


def compute_case(spec: CaseSpec, generator: str = "emulation", builds: dict[Any, Any] | None = None) -> CaseResult:
    """Run one case. ``generator="emulation"``: the 68000 firmware on the emulated CPU, then the integer model on
    the same inputs; any differing word raises :class:`UserError` naming case, sample and word.
    ``generator="model"``: the integer model only (bootstrap; marked in the output). ``builds``: a dict the
    caller keeps over one run of many cases, so each build config is built (loaded) once in that run."""

    cfg, stream = spec.cfg, spec.stream
    adc = np.asarray(stream.adc, dtype=np.int64)
    acc = np.asarray(stream.acc, dtype=np.int64)
    cycles: dict[str, Any] | None = None
    if generator == "emulation":

        build = builds.get(cfg) if builds is not None else None
        if build is None:
            build = build_firmware(_constants(cfg))
            if builds is not None:
                builds[cfg] = build
        consts = build.consts
        trace = run_firmware(build, adc, acc)
        model = run_model(consts, adc, acc)
        _cross_check(spec.name, trace, model)
        label = GENERATOR_EMULATION
        source_sha = build.source_sha256
        if trace.cycles is not None:
            cyc = np.asarray(trace.cycles, dtype=np.int64)
            worst = int(np.argmax(cyc))
            cycles = {"cpu": "MC68000, zero wait states", "step_min": int(cyc.min()), "step_max": int(cyc.max()),
                      "step_max_sample": worst, "step_mean": round(float(cyc.mean()), 3),
                      "init": None if trace.init_cycles is None else int(trace.init_cycles)}
    elif generator == "model":
        consts = _constants(cfg)
        model = run_model(consts, adc, acc)
        trace = model
        label = GENERATOR_MODEL
        source_sha = source_sha256(cfg.program)  # the same hash the emulation path reports (includes too)
    else:
        raise UserError(f"vectors: unknown generator {generator!r} (emulation or model)")
    words = np.asarray(trace.words, dtype=np.int64)
    return CaseResult(spec=spec, generator=label, source=source_path_text(cfg.program),
                      source_sha256=source_sha, consts=consts,
                      init=np.asarray(trace.init_words, dtype=np.int64).tolist(),
                      words=words.tolist(), cycles=cycles,  # int64 -> Python ints
                      first_wrap=int(model.first_wrap), wrap_word=str(model.wrap_word))


def _cross_check(name: str, trace: Any, model: Any) -> None:
    """Raise :class:`UserError` at the first word where the emulated firmware and the integer model differ."""
    names = list(model.names)
    a_init, b_init = np.asarray(trace.init_words), np.asarray(model.init_words)
    if a_init.shape != b_init.shape or np.any(a_init != b_init):
        j = int(np.argmax(a_init != b_init)) if a_init.shape == b_init.shape else 0
        raise UserError(f"vectors: case {name}: emulated firmware and model differ after init, word {names[j]}: "
                        f"firmware {a_init.tolist()} model {b_init.tolist()}")
    a, b = np.asarray(trace.words), np.asarray(model.words)
    if a.shape != b.shape:
        raise UserError(f"vectors: case {name}: firmware trace shape {a.shape} != model {b.shape}")
    diff = np.argwhere(a != b)
    if diff.size:
        i, j = (int(v) for v in diff[0])
        raise UserError(f"vectors: case {name}: emulated firmware and model differ at sample {i} word {names[j]}: "
                        f"firmware {int(a[i, j])} model {int(b[i, j])}")

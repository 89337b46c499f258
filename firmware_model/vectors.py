"""Golden vectors for microcontroller ports (docs/vectors.md).

A *vector set* is a directory::

    <out>/manifest.json        every generated file with its SHA-256 (and the set kind)
    <out>/schema.json          JSON Schema of a case JSON
    <out>/cases/<name>.json    one case: description, build config, constants, inputs, expected words
    <out>/cases/<name>.h       the same data as C99 ``const`` arrays and ``#define`` constants
    <out>/c/cases.h            the table of every case for vectors/c/harness.c
    <out>/c/cases_avr.h        (full set only) the subset that fits an ATmega2560, for ``make -C vectors/c avr``

Expected words come from the 68000 firmware run on the emulated CPU (:mod:`firmware_model.harness`) and are
cross-checked, every word of every sample, against the numpy integer model (:func:`firmware_model.model.run_model`)
before anything is written. ``generator="model"`` (model only) exists for bootstrapping and is marked as such in
every file. Output is deterministic to the byte: sorted keys, floats with 12 significant digits, no timestamps.
Files are written into a temporary directory first and moved into place only when everything succeeded.
"""

from __future__ import annotations

import functools
import hashlib
import itertools
import json
import math
import sys
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from firmware_model.config import PROGRAMS, ROUNDINGS, BuildConfig, load_config
from firmware_model.errors import UserError
from firmware_model.inputs import (ACC_PROGRAMS, EDGE_KINDS, Stream, edge_stream, flight_params_for, read_stream_csv,
                                   supersonic_params_for, synthetic_flight)
from firmware_model.trace import EVENT_BITS, STATE_WORDS, word_names

#: Version of the case JSON layout (bump on any incompatible change; schema.json says the same).
SCHEMA_VERSION: int = 1
#: Generator labels written into every case.
GENERATOR_EMULATION: str = "68000 emulation (isa), cross-checked against the numpy model"
GENERATOR_MODEL: str = "model"
#: Program ids of vectors/c/fw.h (fw_program).
PROGRAM_IDS: dict[str, int] = {"recursive": 0, "kalman_baro": 1, "kalman_accel": 2, "recursive_seed_literal": 3}
C_PROGRAM_ENUM: dict[str, str] = {"recursive": "FW_RECURSIVE", "kalman_baro": "FW_KALMAN_BARO",
                                  "kalman_accel": "FW_KALMAN_ACCEL",
                                  "recursive_seed_literal": "FW_RECURSIVE_SEED_LITERAL"}
#: Gains in fw_consts order (vectors/c/fw.h).
GAIN_NAMES: tuple[str, ...] = ("G11", "G21", "G31", "G12", "G22", "G32", "ACC_G", "G11T", "G21T", "G31T")
#: Scalar constants in fw_consts order.
SCALAR_CONSTANTS: tuple[str, ...] = ("K", "ROUND", "BARO_SIGN", "S", "THR", "V_LIFT", "V_GATE", "MACH_VLO",
                                     "MACH_VHI", "MACH_E", "BARO_MIN", "BARO_MAX", "ALT_SHIFT", "ALT_N", "CAL_P",
                                     "E_GATE", "GATE_N", "APO_N", "MACH_N", "DLY_N", "DV", "A_COAST", "COAST_N",
                                     "V_DESC", "DU")

# ------------------------------------------------------------------------------------------- the case matrix
#: k values (sample period 2^-k s) of the committed set.
MATRIX_K: tuple[int, ...] = (4, 5, 6, 7, 8)
#: Barometer ADC widths of the committed set.
MATRIX_BITS: tuple[int, ...] = (12, 16)
#: Samples per edge stream.
EDGE_SAMPLES: int = 32
#: Seed of the synthetic flight of the committed set (one flight profile, sampled at every k).
FLIGHT_SEED: int = 20240601
#: Programs that get the synthetic flight (the seed-literal filter diverges; it gets the edge streams only).
FLIGHT_PROGRAMS: tuple[str, ...] = ("recursive", "kalman_baro", "kalman_accel")
#: The fast (transonic) flight: Kalman programs only, 16-bit barometer, these k (it is long: ~20 s).
FAST_FLIGHT_PROGRAMS: tuple[str, ...] = ("kalman_baro", "kalman_accel")
FAST_FLIGHT_K: tuple[int, ...] = (4, 5)
FAST_FLIGHT_BITS: int = 16
#: The supersonic flight with a transonic dip (issue 20; :func:`firmware_model.inputs.supersonic_params_for`):
#: every flight program, both roundings, at these k, 16-bit barometer.
SUPERSONIC_K: tuple[int, ...] = (5,)
FAST_FLIGHT_SEED: int = 20240602

Q_FORMATS: dict[str, dict[str, str]] = {
    "recursive": {"EST": "Q24.8 barometer units (z = BARO_SIGN*adc)", "EXT": "Q24.8 barometer units",
                  "VEL": "Q32.0 accelerometer counts x samples", "ACC0": "Q32.0 accelerometer counts",
                  "EVENTS": "uint16 event bits", "ZL": "Q32.0 barometer units (last sample used)",
                  "SUMA": "Q32.0 accelerometer counts (sum of pad readings)", "CAL": "uint16 pad samples",
                  "REJ": "uint16 rejected barometer samples in a row",
                  "NEG": "uint16 apogee evidence samples in a row",
                  "PHASE": "uint16 flight phase (0 pad, 1 boost, 2 coast, 3 apogee, 4 descent)",
                  "CST": "uint16 coast samples in a row"},
    "recursive_seed_literal": {"EST": "Q24.8 barometer units (z = BARO_SIGN*adc)"},
    "kalman_baro": {"X1": "Q24.8 m (table altitude)", "X2": "Q24.8 m/s", "X3": "Q24.8 m/s^2",
                    "EVENTS": "uint16 event bits", "APFRAC": "UQ0.16 fraction of a sample period",
                    "GND": "Q24.8 m (pad average)", "SUMZ": "Q24.8 m (sum of pad altitudes)",
                    "CAL": "uint16 pad samples", "REJ": "uint16 gated samples in a row",
                    "NEG": "uint16 apogee evidence samples in a row",
                    "PHASE": "uint16 flight phase (0 pad, 1 boost, 2 coast, 3 apogee, 4 descent)",
                    "CST": "uint16 coast samples in a row", "DLY": "uint16 Mach-delay samples left",
                    "VB": "Q24.8 m/s (plausibility bound)"},
    "kalman_accel": {"X1": "Q24.8 m (table altitude)", "X2": "Q24.8 m/s", "X3": "Q24.8 m/s^2",
                     "ACC0": "Q32.0 accelerometer counts (pad average)", "EVENTS": "uint16 event bits",
                     "APFRAC": "UQ0.16 fraction of a sample period", "GND": "Q24.8 m (pad average)",
                     "SUMZ": "Q24.8 m (sum of pad altitudes)", "SUMA": "Q32.0 sum of pad accelerometer counts",
                     "CAL": "uint16 pad samples", "REJ": "uint16 gated samples in a row",
                     "NEG": "uint16 apogee evidence samples in a row",
                     "PHASE": "uint16 flight phase (0 pad, 1 boost, 2 coast, 3 apogee, 4 descent)",
                     "CST": "uint16 coast samples in a row", "DLY": "uint16 Mach-delay samples left",
                     "VB": "Q24.8 m/s (plausibility bound)",
                     "LOCK": "uint16 Mach lockout samples left (0: barometer in use)"},
}


def units_per_metre_for(bits: int) -> float:
    """Barometer counts per metre used for a ``bits``-bit ADC in the committed set: 3.5 counts/m at 16 bits,
    scaled by 2^(bits-16) (the same pressure sensor read with fewer bits)."""
    return 3.5 * 2.0 ** (bits - 16)


def baro_sigma_for(bits: int) -> float:
    """Barometer noise (counts rms) of the committed set: 2 counts at 16 bits, scaled like the counts, but not
    below 0.5 count (quantization noise)."""
    return max(0.5, 2.0 * 2.0 ** (bits - 16))


def case_config(program: str, rounding: str, k: int, bits: int) -> BuildConfig:
    """The build config of one committed case: defaults of :class:`BuildConfig` except the ADC width, its counts
    per metre and noise, and a valid barometer range that excludes the two rail codes (0 and 2^bits-1: a saturated
    reading is invalid), so that the adc_min / adc_max / alternating streams exercise BARO_INVALID."""
    pa_per_count, pa_at_zero = _flight_sensor(bits)
    return BuildConfig(program=program, rounding=rounding, k=k, baro_bits=bits,
                       units_per_metre=units_per_metre_for(bits), baro_sigma=baro_sigma_for(bits),
                       baro_min=1, baro_max=(1 << bits) - 2, baro_pa_per_count=pa_per_count,
                       baro_pa_at_zero=pa_at_zero)


def _flight_sensor(bits: int) -> tuple[float, float]:
    """The linear barometer transfer (Pa per count, Pa at count 0) of :func:`firmware_model.inputs.synthetic_flight`
    for a ``bits``-bit ADC with the default pad (altitude, fraction of full scale): the altitude table of the
    committed Kalman cases matches the synthetic flights' sensor (field-ready firmware, docs/firmware-spec.md
    §2a). Counts below about 26,000 (16-bit) map to pressures under the table's floor (above ~31 km)."""
    from firmware_model.atmosphere import pressure_pa
    from firmware_model.inputs import FlightParams

    p = FlightParams()
    p_pad = float(pressure_pa(p.pad_altitude_m))
    a = (p_pad - float(pressure_pa(p.pad_altitude_m + 1.0))) / units_per_metre_for(bits)
    return a, p_pad - a * p.pad_fraction * ((1 << bits) - 1)


@dataclass(frozen=True)
class CaseSpec:
    """One golden-vector case: a build config and an input stream."""

    name: str
    cfg: BuildConfig
    stream: Stream


def case_name(program: str, rounding: str, k: int, bits: int, stream: str) -> str:
    """``<program>_<rounding>_k<k>_b<bits>_<stream>`` (a C identifier); ``bits`` = 32, the pascal kind's word:
    ``<program>_<rounding>_k<k>_pa_<stream>``."""
    return f"{program}_{rounding}_k{k}_{'pa' if bits == 32 else f'b{bits}'}_{stream}"


#: Pascal cases of the committed set (docs/vectors.md, "Pascal cases"): every program and rounding at this k, the
#: pascal edge streams of these kinds, and the pascal synthetic flight for (program, rounding) in
#: :data:`PASCAL_FLIGHTS`. Kept small: the whole set must stay under 20 MB.
PASCAL_K: int = 4
PASCAL_EDGE_KINDS: tuple[str, ...] = ("adc_min", "alternating", "ties", "ramp")
PASCAL_FLIGHTS: tuple[tuple[str, str], ...] = (("recursive", "floor"), ("kalman_baro", "half_up"),
                                               ("kalman_accel", "floor"))
#: Pascals per metre of the pascal cases' builds (rho g at sea level) and their barometer noise (Pa rms).
PASCAL_PA_PER_M: float = 12.0
PASCAL_SIGMA_PA: float = 3.0


def pascal_case_config(program: str, rounding: str, k: int) -> BuildConfig:
    """The build of a pascal case: ``baro_kind`` pascal (MS5607 range 1,000..120,000 Pa, the default table),
    12 Pa/m, 3 Pa noise, otherwise the defaults."""
    return BuildConfig(program=program, rounding=rounding, k=k, baro_kind="pascal", units_per_metre=PASCAL_PA_PER_M,
                       baro_sigma=PASCAL_SIGMA_PA)


def pascal_case_specs() -> list[CaseSpec]:
    """The pascal cases (:data:`PASCAL_K`, :data:`PASCAL_EDGE_KINDS`, :data:`PASCAL_FLIGHTS`), in a fixed order."""
    from firmware_model.inputs import pascal_edge_stream, synthetic_pascal_flight

    specs: list[CaseSpec] = []
    flight = synthetic_pascal_flight(PASCAL_K, seed=FLIGHT_SEED, noise_pa=PASCAL_SIGMA_PA)
    for program in PROGRAMS:
        for rounding in ROUNDINGS:
            cfg = pascal_case_config(program, rounding, PASCAL_K)
            for kind in PASCAL_EDGE_KINDS:
                stream = pascal_edge_stream(kind, EDGE_SAMPLES, PASCAL_K)
                specs.append(CaseSpec(case_name(program, rounding, PASCAL_K, 32, stream.name), cfg, stream))
            if (program, rounding) in PASCAL_FLIGHTS:
                specs.append(CaseSpec(case_name(program, rounding, PASCAL_K, 32, flight.name), cfg, flight))
    return specs


def case_matrix(require_logs: bool = True) -> list[CaseSpec]:
    """Every case of the committed set, in a fixed order (documented in docs/vectors.md):
    programs x roundings x k in :data:`MATRIX_K` x ADC bits in :data:`MATRIX_BITS` x (the
    :data:`~firmware_model.inputs.EDGE_KINDS` edge streams of :data:`EDGE_SAMPLES` samples, plus the synthetic
    flight for :data:`FLIGHT_PROGRAMS`), then the flight cases of
    :data:`firmware_model.flights.vectorcases.FLIGHT_CASES` (the real-log cases need ../shared/flights: without
    it a :class:`UserError`, or with ``require_logs=False`` the set without them)."""
    return grid_case_specs() + tail_case_specs(require_logs)


def grid_case_specs() -> list[CaseSpec]:
    """The first part of :func:`case_matrix`: programs x roundings x k x ADC bits (edge streams and synthetic
    flights). Cheap to build (no log, no simulation): ``--jobs`` starts running it while :func:`tail_case_specs`
    is built."""
    specs: list[CaseSpec] = []
    flights: dict[tuple[int, int], Stream] = {}
    for program in PROGRAMS:
        for rounding in ROUNDINGS:
            for k in MATRIX_K:
                for bits in MATRIX_BITS:
                    cfg = case_config(program, rounding, k, bits)
                    for kind in EDGE_KINDS:
                        stream = edge_stream(kind, EDGE_SAMPLES, bits, k)
                        specs.append(CaseSpec(case_name(program, rounding, k, bits, stream.name), cfg, stream))
                    if program in FLIGHT_PROGRAMS:
                        key = (k, bits)
                        if key not in flights:
                            flights[key] = synthetic_flight(k, bits, FLIGHT_SEED, flight_params_for(cfg))
                        stream = flights[key]
                        specs.append(CaseSpec(case_name(program, rounding, k, bits, stream.name), cfg, stream))
                    if program in FAST_FLIGHT_PROGRAMS and k in FAST_FLIGHT_K and bits == FAST_FLIGHT_BITS:
                        key = (k, -bits)
                        if key not in flights:
                            flights[key] = synthetic_flight(k, bits, FAST_FLIGHT_SEED, flight_params_for(cfg, True),
                                                            name="flight_fast")
                        stream = flights[key]
                        specs.append(CaseSpec(case_name(program, rounding, k, bits, stream.name), cfg, stream))
                    if program in FLIGHT_PROGRAMS and k in SUPERSONIC_K and bits == FAST_FLIGHT_BITS:
                        key = (k, -1000 - bits)
                        if key not in flights:
                            flights[key] = synthetic_flight(k, bits, FAST_FLIGHT_SEED, supersonic_params_for(cfg),
                                                            name="flight_supersonic")
                        stream = flights[key]
                        specs.append(CaseSpec(case_name(program, rounding, k, bits, stream.name), cfg, stream))
    return specs


def tail_case_specs(require_logs: bool = True) -> list[CaseSpec]:
    """The rest of :func:`case_matrix`, in order: the flight cases, then the pascal cases. The flight cases read
    the shared logs and simulate flights (seconds of work; :class:`UserError` when the logs are absent and
    ``require_logs``)."""
    # Flight cases (docs/vectors.md, "Flight cases"): MIT-licensed shared logs and simulated flights, floor, k = 5,
    # built as the apogee table builds them; provenance and licence in each case's input.provenance.
    from firmware_model.flights.vectorcases import flight_case_specs

    return flight_case_specs(case_name, CaseSpec, Stream, require_logs) + pascal_case_specs()


#: The subset run on the ATmega2560 under simavr (must fit 64 KiB of program-memory data: the Kalman cases carry
#: 14-17 words per sample and a 2 KiB altitude table since issue 20, so one flight per program family runs:
#: kalman_accel's, whose C path (step_kalman with the accelerometer) is a superset of kalman_baro's, and the
#: recursive one in floor rounding; the long transonic and the supersonic flights are left to the host).
AVR_CASES: tuple[str, ...] = tuple(
    [case_name("recursive", "floor", 4, 16, "flight")]
    + [case_name(p, "floor", PASCAL_K, 32, "edge_ties") for p in ("recursive", "kalman_accel")]
    + [case_name("kalman_accel", "half_up", 4, 16, "flight")]
    + [case_name(p, r, 4, 16, "edge_" + kind) for p in PROGRAMS for r in ROUNDINGS for kind in ("ties", "step")]
)


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


def _sha256_file(path: Path) -> str | None:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


@functools.lru_cache(maxsize=256)
def _constants(cfg: BuildConfig) -> Any:
    """:func:`firmware_model.constants.build_constants` of ``cfg``, once per process (a pure function of the frozen
    config) and kept in the disk cache (:func:`firmware_model.diskcache.cache_dir`, ``constants/<key>.pickle``) under
    the config's ``repr`` and :func:`firmware_model.diskcache.source_digest`: the gain designs and the altitude
    table fits of the committed matrix's 98 builds cost about 1 CPU-s in every run."""
    from firmware_model import diskcache
    from firmware_model.constants import FirmwareConstants, build_constants

    return diskcache.memo("constants",
                          lambda: hashlib.sha256(repr((1, repr(cfg), diskcache.source_digest())).encode()).hexdigest(),
                          lambda obj: isinstance(obj, FirmwareConstants) and obj.program == cfg.program,
                          lambda: build_constants(cfg))


def compute_case(spec: CaseSpec, generator: str = "emulation", builds: dict[Any, Any] | None = None) -> CaseResult:
    """Run one case. ``generator="emulation"``: the 68000 firmware on the emulated CPU, then the integer model on
    the same inputs; any differing word raises :class:`UserError` naming case, sample and word.
    ``generator="model"``: the integer model only (bootstrap; marked in the output). ``builds``: a dict the
    caller keeps over one run of many cases, so each build config is built (loaded) once in that run."""
    from firmware_model.build import source_sha256
    from firmware_model.model import run_model

    cfg, stream = spec.cfg, spec.stream
    adc = np.asarray(stream.adc, dtype=np.int64)
    acc = np.asarray(stream.acc, dtype=np.int64)
    cycles: dict[str, Any] | None = None
    if generator == "emulation":
        from firmware_model.build import build_firmware
        from firmware_model.harness import run_firmware

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
    return CaseResult(spec=spec, generator=label, source=f"firmware_model/asm/{cfg.program}.s",
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


# ------------------------------------------------------------------------------------------- formatting
def _fmt_float(x: float) -> float | None:
    """A float rounded to 12 significant digits (stable across platforms/BLAS); None for non-finite."""
    if not math.isfinite(x):
        return None
    return float(f"{x:.12g}")


def _clean(obj: Any) -> Any:
    """Recursively convert numpy scalars and floats into stable JSON values."""
    t = type(obj)  # the common exact types first (a case document has ~170 values); the rest as below
    if t is str or t is int or obj is None:
        return obj
    if t is float:
        return _fmt_float(obj)
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return _fmt_float(float(obj))
    return obj


def _dumps(value: Any) -> str:
    return json.dumps(value, sort_keys=True, separators=(", ", ": "), ensure_ascii=True, allow_nan=False)


@functools.lru_cache(maxsize=None)
def tool_version() -> str:
    """The fwemu package version (``fwemu <version>``)."""
    try:
        from importlib.metadata import version

        return f"fwemu {version('fwemu')}"
    except Exception:  # pragma: no cover - not installed
        return "fwemu unknown"


def case_document(res: CaseResult) -> dict[str, Any]:
    """The JSON document of one case (see schema.json)."""
    spec, consts = res.spec, res.consts
    cfg, stream = spec.cfg, spec.stream
    program = cfg.program
    names = word_names(program)
    gains = {}
    for gname, g in sorted(consts.gains.items()):
        gains[gname] = {"m": int(g.m), "s": int(g.s), "value": g.value, "target": g.target,
                        "rel_error": g.rel_error}
    words_first: dict[str, int] = {}
    if res.events_first is not None:
        words_first = dict(res.events_first)
    elif "EVENTS" in names:
        col = names.index("EVENTS")
        for ev, bit in EVENT_BITS.items():
            idx = next((i for i, row in enumerate(res.words) if row[col] & bit), -1)
            words_first[ev] = idx
    doc = {
        "schema_version": SCHEMA_VERSION,
        "name": spec.name,
        "generator": res.generator,
        "tool": tool_version(),
        "firmware": {"program": program, "source": res.source, "source_sha256": res.source_sha256,
                     "c_program_id": PROGRAM_IDS[program]},
        "build_config": cfg.to_dict(),
        "rounding": cfg.rounding,
        "sample_period": {"k": cfg.k, "dt_s": cfg.dt},
        "constants": {name: int(getattr(consts, name)) for name in SCALAR_CONSTANTS},
        "gains": gains,
        "alt_table": ({"file": f"tables/{_alt_tag(consts)}.json", "n_nodes": consts.ALT_N,
                       "shift": consts.ALT_SHIFT} if consts.ALT_TABLE else None),
        "q_formats": dict(Q_FORMATS[program]),
        "words": list(names),
        "word_bytes": {name: size for name, size in STATE_WORDS[program]},
        "event_bits": dict(EVENT_BITS),
        "events_first_sample": words_first,
        "input": {"name": stream.name, "n_samples": len(stream), "adc_bits": stream.bits,
                  "provenance": stream.provenance, "truth": stream.truth},
        "int32_wrap": {"first_sample": res.first_wrap, "quantity": res.wrap_word},
        "cycles_68000": res.cycles,
        "sequencing": "sample 0 is written before init and before the first step; init is sample -1",
        "init": res.init,
    }
    return _clean(doc)


def _joined(chunks: Iterable[str], sep: str) -> Iterator[str]:
    """The non-empty text ``chunks`` with ``sep`` between them."""
    first = True
    for chunk in chunks:
        if not chunk:
            continue
        if not first:
            yield sep
        yield chunk
        first = False


def _json_values(values: Any) -> str:
    arr = np.asarray(values)
    if arr.dtype.kind in "iu":  # tolist() gives Python ints: str is the text int() would give
        return ", ".join(map(str, arr.tolist()))
    return ", ".join(str(int(v)) for v in arr.tolist())


def _json_rows(rows: Any) -> str:
    return ",\n  ".join("[" + ", ".join(str(v) for v in row) + "]" for row in rows)


def case_json_parts(res: CaseResult, adc_chunks: Iterable[str], acc_chunks: Iterable[str],
                    expected_chunks: Iterable[str]) -> Iterator[str]:
    """The case JSON text in pieces (:func:`case_json`), the long arrays given as text chunks (``adc``/``acc``:
    ``", "``-joined values; ``expected``: ``",\n  "``-joined rows), so a long case streams to a file."""
    doc = case_document(res)
    doc["adc"] = None
    doc["acc"] = None
    doc["expected"] = None
    keys = sorted(doc)
    yield "{\n"
    for n, key in enumerate(keys):
        comma = "," if n + 1 < len(keys) else ""
        end = "\n" if n + 1 < len(keys) else ""
        if key in ("adc", "acc"):
            yield f' "{key}": ['
            yield from _joined(adc_chunks if key == "adc" else acc_chunks, ", ")
            yield f"]{comma}{end}"
        elif key == "expected":
            yield ' "expected": [\n  '
            yield from _joined(expected_chunks, ",\n  ")
            yield f"\n ]{comma}{end}"
        else:
            yield f' "{key}": {_dumps(doc[key])}{comma}{end}'
    yield "\n}\n"


def case_json(res: CaseResult) -> str:
    """The case JSON text: sorted keys, one line per key, the inputs and expected words one sample per line."""
    stream = res.spec.stream
    return "".join(case_json_parts(res, [_json_values(stream.adc)], [_json_values(stream.acc)],
                                   [_json_rows(res.words)]))


def _c_rows(values: Iterable[int], per_line: int = 16) -> str:
    ints = values.tolist() if isinstance(values, np.ndarray) and values.dtype.kind in "iu" else None
    if ints is not None and _INT32_MIN not in ints:
        vals = list(map(str, ints))  # Python ints: each value's C text is its str, unless it is INT32_MIN
    else:
        vals = [_c_i32(int(v)) for v in values]
    return ",\n".join("    " + ", ".join(vals[i:i + per_line]) for i in range(0, len(vals), per_line))


_INT32_MIN = -(1 << 31)


def _c_i32(v: int) -> str:
    """An int32 value as a C constant valid for every compiler (INT32_MIN is written as an expression)."""
    return "(-2147483647 - 1)" if v == _INT32_MIN else str(v)


def _c_expected(rows: Any) -> str:
    return ",\n".join("    { " + ", ".join(_c_i32(v) for v in row) + " }" for row in rows)


def case_header_parts(res: CaseResult, adc_chunks: Iterable[str], acc_chunks: Iterable[str],
                      expected_chunks: Iterable[str]) -> Iterator[str]:
    """The C99 header of one case in pieces (:func:`case_header`); the arrays as text chunks of :func:`_c_rows`
    (a multiple of 16 values each, except the last) and of :func:`_c_expected` rows."""
    spec, consts = res.spec, res.consts
    cfg, stream = spec.cfg, spec.stream
    name = spec.name
    up = name.upper()
    names = word_names(cfg.program)
    n, nw = len(stream), len(names)
    out = [f"/* Golden vectors: case {name}. Generated by {tool_version()}; do not edit (fwemu vectors). */",
           f"/* generator: {res.generator} */",
           f"/* program {cfg.program}, rounding {cfg.rounding}, dt = 2^-{cfg.k} s, "
           f"{'32-bit pascal' if cfg.pascal else f'{stream.bits}-bit'} barometer, "
           f"input {stream.name} ({n} samples) */",
           f"/* firmware source sha256: {res.source_sha256} */",
           f"#ifndef FWV_{up}_H", f"#define FWV_{up}_H", "", "#include <stdint.h>", "",
           "#ifndef FWV_ROM", "#define FWV_ROM /* e.g. PROGMEM on AVR */", "#endif", "",
           f'#define FWV_{up}_PROGRAM "{cfg.program}"',
           f"#define FWV_{up}_PROGRAM_ID {PROGRAM_IDS[cfg.program]}",
           f'#define FWV_{up}_ROUNDING "{cfg.rounding}"',
           f"#define FWV_{up}_N_SAMPLES {n}", f"#define FWV_{up}_N_WORDS {nw}"]
    for cname in SCALAR_CONSTANTS:
        out.append(f"#define FWV_{up}_{cname} ({_c_i32(int(getattr(consts, cname)))})")
    for gname in GAIN_NAMES:
        if gname in consts.gains:
            g = consts.gains[gname]
            out.append(f"#define FWV_{up}_{gname}_M ({int(g.m)}) /* {gname} = m / 2^s = {g.value!r} */")
            out.append(f"#define FWV_{up}_{gname}_S ({int(g.s)})")
    if consts.ALT_TABLE:
        out += [f"/* altitude table (Q24.8 m, node j at count j << {consts.ALT_SHIFT}), shared by every case with the "
                "same table */", f'#include "../tables/{_alt_tag(consts)}.h"']
    out.append("/* column index of each state word in fwv_" + name + "_expected (and _init) */")
    for j, wname in enumerate(names):
        out.append(f"#define FWV_{up}_W_{wname} {j} /* {Q_FORMATS[cfg.program][wname]} */")
    if cfg.pascal:
        out += ["", f"#define FWV_{up}_PASCAL (1)",
                "/* barometer: the pascal kind's signed 32-bit word (Pa), sample 0 is also the init sample */",
                f"static const int32_t fwv_{name}_pa[{n}] FWV_ROM = {{", ""]
    else:
        out += ["", f"/* barometer ADC counts (unsigned {stream.bits}-bit), sample 0 is also the init sample */",
                f"static const uint16_t fwv_{name}_adc[{n}] FWV_ROM = {{", ""]
    yield "\n".join(out)
    yield from _joined(adc_chunks, ",\n")
    yield "\n" + "\n".join(["};", "/* accelerometer counts (signed 16-bit) */",
                             f"static const int16_t fwv_{name}_acc[{n}] FWV_ROM = {{", ""])
    yield from _joined(acc_chunks, ",\n")
    yield "\n" + "\n".join([
        "};", "/* state words after init (.w words zero-extended) */",
        f"static const int32_t fwv_{name}_init[{nw}] FWV_ROM = {{ {', '.join(_c_i32(v) for v in res.init)} }};",
        f"/* state words after step i: {' '.join(names)} */",
        f"static const int32_t fwv_{name}_expected[{n}][{nw}] FWV_ROM = {{", ""])
    yield from _joined(expected_chunks, ",\n")
    yield "\n" + "\n".join(["};", "", f"#endif /* FWV_{up}_H */", ""])


def case_header(res: CaseResult) -> str:
    """The C99 header of one case: ``FWV_<NAME>_*`` macros and ``fwv_<name>_*`` const arrays (FWV_ROM placement,
    empty by default: define it to PROGMEM or a section attribute before including)."""
    stream = res.spec.stream
    return "".join(case_header_parts(res, [_c_rows(stream.adc)], [_c_rows(stream.acc)], [_c_expected(res.words)]))


def _row_texts(rows: Any) -> tuple[str, str]:
    """``(_json_rows(rows), _c_expected(rows))`` with each row's numbers converted to text once: a row of Python
    ints prints as ``str(row)`` = ``"[" + ", ".join(map(str, row)) + "]"``, the JSON row, and the same numbers
    make the C row unless one is INT32_MIN (then :func:`_c_expected`'s spelling). Rows that are not lists of
    Python ints are formatted value by value by those two functions."""
    if not (isinstance(rows, list) and all(type(r) is list for r in rows)
            and set(map(type, itertools.chain.from_iterable(rows))) <= {int}):
        return _json_rows(rows), _c_expected(rows)
    text = [str(r)[1:-1] for r in rows]
    json_rows = ",\n  ".join(["[" + t + "]" for t in text])
    c_rows = ",\n".join(["    { " + t + " }" if _INT32_MIN not in r else
                          "    { " + ", ".join(_c_i32(v) for v in r) + " }" for t, r in zip(text, rows)])
    return json_rows, c_rows


def render_case(res: CaseResult) -> tuple[bytes, bytes]:
    """``(case_json(res), case_header(res))`` encoded, with each row of expected words converted to text once for
    both files: a row of Python ints prints as ``str(row)`` = ``"[" + ", ".join(map(str, row)) + "]"``, the JSON
    row, and the same numbers make the C row unless one is INT32_MIN (then :func:`_c_expected`'s spelling). The
    number-to-text conversion is most of the rendering; the bytes equal the two functions' (tests/test_vectors.py)."""
    json_rows, c_rows = _row_texts(res.words)
    stream = res.spec.stream
    json_b = "".join(case_json_parts(res, [_json_values(stream.adc)], [_json_values(stream.acc)], [json_rows]))
    header_b = "".join(case_header_parts(res, [_c_rows(stream.adc)], [_c_rows(stream.acc)], [c_rows]))
    return json_b.encode(), header_b.encode()



def alt_table_files(consts: Any) -> dict[str, bytes]:
    """The shared altitude-table files of a Kalman build: ``tables/<tag>.json`` (the node list, Q24.8 m) and
    ``tables/<tag>.h`` (``fwv_<tag>[]`` with FWV_ROM placement), included by every case header that uses it."""
    return dict(_alt_table_files(tuple(consts.ALT_TABLE), consts.ALT_SHIFT))


@functools.lru_cache(maxsize=64)
def _alt_table_files(table: tuple[int, ...], shift: int) -> tuple[tuple[str, bytes], ...]:
    """:func:`alt_table_files` of a table (every case of a build, and every build with the same sensor, renders
    the same files: once per process)."""
    tag, n = _alt_tag_of(table), len(table)
    doc = {"name": tag, "shift": shift, "n_nodes": n, "q_format": "Q24.8 m",
           "node_count_of_j": f"j << {shift}", "nodes": list(table)}
    h = [f"/* Golden vectors: altitude table {tag}. Generated by {tool_version()}; do not edit (fwemu vectors). */",
         f"#ifndef FWV_{tag.upper()}_H", f"#define FWV_{tag.upper()}_H", "", "#include <stdint.h>", "",
         "#ifndef FWV_ROM", "#define FWV_ROM /* e.g. PROGMEM on AVR */", "#endif", "",
         f"/* {n} nodes, Q24.8 m; node j is the altitude at count j << {shift} */",
         f"static const int32_t fwv_{tag}[{n}] FWV_ROM = {{",
         ",\n".join("    " + ", ".join(_c_i32(v) for v in table[i:i + 8]) for i in range(0, n, 8)),
         "};", "", f"#endif /* FWV_{tag.upper()}_H */", ""]
    return ((f"tables/{tag}.json", (json.dumps(doc, sort_keys=True) + "\n").encode()),
            (f"tables/{tag}.h", "\n".join(h).encode()))


def _alt_tag(consts: Any) -> str:
    """C identifier of a build's altitude table: ``alt_`` + the first 12 hex digits of the nodes' SHA-256."""
    return _alt_tag_of(tuple(consts.ALT_TABLE))


@functools.lru_cache(maxsize=64)
def _alt_tag_of(table: tuple[int, ...]) -> str:
    digest = hashlib.sha256(",".join(str(v) for v in table).encode()).hexdigest()[:12]
    return f"alt_{digest}"


def cases_table_header(results: Sequence[CaseResult], guard: str) -> str:
    """The harness's case table (vectors/c/cases.h or cases_avr.h): includes every case header and fills an
    ``fwv_case`` per case (missing gains are {0, 0})."""
    out = [f"/* Case table for vectors/c/harness.c. Generated by {tool_version()}; do not edit. */",
           f"#ifndef {guard}", f"#define {guard}", "", '#include "fwv_case.h"', ""]
    for res in results:
        out.append(f'#include "{res.spec.name}.h"')
    out += ["", f"#define FWV_N_CASES {len(results)}u", "static const fwv_case fwv_cases[] FWV_ROM = {"]
    rows = []
    for res in results:
        name, up = res.spec.name, res.spec.name.upper()
        program = res.spec.cfg.program
        scal = {c: f"FWV_{up}_{c}" for c in SCALAR_CONSTANTS}
        gains = {g: (f"{{FWV_{up}_{g}_M, FWV_{up}_{g}_S}}" if g in res.consts.gains else "{0, 0}")
                 for g in GAIN_NAMES}
        consts = ("{" + ", ".join(scal[c] for c in ("K", "ROUND", "BARO_SIGN", "S", "THR", "V_LIFT", "V_GATE"))
                  + ", " + ", ".join(gains[g] for g in GAIN_NAMES) + ", "
                  + ", ".join(scal[c] for c in ("MACH_VLO", "MACH_VHI", "MACH_E", "BARO_MIN", "BARO_MAX",
                                                "ALT_SHIFT", "ALT_N", "CAL_P", "E_GATE", "GATE_N", "APO_N",
                                                "MACH_N", "DLY_N", "DV", "A_COAST", "COAST_N", "V_DESC", "DU"))
                  + ", " + (f"fwv_{_alt_tag(res.consts)}" if res.consts.ALT_TABLE else "0") + "}")
        adc_ptr, pa_ptr = ("0", f"fwv_{name}_pa") if res.spec.cfg.pascal else (f"fwv_{name}_adc", "0")
        rows.append(f'    {{"{name}", {C_PROGRAM_ENUM[program]}, {consts},\n'
                    f"     FWV_{up}_N_SAMPLES, FWV_{up}_N_WORDS, {adc_ptr}, fwv_{name}_acc, fwv_{name}_init,\n"
                    f"     &fwv_{name}_expected[0][0], {pa_ptr}}}")
    out.append(",\n".join(rows))
    out += ["};", "", f"#endif /* {guard} */", ""]
    return "\n".join(out)


# ------------------------------------------------------------------------------------------- schema
def case_schema() -> dict[str, Any]:
    """JSON Schema (draft 2020-12) of a case JSON."""
    int_array = {"type": "array", "items": {"type": "integer"}}
    gain = {"type": "object", "required": ["m", "s", "value", "target", "rel_error"],
            "properties": {"m": {"type": "integer", "minimum": -32768, "maximum": 32767},
                           "s": {"type": "integer", "minimum": 0, "maximum": 47},
                           "value": {"type": "number"}, "target": {"type": "number"},
                           "rel_error": {"type": "number"}}}
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "$id": "https://fwemu.invalid/vectors/schema.json",
        "title": "fwemu golden-vector case",
        "description": "One firmware build run on one input stream: inputs and the expected state words after init "
                       "and after every step (docs/firmware-spec.md section 7). .l words are int32, .w words "
                       "unsigned 16-bit.",
        "type": "object",
        "required": ["schema_version", "name", "generator", "tool", "firmware", "build_config", "rounding",
                     "sample_period", "constants", "gains", "alt_table", "q_formats", "words", "word_bytes", "event_bits",
                     "events_first_sample", "input", "int32_wrap", "cycles_68000", "sequencing", "init", "adc",
                     "acc", "expected"],
        "additionalProperties": False,
        "properties": {
            "schema_version": {"const": SCHEMA_VERSION},
            "name": {"type": "string", "pattern": "^[a-z][a-z0-9_]*$"},
            "generator": {"enum": [GENERATOR_EMULATION, GENERATOR_MODEL]},
            "tool": {"type": "string"},
            "firmware": {"type": "object", "required": ["program", "source", "source_sha256", "c_program_id"],
                         "properties": {"program": {"enum": list(PROGRAMS)},
                                        "source": {"type": "string"},
                                        "source_sha256": {"type": ["string", "null"]},
                                        "c_program_id": {"type": "integer", "minimum": 0, "maximum": 3}}},
            "build_config": {"type": "object", "required": ["program", "k", "rounding", "baro_bits"]},
            "rounding": {"enum": list(ROUNDINGS)},
            "sample_period": {"type": "object", "required": ["k", "dt_s"],
                              "properties": {"k": {"type": "integer", "minimum": 0, "maximum": 10},
                                             "dt_s": {"type": "number"}}},
            "constants": {"type": "object", "required": list(SCALAR_CONSTANTS),
                          "additionalProperties": {"type": "integer"}},
            "gains": {"type": "object", "additionalProperties": gain},
            "alt_table": {"type": ["object", "null"], "required": ["file", "n_nodes", "shift"],
                          "properties": {"file": {"type": "string"}, "n_nodes": {"type": "integer", "minimum": 2},
                                         "shift": {"type": "integer", "minimum": 1, "maximum": 15}}},
            "q_formats": {"type": "object", "additionalProperties": {"type": "string"}},
            "words": {"type": "array", "items": {"type": "string"}, "minItems": 1,
                      "maxItems": max(len(w) for w in STATE_WORDS.values())},
            "word_bytes": {"type": "object", "additionalProperties": {"enum": [2, 4]}},
            "event_bits": {"type": "object", "additionalProperties": {"type": "integer"}},
            "events_first_sample": {"type": "object", "additionalProperties": {"type": "integer", "minimum": -1}},
            "input": {"type": "object", "required": ["name", "n_samples", "adc_bits", "provenance", "truth"],
                      "properties": {"n_samples": {"type": "integer", "minimum": 1},
                                     "adc_bits": {"type": "integer", "minimum": 8, "maximum": 32}}},
            "int32_wrap": {"type": "object", "required": ["first_sample", "quantity"]},
            "cycles_68000": {"type": ["object", "null"]},
            "sequencing": {"type": "string"},
            "init": int_array,
            "adc": {"type": "array", "items": {"type": "integer", "minimum": -2147483648, "maximum": 2147483647}},
            "acc": {"type": "array", "items": {"type": "integer", "minimum": -32768, "maximum": 32767}},
            "expected": {"type": "array", "items": {"type": "array", "items": {
                "type": "integer", "minimum": -2147483648, "maximum": 2147483647}}},
        },
    }


def validate(instance: Any, schema: dict[str, Any], where: str = "$") -> list[str]:
    """Check ``instance`` against the subset of JSON Schema that :func:`case_schema` uses (type, const, enum,
    required, properties, additionalProperties, items, minimum/maximum, minItems/maxItems, pattern). Returns the
    problems found as ``<json path>: <why>`` strings (empty when valid)."""
    import re

    errs: list[str] = []
    types = {"object": dict, "array": list, "string": str, "number": (int, float), "integer": int,
             "null": type(None), "boolean": bool}
    if "type" in schema:
        allowed = schema["type"] if isinstance(schema["type"], list) else [schema["type"]]
        ok = any(isinstance(instance, types[t]) and not (t in ("integer", "number") and isinstance(instance, bool))
                 for t in allowed)
        if not ok:
            return [f"{where}: expected {'/'.join(allowed)}, got {type(instance).__name__}"]
    if "const" in schema and instance != schema["const"]:
        errs.append(f"{where}: must be {schema['const']!r}")
    if "enum" in schema and instance not in schema["enum"]:
        errs.append(f"{where}: {instance!r} not one of {schema['enum']!r}")
    if isinstance(instance, (int, float)) and not isinstance(instance, bool):
        if "minimum" in schema and instance < schema["minimum"]:
            errs.append(f"{where}: {instance} < minimum {schema['minimum']}")
        if "maximum" in schema and instance > schema["maximum"]:
            errs.append(f"{where}: {instance} > maximum {schema['maximum']}")
    if isinstance(instance, str) and "pattern" in schema and not re.search(schema["pattern"], instance):
        errs.append(f"{where}: {instance!r} does not match {schema['pattern']!r}")
    if isinstance(instance, dict):
        for key in schema.get("required", []):
            if key not in instance:
                errs.append(f"{where}: missing required key {key!r}")
        props = schema.get("properties", {})
        extra = schema.get("additionalProperties", True)
        for key, value in instance.items():
            if key in props:
                errs += validate(value, props[key], f"{where}.{key}")
            elif extra is False:
                errs.append(f"{where}: unexpected key {key!r}")
            elif isinstance(extra, dict):
                errs += validate(value, extra, f"{where}.{key}")
    if isinstance(instance, list):
        if "minItems" in schema and len(instance) < schema["minItems"]:
            errs.append(f"{where}: fewer than {schema['minItems']} items")
        if "maxItems" in schema and len(instance) > schema["maxItems"]:
            errs.append(f"{where}: more than {schema['maxItems']} items")
        if "items" in schema and not _valid_int_items(instance, schema["items"]):
            for i, value in enumerate(instance):
                errs += validate(value, schema["items"], f"{where}[{i}]")
                if len(errs) > 20:
                    break
    return errs


def _valid_int_items(items: list[Any], schema: dict[str, Any]) -> bool:
    """True when ``schema`` only asks for integers in a range and every item is an int (not a bool) in it: such an
    item gives :func:`validate` no problem, so the per-item walk (1.5 M values in the committed set) is skipped.
    False means "walk them" (any other schema, or some item fails: the walk then names it)."""
    if set(schema) - {"type", "minimum", "maximum"} or schema.get("type") != "integer":
        return False
    if not all(type(v) is int for v in items):
        return False
    if items and "minimum" in schema and min(items) < schema["minimum"]:
        return False
    return not (items and "maximum" in schema and max(items) > schema["maximum"])


# ------------------------------------------------------------------------------------------- writing a set
def _sha256_bytes(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


class _Progress:
    """A one-line progress bar on stderr, drawn only when stderr is a terminal; counts ``unit`` (samples)."""

    def __init__(self, total: int, label: str, enabled: bool | None = None, unit: str = "samples") -> None:
        self.total = max(total, 1)
        self.label = label
        self.unit = unit
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self.done = 0
        self._last = -1.0

    def step(self, what: str, amount: int = 1) -> None:
        self.done += amount
        if not self.enabled:
            return
        import time

        now = time.monotonic()
        if now - self._last < 0.1 and self.done < self.total:
            return
        self._last = now
        width = 30
        fill = int(width * min(self.done, self.total) / self.total)
        sys.stderr.write(f"\r{self.label} [{'#' * fill}{'.' * (width - fill)}] {self.done:,}/{self.total:,} "
                         f"{self.unit} {what[:40]:<40}")
        sys.stderr.flush()

    def close(self) -> None:
        if self.enabled:
            sys.stderr.write("\n")
            sys.stderr.flush()


def render_set(results: Sequence[CaseResult], kind: str, avr: Sequence[str] = ()) -> dict[str, bytes]:
    """All files of a vector set as {relative path: bytes}, including manifest.json (computed last)."""
    files: dict[str, bytes] = {}
    for res in results:
        json_b, header_b = res.rendered or render_case(res)
        files[f"cases/{res.spec.name}.json"] = json_b
        files[f"cases/{res.spec.name}.h"] = header_b
        if res.consts.ALT_TABLE:
            files.update(alt_table_files(res.consts))
    files["c/cases.h"] = cases_table_header(results, "FWV_CASES_H").encode()
    if avr:
        by_name = {r.spec.name: r for r in results}
        missing = [n for n in avr if n not in by_name]
        if missing:
            raise UserError(f"vectors: AVR subset names unknown cases: {', '.join(missing)}")
        files["c/cases_avr.h"] = cases_table_header([by_name[n] for n in avr], "FWV_CASES_AVR_H").encode()
    files["schema.json"] = schema_bytes()
    files["manifest.json"] = manifest_bytes(kind, [r.generator for r in results], len(results),
                                            {path: _sha256_bytes(data) for path, data in sorted(files.items())})
    return files


def schema_bytes() -> bytes:
    """The bytes of ``schema.json``."""
    return (json.dumps(case_schema(), sort_keys=True, indent=1) + "\n").encode()


def manifest_bytes(kind: str, generators: Iterable[str], n_cases: int, hashes: dict[str, str]) -> bytes:
    """The bytes of ``manifest.json``: set kind, tool, generators, case count and {relative path: SHA-256}."""
    manifest = {"schema_version": SCHEMA_VERSION, "kind": kind, "tool": tool_version(),
                "generators": sorted(set(generators)), "n_cases": n_cases, "files": dict(sorted(hashes.items()))}
    return (json.dumps(manifest, sort_keys=True, indent=1) + "\n").encode()


def write_set(files: dict[str, bytes], out: str | Path, kind: str) -> None:
    """Write a rendered set into ``out`` through :func:`firmware_model.output.staged_folder`: every file goes to a
    stage folder beside ``out`` first; then, under the folder lock and with SIGINT/SIGTERM deferred, ``cases/`` is
    swapped in as a whole and each other file replaced with ``os.replace``, the manifest last. On any error or
    interrupt before the commit nothing in ``out`` changes and no temporary name remains. A user set (kind
    ``user``) refuses to overwrite a directory holding the committed set (manifest kind ``all``)."""
    from firmware_model import output

    owned = ("cases", "tables") if any(rel.startswith("tables/") for rel in files) else ("cases",)
    with output.staged_folder(out, owned=owned, guard=_set_guard(kind), last=("manifest.json",)) as stage:
        for rel, data in files.items():
            path = stage / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)


def _set_guard(kind: str) -> Any:
    """The commit guard of :func:`write_set`: a non-``all`` set never replaces the committed set."""

    def guard(out: Path) -> None:
        old_manifest = out / "manifest.json"
        if kind == "all" or not old_manifest.exists():
            return
        try:
            old_kind = json.loads(old_manifest.read_text()).get("kind")
        except (OSError, ValueError, AttributeError):
            old_kind = None
        if old_kind == "all":
            raise UserError(f"vectors: {out} holds the committed vector set; choose another --out for a user set")

    return guard


def _compute_job(job: tuple[Sequence[CaseSpec], str, bool]) -> list[CaseResult]:
    specs, generator, render = job
    builds: dict[Any, Any] = {}
    results = [compute_case(spec, generator, builds) for spec in specs]
    if render:  # the per-case files, in the worker: render_set in the parent is then only the tables + manifest
        for res in results:
            res.rendered = render_case(res)
    return results


def _job_batches(specs: Sequence[CaseSpec], jobs: int) -> list[list[int]]:
    """Indices of ``specs`` in batches for ``jobs`` workers: the cases of one build stay together (a worker then
    assembles or loads each build and compiles its blocks once), about ``4 * jobs`` batches of similar sample
    counts, largest first (so the last batch to finish is a short one)."""
    by_cfg: dict[Any, list[int]] = {}
    for i, spec in enumerate(specs):
        by_cfg.setdefault(spec.cfg, []).append(i)
    groups = sorted(by_cfg.values(), key=lambda g: -sum(len(specs[i].stream) for i in g))
    n_batches = min(len(groups), 4 * jobs)
    batches: list[list[int]] = [[] for _ in range(n_batches)]
    load = [0] * n_batches
    for g in groups:  # greedy: each build to the lightest batch so far
        b = load.index(min(load))
        batches[b] += g
        load[b] += sum(len(specs[i].stream) for i in g) + 2000  # + a build's fixed cost, in samples
    order = sorted(range(n_batches), key=lambda b: -load[b])
    return [sorted(batches[b]) for b in order if batches[b]]


def _worker_start() -> None:
    """Initializer of a ``--jobs`` worker: SIGINT ignored, SIGTERM quiet (:func:`firmware_model.output.worker_init`),
    then the modules every case needs imported, while the parent is still building the case matrix."""
    from firmware_model.output import worker_init

    worker_init()
    import firmware_model.harness  # noqa: F401
    import firmware_model.model  # noqa: F401


def _start_pool(n: int) -> Any:
    import multiprocessing

    from firmware_model.output import worker_signals_ignored

    # spawn, not fork: a forked child of a process whose numba thread pool already ran can deadlock.
    # The workers are started with SIGINT ignored (inherited through exec, kept by Python): a Ctrl-C to
    # the process group while they are still importing must not print their KeyboardInterrupt.
    with worker_signals_ignored():
        return multiprocessing.get_context("spawn").Pool(n, initializer=_worker_start)


def generate(specs: Sequence[CaseSpec], generator: str = "emulation", progress: bool | None = None,
             jobs: int = 1, pool: Any = None, render: bool = False,
             more: Callable[[], Sequence[CaseSpec]] | None = None) -> list[CaseResult]:
    """Run every case (in order); ``jobs`` > 1 runs them in that many worker processes, the cases of one build in
    one worker (:func:`_job_batches`). The results come back in the order of ``specs`` whatever the workers'
    timing, so the files written are byte-identical to ``jobs=1``. An error or interrupt terminates the workers
    at once. ``pool``: workers the caller started already (:func:`_start_pool`; terminated here). ``render``: the
    workers also render each case's files (:attr:`CaseResult.rendered`), in parallel. ``more``: a function
    returning further cases, run after ``specs`` (their results follow in order); with workers it is called
    after the batches of ``specs`` are handed to them, so that building the further cases overlaps running the
    first ones (an error it raises ends the workers as any other)."""
    if jobs <= 1 or (len(specs) <= 1 and more is None):
        specs = list(specs) + (list(more()) if more is not None else [])
        bar = _Progress(sum(len(s.stream) for s in specs), "vectors", progress, unit="samples")
        builds: dict[Any, Any] = {}
        results: list[CaseResult] = []
        try:
            for spec in specs:
                results.append(compute_case(spec, generator, builds))
                bar.step(spec.name, len(spec.stream))
        finally:
            if pool is not None:  # started by the caller, not needed
                pool.terminate()
                pool.join()
            bar.close()
        return results
    bar = None
    try:
        if pool is None:
            pool = _start_pool(jobs)
        pending: list[tuple[list[CaseSpec], Any]] = []  # (a batch's specs, its AsyncResult), in submission order

        def submit(part: Sequence[CaseSpec]) -> None:
            for b in _job_batches(part, jobs):
                batch = [part[i] for i in b]
                pending.append((batch, pool.apply_async(_compute_job, ((batch, generator, render),))))

        order = list(specs)
        submit(order)
        if more is not None:
            tail = list(more())
            submit(tail)
            order += tail
        bar = _Progress(sum(len(s.stream) for s in order), "vectors", progress, unit="samples")
        done: dict[int, CaseResult] = {}
        for batch, pend in pending:
            for spec, res in zip(batch, pend.get()):
                done[id(spec)] = res
                bar.step(res.spec.name, len(res.spec.stream))
        pool.close()
        pool.join()  # every result is in: the workers leave on their own (terminate() after close() once hung)
        pool = None
        return [done[id(s)] for s in order]
    finally:
        if pool is not None:  # an error or an interrupt: end the workers at once
            pool.terminate()
            pool.join()
        if bar is not None:
            bar.close()


def generate_all(out: str | Path, generator: str = "emulation", progress: bool | None = None,
                 jobs: int = 1) -> dict[str, bytes]:
    """Regenerate the whole committed set (:func:`case_matrix`) into ``out``; returns the files written. With
    ``jobs`` > 1 the workers start first, so their start-up overlaps the building of the case matrix, and they
    run the grid cases (:func:`grid_case_specs`) while the flight and pascal cases (:func:`tail_case_specs`:
    logs read, flights simulated) are built."""
    pool = _start_pool(jobs) if jobs > 1 else None
    try:
        grid = grid_case_specs()
    except BaseException:
        if pool is not None:
            pool.terminate()
            pool.join()
        raise
    results = generate(grid, generator, progress, jobs, pool=pool, render=True, more=tail_case_specs)
    files = render_set(results, "all", AVR_CASES)
    write_set(files, out, "all")
    return files


def generate_subset(names: Sequence[str], out: str | Path, generator: str = "emulation") -> dict[str, bytes]:
    """Write the cases of the committed matrix named ``names`` (in matrix order) as a set of kind ``subset``."""
    wanted = set(names)
    specs = [spec for spec in case_matrix(require_logs=False) if spec.name in wanted]
    unknown = wanted - {spec.name for spec in specs}
    if unknown:
        raise UserError(f"vectors: unknown case name(s): {', '.join(sorted(unknown))}")
    files = render_set(generate(specs, generator, progress=False), "subset")
    write_set(files, out, "subset")
    return files


def check_set(directory: str | Path) -> list[str]:
    """Problems with a vector set on disk: files listed in manifest.json that are missing or whose SHA-256 differs,
    and generated files present but not listed. Empty list = consistent."""
    directory = Path(directory)
    try:
        manifest = json.loads((directory / "manifest.json").read_text())
    except (OSError, ValueError) as exc:
        return [f"{directory / 'manifest.json'}: unreadable ({exc})"]
    problems = []
    listed = manifest.get("files", {})
    for rel, digest in sorted(listed.items()):
        path = directory / rel
        if not path.is_file():
            problems.append(f"{rel}: listed in the manifest but missing")
        elif _sha256_file(path) != digest:
            problems.append(f"{rel}: SHA-256 differs from the manifest")
    for sub in ("cases", "tables"):
        for path in sorted((directory / sub).glob("*")) if (directory / sub).is_dir() else []:
            rel = f"{sub}/{path.name}"
            if rel not in listed:
                problems.append(f"{rel}: not listed in the manifest")
    return problems


# ------------------------------------------------------------------------------------------- user streams
def generate_user(program: str, input_csv: str | Path, out: str | Path, config: str | Path | None = None,
                  generator: str = "emulation") -> dict[str, bytes]:
    """A one-case vector set from a user CSV stream, built with ``config`` (JSON BuildConfig; default
    :class:`BuildConfig`) and ``program`` (must agree with the config's program), computed in memory. The CLI
    uses :func:`firmware_model.vectors_stream.generate_user`, which writes the same bytes in constant memory;
    this one is its reference for short streams."""
    if program not in PROGRAMS:
        raise UserError(f"vectors: unknown firmware {program!r}; known: {', '.join(PROGRAMS)}")
    _set_guard("user")(Path(out))
    cfg = load_config(config, {"program": program}, {"program": "--firmware"})
    stream = read_stream_csv(input_csv, cfg.baro_word_bits, cfg.k, require_acc=program in ACC_PROGRAMS)
    spec = CaseSpec(case_name(program, cfg.rounding, cfg.k, cfg.baro_word_bits, stream.name), cfg, stream)
    results = generate([spec], generator, progress=False)
    files = render_set(results, "user")
    write_set(files, out, "user")
    return files


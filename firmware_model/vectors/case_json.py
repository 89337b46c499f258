"""A case as JSON (``cases/<name>.json``): description, build config, constants, inputs and expected words."""

from __future__ import annotations

import functools
import json
import math
from fractions import Fraction
from collections.abc import Iterable, Iterator
from typing import Any

import numpy as np

from firmware_model.model.trace import EVENT_BITS, STATE_WORDS, word_names
from firmware_model.runtime.hashing import sha256_bytes
from firmware_model.vectors.cases import PROGRAM_IDS, Q_FORMATS, SCALAR_CONSTANTS, SCHEMA_VERSION
from firmware_model.vectors.compute import CaseResult


# ------------------------------------------------------------------------------------------- formatting
def _fmt_float(x: float) -> float | None:
    """A float rounded to 12 significant digits; None for non-finite. (What makes the digits the same on every
    machine is the arithmetic that computed them, :mod:`firmware_model.spec.detmath`; the rounding only keeps the
    files short.)"""
    if not math.isfinite(x):
        return None
    return float(f"{x:.12g}")


class _Exact(float):
    """A float written as it is (its shortest round-trip text), not rounded by :func:`_fmt_float`: ``m / 2^s``."""


#: Significant digits of a gain's float ``target`` in the case JSON: the design determines about 7-12 of them
#: (docs/vectors.md, "Exact fields and diagnostics"); 10 are written.
TARGET_DIGITS: int = 10


def gain_fields(m: int, s: int, target: float) -> dict[str, Any]:
    """A quantized gain's JSON fields: ``m`` and ``s`` (exact: what the firmware uses), ``value`` = m / 2^s written
    exactly, ``target`` (the float design's gain to :data:`TARGET_DIGITS` digits) and ``rel_error`` = (value -
    target) / target computed exactly from the three written fields and rounded to 6 digits, so that anyone can
    re-derive it from the file."""
    value = math.ldexp(float(m), -s)
    t = float(f"{target:.{TARGET_DIGITS}g}")
    rel = 0.0 if t == 0.0 else float((Fraction(value) - Fraction(t)) / Fraction(t))
    return {"m": int(m), "s": int(s), "value": _Exact(value), "target": t, "rel_error": float(f"{rel:.6g}")}


def _clean(obj: Any) -> Any:
    """Recursively convert numpy scalars and floats into stable JSON values."""
    t = type(obj)  # the common exact types first (a case document has ~170 values); the rest as below
    if t is str or t is int or obj is None:
        return obj
    if t is _Exact:
        return float(obj)
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
    except Exception:  # pragma: no cover  # noqa: BLE001 - not installed, or any failure to read the metadata
        return "fwemu unknown"


def case_document(res: CaseResult) -> dict[str, Any]:
    """The JSON document of one case (see schema.json)."""
    spec, consts = res.spec, res.consts
    cfg, stream = spec.cfg, spec.stream
    program = cfg.program
    names = word_names(program)
    gains = {}
    for gname, g in sorted(consts.gains.items()):
        gains[gname] = gain_fields(g.m, g.s, g.target)
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


def _alt_tag(consts: Any) -> str:
    """C identifier of a build's altitude table: ``alt_`` + the first 12 hex digits of the nodes' SHA-256."""
    return _alt_tag_of(tuple(consts.ALT_TABLE))


@functools.lru_cache(maxsize=64)
def _alt_tag_of(table: tuple[int, ...]) -> str:
    digest = sha256_bytes(",".join(str(v) for v in table).encode())[:12]
    return f"alt_{digest}"

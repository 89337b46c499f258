"""The JSON Schema of a case document, and a small validator of it (no jsonschema dependency)."""

from __future__ import annotations

import json
from typing import Any

from firmware_model.model.trace import STATE_WORDS
from firmware_model.spec.config import PROGRAMS, ROUNDINGS
from firmware_model.vectors.cases import SCALAR_CONSTANTS, SCHEMA_VERSION
from firmware_model.vectors.compute import GENERATOR_EMULATION, GENERATOR_MODEL


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
                     "sample_period", "constants", "gains", "alt_table", "q_formats", "words", "word_bytes",
                     "event_bits", "events_first_sample", "input", "int32_wrap", "cycles_68000", "sequencing", "init",
                     "adc", "acc", "expected"],
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


def validate(instance: Any, schema: dict[str, Any], where: str = "$") -> list[str]:  # noqa: C901 - one branch per JSON Schema keyword of the subset
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


def schema_bytes() -> bytes:
    """The bytes of ``schema.json``."""
    return (json.dumps(case_schema(), sort_keys=True, indent=1) + "\n").encode()

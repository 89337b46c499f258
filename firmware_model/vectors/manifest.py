"""The manifest of a vector set: every generated file with its SHA-256."""

from __future__ import annotations

import json
from collections.abc import Iterable

from firmware_model.vectors.case_json import tool_version
from firmware_model.vectors.cases import SCHEMA_VERSION


def manifest_bytes(kind: str, generators: Iterable[str], n_cases: int, hashes: dict[str, str]) -> bytes:
    """The bytes of ``manifest.json``: set kind, tool, generators, case count and {relative path: SHA-256}."""
    manifest = {"schema_version": SCHEMA_VERSION, "kind": kind, "tool": tool_version(),
                "generators": sorted(set(generators)), "n_cases": n_cases, "files": dict(sorted(hashes.items()))}
    return (json.dumps(manifest, sort_keys=True, indent=1) + "\n").encode()

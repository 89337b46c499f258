"""SHA-256 of files and bytes: the one place (vector manifests, input-file provenance, flight-case caches)."""

from __future__ import annotations

import hashlib
from pathlib import Path

#: Read size when hashing a file: a large log is hashed in bounded memory.
CHUNK: int = 1 << 20


def sha256_bytes(data: bytes) -> str:
    """Hex SHA-256 of ``data``."""
    return hashlib.sha256(data).hexdigest()


def sha256_file(path: str | Path) -> str:
    """Hex SHA-256 of a file's bytes, read in chunks of :data:`CHUNK`."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(CHUNK):
            h.update(block)
    return h.hexdigest()

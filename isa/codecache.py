"""Process-wide, content-keyed caches of decoded instructions and compiled blocks: code is compiled once per
program, not once per CPU.

Contract with :mod:`isa.cpu` (the only user):

* **Decoded instructions**: :func:`lookup_decoded` / :func:`store_decoded`, keyed by ``(address, the 10 bytes
  at the address)`` (an instruction is at most 10 bytes long, and the decoder reads nothing else; PC-relative
  operands and branch targets depend on the address). A hit is returned only when every word of the
  instruction is mapped in the asking CPU, so a fetch that would bus-error there is never skipped; a decode
  that faults is never stored.
* **Blocks**: :func:`lookup_block` / :func:`store_block`, keyed by ``(start address, memory-map key)`` with the
  block's code bytes ``[start, end)`` compared on every hit. The memory-map key (:func:`map_key`, the regions
  as ``(start, size, writable)``) is part of the key because the generated code may rely on the map (accesses
  to constant addresses known to be mapped RAM/ROM, :mod:`isa.blocks`). What is stored is what
  :func:`isa.blocks.compile_block` returned (``bind``, ``info``) and the block's entries (decoded
  instructions), so a CPU that adopts a cached block decodes and compiles nothing. The extent of a cached
  block was decided from the bytes it covers and the word after it; a CPU whose word after the block differs
  gets the cached (possibly shorter) block: every block boundary is exact (see :mod:`isa.blocks`), so results,
  counters and faults are the same.
* Memory stays bounded: each cache holds at most :data:`MAX_DECODED` / :data:`MAX_BLOCKS` entries and drops the
  least recently used beyond that (a program running off its end into zero-filled RAM compiles a new block
  every few hundred bytes; without the cap that would grow without bound).
* **Compiled block code on disk** (optional, :func:`use_disk`; the firmware harness turns it on in the build
  cache folder): :func:`isa.blocks.compile_block` looks up the marshalled code object of the block's generated
  module, its constants' recipes and its line/clock maps under :func:`block_code_key` = SHA-256 of the cache
  format, the Python version, the source of every ``isa`` module, the entries (address, instruction, handler,
  condition, length) and the map (regions, span): exactly what the generated source depends on. A hit skips
  generating and compiling (about 4 ms a block); the code is the same. Files are written to a temp name in the
  same folder and ``os.replace``d; an unreadable or foreign file is a miss (and is rewritten); an unwritable
  folder only costs the cache. ``stats["disk_hits"]`` / ``stats["disk_stores"]`` count them.
* :data:`stats` counts decodes and block compilations (misses) and hits, for tests and the benchmark;
  :func:`clear` empties both caches; ``enabled = False`` turns both off (every CPU decodes and compiles alone).
"""

from __future__ import annotations

import hashlib
import marshal
import os
import sys
import tempfile
from collections import OrderedDict
from collections.abc import Callable
from pathlib import Path
from typing import Any, BinaryIO

__all__ = ["MAX_BLOCKS", "MAX_DECODED", "clear", "enabled", "map_key", "stats", "use_disk"]

#: Most decoded instructions kept (about 300 bytes each).
MAX_DECODED = 65536
#: Most compiled blocks kept (a few to a few tens of kB each).
MAX_BLOCKS = 4096
#: Set to False to turn both caches off (for tests and the benchmark's "uncached" runs).
enabled = True
#: Counters: ``decodes`` / ``decode_hits``, ``compiles`` / ``block_hits``, ``evicted``.
stats: dict[str, int] = {"decodes": 0, "decode_hits": 0, "compiles": 0, "block_hits": 0, "evicted": 0,
                         "disk_hits": 0, "disk_stores": 0}
#: Folder of the on-disk block code cache (None: off); see :func:`use_disk`.
disk_dir: Path | None = None
_DISK_FORMAT = 1
_isa_digest: list[str] = []

_decoded: OrderedDict[tuple[int, bytes], tuple[Any, ...]] = OrderedDict()
_blocks: OrderedDict[tuple[int, tuple[tuple[int, int, bool], ...]], list[tuple[Any, ...]]] = OrderedDict()
_n_blocks = [0]


def clear() -> None:
    """Forget every cached instruction and block (the counters are kept)."""
    _decoded.clear()
    _blocks.clear()
    _n_blocks[0] = 0


def map_key(regions: Any) -> tuple[tuple[int, int, bool], ...]:
    """The memory-map part of a block key: ``(start, size, writable)`` of each region, sorted."""
    return tuple((r.start, r.size, r.writable) for r in regions)


def lookup_decoded(mem: Any, flags: Any, pc: int) -> tuple[Any, ...] | None:
    """``(instruction, length, handler, condition)`` cached for the bytes at even ``pc``, or None; only when
    every word of it is mapped here (``flags`` bit 0)."""
    if not enabled:
        return None
    key = (pc, mem[pc : pc + 10])
    hit = _decoded.get(key)
    if hit is None:
        return None
    for w in range(pc, pc + hit[1], 2):
        if not flags[w] & 1:
            return None
    _decoded.move_to_end(key)
    stats["decode_hits"] += 1
    return hit


def store_decoded(mem: Any, pc: int, value: tuple[Any, ...]) -> None:
    """Remember ``value`` = ``(instruction, length, handler, condition)`` decoded from the bytes at ``pc``."""
    stats["decodes"] += 1
    if not enabled:
        return
    _decoded[(pc, mem[pc : pc + 10])] = value
    while len(_decoded) > MAX_DECODED:
        _decoded.popitem(last=False)
        stats["evicted"] += 1


def lookup_block(mem: Any, start: int, mkey: tuple[tuple[int, int, bool], ...]) -> tuple[Any, ...] | None:
    """``(end, code, entries, bind, info, adopt)`` of a block compiled for the same bytes at ``start`` under the
    same memory map, or None."""
    if not enabled:
        return None
    key = (start, mkey)
    cands = _blocks.get(key)
    if cands is None:
        return None
    for c in cands:
        if mem[start : c[0]] == c[1]:
            _blocks.move_to_end(key)
            stats["block_hits"] += 1
            return c
    return None


def store_block(mem: Any, start: int, mkey: tuple[tuple[int, int, bool], ...], end: int, entries: list[Any],
                bind: Any, info: Any, adopt: Any = None) -> None:
    """Remember a block compiled from the bytes ``[start, end)`` under memory map ``mkey`` (``adopt``: what a CPU
    taking it over needs besides, returned last by :func:`lookup_block`)."""
    stats["compiles"] += 1
    if not enabled:
        return
    key = (start, mkey)
    _blocks.setdefault(key, []).append((end, mem[start:end], entries, bind, info, adopt))
    _blocks.move_to_end(key)
    _n_blocks[0] += 1
    while _n_blocks[0] > MAX_BLOCKS:
        _, dropped = _blocks.popitem(last=False)
        _n_blocks[0] -= len(dropped)
        stats["evicted"] += len(dropped)


# ------------------------------------------------------------------------------------------------ block code on disk
def use_disk(folder: str | os.PathLike[str] | None) -> None:
    """Keep compiled block code in ``folder`` (created mode 0700 when first written; None turns it off)."""
    global disk_dir
    disk_dir = Path(folder) if folder is not None else None


def _digest() -> str:
    if not _isa_digest:
        h = hashlib.sha256()
        for path in sorted(Path(__file__).resolve().parent.glob("*.py")):
            h.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
        _isa_digest.append(h.hexdigest())
    return _isa_digest[0]


def block_code_key(entries: list[Any], regions: Any, span: tuple[int, int]) -> str | None:
    """The disk key of one block's code (None when the disk cache is off or not enabled)."""
    if disk_dir is None or not enabled:
        return None
    text = repr((_DISK_FORMAT, sys.version_info[:3], _digest(), [tuple(e) for e in entries],
                 map_key(regions), span))
    return hashlib.sha256(text.encode()).hexdigest()


def load_block_code(key: str) -> tuple[Any, ...] | None:
    """``(code, recipes, lines, prefix, ncount, regs)`` stored under ``key``, or None."""
    if disk_dir is None:
        return None
    try:
        data = (disk_dir / key[:2] / f"{key}.marshal").read_bytes()
        value = marshal.loads(data)
    except (OSError, EOFError, ValueError, TypeError):
        return None
    if not (isinstance(value, tuple) and len(value) == 6 and type(value[0]).__name__ == "code"):
        return None
    stats["disk_hits"] += 1
    return value


def write_atomic(path: Path, write: Callable[[BinaryIO], object],
                 errors: tuple[type[BaseException], ...] = ()) -> bool:
    """Write ``path`` as ``write(fh)`` writes it: into a temp file ``.tmp-*`` in the same folder (the folder made,
    mode 0700, if missing), then ``os.replace``d over ``path``, so a reader never sees a partial file and
    concurrent writers of the same content leave one whole file. Returns False, leaving no temp file, when that
    fails with an OSError or one of ``errors`` (a cache write: the caller only loses the cache). The disk caches
    of :mod:`isa` and of ``firmware_model`` (its ``diskcache``) write through this."""
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
        fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=path.suffix, dir=path.parent)
        with os.fdopen(fd, "wb") as fh:
            write(fh)
        os.replace(tmp, path)
        tmp = None
        return True
    except (OSError, *errors):
        return False
    finally:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except OSError:
                pass


def store_block_code(key: str, value: tuple[Any, ...]) -> None:
    """Write ``value`` under ``key`` (:func:`write_atomic`; a failure only costs the cache)."""
    if disk_dir is None:
        return
    if write_atomic(disk_dir / key[:2] / f"{key}.marshal", lambda fh: fh.write(marshal.dumps(value)), (ValueError,)):
        stats["disk_stores"] += 1

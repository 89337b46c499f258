"""Assemble a firmware program (``firmware_model/firmware/asm/*.s``) with the integer constants of one build.

The constants reach the assembly ONLY as assembler symbols: :meth:`FirmwareConstants.equates` is passed as the
assembler's ``defines`` (``K``, ``ROUND``, ``S``, ``G11_M``, ``G11_S``, ...), and the sources select code with
``IF``/``ELSE``/``ENDIF`` on them. See docs/firmware-asm.md.

Usage::

    build = build_firmware(BuildConfig(program="kalman_baro", k=6))      # or build_firmware(consts)
    build.program            # isa.program.Program (listing, symbols, source map)
    build.step_address, build.variables["X1"], build.rom_bytes, build.ram_bytes, build.source_sha256
"""

from __future__ import annotations

import functools
import hashlib
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Mapping, Union

import isa
import isa.program
from firmware_model.model.trace import STATE_WORDS
from firmware_model.runtime import diskcache
from firmware_model.runtime.diskcache import cache_dir  # public here too (harness, tests)
from firmware_model.runtime.errors import UserError
from firmware_model.spec.build_constants import FirmwareConstants, build_constants
from firmware_model.spec.config import PROGRAMS, BuildConfig

#: Directory of the assembly sources (shipped as package data).
ASM_DIR: Path = Path(__file__).resolve().parent / "asm"
#: Program name -> its top-level source file in :data:`ASM_DIR`.
SOURCES: Mapping[str, str] = MappingProxyType({name: f"{name}.s" for name in PROGRAMS})


def source_path_text(program: str) -> str:
    """The top-level source of ``program`` as a path from the checkout's root, with ``/`` (what a case JSON's
    ``firmware.source`` records): derived from :data:`ASM_DIR`, so it follows the package when it moves."""
    package = Path(__file__).resolve().parents[1]           # firmware_model/, wherever it is installed
    return f"{package.name}/{(ASM_DIR / SOURCES[program]).relative_to(package).as_posix()}"

#: Memory map of docs/firmware-spec.md §2 (byte addresses on the 68000's 24-bit bus).
ROM_START, ROM_SIZE = 0x000000, 0x4000
RAM_START, RAM_SIZE = 0x004000, 0x4000
STACK_TOP = RAM_START + RAM_SIZE
IO_START, IO_SIZE = 0xFFF000, 8
BARO_ADC, ACCEL_ADC = 0xFFF000, 0xFFF002
#: The pascal kind's barometer register (signed 32-bit long; docs/firmware-spec.md §2).
BARO_PA = 0xFFF004

_INCLUDE_RE = re.compile(r"""^[ \t]*(?:[A-Za-z_.][\w.]*:?[ \t]+)?include[ \t]+["']?([^"'\s;]+)""",
                         re.IGNORECASE | re.MULTILINE)


@dataclass(frozen=True)
class FirmwareBuild:
    """One assembled firmware program.

    * ``program_name``: one of :data:`firmware_model.spec.config.PROGRAMS`; ``consts`` the constants it was built with.
    * ``program``: the :class:`isa.program.Program` (segments, symbols, listing with cycles, source map).
    * ``sources``: ``(file name, SHA-256 hex)`` of every assembly file used (top-level file first, then its
      includes in the order first included); ``source_sha256``: SHA-256 over those files' names and texts.
    * ``init_address``, ``step_address``: entry points (byte addresses).
    * ``variables``: state word name -> ``(address, size in bytes)`` in the output order of
      :data:`firmware_model.model.trace.STATE_WORDS` (sizes checked against the symbol table).
    * ``rom_image``: the bytes of ROM from ``ROM_START`` up to the end of the code/constants;
      ``rom_bytes = len(rom_image)`` (vectors + code + constants); ``ram_bytes``: bytes of RAM variables (bss).
    """

    program_name: str
    consts: FirmwareConstants
    program: object  # isa.program.Program (kept untyped so that importing this module does not import isa)
    sources: tuple[tuple[str, str], ...]
    source_sha256: str
    init_address: int
    step_address: int
    variables: Mapping[str, tuple[int, int]]
    rom_image: bytes
    ram_bytes: int

    @property
    def rom_bytes(self) -> int:
        """ROM bytes used: vectors, code and constants (the image loaded at ``ROM_START``)."""
        return len(self.rom_image)

    @property
    def equates(self) -> dict[str, int]:
        """The assembler symbols the build was assembled with (``consts.equates()``)."""
        return self.consts.equates()


def source_files(program: str) -> list[Path]:
    """The assembly files of ``program``: its top-level source, then every file it INCLUDEs (recursively, in first
    inclusion order). Raises :class:`UserError` for an unknown program or a missing file."""
    if program not in SOURCES:
        raise UserError(f"unknown firmware program {program!r}; known: {', '.join(SOURCES)}")
    seen: list[Path] = []

    def visit(path: Path, chain: tuple[str, ...]) -> None:
        if path in seen:
            return
        if not path.is_file():
            raise UserError(f"{chain[-1] if chain else 'build'}: assembly source {path} not found")
        seen.append(path)
        for name in _INCLUDE_RE.findall(path.read_text()):
            visit(ASM_DIR / name, chain + (str(path),))

    visit(ASM_DIR / SOURCES[program], ())
    return seen


def _hash_sources(paths: list[Path]) -> tuple[tuple[tuple[str, str], ...], str]:
    total = hashlib.sha256()
    per_file = []
    for path in paths:
        data = path.read_bytes()
        per_file.append((path.name, hashlib.sha256(data).hexdigest()))
        total.update(path.name.encode() + b"\0" + str(len(data)).encode() + b"\0" + data)
    return tuple(per_file), total.hexdigest()


def source_sha256(program: str) -> str:
    """SHA-256 over every assembly file of ``program`` (its top-level source and everything it INCLUDEs), as
    :attr:`FirmwareBuild.source_sha256` reports it, without assembling. Raises :class:`UserError` for an unknown
    program or a missing file."""
    return _hash_sources(source_files(program))[1]


#: Bumped when the cached form changes.
_CACHE_FORMAT = 1


@functools.lru_cache(maxsize=1)
def _assembler_digest() -> str:
    """SHA-256 over the source of the ``isa`` package (assembler, encoder, table, timing, ...): a cached build
    made by another version of the assembler is never used."""

    h = hashlib.sha256()
    for path in sorted(Path(isa.__file__).resolve().parent.glob("*.py")):
        h.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()


def build_key(program: str, equates: tuple[tuple[str, int], ...], digest: str, data: str = "") -> str:
    """The content key of one build: program, equates, source digest, where the sources are (the listing and the
    source map name the files), the assembler's digest, the cache format and the Python version."""
    text = repr((_CACHE_FORMAT, sys.version_info[:2], program, equates, digest, str(ASM_DIR), _assembler_digest(),
                 hashlib.sha256(data.encode()).hexdigest()))
    return hashlib.sha256(text.encode()).hexdigest()


def _load_cached(path: Path) -> object | None:
    return diskcache.load(path, lambda obj: isinstance(obj, isa.program.Program))


def _store_cached(path: Path, prog: object) -> None:
    """Write ``prog`` to ``path`` atomically (:func:`firmware_model.runtime.diskcache.store`)."""
    diskcache.store(path, prog)


#: Counters of the build cache: ``assembled`` (assembler runs), ``disk_hits``.
cache_stats: dict[str, int] = {"assembled": 0, "disk_hits": 0}


@functools.lru_cache(maxsize=128)
def _assemble_cached(program: str, equates: tuple[tuple[str, int], ...], stamp: tuple[tuple[str, int], ...],
                     data: str = "") -> tuple[object, tuple[tuple[str, str], ...], str]:
    """Assemble ``program`` with ``equates`` (``stamp`` = source mtimes, so edited sources are rebuilt in this
    process) and the build's ROM data text ``data`` appended (the altitude table,
    :meth:`FirmwareConstants.data_source`), or load the same build from the disk cache (keyed by content:
    :func:`build_key`, which includes ``data``)."""

    paths = source_files(program)
    sources, digest = _hash_sources(paths)
    folder = cache_dir()
    path = folder / "builds" / f"{build_key(program, equates, digest, data)}.pickle" if folder is not None else None
    prog = _load_cached(path) if path is not None else None
    if prog is not None:
        cache_stats["disk_hits"] += 1
        return prog, sources, digest
    top = paths[0]
    prog = isa.assemble(top.read_text() + data, filename=str(top), origin=ROM_START, include_paths=[str(ASM_DIR)],
                        defines=dict(equates))
    cache_stats["assembled"] += 1
    if path is not None:
        _store_cached(path, prog)
    return prog, sources, digest


def _symbol(prog: object, name: str, program: str) -> object:
    try:
        return prog.symbol(name)  # type: ignore[attr-defined]  # isa's Program/CPU are typed as object here (isa stays an optional import)
    except KeyError:
        raise UserError(f"firmware program {program!r} does not define the symbol {name!r}") from None


def build_firmware(cfg_or_consts: Union[BuildConfig, FirmwareConstants]) -> FirmwareBuild:
    """Assemble the firmware program of ``cfg_or_consts`` (a :class:`BuildConfig`, whose constants are derived with
    :func:`firmware_model.spec.build_constants.build_constants`, or ready :class:`FirmwareConstants`).

    Builds are cached in this process on (program, equates, source file mtimes) and on disk by content
    (:func:`cache_dir`, :func:`build_key`: program, equates, the sources, the assembler's own source). Raises
    :class:`UserError` for a bad config or constants, :class:`isa.errors.AssemblyError` if the sources do not
    assemble (naming file and line)."""
    if isinstance(cfg_or_consts, BuildConfig):
        consts = build_constants(cfg_or_consts)
    elif isinstance(cfg_or_consts, FirmwareConstants):
        consts = cfg_or_consts
    else:
        raise UserError(f"build_firmware needs a BuildConfig or FirmwareConstants, got {type(cfg_or_consts).__name__}")
    name = consts.program
    equates = tuple(sorted(consts.equates().items()))
    stamp = tuple((str(p), p.stat().st_mtime_ns) for p in source_files(name))
    prog, sources, digest = _assemble_cached(name, equates, stamp, consts.data_source())
    return _describe(name, consts, prog, sources, digest)


def _describe(name: str, consts: FirmwareConstants, prog: object, sources: tuple[tuple[str, str], ...],
              digest: str) -> FirmwareBuild:
    init = _symbol(prog, "init", name)
    step = _symbol(prog, "step", name)
    variables: dict[str, tuple[int, int]] = {}
    for word, size in STATE_WORDS[name]:
        sym = _symbol(prog, word, name)
        address = int(sym.address)  # type: ignore[attr-defined]  # isa's Program/CPU are typed as object here (isa stays an optional import)
        if not (RAM_START <= address and address + size <= STACK_TOP) or address % 2:
            raise UserError(f"firmware program {name!r}: state word {word} at ${address:06X} is not an even RAM "
                            f"address in ${RAM_START:06X}-${STACK_TOP - 1:06X}")
        if sym.size and sym.size < size:  # type: ignore[attr-defined]  # isa's Program/CPU are typed as object here (isa stays an optional import)
            raise UserError(f"firmware program {name!r}: state word {word} has {sym.size} bytes, needs {size}")
        variables[word] = (address, size)
    rom = bytearray()
    ram_end = RAM_START
    for seg in prog.segments:  # type: ignore[attr-defined]  # isa's Program/CPU are typed as object here (isa stays an optional import)
        end = seg.origin + len(seg.data)
        if seg.bss or RAM_START <= seg.origin < STACK_TOP:
            if not (RAM_START <= seg.origin and end <= STACK_TOP):
                raise UserError(f"firmware program {name!r}: segment {seg.name} ${seg.origin:06X}-${end:06X} "
                                "leaves RAM")
            ram_end = max(ram_end, end)
            continue
        if not (ROM_START <= seg.origin and end <= ROM_START + ROM_SIZE):
            raise UserError(f"firmware program {name!r}: segment {seg.name} ${seg.origin:06X}-${end:06X} leaves ROM")
        if len(rom) < end - ROM_START:
            rom.extend(bytes(end - ROM_START - len(rom)))
        rom[seg.origin - ROM_START:end - ROM_START] = seg.data
    return FirmwareBuild(
        program_name=name,
        consts=consts,
        program=prog,
        sources=sources,
        source_sha256=digest,
        init_address=int(init.address),  # type: ignore[attr-defined]  # isa's Program/CPU are typed as object here (isa stays an optional import)
        step_address=int(step.address),  # type: ignore[attr-defined]  # isa's Program/CPU are typed as object here (isa stays an optional import)
        variables=MappingProxyType(variables),
        rom_image=bytes(rom),
        ram_bytes=ram_end - RAM_START,
    )


def clear_cache() -> None:
    """Forget every cached assembly (for tools that edit the sources in place)."""
    _assemble_cached.cache_clear()


__all__ = ["ASM_DIR", "SOURCES", "source_path_text", "FirmwareBuild", "build_firmware", "source_files", "clear_cache",
           "cache_dir", "build_key",
           "ROM_START", "ROM_SIZE", "RAM_START", "RAM_SIZE", "STACK_TOP", "IO_START", "IO_SIZE", "BARO_ADC",
           "ACCEL_ADC", "BARO_PA", "write_inputs"]


def write_inputs(cpu: object, pascal: bool, baro: int, acc: int) -> None:
    """Write one sample into the input registers of docs/firmware-spec.md §2: ``baro`` into ``BARO_ADC`` (16-bit
    word) or, for a pascal build, into ``BARO_PA`` (32-bit long, two's complement); ``acc`` into ``ACCEL_ADC``."""
    if pascal:
        cpu.write(BARO_PA, int(baro) & 0xFFFFFFFF, 4)  # type: ignore[attr-defined]  # isa's Program/CPU are typed as object here (isa stays an optional import)
    else:
        cpu.write(BARO_ADC, int(baro), 2)  # type: ignore[attr-defined]  # isa's Program/CPU are typed as object here (isa stays an optional import)
    cpu.write(ACCEL_ADC, int(acc) & 0xFFFF, 2)  # type: ignore[attr-defined]  # isa's Program/CPU are typed as object here (isa stays an optional import)

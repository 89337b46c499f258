"""Build a port into a shared library with the host C compiler and run it in a child process.

:func:`build_port` compiles the team's sources (or links their prebuilt library) together with the glue of
:mod:`firmware_model.vectors.portcheck.adapter`, with strict flags (:data:`STRICT_FLAGS`: C99, every warning an error);
:class:`Port` runs one whole stream per call (init, then step on every sample, all state words back in one
array), so the cost per sample is the port's own, in a child process (:mod:`.isolate`): a crashing or hanging
port is a finding, not the end of check-port.
"""

from __future__ import annotations

import os
import shlex
import shutil
import subprocess
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from firmware_model.model.trace import word_names
from firmware_model.runtime.errors import UserError
from firmware_model.vectors.cases import PROGRAM_IDS
from firmware_model.vectors.portcheck.adapter import (
    GLUE_ABI,
    Adapter,
    api_adapter,
    const_slots,
    consts_vector,
    glue_source,
)
from firmware_model.vectors.portcheck.isolate import DRIVER_C, Child, PortCrash

#: Flags every port is compiled with (then ``--cflags``): the golden-vector harness's (vectors/c/Makefile).
STRICT_FLAGS: tuple[str, ...] = ("-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-O2")
#: Compile timeout (s).
COMPILE_TIMEOUT: float = 120.0


def host_compiler() -> str:
    """``$CC`` if set, else ``cc`` / ``gcc`` / ``clang`` from the PATH (UserError when there is none)."""
    cc = os.environ.get("CC", "").strip()
    if cc:
        return cc
    for name in ("cc", "gcc", "clang"):
        if shutil.which(name):
            return name
    raise UserError("check-port: no C compiler found (set CC, or install gcc or clang)")


def _first_error(text: str) -> str:
    for line in text.splitlines():
        if "error" in line:
            return line.strip()
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    return lines[0] if lines else "no output"


def _compile(cmd: list[str], what: str) -> None:
    try:
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=COMPILE_TIMEOUT)
    except FileNotFoundError:
        raise UserError(f"check-port: compiler {cmd[0]!r} not found") from None
    except subprocess.TimeoutExpired:
        raise UserError(f"check-port: compiling {what} took more than {COMPILE_TIMEOUT:.0f} s") from None
    if r.returncode != 0:
        raise UserError(f"check-port: compiling {what} failed: {_first_error(r.stderr + r.stdout)}")


@dataclass
class Port:
    """A built port: ``run(program, consts, adc, acc)`` gives the state words after init and after each step. The
    port runs in a child process (:class:`~firmware_model.vectors.portcheck.isolate.Child`): a crash or a hang
    raises :class:`~firmware_model.vectors.portcheck.isolate.PortCrash` here; :meth:`close` ends the child."""

    child: Child
    adapter: Adapter
    path: Path
    workdir: Path | None = None
    description: str = ""
    _names: dict[str, tuple[str, ...]] = field(default_factory=dict)

    def port_word_names(self, program: str) -> tuple[str, ...]:
        """The port's own word list for ``program`` (fw.h: ``fw_word_name``; an adapter: the model's words it
        maps)."""
        if program not in self._names:
            pid = PROGRAM_IDS[program]
            try:
                n = self.child.n_words(pid)
                if not 0 <= n <= 256:
                    raise UserError(f"check-port: the port reports {n} state words for {program}")
                names = [self.child.word_name(pid, i) for i in range(n)]
            except PortCrash as exc:
                raise UserError(f"check-port: the port's process ended while listing its state words: {exc}") \
                    from None
            self._names[program] = tuple(names)
        return self._names[program]

    def check_words(self, program: str) -> None:
        """UserError unless the port has exactly the model's words for ``program``, in the model's order."""
        self.adapter.check_program(program)
        model = word_names(program)
        port = self.port_word_names(program)
        if port != model:
            raise UserError(f"check-port: the port's state words for {program} are {' '.join(port) or '(none)'}; "
                            f"the model's are {' '.join(model)} (docs/firmware-spec.md section 7)")

    def run(self, program: str, consts: Any, adc: np.ndarray, acc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(init_words (nw,), words (n, nw))`` as int64 (``.w`` words zero-extended, ``.l`` words signed).
        Raises :class:`PortCrash` when the port crashes, exits or hangs on this stream."""
        nw = len(word_names(program))
        n = int(len(adc))
        vec = np.asarray(consts_vector(consts), dtype=np.int32)
        alt = np.asarray(consts.ALT_TABLE if consts.ALT_TABLE else [0], dtype=np.int32)
        baro = np.asarray(adc, dtype=np.int64).astype(np.int32)
        acc16 = np.asarray(acc, dtype=np.int64).astype(np.int16).astype(np.int32)
        k, out = self.child.run_stream(PROGRAM_IDS[program], vec, alt, baro, acc16, nw)
        if k < 0:
            raise UserError(f"check-port: the port does not run program {program}")
        words = out.reshape(n + 1, nw)
        return words[0], words[1:]

    def close(self) -> None:
        """End the port's child process."""
        self.child.close()


def _load(path: Path, adapter: Adapter, workdir: Path, description: str, limits: dict[str, Any]) -> Port:
    child = Child(workdir / "fwpc_driver", workdir, **limits)
    try:
        abi = child.abi()
    except PortCrash as exc:
        child.close()
        raise UserError(f"check-port: the port's process ended before its first stream: {exc}") from None
    if abi != GLUE_ABI:
        child.close()
        raise UserError(f"check-port: {path}: glue ABI {abi} != {GLUE_ABI}")
    return Port(child=child, adapter=adapter, path=path, workdir=workdir, description=description)


def build_port(sources: list[str | Path] = (), lib: str | Path | None = None, adapter: Adapter | None = None,
               include_dirs: list[str | Path] = (), cflags: str = "", workdir: str | Path | None = None,
               **limits: Any) -> Port:
    """Compile ``sources`` (C files; their folders are include paths) with the glue into one shared library, or
    (``lib``) compile the glue alone and link it against the team's shared library. ``adapter``: default the
    fw.h API (:func:`~firmware_model.vectors.portcheck.adapter.api_adapter`). Build problems are one-line
    :class:`UserError`\\ s (the compiler's first error line). The library is linked into a small driver program
    that runs it in a child process (``limits``: :class:`~firmware_model.vectors.portcheck.isolate.Child`'s
    ``memory_mb``, ``timeout_s``, ``output_bytes``)."""
    adapter = adapter or api_adapter()
    srcs = [Path(s) for s in sources]
    if bool(srcs) == (lib is not None):
        raise UserError("check-port: give the port's C sources or --lib LIB.so (one of them)")
    for s in srcs:
        if not s.is_file():
            raise UserError(f"check-port: {s}: no such C source file")
        if s.suffix not in (".c", ".C"):
            raise UserError(f"check-port: {s}: not a .c file")
    if lib is not None and not Path(lib).is_file():
        raise UserError(f"check-port: {lib}: no such shared library")
    try:
        extra = shlex.split(cflags)
    except ValueError as exc:
        raise UserError(f"check-port: --cflags {cflags!r}: {exc}") from None
    cc = host_compiler()
    wd = Path(workdir) if workdir is not None else Path(tempfile.mkdtemp(prefix="fwemu-port-"))
    wd.mkdir(parents=True, exist_ok=True)
    glue = wd / "fwpc_glue.c"
    glue.write_text(glue_source(adapter))
    incs: list[str] = []
    for d in [*(s.resolve().parent for s in srcs), *(Path(d).resolve() for d in include_dirs)]:
        if f"-I{d}" not in incs:
            incs.append(f"-I{d}")
    out = wd / "port.so"
    if srcs:
        cmd = [cc, *STRICT_FLAGS, *extra, "-fPIC", "-shared", *incs, *(str(s) for s in srcs), str(glue), "-o",
               str(out)]
        what = " ".join(s.name for s in srcs)
    else:
        libp = Path(lib).resolve()  # type: ignore[arg-type]  # lib is set whenever srcs is not (the branch above)
        incs.append(f"-I{libp.parent}")
        cmd = [cc, *STRICT_FLAGS, *extra, "-fPIC", "-shared", *incs, str(glue), "-o", str(out), str(libp),
               f"-Wl,-rpath,{libp.parent}"]
        what = f"the glue for {libp.name}"
    driver = wd / "fwpc_driver.c"
    driver.write_text(DRIVER_C)
    try:
        _compile(cmd, what)
        _compile([cc, "-std=c99", "-O2", str(driver), "-o", str(wd / "fwpc_driver"), str(out),
                  f"-Wl,-rpath,{wd.resolve()}"], "the check-port driver")
        return _load(out, adapter, wd, what, limits)
    except BaseException:
        if workdir is None:  # our own temporary folder: nothing in it is worth keeping
            shutil.rmtree(wd, ignore_errors=True)
        raise


__all__ = ["STRICT_FLAGS", "Port", "build_port", "host_compiler", "const_slots"]

"""Run an assembled firmware program on the emulated 68000 (:mod:`isa`), sample by sample.

Sequencing per docs/firmware-spec.md §7: write sample 0 into the input registers and ``JSR init``; then for each
sample i write ``adc[i]``/``acc[i]`` into ``BARO_ADC``/``ACCEL_ADC`` and ``JSR step``; after each call read every
state word through the symbol table. Memory map per §2: ROM ``$000000-$003FFF`` mapped read-only, RAM
``$004000-$007FFF``, the input registers at ``$FFF000``/``$FFF002`` (and the pascal kind's long at ``$FFF004``);
everything else unmapped (a bus error).

Usage::

    trace = run_firmware(build_firmware(cfg), adc, acc)
    trace.words[i]          # state words after step i (docs/firmware-spec.md §7 order)
    trace.cycles[i]         # 68000 clocks of step i, from its first instruction through its RTS
    trace.stack_bytes, trace.ram_written
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

import isa
from firmware_model.firmware.assemble import (
    ACCEL_ADC,
    BARO_ADC,
    BARO_PA,
    IO_SIZE,
    IO_START,
    RAM_SIZE,
    RAM_START,
    ROM_SIZE,
    ROM_START,
    STACK_TOP,
    FirmwareBuild,
    cache_dir,
    write_inputs,
)
from firmware_model.model.streams import as_input_streams
from firmware_model.model.trace import Trace
from firmware_model.runtime.errors import UserError
from isa import codecache
from isa.errors import CPUFault

#: Default cycle limit of one ``init``/``step`` call: far above any real step (a few thousand clocks), low enough
#: that a runaway loop fails fast.
DEFAULT_MAX_CYCLES_PER_CALL: int = 200_000


@dataclass
class FirmwareTrace(Trace):
    """A :class:`~firmware_model.model.trace.Trace` from the emulated CPU, with the resource counters:

    * ``stack_bytes``: peak stack use in bytes (``STACK_TOP - min SP`` over all calls, including the 4-byte return
      address the call pushes), the maximum over streams.
    * ``ram_written``: distinct RAM bytes written (variables and stack) over the run, the maximum over streams.
    """

    stack_bytes: int = 0
    ram_written: int = 0


class _Machine:
    """One emulated board: CPU with the spec's memory map and the program loaded."""

    def __init__(self, build: FirmwareBuild) -> None:
        self.cpu = firmware_cpu(build)


def firmware_cpu(build: FirmwareBuild) -> Any:
    """A CPU with the firmware memory map of docs/firmware-spec.md §2 (ROM, RAM, input registers; nothing else
    mapped), ``build``'s program loaded and the stack pointer at the top of RAM."""

    folder = cache_dir()  # compiled block code is kept beside the assembled builds (isa.codecache.use_disk)
    codecache.use_disk(folder / "blocks" if folder is not None else None)
    cpu = isa.CPU(mapped=False)
    cpu.map(ROM_START, ROM_SIZE, "rom", writable=False)
    cpu.map(RAM_START, RAM_SIZE, "ram", writable=True)
    cpu.map(IO_START, IO_SIZE, "io", writable=True)
    cpu.load(build.program)
    cpu.a[7] = STACK_TOP
    return cpu


def _fault(build: FirmwareBuild, exc: Exception, where: str) -> Exception:
    """Re-raise a CPU fault with the sample named (same exception class, so callers can catch e.g. BusError)."""

    if isinstance(exc, CPUFault):
        new = type(exc).__new__(type(exc))
        Exception.__init__(new, f"firmware {build.program_name}: {where}: {exc}")
        new.pc, new.instruction, new.source = exc.pc, exc.instruction, exc.source
        return new
    return exc


def run_firmware(build: FirmwareBuild, adc: Any, acc: Any = None, *,
                 max_cycles_per_call: int = DEFAULT_MAX_CYCLES_PER_CALL,
                 progress: Callable[[int, int], None] | None = None) -> FirmwareTrace:
    """Run ``build`` on the emulated 68000 over one stream (``adc`` shape ``(n,)``) or many (``(streams, n)``).

    ``adc``: barometer ADC samples, integers 0..65535 (raw counts, written to ``BARO_ADC``; a pascal build: signed
    32-bit pascal words, written as a long to ``BARO_PA``); ``acc``:
    accelerometer samples, integers -32768..32767 (counts, written to ``ACCEL_ADC``), same shape, ``None`` = all
    zero. Returns a :class:`FirmwareTrace`: ``words`` (int64, ``.l`` words signed, ``.w`` words unsigned) after
    every ``step``, ``init_words`` after ``init``, ``cycles`` per step and ``init_cycles`` (68000 clocks from the
    routine's first instruction through its RTS), ``stack_bytes`` and ``ram_written``.

    Raises :class:`UserError` for bad input values (naming stream/sample and value) and the CPU's own
    :class:`isa.errors.CPUFault` subclass, with the sample index (or ``init``) prepended, if the firmware faults.
    ``progress(done, total)``, if given, is called every 4,096 samples of each stream and at its end.
    """
    if not isinstance(build, FirmwareBuild):
        raise UserError(f"run_firmware needs a FirmwareBuild (from build_firmware), got {type(build).__name__}")
    adc2, acc2 = as_input_streams(adc, acc, bool(build.consts.PASCAL))
    if not isinstance(max_cycles_per_call, int) or max_cycles_per_call <= 0:
        raise UserError(f"max_cycles_per_call={max_cycles_per_call!r} must be a positive integer")
    n_streams, n = adc2.shape
    names = tuple(build.variables)
    addr_size = [build.variables[w] for w in names]
    words = np.zeros((n_streams, n, len(names)), dtype=np.int64)
    init_words = np.zeros((n_streams, len(names)), dtype=np.int64)
    cycles = np.zeros((n_streams, n), dtype=np.int64)
    init_cycles = np.zeros(n_streams, dtype=np.int64)
    stack = written = 0
    for s in range(n_streams):
        init_cycles[s], stack_s, written_s = _run_stream(build, adc2[s], acc2[s] & 0xFFFF, addr_size, words[s],
                                                        init_words[s], cycles[s], max_cycles_per_call,
                                                        "" if n_streams == 1 else f"stream {s} ", progress)
        stack, written = max(stack, stack_s), max(written, written_s)
    if np.ndim(adc) == 1:
        return FirmwareTrace(build.program_name, names, words[0], init_words[0], cycles[0], int(init_cycles[0]),
                             stack_bytes=stack, ram_written=written)
    return FirmwareTrace(build.program_name, names, words, init_words, cycles, init_cycles,
                         stack_bytes=stack, ram_written=written)


def _run_stream(build: FirmwareBuild, adc: np.ndarray, acc: np.ndarray, addr_size: list[tuple[int, int]],
                words: np.ndarray, init_words: np.ndarray, cycles: np.ndarray, max_cycles: int, label: str,
                progress: Callable[[int, int], None] | None = None) -> tuple[int, int, int]:
    """Run one stream into the preallocated ``words``/``init_words``/``cycles``; return (init clocks, stack bytes,
    RAM bytes written)."""
    machine = _Machine(build)
    cpu = machine.cpu
    write, read_bytes, call = cpu.write, cpu.read_bytes, cpu.call
    # The lean path (docs/isa-internals.md, "Harness"): the two input words go straight into the CPU's memory
    # with one struct.pack_into while their flag bytes say they hold no decoded code (a host write there would
    # have to drop compiled code: then cpu.write does it); the state words are unpacked straight from memory
    # after one checked host read (mapping never shrinks, reading changes nothing).
    mem, flags32 = cpu.memory.mem, cpu.memory.flags32
    pascal = bool(build.consts.PASCAL)
    lean = ACCEL_ADC == BARO_ADC + 2 and BARO_PA == BARO_ADC + 4 and not BARO_ADC & 3
    io_word = BARO_ADC >> 2
    pack_io = struct.Struct(">HH").pack_into
    pack_io_pa = struct.Struct(">HHi").pack_into       # BARO_ADC (0), ACCEL_ADC, BARO_PA
    init_addr, step_addr = build.init_address, build.step_address
    step = cpu.caller(step_addr, max_cycles)  # call(step_addr, max_cycles) with its set-up done once
    adc_l = adc.tolist()
    acc_l = acc.tolist()
    # All state words are read with ONE host read of the RAM span that holds them, unpacked by a struct format
    # (big-endian; 'i' for the signed .l words, 'H' for the unsigned .w words, 'x' padding between them).
    base = min(a for a, _ in addr_size)
    order = sorted(range(len(addr_size)), key=lambda j: addr_size[j][0])
    fmt, pos = ">", base
    for j in order:
        address, size = addr_size[j]
        fmt += "x" * (address - pos) + ("i" if size == 4 else "H")
        pos = address + size
    span = pos - base
    unpack = struct.Struct(fmt).unpack
    unpack_from = struct.Struct(fmt).unpack_from
    if order == list(range(len(addr_size))):
        def read_state() -> tuple[int, ...]:
            return unpack(read_bytes(base, span))

        read_bytes(base, span)  # the state span is mapped (else the host read raises here, naming the address)

        def read_state_lean() -> tuple[int, ...]:
            return unpack_from(mem, base)
    else:  # pragma: no cover - the sources declare the words in output order
        inverse = [order.index(j) for j in range(len(addr_size))]

        def read_state() -> tuple[int, ...]:
            raw = unpack(read_bytes(base, span))
            return tuple(raw[i] for i in inverse)

        read_state_lean = read_state

    i = -1  # the sample being run (-1: init); named in a fault's message
    try:
        write_inputs(cpu, pascal, adc_l[0], acc_l[0])
        init_clocks = call(init_addr, max_cycles=max_cycles)
        init_words[:] = read_state()
        out = [None] * len(adc_l)
        cyc = [0] * len(adc_l)
        first = 0  # the first sample the general loop runs
        fast = lean and not pascal and progress is None and read_state_lean is not read_state
        if fast:
            # The common case as one tight loop (same steps as the general loop below, fewer look-ups): inputs
            # packed straight into memory while the two input words hold no decoded code, one call, and the
            # state span kept as bytes (decoded for all samples at once below).
            end = base + span
            for i in range(len(adc_l)):
                if flags32[io_word] & 0x08080808:
                    write(BARO_ADC, adc_l[i], 2)
                    write(ACCEL_ADC, acc_l[i], 2)
                else:
                    pack_io(mem, BARO_ADC, adc_l[i], acc_l[i])
                cyc[i] = step()
                out[i] = mem[base:end]
            first = len(adc_l)
        for i in range(first, len(adc_l)):
            if pascal:
                if lean and not (flags32[io_word] | flags32[io_word + 1]) & 0x08080808:
                    pack_io_pa(mem, BARO_ADC, 0, acc_l[i], adc_l[i])
                else:
                    write_inputs(cpu, True, adc_l[i], acc_l[i])
            elif lean and not flags32[io_word] & 0x08080808:
                pack_io(mem, BARO_ADC, adc_l[i], acc_l[i])
            else:
                write(BARO_ADC, adc_l[i], 2)
                write(ACCEL_ADC, acc_l[i], 2)
            cyc[i] = step()
            out[i] = read_state_lean()
            if progress is not None and not i & 4095:
                progress(i, len(adc_l))
        if progress is not None:
            progress(len(adc_l), len(adc_l))
    except Exception as exc:
        raise _fault(build, exc, f"{label}init" if i < 0 else f"{label}sample {i}") from exc
    if fast:  # the state spans, big-endian: '>i4' for the signed .l words, '>u2' for the unsigned .w words
        spans = np.frombuffer(b"".join(out), dtype=np.dtype({
            "names": [f"w{j}" for j in range(len(addr_size))],
            "formats": [">i4" if size == 4 else ">u2" for _, size in addr_size],
            "offsets": [address - base for address, _ in addr_size], "itemsize": span}))
        for j in range(len(addr_size)):
            words[:, j] = spans[f"w{j}"]
    else:
        words[:] = np.array(out, dtype=np.int64).reshape(words.shape)
    cycles[:] = cyc
    stack = STACK_TOP - int(cpu.min_sp)
    written = cpu.ram_written
    written = int(written if isinstance(written, int) else len(written))
    return int(init_clocks), stack, written


__all__ = ["FirmwareTrace", "run_firmware", "DEFAULT_MAX_CYCLES_PER_CALL"]

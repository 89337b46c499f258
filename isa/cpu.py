"""The MC68000 interpreter: exact results, CCR flags and clock counts for the :mod:`isa` subset.

Modules (each with its contract in its docstring): :mod:`isa.memory` (the address space, program accessors,
host access), :mod:`isa.semantics` (masks, flags, condition table, ALU/shift kernels, the internal fault/stop
signals), :mod:`isa.closures` (one closure per instruction), :mod:`isa.blocks` (the block compiler, with
:mod:`isa.block_plan` and :mod:`isa.block_codegen`), and this module: the CPU itself (registers, the
decode/closure/block caches and their invalidation, the run loop, counters, ``step``/``run``/``call``/``execute``,
and turning internal faults into :class:`isa.errors.CPUFault` with PC, disassembly and source line).

Model
-----
* 24-bit address space (16 MiB), big-endian, mapped in regions (:meth:`CPU.map`). ``CPU()`` maps all 16 MiB as
  RAM; ``CPU(mapped=False)`` maps nothing. Region starts and sizes must be even, so a word never straddles two
  regions. Accesses are not wrapped at the top of the address space: one that runs past ``$FFFFFF`` is a bus error.
* Registers: ``cpu.d[i]``, ``cpu.a[i]`` (``a[7]`` is the one stack pointer; the CPU stays in supervisor mode),
  ``cpu.pc``, ``cpu.sr`` (16 bits, kept as written; CCR = bits 4..0 = X N Z V C). SR is ``$2700`` at reset.
* Faults raise :class:`isa.errors.CPUFault` subclasses naming the PC, the disassembly and ``file:line`` when the
  code came from a :class:`~isa.program.Program`; they never vector. State changes the faulting instruction made
  before the fault (e.g. a postincrement) are kept. ``TRAP #n`` stops :meth:`CPU.run` with the PC after the TRAP.
* Speed: each instruction address is decoded once (:func:`isa.decoder.decode`) and compiled to a closure that
  performs the instruction and returns ``next_pc | clocks << 32`` (used by :meth:`CPU.step`, by :meth:`CPU.run`
  when ``profiling`` is on or ``block_compile`` is off, and for single instructions near a limit). :meth:`CPU.run`
  otherwise runs *blocks*: the instructions from an address up to the first JMP/JSR/BSR/RTS or BRA (decoding goes
  on past one while an earlier forward branch of the block still targets code beyond it; at most
  :data:`BLOCK_MAX`) are generated as the source of ONE Python function (registers in locals, operands/addresses/
  clock constants as literals, CCR flags computed only where a later instruction, a block exit or a possible
  fault can observe them), compiled once and cached by start address. Control flow inside a block: a Bcc forward
  to a later instruction of the same (nested) region becomes an ``if`` (with ``else`` when the skipped code ends
  in a BRA forward: if/else), a BRA forward skips code, and a Bcc/DBcc/BRA back to the earliest instruction a
  backward branch of the block reaches (the loop head) becomes the ``continue`` of a ``while`` loop around the
  instructions from the head on; any other branch leaves the block. Constant clocks and instruction counts are
  folded per path; the locals ``c`` (clocks) and ``ni`` (instructions) carry what differs between paths and
  loop passes. A block starts only when the remaining instruction and cycle budget covers one pass (each
  instruction at most once, worst-case clocks) and ``until_pc`` is not inside it; the loop goes round again only
  while the budget still covers another pass from the head and ``until_pc`` is not the head; otherwise the block
  returns and the run loop single-steps, so limits, ``until_pc`` and counters are exactly those of the
  per-instruction path. A fault inside a block is unwound from the traceback: the block's register locals are
  written back and the faulting instruction's PC, the instructions and clocks before it (path constants + ``ni``
  / ``c``) are recovered, so registers, memory, counters and the fault are exactly those of the per-instruction
  path (tests/isa/test_blocks.py checks both paths against each other and against m68000-python). Writes to
  bytes that hold decoded code invalidate the affected closures and blocks, and a running block that wrote to
  code leaves right after that instruction (self-modifying code works, also inside a loop).

Not modelled (documented simplifications): prefetch, the extra bus read of MOVEM memory-to-register, the
read-before-write of CLR/Scc to memory, exception processing, user mode.

Counters: ``instructions``, ``cycles`` (68000 clocks), ``profile`` (address -> ``[count, clocks]`` when
``profiling`` is true), ``min_sp`` (lowest A7 value seen after an instruction that can lower A7, or at the start
of a run), ``ram_written`` (number of distinct bytes written by executed instructions; host writes through
:meth:`CPU.write` / :meth:`CPU.load` do not count). :meth:`CPU.reset_counters` clears them all.
"""


from __future__ import annotations

import struct
from bisect import bisect_right
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

from isa import codecache
from isa.blocks import _RN, BLOCK_MAX, _BlockInfo, block_entries, compile_block
from isa.closures import HANDLERS, build_closure
from isa.errors import AddressError, BusError, CPUFault, IllegalInstruction, IsaError, LimitExceeded
from isa.memory import _CODE, _TOP, MapError, MapFacts, Memory, Region
from isa.operands import Instruction
from isa.program import Program
from isa.semantics import CALL_SENTINEL, M32, _Fault, _format, _Stop

_SET_CODE_TABLE = bytes(b | _CODE for b in range(256))
_PL = struct.Struct(">L").pack_into

__all__ = ["CPU", "RunResult", "HANDLERS", "MapError", "CALL_SENTINEL", "Region"]


@dataclass(frozen=True)
class RunResult:
    """Why and after how much work :meth:`CPU.run` stopped.

    ``reason``: ``"trap"`` (TRAP #n executed; ``trap_number`` = n, PC after the TRAP), ``"until_pc"`` (PC reached
    ``until_pc``), ``"max_instructions"`` / ``"max_cycles"`` (only with ``stop_at_limit=True``; otherwise a limit
    raises :class:`isa.errors.LimitExceeded`). ``instructions`` and ``cycles`` (68000 clocks) count this run only."""

    reason: str
    trap_number: int | None
    instructions: int
    cycles: int
    pc: int


class RegisterView:
    """Eight 32-bit registers as a list-like view: item assignment masks to 32 bits (``d[0] = -1`` stores
    ``$FFFFFFFF``); values read back as unsigned ints."""

    __slots__ = ("_r", "_base", "_on_set")

    def __init__(self, regs: list[int], base: int, on_set: Callable[[], None] | None = None) -> None:
        self._r = regs
        self._base = base
        self._on_set = on_set

    def _index(self, i: int) -> int:
        if not isinstance(i, int) or not -8 <= i < 8:
            raise MapError(f"register index {i!r} out of range 0..7")
        return self._base + (i % 8)

    def __getitem__(self, i: int) -> int:
        return self._r[self._index(i)]

    def __setitem__(self, i: int, value: int) -> None:
        if not isinstance(value, int):
            raise MapError(f"register value {value!r} is not an int")
        self._r[self._index(i)] = value & M32
        if self._on_set is not None:
            self._on_set()

    def __len__(self) -> int:
        return 8

    def __iter__(self) -> Iterator[int]:
        return iter(self._r[self._base : self._base + 8])

    def __eq__(self, other: object) -> bool:
        try:
            return list(self) == list(other)
        except TypeError:
            return NotImplemented

    def __repr__(self) -> str:
        return "[" + ", ".join(f"${v:08X}" for v in self) + "]"


# ------------------------------------------------------------------------------------------------------------------
class CPU:
    """An MC68000 (subset) with a 24-bit, region-mapped, big-endian address space. See the module docstring."""

    #: Use compiled blocks in :meth:`run` (True) or the per-instruction closures only (False). Both give identical
    #: results, counters and faults; blocks are faster. Set it on one CPU, or on the class for every CPU.
    block_compile: bool = True

    def __init__(self, mapped: bool = True) -> None:
        """``mapped=True``: all 16 MiB are RAM. ``mapped=False``: nothing is mapped; call :meth:`map`."""
        self.memory = Memory(lambda: self._pc, self._invalidate, self._host_invalidate, prefault=mapped)
        self._mem = self.memory.mem
        self._flags = self.memory.flags
        self._flags32 = self.memory.flags32
        self._rd, self._wr = self.memory.rd, self.memory.wr
        self._mkey = codecache.map_key(())
        self._R: list[int] = [0] * 17  # D0-D7, A0-A7, SR
        self._R[16] = 0x2700
        self._pc = 0
        self._cache: dict[int, Callable[[], int]] = {}
        self._decoded: dict[int, tuple[Instruction, int]] = {}
        self._meta: dict[int, tuple[str, int | None]] = {}  # instruction address -> (handler, condition)
        # Compiled blocks: start -> (function or None, most instructions, clock bound, end address); the
        # instruction addresses each block covers; code object -> _BlockInfo (for faults inside a block).
        self._blocks: dict[int, tuple[Callable[[], int] | None, int, int, int]] = {}
        self._block_members: dict[int, list[int]] = {}
        # (block start, addresses of its instructions) of each block bound since _block_members was last brought
        # up to date: only an invalidation reads _block_members (_drop_blocks_at), so binding a block (each new CPU
        # binds every block it runs) does not index its instructions one by one.
        self._members_todo: list[tuple[int, Any]] = []
        self._block_drops: dict[int, int] = {}  # block start -> times its block was dropped by a code write
        self._block_code: dict[Any, _BlockInfo] = {}
        self._smc = [0]  # set when a program write invalidates compiled code (a running block leaves early)
        self.source_map: dict[int, Any] = {}
        self.d = RegisterView(self._R, 0)
        self.a = RegisterView(self._R, 8)
        self.instructions = 0
        self.cycles = 0
        self.profiling = False
        self.profile: dict[int, list[int]] = {}
        self._min_sp = [M32]
        self.last_trap: int | None = None
        if mapped:
            self.map(0, _TOP, "ram", writable=True)

    # ---------------------------------------------------------------------------------------------- registers
    @property
    def pc(self) -> int:
        """Program counter (24-bit address of the next instruction)."""
        return self._pc

    @pc.setter
    def pc(self, value: int) -> None:
        self._pc = int(value) & 0xFFFFFF

    @property
    def sr(self) -> int:
        """Status register, 16 bits as written (CCR = bits 4..0: X N Z V C)."""
        return self._R[16]

    @sr.setter
    def sr(self, value: int) -> None:
        self._R[16] = int(value) & 0xFFFF

    @property
    def ccr(self) -> int:
        """Condition code register: the low 5 bits of SR (X N Z V C)."""
        return self._R[16] & 0x1F

    @property
    def min_sp(self) -> int:
        """Lowest A7 value seen (32-bit), see the module docstring."""
        return min(self._min_sp[0], self._R[15])

    def reset_counters(self) -> None:
        """Zero ``instructions``, ``cycles``, ``profile``, ``ram_written``; set ``min_sp`` to the current A7."""
        self.instructions = 0
        self.cycles = 0
        self.profile = {}
        self._min_sp[0] = self._R[15]
        self.memory.clear_written()

    # --------------------------------------------------------------------------- memory (isa.memory.Memory)
    def map(self, start: int, size: int, name: str, writable: bool = True) -> None:
        """Map ``size`` bytes at ``start`` (both even, inside the 24-bit space, not overlapping another region).

        ``writable=False`` makes a ROM: programs writing it get a :class:`~isa.errors.BusError` (the host may still
        write it through :meth:`write`/:meth:`load`)."""
        self.memory.map(start, size, name, writable)
        self._mkey = codecache.map_key(self.memory.regions)

    @property
    def regions(self) -> tuple[Region, ...]:
        """The mapped regions, sorted by start address."""
        return tuple(self.memory.regions)

    def region_at(self, address: int) -> Region | None:
        """The region containing ``address`` (24-bit), or None."""
        return self.memory.region_at(address)

    @property
    def ram_written(self) -> int:
        """Number of distinct bytes written by executed instructions since construction/:meth:`reset_counters`."""
        return self.memory.ram_written

    def written_ranges(self) -> list[tuple[int, int]]:
        """The bytes counted by :attr:`ram_written`, as sorted ``(start, end_exclusive)`` address ranges."""
        return self.memory.written_ranges()

    def read(self, address: int, size: int) -> int:
        """Read an unsigned big-endian value of ``size`` bytes (1, 2, 4) at ``address`` (host access: no counters;
        unmapped -> BusError, odd word/long -> AddressError)."""
        return self.memory.read(address, size)

    def write(self, address: int, value: int, size: int) -> None:
        """Write ``value`` (masked to ``size`` bytes, big-endian) at ``address``. Host access: ROM regions may be
        written, unmapped ones raise BusError; not counted in :attr:`ram_written`; invalidates compiled code."""
        self.memory.write(address, value, size)

    def read_bytes(self, address: int, n: int) -> bytes:
        """``n`` bytes from ``address`` (host access; every byte must be mapped)."""
        return self.memory.read_bytes(address, n)

    def write_bytes(self, address: int, data: bytes) -> None:
        """Copy ``data`` to ``address`` (host access; every byte must be mapped; ROM allowed)."""
        self.memory.write_bytes(address, data)

    # ------------------------------------------------------------------------------------ the code caches

    def _invalidate(self, b: int) -> None:
        """Drop compiled closures whose bytes include address ``b``; clear code marks no closure still needs."""
        fl = self._flags
        cache, decoded = self._cache, self._decoded
        dropped = []
        for start in range(max(b - 9, 0) & ~1, b + 1, 2):
            info = decoded.get(start)
            if info is not None and start <= b < start + info[1]:
                cache.pop(start, None)
                del decoded[start]
                dropped.append((start, info[1]))
        for start, length in dropped:
            for x in range(start, start + length):
                fl[x] &= ~_CODE
            self._drop_blocks_at(start)
        for start in range(max(b - 19, 0) & ~1, b + 11, 2):  # re-mark bytes of overlapping survivors
            info = decoded.get(start)
            if info is not None:
                for x in range(start, start + info[1]):
                    fl[x] |= _CODE

    def _drop_blocks_at(self, start: int) -> None:
        """Forget every compiled block that contains the instruction at ``start``."""
        if self._members_todo:
            index = self._block_members
            for b, pcs in self._members_todo:
                for pc in pcs:
                    index.setdefault(pc, []).append(b)
            self._members_todo = []
        members = self._block_members.pop(start, None)
        if members:
            blocks = self._blocks
            drops = self._block_drops
            for b in members:
                e = blocks.pop(b, None)
                if e is not None and e[0] is not None:
                    self._block_code.pop(e[0].__code__, None)
                    drops[b] = drops.get(b, 0) + 1
            self._smc[0] = 1

    def _host_invalidate(self, a: int, marks: bytes) -> None:
        """A host write to ``[a, a + len(marks))`` hit bytes of decoded code (``marks[i] == 1``)."""
        i = marks.find(1)
        drops = dict(self._block_drops)
        while i != -1:
            self._invalidate(a + i)
            i = marks.find(1, i + 1)
        self._block_drops = drops  # only program writes count as self-modifying code

    # --------------------------------------------------------------------------------------------- programs
    def load(self, program: Program) -> None:
        """Copy the program's segments (bss zero-filled), keep its source map, set PC to ``program.origin``."""
        if not isinstance(program, Program):
            raise MapError(f"load() needs an isa.program.Program, got {type(program).__name__}")
        for seg in program.segments:
            data = bytes(len(seg.data)) if seg.bss else seg.data
            try:
                self.write_bytes(seg.origin, data)
            except BusError as exc:
                raise BusError(f"segment {seg.name!r} (${seg.origin:06X}, {len(data)} bytes) does not fit the "
                               f"memory map: {exc}", pc=self._pc, instruction="load") from None
        self.source_map = dict(program.source_map)
        self.pc = program.origin

    def _where(self, pc: int) -> tuple[str, str | None]:
        info = self._decoded.get(pc)
        if info is not None:
            text = _format(info[0])
        else:  # not decoded yet (e.g. a limit reached before it): decode it now, without caching
            try:
                from isa.decoder import decode

                text = "?" if pc & 1 else _format(decode(self.memory.fetch_word, pc).instruction)
            except Exception:  # noqa: BLE001 - unfetchable or illegal: no disassembly
                text = "?"
        src = self.source_map.get(pc)
        where = f"{src.file}:{src.line}" if src is not None else None
        return text, where

    def _fault(self, cls: type[CPUFault], message: str, pc: int) -> CPUFault:
        text, where = self._where(pc)
        return cls(message, pc=pc, instruction=text, source=where)

    def _compile(self, pc: int) -> Callable[[], int]:
        """Decode the instruction at ``pc`` (unless a block build already did) and cache its closure (faults are
        raised as _Fault)."""
        info = self._decoded.get(pc)
        if info is None:
            info = self._decode_at(pc)
        h, cond = self._meta[pc]
        fn = self._build(info[0], pc, info[1], h, cond)
        self._cache[pc] = fn
        return fn

    def _decode_at(self, pc: int) -> tuple[Instruction, int]:
        """Decode the instruction at ``pc``, record it (``_decoded``, ``_meta``) and mark its bytes as code;
        faults are raised as _Fault."""
        if pc & 1:
            raise _Fault(AddressError, f"instruction fetch at odd address ${pc:06X}")
        hit = codecache.lookup_decoded(self._mem, self._flags, pc)
        if hit is not None:
            ins, length, h, cond = hit
            info = self._decoded[pc] = (ins, length)
            self._meta[pc] = (h, cond)
            fl = self._flags
            for b in range(pc, pc + length):
                fl[b] |= _CODE
            return info
        from isa.decoder import decode

        try:
            dec = decode(self.memory.fetch_word, pc)
        except _Fault:
            raise
        except CPUFault as exc:
            raise _Fault(type(exc), str(exc).split(" at PC=")[0]) from None
        except IsaError as exc:
            raise _Fault(IllegalInstruction, f"cannot decode: {exc}") from None
        info = self._decoded[pc] = (dec.instruction, dec.length)
        self._meta[pc] = (dec.row.handler, dec.cond)
        codecache.store_decoded(self._mem, pc, (dec.instruction, dec.length, dec.row.handler, dec.cond))
        fl = self._flags
        for b in range(pc, pc + dec.length):
            fl[b] |= _CODE
        return info

    def _build(self, instr: Instruction, pc: int, length: int, handler: str | None = None,
               cond: int | None = None) -> Callable[[], int]:
        return build_closure(self._R, self._rd, self._wr, self._min_sp, instr, pc, length, handler, cond)

    def _build_block(self, start: int) -> tuple[Callable[[], int] | None, int, int, int]:
        """Compile (and cache) the block starting at ``start`` (extent: :func:`isa.blocks.block_entries`).
        Returns the cache entry ``(function or None, most instructions in one pass, clock bound of one pass,
        end address)``, so the run loop can keep ``max_instructions``/``max_cycles`` exact."""
        # code that keeps rewriting itself: recompiling big blocks each time would cost more than it saves
        most = BLOCK_MAX if self._block_drops.get(start, 0) < 2 else 0
        if most == BLOCK_MAX and not start & 1:
            hit = codecache.lookup_block(self._mem, start, self._mkey)
            if hit is not None:
                return self._adopt_block(start, *hit)
        entries = block_entries(start, most, self._decoded_at)
        if not entries:
            entry: tuple[Callable[[], int] | None, int, int, int] = (None, 0, 0, 0)
            if start in self._decoded:  # a TRAP/ILLEGAL/odd branch: remember; an unfetchable start: do not
                self._blocks[start] = entry
                self._members_todo.append((start, (start,)))
            return entry
        bind, info = compile_block(entries, MapFacts(self.memory.regions))
        pcs = tuple(e[0] for e in entries)
        if most == BLOCK_MAX:
            codecache.store_block(self._mem, start, self._mkey, info.end, entries, bind, info,
                                  ({e[0]: (e[1], e[4]) for e in entries}, {e[0]: (e[2], e[3]) for e in entries}, pcs))
        return self._bind_block(start, pcs, bind, info)

    def _adopt_block(self, start: int, end: int, code: bytes, entries: list[Any], bind: Any, info: _BlockInfo,
                     adopt: tuple[dict[int, Any], dict[int, Any], tuple[int, ...]]
                     ) -> tuple[Callable[[], int] | None, int, int, int]:
        """Take over a block another CPU compiled from the same bytes (:mod:`isa.codecache`): record its
        instructions as decoded here (``adopt``: their ``_decoded`` and ``_meta`` items and their addresses, made
        once when the block was stored) and mark its bytes as code, as decoding them would have."""
        decoded_items, meta_items, pcs = adopt
        self._decoded.update(decoded_items)
        self._meta.update(meta_items)
        fl = self._flags
        fl[start:end] = fl[start:end].translate(_SET_CODE_TABLE)
        return self._bind_block(start, pcs, bind, info)

    def _bind_block(self, start: int, pcs: tuple[int, ...], bind: Any, info: _BlockInfo
                    ) -> tuple[Callable[[], int] | None, int, int, int]:
        fn = bind(self._R, self._min_sp, self._smc, self.memory)
        entry = (fn, info.n, info.bound, info.end)
        self._blocks[start] = entry
        self._block_code[fn.__code__] = info
        self._members_todo.append((start, pcs))
        return entry

    def _decoded_at(self, pc: int) -> tuple[Instruction, int, str, int | None] | None:
        """``(instruction, length, handler, condition)`` at ``pc`` (decoding it if needed), None if it cannot be
        fetched or decoded."""
        info = self._decoded.get(pc)
        if info is None:
            try:
                info = self._decode_at(pc)
            except _Fault:
                return None
        h, cond = self._meta[pc]
        return info[0], info[1], h, cond

    def _unwind_block(self, tb: Any) -> tuple[int, int, int] | None:
        """After an exception raised inside a compiled block: write the block's register locals back, and return
        (PC of the instruction that raised, instructions completed before it, their clocks); None when the
        exception did not come from a block."""
        codes = self._block_code
        while tb is not None:
            info = codes.get(tb.tb_frame.f_code)
            if info is not None:
                break
            tb = tb.tb_next
        else:
            return None
        k = bisect_right(info.lines, tb.tb_lineno) - 1
        loc = tb.tb_frame.f_locals
        R = self._R
        for i in info.regs:
            R[i] = loc[_RN[i]]
        if "sr" in loc:
            R[16] = loc["sr"]
        return info.pcs[k], info.ncount[k] + loc.get("ni", 0), info.prefix[k] + loc.get("c", 0)

    # ---------------------------------------------------------------------------------------------- execution
    def execute(self, instr: Instruction, length: int | None = None) -> int:
        """Execute a hand-built instruction as if it sat at the current PC (``length`` bytes long; default from
        :func:`isa.encoder.length`), without reading it from memory. Returns its clocks; updates counters."""
        if length is None:
            from isa.encoder import length as enc_length

            length = enc_length(instr)
        pc = self._pc
        self._decoded[pc] = (instr, length)  # for fault messages only
        fn = self._build(instr, pc, length)
        self._cache.pop(pc, None)
        self._drop_blocks_at(pc)
        try:
            r = fn()
        except _Stop as stop:
            r = stop.packed
            self.last_trap = stop.trap
        except _Fault as f:
            raise self._fault(f.cls, f.message, pc) from None
        finally:
            self._decoded.pop(pc, None)
        self._pc = r & 0xFFFFFF
        self.instructions += 1
        self.cycles += r >> 32
        return r >> 32

    def step(self) -> int:
        """Execute one instruction at PC; return its clocks. A TRAP sets :attr:`last_trap` (else None)."""
        pc = self._pc
        self.last_trap = None
        try:
            f = self._cache.get(pc) or self._compile(pc)
            r = f()
        except _Stop as stop:
            r = stop.packed
            self.last_trap = stop.trap
        except _Fault as fault:
            raise self._fault(fault.cls, fault.message, pc) from None
        self._pc = r & 0xFFFFFF
        c = r >> 32
        self.instructions += 1
        self.cycles += c
        if self.profiling:
            p = self.profile.get(pc)
            if p is None:
                self.profile[pc] = [1, c]
            else:
                p[0] += 1
                p[1] += c
        return c

    def run(self, max_instructions: int | None = 10_000_000, max_cycles: int | None = None,
            until_pc: int | None = None, stop_at_limit: bool = False) -> RunResult:
        """Run until a TRAP, until PC equals ``until_pc`` (checked after each instruction), or a limit.

        A new instruction starts only while fewer than ``max_instructions`` instructions and fewer than
        ``max_cycles`` clocks have run in this call (so the cycle limit may be passed by one instruction). Reaching
        a limit raises :class:`~isa.errors.LimitExceeded`, or returns reason ``"max_instructions"``/
        ``"max_cycles"`` when ``stop_at_limit`` is true. Faults raise their :class:`~isa.errors.CPUFault`."""
        return RunResult(*self._run(max_instructions, max_cycles, until_pc, stop_at_limit))

    def _run(self, max_instructions: int | None, max_cycles: int | None, until_pc: int | None,  # noqa: C901 - the interpreter's hot loop: block dispatch, limits and stop conditions inline for speed
             stop_at_limit: bool, n: int = 0, cyc: int = 0, start_pc: int | None = None
             ) -> tuple[str, int | None, int, int, int]:
        """:meth:`run` without building the :class:`RunResult`: (reason, trap number, instructions, clocks, PC).
        ``n``/``cyc``/``start_pc``: go on with a run that already did ``n`` instructions and ``cyc`` clocks (not
        yet added to the counters) from ``start_pc`` (see :meth:`call`)."""
        maxn = (1 << 62) if max_instructions is None else int(max_instructions)
        maxc = (1 << 62) if max_cycles is None else int(max_cycles)
        until = -1 if until_pc is None else until_pc & 0xFFFFFF
        cache = self._cache
        compile_ = self._compile
        pc = self._pc
        if start_pc is None:
            start_pc = pc
        R = self._R
        if R[15] < self._min_sp[0]:
            self._min_sp[0] = R[15]
        self.last_trap = None
        self._smc[0] = 0
        reason = ""
        trap: int | None = None
        profile = self.profile if self.profiling else None
        try:
            if profile is None and self.block_compile:
                blocks = self._blocks
                build = self._build_block
                while n < maxn and cyc < maxc:
                    e = blocks.get(pc)
                    if e is None:
                        e = build(pc)
                    fn = e[0]
                    bn = maxn - n
                    bc = maxc - cyc
                    if fn is not None and e[1] <= bn and e[2] < bc and not pc < until < e[3]:
                        r = fn(bn, bc, until)
                        pc = r & 0xFFFFFF
                        n += (r >> 24) & 0xFFFFFFFF
                        cyc += r >> 56
                    else:
                        f = cache.get(pc) or compile_(pc)
                        r = f()
                        pc = r & 0xFFFFFF
                        cyc += r >> 32
                        n += 1
                    if pc == until:
                        reason = "until_pc"
                        break
            elif profile is None:
                while n < maxn and cyc < maxc:
                    f = cache.get(pc) or compile_(pc)
                    r = f()
                    pc = r & 0xFFFFFF
                    cyc += r >> 32
                    n += 1
                    if pc == until:
                        reason = "until_pc"
                        break
            else:
                while n < maxn and cyc < maxc:
                    ipc = pc
                    f = cache.get(pc) or compile_(pc)
                    r = f()
                    pc = r & 0xFFFFFF
                    c = r >> 32
                    cyc += c
                    n += 1
                    p = profile.get(ipc)
                    if p is None:
                        profile[ipc] = [1, c]
                    else:
                        p[0] += 1
                        p[1] += c
                    if pc == until:
                        reason = "until_pc"
                        break
        except _Stop as stop:
            fault_pc = pc
            pc = stop.packed & 0xFFFFFF
            c = stop.packed >> 32
            cyc += c
            n += 1
            if profile is not None:
                p = profile.setdefault(fault_pc, [0, 0])
                p[0] += 1
                p[1] += c
            reason = "trap"
            trap = stop.trap
            self.last_trap = trap
        except _Fault as fault:
            fix = self._unwind_block(fault.__traceback__)
            if fix is not None:
                pc, dn, dc = fix
                n += dn
                cyc += dc
            raise self._fault(fault.cls, fault.message, pc) from None
        except BaseException as exc:  # not a CPU fault (e.g. KeyboardInterrupt): keep the state consistent
            fix = self._unwind_block(exc.__traceback__)
            if fix is not None:
                pc, dn, dc = fix
                n += dn
                cyc += dc
            raise
        finally:
            self._pc = pc
            self.instructions += n
            self.cycles += cyc
        if not reason:
            reason = "max_instructions" if n >= maxn else "max_cycles"
            if not stop_at_limit:
                limit = f"{maxn} instructions" if n >= maxn else f"{maxc} cycles"
                raise self._fault(LimitExceeded, f"run limit of {limit} reached (started at ${start_pc:06X})", pc)
        return reason, trap, n, cyc, pc

    def call(self, address: int, max_cycles: int | None = 10_000_000,
             max_instructions: int | None = None) -> int:
        """Call the subroutine at ``address`` as JSR would (push :data:`CALL_SENTINEL` as the return address), run
        until its RTS returns there, restore PC, and return the clocks from its first instruction up to and
        including that RTS (the JSR itself is not counted). A TRAP or limit inside raises a CPUFault. A host that
        calls one routine many times: :meth:`caller`."""
        saved_pc = self._pc
        R = self._R
        sp = (R[15] - 4) & M32
        if sp <= 0xFFFFFC and not sp & 3 and self._flags32[sp >> 2] == 0x07070707:
            _PL(self._mem, sp, CALL_SENTINEL)  # mapped, writable, written, no code: all the accessor would do
        else:
            try:
                self._wr[4](sp, CALL_SENTINEL)
            except _Fault as fault:
                raise self._fault(fault.cls, f"call(${address:06X}): cannot push the return address: "
                                  f"{fault.message}", self._pc) from None
        R[15] = sp
        if sp < self._min_sp[0]:
            self._min_sp[0] = sp
        address &= 0xFFFFFF
        self._pc = address
        return self._call_run(address, saved_pc, max_instructions, max_cycles)

    def _call_block_raised(self, exc: BaseException, address: int) -> None:
        """The entry block run by a :meth:`caller` raised ``exc``: unwind the block (registers,
        PC, counters) as :meth:`_run` does; a CPU fault is raised here as its :class:`CPUFault`, anything else
        (e.g. KeyboardInterrupt) is left for the caller to re-raise."""
        if isinstance(exc, _Fault):
            pc, n, cyc = self._unwind_block(exc.__traceback__) or (address, 0, 0)
            self._pc = pc
            self.instructions += n
            self.cycles += cyc
            raise self._fault(exc.cls, exc.message, pc) from None
        fix = self._unwind_block(exc.__traceback__)
        if fix is not None:
            self._pc = fix[0]
            self.instructions += fix[1]
            self.cycles += fix[2]

    def _call_go_on(self, r: int, address: int, saved_pc: int, max_instructions: int | None,
                    max_cycles: int | None) -> int:
        """The entry block run by a :meth:`caller` returned ``r`` (packed next PC, instructions, clocks) elsewhere
        than to the sentinel: go on in :meth:`_run` from there, counting what the block did (so limits, the
        ``LimitExceeded`` message, "started at" the entry, and the counters are those of one :meth:`_run`)."""
        self._pc = r & 0xFFFFFF
        return self._call_run(address, saved_pc, max_instructions, max_cycles, (r >> 24) & 0xFFFFFFFF, r >> 56,
                              address)

    def _call_run(self, address: int, saved_pc: int, max_instructions: int | None, max_cycles: int | None,
                  n: int = 0, cyc: int = 0, start_pc: int | None = None) -> int:
        """A call whose return address is pushed and PC set: run it in :meth:`_run` (``n``, ``cyc``,
        ``start_pc``: what an entry block already did, as :meth:`_run` takes them) until it returns to the
        sentinel; PC restored to ``saved_pc``, the clocks returned."""
        reason, trap, _, cycles, _ = self._run(max_instructions, max_cycles, CALL_SENTINEL, False, n, cyc, start_pc)
        if reason != "until_pc":
            raise self._fault(CPUFault, f"call(${address:06X}) stopped by TRAP #{trap} before "
                              "returning", (self._pc - 2) & 0xFFFFFF)
        self._pc = saved_pc
        return cycles

    def caller(self, address: int, max_cycles: int | None = 10_000_000,
               max_instructions: int | None = None) -> Callable[[], int]:
        """``lambda: self.call(address, max_cycles, max_instructions)``, with the per-call set-up done once: for a
        host that calls one routine many times (the firmware harness calls ``step`` once a sample). Each call of
        the returned function has exactly the effects and result of that :meth:`call` (registers, memory, PC,
        counters, ``min_sp``, faults), at whatever state the CPU is in then: when the routine's entry block is
        compiled, the return address can be pushed straight into plain RAM and nothing else applies (profiling,
        blocks off, a budget below one pass), it runs the block itself; otherwise it calls :meth:`call`."""
        if not isinstance(address, int):
            raise TypeError(f"caller() needs an int address, got {type(address).__name__}")
        call = self.call
        at = address & 0xFFFFFF
        maxn = (1 << 62) if max_instructions is None else int(max_instructions)
        maxc = (1 << 62) if max_cycles is None else int(max_cycles)
        R, mem, flags32, min_sp, smc, blocks = self._R, self._mem, self._flags32, self._min_sp, self._smc, self._blocks
        sentinel = CALL_SENTINEL
        spans = at < sentinel
        fits: list[Any] = [False]  # the entry tuple last found to fit the budget (a recompiled block is a new one)

        def run() -> int:
            sp = (R[15] - 4) & M32
            e = blocks.get(at)
            if e is not fits[0]:
                if e is None or e[0] is None or e[1] > maxn or e[2] >= maxc or (spans and sentinel < e[3]):
                    return call(address, max_cycles, max_instructions)
                fits[0] = e
            if sp > 0xFFFFFC or sp & 3 or flags32[sp >> 2] != 0x07070707 or self.profiling or not self.block_compile:
                return call(address, max_cycles, max_instructions)
            _PL(mem, sp, sentinel)
            R[15] = sp
            if sp < min_sp[0]:
                min_sp[0] = sp
            saved_pc = self._pc
            self._pc = at
            self.last_trap = None
            smc[0] = 0
            try:
                r = e[0](maxn, maxc, sentinel)
            except BaseException as exc:
                self._call_block_raised(exc, at)
                raise
            if r & 0xFFFFFF == sentinel:
                cyc = r >> 56
                self.instructions += (r >> 24) & 0xFFFFFFFF
                self.cycles += cyc
                self._pc = saved_pc
                return cyc
            return self._call_go_on(r, at, saved_pc, max_instructions, max_cycles)

        return run

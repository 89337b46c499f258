"""Adapters that run ONE 68000 instruction on our interpreter and on the independent references.

Used by ``tests/isa/test_vs_m68000py.py``, ``tests/isa/test_vs_musashi.py`` and ``bench/bench_cpu.py``.
Every adapter takes the same machine description and returns the same :class:`State`, so a test can compare
ours against a reference field by field (:func:`compare`).

Machine used for every run (one flat RAM, the same image loaded into every implementation):

* RAM ``[0, RAM_SIZE)`` is mapped; every other 24-bit address is a bus error.
* Exception vectors ``0..0x3FF``: vector ``n`` points at ``HANDLERS + 4*n`` (a field of NOPs), so a
  reference that takes an exception ends with ``PC`` in ``[HANDLERS, HANDLERS + 0x400)`` and the vector
  number is ``(PC - HANDLERS) // 4``. That is how a reference fault (address error = 3, bus error = 2,
  illegal = 4, zero divide = 5, TRAP #n = 32+n) is recognised.
* The references run in USER mode (SR.S = 0) with the supervisor stack at ``SSP`` (inside the excluded
  region ``[EXCLUDED_LO, RAM_SIZE)``), so an exception frame never touches the user-visible A7 or the memory
  that is compared. Our CPU has no supervisor state; only the CCR (X N Z V C) is compared.

Faults are normalised to strings: ``"address"``, ``"bus"``, ``"illegal"``, ``"zero_divide"``, ``"trap"``
(with :attr:`State.vector`), ``"other"``.
"""

from __future__ import annotations

import functools
import random
import re
from dataclasses import dataclass, field
from typing import Sequence

from hypothesis import assume
from hypothesis import strategies as st

from isa.operands import IndexReg, Instruction, Mode, Operand, Size
from isa.table import TABLE

MASK32 = 0xFFFFFFFF
RAM_SIZE = 0x20000  #: bytes of mapped RAM, from address 0
VECTORS = 0x0000  #: exception vector table (256 longs)
HANDLERS = 0x1F000  #: vector n -> HANDLERS + 4*n (NOP field)
SSP = 0x1FF00  #: the references' supervisor stack (exception frames land below it)
EXCLUDED_LO = 0x1F000  #: memory from here to RAM_SIZE is not compared (handlers, exception frames)
CODE = 0xC000  #: where the instruction under test is placed
DATA_LO = 0x6000  #: random data region used for effective addresses (reachable by abs.W and d16(PC))
DATA_HI = 0x7000
NOP = 0x4E71

CCR_NAMES = ((0x10, "X"), (0x08, "N"), (0x04, "Z"), (0x02, "V"), (0x01, "C"))

VECTOR_FAULTS = {2: "bus", 3: "address", 4: "illegal", 5: "zero_divide"}


@dataclass
class Machine:
    """One starting state: register values (u32), CCR (5 bits, X N Z V C), PC and the RAM image.

    ``d`` and ``a`` are 8 values each (``a[7]`` is the stack pointer); ``memory`` is a ``bytes`` of
    :data:`RAM_SIZE` bytes already containing the code, vectors and data."""

    d: list[int]
    a: list[int]
    ccr: int
    pc: int
    memory: bytes


@dataclass
class State:
    """The outcome of running one instruction.

    ``d``/``a``: registers (u32; ``a[7]`` the user stack pointer); ``pc``: next PC (for a TRAP: the PC the
    reference stacked, i.e. the address after the TRAP); ``ccr``: X N Z V C bits; ``memory``: RAM
    ``[0, EXCLUDED_LO)`` after the step; ``cycles``: 68000 clocks (None when the implementation has no
    trustworthy count); ``fault``: None or one of the strings of the module docstring; ``vector``: the
    exception vector a reference took (None for ours)."""

    d: tuple[int, ...]
    a: tuple[int, ...]
    pc: int
    ccr: int
    memory: bytes
    cycles: int | None
    fault: str | None = None
    vector: int | None = None
    detail: str = ""
    accesses: list[tuple[str, int, int]] = field(default_factory=list)
    fault_address: int | None = None  #: bus errors: the address of the access that faulted (24-bit)


@functools.lru_cache(maxsize=1)
def _vectors_and_handlers() -> bytes:
    """The part of :func:`base_image` every run shares: the RAM with its vectors and NOP handlers (built once)."""
    mem = bytearray(RAM_SIZE)
    for n in range(256):
        mem[VECTORS + 4 * n : VECTORS + 4 * n + 4] = (HANDLERS + 4 * n).to_bytes(4, "big")
    mem[HANDLERS : HANDLERS + 0x400] = NOP.to_bytes(2, "big") * 0x200
    return bytes(mem)


def base_image(seed: int, blocks: Sequence[tuple[int, bytes]] = ()) -> bytearray:
    """The RAM image every run starts from: vectors, NOP handlers, random data bytes from ``seed`` in
    ``[DATA_LO, DATA_HI)``, then ``blocks`` (``(address, bytes)``) written over it in order."""
    mem = bytearray(_vectors_and_handlers())
    mem[DATA_LO:DATA_HI] = random.Random(seed).randbytes(DATA_HI - DATA_LO)
    for address, data in blocks:
        if address < 0 or address + len(data) > RAM_SIZE:
            raise ValueError(f"block at ${address:X} (+{len(data)}) is outside the RAM")
        mem[address : address + len(data)] = data
    return mem


# --------------------------------------------------------------------------------------------- references


def _vector_state(pc: int) -> int | None:
    """Vector number if ``pc`` is the start of one of the NOP handlers, else None."""
    if HANDLERS <= pc < HANDLERS + 0x400 and not (pc - HANDLERS) & 3:
        return (pc - HANDLERS) // 4
    return None


def _fault_of_vector(vector: int) -> str:
    if 32 <= vector < 48:
        return "trap"
    return VECTOR_FAULTS.get(vector, "other")


class M68000PyRef:
    """``m68000-python`` (pure Python, MIT): trusted for data, flags and cycles."""

    name = "m68000-python"
    trusts_cycles = True

    def __init__(self) -> None:
        from m68000_python import M68000CPU, BusError

        self._BusError = BusError
        self.mem = bytearray(RAM_SIZE)
        mem = self.mem
        size = RAM_SIZE
        bus_error = BusError
        self.log: list[tuple[str, int, int]] = []
        log = self.log

        def read_byte(address: int) -> int:
            if address >= size:
                log.append(("R", 1, address))
                raise bus_error()
            return mem[address]

        def read_word(address: int) -> int:
            if address >= size - 1:
                log.append(("R", 2, address))
                raise bus_error()
            return (mem[address] << 8) | mem[address + 1]

        def write_byte(address: int, value: int) -> None:
            if address >= size:
                log.append(("W", 1, address))
                raise bus_error()
            mem[address] = value & 0xFF

        def write_word(address: int, value: int) -> None:
            if address >= size - 1:
                log.append(("W", 2, address))
                raise bus_error()
            mem[address] = (value >> 8) & 0xFF
            mem[address + 1] = value & 0xFF

        self.cpu = M68000CPU(read_byte, read_word, write_byte, write_word)
        self.fast = (read_byte, read_word, write_byte, write_word)

    def run(self, machine: Machine) -> State:
        """Run one instruction from ``machine``; see :class:`State`."""
        from m68000_python import CPUState

        mem = self.mem
        mem[:] = machine.memory
        self.log.clear()
        cpu = self.cpu
        pc = machine.pc
        state = CPUState(
            d=tuple(v & MASK32 for v in machine.d),
            a=tuple(v & MASK32 for v in machine.a[:7]),
            usp=machine.a[7] & MASK32,
            ssp=SSP,
            sr=machine.ccr & 0x1F,
            pc=pc,
            ir=(mem[pc] << 8) | mem[pc + 1],
            irc=(mem[pc + 2] << 8) | mem[pc + 3],
        )
        cpu.restore_state(state)
        cycles = cpu.step()
        after = cpu.capture_state()
        if after.halted:
            return State(after.d, after.a + (after.usp,), after.pc, after.sr & 0x1F, bytes(mem[:EXCLUDED_LO]),
                         cycles, "other", None, "halted (double fault)")
        vector = _vector_state(after.pc)
        d = after.d
        a = after.a + (after.usp,)
        if vector is None:
            return State(d, a, after.pc, after.sr & 0x1F, bytes(mem[:EXCLUDED_LO]), cycles)
        # Exception taken: the 3-word frame (SR, PC) or the 7-word group-0 frame is at the SSP.
        sp = after.ssp
        fault = _fault_of_vector(vector)
        access = None
        if vector in (2, 3):
            stacked_sr = (mem[sp + 8] << 8) | mem[sp + 9]
            stacked_pc = int.from_bytes(mem[sp + 10 : sp + 14], "big")
            access = int.from_bytes(mem[sp + 2 : sp + 6], "big") & 0xFFFFFF
            detail = f"vector {vector} access ${access:06X}"
        else:
            stacked_sr = (mem[sp] << 8) | mem[sp + 1]
            stacked_pc = int.from_bytes(mem[sp + 2 : sp + 6], "big")
            detail = f"vector {vector}"
        return State(d, a, stacked_pc, stacked_sr & 0x1F, bytes(mem[:EXCLUDED_LO]), cycles, fault, vector, detail,
                     fault_address=access if vector == 2 else None)


_MUSASHI: "MusashiRef | None" = None


class MusashiRef:
    """Musashi through ``machine68k`` (Cython, GPL): trusted for data and flags, NOT for cycles.

    machine68k builds Musashi with ``M68K_EMULATE_ADDRESS_ERROR`` off and has one global CPU and RAM per
    process, so :func:`musashi` returns a singleton. Odd word/long accesses and unmapped accesses are
    recognised from the memory trace instead (hardware would address-error / bus-error at the first one)."""

    name = "musashi"
    trusts_cycles = False

    def __init__(self) -> None:
        import machine68k

        self._m = machine68k.Machine(machine68k.CPUType.M68000, RAM_SIZE // 1024)
        self.cpu = self._m.cpu
        self.mem = self._m.mem
        self.Register = machine68k.Register
        self.log: list[tuple[str, int, int]] = []
        self.bad: list[tuple[str, int, int]] = []
        log, bad = self.log, self.bad

        def trace(mode: str, width: int, address: int, value: int) -> None:
            log.append((mode, 1 << width, address))
            if width and address & 1:
                bad.append(("address", mode, address))

        def invalid(mode: str, width: int, address: int) -> None:
            log.append((mode, 1 << width, address))
            # An odd word/long access address-errors before any bus cycle, mapped or not.
            bad.append(("address" if width and address & 1 else "bus", mode, address))

        self.mem.set_invalid_func(invalid)
        self.mem.set_trace_func(trace)
        # Leave the reset state: vectors 0/4 -> SSP and a NOP handler, then one execute absorbs the reset.
        self.mem.w32(0, SSP)
        self.mem.w32(4, HANDLERS)
        self.mem.w16(HANDLERS, NOP)
        self.cpu.pulse_reset()
        self.cpu.execute(1)

    def run(self, machine: Machine, trace: bool = True) -> State:
        """Run one instruction from ``machine``; see :class:`State`. ``cycles`` is Musashi's count
        (reported for information only; :attr:`trusts_cycles` is False)."""
        cpu, mem, R = self.cpu, self.mem, self.Register
        mem.w_block(0, machine.memory)
        self.log.clear()
        self.bad.clear()
        # SR writes through m68k_set_reg do not swap stack pointers: enter user mode first, then set the
        # ISP (stored, since S=0) and A7 (the live USP).
        cpu.w_sr(machine.ccr & 0x1F)
        cpu.w_isp(SSP)
        for i in range(8):
            cpu.w_reg(R.D0 + i, machine.d[i] & MASK32)
            cpu.w_reg(R.A0 + i, machine.a[i] & MASK32)
        cpu.w_pc(machine.pc)
        mem.set_trace_mode(trace)
        try:
            cycles = cpu.execute(1).cycles
        finally:
            mem.set_trace_mode(False)
        d = tuple(cpu.r_reg(R.D0 + i) for i in range(8))
        a = tuple(cpu.r_reg(R.A0 + i) for i in range(7)) + (cpu.r_usp(),)
        pc = cpu.r_pc()
        sr = cpu.r_sr()
        image = mem.r_block(0, EXCLUDED_LO)
        accesses = list(self.log)
        if self.bad:
            kind, mode, address = self.bad[0]
            return State(d, a, pc, sr & 0x1F, image, cycles, kind, None,
                         f"first {'odd' if kind == 'address' else 'unmapped'} {mode} access at ${address:06X}",
                         accesses)
        if pc & 1:
            return State(d, a, pc, sr & 0x1F, image, cycles, "address", None, f"odd PC ${pc:06X}", accesses)
        vector = _vector_state(pc)
        if vector is None:
            return State(d, a, pc, sr & 0x1F, image, cycles, accesses=accesses)
        sp = cpu.r_isp() if not sr & 0x2000 else cpu.r_reg(R.A7)
        stacked_sr = mem.r16(sp)
        stacked_pc = mem.r32(sp + 2)
        return State(d, a, stacked_pc, stacked_sr & 0x1F, image, cycles, _fault_of_vector(vector), vector,
                     f"vector {vector}", accesses)


def musashi() -> MusashiRef:
    """The process-wide Musashi adapter (machine68k keeps one global CPU and RAM)."""
    global _MUSASHI
    if _MUSASHI is None:
        _MUSASHI = MusashiRef()
    return _MUSASHI


# ------------------------------------------------------------------------------------------------ our CPU


def ours_run(machine: Machine) -> State:
    """Run one instruction on :class:`isa.CPU` from ``machine``; faults are caught and named, not raised."""
    return OursAdapter.get().run(machine)


class OursAdapter:
    """Our interpreter behind the same interface as the references (one CPU object reused per process)."""

    name = "ours"
    trusts_cycles = True
    _instance: "OursAdapter | None" = None

    @classmethod
    def get(cls) -> "OursAdapter":
        """The process-wide adapter."""
        if cls._instance is None:
            cls._instance = cls()
        return cls._instance

    def __init__(self) -> None:
        import isa
        from isa import errors

        self.isa = isa
        self.errors = errors
        self.faults = (
            (errors.AddressError, "address"),
            (errors.BusError, "bus"),
            (errors.IllegalInstruction, "illegal"),
            (errors.DivideByZero, "zero_divide"),
        )
        self.cpu = None
        self.image = bytearray()

    def new_cpu(self, machine: Machine):  # isa.CPU is imported lazily
        """The adapter's CPU with ``machine`` loaded (RAM, registers, CCR, PC). One CPU is reused: its 16 MiB
        backing store is costly to allocate, and host writes invalidate any code it compiled before."""
        import numpy as np

        if self.cpu is None:
            self.cpu = make_cpu(self.isa)
            self.cpu.write_bytes(0, machine.memory)
        else:
            # Host writes check every byte (Python loops in isa.cpu): write only the runs that differ from what
            # the CPU holds (self.image mirrors it).
            diff = np.flatnonzero(np.frombuffer(self.image, np.uint8) != np.frombuffer(machine.memory, np.uint8))
            if diff.size:
                breaks = np.flatnonzero(np.diff(diff) > 16)
                starts = np.concatenate(([diff[0]], diff[breaks + 1]))
                ends = np.concatenate((diff[breaks], [diff[-1]])) + 1
                for lo, hi in zip(starts.tolist(), ends.tolist()):
                    self.cpu.write_bytes(lo, machine.memory[lo:hi])
        self.image = bytearray(machine.memory)
        cpu = self.cpu
        cpu.reset_counters()
        for i in range(8):
            cpu.d[i] = machine.d[i] & MASK32
            cpu.a[i] = machine.a[i] & MASK32
        set_ccr(cpu, machine.ccr)
        cpu.pc = machine.pc
        return cpu

    def run(self, machine: Machine) -> State:
        """Run one instruction from ``machine``; see :class:`State`."""
        cpu = self.new_cpu(machine)
        fault = None
        detail = ""
        vector = None
        cycles: int | None = None
        fault_address = None
        try:
            cycles = cpu.step()
        except self.errors.CPUFault as exc:
            detail = str(exc)
            m = _FAULT_ADDRESS.search(detail)
            if m is not None and isinstance(exc, self.errors.BusError):
                fault_address = int(m.group(1), 16)
            for cls, name in self.faults:
                if isinstance(exc, cls):
                    fault = name
                    break
            else:
                fault = "other"
        if fault is None and trapped(cpu):
            fault = "trap"
            vector = 32 + trap_number(cpu)
        image = self.image
        for lo, hi in cpu.written_ranges():  # what the instruction wrote (isa.CPU tracks it per byte)
            image[lo:hi] = cpu.read_bytes(lo, hi - lo)
        return State(
            tuple(cpu.d[i] & MASK32 for i in range(8)),
            tuple(cpu.a[i] & MASK32 for i in range(8)),
            cpu.pc,
            get_ccr(cpu),
            bytes(image[:EXCLUDED_LO]),
            cycles,
            fault,
            vector,
            detail,
            fault_address=fault_address,
        )



#: The faulting address in our BusError messages ("... unmapped address $020000 at PC=...", "... at $020000 at").
_FAULT_ADDRESS = re.compile(r"\$([0-9A-F]{6}) at PC=")


# These four helpers isolate the parts of isa.CPU's interface that the contract leaves open.


def make_cpu(isa_module):
    """An ``isa.CPU`` with only ``[0, RAM_SIZE)`` mapped (as RAM); everything else is a bus error."""
    cpu = isa_module.CPU(mapped=False)
    cpu.map(0, RAM_SIZE, "ram", writable=True)
    return cpu


def set_ccr(cpu, ccr: int) -> None:
    """Set X N Z V C (bits 4..0) of our CPU's status register (the rest stays $2700)."""
    cpu.sr = 0x2700 | (ccr & 0x1F)


def get_ccr(cpu) -> int:
    """X N Z V C (bits 4..0) of our CPU's status register."""
    return cpu.sr & 0x1F


def trapped(cpu) -> bool:
    """True when the last step executed TRAP #n (our CPU stops instead of vectoring)."""
    return cpu.last_trap is not None


def trap_number(cpu) -> int:
    """The n of the TRAP #n the last step executed."""
    return int(cpu.last_trap)


# ------------------------------------------------------------------------------------------------ compare


def _ccr_text(ccr: int) -> str:
    return "".join(name if ccr & bit else "-" for bit, name in CCR_NAMES)


def compare(ours: State, ref: State, cycles: bool) -> list[str]:
    """Differences between our state and a reference's, one readable line each (empty: they agree).

    When either side faulted (other than TRAP) only the fault kinds are compared: the state after a fault is
    not architecturally comparable (ours raises, the reference stacks a frame and vectors)."""
    diffs: list[str] = []
    if ours.fault != ref.fault:
        diffs.append(f"fault: ours {ours.fault or 'none'} ({ours.detail or '-'}), "
                     f"ref {ref.fault or 'none'} ({ref.detail or '-'})")
        return diffs
    if ours.fault not in (None, "trap"):
        return diffs
    if ours.fault == "trap" and ours.vector != ref.vector:
        diffs.append(f"trap vector: ours {ours.vector}, ref {ref.vector}")
    for name, mine, theirs in (("D", ours.d, ref.d), ("A", ours.a, ref.a)):
        for i, (x, y) in enumerate(zip(mine, theirs)):
            if x != y:
                diffs.append(f"{name}{i}: ours ${x:08X}, ref ${y:08X}")
    if ours.pc != ref.pc:
        diffs.append(f"PC: ours ${ours.pc:06X}, ref ${ref.pc:06X}")
    if ours.ccr != ref.ccr:
        bad = [name for bit, name in CCR_NAMES if (ours.ccr ^ ref.ccr) & bit]
        diffs.append(f"CCR {','.join(bad)}: ours {_ccr_text(ours.ccr)}, ref {_ccr_text(ref.ccr)}")
    if ours.memory != ref.memory:
        bad_bytes = [i for i, (x, y) in enumerate(zip(ours.memory, ref.memory)) if x != y]
        shown = ", ".join(f"${i:06X}: ours ${ours.memory[i]:02X} ref ${ref.memory[i]:02X}" for i in bad_bytes[:8])
        diffs.append(f"memory ({len(bad_bytes)} bytes differ): {shown}")
    if cycles and ours.cycles != ref.cycles:
        diffs.append(f"cycles: ours {ours.cycles}, ref {ref.cycles}")
    return diffs


def describe(machine: Machine, text: str, code: bytes) -> str:
    """The starting state in one block, for failure messages."""
    regs = " ".join(f"D{i}=${v & MASK32:08X}" for i, v in enumerate(machine.d))
    aregs = " ".join(f"A{i}=${v & MASK32:08X}" for i, v in enumerate(machine.a))
    return (f"instruction: {text}   bytes: {code.hex(' ')}   at PC=${machine.pc:06X}\n"
            f"  {regs}\n  {aregs}\n  CCR={_ccr_text(machine.ccr)}")


def ref_disassembly(code: bytes, address: int) -> str:
    """m68000-python's disassembly of ``code`` (an independent second opinion in failure messages)."""
    try:
        from m68000_python import disassemble_bytes

        return str(disassemble_bytes(code, address))
    except Exception as exc:  # noqa: BLE001 - only decoration for a message
        return f"<{exc}>"


# ---------------------------------------------------------------------------------------- case generation


#: 32-bit edge values every register and memory draw is biased towards.
EDGE32 = (0, 1, 0xFFFFFFFF, 0x7FFF, 0x8000, 0x7FFFFFFF, 0x80000000, 0xFFFF, 0xFFFF8000, 0x7F, 0x80, 0xFF,
          0xFFFFFF80, 0x10000, 0xFFFF0000, 0x5555AAAA, 0xAAAA5555, 2, 0xFFFFFFFE)
EDGE16 = (0, 1, 0xFFFF, 0x7FFF, 0x8000, 0x7F, 0x80, 0xFF, 0x5555, 0xAAAA, 2, 0xFFFE, 0x8001)
EDGE8 = (0, 1, 0xFF, 0x7F, 0x80, 0x55, 0xAA, 0xFE, 0x81)


# The strategy builders below are memoized: hypothesis strategies are immutable, and one object per argument set
# draws exactly what a fresh one would, without hypothesis validating a new strategy tree at every draw (that was
# most of the data-generation time of the isa_vs_* tests: tests/conftest.py, docs/testing.md).
@functools.lru_cache(maxsize=None)
def u32() -> st.SearchStrategy[int]:
    """A 32-bit value, about half the time one of :data:`EDGE32`."""
    return st.one_of(st.sampled_from(EDGE32), st.integers(0, MASK32))


@functools.lru_cache(maxsize=None)
def value_of(nbytes: int) -> st.SearchStrategy[int]:
    """An unsigned value of ``nbytes`` (1, 2 or 4) biased to that size's edge values."""
    edges = {1: EDGE8, 2: EDGE16, 4: EDGE32}[nbytes]
    return st.one_of(st.sampled_from(edges), st.integers(0, (1 << (8 * nbytes)) - 1))


#: CCR values (X N Z V C) :func:`ccr_value` is biased towards: every one has Z set. A rule that keeps a flag is
#: only tested when the flag is set going in (ADDX, SUBX and NEGX keep Z on a zero result; most instructions keep
#: X): with these, Z is set in 3 of 4 drawn states instead of 1 of 2.
EDGE_CCR = (0x1F, 0x04, 0x14, 0x0F, 0x15)


@functools.lru_cache(maxsize=None)
def ccr_value() -> st.SearchStrategy[int]:
    """A CCR value (5 bits), about half the time one of :data:`EDGE_CCR`."""
    return st.one_of(st.sampled_from(EDGE_CCR), st.integers(0, 0x1F))


SHIFTS = ("asl", "asr", "lsl", "lsr", "rol", "ror", "roxl", "roxr")
MEMORY_MODES = (Mode.AIND, Mode.APOSTINC, Mode.APREDEC, Mode.ADISP, Mode.AINDEX)
ABSOLUTE_MODES = (Mode.ABSW, Mode.ABSL, Mode.PCDISP, Mode.PCINDEX)
_MODE_ORDER = list(Mode)


@dataclass
class Case:
    """One generated test: the instruction, its text, its bytes and the starting machine."""

    instruction: Instruction
    text: str
    code: bytes
    machine: Machine


def size_bytes(row, size: Size | None) -> int:
    """Operand width in bytes of ``row`` at ``size`` (implied sizes: MULS/DIVS word, LEA long ...)."""
    if size is None or size is Size.S:
        return 2
    return size.bytes


@functools.lru_cache(maxsize=None)
def _sampled(values: tuple) -> st.SearchStrategy:
    return st.sampled_from(values)


@functools.lru_cache(maxsize=None)
def _biased(lo: int, hi: int) -> st.SearchStrategy[int]:
    """An integer in [lo, hi], biased to the ends, 0 and +-1."""
    edges = [v for v in (lo, hi, 0, 1, -1, lo + 1, hi - 1) if lo <= v <= hi]
    return st.one_of(st.sampled_from(edges), st.integers(lo, hi))


@functools.lru_cache(maxsize=None)
def _a_value() -> st.SearchStrategy[int]:
    return st.one_of(u32(), st.integers(DATA_LO, DATA_HI - 1))


def draw_instruction(draw, row, size: Size | None, first_mode: Mode | None) -> Instruction:
    """A random canonical instruction of ``row`` at ``size`` whose first EA operand has ``first_mode``.

    The other operands' modes and the condition are drawn here; the operand values come from
    :func:`isa.strategies.build` (with an edge-biased value source). Addresses are placeholders that
    :func:`cases` overwrites."""
    from isa.strategies import Form, build

    modes: list[Mode] = []
    seen_ea = False
    for i, spec in enumerate(row.operands):
        if spec.kind == "ea":
            if not seen_ea and first_mode is not None:
                modes.append(first_mode)
            else:
                modes.append(draw(_sampled(tuple(sorted(row.allowed_modes(i, size), key=_MODE_ORDER.index)))))
            seen_ea = True
        else:
            modes.append(sorted(spec.modes, key=_MODE_ORDER.index)[0])
    cond = draw(_sampled(tuple(sorted(row.condition_codes)))) if row.conditional else None

    def biased(lo: int, hi: int) -> int:
        return draw(_biased(lo, hi))

    return build(Form(row, size, cond, tuple(modes)), CODE, biased)


#: When a list (set by ``tests/support/oracle_draws.py``), :func:`cases` appends what it drew for every case it builds:
#: ``(text, d, a, ccr, targets)``, ``targets`` being the addresses it placed memory operands and jump targets at.
DRAWN: list[tuple[str, tuple[int, ...], tuple[int, ...], int, tuple[int, ...]]] | None = None


@st.composite
def cases(draw, row, size: Size | None, first_mode: Mode | None, odd: bool = False,  # noqa: C901 - one branch per operand constraint of the instruction table's rows
          bus: bool = False) -> Case:
    """A complete test case for ``row``/``size``/``first_mode``.

    Address registers used as bases (and absolute / PC-relative targets) are made to point into the data
    region, even for word/long accesses unless ``odd`` (then every placed address is odd). With ``bus`` every
    placed address except PC-relative ones is at or just below the end of the RAM (:func:`bus_target`), so
    the access runs into unmapped memory (abs.W: ``$FF8000`` and up). Other registers
    get edge-biased random values; DIVS/DIVU divisors are biased towards 0, 1, -1 and overflow; register
    shift counts cover 0..63; the stack pointer A7 is even inside the data region."""
    from isa.encoder import encode

    instr = draw_instruction(draw, row, size, first_mode)
    pc = CODE
    d = [draw(u32()) for _ in range(8)]
    a = [draw(_a_value()) for _ in range(7)]
    a.append(draw(st.integers((DATA_LO + 0x400) // 2, (DATA_HI - 0x400) // 2)) * 2)
    ccr = draw(ccr_value())
    seed = draw(st.integers(0, 2**32 - 1))
    blocks: list[tuple[int, bytes]] = []
    nbytes = size_bytes(row, size)
    align = nbytes > 1 or row.handler in ("movem", "jmp", "jsr", "lea", "pea")

    targets: list[int] = []

    def target(mode: Mode | None = None) -> int:
        if bus and mode not in (Mode.PCDISP, Mode.PCINDEX):
            t = draw(bus_target(mode))
        else:
            t = draw(st.integers(DATA_LO + 0x100, DATA_HI - 0x100))
            t = t | 1 if odd else t & ~1 if align else t
        targets.append(t)
        return t

    def fill(t: int) -> None:
        if t + 8 > EXCLUDED_LO:  # a bus-error target: nothing (or only the excluded region) to fill
            return
        blocks.append((t, draw(value_of(4)).to_bytes(4, "big") + draw(st.integers(0, MASK32)).to_bytes(4, "big")))

    placed: set[tuple[bool, int]] = set()  # (is_areg, num) whose value is final
    ops = list(instr.operands)
    handler = row.handler
    if handler in ("jsr", "pea"):
        # These push onto A7: keep A7 a valid stack pointer by basing the EA on A6 instead (the pushes' order
        # against a faulting EA access is prefetch detail Musashi does not model).
        # The same for an A7 index register (found by the thorough profile: jsr d8(pc,a7.l) with A7 far outside
        # RAM made Musashi push into unmapped memory before the odd-target fault the chip takes first).
        ops = [Operand(op.mode, 6 if op.mode in MEMORY_MODES and op.reg == 7 else op.reg, op.value,
                       IndexReg(True, 6, op.index.long) if op.index is not None and op.index.is_areg
                       and op.index.num == 7 else op.index)
               for op in ops]

    def reg_value(is_areg: bool, num: int) -> int:
        return a[num] if is_areg else d[num]

    def set_reg(is_areg: bool, num: int, value: int) -> None:
        (a if is_areg else d)[num] = value & MASK32
        placed.add((is_areg, num))

    # Instruction-specific biases, before the placement (a biased register may also serve as an index).
    divisor = None
    if handler in ("divs", "divu"):
        divisor = draw(st.one_of(st.sampled_from((0, 1, 0xFFFF, 2, 0xFFFE, 0x7FFF, 0x8000, 3)),
                                 st.integers(0, 0xFFFF)))
        dst = ops[1].reg
        kind = draw(st.sampled_from(("overflow", "edge", "random", "small")))
        if kind == "overflow":  # quotient does not fit 16 bits
            d[dst] = draw(st.integers(0x10000, MASK32)) if handler == "divu" else draw(st.sampled_from(
                (0x80000000, 0x7FFFFFFF, 0xFFFF0000 | draw(st.integers(0, 0xFFFF)), 0x00008000, 0x40000000)))
        elif kind == "small":
            d[dst] = draw(st.integers(0, 0x7FFF)) * divisor
        src = ops[0]
        if src.mode is Mode.DREG:
            d[src.reg] = (d[src.reg] & 0xFFFF0000) | divisor
        elif src.mode is Mode.IMM:
            ops[0] = Operand(Mode.IMM, 0, divisor)
    if row.operands and row.operands[0].kind == "reg" and handler in SHIFTS:
        count = draw(st.integers(0, 63))
        high = draw(st.sampled_from((0, 0, 0, draw(st.integers(0, (1 << 26) - 1)))))
        d[ops[0].reg] = (high << 6) | count
    # Pass 1: simple address-register modes and absolute / PC-displacement targets.
    for i, op in enumerate(ops):
        spec = row.operands[i]
        if spec.kind not in ("ea", "reg") or op.mode in (Mode.DREG, Mode.AREG, Mode.IMM, Mode.AINDEX, Mode.PCINDEX):
            continue
        t = target(op.mode)
        if op.mode in (Mode.AIND, Mode.APOSTINC, Mode.ADISP, Mode.APREDEC):
            if (True, op.reg) in placed:
                continue
            if op.mode is Mode.APREDEC:
                step = 2 if (op.reg == 7 and nbytes == 1) else nbytes
                value = t + (64 if handler == "movem" else step)
            elif op.mode is Mode.ADISP:
                value = t - op.value
            else:
                value = t
            set_reg(True, op.reg, value)
        elif op.mode in (Mode.ABSW, Mode.ABSL, Mode.PCDISP):
            ops[i] = Operand(op.mode, op.reg, t, op.index)
        fill(t)
    # Pass 2: indexed modes (the index register's value is known once pass 1 is done).
    for i, op in enumerate(ops):
        if op.mode not in (Mode.AINDEX, Mode.PCINDEX):
            continue
        t = target(op.mode)
        idx = op.index
        assert idx is not None
        iv = reg_value(idx.is_areg, idx.num)
        ival = iv if idx.long else ((iv & 0xFFFF) ^ 0x8000) - 0x8000
        if op.mode is Mode.AINDEX:
            same = idx.is_areg and idx.num == op.reg
            if same and (True, op.reg) not in placed:
                # EA = 2*An + d8 has the parity of d8: give d8 the parity of the target (odd or even as wanted)
                if (t - op.value) % 2:
                    op = Operand(op.mode, op.reg, op.value + (1 if op.value < 127 else -1), op.index)
                    ops[i] = op
                set_reg(True, op.reg, (t - op.value) // 2)
            elif (True, op.reg) not in placed:
                set_reg(True, op.reg, t - op.value - ival)
            elif (idx.is_areg, idx.num) not in placed:
                need = t - a[op.reg] - op.value
                if idx.long:
                    set_reg(idx.is_areg, idx.num, need)
                elif -0x8000 <= need <= 0x7FFF:
                    set_reg(idx.is_areg, idx.num, (iv & 0xFFFF0000) | (need & 0xFFFF))
        else:
            base = op.value  # isa.strategies.build put it within d8 reach of the extension word
            need = t - base
            if (idx.is_areg, idx.num) not in placed:
                if idx.long:
                    set_reg(idx.is_areg, idx.num, need)
                else:
                    set_reg(idx.is_areg, idx.num, (iv & 0xFFFF0000) | (need & 0xFFFF))
        fill(t)
    # Instruction-specific biases.
    # Branch targets: isa.strategies keeps them within reach of CODE, i.e. inside the mapped RAM.
    if handler == "rts":
        ret = CODE + draw(st.integers(-0x800, 0x800)) * 2 + (1 if odd else 0)
        targets.append(ret)
        blocks.append((a[7], ret.to_bytes(4, "big")))
    if divisor is not None and ops[0].mode not in (Mode.DREG, Mode.IMM) and blocks:
        blocks.append((blocks[0][0], divisor.to_bytes(2, "big")))  # the source operand's target (placed first)
    instr = Instruction(instr.mnemonic, instr.size, tuple(ops))
    code = encode(instr, pc)
    if odd and handler in ("bcc", "bra", "bsr", "dbcc"):
        code = bytearray(code)
        if instr.size is Size.S:
            code[1] |= 1
        else:
            code[3] |= 1
        code = bytes(code)
    # Brief extension words (d8(An,Xn), d8(PC,Xn)): the 68000 ignores bits 10..8 (the 68020's scale and
    # full-format bits); about half the indexed operands get random bits there (issue 8.1).
    from isa.encoder import extension_offsets

    for op, off in zip(instr.operands, extension_offsets(instr)):
        if op.mode in (Mode.AINDEX, Mode.PCINDEX) and off is not None:
            junk = draw(st.one_of(st.just(0), st.integers(1, 7)))
            if junk:
                code = bytearray(code)
                code[off] |= junk
                code = bytes(code)
    blocks.append((pc, code))
    blocks.append((pc + len(code), NOP.to_bytes(2, "big") * 4))
    image = bytes(base_image(seed, blocks))
    text = format_text(instr)
    if DRAWN is not None:
        DRAWN.append((text, tuple(d), tuple(a), ccr, tuple(targets)))
    return Case(instr, text, code, Machine(d, a, ccr, pc, image))


#: Drawn first by :func:`random_case`: 0 in hypothesis's simplest example only (and rarely in a random one).
_NOT_SIMPLEST = st.integers(0, 0xFFFF)


def random_case(data, row, size: Size | None, mode: Mode | None, **kw) -> Case:
    """``data.draw(cases(row, size, mode, **kw))``, but never hypothesis's simplest example.

    Hypothesis runs the simplest example of a test first (every choice at its minimum: D0-D7 = 0, CCR = 0, the
    same state for every row); with one example per case under the ``ci`` profile that was the only state the
    default run drew, and a wrong ADDX Z rule (Z never cleared) passed every single-example case. Rejecting it
    (``assume``) makes hypothesis go on to a random example, derandomized under ``ci``: one random state per
    example at about the cost of one example (the rejected one draws a single integer)."""
    assume(data.draw(_NOT_SIMPLEST, label="not hypothesis's simplest example") != 0)
    return data.draw(cases(row, size, mode, **kw))


@functools.lru_cache(maxsize=None)
def bus_target(mode: Mode | None) -> st.SearchStrategy[int]:
    """An even address where a word or long access faults on the end of the RAM: the last word or long of the
    RAM (a long there straddles the end), the first unmapped word, or further out (abs.W: ``$FF8000..``)."""
    if mode is Mode.ABSW:
        return st.integers(0xFF8000 // 2, 0xFFFF00 // 2).map(lambda v: v * 2)
    return st.one_of(st.sampled_from((RAM_SIZE - 2, RAM_SIZE - 4, RAM_SIZE, RAM_SIZE + 2, RAM_SIZE + 4)),
                     st.integers(RAM_SIZE // 2, 0x7FFF00).map(lambda v: v * 2))


def bus_combos() -> list[tuple[object, Size | None, Mode | None]]:
    """(row, size, first-EA mode) whose first EA is accessed in memory (or jumped to), for bus-error tests: every
    memory and absolute mode except PC-relative ones (they cannot reach past the RAM from CODE); not LEA/PEA (no
    access at the EA), not JMP/JSR (the chip's prefetch at the target faults inside the jump, ours at the next
    fetch: prefetch is not modelled, docs/isa-oracles.md)."""
    return [(row, size, mode) for row, size, mode in combos()
            if mode in MEMORY_MODES + (Mode.ABSW, Mode.ABSL) and row.handler not in ("lea", "pea", "jmp", "jsr")]


@st.composite
def cmpm_cases(draw) -> Case:
    """CMPM (Ay)+,(Ax)+ with Ay = Ax and A7 (byte steps of 2) drawn often, both pointing at edge-valued data."""
    from isa.encoder import encode

    size = draw(st.sampled_from((Size.B, Size.W, Size.L)))
    ay = draw(st.sampled_from((0, 7, draw(st.integers(0, 7)))))
    ax = draw(st.sampled_from((ay, 7, draw(st.integers(0, 7)))))
    instr = Instruction("cmpm", size, (Operand(Mode.APOSTINC, ay), Operand(Mode.APOSTINC, ax)))
    d = [draw(u32()) for _ in range(8)]
    a = [draw(u32()) for _ in range(8)]
    blocks: list[tuple[int, bytes]] = []
    for r in (ay, ax):
        t = draw(st.integers(DATA_LO + 0x100, DATA_HI - 0x100))
        a[r] = t & ~1 if size is not Size.B or r == 7 else t
        blocks.append((a[r], b"".join(draw(value_of(size.bytes)).to_bytes(size.bytes, "big") for _ in range(2))))
    code = encode(instr, CODE)
    blocks += [(CODE, code), (CODE + len(code), NOP.to_bytes(2, "big") * 4)]
    image = bytes(base_image(draw(st.integers(0, 2**32 - 1)), blocks))
    return Case(instr, format_text(instr), code, Machine(d, a, draw(st.integers(0, 0x1F)), CODE, image))


def format_text(instr: Instruction) -> str:
    """Our formatter's text of ``instr`` (falls back to a plain rendering while isa.formatter is absent)."""
    try:
        from isa.formatter import format_instruction

        return format_instruction(instr)
    except ImportError:
        return repr(instr)


# ------------------------------------------------------------------------------------------ test plumbing


def combos() -> list[tuple[object, Size | None, Mode | None]]:
    """Every (row, size, mode of the first EA operand) of :data:`isa.table.TABLE` (None: the row has no EA)."""
    out: list[tuple[object, Size | None, Mode | None]] = []
    for row in TABLE:
        for size in row.sizes:
            eas = [i for i, spec in enumerate(row.operands) if spec.kind == "ea"]
            if not eas:
                out.append((row, size, None))
                continue
            for mode in sorted(row.allowed_modes(eas[0], size), key=_MODE_ORDER.index):
                out.append((row, size, mode))
    return out


def row_sizes() -> list[tuple[object, Size | None]]:
    """Every (row, size) of :data:`isa.table.TABLE`."""
    return [(row, size) for row in TABLE for size in row.sizes]


def odd_combos() -> list[tuple[object, Size | None, Mode | None]]:
    """(row, size, first-EA mode) where an odd effective address / target must address-error on a 68000: word or
    long memory operands, and jumps, branches and RTS to odd targets. Byte accesses, LEA and PEA (no access at
    the EA) are left out."""
    out = []
    for row, size, mode in combos():
        h = row.handler
        if h in ("bcc", "bra", "bsr", "dbcc", "rts"):
            out.append((row, size, mode))
        elif h in ("jmp", "jsr") and mode is not None:
            out.append((row, size, mode))
        elif h in ("lea", "pea", "scc"):
            continue
        elif mode is not None and (size is None or size_bytes(row, size) > 1):
            spec_modes = [m for m in (mode,) if m in MEMORY_MODES + ABSOLUTE_MODES]
            if spec_modes:
                out.append((row, size, mode))
    return out


def combo_id(combo: tuple) -> str:
    """pytest id of a (row, size[, mode]) tuple, e.g. ``add.l-d16(An)``."""
    row, size = combo[0], combo[1]
    text = row.mnemonic + (f".{size.value}" if size is not None else "")
    text += f"[{row.pattern}]"
    if len(combo) > 2 and combo[2] is not None:
        text += "-" + combo[2].value
    return text


def failure(case: Case, ref_name: str, diffs: list[str], ours: State, ref: State) -> str:
    """The assertion message for a mismatch: instruction (ours and the reference's disassembly), state, diffs."""
    return (f"ours vs {ref_name} disagree\n{describe(case.machine, case.text, case.code)}\n"
            f"  reference disassembly: {ref_disassembly(case.code, case.machine.pc)}\n"
            f"  cycles: ours {ours.cycles}, ref {ref.cycles}\n  " + "\n  ".join(diffs))

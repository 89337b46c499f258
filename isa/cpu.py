"""The MC68000 interpreter: exact results, CCR flags and clock counts for the :mod:`isa` subset.

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
  path (tests/test_isa_blocks.py checks both paths against each other and against m68000-python). Writes to
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

import mmap
import struct
from bisect import bisect_right
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

from isa import timing
from isa.errors import (
    AddressError,
    BusError,
    CPUFault,
    DivideByZero,
    IllegalInstruction,
    IsaError,
    LimitExceeded,
)
from isa.operands import Instruction, Mode, Operand, Size
from isa.program import Program

__all__ = ["CPU", "RunResult", "HANDLERS", "MapError", "CALL_SENTINEL"]

M32 = 0xFFFFFFFF
MASK = {1: 0xFF, 2: 0xFFFF, 4: M32}
SIGN = {1: 0x80, 2: 0x8000, 4: 0x80000000}
BITS = {1: 8, 2: 16, 4: 32}
XF, NF, ZF, VF, CF = 0x10, 0x08, 0x04, 0x02, 0x01

_MAPPED, _WRITABLE, _WRITTEN, _CODE = 1, 2, 4, 8
_FAST_W = _MAPPED | _WRITABLE | _WRITTEN  # a write needs no bookkeeping
_TOP = 1 << 24
_PAD = 8  # bytes past $FFFFFF, never mapped (accesses running off the top are bus errors)
_WRITTEN_TABLE = bytes((1 if b & _WRITTEN else 0) for b in range(256))
_UNMAPPED_TABLE = bytes((0 if b & _MAPPED else 1) for b in range(256))  # flag byte -> 1 if unmapped
_CODE_TABLE = bytes((1 if b & _CODE else 0) for b in range(256))  # flag byte -> 1 if it holds compiled code
_HOST_PLAIN_TABLE = bytes((0 if b & _MAPPED and not b & _CODE else 1) for b in range(256))
_ZEROS = {1: b"\0", 2: b"\0\0", 4: b"\0\0\0\0"}
_LONG = struct.Struct(">L")
#: flag byte -> 0 if a program write there needs nothing but the written mark (mapped, writable, not code)
_FIRST_WRITE_TABLE = bytes((0 if b & (_MAPPED | _WRITABLE | _CODE) == _MAPPED | _WRITABLE else 1) for b in range(256))
_FAST_BYTES = {n: bytes([_FAST_W]) * n for n in (1, 2, 4)}

#: Return address pushed by :meth:`CPU.call`; odd, so it can never be the address of a real instruction.
CALL_SENTINEL = 0xFFFFFF

_M = Mode
_MEMORY_MODES = frozenset(m for m in Mode if m not in (_M.DREG, _M.AREG, _M.IMM, _M.REGLIST))


class MapError(IsaError, ValueError):
    """A bad memory-map request (overlapping, odd or out-of-range region) or a bad host argument."""


class _Fault(Exception):
    """Internal: raised inside compiled code; the run loop turns it into ``cls(message, pc, ...)``."""

    def __init__(self, cls: type[CPUFault], message: str) -> None:
        super().__init__(message)
        self.cls = cls
        self.message = message


class _Stop(Exception):
    """Internal: TRAP #n executed; ``packed`` = next_pc | clocks << 32."""

    def __init__(self, trap: int, packed: int) -> None:
        super().__init__(trap)
        self.trap = trap
        self.packed = packed


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
            return list(self) == list(other)  # type: ignore[call-overload]
        except TypeError:
            return NotImplemented

    def __repr__(self) -> str:
        return "[" + ", ".join(f"${v:08X}" for v in self) + "]"


@dataclass(frozen=True)
class Region:
    """One mapped memory region: ``[start, start + size)``, a name, and whether programs may write it."""

    start: int
    size: int
    name: str
    writable: bool


# ------------------------------------------------------------------------------------------------------------------
# Condition codes: _COND[cc][ccr & 31] -> bool (M68000 PRM table 3-19).
def _cond_value(cc: int, f: int) -> bool:
    n, z, v, c = bool(f & NF), bool(f & ZF), bool(f & VF), bool(f & CF)
    return (
        True, False, not c and not z, c or z, not c, c, not z, z,
        not v, v, not n, n, n == v, n != v, not z and n == v, z or n != v,
    )[cc]  # fmt: skip


_COND: tuple[tuple[bool, ...], ...] = tuple(tuple(_cond_value(cc, f) for f in range(32)) for cc in range(16))


def _sx(v: int, nb: int) -> int:
    """Sign-extend an ``nb``-byte unsigned value to a Python int."""
    s = SIGN[nb]
    return (v & MASK[nb] ^ s) - s


def _nz(r: int, nb: int) -> int:
    """N and Z bits of an ``nb``-byte result."""
    return (NF if r & SIGN[nb] else 0) | (0 if r else ZF)


# ------------------------------------------------------------------------------------------------------------------
# Binary kernels: k(s, d, sr) -> (result masked, new sr). Built per size.
def _k_add(nb: int) -> Callable[[int, int, int], tuple[int, int]]:
    M, S = MASK[nb], SIGN[nb]

    def k(s: int, d: int, sr: int) -> tuple[int, int]:
        r = s + d
        rm = r & M
        f = sr & 0xFF00
        if r > M:
            f |= 0x11
        if rm & S:
            f |= 8
        elif not rm:
            f |= 4
        if (s ^ rm) & (d ^ rm) & S:
            f |= 2
        return rm, f

    return k


def _k_sub(nb: int, keep_x: bool = False) -> Callable[[int, int, int], tuple[int, int]]:
    M, S = MASK[nb], SIGN[nb]
    keep = 0xFF10 if keep_x else 0xFF00
    cbits = 0x01 if keep_x else 0x11

    def k(s: int, d: int, sr: int) -> tuple[int, int]:
        r = d - s
        rm = r & M
        f = sr & keep
        if r < 0:
            f |= cbits
        if rm & S:
            f |= 8
        elif not rm:
            f |= 4
        if (s ^ d) & (d ^ rm) & S:
            f |= 2
        return rm, f

    return k


def _k_addx(nb: int) -> Callable[[int, int, int], tuple[int, int]]:
    M, S = MASK[nb], SIGN[nb]

    def k(s: int, d: int, sr: int) -> tuple[int, int]:
        r = s + d + ((sr >> 4) & 1)
        rm = r & M
        f = sr & 0xFF04  # Z: cleared if the result is nonzero, unchanged otherwise
        if rm:
            f &= ~4
        if r > M:
            f |= 0x11
        if rm & S:
            f |= 8
        if (s ^ rm) & (d ^ rm) & S:
            f |= 2
        return rm, f

    return k


def _k_subx(nb: int) -> Callable[[int, int, int], tuple[int, int]]:
    M, S = MASK[nb], SIGN[nb]

    def k(s: int, d: int, sr: int) -> tuple[int, int]:
        r = d - s - ((sr >> 4) & 1)
        rm = r & M
        f = sr & 0xFF04
        if rm:
            f &= ~4
        if r < 0:
            f |= 0x11
        if rm & S:
            f |= 8
        if (s ^ d) & (d ^ rm) & S:
            f |= 2
        return rm, f

    return k


def _k_logic(nb: int, op: str) -> Callable[[int, int, int], tuple[int, int]]:
    S = MASK[nb] ^ (MASK[nb] >> 1)

    if op == "and":

        def k(s: int, d: int, sr: int) -> tuple[int, int]:
            r = s & d
            return r, (sr & 0xFF10) | (8 if r & S else 0) | (0 if r else 4)

    elif op == "or":

        def k(s: int, d: int, sr: int) -> tuple[int, int]:
            r = s | d
            return r, (sr & 0xFF10) | (8 if r & S else 0) | (0 if r else 4)

    else:

        def k(s: int, d: int, sr: int) -> tuple[int, int]:
            r = s ^ d
            return r, (sr & 0xFF10) | (8 if r & S else 0) | (0 if r else 4)

    return k


_KERNELS: dict[str, Callable[[int], Callable[[int, int, int], tuple[int, int]]]] = {
    "add": _k_add,
    "sub": _k_sub,
    "cmp": lambda nb: _k_sub(nb, keep_x=True),
    "addx": _k_addx,
    "subx": _k_subx,
    "and": lambda nb: _k_logic(nb, "and"),
    "or": lambda nb: _k_logic(nb, "or"),
    "eor": lambda nb: _k_logic(nb, "eor"),
}


# ------------------------------------------------------------------------------------------------------------------
# Shift kernels: k(x, n, sr) -> (result, new sr); x unsigned nb-byte value, n >= 0 the count.
def _k_shift(kind: str, nb: int) -> Callable[[int, int, int], tuple[int, int]]:
    W, M, S = BITS[nb], MASK[nb], SIGN[nb]

    def nz(r: int) -> int:
        return (8 if r & S else 0) | (0 if r else 4)

    if kind == "asl":

        def k(x: int, n: int, sr: int) -> tuple[int, int]:
            if n == 0:
                return x, (sr & 0xFF10) | nz(x)
            if n < W:
                r = (x << n) & M
                c = (x >> (W - n)) & 1
                top = x >> (W - 1 - n)
                v = top != 0 and top != (1 << (n + 1)) - 1
            else:
                r = 0
                c = x & 1 if n == W else 0
                v = x != 0
            return r, (sr & 0xFF00) | (0x11 if c else 0) | nz(r) | (2 if v else 0)

    elif kind == "asr":

        def k(x: int, n: int, sr: int) -> tuple[int, int]:
            if n == 0:
                return x, (sr & 0xFF10) | nz(x)
            sx = (x ^ S) - S
            if n < W:
                r = (sx >> n) & M
                c = (sx >> (n - 1)) & 1
            else:
                r = M if sx < 0 else 0
                c = 1 if sx < 0 else 0
            return r, (sr & 0xFF00) | (0x11 if c else 0) | nz(r)

    elif kind == "lsl":

        def k(x: int, n: int, sr: int) -> tuple[int, int]:
            if n == 0:
                return x, (sr & 0xFF10) | nz(x)
            if n <= W:
                r = (x << n) & M
                c = (x >> (W - n)) & 1
            else:
                r = c = 0
            return r, (sr & 0xFF00) | (0x11 if c else 0) | nz(r)

    elif kind == "lsr":

        def k(x: int, n: int, sr: int) -> tuple[int, int]:
            if n == 0:
                return x, (sr & 0xFF10) | nz(x)
            if n <= W:
                r = x >> n
                c = (x >> (n - 1)) & 1
            else:
                r = c = 0
            return r, (sr & 0xFF00) | (0x11 if c else 0) | nz(r)

    elif kind == "rol":

        def k(x: int, n: int, sr: int) -> tuple[int, int]:
            if n == 0:
                return x, (sr & 0xFF10) | nz(x)
            m = n % W
            r = ((x << m) | (x >> (W - m))) & M
            return r, (sr & 0xFF10) | (r & 1) | nz(r)

    elif kind == "ror":

        def k(x: int, n: int, sr: int) -> tuple[int, int]:
            if n == 0:
                return x, (sr & 0xFF10) | nz(x)
            m = n % W
            r = ((x >> m) | (x << (W - m))) & M
            return r, (sr & 0xFF10) | (1 if r & S else 0) | nz(r)

    elif kind in ("roxl", "roxr"):
        W1 = W + 1
        M1 = (1 << W1) - 1
        left = kind == "roxl"

        def k(x: int, n: int, sr: int) -> tuple[int, int]:
            xb = (sr >> 4) & 1
            m = n % W1
            if m == 0:  # includes n == 0: C = X, X unchanged
                return x, (sr & 0xFF10) | xb | nz(x)
            v = (xb << W) | x
            if left:
                v = ((v << m) | (v >> (W1 - m))) & M1
            else:
                v = ((v >> m) | (v << (W1 - m))) & M1
            r = v & M
            return r, (sr & 0xFF00) | (0x11 if v >> W else 0) | nz(r)

    else:  # pragma: no cover - table and handlers are checked to agree
        raise KeyError(kind)
    return k


# ------------------------------------------------------------------------------------------------------------------
class _Ctx:
    """What a handler builder needs: the register list, memory accessors and the instruction's position."""

    __slots__ = ("R", "rd", "wr", "pc", "nxt", "instr", "cpu", "cond")

    def __init__(self, cpu: CPU, instr: Instruction, pc: int, nxt: int, cond: int | None) -> None:
        self.cpu = cpu
        self.R = cpu._R
        self.rd = cpu._rd
        self.wr = cpu._wr
        self.pc = pc
        self.nxt = nxt
        self.instr = instr
        self.cond = cond


def _inc(op: Operand, nb: int) -> int:
    """Postincrement/predecrement step: the size, except byte access through A7 moves it by 2."""
    return 2 if nb == 1 and op.reg == 7 else nb


def _index_fn(R: list[int], op: Operand) -> Callable[[], int]:
    ix = op.index
    assert ix is not None
    xi = ix.num + (8 if ix.is_areg else 0)
    if ix.long:
        return lambda: R[xi]
    return lambda: ((R[xi] & 0xFFFF) ^ 0x8000) - 0x8000


def _pc_target(pc: int, target: int) -> int:
    """The 32-bit address the 68000 forms for a PC-relative operand whose 24-bit target the decoder reported:
    extension-word address + displacement in 32-bit arithmetic (so a negative wrap gives $FFxxxxxx)."""
    delta = ((target - pc + 0x800000) & 0xFFFFFF) - 0x800000
    return (pc + delta) & M32


def _addr(ctx: _Ctx, op: Operand, nb: int) -> tuple[int | None, Callable[[], int] | None]:
    """Effective address of a memory operand: ``(constant, None)`` or ``(None, fn)``; fn applies (An)+/-(An)."""
    R = ctx.R
    m = op.mode
    r = 8 + op.reg
    if m is _M.AIND:
        return None, lambda: R[r]
    if m is _M.APOSTINC:
        inc = _inc(op, nb)

        def post() -> int:
            a = R[r]
            R[r] = (a + inc) & M32
            return a

        return None, post
    if m is _M.APREDEC:
        dec = _inc(op, nb)

        def pre() -> int:
            a = (R[r] - dec) & M32
            R[r] = a
            return a

        return None, pre
    if m is _M.ADISP:
        d = op.value
        return None, lambda: R[r] + d
    if m is _M.AINDEX:
        d = op.value
        ix = _index_fn(R, op)
        return None, lambda: R[r] + d + ix()
    if m is _M.ABSW:
        return ((op.value & 0xFFFF) ^ 0x8000) - 0x8000 & M32, None
    if m is _M.ABSL:
        return op.value & M32, None
    if m is _M.PCDISP:
        return _pc_target(ctx.pc, op.value), None
    if m is _M.PCINDEX:
        base = _pc_target(ctx.pc, op.value)
        ix = _index_fn(R, op)
        return None, lambda: base + ix()
    raise IllegalInstruction(f"mode {m.value} has no address", pc=ctx.pc)


def _addr_fn(ctx: _Ctx, op: Operand, nb: int) -> Callable[[], int]:
    const, fn = _addr(ctx, op, nb)
    if fn is None:
        c = const
        return lambda: c  # type: ignore[return-value]
    return fn


def _reader(ctx: _Ctx, op: Operand, nb: int) -> Callable[[], int]:
    """A function returning the unsigned ``nb``-byte value of a source operand."""
    R = ctx.R
    M = MASK[nb]
    m = op.mode
    if m is _M.DREG or m is _M.AREG:
        i = op.reg + (8 if m is _M.AREG else 0)
        if nb == 4:
            return lambda: R[i]
        return lambda: R[i] & M
    if m is _M.IMM:
        v = op.value & M
        return lambda: v
    rd = ctx.rd[nb]
    r = 8 + op.reg
    if m is _M.AIND:
        return lambda: rd(R[r])
    if m is _M.ADISP:
        d = op.value
        return lambda: rd(R[r] + d)
    const, fn = _addr(ctx, op, nb)
    if fn is None:
        c = const
        return lambda: rd(c)
    f = fn
    return lambda: rd(f())


def _dreg_writer(R: list[int], i: int, nb: int) -> Callable[[int], None]:
    if nb == 4:

        def w4(v: int) -> None:
            R[i] = v

        return w4
    keep = M32 ^ MASK[nb]

    def w(v: int) -> None:
        R[i] = (R[i] & keep) | v

    return w


def _packed(nxt: int, cycles: int) -> int:
    return (nxt & 0xFFFFFF) | (cycles << 32)


Builder = Callable[[_Ctx], Callable[[], int]]


def _nb(instr: Instruction) -> int:
    return instr.size.bytes if instr.size is not None and instr.size is not Size.S else 2


def _rmw(ctx: _Ctx, dst: Operand, nb: int, kernel: Callable[[int, int, int], tuple[int, int]],
         src: Callable[[], int], cycles: int, write: bool = True) -> Callable[[], int]:
    """Generic ``dst <- kernel(src, dst)`` with flags, for a Dn or memory destination."""
    R = ctx.R
    K = _packed(ctx.nxt, cycles)
    M = MASK[nb]
    if dst.mode is _M.DREG:
        i = dst.reg
        if not write:

            def cmp_d() -> int:
                R[16] = kernel(src(), R[i] & M, R[16])[1]
                return K

            return cmp_d
        keep = M32 ^ M

        def op_d() -> int:
            r, R[16] = kernel(src(), R[i] & M, R[16])
            R[i] = (R[i] & keep) | r
            return K

        return op_d
    rd, wr = ctx.rd[nb], ctx.wr[nb]
    addr = _addr_fn(ctx, dst, nb)
    if not write:

        def cmp_m() -> int:
            s = src()
            R[16] = kernel(s, rd(addr()), R[16])[1]
            return K

        return cmp_m

    def op_m() -> int:
        s = src()
        a = addr()
        r, R[16] = kernel(s, rd(a), R[16])
        wr(a, r)
        return K

    return op_m


# ---------------------------------------------------------------------------------------------------------- handlers
def h_binary(ctx: _Ctx) -> Callable[[], int]:
    """ADD SUB AND OR EOR CMP and their immediate forms ADDI SUBI ANDI ORI EORI CMPI (PRM 4: flags per family;
    ADD/SUB set X = C, CMP leaves X, logic ops clear V and C)."""
    ins = ctx.instr
    h = _handler(ins)
    base = h[:-1] if h.endswith("i") else h
    nb = _nb(ins)
    src_op, dst = ins.operands
    kernel = _KERNELS[base](nb)
    cyc = timing.cycles(ins)
    R = ctx.R
    K = _packed(ctx.nxt, cyc)
    M = MASK[nb]
    # Fast paths: register or immediate source, data register destination, long or word.
    if dst.mode is _M.DREG and src_op.mode in (_M.DREG, _M.IMM) and base in ("add", "sub", "cmp") and nb == 4:
        i = dst.reg
        S = SIGN[4]
        if src_op.mode is _M.IMM:
            k = src_op.value & M32
            if base == "add":

                def addl_i() -> int:
                    d = R[i]
                    r = d + k
                    rm = r & M32
                    R[i] = rm
                    R[16] = ((R[16] & 0xFF00) | (0x11 if r > M32 else 0) | (8 if rm & S else (0 if rm else 4))
                             | (2 if (k ^ rm) & (d ^ rm) & S else 0))
                    return K

                return addl_i
            if base == "sub":

                def subl_i() -> int:
                    d = R[i]
                    r = d - k
                    rm = r & M32
                    R[i] = rm
                    R[16] = ((R[16] & 0xFF00) | (0x11 if r < 0 else 0) | (8 if rm & S else (0 if rm else 4))
                             | (2 if (k ^ d) & (d ^ rm) & S else 0))
                    return K

                return subl_i

            def cmpl_i() -> int:
                d = R[i]
                r = d - k
                rm = r & M32
                R[16] = ((R[16] & 0xFF10) | (1 if r < 0 else 0) | (8 if rm & S else (0 if rm else 4))
                         | (2 if (k ^ d) & (d ^ rm) & S else 0))
                return K

            return cmpl_i
        j = src_op.reg
        if base == "add":

            def addl_r() -> int:
                d = R[i]
                s = R[j]
                r = d + s
                rm = r & M32
                R[i] = rm
                R[16] = ((R[16] & 0xFF00) | (0x11 if r > M32 else 0) | (8 if rm & S else (0 if rm else 4))
                         | (2 if (s ^ rm) & (d ^ rm) & S else 0))
                return K

            return addl_r
        if base == "sub":

            def subl_r() -> int:
                d = R[i]
                s = R[j]
                r = d - s
                rm = r & M32
                R[i] = rm
                R[16] = ((R[16] & 0xFF00) | (0x11 if r < 0 else 0) | (8 if rm & S else (0 if rm else 4))
                         | (2 if (s ^ d) & (d ^ rm) & S else 0))
                return K

            return subl_r

        def cmpl_r() -> int:
            d = R[i]
            s = R[j]
            r = d - s
            rm = r & M32
            R[16] = ((R[16] & 0xFF10) | (1 if r < 0 else 0) | (8 if rm & S else (0 if rm else 4))
                     | (2 if (s ^ d) & (d ^ rm) & S else 0))
            return K

        return cmpl_r
    src = _reader(ctx, src_op, nb)
    del M
    return _rmw(ctx, dst, nb, kernel, src, cyc, write=base != "cmp")


def h_addq(ctx: _Ctx) -> Callable[[], int]:
    """ADDQ/SUBQ #1..8: like ADD/SUB; to An the whole 32-bit register changes and no flags (PRM 4-9, 4-181)."""
    ins = ctx.instr
    sub = _handler(ins) == "subq"
    nb = _nb(ins)
    q, dst = ins.operands
    k = q.value & M32
    cyc = timing.cycles(ins)
    R = ctx.R
    K = _packed(ctx.nxt, cyc)
    if dst.mode is _M.AREG:
        i = 8 + dst.reg
        if sub:

            def subq_a() -> int:
                R[i] = (R[i] - k) & M32
                return K

            return subq_a

        def addq_a() -> int:
            R[i] = (R[i] + k) & M32
            return K

        return addq_a
    if dst.mode is _M.DREG and nb == 4:
        i = dst.reg
        S = SIGN[4]
        if sub:

            def subql_d() -> int:
                d = R[i]
                r = d - k
                rm = r & M32
                R[i] = rm
                R[16] = ((R[16] & 0xFF00) | (0x11 if r < 0 else 0) | (8 if rm & S else (0 if rm else 4))
                         | (2 if d & ~rm & S else 0))
                return K

            return subql_d

        def addql_d() -> int:
            d = R[i]
            r = d + k
            rm = r & M32
            R[i] = rm
            R[16] = ((R[16] & 0xFF00) | (0x11 if r > M32 else 0) | (8 if rm & S else (0 if rm else 4))
                     | (2 if ~d & rm & S else 0))
            return K

        return addql_d
    kernel = (_k_sub if sub else _k_add)(nb)
    kk = k & MASK[nb]
    return _rmw(ctx, dst, nb, kernel, lambda: kk, cyc)


def h_addx(ctx: _Ctx) -> Callable[[], int]:
    """ADDX/SUBX Dy,Dx or -(Ay),-(Ax): X joins the sum; Z cleared if the result is nonzero, else unchanged."""
    ins = ctx.instr
    nb = _nb(ins)
    kernel = (_k_subx if _handler(ins) == "subx" else _k_addx)(nb)
    s_op, d_op = ins.operands
    cyc = timing.cycles(ins)
    R = ctx.R
    K = _packed(ctx.nxt, cyc)
    if s_op.mode is _M.DREG:
        return _rmw(ctx, d_op, nb, kernel, _reader(ctx, s_op, nb), cyc)
    rd, wr = ctx.rd[nb], ctx.wr[nb]
    sa = _addr_fn(ctx, s_op, nb)
    da = _addr_fn(ctx, d_op, nb)

    def addx_m() -> int:
        s = rd(sa())
        a = da()
        r, R[16] = kernel(s, rd(a), R[16])
        wr(a, r)
        return K

    return addx_m


def h_adda(ctx: _Ctx) -> Callable[[], int]:
    """ADDA/SUBA: source sign-extended to 32 bits (.W), whole An changes, flags unaffected (PRM 4-7, 4-179)."""
    ins = ctx.instr
    nb = _nb(ins)
    src_op, dst = ins.operands
    src = _reader(ctx, src_op, nb)
    i = 8 + dst.reg
    R = ctx.R
    K = _packed(ctx.nxt, timing.cycles(ins))
    sub = _handler(ins) == "suba"
    if nb == 2:
        if sub:

            def subaw() -> int:
                v = src()
                R[i] = (R[i] - ((v ^ 0x8000) - 0x8000)) & M32
                return K

            return subaw

        def addaw() -> int:
            v = src()
            R[i] = (R[i] + ((v ^ 0x8000) - 0x8000)) & M32
            return K

        return addaw
    if sub:

        def subal() -> int:
            v = src()
            R[i] = (R[i] - v) & M32
            return K

        return subal

    def addal() -> int:
        v = src()
        R[i] = (R[i] + v) & M32
        return K

    return addal


def h_cmpa(ctx: _Ctx) -> Callable[[], int]:
    """CMPA: An minus the sign-extended source, 32-bit compare; N Z V C set, X unaffected (PRM 4-77)."""
    ins = ctx.instr
    nb = _nb(ins)
    src_op, dst = ins.operands
    src = _reader(ctx, src_op, nb)
    i = 8 + dst.reg
    R = ctx.R
    K = _packed(ctx.nxt, timing.cycles(ins))
    kernel = _k_sub(4, keep_x=True)
    if nb == 2:

        def cmpaw() -> int:
            R[16] = kernel(((src() ^ 0x8000) - 0x8000) & M32, R[i], R[16])[1]
            return K

        return cmpaw

    def cmpal() -> int:
        R[16] = kernel(src(), R[i], R[16])[1]
        return K

    return cmpal


def h_move(ctx: _Ctx) -> Callable[[], int]:
    """MOVE: N Z from the value, V C cleared, X unaffected (PRM 4-116). Source is read before the destination
    address is computed."""
    ins = ctx.instr
    nb = _nb(ins)
    src_op, dst = ins.operands
    R = ctx.R
    K = _packed(ctx.nxt, timing.cycles(ins))
    M = MASK[nb]
    S = SIGN[nb]
    if dst.mode is _M.DREG:
        i = dst.reg
        keep = M32 ^ M
        if src_op.mode is _M.DREG:
            j = src_op.reg
            if nb == 4:

                def movel_rr() -> int:
                    v = R[j]
                    R[i] = v
                    R[16] = (R[16] & 0xFF10) | (8 if v & S else (0 if v else 4))
                    return K

                return movel_rr

            def move_rr() -> int:
                v = R[j] & M
                R[i] = (R[i] & keep) | v
                R[16] = (R[16] & 0xFF10) | (8 if v & S else (0 if v else 4))
                return K

            return move_rr
        src = _reader(ctx, src_op, nb)

        def move_xr() -> int:
            v = src()
            R[i] = (R[i] & keep) | v
            R[16] = (R[16] & 0xFF10) | (8 if v & S else (0 if v else 4))
            return K

        return move_xr
    src = _reader(ctx, src_op, nb)
    wr = ctx.wr[nb]
    const, fn = _addr(ctx, dst, nb)
    if dst.mode in (_M.AIND, _M.ADISP):
        ar = 8 + dst.reg
        disp = dst.value if dst.mode is _M.ADISP else 0
        if src_op.mode is _M.DREG:
            j = src_op.reg

            def move_rd() -> int:
                v = R[j] & M
                R[16] = (R[16] & 0xFF10) | (8 if v & S else (0 if v else 4))
                wr(R[ar] + disp, v)
                return K

            return move_rd

        def move_xd() -> int:
            v = src()
            R[16] = (R[16] & 0xFF10) | (8 if v & S else (0 if v else 4))
            wr(R[ar] + disp, v)
            return K

        return move_xd
    if fn is None:
        c = const

        def move_xc() -> int:
            v = src()
            R[16] = (R[16] & 0xFF10) | (8 if v & S else (0 if v else 4))
            wr(c, v)
            return K

        return move_xc
    addr = fn

    def move_xm() -> int:
        v = src()
        a = addr()
        R[16] = (R[16] & 0xFF10) | (8 if v & S else (0 if v else 4))
        wr(a, v)
        return K

    return move_xm


def h_movea(ctx: _Ctx) -> Callable[[], int]:
    """MOVEA: word source sign-extended to 32 bits, flags unaffected (PRM 4-119)."""
    ins = ctx.instr
    nb = _nb(ins)
    src_op, dst = ins.operands
    src = _reader(ctx, src_op, nb)
    i = 8 + dst.reg
    R = ctx.R
    K = _packed(ctx.nxt, timing.cycles(ins))
    if nb == 2:

        def moveaw() -> int:
            R[i] = (((src() ^ 0x8000) - 0x8000)) & M32
            return K

        return moveaw

    def moveal() -> int:
        R[i] = src()
        return K

    return moveal


def h_moveq(ctx: _Ctx) -> Callable[[], int]:
    """MOVEQ #-128..127,Dn: sign-extended to 32 bits; N Z set, V C cleared (PRM 4-134)."""
    ins = ctx.instr
    v = _sx(ins.operands[0].value & 0xFF, 1) & M32
    i = ins.operands[1].reg
    R = ctx.R
    K = _packed(ctx.nxt, timing.cycles(ins))
    flags = _nz(v, 4)

    def moveq() -> int:
        R[i] = v
        R[16] = (R[16] & 0xFF10) | flags
        return K

    return moveq


def h_unary(ctx: _Ctx) -> Callable[[], int]:
    """CLR NOT NEG NEGX TST (PRM 4: CLR Z=1; NOT logic flags; NEG as 0 - d with X = C; NEGX as 0 - d - X with the
    ADDX/SUBX Z rule; TST N Z, V C cleared)."""
    ins = ctx.instr
    h = _handler(ins)
    nb = _nb(ins)
    dst = ins.operands[0]
    cyc = timing.cycles(ins)
    M = MASK[nb]
    if h == "clr":
        kernel = lambda s, d, sr: (0, (sr & 0xFF10) | ZF)  # noqa: E731
    elif h == "not":
        lk = _k_logic(nb, "eor")
        kernel = lambda s, d, sr: lk(M, d, sr)  # noqa: E731
    elif h == "neg":
        sk = _k_sub(nb)
        kernel = lambda s, d, sr: sk(d, 0, sr)  # noqa: E731
    elif h == "negx":
        xk = _k_subx(nb)
        kernel = lambda s, d, sr: xk(d, 0, sr)  # noqa: E731
    else:  # tst
        lk = _k_logic(nb, "or")
        kernel = lambda s, d, sr: lk(0, d, sr)  # noqa: E731
    return _rmw(ctx, dst, nb, kernel, lambda: 0, cyc, write=h != "tst")


def h_ext(ctx: _Ctx) -> Callable[[], int]:
    """EXT.W (byte -> word, upper word kept) / EXT.L (word -> long): N Z set, V C cleared (PRM 4-106)."""
    ins = ctx.instr
    i = ins.operands[0].reg
    R = ctx.R
    K = _packed(ctx.nxt, timing.cycles(ins))
    if ins.size is Size.W:

        def extw() -> int:
            v = _sx(R[i] & 0xFF, 1) & 0xFFFF
            R[i] = (R[i] & 0xFFFF0000) | v
            R[16] = (R[16] & 0xFF10) | _nz(v, 2)
            return K

        return extw

    def extl() -> int:
        v = _sx(R[i] & 0xFFFF, 2) & M32
        R[i] = v
        R[16] = (R[16] & 0xFF10) | _nz(v, 4)
        return K

    return extl


def h_swap(ctx: _Ctx) -> Callable[[], int]:
    """SWAP Dn: exchange the register halves; N from bit 31, Z from all 32 bits, V C cleared (PRM 4-185)."""
    i = ctx.instr.operands[0].reg
    R = ctx.R
    K = _packed(ctx.nxt, timing.cycles(ctx.instr))

    def swap() -> int:
        v = R[i]
        v = ((v << 16) | (v >> 16)) & M32
        R[i] = v
        R[16] = (R[16] & 0xFF10) | _nz(v, 4)
        return K

    return swap


def h_exg(ctx: _Ctx) -> Callable[[], int]:
    """EXG Rx,Ry: exchange two 32-bit registers, flags unaffected (PRM 4-105)."""
    a, b = ctx.instr.operands
    i = a.reg + (8 if a.mode is _M.AREG else 0)
    j = b.reg + (8 if b.mode is _M.AREG else 0)
    R = ctx.R
    K = _packed(ctx.nxt, timing.cycles(ctx.instr))

    def exg() -> int:
        R[i], R[j] = R[j], R[i]
        return K

    return exg


def h_mul(ctx: _Ctx) -> Callable[[], int]:
    """MULU/MULS <ea>.W,Dn: 16x16 -> 32-bit product in Dn; N Z set, V C cleared; 38+2n clocks + EA (UM 8-4)."""
    ins = ctx.instr
    signed = _handler(ins) == "muls"
    src_op, dst = ins.operands
    src = _reader(ctx, src_op, 2)
    i = dst.reg
    R = ctx.R
    ea = timing.EA_TIME[src_op.mode][0]
    nxt = ctx.nxt & 0xFFFFFF
    tc = timing.muls_cycles if signed else timing.mulu_cycles

    def mul() -> int:
        s = src()
        if signed:
            p = (((s ^ 0x8000) - 0x8000) * (((R[i] & 0xFFFF) ^ 0x8000) - 0x8000)) & M32
        else:
            p = s * (R[i] & 0xFFFF)
        R[i] = p
        R[16] = (R[16] & 0xFF10) | _nz(p, 4)
        return nxt | ((tc(s) + ea) << 32)

    return mul


def h_div(ctx: _Ctx) -> Callable[[], int]:
    """DIVU/DIVS <ea>.W,Dn: Dn = remainder:quotient (remainder takes the dividend's sign). Overflow: V=1, N=1,
    Z=0, C=0 and Dn unchanged (the real chip's undocumented N/Z, as m68000-python and Musashi). Divide by zero
    raises :class:`~isa.errors.DivideByZero`. Clocks per :func:`isa.timing.divu_cycles`/``divs_cycles`` + EA."""
    ins = ctx.instr
    signed = _handler(ins) == "divs"
    src_op, dst = ins.operands
    src = _reader(ctx, src_op, 2)
    i = dst.reg
    R = ctx.R
    ea = timing.EA_TIME[src_op.mode][0]
    nxt = ctx.nxt & 0xFFFFFF
    tc = timing.divs_cycles if signed else timing.divu_cycles
    name = "DIVS" if signed else "DIVU"

    def div() -> int:
        s = src()
        if s == 0:
            raise _Fault(DivideByZero, f"{name} by zero (dividend ${R[i]:08X})")
        d = R[i]
        if signed:
            sd = (d ^ 0x80000000) - 0x80000000
            ss = (s ^ 0x8000) - 0x8000
            q = abs(sd) // abs(ss)
            if (sd < 0) != (ss < 0):
                q = -q
            rem = sd - q * ss
            ok = -0x8000 <= q <= 0x7FFF
        else:
            q, rem = divmod(d, s)
            ok = q <= 0xFFFF
        if ok:
            q &= 0xFFFF
            R[i] = ((rem & 0xFFFF) << 16) | q
            R[16] = (R[16] & 0xFF10) | _nz(q, 2)
        else:
            R[16] = (R[16] & 0xFF10) | NF | VF
        return nxt | ((tc(d, s) + ea) << 32)

    return div


def h_shift(ctx: _Ctx) -> Callable[[], int]:
    """ASL ASR LSL LSR ROL ROR ROXL ROXR: register by #1..8, register by Dn (count mod 64), or memory word by 1.
    Flags: see the kernels (ASL V = MSB changed at any time; count 0 clears C, or sets C = X for ROXL/ROXR;
    X unaffected by ROL/ROR and by a zero count). Clocks 6/8 + 2n (register), 8 + EA (memory) (UM 8-7)."""
    ins = ctx.instr
    h = _handler(ins)
    ops = ins.operands
    R = ctx.R
    if len(ops) == 1:
        kernel = _k_shift(h, 2)
        return _rmw(ctx, ops[0], 2, lambda s, d, sr: kernel(d, 1, sr), lambda: 0, timing.cycles(ins))
    nb = _nb(ins)
    kernel = _k_shift(h, nb)
    M = MASK[nb]
    keep = M32 ^ M
    i = ops[1].reg
    if ops[0].mode is _M.IMM:
        n = ops[0].value
        K = _packed(ctx.nxt, timing.cycles(ins))
        # Fast paths for the common long shifts by an immediate count (1..8 < 32).
        S = SIGN[4]
        if nb == 4 and h == "asr":

            def asrl_i() -> int:
                x = R[i]
                sx = (x ^ S) - S
                r = (sx >> n) & M32
                R[i] = r
                R[16] = ((R[16] & 0xFF00) | (0x11 if (sx >> (n - 1)) & 1 else 0)
                         | (8 if r & S else (0 if r else 4)))
                return K

            return asrl_i
        if nb == 4 and h == "lsr":

            def lsrl_i() -> int:
                x = R[i]
                r = x >> n
                R[i] = r
                R[16] = (R[16] & 0xFF00) | (0x11 if (x >> (n - 1)) & 1 else 0) | (8 if r & S else (0 if r else 4))
                return K

            return lsrl_i
        if nb == 4 and h == "lsl":

            def lsll_i() -> int:
                x = R[i]
                r = (x << n) & M32
                R[i] = r
                R[16] = ((R[16] & 0xFF00) | (0x11 if (x >> (32 - n)) & 1 else 0)
                         | (8 if r & S else (0 if r else 4)))
                return K

            return lsll_i

        def shift_i() -> int:
            r, R[16] = kernel(R[i] & M, n, R[16])
            R[i] = (R[i] & keep) | r
            return K

        return shift_i
    j = ops[0].reg
    nxt = ctx.nxt & 0xFFFFFF
    base = (8 if nb == 4 else 6) << 32

    def shift_r() -> int:
        n = R[j] & 63
        r, R[16] = kernel(R[i] & M, n, R[16])
        R[i] = (R[i] & keep) | r
        return nxt | base + (n << 33)

    return shift_r


def h_scc(ctx: _Ctx) -> Callable[[], int]:
    """Scc <ea>: byte $FF if the condition holds, else $00; flags unaffected. Dn: 6 clocks true, 4 false."""
    ins = ctx.instr
    table = _COND[_cond(ctx)]
    dst = ins.operands[0]
    R = ctx.R
    if dst.mode is _M.DREG:
        i = dst.reg
        Kt = _packed(ctx.nxt, timing.cycles(ins, taken=True))
        Kf = _packed(ctx.nxt, timing.cycles(ins, taken=False))

        def scc_d() -> int:
            if table[R[16] & 31]:
                R[i] |= 0xFF
                return Kt
            R[i] &= 0xFFFFFF00
            return Kf

        return scc_d
    K = _packed(ctx.nxt, timing.cycles(ins))
    wb = ctx.wr[1]
    addr = _addr_fn(ctx, dst, 1)

    def scc_m() -> int:
        wb(addr(), 0xFF if table[R[16] & 31] else 0)
        return K

    return scc_m


def h_bcc(ctx: _Ctx) -> Callable[[], int]:
    """Bcc/BRA: 10 clocks taken; not taken 8 (.S) / 12 (.W) (UM 8-8)."""
    ins = ctx.instr
    target = ins.operands[0].value & 0xFFFFFF
    Kt = _packed(target, timing.cycles(ins, taken=True))
    if _handler(ins) == "bra":
        return _odd_jump(target) if target & 1 else lambda: Kt
    Kf = _packed(ctx.nxt, timing.cycles(ins, taken=False))
    table = _COND[_cond(ctx)]
    R = ctx.R
    if target & 1:
        odd = _odd_jump(target)

        def bcc_odd() -> int:
            return odd() if table[R[16] & 31] else Kf

        return bcc_odd

    def bcc() -> int:
        return Kt if table[R[16] & 31] else Kf

    return bcc


def h_dbcc(ctx: _Ctx) -> Callable[[], int]:
    """DBcc Dn,label: condition true -> fall through (12); else Dn.W -= 1, and branch (10) unless it became -1
    (fall through, 14) (PRM 4-91, UM 8-8). An odd target address-errors whenever the condition is false, also when
    the count expires: the 68000 fetches the target word before it tests the count (the expired case's third
    read cycle in UM 8-8, 14(3/0)); m68000-python, checked against hardware, does the same."""
    ins = ctx.instr
    dn, tgt = ins.operands
    i = dn.reg
    R = ctx.R
    table = _COND[_cond(ctx)]
    Kc = _packed(ctx.nxt, timing.cycles(ins, taken=False))
    Kl = _packed(tgt.value, timing.cycles(ins, taken=True))
    Ke = _packed(ctx.nxt, timing.cycles(ins, expired=True))

    def dbcc() -> int:
        if table[R[16] & 31]:
            return Kc
        v = R[i]
        w = (v - 1) & 0xFFFF
        R[i] = (v & 0xFFFF0000) | w
        if Kl & 1:
            raise _Fault(AddressError, f"branch to odd address ${Kl & 0xFFFFFF:06X}")
        if w == 0xFFFF:
            return Ke
        return Kl

    return dbcc


def _push_fn(ctx: _Ctx) -> Callable[[int], None]:
    R = ctx.R
    wl = ctx.wr[4]

    def push(v: int) -> None:
        a = (R[15] - 4) & M32
        wl(a, v)
        R[15] = a

    return push


def h_bsr(ctx: _Ctx) -> Callable[[], int]:
    """BSR: push the address after the BSR, branch (18 clocks)."""
    ins = ctx.instr
    K = _packed(ins.operands[0].value, timing.cycles(ins))
    ret = ctx.nxt & 0xFFFFFF
    push = _push_fn(ctx)
    if K & 1:
        odd = _odd_jump(K & 0xFFFFFF)

        def bsr_odd() -> int:
            push(ret)
            return odd()

        return bsr_odd

    def bsr() -> int:
        push(ret)
        return K

    return bsr


def h_jmp(ctx: _Ctx) -> Callable[[], int]:
    """JMP <ea> (control modes); clocks per UM Table 8-9."""
    ins = ctx.instr
    const, fn = _addr(ctx, ins.operands[0], 4)
    cyc = timing.cycles(ins) << 32
    if fn is None:
        t = (const or 0) & 0xFFFFFF
        if t & 1:
            return _odd_jump(t)
        K = t | cyc
        return lambda: K
    f = fn

    def jmp() -> int:
        a = f() & 0xFFFFFF
        if a & 1:
            raise _Fault(AddressError, f"jump to odd address ${a:06X}")
        return a | cyc

    return jmp


def _odd_jump(t: int) -> Callable[[], int]:
    def odd() -> int:
        raise _Fault(AddressError, f"branch to odd address ${t:06X}")

    return odd


def h_jsr(ctx: _Ctx) -> Callable[[], int]:
    """JSR <ea>: push the return address, jump; clocks per UM Table 8-9."""
    ins = ctx.instr
    addr = _addr_fn(ctx, ins.operands[0], 4)
    cyc = timing.cycles(ins) << 32
    ret = ctx.nxt & 0xFFFFFF
    push = _push_fn(ctx)

    def jsr() -> int:
        a = addr() & 0xFFFFFF
        if a & 1:
            raise _Fault(AddressError, f"jump to odd address ${a:06X}")
        push(ret)
        return a | cyc

    return jsr


def h_rts(ctx: _Ctx) -> Callable[[], int]:
    """RTS: pop the PC (16 clocks)."""
    R = ctx.R
    rl = ctx.rd[4]
    cyc = timing.cycles(ctx.instr) << 32

    def rts() -> int:
        a = R[15]
        v = rl(a)
        R[15] = (a + 4) & M32
        if v & 1 and (v & 0xFFFFFF) != CALL_SENTINEL:
            raise _Fault(AddressError, f"return to odd address ${v & 0xFFFFFF:06X}")
        return (v & 0xFFFFFF) | cyc

    return rts


def h_lea(ctx: _Ctx) -> Callable[[], int]:
    """LEA <ea>,An: An = the 32-bit effective address; flags unaffected."""
    ins = ctx.instr
    addr = _addr_fn(ctx, ins.operands[0], 4)
    i = 8 + ins.operands[1].reg
    R = ctx.R
    K = _packed(ctx.nxt, timing.cycles(ins))

    def lea() -> int:
        R[i] = addr() & M32
        return K

    return lea


def h_pea(ctx: _Ctx) -> Callable[[], int]:
    """PEA <ea>: push the 32-bit effective address."""
    ins = ctx.instr
    addr = _addr_fn(ctx, ins.operands[0], 4)
    push = _push_fn(ctx)
    K = _packed(ctx.nxt, timing.cycles(ins))

    def pea() -> int:
        push(addr() & M32)
        return K

    return pea


def h_movem(ctx: _Ctx) -> Callable[[], int]:
    """MOVEM: registers to memory in order D0..D7,A0..A7 at increasing addresses, or for -(An) A7..D0 at
    decreasing addresses with An written back to the last address (the 68000 stores An's *initial* value when An
    is in the list); memory to registers D0..A7, words sign-extended to 32 bits, (An)+ written back after the
    loads (overriding a loaded An). Flags unaffected. Clocks 8/12+4n (.W) / +8n (.L) + mode (UM 8-9)."""
    ins = ctx.instr
    nb = _nb(ins)
    R = ctx.R
    K = _packed(ctx.nxt, timing.cycles(ins))
    rd, wr = ctx.rd[nb], ctx.wr[nb]
    M = MASK[nb]
    if ins.operands[0].mode is _M.REGLIST:
        mask, ea = ins.operands[0].value, ins.operands[1]
        regs = [i for i in range(16) if mask >> i & 1]
        if ea.mode is _M.APREDEC:
            an = 8 + ea.reg
            rev = regs[::-1]

            def movem_pre() -> int:
                a = R[an]
                for i in rev:
                    a = (a - nb) & M32
                    wr(a, R[i] & M)
                R[an] = a
                return K

            return movem_pre
        addr = _addr_fn(ctx, ea, nb)

        def movem_r2m() -> int:
            a = addr()
            for i in regs:
                wr(a, R[i] & M)
                a += nb
            return K

        return movem_r2m
    ea, mask = ins.operands[0], ins.operands[1].value
    regs = [i for i in range(16) if mask >> i & 1]
    post = ea.mode is _M.APOSTINC
    an = 8 + ea.reg
    addr = (lambda: R[an]) if post else _addr_fn(ctx, ea, nb)

    def movem_m2r() -> int:
        a = addr()
        for i in regs:
            v = rd(a)
            R[i] = v if nb == 4 else ((v ^ 0x8000) - 0x8000) & M32
            a += nb
        if post:
            R[an] = a & M32
        return K

    return movem_m2r


def h_nop(ctx: _Ctx) -> Callable[[], int]:
    """NOP (4 clocks)."""
    K = _packed(ctx.nxt, timing.cycles(ctx.instr))
    return lambda: K


def h_trap(ctx: _Ctx) -> Callable[[], int]:
    """TRAP #n: stops :meth:`CPU.run` with the PC after the TRAP (no exception processing); counted as the
    manual's 34 clocks."""
    n = ctx.instr.operands[0].value
    K = _packed(ctx.nxt, timing.cycles(ctx.instr))

    def trap() -> int:
        raise _Stop(n, K)

    return trap


def h_illegal(ctx: _Ctx) -> Callable[[], int]:
    """ILLEGAL: raises :class:`~isa.errors.IllegalInstruction`."""

    def illegal() -> int:
        raise _Fault(IllegalInstruction, "ILLEGAL instruction")

    return illegal


#: Handler name (``isa.table.Row.handler``) -> builder of the compiled closure for one instruction.
HANDLERS: dict[str, Builder] = {
    "move": h_move, "movea": h_movea, "moveq": h_moveq, "movem": h_movem, "lea": h_lea, "pea": h_pea,
    "clr": h_unary, "ext": h_ext, "swap": h_swap, "exg": h_exg,
    "add": h_binary, "adda": h_adda, "addi": h_binary, "addq": h_addq, "addx": h_addx,
    "sub": h_binary, "suba": h_adda, "subi": h_binary, "subq": h_addq, "subx": h_addx,
    "neg": h_unary, "negx": h_unary, "cmp": h_binary, "cmpa": h_cmpa, "cmpi": h_binary, "tst": h_unary,
    "and": h_binary, "andi": h_binary, "or": h_binary, "ori": h_binary, "eor": h_binary, "eori": h_binary,
    "not": h_unary,
    "asl": h_shift, "asr": h_shift, "lsl": h_shift, "lsr": h_shift, "rol": h_shift, "ror": h_shift,
    "roxl": h_shift, "roxr": h_shift,
    "muls": h_mul, "mulu": h_mul, "divs": h_div, "divu": h_div,
    "bcc": h_bcc, "bra": h_bcc, "bsr": h_bsr, "dbcc": h_dbcc, "scc": h_scc,
    "jmp": h_jmp, "jsr": h_jsr, "rts": h_rts, "nop": h_nop, "trap": h_trap, "illegal": h_illegal,
}  # fmt: skip


def _handler(instr: Instruction) -> str:
    return timing.handler_name(instr.mnemonic)


def _cond(ctx: _Ctx) -> int:
    if ctx.cond is not None:
        return ctx.cond
    from isa.table import match_mnemonic

    found = match_mnemonic(ctx.instr.mnemonic)
    cond = found[0][1] if found else None
    if cond is None:
        raise IllegalInstruction(f"{ctx.instr.mnemonic}: no condition", pc=ctx.pc)
    return cond


def _lowers_sp(instr: Instruction, h: str) -> bool:
    """True when the instruction may lower A7 (so min_sp must be checked after it)."""
    if h in ("jsr", "bsr", "pea"):
        return True
    for op in instr.operands:
        if op.reg == 7 and op.mode in (_M.AREG, _M.APREDEC):
            return True
    return False


def _format(instr: Instruction) -> str:
    try:
        from isa.formatter import format_instruction

        return format_instruction(instr)
    except Exception:  # formatter missing or unable: fall back to a plain rendering
        ops = ", ".join(f"{o.mode.value}:{o.reg}:{o.value}" for o in instr.operands)
        size = f".{instr.size.value}" if instr.size else ""
        return f"{instr.mnemonic}{size} {ops}".strip()


# ------------------------------------------------------------------------------------------------------------------
# Block compiler: straight-line runs of instructions (continuing past not-taken conditional branches) are turned
# into ONE generated Python function each. See the module docstring ("Speed") for the contract.

#: Most instructions in one compiled block.
BLOCK_MAX = 160
#: Decoding goes on past a BRA/JMP/RTS/... while a branch of the block targets code at most this many bytes after
#: the branch and beyond the transfer (that code may be reached inside the block).
_FORWARD_WINDOW = 512
_RN: tuple[str, ...] = tuple(f"d{i}" for i in range(8)) + tuple(f"a{i}" for i in range(8))
_ALL_FLAGS = 0x1F
_FLAGS_NZVC = 0x0F
#: Flags each condition code reads (PRM table 3-19), for the block compiler's flag liveness.
_COND_USES: tuple[int, ...] = (0, 0, CF | ZF, CF | ZF, CF, CF, ZF, ZF, VF, VF, NF, NF, NF | VF, NF | VF,
                               NF | ZF | VF, NF | ZF | VF)  # fmt: skip
#: Inline Python expression (over the local ``sr``) that is true when condition ``cc`` holds.
_COND_EXPR: tuple[str, ...] = (
    "True", "False", "not sr & 5", "sr & 5", "not sr & 1", "sr & 1", "not sr & 4", "sr & 4",
    "not sr & 2", "sr & 2", "not sr & 8", "sr & 8", "not (sr ^ sr >> 2) & 2", "(sr ^ sr >> 2) & 2",
    "not (sr & 4 | (sr ^ sr >> 2) & 2)", "sr & 4 | (sr ^ sr >> 2) & 2",
)  # fmt: skip
_SHIFT_NAMES = frozenset("asl asr lsl lsr rol ror roxl roxr".split())
_NO_FLAGS = frozenset("movea adda suba lea pea exg movem nop bra bsr jmp jsr rts".split())
_NZVC_DEFS = frozenset("move moveq and andi or ori eor eori not tst clr ext swap muls mulu divs divu cmp cmpi "
                       "cmpa".split())


class _Unblockable(Exception):
    """Internal: this instruction is left to the per-instruction path (the block ends before it)."""


def _flag_effect(ins: Instruction, h: str, cond: int | None) -> tuple[int, int]:
    """(flags read, flags always written) of one instruction, as CCR bit masks."""
    ops = ins.operands
    if h in ("bcc", "scc", "dbcc"):
        return _COND_USES[cond if cond is not None else 0], 0
    if h in _NO_FLAGS or (h in ("addq", "subq") and ops[1].mode is _M.AREG):
        return 0, 0
    if h in _NZVC_DEFS:
        return 0, _FLAGS_NZVC
    if h in ("add", "addi", "addq", "sub", "subi", "subq", "neg"):
        return 0, _ALL_FLAGS
    if h in ("addx", "subx", "negx"):
        return XF | ZF, XF | NF | VF | CF
    if h in _SHIFT_NAMES:
        by_reg = len(ops) == 2 and ops[0].mode is _M.DREG
        uses = XF if h in ("roxl", "roxr") else 0
        if h in ("rol", "ror") or by_reg:
            return uses, _FLAGS_NZVC  # a register count of 0 leaves X (and ROXL/ROXR copy it to C)
        return uses, _ALL_FLAGS
    raise KeyError(h)  # pragma: no cover - every handler is listed above


def _may_fault(ins: Instruction, h: str) -> bool:
    """True when the instruction can raise a CPU fault (memory access, divide, pushes/pops, computed jumps)."""
    if h in ("divs", "divu", "jmp", "jsr", "rts", "bsr", "pea", "movem"):
        return True
    return any(op.mode in _MEMORY_MODES for op in ins.operands)


class _BlockGen:
    """Generates the source of one block function. Registers live in locals ``d0..a7``, the status register in
    ``sr``, data-dependent clocks accumulate in ``c``; every exit writes the registers back and returns
    ``next_pc | instructions << 24 | clocks << 56``."""

    def __init__(self, cpu: CPU) -> None:
        self.cpu = cpu
        self.items: list[tuple[int, object]] = []  # (indent, line str | ("exit", ...) | ("mark", i))
        self.ind = 1
        self.used: set[int] = set()
        self.dirty: set[int] = set()
        self.consts: dict[str, object] = {}
        self.dyn = False

    # ---- emission helpers
    def emit(self, line: str) -> None:
        self.items.append((self.ind, line))

    def const(self, obj: object, hint: str) -> str:
        for k, v in self.consts.items():
            if v is obj:
                return k
        name = f"{hint}_{len(self.consts)}"
        self.consts[name] = obj
        return name

    def rg(self, i: int) -> str:
        self.used.add(i)
        return _RN[i]

    def wg(self, i: int) -> str:
        self.used.add(i)
        self.dirty.add(i)
        return _RN[i]

    def exit(self, target: str | int, n: int, cycles: int) -> None:
        """Leave the block to ``target`` (int or expression) after ``n`` instructions and ``cycles`` clocks (+c)."""
        self.items.append((self.ind, ("exit", target, n, cycles, frozenset(self.dirty))))

    def cycles(self, expr: str) -> None:
        self.dyn = True
        self.emit(f"c += {expr}")

    # ---- operands
    def index_expr(self, op: Operand) -> str:
        ix = op.index
        assert ix is not None
        x = self.rg(ix.num + (8 if ix.is_areg else 0))
        return x if ix.long else f"((({x} & 0xFFFF) ^ 0x8000) - 0x8000)"

    def addr(self, op: Operand, nb: int, pc: int, tmp: str) -> str:
        """Emit the address calculation of a memory operand (with its (An)+/-(An) side effect, in the order the
        per-instruction closures use); return an expression for the (unmasked) address."""
        m = op.mode
        if m is _M.AIND:
            return self.rg(8 + op.reg)
        if m is _M.APOSTINC:
            an = self.wg(8 + op.reg)
            self.emit(f"{tmp} = {an}")
            self.emit(f"{an} = ({tmp} + {_inc(op, nb)}) & 0xFFFFFFFF")
            return tmp
        if m is _M.APREDEC:
            an = self.wg(8 + op.reg)
            self.emit(f"{an} = ({an} - {_inc(op, nb)}) & 0xFFFFFFFF")
            self.emit(f"{tmp} = {an}")
            return tmp
        if m is _M.ADISP:
            return f"({self.rg(8 + op.reg)} + {op.value})"
        if m is _M.AINDEX:
            return f"({self.rg(8 + op.reg)} + {op.value} + {self.index_expr(op)})"
        if m is _M.ABSW:
            return str(((op.value & 0xFFFF) ^ 0x8000) - 0x8000 & M32)
        if m is _M.ABSL:
            return str(op.value & M32)
        if m is _M.PCDISP:
            return str(_pc_target(pc, op.value))
        if m is _M.PCINDEX:
            return f"({_pc_target(pc, op.value)} + {self.index_expr(op)})"
        raise _Unblockable(m)

    def addr_tmp(self, op: Operand, nb: int, pc: int, tmp: str) -> str:
        """Like :meth:`addr` but the address is held in local ``tmp`` (used twice: read-modify-write)."""
        e = self.addr(op, nb, pc, tmp)
        if e != tmp:
            self.emit(f"{tmp} = {e}")
        return tmp

    def read(self, op: Operand, nb: int, pc: int, tmp: str, materialize: bool = False) -> str:
        """Emit what reading a source operand needs; return an expression of its unsigned ``nb``-byte value."""
        M = MASK[nb]
        m = op.mode
        if m is _M.DREG or m is _M.AREG:
            r = self.rg(op.reg + (8 if m is _M.AREG else 0))
            e = r if nb == 4 else f"({r} & {M})"
            if materialize:
                self.emit(f"{tmp} = {e}")
                return tmp
            return e
        if m is _M.IMM:
            if materialize:
                self.emit(f"{tmp} = {op.value & M}")
                return tmp
            return str(op.value & M)
        a = self.addr(op, nb, pc, "ea")
        self.emit(f"{tmp} = {'rb rw _ rl'.split()[nb - 1]}({a})")
        return tmp

    # ---- flag fragments
    def nz(self, v: str, nb: int) -> str:
        return f"(8 if {v} & {SIGN[nb]} else (0 if {v} else 4))"

    def logic_flags(self, v: str, nb: int, need: int) -> None:
        if need & _FLAGS_NZVC:
            self.emit(f"sr = (sr & 0xFF10) | {self.nz(v, nb)}")

    def arith_flags(self, kind: str, nb: int, s: str, d: str, need: int) -> None:
        """ADD/SUB/CMP flags from ``r`` (unmasked result) and ``rm`` (masked); only the bits in ``need``."""
        M, S = MASK[nb], SIGN[nb]
        keep = 0xFF1F
        parts = []
        if need & (CF | (XF if kind != "cmp" else 0)):
            bits = 1 if kind == "cmp" else 0x11
            test = f"r > {M}" if kind == "add" else "r < 0"
            parts.append(f"({bits} if {test} else 0)")
            keep &= ~bits
        if need & (NF | ZF):
            parts.append(self.nz("rm", nb))
            keep &= ~(NF | ZF)
        if need & VF:
            v = f"({s} ^ rm) & ({d} ^ rm)" if kind == "add" else f"({s} ^ {d}) & ({d} ^ rm)"
            parts.append(f"(2 if {v} & {S} else 0)")
            keep &= ~VF
        if kind == "cmp":
            keep |= XF
        if parts:
            self.emit(f"sr = (sr & 0x{keep:04X}) | " + " | ".join(parts))

    def set_dreg(self, i: int, nb: int, v: str) -> None:
        r = self.wg(i)
        if nb == 4:
            last = self.items[-1]
            if v == "rm" and last[0] == self.ind and isinstance(last[1], str) and last[1].startswith("rm = "):
                self.items[-1] = (self.ind, f"{r} = {last[1][5:]}")  # the result goes straight to the register
                return
            self.emit(f"{r} = {v}")
        else:
            self.emit(f"{r} = ({r} & 0x{M32 ^ MASK[nb]:08X}) | {v}")

    def write(self, nb: int, a: str, v: str) -> None:
        self.emit(f"{'wb ww _ wl'.split()[nb - 1]}({a}, {v})")

    def push(self, v: str) -> None:
        """Push the long ``v`` (PEA, BSR, JSR) and lower ``min_sp`` at once: a later instruction of the same
        block (an RTS after a PEA, say) may raise A7 again before the block exits."""
        sp = self.wg(15)
        self.emit(f"eb = ({sp} - 4) & 0xFFFFFFFF")
        self.emit(f"wl(eb, {v})")
        self.emit(f"{sp} = eb")
        self.emit("if eb < MS[0]:")
        self.emit("    MS[0] = eb")

    # ---- one instruction
    def instruction(self, idx: int, ins: Instruction, h: str, cond: int | None, pc: int, nxt: int, need: int,
                    prefix: int) -> tuple[int, bool]:
        """Emit one instruction; return (its clocks on the fall-through path, excluding ``c``, and whether the
        block ends after it). ``idx``/``prefix``: constant instruction count/clocks before it on the path the
        generator is on (the locals ``ni``/``c`` hold the rest)."""
        ops = ins.operands
        nb = _nb(ins)
        M = MASK[nb]
        base = timing.cycles(ins) if h not in ("bcc", "dbcc", "scc", "mulu", "muls", "divu", "divs") \
            and not (h in _SHIFT_NAMES and len(ops) == 2 and ops[0].mode is _M.DREG) else 0
        n_done = idx + 1
        if h == "moveq":
            v = _sx(ops[0].value & 0xFF, 1) & M32
            self.emit(f"{self.wg(ops[1].reg)} = {v}")
            if need & _FLAGS_NZVC:
                self.emit(f"sr = (sr & 0xFF10) | {_nz(v, 4)}")
            return base, False
        if h == "move":
            src, dst = ops
            if dst.mode is _M.DREG:
                v = self.read(src, nb, pc, "v", materialize=nb != 4 or src.mode not in (_M.DREG, _M.AREG))
                self.set_dreg(dst.reg, nb, v)
                self.logic_flags(self.rg(dst.reg) if nb == 4 else v, nb, need)
                return base, False
            v = self.read(src, nb, pc, "v", materialize=True)
            a = self.addr(dst, nb, pc, "eb")
            self.logic_flags(v, nb, need)
            self.write(nb, a, v)
            return base, False
        if h == "movea":
            v = self.read(ops[0], nb, pc, "v")
            an = self.wg(8 + ops[1].reg)
            self.emit(f"{an} = {v}" if nb == 4 else f"{an} = (({v} ^ 0x8000) - 0x8000) & 0xFFFFFFFF")
            return base, False
        if h in ("add", "addi", "sub", "subi", "cmp", "cmpi", "and", "andi", "or", "ori", "eor", "eori",
                 "addq", "subq"):
            kind = h[:-1] if h.endswith(("i", "q")) else h
            src, dst = ops
            if h in ("addq", "subq"):
                k = src.value
                if dst.mode is _M.AREG:
                    an = self.wg(8 + dst.reg)
                    self.emit(f"{an} = ({an} {'+' if kind == 'add' else '-'} {k}) & 0xFFFFFFFF")
                    return base, False
                s = str(k & M)
            else:
                s = self.read(src, nb, pc, "s", materialize=dst.mode is not _M.DREG)
            if dst.mode is _M.DREG:
                dn = self.rg(dst.reg)
                d = dn if nb == 4 else "x"
                if nb != 4:
                    self.emit(f"x = {dn} & {M}")
            else:
                a = self.addr_tmp(dst, nb, pc, "eb")
                d = "x"
                self.emit(f"x = {'rb rw _ rl'.split()[nb - 1]}({a})")
            if kind in ("add", "sub", "cmp"):
                expr = f"{s} + {d}" if kind == "add" else f"{d} - {s}"
                if need & (_ALL_FLAGS if kind != "cmp" else _FLAGS_NZVC):
                    self.emit(f"r = {expr}")
                    self.emit(f"rm = r & {M}")
                    self.arith_flags(kind, nb, s, d, need)
                elif kind == "cmp":
                    return base, False
                else:
                    self.emit(f"rm = ({expr}) & {M}")
            else:
                op = {"and": "&", "or": "|", "eor": "^"}[kind]
                self.emit(f"rm = {s} {op} {d}")
                self.logic_flags("rm", nb, need)
            if kind == "cmp":
                return base, False
            if dst.mode is _M.DREG:
                self.set_dreg(dst.reg, nb, "rm")
            else:
                self.write(nb, "eb", "rm")
            return base, False
        if h in ("adda", "suba"):
            v = self.read(ops[0], nb, pc, "v")
            an = self.wg(8 + ops[1].reg)
            sign = "+" if h == "adda" else "-"
            if nb == 2:
                v = f"((({v}) ^ 0x8000) - 0x8000)"
            self.emit(f"{an} = ({an} {sign} {v}) & 0xFFFFFFFF")
            return base, False
        if h == "cmpa":
            v = self.read(ops[0], nb, pc, "v")
            if nb == 2:
                self.emit(f"s = ((({v}) ^ 0x8000) - 0x8000) & 0xFFFFFFFF")
                v = "s"
            an = self.rg(8 + ops[1].reg)
            if need & _FLAGS_NZVC:
                self.emit(f"r = {an} - {v}")
                self.emit("rm = r & 0xFFFFFFFF")
                self.arith_flags("cmp", 4, v, an, need)
            return base, False
        if h == "lea":
            a = self.addr(ops[0], 4, pc, "ea")
            self.emit(f"{self.wg(8 + ops[1].reg)} = {a} & 0xFFFFFFFF")
            return base, False
        if h == "pea":
            a = self.addr(ops[0], 4, pc, "ea")
            self.emit(f"v = {a} & 0xFFFFFFFF")
            self.push("v")
            return base, False
        if h in ("clr", "not", "neg", "negx", "tst"):
            dst = ops[0]
            if dst.mode is _M.DREG:
                dn = self.rg(dst.reg)
                self.emit(f"x = {dn}" if nb == 4 else f"x = {dn} & {M}")
            else:
                a = self.addr_tmp(dst, nb, pc, "eb")
                self.emit(f"x = {'rb rw _ rl'.split()[nb - 1]}({a})")
            if h == "clr":
                self.emit("rm = 0")
                if need & _FLAGS_NZVC:
                    self.emit("sr = (sr & 0xFF10) | 4")
            elif h == "not":
                self.emit(f"rm = x ^ {M}")
                self.logic_flags("rm", nb, need)
            elif h == "tst":
                self.logic_flags("x", nb, need)
                return base, False
            elif h == "neg":
                self.emit("r = -x")
                self.emit(f"rm = r & {M}")
                self.arith_flags("sub", nb, "x", "0", need)
            else:
                k = self.const(_k_subx(nb), f"negx{nb}")
                self.emit(f"rm, sr = {k}(x, 0, sr)")
            if dst.mode is _M.DREG:
                self.set_dreg(dst.reg, nb, "rm")
            else:
                self.write(nb, "eb", "rm")
            return base, False
        if h in ("addx", "subx"):
            s_op, d_op = ops
            k = self.const((_k_subx if h == "subx" else _k_addx)(nb), f"{h}{nb}")
            if s_op.mode is _M.DREG:
                s = self.read(s_op, nb, pc, "s")
                dn = self.rg(d_op.reg)
                self.emit(f"rm, sr = {k}({s}, {dn if nb == 4 else f'{dn} & {M}'}, sr)")
                self.set_dreg(d_op.reg, nb, "rm")
                return base, False
            sa = self.addr(s_op, nb, pc, "ea")
            self.emit(f"s = {'rb rw _ rl'.split()[nb - 1]}({sa})")
            da = self.addr_tmp(d_op, nb, pc, "eb")
            self.emit(f"rm, sr = {k}(s, {'rb rw _ rl'.split()[nb - 1]}({da}), sr)")
            self.write(nb, "eb", "rm")
            return base, False
        if h == "ext":
            dn = self.wg(ops[0].reg)
            if ins.size is Size.W:
                self.emit(f"v = ((({dn} & 0xFF) ^ 0x80) - 0x80) & 0xFFFF")
                self.emit(f"{dn} = ({dn} & 0xFFFF0000) | v")
                self.logic_flags("v", 2, need)
            else:
                self.emit(f"{dn} = ((({dn} & 0xFFFF) ^ 0x8000) - 0x8000) & 0xFFFFFFFF")
                self.logic_flags(dn, 4, need)
            return base, False
        if h == "swap":
            dn = self.wg(ops[0].reg)
            self.emit(f"{dn} = (({dn} << 16) | ({dn} >> 16)) & 0xFFFFFFFF")
            self.logic_flags(dn, 4, need)
            return base, False
        if h == "exg":
            a, b = (self.wg(o.reg + (8 if o.mode is _M.AREG else 0)) for o in ops)
            self.emit(f"{a}, {b} = {b}, {a}")
            return base, False
        if h in ("mulu", "muls") and ops[0].mode is _M.IMM:  # constant source: constant clocks
            sv = ops[0].value & 0xFFFF
            dn = self.wg(ops[1].reg)
            if h == "muls":
                self.emit(f"{dn} = ({_sx(sv, 2)} * ((({dn} & 0xFFFF) ^ 0x8000) - 0x8000)) & 0xFFFFFFFF")
                x = sv << 1
                extra = 2 * ((x ^ (x >> 1)) & 0xFFFF).bit_count()
            else:
                self.emit(f"{dn} = {sv} * ({dn} & 0xFFFF)")
                extra = 2 * sv.bit_count()
            self.logic_flags(dn, 4, need)
            return 38 + timing.EA_TIME[ops[0].mode][0] + extra, False
        if h in ("mulu", "muls"):
            s = self.read(ops[0], 2, pc, "s", materialize=True)
            dn = self.wg(ops[1].reg)
            if h == "muls":
                self.emit(f"{dn} = ((({s} ^ 0x8000) - 0x8000) * ((({dn} & 0xFFFF) ^ 0x8000) - 0x8000)) "
                          "& 0xFFFFFFFF")
            else:
                self.emit(f"{dn} = {s} * ({dn} & 0xFFFF)")
            self.logic_flags(dn, 4, need)
            if h == "muls":
                self.emit(f"x = {s} << 1")
                self.cycles("2 * ((x ^ (x >> 1)) & 0xFFFF).bit_count()")
            else:
                self.cycles(f"2 * {s}.bit_count()")
            return 38 + timing.EA_TIME[ops[0].mode][0], False
        if h in ("divu", "divs"):
            s = self.read(ops[0], 2, pc, "s", materialize=True)
            dn = self.wg(ops[1].reg)
            name = "DIVS" if h == "divs" else "DIVU"
            fault = self.const(_Fault, "Fault")
            dz = self.const(DivideByZero, "DivideByZero")
            self.emit(f"if {s} == 0:")
            self.emit(f"    raise {fault}({dz}, f\"{name} by zero (dividend ${{{dn}:08X}})\")")
            self.emit(f"d = {dn}")
            if h == "divs":
                self.emit("sd = (d ^ 0x80000000) - 0x80000000")
                self.emit(f"ss = ({s} ^ 0x8000) - 0x8000")
                self.emit("q = abs(sd) // abs(ss)")
                self.emit("if (sd < 0) != (ss < 0):")
                self.emit("    q = -q")
                self.emit("rem = sd - q * ss")
                self.emit("if -0x8000 <= q <= 0x7FFF:")
            else:
                self.emit(f"q, rem = divmod(d, {s})")
                self.emit("if q <= 0xFFFF:")
            self.emit("    q &= 0xFFFF")
            self.emit(f"    {dn} = ((rem & 0xFFFF) << 16) | q")
            self.emit(f"    sr = (sr & 0xFF10) | {self.nz('q', 2)}")
            self.emit("else:")
            self.emit(f"    sr = (sr & 0xFF10) | {NF | VF}")
            tc = self.const(timing.divs_cycles if h == "divs" else timing.divu_cycles, "divc")
            self.cycles(f"{tc}(d, {s})")
            return timing.EA_TIME[ops[0].mode][0], False
        if h in _SHIFT_NAMES:
            return self.shift(ins, h, nb, pc, need, base), False
        if h == "scc":
            dst = ops[0]
            ce = _COND_EXPR[cond]  # type: ignore[index]
            if dst.mode is _M.DREG:
                dn = self.wg(dst.reg)
                self.emit(f"if {ce}:")
                self.emit(f"    {dn} |= 0xFF")
                self.emit("    c += 2")
                self.emit("else:")
                self.emit(f"    {dn} &= 0xFFFFFF00")
                self.dyn = True
                return 4, False
            a = self.addr(dst, 1, pc, "eb")
            self.emit(f"wb({a}, 0xFF if {ce} else 0)")
            return timing.cycles(ins), False
        if h in ("bcc", "bra", "bsr"):
            target = ops[0].value & 0xFFFFFF
            if target & 1:
                raise _Unblockable("odd branch target")
            if h == "bsr":
                self.push(str(nxt & 0xFFFFFF))
                self.exit(target, n_done, prefix + base)
                return base, True
            if h == "bra":
                self.exit(target, n_done, prefix + base)
                return base, True
            self.emit(f"if {_COND_EXPR[cond]}:")  # type: ignore[index]
            self.ind += 1
            self.exit(target, n_done, prefix + timing.cycles(ins, taken=True))
            self.ind -= 1
            return timing.cycles(ins, taken=False), False
        if h == "dbcc":
            dn_op, tgt = ops
            target = tgt.value & 0xFFFFFF
            if target & 1:
                raise _Unblockable("odd branch target")
            ce = _COND_EXPR[cond]  # type: ignore[index]
            if ce == "True":
                return 12, False
            if ce != "False":
                self.emit(f"if not ({ce}):")
                self.ind += 1
            dn = self.wg(dn_op.reg)
            self.emit(f"w = ({dn} - 1) & 0xFFFF")
            self.emit(f"{dn} = ({dn} & 0xFFFF0000) | w")
            self.emit("if w == 0xFFFF:")
            self.emit("    c += 2")
            self.dyn = True
            self.emit("else:")
            self.ind += 1
            self.exit(target, n_done, prefix + timing.cycles(ins, taken=True))
            self.ind -= 1
            if ce != "False":
                self.ind -= 1
            return 12, False
        if h in ("jmp", "jsr"):
            a = self.addr(ops[0], 4, pc, "ea")
            fault = self.const(_Fault, "Fault")
            ae = self.const(AddressError, "AddressError")
            self.emit(f"t = {a} & 0xFFFFFF")
            self.emit("if t & 1:")
            self.emit(f"    raise {fault}({ae}, f\"jump to odd address ${{t:06X}}\")")
            if h == "jsr":
                self.push(str(nxt & 0xFFFFFF))
            self.exit("t", n_done, prefix + base)
            return base, True
        if h == "rts":
            sp = self.wg(15)
            fault = self.const(_Fault, "Fault")
            ae = self.const(AddressError, "AddressError")
            self.emit(f"v = rl({sp})")
            self.emit(f"{sp} = ({sp} + 4) & 0xFFFFFFFF")
            self.emit(f"if v & 1 and (v & 0xFFFFFF) != {CALL_SENTINEL}:")
            self.emit(f"    raise {fault}({ae}, f\"return to odd address ${{v & 0xFFFFFF:06X}}\")")
            self.exit("(v & 0xFFFFFF)", n_done, prefix + base)
            return base, True
        if h == "movem":
            self.movem(ins, nb, pc)
            return base, False
        if h == "nop":
            return base, False
        raise _Unblockable(h)  # trap, illegal: the per-instruction path handles them

    def shift(self, ins: Instruction, h: str, nb: int, pc: int, need: int, base: int) -> int:
        ops = ins.operands
        M, S, W = MASK[nb], SIGN[nb], BITS[nb]
        if len(ops) == 1:  # memory word by 1
            k = self.const(_k_shift(h, 2), f"{h}2")
            a = self.addr_tmp(ops[0], 2, pc, "eb")
            self.emit(f"rm, sr = {k}(rw({a}), 1, sr)")
            self.write(2, "eb", "rm")
            return base
        cnt, dst = ops
        dn = self.rg(dst.reg)
        x = dn if nb == 4 else "x"
        if nb != 4:
            self.emit(f"x = {dn} & {M}")
        if cnt.mode is _M.IMM and h in ("lsl", "lsr", "asr"):
            n = cnt.value
            if h == "lsl":
                self.emit(f"rm = ({x} << {n}) & {M}" if n else f"rm = {x}")
                cexpr = f"{x} >> {W - n} & 1"
            elif h == "lsr":
                self.emit(f"rm = {x} >> {n}")
                cexpr = f"{x} >> {n - 1} & 1"
            else:
                self.emit(f"sx = ({x} ^ {S}) - {S}")
                self.emit(f"rm = (sx >> {n}) & {M}")
                cexpr = f"sx >> {n - 1} & 1"
            if need & _ALL_FLAGS:
                self.emit(f"sr = (sr & 0xFF00) | (0x11 if {cexpr} else 0) | {self.nz('rm', nb)}")
            self.set_dreg(dst.reg, nb, "rm")
            return base
        k = self.const(_k_shift(h, nb), f"{h}{nb}")
        if cnt.mode is _M.IMM:
            self.emit(f"rm, sr = {k}({x}, {cnt.value}, sr)")
            self.set_dreg(dst.reg, nb, "rm")
            return base
        self.emit(f"n = {self.rg(cnt.reg)} & 63")
        self.emit(f"rm, sr = {k}({x}, n, sr)")
        self.set_dreg(dst.reg, nb, "rm")
        self.cycles("n + n")
        return 8 if nb == 4 else 6

    def movem(self, ins: Instruction, nb: int, pc: int) -> None:
        M = MASK[nb]
        rd = "rb rw _ rl".split()[nb - 1]
        if ins.operands[0].mode is _M.REGLIST:
            mask, ea = ins.operands[0].value, ins.operands[1]
            regs = [i for i in range(16) if mask >> i & 1]
            if ea.mode is _M.APREDEC:
                an = 8 + ea.reg
                self.emit(f"ea = {self.rg(an)}")
                for i in regs[::-1]:
                    self.emit(f"ea = (ea - {nb}) & 0xFFFFFFFF")
                    r = self.rg(i)
                    self.write(nb, "ea", r if nb == 4 else f"{r} & {M}")
                self.emit(f"{self.wg(an)} = ea")
                return
            self.addr_tmp(ea, nb, pc, "ea")
            for j, i in enumerate(regs):
                r = self.rg(i)
                self.write(nb, f"ea + {j * nb}" if j else "ea", r if nb == 4 else f"{r} & {M}")
            return
        ea, mask = ins.operands[0], ins.operands[1].value
        regs = [i for i in range(16) if mask >> i & 1]
        post = ea.mode is _M.APOSTINC
        an = 8 + ea.reg
        if post:
            self.emit(f"ea = {self.rg(an)}")
        else:
            self.addr_tmp(ea, nb, pc, "ea")
        for j, i in enumerate(regs):
            a = f"ea + {j * nb}" if j else "ea"
            r = self.wg(i)
            if nb == 4:
                self.emit(f"{r} = {rd}({a})")
            else:
                self.emit(f"{r} = (({rd}({a}) ^ 0x8000) - 0x8000) & 0xFFFFFFFF")
        if post:
            self.emit(f"{self.wg(an)} = (ea + {len(regs) * nb}) & 0xFFFFFFFF")


class _BlockInfo:
    """What the run loop and the fault path need to know about one compiled block."""

    __slots__ = ("start", "pcs", "lines", "prefix", "ncount", "regs")

    def __init__(self, start: int, pcs: list[int], lines: list[int], prefix: list[int], ncount: list[int],
                 regs: list[int]) -> None:
        self.start = start
        self.pcs = pcs  #: address of each instruction
        self.lines = lines  #: first source line of each instruction in the generated code
        self.prefix = prefix  #: constant clocks before each instruction on the path that reaches it (+ local c)
        self.ncount = ncount  #: constant instruction count before each instruction on that path (+ local ni)
        self.regs = regs  #: register indices held in locals


_BLOCK_ENDS = frozenset("bra bsr jmp jsr rts trap illegal".split())


def _blockable(ins: Instruction, h: str) -> bool:
    """False for instructions the block compiler leaves to the per-instruction path: TRAP and ILLEGAL (they stop
    the run or fault), and branches/jumps to a constant odd target (their fault message is the closure's)."""
    if h in ("trap", "illegal"):
        return False
    if h in ("bcc", "bra", "bsr"):
        return not ins.operands[0].value & 1
    if h == "dbcc":
        return not ins.operands[1].value & 1
    if h == "jmp" and ins.operands[0].mode in (_M.ABSW, _M.ABSL, _M.PCDISP):
        return not _addr_const(ins.operands[0]) & 1
    return True


def _addr_const(op: Operand) -> int:
    if op.mode is _M.ABSW:
        return ((op.value & 0xFFFF) ^ 0x8000) - 0x8000 & 0xFFFFFF
    return op.value & 0xFFFFFF


_Entry = tuple[int, Instruction, str, "int | None", int]


def _branch_target(ins: Instruction) -> int:
    return ins.operands[-1].value & 0xFFFFFF


def _plan(entries: list[_Entry]) -> tuple[dict[int, tuple[Any, ...]], list[bool], int | None]:
    """Control flow inside a block. Returns (role of each internal branch by entry index, reachable per entry,
    index of the loop head or None).

    Roles: ``("if", j)`` a Bcc forward to entry ``j`` of the same region (generated as an ``if``);
    ``("ifelse", j, t)`` a Bcc forward to ``j`` where entry ``j-1`` is a BRA forward to ``t`` (``if``/``else``,
    the BRA gets ``("join", t)``); ``("skip", j)`` a BRA forward to ``j`` (the entries between are dead);
    ``("loop",)`` a Bcc/DBcc/BRA back to the loop head (``continue`` of the ``while`` loop that holds the entries
    from the head on; the entries before it run once). The head is the earliest entry a backward branch goes
    to. Any other branch leaves the block when taken. Regions nest: a forward branch is internal only when its
    target does not lie beyond the end of the region (``if`` body, the part before the head) it is in;
    otherwise it is an exit."""
    k = len(entries)
    last_pc, _, _, _, last_len = entries[-1]
    at = {e[0]: i for i, e in enumerate(entries)}
    at[(last_pc + last_len) & 0xFFFFFF] = k
    role: dict[int, tuple[Any, ...]] = {}
    reach = [False] * k
    heads = [at[t] for i, (_, ins, h, cond, _) in enumerate(entries)
             if h in ("bcc", "bra", "dbcc") and not (h == "dbcc" and cond == 0)
             and (t := _branch_target(ins)) in at and at[t] <= i]
    head = min(heads) if heads else None
    start = entries[head][0] if head is not None else -1

    def plan(lo: int, hi: int) -> bool:
        """Plan entries lo..hi-1; True when every path through them leaves the block."""
        i = lo
        while i < hi:
            _, ins, h, cond, _ = entries[i]
            reach[i] = True
            if h in ("bcc", "bra", "dbcc"):
                tgt = _branch_target(ins)
                j = at.get(tgt)
                if tgt == start and i >= head and not (h == "dbcc" and cond == 0):  # type: ignore[operator]
                    role[i] = ("loop",)
                elif h == "bcc" and j is not None and i < j <= hi:
                    if j - 1 > i and entries[j - 1][2] == "bra":
                        t = at.get(_branch_target(entries[j - 1][1]))
                        if t is not None and j < t <= hi:
                            role[i] = ("ifelse", j, t)
                            role[j - 1] = ("join", t)
                            plan(i + 1, j - 1)
                            reach[j - 1] = True
                            plan(j, t)
                            i = t
                            continue
                    role[i] = ("if", j)
                    plan(i + 1, j)
                    i = j
                    continue
                elif h == "bra" and j is not None and i < j <= hi:
                    role[i] = ("skip", j)
                    i = j
                    continue
            if h in _BLOCK_ENDS:
                return True
            i += 1
        return False

    if head is not None and plan(0, head):  # the loop head is never reached: no loop
        role.clear()
        reach = [False] * k
        head, start = None, -1
    if head is None:
        plan(0, k)
    else:
        plan(head, k)
    return role, reach, head


def _liveness(entries: list[_Entry], role: dict[int, tuple[Any, ...]], reach: list[bool], head: int | None
              ) -> list[int]:
    """Flags live after each entry (CCR bit masks): what a later instruction on any path inside the block reads,
    all flags at a block exit and around an instruction that may fault (a fault exposes SR)."""
    k = len(entries)
    need = [_ALL_FLAGS] * k
    live0 = 0
    while True:
        live_in = [_ALL_FLAGS] * (k + 1)
        for i in range(k - 1, -1, -1):
            if not reach[i]:
                continue
            _, ins, h, cond, _ = entries[i]
            r = role.get(i)
            if r is None:
                after = live_in[i + 1]
                if h in _BLOCK_ENDS or h in ("bcc", "dbcc") or _may_fault(ins, h):
                    after = _ALL_FLAGS
            elif r[0] in ("if", "ifelse"):
                after = live_in[i + 1] | live_in[r[1]]
            elif r[0] in ("skip", "join"):
                after = live_in[r[1]]
            else:  # loop
                after = live0 if h == "bra" else live0 | live_in[i + 1]
            uses, defs = _flag_effect(ins, h, cond)
            need[i] = after
            live_in[i] = _ALL_FLAGS if _may_fault(ins, h) else (after & ~defs) | uses
        if head is None or live_in[head] | live0 == live0:
            return need
        live0 |= live_in[head]


def _block_source(cpu: CPU, entries: list[_Entry]
                  ) -> tuple[str, dict[str, object], list[int], list[int], list[int], list[int], bool]:
    """Python source of the block function for ``entries`` ((pc, instruction, handler, cond, length) each, back to
    back in memory). Returns (source, constants, first generated line per entry, constant clocks and constant
    instruction count before each entry on the path that reaches it, registers used, whether it loops)."""
    k = len(entries)
    role, reach, head = _plan(entries)
    need = _liveness(entries, role, reach, head)
    loops = head is not None
    g = _BlockGen(cpu)
    prefix = [0] * k
    ncount = [0] * k
    marks: dict[int, int] = {}
    flow = bool(role)  # dynamic instruction count (local ni) needed

    def mark(i: int, n: int, cy: int) -> None:
        g.items.append((0, ("mark", i)))
        marks[i] = len(g.items)
        prefix[i] = cy
        ncount[i] = n

    def body_start() -> int:
        return len(g.items)

    def close_body(pos: int) -> None:
        if not any(isinstance(t, str) for _, t in g.items[pos:]):
            g.emit("pass")

    def adjust(dn: int, dc: int) -> None:
        pos = body_start()
        if dn:
            g.emit(f"ni += {dn}")
        if dc:
            g.emit(f"c += {dc}")
        close_body(pos)

    def loopback(n: int, cy: int) -> None:
        if n != n_head:
            g.emit(f"ni += {n - n_head}")
        if cy != c_head:
            g.emit(f"c += {cy - c_head}")
        g.emit("if ni <= ln and c < lc:")
        g.emit("    continue")
        g.exit(head_pc, n_head, c_head)

    def gen(lo: int, hi: int, n: int, cy: int) -> tuple[bool, int, int]:
        """Emit entries lo..hi-1 reached with ``n`` instructions and ``cy`` constant clocks done; return (every
        path has left the block, n, cy at ``hi``)."""
        i = lo
        while i < hi:
            pc, ins, h, cond, length = entries[i]
            nxt = (pc + length) & 0xFFFFFF
            mark(i, n, cy)
            r = role.get(i)
            if r is None:
                n_items = len(g.items)
                cyc, ended = g.instruction(n, ins, h, cond, pc, nxt, need[i], cy)
                cy += cyc
                n += 1
                if _lowers_sp(ins, h) and h not in ("pea", "bsr", "jsr"):
                    g.emit(f"if {g.rg(15)} < MS[0]:")
                    g.emit(f"    MS[0] = {g.rg(15)}")
                wrote = any(isinstance(t, str) and t.startswith(("wb(", "ww(", "wl(")) for _, t in g.items[n_items:])
                if wrote and not ended:
                    g.emit("if D[0]:")
                    g.ind += 1
                    g.emit("D[0] = 0")
                    g.exit(nxt, n, cy)
                    g.ind -= 1
                if ended:
                    return True, n, cy
                i += 1
                continue
            kind = r[0]
            taken = timing.cycles(ins, taken=True)
            if kind == "loop":
                g.dyn = True
                if h == "bra":
                    loopback(n + 1, cy + taken)
                    return True, n + 1, cy + taken
                if h == "bcc":
                    g.emit(f"if {_COND_EXPR[cond]}:")  # type: ignore[index]
                    g.ind += 1
                    loopback(n + 1, cy + taken)
                    g.ind -= 1
                    cy += timing.cycles(ins, taken=False)
                else:  # dbcc
                    ce = _COND_EXPR[cond]  # type: ignore[index]
                    if ce != "False":
                        g.emit(f"if {_COND_EXPR[cond ^ 1]}:")  # type: ignore[operator]
                        g.ind += 1
                    dn = g.wg(ins.operands[0].reg)
                    g.emit(f"w = ({dn} - 1) & 0xFFFF")
                    g.emit(f"{dn} = ({dn} & 0xFFFF0000) | w")
                    g.emit("if w == 0xFFFF:")
                    g.emit("    c += 2")
                    g.emit("else:")
                    g.ind += 1
                    loopback(n + 1, cy + taken)
                    g.ind -= 1
                    if ce != "False":
                        g.ind -= 1
                    cy += 12
                n += 1
                i += 1
                continue
            if kind == "skip":
                n += 1
                cy += taken
                i = r[1]
                continue
            not_taken = timing.cycles(ins, taken=False)
            j = r[1]
            g.dyn = True
            if kind == "if" and j == i + 1:
                g.emit(f"if {_COND_EXPR[cond]}:")  # type: ignore[index]
                g.ind += 1
                adjust(0, taken - not_taken)
                g.ind -= 1
                n += 1
                cy += not_taken
                i = j
                continue
            g.emit(f"if {_COND_EXPR[cond ^ 1]}:")  # type: ignore[operator]
            g.ind += 1
            pos = body_start()
            if kind == "if":
                e1, n1, c1 = gen(i + 1, j, n + 1, cy + not_taken)
                close_body(pos)
                g.ind -= 1
                n2, c2 = n + 1, cy + taken
                if e1:
                    n, cy = n2, c2
                else:
                    if (n1, c1) != (n2, c2):
                        g.emit("else:")
                        g.ind += 1
                        adjust(n2 - n1, c2 - c1)
                        g.ind -= 1
                    n, cy = n1, c1
                i = j
                continue
            t = r[2]
            e1, n1, c1 = gen(i + 1, j - 1, n + 1, cy + not_taken)
            if not e1:
                mark(j - 1, n1, c1)
                n1 += 1
                c1 += timing.cycles(entries[j - 1][1])
            close_body(pos)
            g.ind -= 1
            g.emit("else:")
            g.ind += 1
            pos = body_start()
            e2, n2, c2 = gen(j, t, n + 1, cy + taken)
            if not e1 and not e2 and (n1, c1) != (n2, c2):
                adjust(n2 - n1, c2 - c1)
            close_body(pos)
            g.ind -= 1
            if e1 and e2:
                return True, n, cy
            n, cy = (n2, c2) if e1 else (n1, c1)
            i = t
        return False, n, cy

    if head is None:
        ended, n_end, c_end = gen(0, k, 0, 0)
    else:
        head_pc = entries[head][0]
        _, n_head, c_head = gen(0, head, 0, 0)  # the entries before the loop head (never all leave: see _plan)
        g.emit("while True:")
        g.ind += 1
        ended, n_end, c_end = gen(head, k, n_head, c_head)
    if not ended:
        last_pc, _, _, _, last_len = entries[-1]
        g.exit((last_pc + last_len) & 0xFFFFFF, n_end, c_end)
    body: list[str] = []
    dirty = sorted(g.dirty)
    text = [t for _, t in g.items if isinstance(t, str)]
    uses_sr = any("sr" in t for t in text)
    sr_dirty = any("sr = " in t for t in text)
    lines_ = [f"def __make(R, MS, D, rb, rw, rl, wb, ww, wl{''.join(', ' + n for n in g.consts)}):",
            "    def __block(bn, bc, until):"]
    used = sorted(g.used)
    lines_ += [f"        {_RN[r]} = R[{r}]" for r in used]
    if uses_sr:
        lines_.append("        sr = R[16]")
    if g.dyn:
        lines_.append("        c = 0")
    if flow or loops:
        lines_.append("        ni = 0")
    if loops:  # another pass from the head may start only if its worst case fits the budget (see CPU.run)
        lines_.append(f"        ln = (bn if bn < 0x40000000 else 0x40000000) - {k - head + n_head}")
        lines_.append(f"        if until == {head_pc}:")
        lines_.append("            ln = -1")
        lines_.append(f"        lc = bc - {_block_bound(entries[head:]) + c_head}")
    first = len(lines_) + 1
    line_at: dict[int, int] = {}
    sr_so_far = False
    for ind, item in g.items:
        pad = "    " * (ind + 1)
        if isinstance(item, str):
            body.append(pad + item)
            sr_so_far = sr_so_far or "sr = " in item
        elif item[0] == "mark":
            line_at[item[1]] = first + len(body)
        else:
            # Without a loop, code runs in text order: only registers assigned before this exit can differ from R.
            _, target, n, cycles, assigned = item
            for r in dirty:
                if loops or r in assigned:
                    body.append(f"{pad}R[{r}] = {_RN[r]}")
            if sr_dirty and (sr_so_far or loops):
                body.append(f"{pad}R[16] = sr")
            packed = n << 24 | cycles << 56
            expr = str(target | packed) if isinstance(target, int) else f"{target} | {packed}"
            if g.dyn:
                expr += " + (c << 56)"
            if flow or loops:
                expr += " + (ni << 24)"
            body.append(f"{pad}return {expr}")
    lines: list[int] = []
    nxt_line = 1 << 30
    for i in range(k - 1, -1, -1):  # entries never generated (dead) share the next generated entry's line
        nxt_line = line_at.get(i, nxt_line)
        lines.append(nxt_line)
    lines.reverse()
    src = "\n".join(lines_ + body + ["    return __block", ""])
    return src, g.consts, lines, prefix, ncount, used, loops


def _block_bound(entries: list[_Entry]) -> int:
    """Clocks that bound the start of any instruction of one pass through the block: the worst-case clocks of
    every entry but the one with the smallest worst case (a pass never runs an entry twice)."""
    worst = [timing.cycle_range(e[1])[1] for e in entries]
    return sum(worst) - min(worst)


# ------------------------------------------------------------------------------------------------------------------
class CPU:
    """An MC68000 (subset) with a 24-bit, region-mapped, big-endian address space. See the module docstring."""

    #: Use compiled blocks in :meth:`run` (True) or the per-instruction closures only (False). Both give identical
    #: results, counters and faults; blocks are faster. Set it on one CPU, or on the class for every CPU.
    block_compile: bool = True

    def __init__(self, mapped: bool = True) -> None:
        """``mapped=True``: all 16 MiB are RAM. ``mapped=False``: nothing is mapped; call :meth:`map`."""
        # Anonymous mmaps: zero-filled lazily by the OS, so an unused 16 MiB space costs nothing to create.
        self._mem = mmap.mmap(-1, _TOP + _PAD)
        self._flags = mmap.mmap(-1, _TOP + _PAD)
        self._regions: list[Region] = []
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
        self._build_memory()
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

    @property
    def ram_written(self) -> int:
        """Number of distinct bytes written by executed instructions since construction/:meth:`reset_counters`."""
        fl = self._flags
        return sum(fl[r.start : r.start + r.size].translate(_WRITTEN_TABLE).count(1) for r in self._regions)

    def written_ranges(self) -> list[tuple[int, int]]:
        """The bytes counted by :attr:`ram_written`, as sorted ``(start, end_exclusive)`` address ranges."""
        out: list[tuple[int, int]] = []
        for r in self._regions:
            marks = self._flags[r.start : r.start + r.size].translate(_WRITTEN_TABLE)
            i = marks.find(1)
            while i != -1:
                j = marks.find(0, i)
                j = len(marks) if j == -1 else j
                if out and out[-1][1] == r.start + i:
                    out[-1] = (out[-1][0], r.start + j)
                else:
                    out.append((r.start + i, r.start + j))
                i = marks.find(1, j)
        return out

    def reset_counters(self) -> None:
        """Zero ``instructions``, ``cycles``, ``profile``, ``ram_written``; set ``min_sp`` to the current A7."""
        self.instructions = 0
        self.cycles = 0
        self.profile = {}
        self._min_sp[0] = self._R[15]
        fl = self._flags
        table = bytes(b & ~_WRITTEN for b in range(256))
        for r in self._regions:
            fl[r.start : r.start + r.size] = fl[r.start : r.start + r.size].translate(table)

    # ------------------------------------------------------------------------------------------------- memory
    def map(self, start: int, size: int, name: str, writable: bool = True) -> None:
        """Map ``size`` bytes at ``start`` (both even, inside the 24-bit space, not overlapping another region).

        ``writable=False`` makes a ROM: programs writing it get a :class:`~isa.errors.BusError` (the host may still
        write it through :meth:`write`/:meth:`load`)."""
        if not isinstance(start, int) or not isinstance(size, int):
            raise MapError(f"map {name!r}: start and size must be ints, got {start!r}, {size!r}")
        if start < 0 or size <= 0 or start + size > _TOP:
            raise MapError(f"map {name!r}: region ${start:X}+${size:X} is outside the 24-bit address space")
        if start & 1 or size & 1:
            raise MapError(f"map {name!r}: start ${start:X} and size ${size:X} must be even")
        for r in self._regions:
            if start < r.start + r.size and r.start < start + size:
                raise MapError(f"map {name!r}: ${start:06X}..${start + size - 1:06X} overlaps region {r.name!r} "
                               f"${r.start:06X}..${r.start + r.size - 1:06X}")
        self._regions.append(Region(start, size, name, writable))
        self._regions.sort(key=lambda r: r.start)
        value = _MAPPED | (_WRITABLE if writable else 0)
        self._flags[start : start + size] = bytes([value]) * size

    @property
    def regions(self) -> tuple[Region, ...]:
        """The mapped regions, sorted by start address."""
        return tuple(self._regions)

    def region_at(self, address: int) -> Region | None:
        """The region containing ``address`` (24-bit), or None."""
        address &= 0xFFFFFF
        for r in self._regions:
            if r.start <= address < r.start + r.size:
                return r
        return None

    def _build_memory(self) -> None:
        m = self._mem
        fl = self._flags
        slow_write = self._slow_write
        unpack_l, pack_l = _LONG.unpack_from, _LONG.pack_into

        def fault(cls: type[CPUFault], what: str, a: int) -> _Fault:
            return _Fault(cls, f"{what} ${a & 0xFFFFFF:06X}")

        def rb(a: int) -> int:
            a &= 0xFFFFFF
            if fl[a] & 1:
                return m[a]
            raise fault(BusError, "byte read of unmapped address", a)

        def rw(a: int) -> int:
            if a & 1:
                raise fault(AddressError, "word read at odd address", a)
            a &= 0xFFFFFF
            if fl[a] & 1:
                return (m[a] << 8) | m[a + 1]
            raise fault(BusError, "word read of unmapped address", a)

        def rl(a: int) -> int:
            if a & 1:
                raise fault(AddressError, "long read at odd address", a)
            a &= 0xFFFFFF
            if fl[a] & fl[a + 2] & 1:
                return unpack_l(m, a)[0]
            raise fault(BusError, "long read of unmapped address", a + (0 if fl[a] & 1 else 2))

        def wb(a: int, v: int) -> None:
            a &= 0xFFFFFF
            if fl[a] != 7:
                slow_write(a, 1)
            m[a] = v & 0xFF

        def ww(a: int, v: int) -> None:
            if a & 1:
                raise fault(AddressError, "word write at odd address", a)
            a &= 0xFFFFFF
            if fl[a] != 7 or fl[a + 1] != 7:
                slow_write(a, 2)
            m[a] = (v >> 8) & 0xFF
            m[a + 1] = v & 0xFF

        def wl(a: int, v: int) -> None:
            if a & 1:
                raise fault(AddressError, "long write at odd address", a)
            a &= 0xFFFFFF
            if fl[a] != 7 or fl[a + 1] != 7 or fl[a + 2] != 7 or fl[a + 3] != 7:
                slow_write(a, 4)
            pack_l(m, a, v & M32)

        self._rd = {1: rb, 2: rw, 4: rl}
        self._wr = {1: wb, 2: ww, 4: wl}

    def _slow_write(self, a: int, n: int) -> None:
        """A program write that needs bookkeeping: bus errors, first-write marking, code invalidation."""
        fl = self._flags
        if fl[a : a + n].translate(_FIRST_WRITE_TABLE) == _ZEROS[n]:  # writable RAM, no code: mark written
            fl[a : a + n] = _FAST_BYTES[n]
            return
        for b in range(a, a + n):
            f = fl[b]
            if not f & _MAPPED:
                raise _Fault(BusError, f"write to unmapped address ${b:06X}")
            if not f & _WRITABLE:
                r = self.region_at(b)
                raise _Fault(BusError, f"write to read-only region {r.name if r else '?'!r} at ${b:06X}")
        for b in range(a, a + n):
            if fl[b] & _CODE:
                self._invalidate(b)
            fl[b] |= _WRITTEN

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

    def _host_fault(self, cls: type[CPUFault], message: str) -> CPUFault:
        return cls(message, pc=self._pc, instruction="host access")

    def _check_host(self, address: int, n: int, write: bool) -> int:
        if not isinstance(address, int) or not isinstance(n, int) or n < 0:
            raise MapError(f"bad host access address={address!r} length={n!r}")
        a = address & 0xFFFFFF
        if a + n > _TOP:
            raise self._host_fault(BusError, f"host access ${a:06X}+{n} runs past $FFFFFF")
        i = self._flags[a : a + n].translate(_UNMAPPED_TABLE).find(1)
        if i != -1:
            raise self._host_fault(BusError, f"host {'write' if write else 'read'} of unmapped address ${a + i:06X}")
        return a

    def read(self, address: int, size: int) -> int:
        """Read an unsigned big-endian value of ``size`` bytes (1, 2, 4) at ``address`` (host access: no counters;
        unmapped -> BusError, odd word/long -> AddressError)."""
        if size not in (1, 2, 4):
            raise MapError(f"read size must be 1, 2 or 4, not {size!r}")
        if size > 1 and address & 1:
            raise self._host_fault(AddressError, f"host read of {size} bytes at odd address ${address:06X}")
        a = self._check_host(address, size, False)
        return int.from_bytes(self._mem[a : a + size], "big")

    def write(self, address: int, value: int, size: int) -> None:
        """Write ``value`` (masked to ``size`` bytes, big-endian) at ``address``. Host access: ROM regions may be
        written, unmapped ones raise BusError; not counted in :attr:`ram_written`; invalidates compiled code."""
        if size not in (1, 2, 4):
            raise MapError(f"write size must be 1, 2 or 4, not {size!r}")
        if not isinstance(value, int):
            raise MapError(f"host write value {value!r} is not an int")
        if size > 1 and address & 1:
            raise self._host_fault(AddressError, f"host write of {size} bytes at odd address ${address:06X}")
        if isinstance(address, int) and 0 <= address and address + size <= _TOP:
            # Fast path: mapped and holding no compiled code (one translate of the 1..4 flag bytes).
            if self._flags[address : address + size].translate(_HOST_PLAIN_TABLE) == _ZEROS[size]:
                self._mem[address : address + size] = (value & MASK[size]).to_bytes(size, "big")
                return
        self.write_bytes(address, (value & MASK[size]).to_bytes(size, "big"))

    def read_bytes(self, address: int, n: int) -> bytes:
        """``n`` bytes from ``address`` (host access; every byte must be mapped)."""
        a = self._check_host(address, n, False)
        return self._mem[a : a + n]

    def write_bytes(self, address: int, data: bytes) -> None:
        """Copy ``data`` to ``address`` (host access; every byte must be mapped; ROM allowed)."""
        data = bytes(data)
        a = self._check_host(address, len(data), True)
        self._mem[a : a + len(data)] = data
        if self._decoded:
            self._host_invalidate(a, len(data))

    def _host_invalidate(self, a: int, n: int) -> None:
        marks = self._flags[a : a + n].translate(_CODE_TABLE)
        i = marks.find(1)
        if i == -1:
            return
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

                text = "?" if pc & 1 else _format(decode(self._fetch_word, pc).instruction)
            except Exception:  # noqa: BLE001 - unfetchable or illegal: no disassembly
                text = "?"
        src = self.source_map.get(pc)
        where = f"{src.file}:{src.line}" if src is not None else None
        return text, where

    def _fault(self, cls: type[CPUFault], message: str, pc: int) -> CPUFault:
        text, where = self._where(pc)
        return cls(message, pc=pc, instruction=text, source=where)

    def _fetch_word(self, a: int) -> int:
        if a < _TOP and self._flags[a] & _MAPPED:
            return (self._mem[a] << 8) | self._mem[a + 1]
        raise _Fault(BusError, f"instruction fetch from unmapped address ${a:06X}")

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
        from isa.decoder import decode

        try:
            dec = decode(self._fetch_word, pc)
        except _Fault:
            raise
        except CPUFault as exc:
            raise _Fault(type(exc), str(exc).split(" at PC=")[0]) from None
        except IsaError as exc:
            raise _Fault(IllegalInstruction, f"cannot decode: {exc}") from None
        info = self._decoded[pc] = (dec.instruction, dec.length)
        self._meta[pc] = (dec.row.handler, dec.cond)
        fl = self._flags
        for b in range(pc, pc + dec.length):
            fl[b] |= _CODE
        return info

    def _build(self, instr: Instruction, pc: int, length: int, handler: str | None = None,
               cond: int | None = None) -> Callable[[], int]:
        h = handler or timing.handler_name(instr.mnemonic)
        ctx = _Ctx(self, instr, pc, (pc + length) & 0xFFFFFF, cond)
        fn = HANDLERS[h](ctx)
        if _lowers_sp(instr, h):
            R = self._R
            ms = self._min_sp
            inner = fn

            def tracked() -> int:
                r = inner()
                if R[15] < ms[0]:
                    ms[0] = R[15]
                return r

            fn = tracked
        return fn

    def _build_block(self, start: int) -> tuple[Callable[[], int] | None, int, int, int]:
        """Compile (and cache) the block starting at ``start``: instructions up to the first unconditional
        transfer (BRA, BSR, JMP, JSR, RTS) that no earlier forward branch of the block (nor the BRA itself)
        jumps past by at most :data:`_FORWARD_WINDOW` bytes, an instruction left to the per-instruction path
        (TRAP, ILLEGAL, an odd constant branch target, an undecodable word) or :data:`BLOCK_MAX` instructions.
        Control flow inside the block: see :func:`_plan`. Returns the cache entry ``(function or None, most
        instructions in one pass, clock bound of one pass (:func:`_block_bound`), end address)``, so the run loop
        can keep ``max_instructions``/``max_cycles`` exact."""
        entries: list[tuple[int, Instruction, str, int | None, int]] = []
        pc = start
        decoded, meta = self._decoded, self._meta
        pending = -1  # furthest forward branch target so far (within the window)
        # code that keeps rewriting itself: recompiling big blocks each time would cost more than it saves
        most = BLOCK_MAX if self._block_drops.get(start, 0) < 2 else 0
        while len(entries) < most:
            if pc & 1:
                break
            if pc not in decoded:
                try:
                    self._decode_at(pc)
                except _Fault:
                    break
            ins, length = decoded[pc]
            h, cond = meta[pc]
            if not _blockable(ins, h):
                break
            entries.append((pc, ins, h, cond, length))
            if h in ("bcc", "bra", "dbcc") and 0 < _branch_target(ins) - pc <= _FORWARD_WINDOW:
                pending = max(pending, _branch_target(ins))
            if h in _BLOCK_ENDS and pending <= pc:
                break
            pc = (pc + length) & 0xFFFFFF
        if not entries:
            entry: tuple[Callable[[], int] | None, int, int, int] = (None, 0, 0, 0)
            if start in decoded:  # a TRAP/ILLEGAL/odd branch: remember; an unfetchable start: do not
                self._blocks[start] = entry
                self._block_members.setdefault(start, []).append(start)
            return entry
        src, consts, lines, prefix, ncount, regs, _ = _block_source(self, entries)
        ns: dict[str, Any] = {}
        exec(compile(src, f"<block ${start:06X}>", "exec"), ns)  # noqa: S102 - our own generated source
        rd, wr = self._rd, self._wr
        fn = ns["__make"](self._R, self._min_sp, self._smc, rd[1], rd[2], rd[4], wr[1], wr[2], wr[4], *consts.values())
        last_pc, _, _, _, last_len = entries[-1]
        entry = (fn, len(entries), _block_bound(entries), last_pc + last_len)
        self._blocks[start] = entry
        self._block_code[fn.__code__] = _BlockInfo(start, [e[0] for e in entries], lines, prefix, ncount, regs)
        for e in entries:
            self._block_members.setdefault(e[0], []).append(start)
        return entry

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
        maxn = (1 << 62) if max_instructions is None else int(max_instructions)
        maxc = (1 << 62) if max_cycles is None else int(max_cycles)
        until = -1 if until_pc is None else until_pc & 0xFFFFFF
        cache = self._cache
        compile_ = self._compile
        pc = self._pc
        start_pc = pc
        n = 0
        cyc = 0
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
        return RunResult(reason, trap, n, cyc, pc)

    def call(self, address: int, max_cycles: int | None = 10_000_000,
             max_instructions: int | None = None) -> int:
        """Call the subroutine at ``address`` as JSR would (push :data:`CALL_SENTINEL` as the return address), run
        until its RTS returns there, restore PC, and return the clocks from its first instruction up to and
        including that RTS (the JSR itself is not counted). A TRAP or limit inside raises a CPUFault."""
        saved_pc = self._pc
        R = self._R
        sp = (R[15] - 4) & M32
        try:
            self._wr[4](sp, CALL_SENTINEL)
        except _Fault as fault:
            raise self._fault(fault.cls, f"call(${address:06X}): cannot push the return address: "
                              f"{fault.message}", self._pc) from None
        R[15] = sp
        if sp < self._min_sp[0]:
            self._min_sp[0] = sp
        self._pc = address & 0xFFFFFF
        res = self.run(max_instructions=max_instructions, max_cycles=max_cycles, until_pc=CALL_SENTINEL)
        if res.reason != "until_pc":
            raise self._fault(CPUFault, f"call(${address:06X}) stopped by TRAP #{res.trap_number} before "
                              "returning", (self._pc - 2) & 0xFFFFFF)
        self._pc = saved_pc
        return res.cycles

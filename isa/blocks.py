"""The block compiler: a run of decoded instructions becomes the source of ONE generated Python function.

Contract with :mod:`isa.cpu` (which decodes, caches and runs blocks):

* Input: ``entries``, a list of ``(pc, instruction, handler name, condition or None, length)`` back to back in
  memory, each accepted by :func:`_blockable`, and the :class:`isa.memory.MapFacts` of the CPU's map.
  :func:`compile_block` returns ``(bind, info)``: ``bind(R, MS, D, memory)`` binds the block to one CPU (``R``
  its 17-register list, ``MS`` its one-element ``min_sp`` list, ``D`` its one-element "compiled code was
  written" flag, ``memory`` its :class:`isa.memory.Memory`) and returns ``block(bn, bc, until) -> next_pc |
  instructions << 24 | clocks << 56`` where ``bn``/``bc`` are the instruction/clock budget left and ``until``
  the ``until_pc`` (-1: none). ``info`` (:class:`_BlockInfo`) maps each line of the generated code back to its
  instruction, so that a fault inside the block can be unwound exactly (:meth:`isa.cpu.CPU._unwind_block`). The
  generated source depends only on the entries and the map facts, so ``bind`` may be shared by every CPU that
  holds the same code at the same address under the same map (:mod:`isa.codecache`).
* Memory: reads of constant addresses the map guarantees go straight to ``memory.mem``; other reads are
  span-checked inline; writes look at the aligned flag bytes once (``flags16``/``flags32``); anything else calls
  the exact accessor, which raises the fault (docs/isa-internals.md, "Fast memory ...").
* Semantics: registers live in locals (``d0..a7``, ``sr``), operands, addresses and clock constants are literals,
  CCR flags are computed only where a later instruction, a block exit or a possible fault can observe them
  (:func:`_liveness`). Control flow inside a block (:func:`_plan`): a Bcc forward inside the same region becomes
  an ``if`` (``if``/``else`` when the skipped code ends in a BRA forward), a BRA forward skips code, a branch back
  to the loop head becomes the ``continue`` of a ``while`` loop bounded by the remaining budget and ``until``;
  any other branch leaves the block. Clocks and instruction counts are folded per path (locals ``c``/``ni`` hold
  what differs); flags only a fault could see are assigned on the faulting slow paths only (:func:`_defer_flags`);
  in a loop, an ADD/SUB's flags may be kept as its result and source and computed only on the exits and the
  slow memory paths (:func:`_lazy_kind`).
  A memory write that hits compiled code sets ``D[0]`` (in the memory accessor); the block then leaves right
  after that instruction, unless the write was to a constant address outside the block's own code
  (:func:`_quiet_write`: this block's instructions did not change). Instructions the block compiler does not take (TRAP, ILLEGAL, constant
  odd branch targets) end the block; the CPU runs them through :mod:`isa.closures`.
* The run loop starts a block only when ``bn >= info's most instructions`` and ``bc >`` the clock bound of one
  pass (:func:`_block_bound`) and ``until`` is not inside it: that keeps limits exact.
"""

from __future__ import annotations

import re
import struct
from typing import Any

from isa import codecache, timing
from isa.errors import AddressError, DivideByZero
from isa.operands import Instruction, Operand, Size
from isa.memory import MapFacts
from isa.semantics import (BITS, CALL_SENTINEL, CF, M32, MASK, NF, SIGN, VF, XF, ZF, _M, _MEMORY_MODES, _Fault,
                           _inc, _k_addx, _k_shift, _k_subx, _lowers_sp, _nb, _nz, _pc_target, _sx)

__all__ = ["BLOCK_MAX", "block_entries", "compile_block"]

_UL, _PL = struct.Struct(">L").unpack_from, struct.Struct(">L").pack_into
_UW, _PW = struct.Struct(">H").unpack_from, struct.Struct(">H").pack_into
#: An address expression ``(<register local> + <displacement >= 0>)`` (d16(An) with d16 >= 0): never negative.
_REG_PLUS_DISP = re.compile(r"\([ad][0-7] \+ \d+\)\Z")


#: Most instructions in one compiled block.
BLOCK_MAX = 320
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
                       "cmpa cmpm".split())


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


#: Constant-address modes (the address is known when compiling).
_CONST_MODES = frozenset((_M.ABSW, _M.ABSL, _M.PCDISP))
#: Handlers that only read their last operand (every other handler with a memory destination writes it).
_READ_ONLY_DST = frozenset("cmp cmpi cmpa cmpm tst".split())


def _const_addr(op: Operand, pc: int) -> int:
    """The 32-bit address of a constant-address operand (as :meth:`_BlockGen.addr` forms it)."""
    if op.mode is _M.ABSW:
        return ((op.value & 0xFFFF) ^ 0x8000) - 0x8000 & M32
    if op.mode is _M.ABSL:
        return op.value & M32
    return _pc_target(pc, op.value)


#: Handlers whose faults are not all through the memory accessors, or that read flags or end/branch the block.
_NO_DEFER = frozenset("divs divu jmp jsr rts bsr pea movem bcc bra dbcc scc trap illegal".split())


def _defer_flags(entries: list[_Entry], i: int, hi: int, role: dict[int, tuple[Any, ...]], targets: set[int]
                 ) -> bool:
    """True when entry ``i``'s NZVC flags (from a value, as MOVE/TST/AND... set them) may be set on the faulting
    paths only: the next entry follows it in straight line (no internal branch role, not a branch target, inside
    the region being generated), reads no flag and sets all of N, Z, V and C, and its only faults are memory
    accesses (whose slow paths assign the deferred SR first); entry ``i`` itself writes memory at most once, as
    its last action (its slow path also assigns SR first) and does not lower A7."""
    j = i + 1
    if j >= hi or i in role or j in role or j in targets:
        return False
    _, ins, h, cond, _ = entries[i]
    _, kins, kh, kcond, _ = entries[j]
    if h in _NO_DEFER or kh in _NO_DEFER or _lowers_sp(ins, h):
        return False
    uses, defs = _flag_effect(kins, kh, kcond)
    return not uses and defs & _FLAGS_NZVC == _FLAGS_NZVC


def _quiet_write(address: int, n: int, facts: MapFacts, code: tuple[int, int]) -> bool:
    """True when an ``n``-byte write at the constant ``address`` can never fault and never touches the block's
    own code ``[code[0], code[1])``: it needs no fault path and no "leave the block" check (a write that hits
    other compiled code drops that code; this block's instructions stay what they are)."""
    a = address & 0xFFFFFF
    return facts.writable(address, n) and (a + n <= code[0] or a >= code[1])


def _may_fault(ins: Instruction, h: str, facts: MapFacts | None = None, pc: int = 0,
               code: tuple[int, int] = (0, 1 << 24)) -> bool:
    """True when the instruction can raise a CPU fault (memory access, divide, pushes/pops, computed jumps) or
    leave the block after a write to its own code. With ``facts``, a read of a constant address that the memory
    map guarantees (:class:`MapFacts`) does not count, nor does a write to such an address outside the block's
    code ``code`` (:func:`_quiet_write`), DIVU/DIVS by a nonzero immediate, LEA, or JMP to a constant (even)
    address."""
    ops = ins.operands
    if h in ("bcc", "bra", "dbcc"):  # the operand is the branch target (even: _blockable), not a memory access
        return False
    if h in ("jsr", "rts", "bsr", "pea", "movem"):
        return True
    if h in ("divs", "divu") and not (ops[0].mode is _M.IMM and ops[0].value & 0xFFFF):
        return True
    if h == "jmp":
        return ops[0].mode not in _CONST_MODES
    if h == "lea":
        return False
    nb = _nb(ins)
    for k, op in enumerate(ops):
        if op.mode not in _MEMORY_MODES:
            continue
        if facts is None or op.mode not in _CONST_MODES:
            return True
        n = 2 if h in _SHIFT_NAMES else nb
        if k == len(ops) - 1 and h not in _READ_ONLY_DST:
            if not _quiet_write(_const_addr(op, pc), n, facts, code):
                return True  # may fault, or may rewrite this block (which then leaves right after it)
        elif not facts.readable(_const_addr(op, pc), n):
            return True
    return False


class _BlockGen:
    """Generates the source of one block function. Registers live in locals ``d0..a7``, the status register in
    ``sr``, data-dependent clocks accumulate in ``c``; every exit writes the registers back and returns
    ``next_pc | instructions << 24 | clocks << 56``."""

    def __init__(self, facts: MapFacts, code: tuple[int, int] = (0, 1 << 24)) -> None:
        self.facts = facts
        self.code = code  # the block's own code bytes [start, end)
        self.known: dict[int, int] = {}
        self.wrote = False  # set by write(): the instruction writes memory; check D[0] after it
        self.u32: set[str] = set()  # temporaries of this instruction known to hold a masked 32-bit address
        # Deferred flags (set by gen() for an instruction whose NZVC only a fault of itself or of the next
        # instruction can observe): ``pending`` is the SR expression the slow (faulting) paths assign first.
        self.defer = False
        self.pending: str | None = None
        self.pending_nz = ""  # the N/Z part of ``pending`` (over ``pf``)
        self.pending_from = -1
        # Lazy flags across the loop edge (_lazy_kind): (kind, nb) of the block's ADD/SUB whose flags are kept as
        # ``lr`` (unmasked result) and ``ls`` (source) instead of being computed; ``lr is None`` when ``sr`` holds
        # them. ``lazy_x`` is the expression of the true SR; ``slow_texts`` the SR assignments made on slow paths.
        self.lazy: tuple[str, int] | None = None
        self.lazy_x = "sr"
        self.slow_texts: set[str] = set()
        self.cur = -1
        self.smc_inline = False  # set by gen(): a last write may leave the block right after it (smc_slots)
        self.smc_slots: list[int] = []  # item indices to fill with the exit after the instruction  # data register -> value known here (set by gen() for one instruction)
        self.items: list[tuple[int, object]] = []  # (indent, line str | ("exit", ...) | ("mark", i))
        self.ind = 1
        self.used: set[int] = set()
        self.dirty: set[int] = set()
        self.consts: dict[str, object] = {}
        self.recipes: dict[str, tuple[Any, ...]] = {}
        self.dyn = False

    # ---- emission helpers
    def emit(self, line: str) -> None:
        if self.pending is not None and self.cur != self.pending_from and line.startswith(("sr = ", "rm, sr = ")):
            self.pending = None  # the next instruction sets all the flags the deferred ones were (see gen)
        self.items.append((self.ind, line))

    def const(self, obj: object, hint: str, recipe: tuple[Any, ...]) -> str:
        """The name under which the generated code sees ``obj``; ``recipe`` makes it again (:func:`_make_const`:
        the disk cache of compiled blocks stores recipes, not objects)."""
        for k, v in self.consts.items():
            if v is obj:
                return k
        name = f"{hint}_{len(self.consts)}"
        self.consts[name] = obj
        self.recipes[name] = recipe
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

    def slow_sr(self) -> str | None:
        """The SR expression a slow (possibly faulting) path assigns before calling the accessor, or None: the
        deferred flags (``pending``) and, in a lazy block, the lazy ADD/SUB flags under them."""
        if self.lazy is None:
            return self.pending
        if self.pending is None:
            return self.lazy_x
        return f"({self.lazy_x} & 0xFF10) | {self.pending_nz}"

    def set_lazy(self, kind: str, nb: int) -> None:
        """Turn on lazy ADD/SUB flags for this block (see :func:`_lazy_kind`)."""
        M, b = MASK[nb], BITS[nb]
        rm = f"(lr & {M})"
        if kind == "add":
            cx, d = f"(17 if lr > {M} else 0)", "(lr - ls)"
        else:
            cx, d = "(17 if lr < 0 else 0)", "(lr + ls)"
        v = f"(ls ^ {rm}) & ({d} ^ {rm})" if kind == "add" else f"(ls ^ {d}) & ({d} ^ {rm})"
        mat = f"(sr & 0xFF00) | {cx} | ({rm} >> {b - 4} & 8 if {rm} else 4) | (({v}) >> {b - 2} & 2)"
        self.lazy = (kind, nb)
        self.lazy_x = f"(sr if lr is None else {mat})"

    def slow_assign(self, sx: str, pad: str = "") -> None:
        """Emit ``sr = sx`` on a slow path (and, in a lazy block, mark the lazy flags as taken into ``sr``)."""
        self.emit(f"{pad}sr = {sx}")
        self.slow_texts.add(f"sr = {sx}")
        if self.lazy is not None:
            self.emit(f"{pad}lr = None")

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
            k = _inc(op, nb)  # one addition, no mask, unless it wraps
            self.emit(f"{an} = {tmp} + {k} if {tmp} < {(1 << 32) - k} else {tmp} - {(1 << 32) - k}")
            self.u32.add(tmp)
            return tmp
        if m is _M.APREDEC:
            an = self.wg(8 + op.reg)
            k = _inc(op, nb)  # one subtraction, no mask, unless it wraps
            self.emit(f"{an} = {an} - {k} if {an} >= {k} else {an} + {(1 << 32) - k}")
            self.emit(f"{tmp} = {an}")
            self.u32.add(tmp)
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
        self.emit(f"{tmp} = {self.load(nb, a)}")
        return tmp

    # ---- memory
    def load(self, nb: int, a: str) -> str:
        """An expression reading ``nb`` bytes at address expression ``a`` (32-bit, unmasked). A constant address
        the map guarantees is read straight from memory; any other address is checked against the largest mapped
        span inline and read straight from memory when inside it, else through the exact accessor (which raises
        the fault)."""
        fn = "rb rw _ rl".split()[nb - 1]
        sx = self.slow_sr()
        if sx is None:
            slow = f"{fn}({a})"
        elif self.lazy is None:
            slow = f"(sr := {sx}, {fn}({a}))[1]"
        else:
            slow = f"(sr := {sx}, lr := None, {fn}({a}))[2]"
            self.slow_texts.add(f"sr := {sx}")
        if a.isdigit():
            v = int(a)
            if self.facts.readable(v, nb):
                t = v & 0xFFFFFF
                return (f"m[{t}]", f"(m[{t}] << 8 | m[{t + 1}])", "", f"UL(m, {t})[0]")[nb - 1]
            return slow
        lo, hi = self.facts.span
        if hi - lo < nb:
            return slow
        if a in self.u32 or a in _RN:  # a local holding 0..2^32-1: the span comparison needs no mask
            odd = "" if nb == 1 else f"not {a} & 1 and "
            rng = f"{a} <= {hi - nb}" if lo == 0 else f"{lo} <= {a} <= {hi - nb}"
            val = (f"m[{a}]", f"(m[{a}] << 8 | m[{a} + 1])", "", f"UL(m, {a})[0]")[nb - 1]
            return f"({val} if {odd}{rng} else {slow})"
        # Any other address (d16(An), d8(An,Xn), d8(PC,Xn)) is computed once, unmasked, into _t: inside the span
        # it is the 24-bit address itself (the span lies in 0..2^24-1); outside (negative, or at/above 2^24, where
        # the 68000 wraps) it takes the accessor, which masks. Only a register plus a displacement >= 0 cannot
        # be negative, so only it may skip the lower bound when the span starts at 0.
        nonneg = lo == 0 and _REG_PLUS_DISP.match(a) is not None
        if nb == 1:
            rng = f"(_t := {a}) <= {hi - nb}" if nonneg else f"{lo} <= (_t := {a}) <= {hi - nb}"
        else:
            rng = f"not (_t := {a}) & 1 and " + (f"_t <= {hi - nb}" if nonneg else f"{lo} <= _t <= {hi - nb}")
        val = ("m[_t]", "(m[_t] << 8 | m[_t + 1])", "", "UL(m, _t)[0]")[nb - 1]
        return f"({val} if {rng} else {slow})"

    def write(self, nb: int, a: str, v: str, last: bool = False) -> None:
        """Emit a write of the ``nb``-byte value ``v`` (already masked) at address expression ``a``: straight
        into memory when one look at the (aligned) flag bytes says mapped, writable and holding no code (marking
        them written on a first write), else through the exact accessor (faults, code invalidation, mixed or
        misaligned flag bytes). ``last``: the write is the instruction's last action, so a write that hit
        compiled code (``D[0]``) can leave the block right there (:attr:`smc_slots`); otherwise the block
        checks ``D[0]`` after the instruction (:attr:`wrote`)."""
        fn = "wb ww _ wl".split()[nb - 1]
        const = a.isdigit()
        if const and not self.facts.writable(int(a), nb):
            sx = self.slow_sr()
            if sx is not None:
                self.slow_assign(sx)
                self.pending = None
            self.emit(f"{fn}({a}, {v})")
            self.wrote = True
            return
        t = str(int(a) & 0xFFFFFF) if const else "_t"
        ta = t if const else f"(_t := ({a}) & 0xFFFFFF)"
        if nb == 1:
            fast, first, store = f"(f := fl[{ta}]) == 7", "f == 3", f"m[{t}] = {v}"
            setf = f"fl[{t}] = 7"
        elif nb == 2:
            i16 = str(int(t) >> 1) if const else f"{ta} >> 1"
            fast = f"(f := F16[{i16}]) == 1799"
            first, store = "f == 771", f"PW(m, {t}, {v})"
            setf = f"F16[{int(t) >> 1 if const else '_t >> 1'}] = 1799"
            if not const:  # the address once, masked, into _t (the parity is that of the unmasked address)
                fast = f"not (_t := ({a}) & 0xFFFFFF) & 1 and (f := F16[_t >> 1]) == 1799"
                first = "not _t & 1 and " + first
        else:
            aligned = (int(a) & 3) == 0 if const else True
            i32 = str(int(t) >> 2) if const else f"{ta} >> 2"
            fast = f"(f := F32[{i32}]) == 117901063"
            first, store = "f == 50529027", f"PL(m, {t}, {v})"
            setf = f"F32[{int(t) >> 2 if const else '_t >> 2'}] = 117901063"
            if not const:
                fast = f"not (_t := ({a}) & 0xFFFFFF) & 3 and (f := F32[_t >> 2]) == 117901063"
                first = "not _t & 3 and " + first
            elif not aligned:
                fast = f"UL(fl, {t})[0] == 117901063"
                first = None
        self.emit(f"if {fast}:")
        self.emit(f"    {store}")
        if first is not None:
            self.emit(f"elif {first}:")
            self.emit(f"    {setf}")
            self.emit(f"    {store}")
        self.emit("else:")
        if const and _quiet_write(int(a), nb, self.facts, self.code):
            self.emit(f"    {fn}({a}, {v})")  # first-write bookkeeping or other code dropped: no fault, no exit
            return
        sx = self.slow_sr()
        if sx is not None:
            self.slow_assign(sx, "    ")
        self.emit(f"    {fn}({a}, {v})")
        if last and self.smc_inline:
            self.emit("    if D[0]:")
            self.emit("        D[0] = 0")
            self.ind += 2
            self.smc_slots.append(len(self.items))
            self.items.append((self.ind, ("smc",)))
            self.ind -= 2
        else:
            self.wrote = True

    # ---- flag fragments
    def nz(self, v: str, nb: int) -> str:
        return f"({v} >> {BITS[nb] - 4} & 8 if {v} else 4)"  # N = the sign bit moved to bit 3; Z

    def logic_flags(self, v: str, nb: int, need: int) -> None:
        if need & _FLAGS_NZVC:
            if self.defer:  # only a fault can observe them: keep the value, set SR on the slow paths only
                self.emit(f"pf = {v}")
                self.pending_nz = self.nz('pf', nb)
                self.pending = f"(sr & 0xFF10) | {self.pending_nz}"
                self.pending_from = self.cur
                return
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
            parts.append(f"(({v}) >> {BITS[nb] - 2} & 2)")  # the sign bit of the overflow test moved to bit 1
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

    def push(self, v: str) -> None:
        """Push the long ``v`` (PEA, BSR, JSR) and lower ``min_sp`` at once: a later instruction of the same
        block (an RTS after a PEA, say) may raise A7 again before the block exits."""
        sp = self.wg(15)
        self.emit(f"eb = ({sp} - 4) & 0xFFFFFFFF")
        self.write(4, "eb", v)
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
            self.write(nb, a, v, last=True)
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
            lazy = self.lazy == (kind, nb) and need & _ALL_FLAGS  # flags kept as lr/ls (set_lazy)
            if h in ("addq", "subq"):
                k = src.value
                if dst.mode is _M.AREG:
                    an = self.wg(8 + dst.reg)
                    self.emit(f"{an} = ({an} {'+' if kind == 'add' else '-'} {k}) & 0xFFFFFFFF")
                    return base, False
                s = str(k & M)
            else:
                # straight into ls only when no slow path of this instruction follows (a memory destination's
                # read would take the previous lazy flags, which need the previous ls)
                s = self.read(src, nb, pc, "ls" if lazy and dst.mode is _M.DREG else "s",
                              materialize=dst.mode is not _M.DREG)
            if dst.mode is _M.DREG:
                dn = self.rg(dst.reg)
                d = dn if nb == 4 else "x"
                if nb != 4:
                    self.emit(f"x = {dn} & {M}")
            else:
                a = self.addr_tmp(dst, nb, pc, "eb")
                d = "x"
                self.emit(f"x = {self.load(nb, a)}")
            if lazy:
                if s != "ls":
                    self.emit(f"ls = {s}")
                self.emit(f"lr = ls + {d}" if kind == "add" else f"lr = {d} - ls")
                self.emit(f"rm = lr & {M}")
                self.pending = None  # all five flags are now the lazy ones (a deferred MOVE's are overwritten)
            elif kind in ("add", "sub", "cmp"):
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
                self.write(nb, "eb", "rm", last=True)
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
                self.emit(f"x = {self.load(nb, a)}")
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
                k = self.const(_k_subx(nb), f"negx{nb}", ("subx", nb))
                self.emit(f"rm, sr = {k}(x, 0, sr)")
            if dst.mode is _M.DREG:
                self.set_dreg(dst.reg, nb, "rm")
            else:
                self.write(nb, "eb", "rm", last=True)
            return base, False
        if h == "cmpm":  # (Ay)+,(Ax)+: Ay read and incremented first; flags as CMP (X kept)
            s_op, d_op = ops
            sa = self.addr(s_op, nb, pc, "ea")
            self.emit(f"s = {self.load(nb, sa)}")
            da = self.addr(d_op, nb, pc, "eb")
            self.emit(f"x = {self.load(nb, da)}")
            if need & _FLAGS_NZVC:
                self.emit("r = x - s")
                self.emit(f"rm = r & {M}")
                self.arith_flags("cmp", nb, "s", "x", need)
            return base, False
        if h in ("addx", "subx"):
            s_op, d_op = ops
            k = self.const((_k_subx if h == "subx" else _k_addx)(nb), f"{h}{nb}", (h, nb))
            if s_op.mode is _M.DREG:
                s = self.read(s_op, nb, pc, "s")
                dn = self.rg(d_op.reg)
                self.emit(f"rm, sr = {k}({s}, {dn if nb == 4 else f'{dn} & {M}'}, sr)")
                self.set_dreg(d_op.reg, nb, "rm")
                return base, False
            sa = self.addr(s_op, nb, pc, "ea")
            self.emit(f"s = {self.load(nb, sa)}")
            da = self.addr_tmp(d_op, nb, pc, "eb")
            self.emit(f"x = {self.load(nb, da)}")
            self.emit(f"rm, sr = {k}(s, x, sr)")
            self.write(nb, "eb", "rm", last=True)
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
            return self.divide(ops, h, pc, need), False
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
            self.write(1, a, f"(0xFF if {ce} else 0)", last=True)
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
            fault = self.const(_Fault, "Fault", ("Fault",))
            ae = self.const(AddressError, "AddressError", ("AddressError",))
            self.emit(f"t = {a} & 0xFFFFFF")
            self.emit("if t & 1:")
            self.emit(f"    raise {fault}({ae}, f\"jump to odd address ${{t:06X}}\")")
            if h == "jsr":
                self.push(str(nxt & 0xFFFFFF))
            self.exit("t", n_done, prefix + base)
            return base, True
        if h == "rts":
            sp = self.wg(15)
            fault = self.const(_Fault, "Fault", ("Fault",))
            ae = self.const(AddressError, "AddressError", ("AddressError",))
            self.emit(f"v = {self.load(4, sp)}")
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

    def divide(self, ops: tuple[Operand, ...], h: str, pc: int, need: int = _ALL_FLAGS) -> int:
        """DIVU/DIVS with the clocks of :func:`isa.timing.divu_cycles` / :func:`isa.timing.divs_cycles` computed
        inline from the quotient (the microcode's shift-and-subtract steps in closed form: DIVU 136 - 2 per
        quotient bit 15..1 set - 2 per step whose partial remainder has its top bit set, which needs a divisor
        above $8000 (then the timing function is called); DIVS 2 * (61 + ...) as in divs_cycles). Returns the
        constant clocks (EA time); the rest goes to ``c``. N/Z/V/C are assigned only when ``need`` has one of
        them (a division that cannot fault, followed by an instruction that sets them all, leaves them dead)."""
        src, dst = ops
        fl = need & _FLAGS_NZVC
        const = src.mode is _M.IMM
        sv = src.value & 0xFFFF
        s = str(sv) if const else self.read(src, 2, pc, "s", materialize=True)
        dn = self.wg(dst.reg)
        name = "DIVS" if h == "divs" else "DIVU"
        if not const or sv == 0:
            fault = self.const(_Fault, "Fault", ("Fault",))
            dz = self.const(DivideByZero, "DivideByZero", ("DivideByZero",))
            if const:
                self.emit(f"raise {fault}({dz}, f\"{name} by zero (dividend ${{{dn}:08X}})\")")
                return timing.EA_TIME[src.mode][0]
            self.emit(f"if {s} == 0:")
            self.emit(f"    raise {fault}({dz}, f\"{name} by zero (dividend ${{{dn}:08X}})\")")
        self.dyn = True
        self.emit(f"d = {dn}")
        if h == "divu":
            self.emit(f"if d >> 16 >= {s}:")
            if fl:
                self.emit(f"    sr = (sr & 0xFF10) | {NF | VF}")
            self.emit("    c += 10")
            self.emit("else:")
            self.emit(f"    q, rem = divmod(d, {s})")
            self.emit(f"    {dn} = (rem << 16) | q")
            if fl:
                self.emit(f"    sr = (sr & 0xFF10) | {self.nz('q', 2)}")
            tc = self.const(timing.divu_cycles, "divc", ("divc",))
            if const and sv <= 0x8000:
                self.emit("    c += 136 - 2 * (q >> 1).bit_count()")
            elif const:
                self.emit(f"    c += {tc}(d, {s})")
            else:
                self.emit(f"    c += 136 - 2 * (q >> 1).bit_count() if {s} <= 0x8000 else {tc}(d, {s})")
            return timing.EA_TIME[src.mode][0]
        self.emit("sd = (d ^ 0x80000000) - 0x80000000")
        if const:
            ss = _sx(sv, 2)
            ss_e, as_e = str(ss), str(abs(ss))
        else:
            self.emit(f"ss = ({s} ^ 0x8000) - 0x8000")
            ss_e, as_e = "ss", "abs(ss)"
        self.emit("ad = abs(sd)")
        self.emit(f"if ad >> 16 >= {as_e}:")
        if fl:
            self.emit(f"    sr = (sr & 0xFF10) | {NF | VF}")
        self.emit("    c += 18 if sd < 0 else 16")
        self.emit("else:")
        self.emit(f"    aq = ad // {as_e}")
        if const:
            self.emit(f"    q = -aq if sd < 0 else aq" if ss > 0 else f"    q = aq if sd < 0 else -aq")
            base = (126, 120) if ss >= 0 else (124, 122)  # 2 * (61 + [sd < 0] + adjust): (sd < 0, sd >= 0)
            self.emit(f"    c += ({base[0]} if sd < 0 else {base[1]}) + 30 - 2 * ((aq >> 1) & 0x7FFF).bit_count()")
        else:
            self.emit("    q = -aq if (sd < 0) != (ss < 0) else aq")
            self.emit("    c += ((126 if sd < 0 else 120) if ss >= 0 else (124 if sd < 0 else 122)) + 30 "
                      "- 2 * ((aq >> 1) & 0x7FFF).bit_count()")
        self.emit("    if -0x8000 <= q <= 0x7FFF:")
        self.emit(f"        {dn} = (((sd - q * {ss_e}) & 0xFFFF) << 16) | (q & 0xFFFF)")
        if fl:
            self.emit(f"        sr = (sr & 0xFF10) | {self.nz('(q & 0xFFFF)', 2)}")
            self.emit("    else:")
            self.emit(f"        sr = (sr & 0xFF10) | {NF | VF}")
        return timing.EA_TIME[src.mode][0]

    def shift(self, ins: Instruction, h: str, nb: int, pc: int, need: int, base: int) -> int:
        ops = ins.operands
        M, S, W = MASK[nb], SIGN[nb], BITS[nb]
        if len(ops) == 1:  # memory word by 1
            k = self.const(_k_shift(h, 2), f"{h}2", ("shift", h, 2))
            a = self.addr_tmp(ops[0], 2, pc, "eb")
            self.emit(f"x = {self.load(2, a)}")
            self.emit(f"rm, sr = {k}(x, 1, sr)")
            self.write(2, "eb", "rm", last=True)
            return base
        cnt, dst = ops
        dn = self.rg(dst.reg)
        x = dn if nb == 4 else "x"
        if nb != 4:
            self.emit(f"x = {dn} & {M}")
        fixed = None  # a count known when compiling: an immediate, or a register set by the MOVEQ just before
        if cnt.mode is _M.IMM:
            fixed = cnt.value
        elif cnt.reg in self.known:
            fixed = self.known[cnt.reg] & 63
            base = (8 if nb == 4 else 6) + 2 * fixed
        if fixed and h in ("lsl", "lsr", "asr"):
            n = fixed
            if h == "lsl":
                self.emit(f"rm = ({x} << {n}) & {M}" if n else f"rm = {x}")
                cexpr = f"{x} >> {W - n} & 1" if n <= W else "0"
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
        k = self.const(_k_shift(h, nb), f"{h}{nb}", ("shift", h, nb))
        if fixed is not None:
            self.emit(f"rm, sr = {k}({x}, {fixed}, sr)")
            self.set_dreg(dst.reg, nb, "rm")
            return base
        self.emit(f"n = {self.rg(cnt.reg)} & 63")
        self.emit(f"rm, sr = {k}({x}, n, sr)")
        self.set_dreg(dst.reg, nb, "rm")
        self.cycles("n + n")
        return 8 if nb == 4 else 6

    def movem(self, ins: Instruction, nb: int, pc: int) -> None:
        M = MASK[nb]
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
                self.emit(f"{r} = {self.load(nb, a)}")
            else:
                self.emit(f"{r} = (({self.load(nb, a)} ^ 0x8000) - 0x8000) & 0xFFFFFFFF")
        if post:
            self.emit(f"{self.wg(an)} = (ea + {len(regs) * nb}) & 0xFFFFFFFF")
        self.emit(self.load(2, f"ea + {len(regs) * nb}" if regs else "ea"))  # the 68000's extra word read


class _BlockInfo:
    """What the run loop and the fault path need to know about one compiled block."""

    __slots__ = ("start", "pcs", "lines", "prefix", "ncount", "regs", "n", "bound", "end")

    def __init__(self, start: int, pcs: list[int], lines: list[int], prefix: list[int], ncount: list[int],
                 regs: list[int], bound: int, end: int, n: int) -> None:
        self.start = start
        self.n = n  #: most instructions in one pass (the entries: a pass runs each at most once)
        self.bound = bound  #: clock bound of one pass (_block_bound)
        self.end = end  #: address after the last instruction
        # One item per segment: each generated copy of an instruction (a duplicated tail copies some), in line order.
        self.pcs = pcs  #: address of the segment's instruction
        self.lines = lines  #: first source line of the segment in the generated code
        self.prefix = prefix  #: constant clocks before the segment on the path that reaches it (+ local c)
        self.ncount = ncount  #: constant instruction count before the segment on that path (+ local ni)
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

    # No loop either when the loop head is never reached, or when code before the head branches past it (those
    # branches could only leave the block; planned without the loop they are ifs or duplicated tails, and the
    # back edge leaves to the block at the head instead, which runs the loop).
    if head is not None and (plan(0, head) or any(
            h in ("bcc", "bra", "dbcc") and at.get(_branch_target(ins), -1) > head
            for _, ins, h, _, _ in entries[:head])):
        role.clear()
        reach = [False] * k
        head, start = None, -1
    if head is None:
        plan(0, k)
        _plan_tails(entries, role, reach, at)
    else:
        plan(head, k)
    return role, reach, head


#: Most entries one block may generate with duplicated tails (:func:`_plan_tails`), as a multiple of its entries.
TAIL_BUDGET = 4


def _plan_tails(entries: list[_Entry], role: dict[int, tuple[Any, ...]], reach: list[bool], at: dict[int, int]
                ) -> None:
    """Tail duplication (blocks without a loop only): a Bcc or BRA that would leave the block to a later entry
    ``j`` of the same block (a branch out of a nested region to code after it, e.g. from the then-part of an
    if/else to the start of its else-part, or to a common ``.done`` from any depth) gets the role ``("dup", j)``:
    the generator emits a copy of the code from ``j`` to the end of the block in the branch's taken path. Every
    copy goes forward, so a path still runs each entry at most once (the instruction and clock bounds of one
    pass hold). Targets the main plan never reaches stay exits; while the generated entries would exceed
    :data:`TAIL_BUDGET` times the block's entries, the duplication with the largest copy is dropped."""
    k = len(entries)
    cands = []
    for i, (_, ins, h, _, _) in enumerate(entries):
        if reach[i] and i not in role and h in ("bcc", "bra"):
            j = at.get(_branch_target(ins))
            if j is not None and i < j < k and reach[j]:
                cands.append((i, j))
    if not cands:
        return
    for i, j in cands:
        role[i] = ("dup", j)
    while True:
        memo: dict[int, int] = {}

        def walk(lo: int, hi: int) -> tuple[int, bool]:
            """(entries generated for lo..hi-1, whether every path leaves) -- mirrors _block_source's gen."""
            i, cnt = lo, 0
            while i < hi:
                if not reach[i]:
                    return cnt, True  # a copy that runs into code the plan never reached: an exit there
                r = role.get(i)
                cnt += 1
                if r is None:
                    if entries[i][2] in _BLOCK_ENDS:
                        return cnt, True
                    i += 1
                elif r[0] in ("skip", "join"):
                    i = r[1]
                elif r[0] == "dup":
                    cnt += tail(r[1])
                    if entries[i][2] == "bra":
                        return cnt, True
                    i += 1
                elif r[0] == "if":
                    cnt += walk(i + 1, r[1])[0]
                    i = r[1]
                else:  # ifelse
                    c1, e1 = walk(i + 1, r[1] - 1)
                    c2, e2 = walk(r[1], r[2])
                    cnt += c1 + c2 + 1
                    if e1 and e2:
                        return cnt, True
                    i = r[2]
            return cnt, False

        def tail(j: int) -> int:
            if j not in memo:
                memo[j] = walk(j, k)[0]
            return memo[j]

        total = walk(0, k)[0]
        dups = [i for i, r in role.items() if r[0] == "dup"]
        if total <= TAIL_BUDGET * k or not dups:
            return
        del role[max(dups, key=lambda i: (tail(role[i][1]), i))]


def _liveness(entries: list[_Entry], role: dict[int, tuple[Any, ...]], reach: list[bool], head: int | None,
              facts: MapFacts) -> list[int]:
    code = (entries[0][0], entries[-1][0] + entries[-1][4])
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
            pc, ins, h, cond, _ = entries[i]
            faults = _may_fault(ins, h, facts, pc, code)
            r = role.get(i)
            if r is None:
                after = live_in[i + 1]
                if h in _BLOCK_ENDS or h in ("bcc", "dbcc") or faults:
                    after = _ALL_FLAGS
            elif r[0] in ("if", "ifelse"):
                after = live_in[i + 1] | live_in[r[1]]
            elif r[0] in ("skip", "join"):
                after = live_in[r[1]]
            elif r[0] == "dup":  # the copy of the code from r[1] runs on the taken path
                after = live_in[r[1]] if h == "bra" else live_in[i + 1] | live_in[r[1]]
            else:  # loop
                after = live0 if h == "bra" else live0 | live_in[i + 1]
            uses, defs = _flag_effect(ins, h, cond)
            need[i] = after
            live_in[i] = _ALL_FLAGS if faults else (after & ~defs) | uses
        if head is None or live_in[head] | live0 == live0:
            return need
        live0 |= live_in[head]


#: Handlers that may sit in the loop of a block with lazy ADD/SUB flags (_lazy_kind): no flag reads, memory
#: accesses only through _BlockGen.load/write (whose slow paths take the lazy flags into SR first).
_LAZY_SAFE = frozenset("move movea adda suba lea exg nop and andi or ori eor eori cmp cmpi cmpa add addi addq sub "
                       "subi subq bra dbcc clr not neg tst swap ext muls mulu divu divs".split())


def _lazy_kind(entries: list[_Entry], reach: list[bool], head: int | None, need: list[int]) -> tuple[str, int] | None:
    """(kind, size) of the ADD/SUB whose flags a looping block keeps lazily, or None. Inside a ``while`` loop the
    flags of an ADD/SUB (all five) are usually seen only by a block exit or a fault of a later instruction (the
    next pass's MOVE, say): the block keeps its unmasked result ``lr`` and source ``ls`` and computes SR from them
    only on the exits and the slow (possibly faulting) memory paths, which then set ``lr = None`` (``sr`` holds
    the flags again). Taken when every entry of the loop is in :data:`_LAZY_SAFE` (DBcc only as DBRA, which reads
    no flag), every ADD/SUB with live flags there has the same kind and size, and there is one; the generated
    code is then checked for any other use of ``sr`` in the loop (:func:`_block_source`), which undoes it."""
    if head is None:
        return None
    kinds = set()
    for i in range(head, len(entries)):
        if not reach[i]:
            continue
        _, ins, h, cond, _ = entries[i]
        if h not in _LAZY_SAFE or (h == "dbcc" and cond != 1):
            return None
        if h in ("divu", "divs") and not (ins.operands[0].mode is _M.IMM and ins.operands[0].value & 0xFFFF):
            return None  # its divide-by-zero fault is raised inline, not on a slow memory path
        if h in ("add", "addi", "addq", "sub", "subi", "subq") and need[i] & _ALL_FLAGS and not (
                h in ("addq", "subq") and ins.operands[1].mode is _M.AREG):
            kinds.add((h[:3], _nb(ins)))
    return kinds.pop() if len(kinds) == 1 else None


def _block_source(entries: list[_Entry], facts: MapFacts, lazy_ok: bool = True
                  ) -> tuple[str, dict[str, object], tuple[list[int], list[int]], list[int], list[int], list[int],
                             bool, list[tuple[Any, ...]]]:
    """Python source of the block function for ``entries`` ((pc, instruction, handler, cond, length) each, back to
    back in memory). Returns (source, constants, (first generated line, address) per segment (a generated copy of
    an entry, in line order), constant clocks and constant instruction count before each segment on the path
    that reaches it, registers used, whether it loops, the recipe of each constant in order)."""
    k = len(entries)
    role, reach, head = _plan(entries)
    need = _liveness(entries, role, reach, head, facts)
    loops = head is not None
    g = _BlockGen(facts, (entries[0][0], entries[-1][0] + entries[-1][4]))
    lazy = _lazy_kind(entries, reach, head, need) if lazy_ok else None
    loop_at = 0  # first item of the while loop
    # One segment per generated copy of an entry (a duplicated tail generates entries more than once): the
    # entry, and the constant instruction count and clocks before it on the path that reaches that copy.
    segs: list[tuple[int, int, int]] = []
    flow = bool(role)  # dynamic instruction count (local ni) needed

    def mark(i: int, n: int, cy: int) -> None:
        g.items.append((0, ("mark", len(segs))))
        segs.append((i, n, cy))

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
        g.emit("if ni <= ln:")  # implies c < lc (see the cap before the loop)
        g.emit("    continue")
        g.exit(head_pc, n_head, c_head)

    # Entries reached other than by falling through from the entry before (values known there do not hold).
    targets = {head} if head is not None else set()
    for rr in role.values():
        targets.update(x for x in rr[1:] if isinstance(x, int))

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
                g.cur = i
                g.defer = _defer_flags(entries, i, hi, role, targets)
                g.wrote = False
                g.u32 = set()
                g.smc_inline = not _lowers_sp(ins, h)
                g.smc_slots = []
                g.known = {}
                if i > lo and i not in targets and entries[i - 1][2] == "moveq" and (i - 1) not in role:
                    prev = entries[i - 1][1].operands
                    g.known = {prev[1].reg: _sx(prev[0].value & 0xFF, 1) & M32}
                cyc, ended = g.instruction(n, ins, h, cond, pc, nxt, need[i], cy)
                cy += cyc
                n += 1
                if _lowers_sp(ins, h) and h not in ("pea", "bsr", "jsr"):
                    g.emit(f"if {g.rg(15)} < MS[0]:")
                    g.emit(f"    MS[0] = {g.rg(15)}")
                wrote = g.wrote
                g.defer = False
                if g.pending is not None and g.pending_from < i:
                    g.pending = None  # the instruction after the deferring one is done
                for slot in g.smc_slots:
                    g.items[slot] = (g.items[slot][0], ("exit", nxt, n, cy, frozenset(g.dirty)))
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
            if kind == "dup":  # the taken path runs a copy of the code from r[1] on (_plan_tails)
                g.dyn = True
                if h == "bra":
                    copy(r[1], n + 1, cy + taken)
                    return True, n + 1, cy + taken
                g.emit(f"if {_COND_EXPR[cond]}:")  # type: ignore[index]
                g.ind += 1
                copy(r[1], n + 1, cy + taken)
                g.ind -= 1
                n += 1
                cy += timing.cycles(ins, taken=False)
                i += 1
                continue
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
                    # the low word counts down: nonzero -> minus 1 (no borrow out of it), loop; zero -> $FFFF, out
                    g.emit(f"if {dn} & 0xFFFF:")
                    g.ind += 1
                    g.emit(f"{dn} -= 1")
                    loopback(n + 1, cy + taken)
                    g.ind -= 1
                    g.emit("else:")
                    g.emit(f"    {dn} |= 0xFFFF")
                    g.emit("    c += 2")
                    if ce != "False":
                        g.ind -= 1
                    cy += 12
                n += 1
                i += 1
                continue
            if kind in ("skip", "join"):  # a join is reached here only in a copy that starts in a then-part
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

    def copy(j: int, n: int, cy: int) -> None:
        """A copy of the entries from ``j`` to the end of the block (a duplicated tail), ending in exits."""
        pos = body_start()
        e, n1, c1 = gen(j, k, n, cy)
        if not e:
            g.exit((entries[-1][0] + entries[-1][4]) & 0xFFFFFF, n1, c1)
        close_body(pos)

    if head is None:
        ended, n_end, c_end = gen(0, k, 0, 0)
    else:
        head_pc = entries[head][0]
        _, n_head, c_head = gen(0, head, 0, 0)  # the entries before the loop head (never all leave: see _plan)
        # One test per pass instead of two (loopback): p more passes take at most p * C clocks (C: every entry of
        # the loop once, at its worst) and at least p instructions, so capping ln at ni + (lc - c - 1) // C here
        # makes `ni <= ln` imply the clock test `c < lc`. The cap only binds near a small max_cycles, where the
        # block then leaves earlier than it had to (exact either way: CPU.run goes on from the head).
        worst_pass = sum(timing.cycle_range(e[1])[1] for e in entries[head:])
        g.dyn = True  # the cap reads c (a loop whose only pass leaves at once may add no clock to c itself)
        g.emit(f"lx = ni + (lc - c - 1) // {worst_pass}")
        g.emit("if lx < ln:")
        g.emit("    ln = lx")
        g.emit("while True:")
        g.ind += 1
        loop_at = len(g.items)
        if lazy is not None:
            g.set_lazy(*lazy)
        ended, n_end, c_end = gen(head, k, n_head, c_head)
    if not ended:
        last_pc, _, _, _, last_len = entries[-1]
        g.exit((last_pc + last_len) & 0xFFFFFF, n_end, c_end)
    if lazy is not None:  # any use of sr in the loop other than the slow paths' assignments undoes the lazy flags
        for _, t in g.items[loop_at:]:
            if isinstance(t, str):
                for x in g.slow_texts:
                    t = t.replace(x, "")
                if re.search(r"\bsr\b", t):
                    return _block_source(entries, facts, lazy_ok=False)
    body: list[str] = []
    dirty = sorted(g.dirty)
    text = [t for _, t in g.items if isinstance(t, str)]
    uses_sr = lazy is not None or any("sr" in t for t in text)
    sr_dirty = lazy is not None or any("sr = " in t for t in text)
    lines_ = [f"def __make(R, MS, D, rb, rw, rl, wb, ww, wl, m, fl, F16, F32, UL, UW, PL, PW{''.join(', ' + n for n in g.consts)}):",
            "    def __block(bn, bc, until):"]
    used = sorted(g.used)
    lines_ += [f"        {_RN[r]} = R[{r}]" for r in used]
    if uses_sr:
        lines_.append("        sr = R[16]")
    if g.dyn:
        lines_.append("        c = 0")
    if lazy is not None:
        lines_.append("        lr = None")
    if flow or loops:
        lines_.append("        ni = 0")
    if loops:  # another pass from the head may start only if its worst case fits the budget (see CPU.run)
        lines_.append(f"        ln = (bn if bn < 0x40000000 else 0x40000000) - {k - head + n_head}")
        lines_.append(f"        if until == {head_pc}:")
        lines_.append("            ln = -1")
        lines_.append(f"        lc = bc - {_block_bound(entries[head:]) + c_head}")
    first = len(lines_) + 1
    seg_line = [0] * len(segs)
    sr_so_far = False
    for ind, item in g.items:
        pad = "    " * (ind + 1)
        if isinstance(item, str):
            body.append(pad + item)
            sr_so_far = sr_so_far or "sr = " in item
        elif item[0] == "mark":
            seg_line[item[1]] = first + len(body)
        else:
            # Without a loop, code runs in text order: only registers assigned before this exit can differ from R.
            _, target, n, cycles, assigned = item
            for r in dirty:
                if loops or r in assigned:
                    body.append(f"{pad}R[{r}] = {_RN[r]}")
            if sr_dirty and (sr_so_far or loops):
                body.append(f"{pad}R[16] = {g.lazy_x}")
            packed = n << 24 | cycles << 56
            expr = str(target | packed) if isinstance(target, int) else f"{target} | {packed}"
            if g.dyn:
                expr += " + (c << 56)"
            if flow or loops:
                expr += " + (ni << 24)"
            body.append(f"{pad}return {expr}")
    # Segments in text order (as generated): the line map of _BlockInfo (a fault's line -> its segment).
    lines = seg_line
    seg_pcs = [entries[i][0] for i, _, _ in segs]
    ncount = [n for _, n, _ in segs]
    prefix = [cy for _, _, cy in segs]
    src = "\n".join(lines_ + body + ["    return __block", ""])
    return src, g.consts, (lines, seg_pcs), prefix, ncount, used, loops, [g.recipes[name] for name in g.consts]


def _block_bound(entries: list[_Entry]) -> int:
    """Clocks that bound the start of any instruction of one pass through the block: the worst-case clocks of
    every entry but the one with the smallest worst case (a pass never runs an entry twice)."""
    worst = [timing.cycle_range(e[1])[1] for e in entries]
    return sum(worst) - min(worst)


def _make_const(recipe: tuple[Any, ...]) -> object:
    """The block constant of ``recipe`` (see :meth:`_BlockGen.const`)."""
    kind = recipe[0]
    fixed = {"Fault": _Fault, "AddressError": AddressError, "DivideByZero": DivideByZero, "divc": timing.divu_cycles}
    if kind in fixed:
        return fixed[kind]
    if kind in ("subx", "negx"):
        return _k_subx(recipe[1])
    if kind == "addx":
        return _k_addx(recipe[1])
    if kind == "shift":
        return _k_shift(recipe[1], recipe[2])
    raise KeyError(recipe)


def compile_block(entries: list[_Entry], facts: MapFacts) -> tuple[Any, _BlockInfo]:
    """Generate and compile the block of ``entries`` for an address space with map ``facts`` (see the module
    docstring); returns ``(bind, info)``, ``bind(R, MS, D, memory)`` giving the block function of one CPU. With
    :func:`isa.codecache.use_disk`, the compiled code is read from / written to disk, keyed by the entries, the
    map and the ``isa`` sources (the same code the generator would make, without generating it)."""
    start = entries[0][0]
    key = codecache.block_code_key(entries, facts.regions, facts.span)
    hit = codecache.load_block_code(key) if key is not None else None
    if hit is not None:
        code, recipes, lines, prefix, ncount, regs = hit
        values = tuple(_make_const(r) for r in recipes)
    else:
        src, consts, lines, prefix, ncount, regs, _, recipes = _block_source(entries, facts)
        code = compile(src, f"<block ${start:06X}>", "exec")
        values = tuple(consts.values())
        if key is not None:
            codecache.store_block_code(key, (code, recipes, lines, prefix, ncount, regs))
    ns: dict[str, Any] = {}
    exec(code, ns)  # noqa: S102 - our own generated code
    make = ns["__make"]
    last_pc, _, _, _, last_len = entries[-1]
    seg_lines, seg_pcs = lines
    info = _BlockInfo(start, list(seg_pcs), list(seg_lines), list(prefix), list(ncount), list(regs),
                      _block_bound(entries), last_pc + last_len, len(entries))

    def bind(R: list[int], MS: list[int], D: list[int], memory: Any) -> Any:
        rd, wr = memory.rd, memory.wr
        return make(R, MS, D, rd[1], rd[2], rd[4], wr[1], wr[2], wr[4], memory.mem, memory.flags,
                    memory.flags16, memory.flags32, _UL, _UW, _PL, _PW, *values)

    return bind, info


def block_entries(start: int, most: int,
                  decoded_at: Any) -> list[_Entry]:
    """The extent of the block at ``start``: instructions up to the first unconditional transfer (BRA, BSR, JMP,
    JSR, RTS) that no earlier forward branch of the block (nor the BRA itself) jumps past by at most
    :data:`_FORWARD_WINDOW` bytes, an instruction left to the per-instruction path (TRAP, ILLEGAL, an odd constant
    branch target, an undecodable or unfetchable word) or ``most`` instructions. ``decoded_at(pc)`` returns
    ``(instruction, length, handler, condition)`` or None."""
    entries: list[_Entry] = []
    pc = start
    pending = -1  # furthest forward branch target so far (within the window)
    while len(entries) < most:
        if pc & 1:
            break
        d = decoded_at(pc)
        if d is None:
            break
        ins, length, h, cond = d
        if not _blockable(ins, h):
            break
        entries.append((pc, ins, h, cond, length))
        if h in ("bcc", "bra", "dbcc") and 0 < _branch_target(ins) - pc <= _FORWARD_WINDOW:
            pending = max(pending, _branch_target(ins))
        if h in _BLOCK_ENDS and pending <= pc:
            break
        pc = (pc + length) & 0xFFFFFF
    return entries

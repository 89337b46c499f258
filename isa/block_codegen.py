"""The block code generator: the Python code of each instruction of a block (:class:`_BlockGen`).

Contract with :mod:`isa.blocks` (whose :func:`_block_source` drives it) and :mod:`isa.block_plan`:

* :func:`_block_source` makes one ``_BlockGen(facts, (start, end))`` per block, sets its per-instruction state
  (``known``, ``defer``, ``lazy``, ``cur``, ``smc_inline``, ... as its attributes document) from the plan
  (:mod:`isa.block_plan`: roles, live flags, deferred and lazy flags) and calls :meth:`_BlockGen.instruction`
  for each entry in the order planned, with the flags ``need``-ed after it. The generator appends indented lines,
  exits (``("exit", target, n, cycles, dirty registers)``) and marks to ``items``; :func:`_block_source` turns
  them into the function's text (the exits' register write-back, clocks and counts per path).
* Registers are the locals :data:`_RN` (``d0..a7``), the SR is ``sr``, :data:`_COND_EXPR` is the inline test of
  each condition code. Objects the generated code needs are named through :meth:`_BlockGen.const` together with
  a recipe that :func:`isa.blocks._make_const` turns back into the object (the disk cache stores recipes).
* Memory accesses follow :mod:`isa.memory`'s contract (direct ``mem`` for constant addresses the map
  guarantees, span/flag checks inline, the exact accessor otherwise, which raises the fault); a write that
  :func:`isa.block_plan._quiet_write` accepts gets no fault path and no leave-the-block check.
* The value layer (:data:`SYMBOLIC`, :meth:`_BlockGen.symbolic`): a register-only data instruction (and a MOVE
  or ALU source at a constant address the map guarantees) does not become a statement; its result is the pending
  value (:class:`_Val`: an expression congruent to the register modulo 2^32, its range, a cheap low-word view) of
  its data register, composed into later instructions' expressions. Pending values are assigned to the register
  locals (:meth:`_BlockGen.flush`) before anything can observe them: all of them before an instruction that may
  fault, writes memory, branches or leaves (the fault unwinding reads every register local; exits write them
  back), before every control-flow role and at the end of every straight line (:func:`_block_source` calls
  ``flush``); before another non-faulting instruction, its own registers and every pending value that names
  them. So the fault line map (one segment per generated entry, in line order) stays exact: a value-layer entry
  has an empty segment, and no line that can raise belongs to another entry than its own. ``later`` (set per
  entry from :func:`isa.block_plan._read_later`) only decides whether a value read by another instruction is
  bound to a temporary first (computed once) or composed (read once): cost, not correctness.
* Flag/branch fusion (:meth:`_BlockGen.fuse_setup`): a value-layer instruction whose N/Z/V/C only the Bcc right
  after it reads (``nxt``: none of them live after the branch, by the planner's liveness) assigns no flag; the
  branch's ``if`` (:meth:`_BlockGen.branch_test`, also called by :func:`isa.blocks._block_source`) tests the
  value or compares the operands itself. X is kept, or assigned by an ADD/SUB when live.
* Imports: :mod:`isa.block_plan` (flag constants, :func:`_quiet_write`, :func:`_may_fault`), :mod:`isa.semantics`,
  :mod:`isa.timing`; never :mod:`isa.blocks`.
"""

from __future__ import annotations

import re
from typing import Any, NamedTuple

from isa import timing
from isa.block_plan import (_ALL_FLAGS, _CONTROL, _FLAGS_NZVC, _READ_ONLY_DST, _SHIFT_NAMES, _may_fault,
                             _quiet_write)
from isa.errors import AddressError, DivideByZero
from isa.operands import Instruction, Operand, Size
from isa.memory import MapFacts
from isa.semantics import (BITS, CALL_SENTINEL, CF, M32, MASK, NF, SIGN, VF, XF, ZF, _M, _MEMORY_MODES, _Fault, _inc,
                           _k_addx, _k_shift, _k_subx, _nb, _nz, _pc_target, _sx)


#: An address expression ``(<register local> + <displacement >= 0>)`` (d16(An) with d16 >= 0): never negative.
_REG_PLUS_DISP = re.compile(r"\([ad][0-7] \+ \d+\)\Z")


_RN: tuple[str, ...] = tuple(f"d{i}" for i in range(8)) + tuple(f"a{i}" for i in range(8))
#: Inline Python expression (over the local ``sr``) that is true when condition ``cc`` holds.
_COND_EXPR: tuple[str, ...] = (
    "True", "False", "not sr & 5", "sr & 5", "not sr & 1", "sr & 1", "not sr & 4", "sr & 4",
    "not sr & 2", "sr & 2", "not sr & 8", "sr & 8", "not (sr ^ sr >> 2) & 2", "(sr ^ sr >> 2) & 2",
    "not (sr & 4 | (sr ^ sr >> 2) & 2)", "sr & 4 | (sr ^ sr >> 2) & 2",
)  # fmt: skip


#: Pending register values (:class:`_Val`): register-only data instructions that cannot fault are not assigned as
#: statements; their values are expressions, composed into the next instruction's, and assigned to the register
#: locals only where something can observe them. False: every instruction is generated as statements.
SYMBOLIC = True

_ATOM = re.compile(r"(?:\d+|[ad][0-7]|_y\d+)\Z")  # a register local, a temporary or a literal
_DREF = re.compile(r"\bd[0-7]\b")
_CONST_SRC = frozenset((_M.ABSW, _M.ABSL, _M.PCDISP))
#: Handlers whose register-only forms the value layer takes (some only with their flags dead: _BlockGen.symbolic).
_SYM = frozenset("move moveq add addi addq sub subi subq and andi or ori eor eori cmp cmpi tst clr not neg swap ext "
                 "exg mulu muls asl asr lsl lsr".split())


#: Flag/branch fusion (:meth:`_BlockGen.fuse_setup`): a compare whose flags only the next Bcc reads: the branch's
#: condition code -> (the comparison of the operands, over their unsigned (u) or signed (s) values, that equals the
#: condition). VC/VS, MI/PL (and T/F) are left to the flag computation.
_CMP_COND: dict[int, tuple[str, str]] = {
    2: ("u", ">"), 3: ("u", "<="), 4: ("u", ">="), 5: ("u", "<"), 6: ("u", "!="), 7: ("u", "=="),
    12: ("s", ">="), 13: ("s", "<"), 14: ("s", ">"), 15: ("s", "<="),
}
_CMP_CONDS = frozenset(_CMP_COND)
_NOT_OP = {">": "<=", "<=": ">", ">=": "<", "<": ">=", "!=": "==", "==": "!="}
#: Conditions decided by N/Z of a value with V and C cleared (MOVE, TST, AND, ...): HI = NE, LS = EQ, GE = PL,
#: LT = MI, GT = "0 < v < sign", LE its negation (CC/CS/VC/VS are constant: left to the flag computation).
_NZ_CONDS = frozenset((2, 3, 6, 7, 10, 11, 12, 13, 14, 15))
#: Conditions decided by N or Z alone (an ADD/SUB's: C and V are its own there).
_NZ_ONLY = frozenset((6, 7, 10, 11))
#: Value-layer handlers that write their data register and may give a fused test (fuse_setup): N/Z of the result.
_FUSE_ARITH = frozenset("add addi addq sub subi subq".split())
_FUSE_NZ = frozenset("move and andi or ori eor eori not ext swap mulu muls".split()) | _FUSE_ARITH
_WALRUS = re.compile(r"(\w+) :=")


def _paren(x: str) -> bool:
    """True when ``x`` is one parenthesized expression (its first parenthesis closes at its end)."""
    if not x.startswith("("):
        return False
    depth = 0
    for k, ch in enumerate(x):
        depth += ch == "("
        depth -= ch == ")"
        if depth == 0:
            return k == len(x) - 1
    return False


def _nz_tests(first: str, nb: int, cond: int) -> tuple[str, str]:
    """(test true when ``cond`` holds, test true when it does not) for the N/Z of the exact ``nb``-byte value whose
    expression (evaluated once, in the test) is ``first``, V and C cleared (``cond`` in :data:`_NZ_CONDS`)."""
    S = SIGN[nb]
    if first.isdigit():  # a known value: a known outcome
        v = int(first)
        holds = {2: v != 0, 3: v == 0, 6: v != 0, 7: v == 0, 10: v < S, 11: v >= S, 12: v < S, 13: v >= S,
                 14: 0 < v < S, 15: not 0 < v < S}[cond]
        return ("True", "False") if holds else ("False", "True")
    if cond in (2, 6):
        return first, f"not {first}"
    if cond in (3, 7):
        return f"not {first}", first
    if cond in (11, 13):
        return f"{first} >= {S}", f"{first} < {S}"
    if cond in (10, 12):
        return f"{first} < {S}", f"{first} >= {S}"
    if cond == 14:
        return f"0 < {first} < {S}", f"not 0 < {first} < {S}"
    return f"not 0 < {first} < {S}", f"0 < {first} < {S}"


class _Val:
    """The value of a data register not yet assigned to its local. ``e``: a pure expression (over the register
    locals as they are now, ``_y`` temporaries and literals), or a function that makes it (and may bind a
    temporary first), of a Python int in ``[lo, hi]`` congruent to the register's value modulo 2^32 (the value
    itself when ``0 <= lo`` and ``hi < 2^32``: :meth:`exact`); ``w``: a cheaper expression of its low word, or
    None, and ``whi`` an upper bound of that word."""

    __slots__ = ("e", "lo", "hi", "w", "whi")

    def __init__(self, e: Any, lo: int, hi: int, w: str | None = None, whi: int | None = None) -> None:
        self.e = e
        self.lo = lo
        self.hi = hi
        self.w = w
        self.whi = (hi if 0 <= lo and hi <= 0xFFFF else 0xFFFF) if whi is None else whi

    def exact(self) -> bool:
        return 0 <= self.lo and self.hi <= M32


def _lit(v: int) -> str:
    return str(v) if v >= 0 else f"({v})"


class _Unblockable(Exception):
    """Internal: this instruction is left to the per-instruction path (the block ends before it)."""


class _Ins(NamedTuple):
    """One instruction as :meth:`_BlockGen.instruction` hands it to the emitter of its handler (:data:`_EMITTERS`):
    the instruction, its operands, size in bytes and mask, handler name, condition, address, the next address, the
    flags asked for, its base clocks, the instruction count and constant clocks done on the path (``n_done``,
    ``prefix``)."""

    ins: Instruction
    ops: tuple[Operand, ...]
    nb: int
    M: int
    h: str
    cond: int | None
    pc: int
    nxt: int
    need: int
    base: int
    n_done: int
    prefix: int


class _BlockGen:
    """Generates the source of one block function. Registers live in locals ``d0..a7``, the status register in
    ``sr``, data-dependent clocks accumulate in ``c``; every exit writes the registers back and returns
    ``next_pc | instructions << 24 | clocks << 56``."""

    def __init__(self, facts: MapFacts, code: tuple[int, int] = (0, 1 << 24)) -> None:
        self.facts = facts
        self.code = code  # the block's own code bytes [start, end)
        self.known: dict[int, int] = {}  # data register -> value known here (set by gen() for one instruction)
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
        self.smc_slots: list[int] = []  # item indices to fill with the exit after the instruction
        self.items: list[tuple[int, object]] = []  # (indent, line str | ("exit", ...) | ("mark", i))
        self.ind = 1
        self.used: set[int] = set()
        self.dirty: set[int] = set()
        self.consts: dict[str, object] = {}
        self.recipes: dict[str, tuple[Any, ...]] = {}
        self.dyn = False
        # The value layer (SYMBOLIC): data register -> its pending value; the temporaries' counter; ``later(r)``
        # (set by _block_source per entry): whether register r is read again before being overwritten
        # (:func:`isa.block_plan._read_later`; only a cost guess).
        self.sym = SYMBOLIC
        self.pend: dict[int, _Val] = {}
        self.ntmp = 0
        self.memo: dict[str, str] = {}  # expression -> the temporary bound to it (until a register local changes)
        self.later: Any = lambda r: True
        # (condition, flags live after it) of the Bcc right after this instruction on the straight line, or None
        self.nxt: tuple[int, int] | None = None
        # Flag/branch fusion (fuse_setup): ``fusing`` the condition (and kind) this instruction's flags may be
        # fused into; ``fused`` (condition, test when it holds, test when it does not) for the next Bcc's ``if``
        # (branch_test), which then reads no flag: the instruction assigns none.
        self.fusing: tuple[int, str] | None = None
        self.fused: tuple[int, str, str] | None = None
        self.shifted: dict[str, tuple[str, str, int, int, int]] = {}  # shift result -> (kind, operand, lo, hi, n)

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
        self.memo.clear()  # a register local changes: expressions over it no longer equal their temporaries
        return _RN[i]

    def exit(self, target: str | int, n: int, cycles: int) -> None:
        """Leave the block to ``target`` (int or expression) after ``n`` instructions and ``cycles`` clocks (+c)."""
        assert not self.pend, "pending register values at a block exit"
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
            assert not self.pend, "pending register values at a block exit"
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

    def arith_flags(self, kind: str, nb: int, s: str, d: str, need: int, r: str = "r", rm: str | None = "rm"
                    ) -> None:
        """ADD/SUB/CMP flags from ``r`` (unmasked result) and ``rm`` (masked; None: only C/X asked for); only the
        bits in ``need``."""
        M = MASK[nb]
        keep = 0xFF1F
        parts = []
        if need & (CF | (XF if kind != "cmp" else 0)):
            bits = 1 if kind == "cmp" else 0x11
            test = f"{r} > {M}" if kind == "add" else f"{r} < 0"
            parts.append(f"({bits} if {test} else 0)")
            keep &= ~bits
        if need & (NF | ZF):
            parts.append(self.nz(rm, nb))
            keep &= ~(NF | ZF)
        if need & VF:
            v = f"({s} ^ {rm}) & ({d} ^ {rm})" if kind == "add" else f"({s} ^ {d}) & ({d} ^ {rm})"
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

    # ---- the value layer: pending register values (SYMBOLIC)
    def tmp(self) -> str:
        self.ntmp += 1
        return f"_y{self.ntmp}"

    def val(self, r: int) -> _Val:
        """The value of data register ``r`` here: pending, or its local."""
        v = self.pend.get(r)
        return v if v is not None else _Val(self.rg(r), 0, M32)

    def force(self, v: _Val) -> str:
        if not isinstance(v.e, str):
            v.e = v.e()
        return v.e

    def bind(self, v: _Val) -> _Val:
        """``v`` as a name or literal: a composite value is assigned to a fresh temporary (one statement)."""
        e = self.force(v)
        if _ATOM.match(e):
            return v
        x = self.u(v)  # the exact value: a value read twice is mostly read as itself
        t = self.memo.get(x)
        if t is None:
            t = self.memo[x] = self.tmp()
            self.emit(f"{t} = {x}")
        return _Val(t, 0, v.hi if v.exact() else M32, None, v.whi)

    def take(self, r: int, dst: int | None) -> _Val:
        """The value of data register ``r`` as an operand of an instruction that writes ``dst`` (None: of a
        statement). A composite value that another instruction reads again is bound to a temporary first (then it
        is computed once); one read only once (the register is overwritten next) is composed into the reader."""
        v = self.val(r)
        if r == dst or r not in self.pend or (isinstance(v.e, str) and _ATOM.match(v.e)):
            return v
        if self.later(r):
            v = self.pend[r] = self.bind(v)
        return v

    def setv(self, r: int, v: _Val) -> None:
        if v.lo < -(1 << 60) or v.hi > 1 << 60:  # keep the integers small: the exact value
            v = _Val(f"({self.force(v)} & {M32})", 0, M32, v.w, v.whi)
        if isinstance(v.e, str) and len(v.e) > 400:  # keep expressions (and their nesting) small
            v = self.bind(v)
        self.pend[r] = v

    def u(self, v: _Val) -> str:
        """Expression of the exact (unsigned 32-bit) value of ``v``."""
        e = self.force(v)
        return e if v.exact() else f"({e} & {M32})"

    def s32(self, v: _Val) -> tuple[str, int, int]:
        """Expression of the signed 32-bit value of ``v`` and its range."""
        e = self.force(v)
        if -SIGN[4] <= v.lo and v.hi < SIGN[4]:
            return e, v.lo, v.hi
        if e.isdigit():
            k = _sx(int(e), 4)
            return _lit(k), k, k
        return f"(({self.u(v)} ^ {SIGN[4]}) - {SIGN[4]})", -SIGN[4], SIGN[4] - 1

    def low(self, v: _Val, nb: int) -> str:
        """Expression of the low ``nb`` bytes of ``v`` (exact)."""
        if nb == 4:
            return self.u(v)
        m = MASK[nb]
        if v.w is not None:
            base, ok = v.w, v.whi <= m
        else:
            base, ok = self.force(v), 0 <= v.lo and v.hi <= m
        if base.lstrip("-").isdigit():
            return str(int(base) & m)
        return base if ok else f"({base} & {m})"

    @staticmethod
    def lowhi(v: _Val, nb: int) -> int:
        if nb == 4:
            return v.hi if v.exact() else M32
        return min(MASK[nb], v.whi)

    def sx16(self, v: _Val) -> tuple[str, int, int]:
        """Expression of the low word of ``v`` sign-extended (a Python int) and its range."""
        if -0x8000 <= v.lo and v.hi <= 0x7FFF:
            return self.force(v), v.lo, v.hi
        x = self.low(v, 2)
        if x.isdigit():
            k = _sx(int(x), 2)
            return _lit(k), k, k
        if v.whi <= 0x7FFF:
            return x, 0, v.whi
        return f"(({x} ^ 32768) - 32768)", -0x8000, 0x7FFF

    def merge(self, d: _Val, nb: int, x: str, xhi: int) -> _Val:
        """Register value ``d`` with its low ``nb`` bytes replaced by ``x`` (exact, at most ``xhi``)."""
        if nb == 4:
            return _Val(x, 0, xhi)
        m = MASK[nb]
        keep = M32 ^ m
        w, whi = (x, xhi) if nb == 2 else (None, None)
        if d.exact() and d.hi <= m:
            return _Val(x, 0, xhi, w, whi)
        de = self.force(d)
        if de.isdigit():
            k = int(de) & keep
            return _Val(f"({k} | {x})" if k else x, 0, k | m, w, whi)
        return _Val(f"(({de} & {keep}) | {x})", 0, (d.hi if d.exact() else M32) | m, w, whi)

    def vflags(self, x: str, nb: int, need: int, reg: int | None = None) -> str:
        """N/Z (V, C cleared) from the exact ``nb``-byte value ``x`` when ``need`` asks for them; returns an
        expression of the same value (a temporary bound by the flag line when ``x`` is composite). ``reg``: ``x``
        is the whole new value of that data register: the flag line may assign it to the register's local
        straight away (when no other pending value names that local); the result is then the local's name and
        the caller drops the register's pending value."""
        if not need & _FLAGS_NZVC:
            return x
        if self.fusing is not None:  # only the next Bcc reads them: it tests the value itself
            return self.fuse_nz(x, nb, reg)
        if self.defer:  # deferred: pf = x (logic_flags)
            self.logic_flags(x, nb, need)
            return x
        if x.isdigit():
            self.emit(f"sr = (sr & 0xFF10) | {_nz(int(x), nb)}")
            return x
        if _ATOM.match(x):
            self.emit(f"sr = (sr & 0xFF10) | {self.nz(x, nb)}")
            return x
        t = self.tmp()
        if reg is not None and self.free(reg):
            t = self.wg(reg)
        if need & NF:
            self.emit(f"sr = (sr & 0xFF10) | (4 if not ({t} := {x}) else {t} >> {BITS[nb] - 4} & 8)")
        else:  # N is dead: only Z is asked for
            self.emit(f"sr = (sr & 0xFF10) | (0 if ({t} := {x}) else 4)")
        return t

    def fuse_setup(self, conds: frozenset[int], keep: int | None) -> None:
        """Flag/branch fusion. When this instruction's N/Z/V/C are read only by the Bcc right after it on the
        straight line (``nxt``: none of them is live after the branch on either path, by the planner's liveness,
        which makes every flag live at block exits, around instructions that may fault and after a loop's back
        edge) and the branch's condition is in ``conds``, the instruction's flag code assigns no flag: it gives
        the branch's test instead (``fused``, taken by :meth:`branch_test`); X and any flag live after the branch
        are left as they are or computed by the instruction as before. Between the two nothing can fault or
        leave, so nothing can observe the flags not assigned. First every pending value but register ``keep``'s
        is assigned (they would be at the branch anyway): the assignments the branch makes before its ``if``
        then change no local that the test reads."""
        self.fusing = None
        nx = self.nxt
        if nx is None or nx[1] & _FLAGS_NZVC or nx[0] not in conds or self.lazy is not None or self.defer:
            return
        self.flush(set(self.pend) - {keep})
        self.fusing = nx[0]

    def fuse_nz(self, x: str, nb: int, reg: int | None, used: bool = True) -> str:
        """The fused form of :meth:`vflags`: the next Bcc tests the exact ``nb``-byte value ``x`` itself (its N/Z,
        V and C clear). Returns an expression of the value, as :meth:`vflags` does: the register's local when the
        test assigns it (``(d0 := x)``: ``reg`` given and free), else an atom (``x`` or a temporary assigned now).
        ``used`` False: only the test reads the value (TST): it is computed in the test."""
        cond, self.fusing = self.fusing, None
        assert cond is not None
        if _ATOM.match(x):
            v = first = x
        elif not used:
            v = first = x if _paren(x) else f"({x})"
        elif reg is not None and self.free(reg):
            v = self.wg(reg)
            first = f"({v} := {x})"
        else:
            v = first = self.tmp()
            self.emit(f"{v} = {x}")
        self.fused = (cond, *_nz_tests(first, nb, cond))
        return v

    def branch_test(self, cond: int, holds: bool = True) -> str:
        """The ``if`` test of a Bcc with condition ``cond`` (``holds``: true when it holds; else when it does not):
        the fused test of the instruction before (:meth:`fuse_setup`), or the test of ``sr``."""
        f, self.fused = self.fused, None
        if f is not None:
            assert f[0] == cond, "a fused test taken by another branch"
            return f[1] if holds else f[2]
        return _COND_EXPR[cond] if holds else _COND_EXPR[cond ^ 1]

    def free(self, r: int) -> bool:
        """True when no pending value other than register ``r``'s own names ``r``'s local (it may be assigned)."""
        name = _RN[r]
        return not any(q != r and name in _DREF.findall(self.force(v)) for q, v in self.pend.items())

    def setx(self, r: int, x: str, v: _Val) -> None:
        """Register ``r``'s new value ``v`` (whose expression is ``x`` unless :meth:`vflags` returned the
        register's own local: then it is assigned already)."""
        if x == _RN[r]:
            self.pend.pop(r, None)
        else:
            self.setv(r, v)

    def flush(self, regs: set[int] | None = None, extra: set[str] = frozenset()) -> None:
        """Assign pending values to their register locals: all of them (``regs`` None), or those of ``regs`` and
        every pending value that names one of their locals or a local in ``extra`` (those locals are about to
        change)."""
        self.memo.clear()  # (also at every control-flow point: a temporary bound on one path only)
        if not self.pend:
            return
        texts = {q: self.u(v) for q, v in self.pend.items()}  # before any assignment (may bind temporaries)
        if self.fused is not None:  # the branch's fused test follows these assignments: they must not touch it
            changed = {_RN[q] for q, t in texts.items() if t != _RN[q]}
            named = set(re.findall(r"\b\w+\b", " ".join(texts.values())))
            assert not changed.intersection(re.findall(r"\b\w+\b", self.fused[1])) and \
                not named.intersection(_WALRUS.findall(self.fused[1])), "a fused test over a changing local"
        if regs is None:
            todo = set(self.pend)
        else:
            todo = {r for r in regs if r in self.pend}
            names = {_RN[r] for r in regs} | extra
            grow = True
            while grow:
                grow = False
                for q, t in texts.items():
                    if q not in todo and names.intersection(_DREF.findall(t)):
                        todo.add(q)
                        names.add(_RN[q])
                        grow = True
        for q in todo:
            del self.pend[q]
        self.shifted.clear()
        order = [q for q in sorted(todo) if texts[q] != _RN[q]]
        refs = {q: set(_DREF.findall(texts[q])) for q in order}
        while order:
            ready = [q for q in order if not any(_RN[q] in refs[o] for o in order if o != q)]
            if not ready:  # a cycle (EXG): one tuple assignment
                self.emit(f"{', '.join(self.wg(q) for q in order)} = {', '.join(texts[q] for q in order)}")
                break
            for q in ready:
                self.emit(f"{self.wg(q)} = {texts[q]}")
                order.remove(q)

    def pre_flush(self, ins: Instruction, h: str, pc: int) -> None:
        """Before an instruction the value layer does not take: everything is assigned when it may fault (the
        fault unwinding reads every register local) or branch/leave; else its own data registers."""
        self.memo.clear()
        if not self.pend:
            return
        ops = ins.operands
        if h in _CONTROL or _may_fault(ins, h, self.facts, pc, self.code) or (
                ops and ops[-1].mode in _MEMORY_MODES and h not in _READ_ONLY_DST):
            # (a memory write: its generated slow path may leave the block after writing compiled code even where
            # the planner knows it cannot fault and cannot rewrite this block)
            self.flush()
            return
        regs = set()
        for o in ins.operands:
            if o.mode is _M.DREG:
                regs.add(o.reg)
            elif o.index is not None and not o.index.is_areg:
                regs.add(o.index.num)
        self.flush(regs)

    def move_const(self, ins: Instruction, nb: int, need: int, pc: int) -> int | None:
        """MOVE between a data register (or an immediate) and a constant address the map guarantees, which cannot
        fault (:func:`isa.block_plan._may_fault`): a read goes straight into the register's local (a long) or
        into a temporary merged into its value; a write stores the register's value without assigning it."""
        src, dst = ins.operands
        if _may_fault(ins, "move", self.facts, pc, self.code):
            return None
        if dst.mode is _M.DREG and src.mode in (_M.ABSW, _M.ABSL, _M.PCDISP):
            r = dst.reg
            if need & _FLAGS_NZVC:
                self.fuse_setup(_NZ_CONDS, r)
            ld = self.load(nb, self.addr(src, nb, pc, "ea"))
            if nb == 4:
                self.pend.pop(r, None)  # overwritten whole; the names of its old local in pending values:
                self.flush(set(), {_RN[r]})
                dn = self.wg(r)
                self.emit(f"{dn} = {ld}")
                self.vflags(dn, 4, need)
                return timing.cycles(ins)
            t = self.tmp()
            self.emit(f"{t} = {ld}")
            self.setv(r, self.merge(self.val(r), nb, self.vflags(t, nb, need), MASK[nb]))
            return timing.cycles(ins)
        if src.mode in (_M.DREG, _M.IMM) and dst.mode in (_M.ABSW, _M.ABSL):
            if src.mode is _M.IMM:
                x = str(src.value & MASK[nb])
            else:
                x = self.low(self.take(src.reg, None), nb)
            if not _ATOM.match(x):
                self.emit(f"v = {x}")
                x = "v"
            self.logic_flags(x, nb, need)
            self.write(nb, self.addr(dst, nb, pc, "eb"), x, last=True)
            return timing.cycles(ins)
        return None

    def symbolic(self, ins: Instruction, h: str, need: int, pc: int) -> int | None:
        """Take a register-only data instruction into the value layer: its result becomes the pending value of its
        register (no statement), flags are emitted when asked for. Returns its clocks, or None when it is left to
        the statement generator (memory operands, address registers, shifts with live flags, MUL by a register,
        ADD/SUB with live flags in a block with lazy flags). One step per instruction family (:data:`_SYM_STEPS`,
        each called with the instruction, its handler name, ``need``, ``pc``, size in bytes, source operand (None
        for one operand), destination data register, whether the source is that register, and the NZVC asked for)."""
        if h not in _SYM:
            return None
        ops = ins.operands
        if h == "moveq":
            k = _sx(ops[0].value & 0xFF, 1) & M32
            self.setv(ops[1].reg, _Val(str(k), k, k))
            if need & _FLAGS_NZVC:
                self.emit(f"sr = (sr & 0xFF10) | {_nz(k, 4)}")
            return 4
        nb = _nb(ins)
        src, dst = (ops[0], ops[1]) if len(ops) == 2 else (None, ops[0])
        if h == "move" and (dst.mode is not _M.DREG or src.mode not in (_M.DREG, _M.IMM)):
            return self.move_const(ins, nb, need, pc)
        if dst.mode is not _M.DREG or (src is not None and src.mode not in (_M.DREG, _M.IMM) and (
                src.mode not in _CONST_SRC or _may_fault(ins, h, self.facts, pc, self.code))):
            return None
        r = dst.reg
        same = src is not None and src.mode is _M.DREG and src.reg == r
        nzvc = need & _FLAGS_NZVC
        if nzvc and h in _FUSE_NZ:
            self.fuse_setup(_NZ_ONLY if h in _FUSE_ARITH else _NZ_CONDS, r)
        return _SYM_STEPS[h](self, ins, h, need, pc, nb, src, r, same, nzvc)

    def _sym_operand(self, o: Operand, dest: int | None, n: int, pc: int) -> _Val:
        """The value of the ``n``-byte source operand ``o`` of the instruction at ``pc``: an immediate, a constant
        address the map guarantees (read now: it cannot fault) or a data register (:meth:`take` for ``dest``)."""
        if o.mode is _M.IMM:
            k = o.value & MASK[n]
            return _Val(str(k), k, k)
        if o.mode is not _M.DREG:  # a constant address the map guarantees (cannot fault): read it now
            t = self.tmp()
            self.emit(f"{t} = {self.load(n, self.addr(o, n, pc, 'ea'))}")
            return _Val(t, 0, MASK[n])
        return self.take(o.reg, dest)

    def _s_exg(self, ins: Instruction, h: str, need: int, pc: int, nb: int, src: Operand | None, r: int, same: bool,
               nzvc: int) -> int | None:
        """EXG Dx,Dy: the two pending values trade places."""
        if src.mode is not _M.DREG:
            return None
        a, b = self.val(src.reg), self.val(r)
        self.pend[src.reg], self.pend[r] = b, a
        return timing.cycles(ins)

    def _s_cmp(self, ins: Instruction, h: str, need: int, pc: int, nb: int, src: Operand | None, r: int, same: bool,
               nzvc: int) -> int | None:
        """CMP/CMPI into a data register: flags only (or a test fused into the next Bcc)."""
        M = MASK[nb]
        if nzvc:
            self.fuse_setup(_CMP_CONDS, None)
            s, d = self._sym_operand(src, None, nb, pc), self.take(r, None)
            ls, ld = self.low(s, nb), self.low(d, nb)
            if self.fusing is not None:  # only the next Bcc reads them: it compares the operands itself
                cond, self.fusing = self.fusing, None
                kind, op = _CMP_COND[cond]
                if kind == "s":
                    ls = _lit(_sx(int(ls), nb)) if ls.isdigit() else f"(({ls} ^ {SIGN[nb]}) - {SIGN[nb]})"
                    ld = _lit(_sx(int(ld), nb)) if ld.isdigit() else f"(({ld} ^ {SIGN[nb]}) - {SIGN[nb]})"
                self.fused = (cond, f"{ld} {op} {ls}", f"{ld} {_NOT_OP[op]} {ls}")
            elif nzvc == CF:
                self.emit(f"sr = (sr & 0xFF1E) | (1 if {ld} < {ls} else 0)")
            elif nzvc == ZF:
                self.emit(f"sr = (sr & 0xFF1B) | (4 if {ld} == {ls} else 0)")
            else:
                if not _ATOM.match(ls):
                    self.emit(f"s = {ls}")
                    ls = "s"
                if not _ATOM.match(ld):
                    self.emit(f"x = {ld}")
                    ld = "x"
                self.emit(f"r = {ld} - {ls}")
                self.emit(f"rm = r & {M}")
                self.arith_flags("cmp", nb, ls, ld, need)
        return timing.cycles(ins)

    def _s_tst(self, ins: Instruction, h: str, need: int, pc: int, nb: int, src: Operand | None, r: int, same: bool,
               nzvc: int) -> int | None:
        """TST Dn: flags only (or a test fused into the next Bcc)."""
        if nzvc:
            self.fuse_setup(_NZ_CONDS, None)
        x = self.low(self.take(r, None), nb)
        if self.fusing is not None:
            self.fuse_nz(x, nb, None, used=False)
        else:
            self.vflags(x, nb, need)
        return timing.cycles(ins)

    def _s_move(self, ins: Instruction, h: str, need: int, pc: int, nb: int, src: Operand | None, r: int, same: bool,
                nzvc: int) -> int | None:
        """MOVE of a data register or an immediate into a data register."""
        s = self._sym_operand(src, r, nb, pc)
        if nb == 4:
            if nzvc:
                x = self.vflags(self.u(s), 4, need, r)
                if x == _RN[r]:
                    self.pend.pop(r, None)
                    return timing.cycles(ins)
                s = s if x == s.e else _Val(x, 0, s.hi if s.exact() else M32, None, s.whi)
            self.setv(r, s)
            return timing.cycles(ins)
        d = self.val(r)
        if same:
            d = s = self.bind(d)
        x, xhi = self.low(s, nb), self.lowhi(s, nb)
        self.setv(r, self.merge(d, nb, self.vflags(x, nb, need), xhi))
        return timing.cycles(ins)

    def _s_logic(self, ins: Instruction, h: str, need: int, pc: int, nb: int, src: Operand | None, r: int, same: bool,
                 nzvc: int) -> int | None:
        """AND/OR/EOR (and the immediate forms) into a data register."""
        M = MASK[nb]
        kind = h.rstrip("i")
        op = {"and": "&", "or": "|", "eor": "^"}[kind]
        s = self._sym_operand(src, r, nb, pc)
        d = self.val(r)
        if same:
            d = s = self.bind(d)
        if nb == 4 or not nzvc:
            if kind == "and":
                se = self.u(s) if nb == 4 else self.low(s, nb)
                de = self.force(d)
                mask = int(se) | (M32 ^ M) if se.isdigit() else None
                if mask is not None:  # any representative of d: & a constant <= 2^32-1 is exact
                    e, hi = f"({de} & {mask})", min(mask, d.hi) if d.lo >= 0 else mask
                else:
                    se = se if nb == 4 else f"({se} | {M32 ^ M})"
                    e, hi = f"({self.u(d)} & {se})", min(s.hi if s.exact() else M32, d.hi if d.exact() else M32)
                    if nb != 4:
                        hi = d.hi if d.exact() else M32
                if de.isdigit() and not self.force(s).isdigit():  # a constant d: & it the other way round
                    k = int(de)
                    e, hi = f"({self.force(s)} & {k & M})", k & M
                    if k & (M32 ^ M):
                        e, hi = f"({k & (M32 ^ M)} | {e})", k
            else:
                de, se = self.u(d), (self.u(s) if nb == 4 else self.low(s, nb))
                hi = (1 << max(d.hi if d.exact() else M32, self.lowhi(s, nb)).bit_length()) - 1
                e = f"({de} {op} {se})"
            if nb == 4:
                x = self.vflags(e, 4, need, r)
                self.setx(r, x, _Val(x, 0, hi))
            else:
                self.setv(r, _Val(e, 0, hi))
            return timing.cycles(ins)
        d = self.bind(d) if s is not d else d
        ld, ls = self.low(d, nb), self.low(s, nb)
        if kind == "and" and ls.isdigit() and not ld.isdigit():
            x, xhi = f"({self.force(d)} & {ls})", int(ls)
        elif kind == "and" and ld.isdigit() and not ls.isdigit():
            x, xhi = f"({self.force(s)} & {ld})", int(ld)
        else:
            x = f"({ld} {op} {ls})"
            xhi = min(self.lowhi(s, nb), self.lowhi(d, nb)) if kind == "and" else M
        whole = d.exact() and d.hi <= M
        x = self.vflags(x, nb, need, r if whole else None)
        self.setx(r, x, self.merge(d, nb, x, xhi))
        return timing.cycles(ins)

    def _s_addsub(self, ins: Instruction, h: str, need: int, pc: int, nb: int, src: Operand | None, r: int, same: bool,
                  nzvc: int) -> int | None:
        """ADD/SUB (immediate and quick forms included) into a data register."""
        M = MASK[nb]
        flags = need & _ALL_FLAGS
        if flags and self.lazy is not None:
            return None
        add = h.startswith("add")
        if h in ("addq", "subq"):
            s = _Val(str(src.value & M), src.value & M, src.value & M)
        else:
            s = self._sym_operand(src, r, nb, pc)
        d = self.val(r)
        if same:
            d = s = self.bind(d)
        if nb == 4 and not flags:
            de, se = self.force(d), self.force(s)
            if add:
                self.setv(r, _Val(f"({de} + {se})", d.lo + s.lo, d.hi + s.hi))
            elif se == "0":
                self.setv(r, d)
            else:
                self.setv(r, _Val(f"({de} - {se})", d.lo - s.hi, d.hi - s.lo))
            return timing.cycles(ins)
        if nb != 4:
            d = self.bind(d) if s is not d else d
        de, se = self.low(d, nb), self.low(s, nb)
        dhi, shi = self.lowhi(d, nb), self.lowhi(s, nb)
        if flags and self.fusing is not None:  # only the next Bcc reads N or Z: it tests the result; X (C with
            # it: dead after the branch) is assigned when it is live
            if need & XF:
                t = self.tmp()
                self.emit(f"{t} = {de} + {se}" if add else f"{t} = {de} - {se}")
                self.arith_flags("add" if add else "sub", nb, se, de, XF, t, None)
                rme = f"({t} & {M})"
            else:
                rme = f"(({de} + {se}) & {M})" if add else f"(({de} - {se}) & {M})"
            x = self.fuse_nz(rme, nb, r if nb == 4 else None)
            self.setx(r, x, _Val(x, 0, M) if nb == 4 else self.merge(d, nb, x, M))
            return timing.cycles(ins)
        if not flags:
            if add:
                x = f"({de} + {se})" if dhi + shi <= M else f"(({de} + {se}) & {M})"
                xhi = min(dhi + shi, M)
            else:
                x, xhi = (de, dhi) if se == "0" else (f"(({de} - {se}) & {M})", M)
            self.setv(r, self.merge(d, nb, x, xhi))
            return timing.cycles(ins)
        if need & VF:  # the overflow test reads both operands again
            if not _ATOM.match(de):
                de = self.bind(_Val(de, 0, dhi)).e
            if same:
                se = de
            elif not _ATOM.match(se):
                se = self.bind(_Val(se, 0, shi)).e
        t = self.tmp()
        self.emit(f"{t} = {de} + {se}" if add else f"{t} = {de} - {se}")
        if need & (NF | ZF | VF):
            rm = self.tmp()
            self.emit(f"{rm} = {t} & {M}")
            res = _Val(rm, 0, M)
        else:
            rm = None
            res = _Val(t, 0, dhi + shi) if add else _Val(t, -shi, dhi)
        self.arith_flags("add" if add else "sub", nb, se, de, need, t, rm)
        self.setv(r, res if nb == 4 else self.merge(d, nb, self.low(res, nb), M))
        return timing.cycles(ins)

    def _s_unary(self, ins: Instruction, h: str, need: int, pc: int, nb: int, src: Operand | None, r: int, same: bool,
                 nzvc: int) -> int | None:
        """CLR/NOT/NEG of a data register (NEG only with its flags dead)."""
        M = MASK[nb]
        if h == "neg" and need & _ALL_FLAGS:
            return None
        d = self.val(r)
        if h == "clr":
            if nzvc:
                self.emit("sr = (sr & 0xFF10) | 4")
            self.setv(r, self.merge(d, nb, "0", 0))
            return timing.cycles(ins)
        if nb == 4 and not nzvc:
            de = self.force(d)
            self.setv(r, _Val(f"(~{de})", -d.hi - 1, -d.lo - 1) if h == "not" else _Val(f"(-{de})", -d.hi, -d.lo))
            return timing.cycles(ins)
        d = self.bind(d)
        ld = self.low(d, nb)
        x = f"({ld} ^ {M})" if h == "not" else f"(-{ld} & {M})"
        self.setv(r, self.merge(d, nb, self.vflags(x, nb, need), M))
        return timing.cycles(ins)

    def _s_swap(self, ins: Instruction, h: str, need: int, pc: int, nb: int, src: Operand | None, r: int, same: bool,
                nzvc: int) -> int | None:
        """SWAP Dn: the two words trade places."""
        d = self.val(r)
        if d.exact() and d.hi <= 0xFFFF:
            x = f"({self.force(d)} << 16)"
            self.setv(r, _Val(self.vflags(x, 4, need), 0, d.hi << 16, "0", 0))
            return timing.cycles(ins)
        ue = self.u(d)
        uhi = d.hi if d.exact() else M32
        w, whi = f"({ue} >> 16)", uhi >> 16
        if _ATOM.match(ue) or nzvc:
            if not _ATOM.match(ue):
                d = self.bind(_Val(ue, 0, uhi))
                ue = d.e
                w = f"({ue} >> 16)"
            x = self.vflags(f"(({self.low(d, 2)} << 16) | ({ue} >> 16))", 4, need, r)
            self.setx(r, x, _Val(x, 0, M32, w, whi))
            return timing.cycles(ins)

        def make(d: _Val = _Val(ue, 0, uhi)) -> str:  # both halves of a composite value: bound once, if needed
            t = self.bind(d)
            return f"(({self.low(t, 2)} << 16) | ({t.e} >> 16))"

        self.setv(r, _Val(make, 0, M32, w, whi))
        return timing.cycles(ins)

    def _s_ext(self, ins: Instruction, h: str, need: int, pc: int, nb: int, src: Operand | None, r: int, same: bool,
               nzvc: int) -> int | None:
        """EXT.W / EXT.L Dn."""
        d = self.val(r)
        if ins.size is Size.W:
            d = self.bind(d)
            b, bhi = self.low(d, 1), self.lowhi(d, 1)
            x, xhi = (b, bhi) if bhi <= 0x7F else (f"((({b} ^ 128) - 128) & 65535)", 0xFFFF)
            self.setv(r, self.merge(d, 2, self.vflags(x, 2, need), xhi))
            return timing.cycles(ins)
        w, lo, hi = self.sx16(d)
        ww = self.low(d, 2)
        if nzvc:
            x = self.vflags(w if lo >= 0 else f"({w} & {M32})", 4, need, r)
            self.setx(r, x, _Val(x, 0, hi if lo >= 0 else M32, None, d.whi))
        else:
            self.setv(r, _Val(w, lo, hi, ww if _ATOM.match(ww) else None, min(d.whi, 0xFFFF)))
        return timing.cycles(ins)

    def _s_mul(self, ins: Instruction, h: str, need: int, pc: int, nb: int, src: Operand | None, r: int, same: bool,
               nzvc: int) -> int | None:
        """MULU/MULS into a data register: by a register (data-dependent clocks) or a known source."""
        if src.mode is _M.IMM:
            return self._s_mul_imm(h, need, src, r, nzvc, timing.EA_TIME[_M.IMM][0])
        sv = self._sym_operand(src, r, 2, pc)
        d = self.val(r)
        if same:
            d = sv = self.bind(d)
        t = self.low(sv, 2)
        if t.isdigit():  # a known source: constant clocks, as MUL #imm
            return self._s_mul_imm(h, need, Operand(_M.IMM, value=int(t)), r, nzvc, timing.EA_TIME[_M.DREG][0])
        if not _ATOM.match(t):
            t = self.bind(_Val(t, 0, sv.whi)).e
            sv = _Val(t, 0, sv.whi)
        if h == "mulu":
            self.cycles(f"2 * {t}.bit_count()")
            x, lo, hi = f"({t} * {self.low(d, 2)})", 0, 0xFFFF * d.whi
        else:
            self.cycles(f"2 * (({t} << 1 ^ {t}) & 0xFFFF).bit_count()")
            a, alo, ahi = self.sx16(sv)
            b, blo, bhi = self.sx16(d)
            ps = (alo * blo, alo * bhi, ahi * blo, ahi * bhi)
            x, lo, hi = f"({a} * {b})", min(ps), max(ps)
        if nzvc:
            x = self.vflags(x if lo >= 0 else f"({x} & {M32})", 4, need, r)
            lo, hi = 0, (hi if lo >= 0 else M32)
        self.setx(r, x, _Val(x, lo, hi))
        return 38 + timing.EA_TIME[src.mode][0]

    def _s_mul_imm(self, h: str, need: int, src: Operand, r: int, nzvc: int, ea: int) -> int | None:
        """MULU/MULS by a known 16-bit source (``src`` an immediate), its EA time ``ea``."""
        k = src.value & 0xFFFF
        d = self.val(r)
        if h == "mulu":
            x, lo, hi = f"({k} * {self.low(d, 2)})", 0, k * d.whi
            extra = 2 * k.bit_count()
        else:
            ks = _sx(k, 2)
            w, wlo, whi = self.sx16(d)
            x, lo, hi = f"({_lit(ks)} * {w})", min(ks * wlo, ks * whi), max(ks * wlo, ks * whi)
            y = k << 1
            extra = 2 * ((y ^ (y >> 1)) & 0xFFFF).bit_count()
        if k == 0:
            x, lo, hi = "0", 0, 0
        if nzvc:
            x = self.vflags(x if lo >= 0 else f"({x} & {M32})", 4, need, r)
            lo, hi = 0, (hi if lo >= 0 else M32)
        self.setx(r, x, _Val(x, lo, hi))
        return 38 + ea + extra

    def _s_shift(self, ins: Instruction, h: str, need: int, pc: int, nb: int, src: Operand | None, r: int, same: bool,
                 nzvc: int) -> int | None:
        """ASL/ASR/LSL/LSR.L of a data register by an immediate or a known count."""
        # shifts: long, by an immediate or by a register holding a known count (with live flags: ASR/LSR/LSL by
        # 1..31 only)
        if nb != 4 or len(ins.operands) != 2:
            return None
        if src.mode is _M.IMM:
            n = src.value
            base = timing.cycles(ins)
        else:
            c = self.val(src.reg)
            if not (isinstance(c.e, str) and c.e.isdigit()):
                return None
            n = int(c.e) & 63
            base = 8 + 2 * n
        d = self.val(r)
        if need & _ALL_FLAGS:
            if h == "asl" or not 1 <= n <= 31:
                return None
            if h == "asr":
                x = self.s32(d)[0]
            else:
                x = self.u(d)
            if not _ATOM.match(x):  # read twice (result and carry); ASR's is the signed value: no bind()
                t = self.tmp()
                self.emit(f"{t} = {x}")
                x = t
            c = f"{x} >> {32 - n} & 1" if h == "lsl" else f"{x} >> {n - 1} & 1"
            e = f"({x} << {n}) & {M32}" if h == "lsl" else (f"({x} >> {n}) & {M32}" if h == "asr" else f"{x} >> {n}")
            t = self.wg(r) if self.free(r) else self.tmp()
            self.emit(f"sr = (sr & 0xFF00) | (0x11 if {c} else 0) | (4 if not ({t} := {e}) else {t} >> 28 & 8)")
            self.setx(r, t, _Val(t, 0, M32))
            return base
        if n == 0:
            self.setv(r, d)
            return base
        kind = "lsl" if h == "asl" else h
        prev = self.shifted.get(d.e) if isinstance(d.e, str) else None
        if prev is not None and prev[0] == kind:  # a shift of a shift: one shift by the sum
            _, e, lo, hi, k = prev
            n += k
        elif kind == "lsl":
            e, lo, hi = self.force(d), d.lo, d.hi
        elif kind == "lsr":
            e, lo, hi = self.u(d), 0, d.hi if d.exact() else M32
        else:
            e, lo, hi = self.s32(d)
        if kind != "asr" and n >= 32:
            self.setv(r, _Val("0", 0, 0))
            return base
        v = _Val(f"({e} << {n})", lo << n, hi << n) if kind == "lsl" else _Val(f"({e} >> {n})", lo >> n, hi >> n)
        self.shifted[v.e] = (kind, e, lo, hi, n)
        self.setv(r, v)
        return base

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
        if self.sym:
            sc = self.symbolic(ins, h, need, pc)
            self.fusing = None  # (a fused test not given: the flags were assigned)
            if sc is not None:
                return sc, False
            self.pre_flush(ins, h, pc)
        emitter = _EMITTERS.get(h)
        if emitter is None:
            raise _Unblockable(h)  # trap, illegal: the per-instruction path handles them
        return emitter(self, _Ins(ins, ops, nb, M, h, cond, pc, nxt, need, base, n_done, prefix))

    def _i_moveq(self, e: _Ins) -> tuple[int, bool]:
        """MOVEQ."""
        ins, ops, nb, M, h, cond, pc, nxt, need, base, n_done, prefix = e
        v = _sx(ops[0].value & 0xFF, 1) & M32
        self.emit(f"{self.wg(ops[1].reg)} = {v}")
        if need & _FLAGS_NZVC:
            self.emit(f"sr = (sr & 0xFF10) | {_nz(v, 4)}")
        return base, False

    def _i_move(self, e: _Ins) -> tuple[int, bool]:
        """MOVE."""
        ins, ops, nb, M, h, cond, pc, nxt, need, base, n_done, prefix = e
        src, dst = ops
        if dst.mode is _M.DREG:
            if nb == 4 and src.mode not in (_M.DREG, _M.AREG, _M.IMM):  # straight into the register
                v = self.read(src, nb, pc, self.wg(dst.reg))
            else:
                v = self.read(src, nb, pc, "v", materialize=nb != 4 or src.mode not in (_M.DREG, _M.AREG))
                self.set_dreg(dst.reg, nb, v)
            self.logic_flags(self.rg(dst.reg) if nb == 4 else v, nb, need)
            return base, False
        v = self.read(src, nb, pc, "v", materialize=True)
        a = self.addr(dst, nb, pc, "eb")
        self.logic_flags(v, nb, need)
        self.write(nb, a, v, last=True)
        return base, False

    def _i_movea(self, e: _Ins) -> tuple[int, bool]:
        """MOVEA."""
        ins, ops, nb, M, h, cond, pc, nxt, need, base, n_done, prefix = e
        v = self.read(ops[0], nb, pc, "v")
        an = self.wg(8 + ops[1].reg)
        self.emit(f"{an} = {v}" if nb == 4 else f"{an} = (({v} ^ 0x8000) - 0x8000) & 0xFFFFFFFF")
        return base, False

    def _i_arith(self, e: _Ins) -> tuple[int, bool]:
        """ADD, ADDI, SUB, SUBI, CMP, CMPI, AND, ANDI, OR, ORI, EOR, EORI, ADDQ, SUBQ."""
        ins, ops, nb, M, h, cond, pc, nxt, need, base, n_done, prefix = e
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

    def _i_adda_suba(self, e: _Ins) -> tuple[int, bool]:
        """ADDA, SUBA."""
        ins, ops, nb, M, h, cond, pc, nxt, need, base, n_done, prefix = e
        v = self.read(ops[0], nb, pc, "v")
        an = self.wg(8 + ops[1].reg)
        sign = "+" if h == "adda" else "-"
        if nb == 2:
            v = f"((({v}) ^ 0x8000) - 0x8000)"
        self.emit(f"{an} = ({an} {sign} {v}) & 0xFFFFFFFF")
        return base, False

    def _i_cmpa(self, e: _Ins) -> tuple[int, bool]:
        """CMPA."""
        ins, ops, nb, M, h, cond, pc, nxt, need, base, n_done, prefix = e
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

    def _i_lea(self, e: _Ins) -> tuple[int, bool]:
        """LEA."""
        ins, ops, nb, M, h, cond, pc, nxt, need, base, n_done, prefix = e
        a = self.addr(ops[0], 4, pc, "ea")
        self.emit(f"{self.wg(8 + ops[1].reg)} = {a} & 0xFFFFFFFF")
        return base, False

    def _i_pea(self, e: _Ins) -> tuple[int, bool]:
        """PEA."""
        ins, ops, nb, M, h, cond, pc, nxt, need, base, n_done, prefix = e
        a = self.addr(ops[0], 4, pc, "ea")
        self.emit(f"v = {a} & 0xFFFFFFFF")
        self.push("v")
        return base, False

    def _i_unary(self, e: _Ins) -> tuple[int, bool]:
        """CLR, NOT, NEG, NEGX, TST."""
        ins, ops, nb, M, h, cond, pc, nxt, need, base, n_done, prefix = e
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

    def _i_cmpm(self, e: _Ins) -> tuple[int, bool]:
        """CMPM: (Ay)+,(Ax)+: Ay read and incremented first; flags as CMP (X kept)."""
        ins, ops, nb, M, h, cond, pc, nxt, need, base, n_done, prefix = e
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

    def _i_addx_subx(self, e: _Ins) -> tuple[int, bool]:
        """ADDX, SUBX."""
        ins, ops, nb, M, h, cond, pc, nxt, need, base, n_done, prefix = e
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

    def _i_ext(self, e: _Ins) -> tuple[int, bool]:
        """EXT."""
        ins, ops, nb, M, h, cond, pc, nxt, need, base, n_done, prefix = e
        dn = self.wg(ops[0].reg)
        if ins.size is Size.W:
            self.emit(f"v = ((({dn} & 0xFF) ^ 0x80) - 0x80) & 0xFFFF")
            self.emit(f"{dn} = ({dn} & 0xFFFF0000) | v")
            self.logic_flags("v", 2, need)
        else:
            self.emit(f"{dn} = ((({dn} & 0xFFFF) ^ 0x8000) - 0x8000) & 0xFFFFFFFF")
            self.logic_flags(dn, 4, need)
        return base, False

    def _i_swap(self, e: _Ins) -> tuple[int, bool]:
        """SWAP."""
        ins, ops, nb, M, h, cond, pc, nxt, need, base, n_done, prefix = e
        dn = self.wg(ops[0].reg)
        self.emit(f"{dn} = (({dn} << 16) | ({dn} >> 16)) & 0xFFFFFFFF")
        self.logic_flags(dn, 4, need)
        return base, False

    def _i_exg(self, e: _Ins) -> tuple[int, bool]:
        """EXG."""
        ins, ops, nb, M, h, cond, pc, nxt, need, base, n_done, prefix = e
        a, b = (self.wg(o.reg + (8 if o.mode is _M.AREG else 0)) for o in ops)
        self.emit(f"{a}, {b} = {b}, {a}")
        return base, False

    def _i_mul(self, e: _Ins) -> tuple[int, bool]:
        """MULU, MULS."""
        ins, ops, nb, M, h, cond, pc, nxt, need, base, n_done, prefix = e
        if ops[0].mode is _M.IMM:  # constant source:  constant clocks
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
        s = self.read(ops[0], 2, pc, "s", materialize=True)
        dn = self.wg(ops[1].reg)
        if h == "muls":
            self.emit(f"{dn} = ((({s} ^ 0x8000) - 0x8000) * ((({dn} & 0xFFFF) ^ 0x8000) - 0x8000)) "
                      "& 0xFFFFFFFF")
        else:
            self.emit(f"{dn} = {s} * ({dn} & 0xFFFF)")
        self.logic_flags(dn, 4, need)
        if h == "muls":
            self.cycles(f"2 * (({s} << 1 ^ {s}) & 0xFFFF).bit_count()")
        else:
            self.cycles(f"2 * {s}.bit_count()")
        return 38 + timing.EA_TIME[ops[0].mode][0], False

    def _i_div(self, e: _Ins) -> tuple[int, bool]:
        """DIVU, DIVS."""
        ins, ops, nb, M, h, cond, pc, nxt, need, base, n_done, prefix = e
        return self.divide(ops, h, pc, need), False

    def _i_shift(self, e: _Ins) -> tuple[int, bool]:
        """ASx, LSx, ROx, ROXx."""
        ins, ops, nb, M, h, cond, pc, nxt, need, base, n_done, prefix = e
        return self.shift(ins, h, nb, pc, need, base), False

    def _i_scc(self, e: _Ins) -> tuple[int, bool]:
        """SCC."""
        ins, ops, nb, M, h, cond, pc, nxt, need, base, n_done, prefix = e
        dst = ops[0]
        ce = _COND_EXPR[cond]
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

    def _i_branch(self, e: _Ins) -> tuple[int, bool]:
        """BCC, BRA, BSR."""
        ins, ops, nb, M, h, cond, pc, nxt, need, base, n_done, prefix = e
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
        self.emit(f"if {self.branch_test(cond)}:")
        self.ind += 1
        self.exit(target, n_done, prefix + timing.cycles(ins, taken=True))
        self.ind -= 1
        return timing.cycles(ins, taken=False), False

    def _i_dbcc(self, e: _Ins) -> tuple[int, bool]:
        """DBCC."""
        ins, ops, nb, M, h, cond, pc, nxt, need, base, n_done, prefix = e
        dn_op, tgt = ops
        target = tgt.value & 0xFFFFFF
        if target & 1:
            raise _Unblockable("odd branch target")
        ce = _COND_EXPR[cond]
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

    def _i_jump(self, e: _Ins) -> tuple[int, bool]:
        """JMP, JSR."""
        ins, ops, nb, M, h, cond, pc, nxt, need, base, n_done, prefix = e
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

    def _i_rts(self, e: _Ins) -> tuple[int, bool]:
        """RTS."""
        ins, ops, nb, M, h, cond, pc, nxt, need, base, n_done, prefix = e
        sp = self.wg(15)
        fault = self.const(_Fault, "Fault", ("Fault",))
        ae = self.const(AddressError, "AddressError", ("AddressError",))
        self.emit(f"v = {self.load(4, sp)}")
        self.emit(f"{sp} = ({sp} + 4) & 0xFFFFFFFF")
        self.emit(f"if v & 1 and (v & 0xFFFFFF) != {CALL_SENTINEL}:")
        self.emit(f"    raise {fault}({ae}, f\"return to odd address ${{v & 0xFFFFFF:06X}}\")")
        self.exit("(v & 0xFFFFFF)", n_done, prefix + base)
        return base, True

    def _i_movem(self, e: _Ins) -> tuple[int, bool]:
        """MOVEM."""
        ins, ops, nb, M, h, cond, pc, nxt, need, base, n_done, prefix = e
        self.movem(ins, nb, pc)
        return base, False

    def _i_nop(self, e: _Ins) -> tuple[int, bool]:
        """NOP."""
        ins, ops, nb, M, h, cond, pc, nxt, need, base, n_done, prefix = e
        return base, False


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
            self.emit("    q = -aq if sd < 0 else aq" if ss > 0 else "    q = aq if sd < 0 else -aq")
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


#: Handler name -> the :class:`_BlockGen` method that emits it (what :meth:`_BlockGen.instruction` dispatches on;
#: a handler without one, TRAP or ILLEGAL, is left to the per-instruction path).
_EMITTERS: dict[str, Any] = {
    "moveq": _BlockGen._i_moveq, "move": _BlockGen._i_move, "movea": _BlockGen._i_movea,
    **dict.fromkeys(("add", "addi", "sub", "subi", "cmp", "cmpi", "and", "andi", "or", "ori", "eor", "eori", "addq",
                     "subq"), _BlockGen._i_arith),
    "adda": _BlockGen._i_adda_suba, "suba": _BlockGen._i_adda_suba, "cmpa": _BlockGen._i_cmpa,
    "lea": _BlockGen._i_lea, "pea": _BlockGen._i_pea,
    **dict.fromkeys(("clr", "not", "neg", "negx", "tst"), _BlockGen._i_unary),
    "cmpm": _BlockGen._i_cmpm, "addx": _BlockGen._i_addx_subx, "subx": _BlockGen._i_addx_subx,
    "ext": _BlockGen._i_ext, "swap": _BlockGen._i_swap, "exg": _BlockGen._i_exg,
    "mulu": _BlockGen._i_mul, "muls": _BlockGen._i_mul, "divu": _BlockGen._i_div, "divs": _BlockGen._i_div,
    **dict.fromkeys(_SHIFT_NAMES, _BlockGen._i_shift),
    "scc": _BlockGen._i_scc, **dict.fromkeys(("bcc", "bra", "bsr"), _BlockGen._i_branch),
    "dbcc": _BlockGen._i_dbcc, "jmp": _BlockGen._i_jump, "jsr": _BlockGen._i_jump, "rts": _BlockGen._i_rts,
    "movem": _BlockGen._i_movem, "nop": _BlockGen._i_nop,
}


#: Handler name -> the :class:`_BlockGen` step of the value layer that takes it (:meth:`_BlockGen.symbolic`; MOVEQ
#: and the MOVEs to or from a constant address are taken before the dispatch).
_SYM_STEPS: dict[str, Any] = {
    "exg": _BlockGen._s_exg, "cmp": _BlockGen._s_cmp, "cmpi": _BlockGen._s_cmp, "tst": _BlockGen._s_tst,
    "move": _BlockGen._s_move, **dict.fromkeys(("and", "andi", "or", "ori", "eor", "eori"), _BlockGen._s_logic),
    **dict.fromkeys(("add", "addi", "addq", "sub", "subi", "subq"), _BlockGen._s_addsub),
    **dict.fromkeys(("clr", "not", "neg"), _BlockGen._s_unary), "swap": _BlockGen._s_swap, "ext": _BlockGen._s_ext,
    "mulu": _BlockGen._s_mul, "muls": _BlockGen._s_mul,
    **dict.fromkeys(("asl", "asr", "lsl", "lsr"), _BlockGen._s_shift),
}
assert _SYM_STEPS.keys() | {"moveq"} == _SYM

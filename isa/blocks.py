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
  (:func:`_quiet_write`: this block's instructions did not change). Instructions the block compiler does not take
  (TRAP, ILLEGAL, constant odd branch targets) end the block; the CPU runs them through :mod:`isa.closures`.
* The run loop starts a block only when ``bn >= info's most instructions`` and ``bc >`` the clock bound of one
  pass (:func:`_block_bound`) and ``until`` is not inside it: that keeps limits exact.
* Modules (a pure split of one module; no cycles: ``blocks`` imports both, ``block_codegen`` imports
  ``block_plan``, ``block_plan`` neither): :mod:`isa.block_plan` decides which instructions form a block
  (:func:`block_entries`, :data:`BLOCK_MAX`) and plans it (:func:`_plan`, :func:`_plan_tails`,
  :func:`_liveness`, :func:`_defer_flags`, :func:`_lazy_kind`, :func:`_may_fault`); :mod:`isa.block_codegen`
  (:class:`_BlockGen`) generates each instruction's code as planned; this module assembles the block function
  from them (:func:`_block_source`: paths, loop, exits, clock and count bookkeeping), compiles it (with the
  disk cache) and binds it (:func:`compile_block`, :class:`_BlockInfo`). Names other modules import from here
  (``BLOCK_MAX``, ``block_entries``, ``_RN``, ``_COND_EXPR``, ``_plan``) are re-exported.
"""

from __future__ import annotations

import re
import struct
from typing import Any

from isa import codecache, timing
# BLOCK_MAX, block_entries, _RN, _COND_EXPR and _plan are also imported from here (isa.cpu, tests): re-exported.
from isa.block_codegen import _COND_EXPR, _RN, _BlockGen
from isa.block_plan import (BLOCK_MAX, _Entry, _defer_flags, _lazy_kind, _liveness, _plan, _read_later,
                            block_entries)
from isa.errors import AddressError, DivideByZero
from isa.memory import MapFacts
from isa.semantics import M32, _Fault, _k_addx, _k_shift, _k_subx, _lowers_sp, _sx

__all__ = ["BLOCK_MAX", "block_entries", "compile_block"]

_UL, _PL = struct.Struct(">L").unpack_from, struct.Struct(">L").pack_into
_UW, _PW = struct.Struct(">H").unpack_from, struct.Struct(">H").pack_into


#: Registers (SR included) a block reads at its start from which it unpacks the whole register list in one statement
#: (``d0, d1, _, ... = R``) instead of one subscript each (timeit, CPU time: 11 of 17 registers 157 ns against 211 ns
#: for 11 subscripts; about even at 5-7).
_UNPACK_MIN = 7


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


class _Walk:
    """The walk of :func:`_block_source` over the entries of one block, generating each as planned through the
    block's :class:`_BlockGen`: straight-line instructions (:meth:`gen`), and one step per control-flow role of
    :func:`_plan` (:meth:`flow`: :meth:`dup`, :meth:`loop`, :meth:`branch`). Every step takes and returns the constant
    instruction count ``n`` and clocks ``cy`` done on the path it is on (the locals ``ni``/``c`` hold the rest)."""

    def __init__(self, entries: list[_Entry], facts: MapFacts, g: _BlockGen, role: dict[int, Any], head: int | None,
                 need: list[int]) -> None:
        self.entries = entries
        self.facts = facts
        self.g = g
        self.role = role
        self.need = need
        # One segment per generated copy of an entry (a duplicated tail generates entries more than once): the
        # entry, and the constant instruction count and clocks before it on the path that reaches that copy.
        self.segs: list[tuple[int, int, int]] = []
        # Entries reached other than by falling through from the entry before (values known there do not hold).
        self.targets = {head} if head is not None else set()
        for rr in role.values():
            self.targets.update(x for x in rr[1:] if isinstance(x, int))
        # The loop head: its address, and the count and clocks done when the walk reaches it (set by the caller).
        self.head_pc = self.n_head = self.c_head = 0

    def mark(self, i: int, n: int, cy: int) -> None:
        self.g.items.append((0, ("mark", len(self.segs))))
        self.segs.append((i, n, cy))

    def body_start(self) -> int:
        return len(self.g.items)

    def close_body(self, pos: int) -> None:
        if not any(isinstance(t, str) for _, t in self.g.items[pos:]):
            self.g.emit("pass")

    def adjust(self, dn: int, dc: int) -> None:
        pos = self.body_start()
        if dn:
            self.g.emit(f"ni += {dn}")
        if dc:
            self.g.emit(f"c += {dc}")
        self.close_body(pos)

    def loopback(self, n: int, cy: int) -> None:
        g = self.g
        if n != self.n_head:
            g.emit(f"ni += {n - self.n_head}")
        if cy != self.c_head:
            g.emit(f"c += {cy - self.c_head}")
        g.emit("if ni <= ln:")  # implies c < lc (see the cap before the loop)
        g.emit("    continue")
        g.exit(self.head_pc, self.n_head, self.c_head)

    def gen(self, lo: int, hi: int, n: int, cy: int) -> tuple[bool, int, int]:
        """Emit entries lo..hi-1 reached with ``n`` instructions and ``cy`` constant clocks done; return (every
        path has left the block, n, cy at ``hi``). A straight-line entry is emitted here (the per-instruction path
        of the compiler, kept in one frame), a control-flow role by :meth:`flow`."""
        entries, g, role, targets, need, facts = self.entries, self.g, self.role, self.targets, self.need, self.facts
        i = lo
        while i < hi:
            pc, ins, h, cond, length = entries[i]
            nxt = (pc + length) & 0xFFFFFF
            self.mark(i, n, cy)
            r = role.get(i)
            if r is not None:
                g.flush()  # control flow: pending register values are assigned before it
                ended, i, n, cy = self.flow(i, r, n, cy)
                if ended:
                    return True, n, cy
                continue
            assert g.fused is None, "a fused test not taken by its branch"
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
            g.later = lambda reg, i=i: _read_later(entries, i, reg, role, targets, facts, g.code)
            g.nxt = None
            if i + 1 < hi and i + 1 not in targets and entries[i + 1][2] == "bcc":
                g.nxt = (entries[i + 1][3], need[i + 1])
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
        g.flush()  # the end of a straight line (a join, the loop edge or the block's end follows)
        return False, n, cy

    def flow(self, i: int, r: tuple[Any, ...], n: int, cy: int) -> tuple[bool, int, int, int]:
        """Emit entry ``i``, a branch with the role ``r``; return (every path has left the block, the entry the
        walk goes on from, n, cy there)."""
        kind = r[0]
        if kind == "dup":  # the taken path runs a copy of the code from r[1] on (_plan_tails)
            return self.dup(i, r[1], n, cy)
        if kind == "loop":
            return self.loop(i, n, cy)
        if kind in ("skip", "join"):  # a join is reached here only in a copy that starts in a then-part
            return False, r[1], n + 1, cy + timing.cycles(self.entries[i][1], taken=True)
        return self.branch(i, r, n, cy)

    def dup(self, i: int, j: int, n: int, cy: int) -> tuple[bool, int, int, int]:
        """A branch whose taken path runs a copy of the code from entry ``j`` to the block's end."""
        g = self.g
        _, ins, h, cond, _ = self.entries[i]
        taken = timing.cycles(ins, taken=True)
        g.dyn = True
        if h == "bra":
            self.copy(j, n + 1, cy + taken)
            return True, i, n + 1, cy + taken
        g.emit(f"if {g.branch_test(cond)}:")
        g.ind += 1
        self.copy(j, n + 1, cy + taken)
        g.ind -= 1
        return False, i + 1, n + 1, cy + timing.cycles(ins, taken=False)

    def loop(self, i: int, n: int, cy: int) -> tuple[bool, int, int, int]:
        """A BRA, Bcc or DBcc back to the loop head: the ``continue`` of the block's ``while`` loop."""
        g = self.g
        _, ins, h, cond, _ = self.entries[i]
        taken = timing.cycles(ins, taken=True)
        g.dyn = True
        if h == "bra":
            self.loopback(n + 1, cy + taken)
            return True, i, n + 1, cy + taken
        if h == "bcc":
            g.emit(f"if {g.branch_test(cond)}:")
            g.ind += 1
            self.loopback(n + 1, cy + taken)
            g.ind -= 1
            cy += timing.cycles(ins, taken=False)
        else:  # dbcc
            ce = _COND_EXPR[cond]
            if ce != "False":
                g.emit(f"if {_COND_EXPR[cond ^ 1]}:")
                g.ind += 1
            dn = g.wg(ins.operands[0].reg)
            # the low word counts down: nonzero -> minus 1 (no borrow out of it), loop; zero -> $FFFF, out
            g.emit(f"if {dn} & 0xFFFF:")
            g.ind += 1
            g.emit(f"{dn} -= 1")
            self.loopback(n + 1, cy + taken)
            g.ind -= 1
            g.emit("else:")
            g.emit(f"    {dn} |= 0xFFFF")
            g.emit("    c += 2")
            if ce != "False":
                g.ind -= 1
            cy += 12
        return False, i + 1, n + 1, cy

    def branch(self, i: int, r: tuple[Any, ...], n: int, cy: int) -> tuple[bool, int, int, int]:
        """A Bcc forward inside the block: an ``if`` over the skipped entries (role "if"), or an ``if``/``else``
        when they end in a BRA forward (role "ifelse": the else part runs to ``r[2]``)."""
        g, entries = self.g, self.entries
        kind, j = r[0], r[1]
        _, ins, _, cond, _ = entries[i]
        taken = timing.cycles(ins, taken=True)
        not_taken = timing.cycles(ins, taken=False)
        g.dyn = True
        if kind == "if" and j == i + 1:
            g.emit(f"if {g.branch_test(cond)}:")
            g.ind += 1
            self.adjust(0, taken - not_taken)
            g.ind -= 1
            return False, j, n + 1, cy + not_taken
        g.emit(f"if {g.branch_test(cond, False)}:")
        g.ind += 1
        pos = self.body_start()
        if kind == "if":
            e1, n1, c1 = self.gen(i + 1, j, n + 1, cy + not_taken)
            self.close_body(pos)
            g.ind -= 1
            n2, c2 = n + 1, cy + taken
            if e1:
                return False, j, n2, c2
            if (n1, c1) != (n2, c2):
                g.emit("else:")
                g.ind += 1
                self.adjust(n2 - n1, c2 - c1)
                g.ind -= 1
            return False, j, n1, c1
        t = r[2]
        e1, n1, c1 = self.gen(i + 1, j - 1, n + 1, cy + not_taken)
        if not e1:
            self.mark(j - 1, n1, c1)
            n1 += 1
            c1 += timing.cycles(entries[j - 1][1])
        self.close_body(pos)
        g.ind -= 1
        g.emit("else:")
        g.ind += 1
        pos = self.body_start()
        e2, n2, c2 = self.gen(j, t, n + 1, cy + taken)
        if not e1 and not e2 and (n1, c1) != (n2, c2):
            self.adjust(n2 - n1, c2 - c1)
        self.close_body(pos)
        g.ind -= 1
        if e1 and e2:
            return True, t, n, cy
        n, cy = (n2, c2) if e1 else (n1, c1)
        return False, t, n, cy

    def copy(self, j: int, n: int, cy: int) -> None:
        """A copy of the entries from ``j`` to the end of the block (a duplicated tail), ending in exits."""
        pos = self.body_start()
        e, n1, c1 = self.gen(j, len(self.entries), n, cy)
        if not e:
            self.g.exit((self.entries[-1][0] + self.entries[-1][4]) & 0xFFFFFF, n1, c1)
        self.close_body(pos)


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
    g = _BlockGen(facts, (entries[0][0], entries[-1][0] + entries[-1][4]))
    lazy = _lazy_kind(entries, reach, head, need) if lazy_ok else None
    w = _Walk(entries, facts, g, role, head, need)
    loop_at = 0  # first item of the while loop
    if head is None:
        ended, n_end, c_end = w.gen(0, k, 0, 0)
    else:
        w.head_pc = entries[head][0]
        _, w.n_head, w.c_head = w.gen(0, head, 0, 0)  # the entries before the loop head (never all leave: _plan)
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
        ended, n_end, c_end = w.gen(head, k, w.n_head, w.c_head)
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
    return _assemble(w, head, lazy is not None, flow=bool(role))


def _assemble(w: _Walk, head: int | None, lazy: bool, flow: bool
              ) -> tuple[str, dict[str, object], tuple[list[int], list[int]], list[int], list[int], list[int],
                         bool, list[tuple[Any, ...]]]:
    """The block function's text from the walk ``w`` of its entries (``head``: the loop head or None; ``lazy``:
    the loop keeps lazy flags; ``flow``: there is control flow, so the local ``ni`` counts instructions), and
    the rest of what :func:`_block_source` returns."""
    g, entries, k = w.g, w.entries, len(w.entries)
    loops = head is not None
    body: list[str] = []
    dirty = sorted(g.dirty)
    text = [t for _, t in g.items if isinstance(t, str)]
    uses_sr = lazy or any("sr" in t for t in text)
    sr_dirty = lazy or any("sr = " in t for t in text)
    params = "R, MS, D, rb, rw, rl, wb, ww, wl, m, fl, F16, F32, UL, UW, PL, PW" + "".join(", " + n for n in g.consts)
    lines_ = [f"def __make({params}):", "    def __block(bn, bc, until):"]
    used = sorted(g.used)
    loads = used + [16] * uses_sr
    if len(loads) >= _UNPACK_MIN:  # one unpacking of the 17-item register list (CPU._R): cheaper than 7 subscripts
        names = _RN + ("sr",)
        lines_.append("        " + ", ".join(names[r] if r in loads else "_" for r in range(17)) + " = R")
    else:
        lines_ += [f"        {_RN[r]} = R[{r}]" for r in used]
        if uses_sr:
            lines_.append("        sr = R[16]")
    if g.dyn:
        lines_.append("        c = 0")
    if lazy:
        lines_.append("        lr = None")
    if flow or loops:
        lines_.append("        ni = 0")
    if head is not None:  # another pass from the head may start only if its worst case fits the budget (CPU.run)
        lines_.append(f"        ln = (bn if bn < 0x40000000 else 0x40000000) - {k - head + w.n_head}")
        lines_.append(f"        if until == {w.head_pc}:")
        lines_.append("            ln = -1")
        lines_.append(f"        lc = bc - {_block_bound(entries[head:]) + w.c_head}")
    first = len(lines_) + 1
    seg_line = [0] * len(w.segs)
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
    seg_pcs = [entries[i][0] for i, _, _ in w.segs]
    ncount = [n for _, n, _ in w.segs]
    prefix = [cy for _, _, cy in w.segs]
    src = "\n".join(lines_ + body + ["    return __block", ""])
    return src, g.consts, (seg_line, seg_pcs), prefix, ncount, used, loops, [g.recipes[name] for name in g.consts]


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
    exec(code, ns)  # our own generated code
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

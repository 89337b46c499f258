"""The block planner: which instructions form a block, how control flows inside it, and which CCR flags each
instruction's code must compute. Pure analysis of decoded instructions: it generates no code.

Contract with :mod:`isa.blocks` (which assembles and compiles the block) and :mod:`isa.block_codegen` (which
generates each instruction's code):

* Extent: :func:`block_entries` ``(start, most, decoded_at)`` returns the block's entries, a list of ``(pc,
  instruction, handler name, condition or None, length)`` (:data:`_Entry`) back to back in memory, each accepted
  by :func:`_blockable`; :data:`BLOCK_MAX` is the ``most`` the CPU passes (:mod:`isa.cpu`).
* Control flow: :func:`_plan` gives the role of each internal branch (``if``, ``ifelse``/``join``, ``skip``,
  ``loop``, and ``dup`` from :func:`_plan_tails`, bounded by :data:`TAIL_BUDGET`), which entries are reachable
  and the loop head. :func:`_block_source` generates exactly the shape planned (its ``gen`` mirrors the walk of
  :func:`_plan_tails`).
* Flags: :func:`_liveness` gives the flags live after each entry (what a later instruction on any path reads,
  everything at an exit and around an instruction that :func:`_may_fault` says may fault); :func:`_defer_flags`
  says when an entry's NZVC may be assigned on faulting paths only; :func:`_lazy_kind` picks the ADD/SUB whose
  flags a looping block keeps lazily. :func:`_flag_effect` (flags read/written per instruction) and
  :func:`_quiet_write` (a constant-address write that can neither fault nor touch the block's own code) are
  shared with the code generator, which must emit code consistent with these answers.
* Registers: :func:`_read_later` says whether a data register is read again on the straight line after an entry
  before being overwritten whole (the generator's value layer binds such a pending value to a temporary; a cost
  guess only), :data:`_CONTROL` the instructions before which every pending value is assigned.
* Imports: :mod:`isa.semantics`, :mod:`isa.operands`, :mod:`isa.memory` (:class:`MapFacts`) only; never the
  code generator or :mod:`isa.blocks`.
"""

from __future__ import annotations

from typing import Any

from isa.operands import Instruction, Operand, Size
from isa.memory import MapFacts
from isa.semantics import CF, M32, NF, VF, XF, ZF, _M, _MEMORY_MODES, _lowers_sp, _nb, _pc_target

__all__ = ["BLOCK_MAX", "TAIL_BUDGET", "block_entries"]

#: Most instructions in one compiled block.
BLOCK_MAX = 480
#: Decoding goes on past a BRA/JMP/RTS/... while a branch of the block targets code at most this many bytes after
#: the branch and beyond the transfer (that code may be reached inside the block).
_FORWARD_WINDOW = 512
_ALL_FLAGS = 0x1F
_FLAGS_NZVC = 0x0F
#: Flags each condition code reads (PRM table 3-19), for the block compiler's flag liveness.
_COND_USES: tuple[int, ...] = (0, 0, CF | ZF, CF | ZF, CF, CF, ZF, ZF, VF, VF, NF, NF, NF | VF, NF | VF,
                               NF | ZF | VF, NF | ZF | VF)  # fmt: skip
_SHIFT_NAMES = frozenset("asl asr lsl lsr rol ror roxl roxr".split())
_NO_FLAGS = frozenset("movea adda suba lea pea exg movem nop bra bsr jmp jsr rts".split())
_NZVC_DEFS = frozenset("move moveq and andi or ori eor eori not tst clr ext swap muls mulu divs divu cmp cmpi "
                       "cmpa cmpm".split())


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
                if tgt == start and i >= head and not (h == "dbcc" and cond == 0):  # type: ignore[operator]  # head is not None here: start == -1 (no address) when it is
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
            else:  # loop: the back edge is also where the instruction budget or until_pc ends the loop (the
                # block leaves at the head with SR as it is then: every flag is observable there)
                after = _ALL_FLAGS
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


#: Instructions after which the generator writes every pending register value back (they branch or leave).
_CONTROL = frozenset("bcc bra bsr dbcc jmp jsr rts trap illegal".split())


def _mentions(op: Operand, r: int) -> bool:
    """True when operand ``op`` names data register ``r`` (as the register, an index or in a register list)."""
    if op.mode is _M.DREG:
        return op.reg == r
    if op.mode is _M.REGLIST:
        return bool(op.value >> r & 1)
    return op.index is not None and not op.index.is_areg and op.index.num == r


def _read_later(entries: list[_Entry], i: int, r: int, role: dict[int, tuple[Any, ...]], targets: set[int],
                facts: MapFacts, code: tuple[int, int]) -> bool:
    """For the generator's pending register values (:class:`isa.block_codegen._BlockGen`): False when data
    register ``r`` is next written whole by a MOVEQ or a MOVE.L from another data register or an immediate, on the
    straight line after entry ``i``, before any entry names it, might fault, branches or is reached from elsewhere
    (each of which makes the generator assign the pending value to the register). Only a guess about cost: the
    generated code is exact either way (a value used again is computed twice)."""
    for j in range(i + 1, len(entries)):
        if j in role or j in targets:
            return True
        pc, ins, h, _, _ = entries[j]
        if h in _CONTROL or _may_fault(ins, h, facts, pc, code):
            return True
        ops = ins.operands
        if len(ops) == 2 and ops[1].mode is _M.DREG and ops[1].reg == r and not _mentions(ops[0], r) and (
                h == "moveq" or (h == "move" and ins.size is Size.L and ops[0].mode in (_M.DREG, _M.IMM))):
            return False
        if any(_mentions(o, r) for o in ops):
            return True
    return True

"""Per-instruction execution closures: one semantic builder per :data:`isa.table.TABLE` handler name.

Contract:

* :data:`HANDLERS` maps every handler name used in ``TABLE`` to exactly one builder (a test checks the two sets
  are equal). A builder takes a :class:`_Ctx` (the register list, the memory accessors, the instruction, its
  address and the address after it) and returns a closure ``f() -> next_pc | clocks << 32`` that performs the
  instruction on the bound registers/memory. :func:`build_closure` is the one entry point the CPU uses; it wraps
  instructions that may lower A7 so that ``min_sp`` (a one-element list) is updated after them.
* Registers are ``R``: a list of 17 ints (D0-D7, A0-A7, SR), each unsigned 32-bit (SR 16-bit). Memory is reached
  only through ``rd[n](address) -> value`` and ``wr[n](address, value)`` for n = 1, 2, 4 (from
  :class:`isa.memory.Memory`), which mask the address to 24 bits and raise :class:`isa.semantics._Fault`.
* A fault is raised as :class:`isa.semantics._Fault`, TRAP #n as :class:`isa.semantics._Stop`; state changes made
  before the fault (a postincrement, say) are kept. Nothing here knows about blocks, caches or counters.
* These closures are the reference the block compiler (:mod:`isa.blocks`) is tested against, and the path
  :meth:`isa.cpu.CPU.step`, profiling and ``block_compile = False`` use.
"""

from __future__ import annotations

from collections.abc import Callable

from isa import timing
from isa.errors import AddressError, DivideByZero, IllegalInstruction
from isa.operands import Instruction, Operand, Size
from isa.semantics import (CALL_SENTINEL, CCR, KEEP_SYS, KEEP_SYS_X, M32, MASK, NF, SIGN, SR, VF, XC, ZF, _COND,
                           _KERNELS, _M, _Fault, _Stop, _handler, _inc, _k_add, _k_addx, _k_logic, _k_shift, _k_sub,
                           _k_subx, _lowers_sp, _nb, _nz, _pc_target, _sx)

__all__ = ["HANDLERS", "build_closure"]


class _Ctx:
    """What a handler builder needs: the register list, memory accessors and the instruction's position."""

    __slots__ = ("R", "rd", "wr", "pc", "nxt", "instr", "cond")

    def __init__(self, R: list[int], rd: dict[int, Callable[[int], int]], wr: dict[int, Callable[[int, int], None]],
                 instr: Instruction, pc: int, nxt: int, cond: int | None) -> None:
        self.R = R
        self.rd = rd
        self.wr = wr
        self.pc = pc
        self.nxt = nxt
        self.instr = instr
        self.cond = cond


def _index_fn(R: list[int], op: Operand) -> Callable[[], int]:
    ix = op.index
    assert ix is not None
    xi = ix.num + (8 if ix.is_areg else 0)
    if ix.long:
        return lambda: R[xi]
    return lambda: ((R[xi] & 0xFFFF) ^ 0x8000) - 0x8000


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
        return lambda: c  # type: ignore[return-value]  # the constant closure returns an int like the others
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


def _packed(nxt: int, cycles: int) -> int:
    return (nxt & 0xFFFFFF) | (cycles << 32)


Builder = Callable[[_Ctx], Callable[[], int]]


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
                R[SR] = kernel(src(), R[i] & M, R[SR])[1]
                return K

            return cmp_d
        keep = M32 ^ M

        def op_d() -> int:
            r, R[SR] = kernel(src(), R[i] & M, R[SR])
            R[i] = (R[i] & keep) | r
            return K

        return op_d
    rd, wr = ctx.rd[nb], ctx.wr[nb]
    addr = _addr_fn(ctx, dst, nb)
    if not write:

        def cmp_m() -> int:
            s = src()
            R[SR] = kernel(s, rd(addr()), R[SR])[1]
            return K

        return cmp_m

    def op_m() -> int:
        s = src()
        a = addr()
        r, R[SR] = kernel(s, rd(a), R[SR])
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
                    R[SR] = ((R[SR] & KEEP_SYS) | (XC if r > M32 else 0) | (8 if rm & S else (0 if rm else 4))
                             | (2 if (k ^ rm) & (d ^ rm) & S else 0))
                    return K

                return addl_i
            if base == "sub":

                def subl_i() -> int:
                    d = R[i]
                    r = d - k
                    rm = r & M32
                    R[i] = rm
                    R[SR] = ((R[SR] & KEEP_SYS) | (XC if r < 0 else 0) | (8 if rm & S else (0 if rm else 4))
                             | (2 if (k ^ d) & (d ^ rm) & S else 0))
                    return K

                return subl_i

            def cmpl_i() -> int:
                d = R[i]
                r = d - k
                rm = r & M32
                R[SR] = ((R[SR] & KEEP_SYS_X) | (1 if r < 0 else 0) | (8 if rm & S else (0 if rm else 4))
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
                R[SR] = ((R[SR] & KEEP_SYS) | (XC if r > M32 else 0) | (8 if rm & S else (0 if rm else 4))
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
                R[SR] = ((R[SR] & KEEP_SYS) | (XC if r < 0 else 0) | (8 if rm & S else (0 if rm else 4))
                         | (2 if (s ^ d) & (d ^ rm) & S else 0))
                return K

            return subl_r

        def cmpl_r() -> int:
            d = R[i]
            s = R[j]
            r = d - s
            rm = r & M32
            R[SR] = ((R[SR] & KEEP_SYS_X) | (1 if r < 0 else 0) | (8 if rm & S else (0 if rm else 4))
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
                R[SR] = ((R[SR] & KEEP_SYS) | (XC if r < 0 else 0) | (8 if rm & S else (0 if rm else 4))
                         | (2 if d & ~rm & S else 0))
                return K

            return subql_d

        def addql_d() -> int:
            d = R[i]
            r = d + k
            rm = r & M32
            R[i] = rm
            R[SR] = ((R[SR] & KEEP_SYS) | (XC if r > M32 else 0) | (8 if rm & S else (0 if rm else 4))
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
        r, R[SR] = kernel(s, rd(a), R[SR])
        wr(a, r)
        return K

    return addx_m


def h_cmpm(ctx: _Ctx) -> Callable[[], int]:
    """CMPM (Ay)+,(Ax)+: flags of (Ax) - (Ay) as CMP (X unchanged); Ay is read (and incremented) first."""
    ins = ctx.instr
    nb = _nb(ins)
    kernel = _KERNELS["cmp"](nb)
    R = ctx.R
    K = _packed(ctx.nxt, timing.cycles(ins))
    rd = ctx.rd[nb]
    sa = _addr_fn(ctx, ins.operands[0], nb)
    da = _addr_fn(ctx, ins.operands[1], nb)

    def cmpm() -> int:
        s = rd(sa())
        R[SR] = kernel(s, rd(da()), R[SR])[1]
        return K

    return cmpm


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
            R[SR] = kernel(((src() ^ 0x8000) - 0x8000) & M32, R[i], R[SR])[1]
            return K

        return cmpaw

    def cmpal() -> int:
        R[SR] = kernel(src(), R[i], R[SR])[1]
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
                    R[SR] = (R[SR] & KEEP_SYS_X) | (8 if v & S else (0 if v else 4))
                    return K

                return movel_rr

            def move_rr() -> int:
                v = R[j] & M
                R[i] = (R[i] & keep) | v
                R[SR] = (R[SR] & KEEP_SYS_X) | (8 if v & S else (0 if v else 4))
                return K

            return move_rr
        src = _reader(ctx, src_op, nb)

        def move_xr() -> int:
            v = src()
            R[i] = (R[i] & keep) | v
            R[SR] = (R[SR] & KEEP_SYS_X) | (8 if v & S else (0 if v else 4))
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
                R[SR] = (R[SR] & KEEP_SYS_X) | (8 if v & S else (0 if v else 4))
                wr(R[ar] + disp, v)
                return K

            return move_rd

        def move_xd() -> int:
            v = src()
            R[SR] = (R[SR] & KEEP_SYS_X) | (8 if v & S else (0 if v else 4))
            wr(R[ar] + disp, v)
            return K

        return move_xd
    if fn is None:
        c = const

        def move_xc() -> int:
            v = src()
            R[SR] = (R[SR] & KEEP_SYS_X) | (8 if v & S else (0 if v else 4))
            wr(c, v)
            return K

        return move_xc
    addr = fn

    def move_xm() -> int:
        v = src()
        a = addr()
        R[SR] = (R[SR] & KEEP_SYS_X) | (8 if v & S else (0 if v else 4))
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
        R[SR] = (R[SR] & KEEP_SYS_X) | flags
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
        kernel = lambda s, d, sr: (0, (sr & KEEP_SYS_X) | ZF)
    elif h == "not":
        lk = _k_logic(nb, "eor")
        kernel = lambda s, d, sr: lk(M, d, sr)
    elif h == "neg":
        sk = _k_sub(nb)
        kernel = lambda s, d, sr: sk(d, 0, sr)
    elif h == "negx":
        xk = _k_subx(nb)
        kernel = lambda s, d, sr: xk(d, 0, sr)
    else:  # tst
        lk = _k_logic(nb, "or")
        kernel = lambda s, d, sr: lk(0, d, sr)
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
            R[SR] = (R[SR] & KEEP_SYS_X) | _nz(v, 2)
            return K

        return extw

    def extl() -> int:
        v = _sx(R[i] & 0xFFFF, 2) & M32
        R[i] = v
        R[SR] = (R[SR] & KEEP_SYS_X) | _nz(v, 4)
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
        R[SR] = (R[SR] & KEEP_SYS_X) | _nz(v, 4)
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
        R[SR] = (R[SR] & KEEP_SYS_X) | _nz(p, 4)
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
            R[SR] = (R[SR] & KEEP_SYS_X) | _nz(q, 2)
        else:
            R[SR] = (R[SR] & KEEP_SYS_X) | NF | VF
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
                R[SR] = ((R[SR] & KEEP_SYS) | (XC if (sx >> (n - 1)) & 1 else 0)
                         | (8 if r & S else (0 if r else 4)))
                return K

            return asrl_i
        if nb == 4 and h == "lsr":

            def lsrl_i() -> int:
                x = R[i]
                r = x >> n
                R[i] = r
                R[SR] = (R[SR] & KEEP_SYS) | (XC if (x >> (n - 1)) & 1 else 0) | (8 if r & S else (0 if r else 4))
                return K

            return lsrl_i
        if nb == 4 and h == "lsl":

            def lsll_i() -> int:
                x = R[i]
                r = (x << n) & M32
                R[i] = r
                R[SR] = ((R[SR] & KEEP_SYS) | (XC if (x >> (32 - n)) & 1 else 0)
                         | (8 if r & S else (0 if r else 4)))
                return K

            return lsll_i

        def shift_i() -> int:
            r, R[SR] = kernel(R[i] & M, n, R[SR])
            R[i] = (R[i] & keep) | r
            return K

        return shift_i
    j = ops[0].reg
    nxt = ctx.nxt & 0xFFFFFF
    base = (8 if nb == 4 else 6) << 32

    def shift_r() -> int:
        n = R[j] & 63
        r, R[SR] = kernel(R[i] & M, n, R[SR])
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
            if table[R[SR] & CCR]:
                R[i] |= 0xFF
                return Kt
            R[i] &= 0xFFFFFF00
            return Kf

        return scc_d
    K = _packed(ctx.nxt, timing.cycles(ins))
    wb = ctx.wr[1]
    addr = _addr_fn(ctx, dst, 1)

    def scc_m() -> int:
        wb(addr(), 0xFF if table[R[SR] & CCR] else 0)
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
            return odd() if table[R[SR] & CCR] else Kf

        return bcc_odd

    def bcc() -> int:
        return Kt if table[R[SR] & CCR] else Kf

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
        if table[R[SR] & CCR]:
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
    loads (overriding a loaded An), then the one extra word read the 68000 makes after the last register (its
    value is discarded; it faults like any read, so an empty list at an odd address address-errors as on the chip).
    Flags unaffected. Clocks 8/12+4n (.W) / +8n (.L) + mode (UM 8-9; the extra read is in the 12)."""
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
    rw = ctx.rd[2]

    def movem_m2r() -> int:
        a = addr()
        for i in regs:
            v = rd(a)
            R[i] = v if nb == 4 else ((v ^ 0x8000) - 0x8000) & M32
            a += nb
        if post:
            R[an] = a & M32
        rw(a)  # the extra word read after the last register
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
    "neg": h_unary, "negx": h_unary, "cmp": h_binary, "cmpa": h_cmpa, "cmpi": h_binary, "cmpm": h_cmpm, "tst": h_unary,
    "and": h_binary, "andi": h_binary, "or": h_binary, "ori": h_binary, "eor": h_binary, "eori": h_binary,
    "not": h_unary,
    "asl": h_shift, "asr": h_shift, "lsl": h_shift, "lsr": h_shift, "rol": h_shift, "ror": h_shift,
    "roxl": h_shift, "roxr": h_shift,
    "muls": h_mul, "mulu": h_mul, "divs": h_div, "divu": h_div,
    "bcc": h_bcc, "bra": h_bcc, "bsr": h_bsr, "dbcc": h_dbcc, "scc": h_scc,
    "jmp": h_jmp, "jsr": h_jsr, "rts": h_rts, "nop": h_nop, "trap": h_trap, "illegal": h_illegal,
}  # fmt: skip


def _cond(ctx: _Ctx) -> int:
    if ctx.cond is not None:
        return ctx.cond
    from isa.table import match_mnemonic

    found = match_mnemonic(ctx.instr.mnemonic)
    cond = found[0][1] if found else None
    if cond is None:
        raise IllegalInstruction(f"{ctx.instr.mnemonic}: no condition", pc=ctx.pc)
    return cond


def build_closure(R: list[int], rd: dict[int, Callable[[int], int]], wr: dict[int, Callable[[int, int], None]],
                  min_sp: list[int], instr: Instruction, pc: int, length: int, handler: str | None = None,
                  cond: int | None = None) -> Callable[[], int]:
    """The closure of ``instr`` at ``pc`` (``length`` bytes) over registers ``R`` and memory ``rd``/``wr``; when
    the instruction may lower A7 the closure also lowers ``min_sp[0]`` to A7 after it."""
    h = handler or timing.handler_name(instr.mnemonic)
    fn = HANDLERS[h](_Ctx(R, rd, wr, instr, pc, (pc + length) & 0xFFFFFF, cond))
    if _lowers_sp(instr, h):
        inner = fn

        def tracked() -> int:
            r = inner()
            if R[15] < min_sp[0]:
                min_sp[0] = R[15]
            return r

        fn = tracked
    return fn

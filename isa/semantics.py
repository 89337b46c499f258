"""Bit-level MC68000 semantics shared by both execution paths (:mod:`isa.closures`, :mod:`isa.blocks`).

Contract: everything here is pure (no CPU, no memory): value masks and sign bits per operand size, the CCR bit
masks, the condition-code truth table (:data:`_COND`), the ALU and shift kernels ``k(src, dst_or_count, sr) ->
(result, new sr)`` that the per-instruction closures and the generated block code both call, operand helpers
(postincrement step, PC-relative address, operand size in bytes, handler name, whether an instruction may lower
A7, a disassembly for messages) and the two internal signals compiled code raises: :class:`_Fault` (a CPU fault;
the CPU turns it into ``cls(message, pc, instruction, source)``) and :class:`_Stop` (TRAP #n). A semantic rule
both paths share is written here once. Names with a leading underscore are internal to the ``isa`` package.
"""

from __future__ import annotations

from collections.abc import Callable

from isa import timing
from isa.errors import CPUFault
from isa.operands import Instruction, Mode, Operand, Size

M32 = 0xFFFFFFFF
MASK = {1: 0xFF, 2: 0xFFFF, 4: M32}
SIGN = {1: 0x80, 2: 0x8000, 4: 0x80000000}
BITS = {1: 8, 2: 16, 4: 32}
XF, NF, ZF, VF, CF = 0x10, 0x08, 0x04, 0x02, 0x01
#: The status register's index in the register file ``R`` (D0-D7, A0-A7, SR: :mod:`isa.closures`).
SR = 16
#: The condition-code bits of the SR (X N Z V C).
CCR = 0x1F
#: SR masks that keep the system byte (``KEEP_SYS``), or the system byte and X (``KEEP_SYS_X``: the instructions
#: that leave X alone), while the flags are rewritten.
KEEP_SYS = 0xFF00
KEEP_SYS_X = 0xFF10
#: X and C together: a carry or borrow that extends (ADD/SUB/NEG set both, Musashi's FLAG_X = FLAG_C).
XC = XF | CF

#: Return address pushed by :meth:`isa.cpu.CPU.call`; odd, so it can never be the address of a real instruction.
CALL_SENTINEL = 0xFFFFFF

_M = Mode
_MEMORY_MODES = frozenset(m for m in Mode if m not in (_M.DREG, _M.AREG, _M.IMM, _M.REGLIST))


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
        f = sr & KEEP_SYS
        if r > M:
            f |= XC
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
    keep = KEEP_SYS_X if keep_x else KEEP_SYS
    cbits = CF if keep_x else XC

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
            f |= XC
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
            f |= XC
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
            return r, (sr & KEEP_SYS_X) | (8 if r & S else 0) | (0 if r else 4)

    elif op == "or":

        def k(s: int, d: int, sr: int) -> tuple[int, int]:
            r = s | d
            return r, (sr & KEEP_SYS_X) | (8 if r & S else 0) | (0 if r else 4)

    else:

        def k(s: int, d: int, sr: int) -> tuple[int, int]:
            r = s ^ d
            return r, (sr & KEEP_SYS_X) | (8 if r & S else 0) | (0 if r else 4)

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
def _k_shift(kind: str, nb: int) -> Callable[[int, int, int], tuple[int, int]]:  # noqa: C901 - one branch per shift/rotate kind (ASx, LSx, ROx, ROXx), as Musashi
    W, M, S = BITS[nb], MASK[nb], SIGN[nb]

    def nz(r: int) -> int:
        return (8 if r & S else 0) | (0 if r else 4)

    if kind == "asl":

        def k(x: int, n: int, sr: int) -> tuple[int, int]:
            if n == 0:
                return x, (sr & KEEP_SYS_X) | nz(x)
            if n < W:
                r = (x << n) & M
                c = (x >> (W - n)) & 1
                top = x >> (W - 1 - n)
                v = top != 0 and top != (1 << (n + 1)) - 1
            else:
                r = 0
                c = x & 1 if n == W else 0
                v = x != 0
            return r, (sr & KEEP_SYS) | (XC if c else 0) | nz(r) | (2 if v else 0)

    elif kind == "asr":

        def k(x: int, n: int, sr: int) -> tuple[int, int]:
            if n == 0:
                return x, (sr & KEEP_SYS_X) | nz(x)
            sx = (x ^ S) - S
            if n < W:
                r = (sx >> n) & M
                c = (sx >> (n - 1)) & 1
            else:
                r = M if sx < 0 else 0
                c = 1 if sx < 0 else 0
            return r, (sr & KEEP_SYS) | (XC if c else 0) | nz(r)

    elif kind == "lsl":

        def k(x: int, n: int, sr: int) -> tuple[int, int]:
            if n == 0:
                return x, (sr & KEEP_SYS_X) | nz(x)
            if n <= W:
                r = (x << n) & M
                c = (x >> (W - n)) & 1
            else:
                r = c = 0
            return r, (sr & KEEP_SYS) | (XC if c else 0) | nz(r)

    elif kind == "lsr":

        def k(x: int, n: int, sr: int) -> tuple[int, int]:
            if n == 0:
                return x, (sr & KEEP_SYS_X) | nz(x)
            if n <= W:
                r = x >> n
                c = (x >> (n - 1)) & 1
            else:
                r = c = 0
            return r, (sr & KEEP_SYS) | (XC if c else 0) | nz(r)

    elif kind == "rol":

        def k(x: int, n: int, sr: int) -> tuple[int, int]:
            if n == 0:
                return x, (sr & KEEP_SYS_X) | nz(x)
            m = n % W
            r = ((x << m) | (x >> (W - m))) & M
            return r, (sr & KEEP_SYS_X) | (r & 1) | nz(r)

    elif kind == "ror":

        def k(x: int, n: int, sr: int) -> tuple[int, int]:
            if n == 0:
                return x, (sr & KEEP_SYS_X) | nz(x)
            m = n % W
            r = ((x >> m) | (x << (W - m))) & M
            return r, (sr & KEEP_SYS_X) | (1 if r & S else 0) | nz(r)

    elif kind in ("roxl", "roxr"):
        W1 = W + 1
        M1 = (1 << W1) - 1
        left = kind == "roxl"

        def k(x: int, n: int, sr: int) -> tuple[int, int]:
            xb = (sr >> 4) & 1
            m = n % W1
            if m == 0:  # includes n == 0: C = X, X unchanged
                return x, (sr & KEEP_SYS_X) | xb | nz(x)
            v = (xb << W) | x
            if left:
                v = ((v << m) | (v >> (W1 - m))) & M1
            else:
                v = ((v >> m) | (v << (W1 - m))) & M1
            r = v & M
            return r, (sr & KEEP_SYS) | (XC if v >> W else 0) | nz(r)

    else:  # pragma: no cover - table and handlers are checked to agree
        raise KeyError(kind)
    return k


# ------------------------------------------------------------------------------------------------------------------
# Operand helpers
def _inc(op: Operand, nb: int) -> int:
    """Postincrement/predecrement step: the size, except byte access through A7 moves it by 2."""
    return 2 if nb == 1 and op.reg == 7 else nb


def _pc_target(pc: int, target: int) -> int:
    """The 32-bit address the 68000 forms for a PC-relative operand whose 24-bit target the decoder reported:
    extension-word address + displacement in 32-bit arithmetic (so a negative wrap gives $FFxxxxxx)."""
    delta = ((target - pc + 0x800000) & 0xFFFFFF) - 0x800000
    return (pc + delta) & M32


def _nb(instr: Instruction) -> int:
    return instr.size.bytes if instr.size is not None and instr.size is not Size.S else 2


def _handler(instr: Instruction) -> str:
    return timing.handler_name(instr.mnemonic)


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
    except Exception:  # noqa: BLE001 - formatter missing or unable: fall back to a plain rendering
        ops = ", ".join(f"{o.mode.value}:{o.reg}:{o.value}" for o in instr.operands)
        size = f".{instr.size.value}" if instr.size else ""
        return f"{instr.mnemonic}{size} {ops}".strip()

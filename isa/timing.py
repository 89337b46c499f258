"""MC68000 clock counts (M68000 User's Manual, section 8, zero wait states), derived from modes and handlers.

Nothing here is a per-opcode list: a count is an effective-address (EA) calculation time per addressing mode
(UM Table 8-1) plus a base time per handler family and operand shape (UM Tables 8-2 .. 8-11), plus the
data-dependent part where the manual has one:

* shifts/rotates of a register: ``6 + 2n`` (byte, word) / ``8 + 2n`` (long), n = the count (a register count is
  taken modulo 64, UM Table 8-7);
* MULU: ``38 + 2n``, n = number of 1 bits in the 16-bit source; MULS: ``38 + 2n``, n = number of 01/10 bit
  transitions in ``source << 1`` (17-bit pattern) (UM Table 8-4 note);
* DIVU/DIVS: the microcode's shift-and-subtract loop (the manual gives only the maxima 140/158; the exact
  per-operand counts follow Jorge Cwik's "68000 division timing" analysis, as used by m68000-python, WinUAE,
  MAME and Moira): DIVU 76..136 (+EA), overflow 10; DIVS 120..156 (+EA), overflow 16 or 18 (see
  :func:`divu_cycles`, :func:`divs_cycles`);
* Bcc: taken 10, not taken 8 (.S) / 12 (.W); DBcc: condition true 12, counter expired 14, looping 10;
  Scc register: 4 when false, 6 when true.

All counts are in 68000 clock periods (one bus cycle = 4 clocks). TRAP is given its manual figure (34) although
the interpreter stops at a TRAP instead of vectoring.
"""

from __future__ import annotations

import functools

from isa.operands import Instruction, Mode, Operand, Size

_M = Mode

#: EA calculation time (byte/word, long), UM Table 8-1.
EA_TIME: dict[Mode, tuple[int, int]] = {
    _M.DREG: (0, 0), _M.AREG: (0, 0), _M.AIND: (4, 8), _M.APOSTINC: (4, 8), _M.APREDEC: (6, 10),
    _M.ADISP: (8, 12), _M.AINDEX: (10, 14), _M.ABSW: (8, 12), _M.ABSL: (12, 16), _M.PCDISP: (8, 12),
    _M.PCINDEX: (10, 14), _M.IMM: (4, 8),
}  # fmt: skip

#: EA time of a MOVE destination (UM Tables 8-2/8-3: -(An) costs as (An) when written).
_MOVE_DEST: dict[Mode, tuple[int, int]] = dict(EA_TIME)
_MOVE_DEST[_M.APREDEC] = EA_TIME[_M.AIND]

#: Control-mode tables of UM Table 8-9: (An) d16(An) d8(An,Xn) abs.W abs.L d16(PC) d8(PC,Xn) [+ (An)+ / -(An)].
_JMP = {_M.AIND: 8, _M.ADISP: 10, _M.AINDEX: 14, _M.ABSW: 10, _M.ABSL: 12, _M.PCDISP: 10, _M.PCINDEX: 14}
_JSR = {_M.AIND: 16, _M.ADISP: 18, _M.AINDEX: 22, _M.ABSW: 18, _M.ABSL: 20, _M.PCDISP: 18, _M.PCINDEX: 22}
_LEA = {_M.AIND: 4, _M.ADISP: 8, _M.AINDEX: 12, _M.ABSW: 8, _M.ABSL: 12, _M.PCDISP: 8, _M.PCINDEX: 12}
_PEA = {_M.AIND: 12, _M.ADISP: 16, _M.AINDEX: 20, _M.ABSW: 16, _M.ABSL: 20, _M.PCDISP: 16, _M.PCINDEX: 20}
#: MOVEM base (before + 4n word / + 8n long), memory -> registers and registers -> memory.
_MOVEM_M2R = {_M.AIND: 12, _M.APOSTINC: 12, _M.ADISP: 16, _M.AINDEX: 18, _M.ABSW: 16, _M.ABSL: 20,
              _M.PCDISP: 16, _M.PCINDEX: 18}  # fmt: skip
_MOVEM_R2M = {_M.AIND: 8, _M.APREDEC: 8, _M.ADISP: 12, _M.AINDEX: 14, _M.ABSW: 12, _M.ABSL: 16}

_REG = (_M.DREG, _M.AREG)
_SHIFTS = frozenset("asl asr lsl lsr rol ror roxl roxr".split())

_SPECIAL = {"bra": "bra", "bsr": "bsr", "dbra": "dbcc"}


@functools.lru_cache(maxsize=1024)
def handler_name(mnemonic: str) -> str:
    """Handler family of a canonical mnemonic (``"beq"`` -> ``"bcc"``, ``"dbra"`` -> ``"dbcc"``, ``"sne"`` ->
    ``"scc"``), from :data:`isa.table.TABLE`. Raises ``KeyError`` for an unknown mnemonic (not memoized).
    Memoized: a pure function of the string over an immutable table, asked about a million times while the
    block compiler generates the property tests' programs (the timing of every generated copy)."""
    from isa.table import match_mnemonic

    found = match_mnemonic(mnemonic)
    if not found:
        raise KeyError(mnemonic)
    return found[0][0].handler


def _ea(op: Operand, size: Size | None) -> int:
    return EA_TIME[op.mode][1 if size is Size.L else 0]


def _bits(x: int) -> int:
    return bin(x).count("1")


def mulu_cycles(source: int) -> int:
    """MULU clocks without EA time: ``38 + 2n``, n = ones in the 16-bit ``source`` (UM Table 8-4)."""
    return 38 + 2 * _bits(source & 0xFFFF)


def muls_cycles(source: int) -> int:
    """MULS clocks without EA time: ``38 + 2n``, n = 01/10 transitions in the 17-bit ``(source & $FFFF) << 1``."""
    p = (source & 0xFFFF) << 1
    return 38 + 2 * _bits((p ^ (p >> 1)) & 0xFFFF)


def divu_cycles(dividend: int, divisor: int) -> int:
    """DIVU clocks without EA time for an unsigned 32-bit ``dividend`` and a nonzero 16-bit ``divisor``.

    Overflow (quotient > $FFFF, detected first) takes 10. Otherwise 15 quotient steps run the microcode's
    shift-and-subtract loop: 76 + per step 4 if the bit shifted out of the dividend was 0, minus 2 if the trial
    subtraction then succeeded (Cwik 2005). Range 76..136."""
    dividend &= 0xFFFFFFFF
    divisor &= 0xFFFF
    if dividend >> 16 >= divisor:
        return 10
    half = 38
    shifted = divisor << 16
    for _ in range(15):
        carry = dividend & 0x80000000
        dividend = (dividend << 1) & 0xFFFFFFFF
        if carry:
            dividend = (dividend - shifted) & 0xFFFFFFFF
        else:
            half += 2
            if dividend >= shifted:
                dividend -= shifted
                half -= 1
    return half * 2


def divs_cycles(dividend: int, divisor: int) -> int:
    """DIVS clocks without EA time for a 32-bit ``dividend`` and a nonzero 16-bit ``divisor`` (either signed or
    unsigned two's-complement bit patterns).

    12 (+2 if the dividend is negative), then overflow on ``|dividend| >> 16 >= |divisor|`` ends at 16/18.
    Otherwise 122 + 2 per zero among the top 15 bits of the magnitude quotient, -2 if both operands are
    non-negative, +2 if only the dividend is negative (Cwik 2005). Range 120..156."""
    if dividend & 0x80000000 or dividend < 0:
        dividend = (dividend & 0xFFFFFFFF) - (1 << 32) if dividend >= 0 else dividend
    divisor &= 0xFFFF
    if divisor & 0x8000:
        divisor -= 0x10000
    half = 6
    if dividend < 0:
        half += 1
    if abs(dividend) >> 16 >= abs(divisor):
        return (half + 2) * 2
    quotient = abs(dividend) // abs(divisor)
    half += 55
    if divisor >= 0:
        half += -1 if dividend >= 0 else 1
    for bit in range(15):
        if not quotient & (0x8000 >> bit):
            half += 1
    return half * 2


def shift_count_cycles(size: Size | None, count: int) -> int:
    """Register shift/rotate clocks for ``count`` (already reduced modulo 64): 6+2n (.B/.W), 8+2n (.L)."""
    return (8 if size is Size.L else 6) + 2 * count


#: Handlers that change the flow (or test a condition) other than Bcc and DBcc: :func:`_flow_cycles`.
_FLOW = frozenset("scc bra bsr jmp jsr rts trap illegal".split())
#: Clocks of the flow instructions that take the same time whatever their operands.
_FLOW_FIXED = {"bra": 10, "bsr": 18, "rts": 16, "trap": 34, "illegal": 34}


def cycles(  # noqa: C901 - one branch per instruction timing rule of the 68000 tables
    instr: Instruction,
    *,
    taken: bool = True,
    count: int | None = None,
    source: int = 0,
    dividend: int = 0,
    expired: bool = False,
) -> int:
    """Clocks of ``instr`` given its data-dependent facts (defaults give one representative case).

    * ``taken``: Bcc branch taken; DBcc loops (condition false, counter not expired); Scc condition true.
    * ``expired``: DBcc condition false and counter expired (``taken`` ignored then).
    * ``count``: register shift count (modulo 64 already applied); ignored for immediate counts.
    * ``source``/``dividend``: the 16-bit MUL/DIV source operand and the 32-bit dividend. DIV by zero raises
      in the interpreter and has no count here (``source=0`` for DIV gives the overflow count of divisor 1)."""
    h = handler_name(instr.mnemonic)
    ops = instr.operands
    size = instr.size
    long = size is Size.L
    if h in ("move", "movea"):
        return 4 + _ea(ops[0], size) + _MOVE_DEST[ops[1].mode][1 if long else 0]
    if h == "moveq":
        return 4
    if h in ("add", "sub", "and", "or", "cmp", "eor"):
        src, dst = ops
        if dst.mode is _M.DREG and h == "cmp":
            return (6 if long else 4) + _ea(src, size)
        if dst.mode is _M.DREG and (h != "eor"):
            if long:
                return (8 if src.mode in _REG or src.mode is _M.IMM else 6) + _ea(src, size)
            return 4 + _ea(src, size)
        if h == "eor" and dst.mode is _M.DREG:
            return 8 if long else 4
        return (12 if long else 8) + _ea(dst, size)
    if h in ("adda", "suba"):
        src = ops[0]
        if long:
            return (8 if src.mode in _REG or src.mode is _M.IMM else 6) + _ea(src, size)
        return 8 + _ea(src, size)
    if h == "cmpa":
        return 6 + _ea(ops[0], size)
    if h in ("addi", "subi", "ori", "eori", "andi", "cmpi"):
        dst = ops[1]
        if dst.mode is _M.DREG:
            if not long:
                return 8
            return 14 if h == "cmpi" else 16  # UM Table 8-5 prints ANDI.L #,Dn as 14; the chip takes 16
        if h == "cmpi":
            return (12 if long else 8) + _ea(dst, size)
        return (20 if long else 12) + _ea(dst, size)
    if h in ("addq", "subq"):
        dst = ops[1]
        if dst.mode is _M.AREG:
            return 8
        if dst.mode is _M.DREG:
            return 8 if long else 4
        return (12 if long else 8) + _ea(dst, size)
    if h == "cmpm":  # UM Table 8-4 (multiprecision): CMPM (Ay)+,(Ax)+ .b/.w 12(3/0), .l 20(5/0)
        return 20 if long else 12
    if h in ("addx", "subx"):
        if ops[0].mode is _M.DREG:
            return 8 if long else 4
        return 30 if long else 18
    if h in ("clr", "neg", "negx", "not"):
        dst = ops[0]
        if dst.mode is _M.DREG:
            return 6 if long else 4
        return (12 if long else 8) + _ea(dst, size)
    if h == "tst":
        return 4 + _ea(ops[0], size)
    if h == "bcc":  # the two commonest flow rules here; the others in _flow_cycles
        if taken:
            return 10
        return 8 if size is Size.S else 12
    if h == "dbcc":
        if expired:
            return 14
        return 10 if taken else 12
    if h in _FLOW:  # other branches, jumps, Scc, exceptions
        return _flow_cycles(h, ops, size, taken)
    if h in _SHIFTS:
        if len(ops) == 1:
            return 8 + _ea(ops[0], Size.W)
        if ops[0].mode is _M.IMM:
            n = ops[0].value
        else:
            n = 0 if count is None else count
        return shift_count_cycles(size, n)
    if h == "mulu":
        return mulu_cycles(source) + _ea(ops[0], Size.W)
    if h == "muls":
        return muls_cycles(source) + _ea(ops[0], Size.W)
    if h in ("divu", "divs"):
        divisor = source or 1
        fn = divu_cycles if h == "divu" else divs_cycles
        return fn(dividend, divisor) + _ea(ops[0], Size.W)
    if h == "lea":
        return _LEA[ops[0].mode]
    if h == "pea":
        return _PEA[ops[0].mode]
    if h == "movem":
        if ops[0].mode is _M.REGLIST:
            n, ea_op, table = _bits(ops[0].value), ops[1], _MOVEM_R2M
        else:
            n, ea_op, table = _bits(ops[1].value), ops[0], _MOVEM_M2R
        return table[ea_op.mode] + (8 if long else 4) * n
    if h in ("ext", "swap", "nop"):
        return 4
    if h == "exg":
        return 6
    raise KeyError(f"no timing for handler {h!r}")



def _flow_cycles(h: str, ops: tuple[Operand, ...], size: Size | None, taken: bool) -> int:
    """Clocks of the branch, jump, Scc or exception instruction ``h`` (a name of :data:`_FLOW`); ``taken`` as for
    :func:`cycles`."""
    if h == "scc":
        if ops[0].mode is _M.DREG:
            return 6 if taken else 4
        return 8 + _ea(ops[0], size)
    if h == "jmp":
        return _JMP[ops[0].mode]
    if h == "jsr":
        return _JSR[ops[0].mode]
    return _FLOW_FIXED[h]


def cycle_range(instr: Instruction) -> tuple[int, int]:
    """(min, max) clocks of ``instr`` over all data (68000 clocks, zero wait states), for listings.

    Register shifts range over counts 0..63; MULU over 0..16 one bits (38..70 + EA); MULS over 0..16 transitions;
    DIVU 10 (overflow) .. 136 (+EA); DIVS 16 (overflow, dividend >= 0) .. 156 (+EA); Bcc/DBcc/Scc over both
    outcomes."""
    h = handler_name(instr.mnemonic)
    ops = instr.operands
    if h in ("bcc", "scc"):
        a, b = cycles(instr, taken=True), cycles(instr, taken=False)
        return (min(a, b), max(a, b))
    if h == "dbcc":
        vals = (cycles(instr, taken=True), cycles(instr, taken=False), cycles(instr, expired=True))
        return (min(vals), max(vals))
    if h in _SHIFTS and len(ops) == 2 and ops[0].mode is _M.DREG:
        return (cycles(instr, count=0), cycles(instr, count=63))
    if h in ("mulu", "muls"):
        ea = _ea(ops[0], Size.W)
        return (38 + ea, 70 + ea)
    if h == "divu":
        ea = _ea(ops[0], Size.W)
        return (10 + ea, 136 + ea)
    if h == "divs":
        ea = _ea(ops[0], Size.W)
        return (16 + ea, 156 + ea)
    c = cycles(instr)
    return (c, c)

"""The block-compiled path of ``CPU.run`` (isa/cpu.py, "Speed") against independent and internal references.

* Against m68000-python (the cycle oracle, docs/isa-oracles.md): random multi-instruction straight-line blocks,
  blocks with forward conditional branches and small DBRA loops, drawn with :mod:`isa.strategies`, run by our
  ``run()`` (blocks) and by m68000-python ``step()`` from the same machine: registers, CCR, PC, memory, total
  clocks and instruction count must agree; when either side faults, the fault kinds must agree.
* Against our own per-instruction closures (``block_compile = False``, the path the one-instruction differential
  tests check): random sequences of ANY instructions (faults included) with random instruction/cycle limits and
  ``until_pc``: everything must be identical, including the fault class, PC, disassembly and message, and the
  registers, memory and counters left after a fault.
* The firmware programs: every call's clocks, the state words, and the counters (instructions, cycles, min_sp,
  ram_written, profile) identical with and without blocks.
"""

from __future__ import annotations

import random

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import isa
from isa.blocks import _COND_EXPR
from isa.cpu import CPU
from isa.semantics import _COND
from isa.encoder import encode, length
from isa.errors import CPUFault
from isa.operands import Instruction, Mode, Operand, Size
from isa.strategies import instructions
from tests.support.profiles import examples

from tests.support import oracles

M32 = 0xFFFFFFFF
EDGE = (0, 1, 2, 7, 0x7F, 0x80, 0xFF, 0x7FFF, 0x8000, 0xFFFF, 0x7FFFFFFF, 0x80000000, 0xFFFFFFFF, 0xFFFF8000)

#: Data-processing rows for the m68000-python comparison (no TRAP/ILLEGAL/jumps/calls, no rows that load an
#: address register with an arbitrary value, which would only turn most blocks into bus errors).
ALU_ROWS = ["move", "moveq", "add", "addi", "addq", "addx", "sub", "subi", "subq", "subx", "neg", "negx", "cmp",
            "cmpa", "cmpi", "cmpm", "tst", "and", "andi", "or", "ori", "eor", "eori", "not", "clr", "ext", "swap",
            "asl", "asr", "lsl", "lsr", "rol", "ror", "roxl", "roxr", "muls", "mulu", "divs", "divu", "scc", "nop"]
SAFE_MODES = frozenset({Mode.DREG, Mode.AREG, Mode.IMM, Mode.AIND, Mode.APOSTINC, Mode.APREDEC, Mode.ADISP,
                        Mode.ABSW})
DATA_ABS = st.integers(oracles.DATA_LO // 2, (oracles.DATA_HI - 8) // 2).map(lambda v: 2 * v)


def _touches_d7(ins: Instruction) -> bool:
    return any((op.mode is Mode.DREG and op.reg == 7) or (op.index is not None and not op.index.is_areg
                                                          and op.index.num == 7) for op in ins.operands)


def _small_disp(ins: Instruction) -> bool:
    """d16(An) displacements that keep the access inside the data region's neighbourhood (never the code)."""
    return all(op.mode is not Mode.ADISP or -0x400 <= op.value <= 0x400 for op in ins.operands)


ALU = instructions(rows=ALU_ROWS, address=oracles.CODE, modes=SAFE_MODES, absolute=DATA_ABS).filter(
    lambda i: not _touches_d7(i) and _small_disp(i))


def layout(items: list[object], origin: int) -> bytes:
    """Encode ``items`` from ``origin``: an Instruction, or ("b", cond, skip) = a Bcc.S over the next ``skip``
    items, or ("dbra", back) = DBRA D7 to the item ``back`` places before it."""
    sizes = [length(i) if isinstance(i, Instruction) else (4 if i[0] == "dbra" else 2) for i in items]
    addrs = [origin]
    for s in sizes:
        addrs.append(addrs[-1] + s)
    out = b""
    for k, item in enumerate(items):
        if isinstance(item, Instruction):
            out += encode(item, addrs[k])
        elif item[0] == "b":
            target = addrs[min(k + 1 + item[2], len(items))]
            out += encode(Instruction(item[1], Size.S, (Operand(Mode.ABSL, value=target),)), addrs[k])
        else:
            out += encode(Instruction("dbra", Size.W, (Operand(Mode.DREG, 7), Operand(Mode.ABSL,
                                                                                         value=addrs[k - item[1]]))),
                          addrs[k])
    return out


def machine(code: bytes, seed: int, d: list[int], ccr: int) -> oracles.Machine:
    """Code at CODE, random data, address registers inside the data region, A7 near its top."""
    rng = random.Random(seed)
    image = bytes(oracles.base_image(seed, [(oracles.CODE, code)]))
    a = [oracles.DATA_LO + 2 * rng.randrange(0x100, 0x700) for _ in range(7)] + [0x6F00]
    return oracles.Machine([v & M32 for v in d], a, ccr & 0x1F, oracles.CODE, image)


def ours_blocks(m: oracles.Machine, end: int, limit: int, upto: bool = False) -> tuple[object, ...]:
    """Our CPU (blocks on) from ``m`` until PC == ``end`` or a fault (``upto``: or after ``limit`` instructions,
    returning the state there; else stopping at the limit fails the test), as :func:`ref_run`."""
    cpu = oracles.make_cpu(isa)
    cpu.write_bytes(0, m.memory)
    for i in range(8):
        cpu.d[i], cpu.a[i] = m.d[i], m.a[i]
    cpu.sr = 0x2700 | m.ccr
    cpu.pc = m.pc
    try:
        res = cpu.run(max_instructions=limit, until_pc=end, stop_at_limit=True)
    except CPUFault as exc:
        kind = next((k for cls, k in oracles.OursAdapter.get().faults if isinstance(exc, cls)), "other")
        return (kind,)
    assert upto or res.reason == "until_pc", res
    return (None, tuple(cpu.d), tuple(cpu.a), cpu.pc, cpu.sr & 0x1F,
            cpu.read_bytes(0, oracles.EXCLUDED_LO), res.cycles, res.instructions)


_REF: list[oracles.M68000PyRef] = []


def ref_run(m: oracles.Machine, end: int, limit: int, upto: bool = False) -> tuple[object, ...]:
    """m68000-python stepping from ``m`` until PC == ``end`` or it takes an exception (``upto``: or after
    ``limit`` instructions, returning the state there; else reaching the limit fails the test)."""
    from m68000_python import CPUState

    if not _REF:
        _REF.append(oracles.M68000PyRef())
    ref = _REF[0]
    mem = ref.mem
    mem[:] = m.memory
    cpu = ref.cpu
    pc = m.pc
    cpu.restore_state(CPUState(d=tuple(m.d), a=tuple(m.a[:7]), usp=m.a[7], ssp=oracles.SSP, sr=m.ccr, pc=pc,
                               ir=(mem[pc] << 8) | mem[pc + 1], irc=(mem[pc + 2] << 8) | mem[pc + 3]))
    cycles = n = 0
    while True:
        cycles += cpu.step()
        n += 1
        after = cpu.capture_state()
        vector = oracles._vector_state(after.pc)
        if vector is not None or after.halted:
            return (oracles._fault_of_vector(vector) if vector is not None else "other",)
        if after.pc == end or (upto and n == limit):
            return (None, tuple(after.d), tuple(after.a) + (after.usp,), after.pc, after.sr & 0x1F,
                    bytes(mem[: oracles.EXCLUDED_LO]), cycles, n)
        assert n < limit, "reference did not reach the end of the block"


def _diff(ours: tuple[object, ...], ref: tuple[object, ...]) -> str:
    names = ("fault", "D", "A", "PC", "CCR", "memory", "cycles", "instructions")
    return "; ".join(f"{k}: ours {a!r:.200} ref {b!r:.200}" for k, a, b in zip(names, ours, ref) if a != b)


def _regs(draw: st.DrawFn) -> list[int]:
    return [draw(st.sampled_from(EDGE) | st.integers(0, M32)) for _ in range(8)]


@st.composite
def straight_blocks(draw: st.DrawFn) -> tuple[bytes, list[int], int, int]:
    """2..12 data instructions, some Bcc.S forward over 1..3 of them."""
    items: list[object] = []
    for _ in range(draw(st.integers(2, 12))):
        if draw(st.integers(0, 5)) == 0:
            items.append(("b", "b" + draw(st.sampled_from("hi ls cc cs ne eq vc vs pl mi ge lt gt le".split())),
                          draw(st.integers(1, 3))))
        items.append(draw(ALU))
    return layout(items, oracles.CODE), _regs(draw), draw(st.integers(0, 31)), draw(st.integers(0, 1 << 30))


@st.composite
def loops(draw: st.DrawFn) -> tuple[bytes, list[int], int, int]:
    """MOVEQ #n,D7 then a body of 1..6 data instructions (maybe a forward Bcc) closed by DBRA D7."""
    body: list[object] = [draw(ALU) for _ in range(draw(st.integers(1, 6)))]
    if len(body) > 1 and draw(st.booleans()):
        body.insert(draw(st.integers(0, len(body) - 1)), ("b", "b" + draw(st.sampled_from(["ne", "eq", "cs", "pl"])),
                                                            1))
    count = draw(st.integers(0, 5))
    items: list[object] = [Instruction("moveq", None, (Operand(Mode.IMM, value=count), Operand(Mode.DREG, 7)))]
    items += body + [("dbra", len(body))]
    return layout(items, oracles.CODE), _regs(draw), draw(st.integers(0, 31)), draw(st.integers(0, 1 << 30))


def _check_vs_ref(case: tuple[bytes, list[int], int, int], limit: int) -> None:
    code, d, ccr, seed = case
    m = machine(code, seed, d, ccr)
    end = oracles.CODE + len(code)
    ours, ref = ours_blocks(m, end, limit), ref_run(m, end, limit)
    assert ours == ref, f"{_diff(ours, ref)}\n  code {code.hex(' ')} d={[hex(v) for v in d]} ccr={ccr:#x}"


@settings(max_examples=examples(150, ci=30), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(straight_blocks())
def test_straight_blocks_vs_m68000py(case: tuple[bytes, list[int], int, int]) -> None:
    _check_vs_ref(case, 200)


@settings(max_examples=examples(100, ci=20), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(loops())
def test_loops_vs_m68000py(case: tuple[bytes, list[int], int, int]) -> None:
    _check_vs_ref(case, 200)


def test_reference_comparison_is_not_vacuous() -> None:
    """A straight block that runs clean on both: the comparison really covers registers, flags and clocks."""
    src = " moveq #5,d0\n add.l d0,d1\n lsl.w #3,d1\n muls.w d1,d2\n bne.s over\n not.l d3\nover: move.w d2,(a0)+\n"
    code = isa.assemble(src, origin=oracles.CODE).code
    m = machine(code, 1, [0, 3, 0x1234, 0, 0, 0, 0, 0], 0x1F)
    end = oracles.CODE + len(code)
    ours, ref = ours_blocks(m, end, 50), ref_run(m, end, 50)
    assert ours[0] is None and ours == ref
    # D1 = 8, LSL.W #3 -> $0040; MULS: 38 + 2n, n = 2 transitions in $0080 (UM 8-4); D2 != 0 so BNE is taken
    assert ours[6] == 4 + 8 + (6 + 2 * 3) + (38 + 2 * 2) + 10 + 8


# ------------------------------------------------------------------------------------------------ blocks == closures
ANY = instructions(rows=[r for r in
                         "move movea moveq movem lea pea clr ext swap exg add adda addi addq addx sub suba subi subq "
                         "subx neg negx cmp cmpa cmpi tst and andi or ori eor eori not asl asr lsl lsr rol ror roxl "
                         "roxr muls mulu divs divu bcc bra bsr dbcc scc jmp jsr rts nop trap illegal".split()],
                   address=st.integers(oracles.CODE // 2, (oracles.CODE + 0x40) // 2).map(lambda v: 2 * v),
                   absolute=st.sampled_from([0x6000, 0x6002, 0x6001, 0x7FFE, 0xC000, 0xC010, 0x30000, 0xFFFFF0]))


def _snapshot(cpu: CPU) -> tuple[object, ...]:
    return (tuple(cpu.d), tuple(cpu.a), cpu.pc, cpu.sr, cpu.instructions, cpu.cycles, cpu.min_sp, cpu.ram_written,
            cpu.written_ranges(), cpu.read_bytes(0, oracles.RAM_SIZE))


def _run_both(image: bytes, d: list[int], a: list[int], ccr: int, kwargs: dict[str, object],
              profiling: bool = False) -> list[tuple[object, ...]]:
    out = []
    for blocks in (True, False):
        cpu = oracles.make_cpu(isa)
        cpu.block_compile = blocks
        cpu.profiling = profiling
        cpu.write_bytes(0, image)
        cpu.source_map = {}
        for i in range(8):
            cpu.d[i], cpu.a[i] = d[i], a[i]
        cpu.sr = 0x2700 | ccr
        cpu.pc = oracles.CODE
        try:
            res = cpu.run(**kwargs)  # type: ignore[arg-type]  # **kwargs of mixed run() argument types
            outcome: tuple[object, ...] = ("ok", res)
        except CPUFault as exc:
            outcome = (type(exc).__name__, str(exc), exc.pc, exc.instruction)
        # a second run from wherever the first stopped (blocks compiled by the first run are reused)
        try:
            res2 = cpu.run(max_instructions=20, stop_at_limit=True)
            again: tuple[object, ...] = ("ok", res2)
        except CPUFault as exc:
            again = (type(exc).__name__, str(exc), exc.pc)
        out.append(outcome + _snapshot(cpu) + again + (dict(cpu.profile),))
    return out


@settings(max_examples=examples(300, ci=60), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(ANY, min_size=1, max_size=14), st.lists(st.sampled_from(EDGE) | st.integers(0, M32), min_size=8,
                                                        max_size=8),
       st.integers(0, 31), st.integers(0, 1 << 30), st.integers(1, 40), st.integers(1, 600), st.integers(0, 40))
def test_blocks_equal_closures_any_instructions(prog: list[Instruction], d: list[int], ccr: int, seed: int,
                                                 max_n: int, max_c: int, until_k: int) -> None:
    """Random sequences of any instructions (laid out back to back from CODE; branch targets where the strategy
    put them, so some land in the middle of other instructions or in data): run with blocks and without, with a
    random instruction limit, a random cycle limit and sometimes an until_pc inside the code; everything equal."""
    code = b""
    addr = oracles.CODE
    for ins in prog:
        try:
            code += encode(ins, addr)
        except isa.errors.EncodingError:
            code += b"\x4e\x71"  # a branch drawn out of reach from here: NOP instead
        addr = oracles.CODE + len(code)
    rng = random.Random(seed)
    image = bytes(oracles.base_image(seed, [(oracles.CODE, code)]))
    a = [oracles.DATA_LO + 2 * rng.randrange(0, 0x800) for _ in range(7)] + [0x6F00 + 2 * rng.randrange(0, 64)]
    until = oracles.CODE + 2 * until_k if until_k < 20 else None
    kwargs = dict(max_instructions=max_n, max_cycles=max_c, until_pc=until, stop_at_limit=bool(seed & 1))
    blocks, closures = _run_both(image, d, a, ccr, kwargs)
    assert blocks == closures


def test_self_modifying_block_and_limits_inside_block() -> None:
    """A block that rewrites one of its own later instructions must leave before it; limits and until_pc that
    fall inside a block are honoured exactly."""
    src = """
        moveq #0,d0
        move.w #$7205,patch     ; rewrite the MOVEQ below (moveq #1,d1 -> moveq #5,d1) before it runs
        addq.l #1,d0
patch:  moveq #1,d1
        add.l d1,d0
        trap #0
"""
    prog = isa.assemble(src, origin=oracles.CODE)
    image = bytes(oracles.base_image(0, [(oracles.CODE, prog.code)]))
    for kwargs in ({}, {"max_instructions": 3, "stop_at_limit": True}, {"max_cycles": 25, "stop_at_limit": True},
                   {"until_pc": prog.symbol("patch").address}):
        blocks, closures = _run_both(image, [0] * 8, [0x6000] * 7 + [0x6F00], 0, kwargs)
        assert blocks == closures
    cpu = oracles.make_cpu(isa)
    cpu.write_bytes(0, image)
    cpu.a[7] = 0x6F00
    cpu.pc = oracles.CODE
    assert cpu.run().reason == "trap" and cpu.d[1] == 5 and cpu.d[0] == 6


def test_fault_inside_block_reports_instruction_and_keeps_state() -> None:
    src = " moveq #3,d0\n addq.l #1,d0\n lsl.l #2,d0\n move.l d0,(a0)+\n move.w (a1),d1\n moveq #9,d2\n"
    prog = isa.assemble(src, filename="f.s", origin=oracles.CODE)
    image = bytes(oracles.base_image(0, [(oracles.CODE, prog.code)]))
    blocks, closures = _run_both(image, [0] * 8, [0x6000, 0x6001] + [0x6000] * 5 + [0x6F00], 0, {})
    assert blocks == closures
    assert blocks[0] == "AddressError" and blocks[2] == oracles.CODE + 8
    d, a, pc, sr, n, cycles = blocks[4:10]
    assert d[0] == 16 and a[0] == 0x6004 and n == 4 and cycles == 4 + 8 + 12 + 12 and sr & 0x1F == 0


def test_condition_expressions_match_table() -> None:
    """The inline condition expressions of generated code equal the PRM table used by the closures."""
    for cc in range(16):
        for f in range(32):
            assert bool(eval(_COND_EXPR[cc], {}, {"sr": 0x2700 | f})) == _COND[cc][f], (cc, f)


# ---------------------------------------------------------------------------------------------------- firmware
@pytest.mark.parametrize("program", ["recursive", "kalman_baro", "kalman_accel"])
def test_firmware_blocks_equal_closures(program: str) -> None:
    np = pytest.importorskip("numpy")
    from firmware_model.firmware.assemble import build_firmware
    from firmware_model.spec.config import BuildConfig
    from firmware_model.firmware.harness import ACCEL_ADC, BARO_ADC, _Machine
    from firmware_model.model.streams import synthetic_flight

    build = build_firmware(BuildConfig(program=program, k=5))
    flight = synthetic_flight(5, seed=3)
    adc = np.asarray(flight.adc).tolist()[:300]
    acc = (np.asarray(flight.acc).astype(int) & 0xFFFF).tolist()[:300]
    results = []
    for blocks, profiling in ((True, False), (False, False), (True, True)):
        cpu = _Machine(build).cpu
        cpu.block_compile = blocks
        cpu.profiling = profiling
        cpu.reset_counters()
        trace = []
        cpu.write(BARO_ADC, adc[0], 2)
        cpu.write(ACCEL_ADC, acc[0], 2)
        trace.append(cpu.call(build.init_address))
        for x, y in zip(adc, acc):
            cpu.write(BARO_ADC, x, 2)
            cpu.write(ACCEL_ADC, y, 2)
            trace.append(cpu.call(build.step_address))
            trace.append(cpu.read_bytes(0x0, 0) + bytes(cpu.read_bytes(build.program.symbol("X1").address
                                                                       if program != "recursive" else
                                                                       build.program.symbol("EST").address, 4)))
        results.append((trace, cpu.instructions, cpu.cycles, cpu.min_sp, cpu.ram_written, tuple(cpu.d),
                        tuple(cpu.a), cpu.sr, cpu.profile if profiling else None))
    assert results[0][:8] == results[1][:8] == results[2][:8]
    assert results[0][1] > 300 * 10  # the firmware really ran
    prof = results[2][8]
    assert sum(v[0] for v in prof.values()) == results[2][1] and sum(v[1] for v in prof.values()) == results[2][2]


# ------------------------------------------------------------------------------------- control flow inside blocks
# Programs with forward branches that land inside the same block (compiled as if / if-else), BRA forward over
# code, and loops back to the block's first instruction (compiled as a while loop inside the block function).
COND_B = "bhi bls bcc bcs bne beq bvc bvs bpl bmi bge blt bgt ble".split()
COND_DB = "dbra dbt dbhi dbls dbcc dbcs dbne dbeq dbvc dbvs dbpl dbmi dbge dblt dbgt dble".split()


def flow_layout(items: list[object], origin: int) -> bytes:
    """Encode ``items`` back to back from ``origin``. An item is an Instruction, or
    ``("b", mnemonic, skip, short)``: Bcc/BRA forward to the item ``skip`` places after the next one (clamped to
    the end of the code), ``("bb", mnemonic, back, short)``: Bcc/BRA backward to the item ``back`` places before
    it, ``("db", mnemonic, back)``: DBcc D7 to the item ``back`` places before it. ``short`` asks for Bcc.S,
    used when the displacement fits (the layout is first made with every branch .W; .S only shortens it)."""
    def size(item: object, short_ok: list[bool], k: int) -> int:
        if isinstance(item, Instruction):
            return length(item)
        return 2 if item[0] in ("b", "bb") and short_ok[k] else 4

    def addresses(short_ok: list[bool]) -> list[int]:
        out = [origin]
        for k, item in enumerate(items):
            out.append(out[-1] + size(item, short_ok, k))
        return out

    def target(k: int, item: tuple[object, ...]) -> int:
        if item[0] == "b":
            return min(k + 1 + item[2], len(items))  # type: ignore[operator]  # item[2] is an int in these rows
        return max(k - item[2], 0)  # type: ignore[operator]  # item[2] is an int in these rows

    wide = addresses([False] * len(items))
    short_ok = [not isinstance(it, Instruction) and it[0] in ("b", "bb") and bool(it[3])
                and -100 <= wide[target(k, it)] - (wide[k] + 2) <= 100
                and target(k, it) != k + 1 for k, it in enumerate(items)]
    addrs = addresses(short_ok)
    out = b""
    for k, item in enumerate(items):
        if isinstance(item, Instruction):
            out += encode(item, addrs[k])
            continue
        t = Operand(Mode.ABSL, value=addrs[target(k, item)])
        if item[0] == "db":
            out += encode(Instruction(item[1], Size.W, (Operand(Mode.DREG, 7), t)), addrs[k])
        else:
            out += encode(Instruction(item[1], Size.S if short_ok[k] else Size.W, (t,)), addrs[k])
    return out


def _flow_body(draw: st.DrawFn, ins: st.SearchStrategy[Instruction], depth: int = 0) -> list[object]:
    """1..6 instructions mixed with forward Bcc/BRA over some of them and, now and then, an explicit
    ``bcc L1; then...; bra L2; L1: else...; L2:`` (nested up to depth 2)."""
    items: list[object] = []
    for _ in range(draw(st.integers(1, 6))):
        pick = draw(st.integers(0, 9))
        if pick == 0:
            items.append(("b", draw(st.sampled_from(COND_B + ["bra"])), draw(st.integers(0, 4)), draw(st.booleans())))
        elif pick == 1 and depth < 2:
            then = _flow_body(draw, ins, depth + 1)
            other = _flow_body(draw, ins, depth + 1)
            items.append(("b", draw(st.sampled_from(COND_B)), len(then) + 1, draw(st.booleans())))
            items += then
            items.append(("b", "bra", len(other) - 1, draw(st.booleans())))
            items += other
        else:
            items.append(draw(ins))
    return items


@st.composite
def flow_loops(draw: st.DrawFn) -> tuple[bytes, list[int], int, int]:
    """A loop whose first instruction is the run's (so the block's) start: a body with forward branches closed by
    DBcc D7 (D7 = 0..5), or by ``SUBQ.W #1,D7`` and a Bcc back that ends once D7 runs out (D7 = 1..5); the body
    never touches D7, so every loop ends."""
    body = _flow_body(draw, ALU)
    for p, it in enumerate(body):  # forward branches stay inside the body (never skip the loop's counting)
        if isinstance(it, tuple):
            body[p] = (it[0], it[1], min(it[2], len(body) - p - 1), it[3])
    d = _regs(draw)
    if draw(st.booleans()):
        body.append(("db", draw(st.sampled_from(COND_DB)), len(body)))
        d[7] = draw(st.integers(0, 5))
    else:
        body.append(Instruction("subq", Size.W, (Operand(Mode.IMM, value=1), Operand(Mode.DREG, 7))))
        body.append(("bb", draw(st.sampled_from(["bne", "bpl", "bcc", "bge", "bgt"])), len(body), draw(st.booleans())))
        d[7] = draw(st.integers(1, 5))
    if draw(st.integers(0, 3)) == 0:  # the loop head is not the first block's start (second block loops)
        body = [Instruction("moveq", None, (Operand(Mode.IMM, value=d[7]), Operand(Mode.DREG, 7)))] + body
    return flow_layout(body, oracles.CODE), d, draw(st.integers(0, 31)), draw(st.integers(0, 1 << 30))


@settings(max_examples=examples(150, ci=30), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(flow_loops())
def test_flow_loops_vs_m68000py(case: tuple[bytes, list[int], int, int]) -> None:
    """Loops to the block start with if/else bodies: registers, CCR, PC, memory, clocks, instruction count (or
    the fault kind, e.g. a DIVU by zero in the second iteration) equal to m68000-python's."""
    _check_vs_ref(case, 1000)


@st.composite
def flow_straight(draw: st.DrawFn) -> tuple[bytes, list[int], int, int]:
    """No loop: nested forward branches and if/else only (targets clamped to the end of the code)."""
    body = _flow_body(draw, ALU) + _flow_body(draw, ALU)
    return flow_layout(body, oracles.CODE), _regs(draw), draw(st.integers(0, 31)), draw(st.integers(0, 1 << 30))


@settings(max_examples=examples(100, ci=20), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(flow_straight())
def test_flow_forward_branches_vs_m68000py(case: tuple[bytes, list[int], int, int]) -> None:
    _check_vs_ref(case, 200)


#: Data instructions for the closures comparison: any data row and mode, absolute addresses that hit data, odd
#: addresses (address errors), unmapped memory (bus errors) and the code itself (self-modifying code). No
#: PC-relative operands: they are drawn for one address and the instructions land at others.
FLOW_ANY = instructions(rows=ALU_ROWS + ["movea", "lea", "pea", "movem", "adda", "suba", "exg"],
                        address=oracles.CODE, modes=frozenset(Mode) - {Mode.PCDISP, Mode.PCINDEX},
                        absolute=st.sampled_from([0x6000, 0x6002, 0x6001, 0x7FFE, 0x30000, oracles.CODE,
                                                  oracles.CODE + 2, oracles.CODE + 6, oracles.CODE + 10])
                        ).filter(lambda i: not _touches_d7(i))


@st.composite
def flow_any(draw: st.DrawFn) -> list[object]:
    """Any flow program: the loop back may be a DBcc, a Bcc (maybe never ending: the limits end it) or a BRA."""
    body = _flow_body(draw, FLOW_ANY)
    kind = draw(st.integers(0, 3))
    if kind == 0:
        body.append(("db", draw(st.sampled_from(COND_DB)), len(body)))
    elif kind == 1:
        body.append(("bb", draw(st.sampled_from(COND_B + ["bra"])), len(body), draw(st.booleans())))
    elif kind == 2:
        body.append(("bb", draw(st.sampled_from(COND_B)), draw(st.integers(0, len(body))), draw(st.booleans())))
    return body


@settings(max_examples=examples(250, ci=50), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(flow_any(), st.lists(st.sampled_from(EDGE) | st.integers(0, M32), min_size=8, max_size=8),
       st.integers(0, 31), st.integers(0, 1 << 30), st.integers(1, 300), st.integers(1, 4000), st.integers(0, 60))
def test_flow_blocks_equal_closures(items: list[object], d: list[int], ccr: int, seed: int, max_n: int, max_c: int,
                                    until_k: int) -> None:
    """Loops and forward branches over any data instructions (faults, self-modifying writes included), with a
    random instruction limit, cycle limit and until_pc (at the start, inside the loop or nowhere): blocks and
    per-instruction closures leave everything identical (result or fault, registers, memory, counters)."""
    code = flow_layout(items, oracles.CODE)
    rng = random.Random(seed)
    # ILLEGAL words after the code, so blocks do not run on into random data (test_blocks_equal_closures_any_...
    # covers that); branches clamped to the end land on one
    image = bytes(oracles.base_image(seed, [(oracles.CODE, code + b"\x4a\xfc" * 4)]))
    a = [oracles.DATA_LO + 2 * rng.randrange(0, 0x800) for _ in range(7)] + [0x6F00 + 2 * rng.randrange(0, 64)]
    d = list(d)
    d[7] = d[7] & 0xFFFF0000 | rng.randrange(0, 12)
    until = oracles.CODE + 2 * until_k if until_k < 30 and 2 * until_k < len(code) else None
    kwargs = dict(max_instructions=max_n, max_cycles=max_c, until_pc=until, stop_at_limit=bool(seed & 1))
    blocks, closures = _run_both(image, d, a, ccr, kwargs)
    assert blocks == closures


LOOP_SRC = """
top:    add.l   d7,d0
        bne.s   skip
        addq.l  #1,d5
skip:   cmpa.l  #$6010,a0
        bcs.s   keep
        movea.l a1,a0
        bra.s   join
keep:   move.w  d0,(a0)+
join:   dbra    d7,top
        trap    #0
"""


def test_loop_limits_and_until_pc_at_every_point() -> None:
    """A loop with if/else in its body: every instruction limit, every cycle limit up to past the end, and
    until_pc at every instruction (the loop head included): blocks and closures agree exactly."""
    prog = isa.assemble(LOOP_SRC, origin=oracles.CODE)
    image = bytes(oracles.base_image(0, [(oracles.CODE, prog.code)]))
    d, a = [0, 0, 0, 0, 0, 0, 0, 9], [0x6000, 0x6000] + [0x6000] * 5 + [0x6F00]
    full = _run_both(image, d, a, 0, {})[0]
    assert full[0] == "ok" and full[1].reason == "trap" and full[1].instructions > 60
    for n in range(1, full[1].instructions + 2):
        blocks, closures = _run_both(image, d, a, 0, {"max_instructions": n, "stop_at_limit": True})
        assert blocks == closures, n
    for c in range(1, full[1].cycles + 20, 3):
        blocks, closures = _run_both(image, d, a, 0, {"max_cycles": c, "stop_at_limit": bool(c & 1)})
        assert blocks == closures, c
    addrs = sorted({oracles.CODE + off for off in range(0, len(prog.code), 2)})
    for u in addrs:
        blocks, closures = _run_both(image, d, a, 0, {"until_pc": u})
        assert blocks == closures, hex(u)


def test_loop_runs_inside_one_block_call() -> None:
    """Not vacuous: the loop above really runs as ONE call of the block function (a while loop inside it), and
    a budget that ends mid-loop makes it leave at the loop head with exact counters."""
    prog = isa.assemble(LOOP_SRC, origin=oracles.CODE)
    cpu = oracles.make_cpu(isa)
    cpu.write_bytes(oracles.CODE, prog.code)
    cpu.d[7], cpu.a[0], cpu.a[1], cpu.a[7] = 500, 0x6000, 0x6000, 0x6F00
    cpu.pc = oracles.CODE
    fn, *rest = cpu._build_block(oracles.CODE)
    calls = []

    def counting(*args: int) -> int:
        calls.append(args)
        return fn(*args)

    cpu._blocks[oracles.CODE] = (counting, *rest)
    res = cpu.run()
    assert res.reason == "trap" and len(calls) == 1 and res.instructions > 500 * 6
    ref = oracles.make_cpu(isa)
    ref.block_compile = False
    ref.write_bytes(oracles.CODE, prog.code)
    ref.d[7], ref.a[0], ref.a[1], ref.a[7] = 500, 0x6000, 0x6000, 0x6F00
    ref.pc = oracles.CODE
    assert ref.run() == res and tuple(ref.d) == tuple(cpu.d) and tuple(ref.a) == tuple(cpu.a) and ref.sr == cpu.sr


def test_self_modifying_write_inside_loop() -> None:
    """The loop rewrites its own ADDQ #1 into ADDQ #3 in the third iteration (a MOVE.W to the code in the loop
    body): the block leaves after the write, is recompiled, and the rest of the loop adds 3 per iteration."""
    src = """
top:    cmpi.w  #2,d7
        bne.s   same
        move.w  #$5681,patch    ; addq.l #3,d1
same:   nop
patch:  addq.l  #1,d1
        dbra    d7,top
        trap    #0
"""
    prog = isa.assemble(src, origin=oracles.CODE)
    image = bytes(oracles.base_image(0, [(oracles.CODE, prog.code)]))
    blocks, closures = _run_both(image, [0] * 7 + [4], [0x6000] * 7 + [0x6F00], 0, {})
    assert blocks == closures
    assert blocks[0] == "ok" and blocks[1].reason == "trap"
    d = blocks[2]
    # D7 = 4, 3, 2 (rewritten here, before the ADDQ runs), 1, 0: adds 1 + 1 + 3 + 3 + 3
    assert d[1] == 11, d


def test_fault_in_second_iteration_of_loop() -> None:
    """A loop that walks A0 by 3 bytes: the word read at an odd address in the second iteration faults; the
    counters and registers left are exactly those after the first iteration plus the instructions before."""
    src = """
top:    addq.l  #1,d2
        move.w  (a0),d0
        addq.l  #3,a0
        dbra    d7,top
        trap    #0
"""
    prog = isa.assemble(src, filename="loop.s", origin=oracles.CODE)
    image = bytes(oracles.base_image(0, [(oracles.CODE, prog.code)]))
    blocks, closures = _run_both(image, [0] * 7 + [5], [0x6000] * 7 + [0x6F00], 0, {})
    assert blocks == closures
    assert blocks[0] == "AddressError" and blocks[2] == oracles.CODE + 2
    d, a, pc, sr, n, cycles = blocks[4:10]
    # iteration 1: ADDQ.L #1,Dn 8 + MOVE.W (An),Dn 8 + ADDQ.L #3,An 8 + DBRA taken 10; then ADDQ 8
    assert d[2] == 2 and a[0] == 0x6003 and d[7] == 4 and n == 5 and cycles == 8 + 8 + 8 + 10 + 8


@pytest.mark.parametrize("block", [True, False])
def test_min_sp_sees_a_push_that_the_same_block_pops(block: bool) -> None:
    """PEA then RTS in one block: A7 dips by 4 and comes back before the block exits; min_sp must see the dip
    (found by the thorough profile: the block path only looked at A7 after the block)."""
    cpu = CPU()
    cpu.block_compile = block
    program = isa.assemble(" pea (a0)\n rts\nback: trap #0\n", origin=0x1000)
    cpu.load(program)
    cpu.a[0] = program.symbol("back").address  # the PEA pushes the address of `back`, the RTS returns there
    cpu.a[7] = 0x8000
    cpu.reset_counters()
    result = cpu.run(max_instructions=10)
    assert result.reason == "trap" and cpu.a[7] == 0x8000
    assert cpu.min_sp == 0x8000 - 4


# ------------------------------------------------------------------------------------------------------------------
# Memory accesses compiled without accessor calls (isa/blocks.py: constant addresses the map guarantees, span-guarded
# register-indirect reads, flag-guarded writes with first-write marking) on a map with ROM, RAM, I/O and holes.
FW_CODE = 0x1000
#: Interesting addresses: ROM (read-only, holds the code), RAM start/end, I/O, holes, region edges, odd ones.
MAP_ADDRS = [0x0800, 0x0FFC, 0x3FFC, 0x3FFE, 0x4000, 0x4002, 0x4004, 0x4100, 0x4101, 0x7FFC, 0x7FFE, 0x7FFF,
             0x8000, 0x9000, 0xFFF000, 0xFFF002, 0xFFF003, 0xFFEFFE, 0xFFF004, 0xFFFFFC, 0x3FFF, 0x4003]
MAP_ABS = st.sampled_from(MAP_ADDRS)
MEM_ROWS = ["move", "add", "addi", "addq", "sub", "subi", "subq", "cmp", "cmpi", "tst", "and", "andi", "or", "ori",
            "eor", "eori", "not", "neg", "negx", "clr", "addx", "subx", "scc", "asl", "lsr", "roxl", "movem", "pea",
            "lea", "moveq", "divu", "divs", "muls", "mulu"]
MEM_INS = instructions(rows=MEM_ROWS, address=FW_CODE,
                       modes=frozenset({Mode.DREG, Mode.AREG, Mode.IMM, Mode.AIND, Mode.APOSTINC, Mode.APREDEC,
                                        Mode.ADISP, Mode.ABSW, Mode.ABSL, Mode.PCDISP}),
                       absolute=MAP_ABS).filter(lambda i: _small_disp(i))


def _map_cpu(blocks: bool) -> CPU:
    cpu = CPU(mapped=False)
    cpu.block_compile = blocks
    cpu.map(0, 0x4000, "rom", writable=False)
    cpu.map(0x4000, 0x4000, "ram")
    cpu.map(0xFFF000, 4, "io")
    return cpu


def _run_map(code: bytes, d: list[int], a: list[int], ccr: int, pre_written: bool, limit: int
             ) -> list[tuple[object, ...]]:
    out = []
    for blocks in (True, False):
        cpu = _map_cpu(blocks)
        cpu.write_bytes(FW_CODE, code)
        cpu.write_bytes(0x4000, bytes(range(256)) * 64)
        if pre_written:  # some RAM already written by the program (the fast write path), the rest first writes
            cpu.write_bytes(0x1F00, bytes([0x21, 0xFC, 0xAB, 0xCD, 0x12, 0x34, 0x41, 0x00, 0x4E, 0x40]))
            cpu.pc = 0x1F00  # move.l #$ABCD1234,($4100).w ; trap #0
            cpu.run()
        for i in range(8):
            cpu.d[i], cpu.a[i] = d[i], a[i]
        cpu.sr = 0x2700 | ccr
        cpu.pc = FW_CODE
        cpu.reset_counters()
        try:
            res = cpu.run(max_instructions=limit, stop_at_limit=True)
            outcome: tuple[object, ...] = ("ok", res)
        except CPUFault as exc:
            outcome = (type(exc).__name__, str(exc), exc.pc, exc.instruction)
        out.append(outcome + (tuple(cpu.d), tuple(cpu.a), cpu.pc, cpu.sr, cpu.instructions, cpu.cycles,
                              cpu.min_sp, cpu.ram_written, cpu.written_ranges(), cpu.read_bytes(0x4000, 0x4000),
                              cpu.read_bytes(0xFFF000, 4)))
    return out


@settings(max_examples=examples(250, ci=50), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(MEM_INS, min_size=1, max_size=12), st.lists(st.sampled_from(EDGE) | st.integers(0, M32),
                                                            min_size=8, max_size=8),
       st.lists(st.sampled_from(MAP_ADDRS + [0x4200, 0x5000, 0x7F00]), min_size=8, max_size=8),
       st.integers(0, 31), st.booleans(), st.integers(1, 30))
def test_blocks_equal_closures_on_a_rom_ram_io_map(prog: list[Instruction], d: list[int], a: list[int], ccr: int,
                                                   pre_written: bool, limit: int) -> None:
    """Constant and register-indirect reads/writes of ROM, RAM, I/O, holes, region edges and odd addresses, first
    writes and re-writes: blocks and closures give the same registers, SR (also at a fault after constant accesses
    whose flags the block compiler treats as dead), memory, counters, written ranges and fault."""
    code = b""
    for ins in prog:
        try:
            code += encode(ins, FW_CODE + len(code))
        except isa.errors.EncodingError:
            code += b"\x4e\x71"  # a PC-relative operand drawn out of reach from here: NOP instead
    addr = FW_CODE + len(code)
    code += bytes([0x4E, 0x40])  # trap #0
    if addr + 2 > 0x4000:
        return
    a = a[:7] + [0x7F00]
    blocks, closures = _run_map(code, d, a, ccr, pre_written, limit)
    assert blocks == closures


def test_constant_access_paths_are_used_and_exact() -> None:
    """Not vacuous: a block with constant RAM/ROM/I-O reads and writes runs in one call, marks first writes, and
    a constant write to ROM or to a hole faults exactly as the closures do (same SR, counters, message)."""
    src = """
        move.l  ($4000).w,d0
        add.l   ($0800).w,d0
        move.w  ($FFF000).l,d1
        move.l  d0,($4004).w
        move.l  d0,($4004).w
        move.b  d1,($4009).w
        cmp.l   ($4004).w,d0
        move.l  d0,(a0)+
        move.w  d1,(a0)+
        move.l  -4(a0),d2
        trap    #0
"""
    prog = isa.assemble(src, origin=FW_CODE)
    results = []
    for blocks in (True, False):
        cpu = _map_cpu(blocks)
        cpu.write_bytes(FW_CODE, prog.code)
        cpu.write_bytes(0x4000, bytes(range(1, 65)))
        cpu.write(0xFFF000, 0x1234, 2)
        cpu.a[0] = 0x4100
        cpu.pc = FW_CODE
        res = cpu.run()
        results.append((res, tuple(cpu.d), tuple(cpu.a), cpu.sr, cpu.ram_written, cpu.written_ranges(),
                        cpu.read_bytes(0x4000, 0x200)))
        if blocks:
            assert len(cpu._block_code) == 1  # the whole program ran as one block
    assert results[0] == results[1]
    assert results[0][4] == 4 + 1 + 6 and results[0][5] == [(0x4004, 0x4008), (0x4009, 0x400A), (0x4100, 0x4106)]
    for target in ("($0800).w", "($9000).l", "($FFF004).l", "($4001).w", "($FFEFFE).l"):
        bad = isa.assemble(f" moveq #-1,d0\n tst.l d0\n move.l d0,{target}\n trap #0\n", origin=FW_CODE)
        outs = []
        for blocks in (True, False):
            cpu = _map_cpu(blocks)
            cpu.write_bytes(FW_CODE, bad.code)
            cpu.pc = FW_CODE
            with pytest.raises(CPUFault) as info:
                cpu.run()
            outs.append((type(info.value), str(info.value), cpu.sr, cpu.instructions, cpu.cycles, cpu.pc))
        assert outs[0] == outs[1], target


@pytest.mark.parametrize("src", ["moveq #12,d5\n asr.l d5,d0", "moveq #40,d5\n lsl.l d5,d0",
                                 "moveq #33,d5\n lsr.l d5,d0", "moveq #0,d5\n asr.l d5,d0",
                                 "moveq #-1,d5\n ror.w d5,d0", "moveq #9,d5\n roxl.l d5,d0"])
def test_shift_by_a_register_set_by_moveq(src: str) -> None:
    """MOVEQ #n,Dc then a shift by Dc compiles as a constant shift: same result, flags and clocks as the
    closures and as m68000-python."""
    for value in (0, 1, 0x7FFFFFFF, 0x80000000, 0xDEADBEEF, 0x00012345):
        code = isa.assemble(f" {src}\n trap #0\n", origin=oracles.CODE).code
        image = bytes(oracles.base_image(0, [(oracles.CODE, code)]))
        for ccr in (0, 0x1F):
            blocks, closures = _run_both(image, [value] + [0] * 7, [0x6000] * 7 + [0x6F00], ccr, {})
            assert blocks == closures
            m = oracles.Machine([value] + [0] * 7, [0x6000] * 7 + [0x6F00], ccr, oracles.CODE, image)
            end = oracles.CODE + len(code) - 2
            assert ours_blocks(m, end, 10) == ref_run(m, end, 10)


@pytest.mark.parametrize("op", ["divu.w #1000,d0", "divu.w #$9001,d0", "divu.w #1,d0", "divs.w #-3000,d0",
                                "divs.w #7,d0", "divs.w #-1,d0", "divu.w d1,d0", "divs.w d1,d0"])
def test_division_clocks_inline_vs_m68000py(op: str) -> None:
    """DIVU/DIVS clocks computed inline (closed form of the microcode loop) equal m68000-python's for dividends
    and divisors at the edges: overflow, divisors above $8000, negative operands, zero quotient."""
    code = isa.assemble(f" {op}\n trap #0\n", origin=oracles.CODE).code
    image = bytes(oracles.base_image(0, [(oracles.CODE, code)]))
    end = oracles.CODE + len(code) - 2
    rng = random.Random(op)
    values = [0, 1, 999, 0x7FFF, 0x8000, 0xFFFF, 0x10000, 0x7FFFFFFF, 0x80000000, 0xFFFFFFFF, 0xFFFF8000, 0x12345678]
    values += [rng.getrandbits(32) for _ in range(12)] + [rng.getrandbits(20) for _ in range(12)]
    for dividend in values:
        for divisor in (3, 0x9001, 0xFFFF, 0x8000, 0x8001, 7, 1000):
            m = oracles.Machine([dividend, divisor] + [0] * 6, [0x6000] * 7 + [0x6F00], 0, oracles.CODE, image)
            assert ours_blocks(m, end, 10) == ref_run(m, end, 10), (hex(dividend), hex(divisor))


def test_constant_write_to_other_code_keeps_running_and_rewrites_it() -> None:
    """A constant-address write outside the running block's own code (here: into a subroutine compiled earlier)
    needs no block exit; the subroutine's compiled code is dropped and the rewritten instruction runs. A write
    into the running block's own code still leaves the block (test_self_modifying_write_inside_loop)."""
    src = """
start:  moveq   #0,d1
        bsr.s   sub             ; compiles and runs sub: d1 = 1
        move.w  #$5283,patch    ; patch (in sub) becomes addq.l #1,d3
        moveq   #5,d0
        cmp.l   d0,d1
        bsr.s   sub
        trap    #0
sub:    addq.l  #1,d1
patch:  addq.l  #1,d2
        rts
"""
    prog = isa.assemble(src, origin=oracles.CODE)
    image = bytes(oracles.base_image(0, [(oracles.CODE, prog.code)]))
    for limit in (3, 5, 7, 9, 11):
        blocks, closures = _run_both(image, [0] * 8, [0x6000] * 7 + [0x6F00], 0,
                                     {"max_instructions": limit, "stop_at_limit": True})
        assert blocks == closures, limit
    blocks, closures = _run_both(image, [0] * 8, [0x6000] * 7 + [0x6F00], 0, {})
    assert blocks == closures
    d = blocks[2]
    assert blocks[0] == "ok" and blocks[1].reason == "trap"
    # sub ran once unpatched (d2 += 1), then patched: once from the second BSR and once more when _run_both's
    # second run goes on after the TRAP into sub (d3 += 1 each time)
    assert d[1] == 3 and d[2] == 1 and d[3] == 2, d


@pytest.mark.parametrize("text", ["move.l 8(a0),d0", "move.l -8(a0),d0", "move.w 6(a0),d0", "move.b 3(a0),d0",
                                  "move.w -2(a0,d1.w),d2", "move.l 4(a0,d1.l),d2", "add.l d1,4(a0)",
                                  "move.l d1,8(a0)", "move.w d1,-2(a0)", "move.w d1,2(a0,d1.w)", "addq.w #1,-6(a0)"])
@pytest.mark.parametrize("a0", [0, 2, 6, 0x3FFA, 0x4000, 0x7FFA, 0xFFFFFFFC, 0xFFFFFFF8, 0x00FFFFFC, 0x00FFEFFC,
                                0xFFFFF000 - 6])
@pytest.mark.parametrize("d1", [0, 4, 0xFFFC, 0xFFFFFFF8, 0x10000])
def test_displacement_addresses_that_go_negative_or_wrap(text: str, a0: int, d1: int) -> None:
    """d16(An) / d8(An,Xn) addresses computed once inside blocks (unmasked, into _t): a sum below 0 or at/above
    2^24 (the 68000 wraps it) takes the exact accessor; blocks and closures agree on registers, memory, faults."""
    code = isa.assemble(f" {text}\n trap #0\n", origin=FW_CODE).code
    d = [0x11223344, d1, 0, 0, 0, 0, 0, 0]
    a = [a0, 0, 0, 0, 0, 0, 0, 0x7F00]
    blocks, closures = _run_map(code, d, a, 0, True, 5)
    assert blocks == closures


# ------------------------------------------------------------------------------------- duplicated tails (planner)
#: Instructions that neither read nor set a flag (D0-D6/A0-A6 only).
NEUTRAL = st.sampled_from([
    Instruction("nop", None, ()),
    Instruction("movea", Size.L, (Operand(Mode.DREG, 4), Operand(Mode.AREG, 0))),
    Instruction("exg", Size.L, (Operand(Mode.DREG, 5), Operand(Mode.DREG, 6))),
    Instruction("adda", Size.W, (Operand(Mode.DREG, 3), Operand(Mode.AREG, 1))),
    Instruction("lea", Size.L, (Operand(Mode.ADISP, 2, value=6), Operand(Mode.AREG, 3)))])

@st.composite
def dup_flow(draw: st.DrawFn, ins: st.SearchStrategy[Instruction]) -> list[object]:
    """Branches that leave nested regions for later code of the same block (isa.block_plan._plan_tails): the
    firmware's gate shape (``bcc L1; ...; bcc L1; ...; bra L2; L1: ...; L2:``, the inner Bcc jumping from the
    then-part to the start of the else-part), Bcc/BRA from the then-part, the else-part and a nested ``if`` to a
    common tail ``far``; labels resolved to flow_layout items (``("b", mnemonic, skip, short)``)."""
    cond = st.sampled_from(COND_B)
    any_b = st.sampled_from(COND_B) | st.just("bra")  # BRA half the time: an unconditional jump into a copy

    def body(lo: int, hi: int) -> list[object]:
        """lo..hi instructions, often after flag-neutral ones (so that flags set before a jump reach the copy's
        exit: the liveness of a duplicated tail is observable)."""
        out: list[object] = [draw(NEUTRAL) for _ in range(draw(st.integers(0, 2)))]
        return out + [draw(ins) for _ in range(draw(st.integers(lo, hi)))]

    raw: list[object] = body(0, 3)
    raw.append(("J", draw(cond), "else"))
    raw += body(0, 2)
    raw.append(("J", draw(cond), "else"))  # then-part -> start of the else-part
    raw += body(0, 2)
    if draw(st.booleans()):
        raw.append(("J", draw(any_b), "far"))
        raw += body(0, 2)
    raw.append(("J", "bra", "join"))
    raw.append(("L", "else"))
    raw += body(1, 3)
    raw.append(("J", draw(any_b), "far"))  # else-part -> far
    raw += body(0, 2)
    raw.append(("L", "join"))
    raw += body(1, 3)
    raw.append(("J", draw(cond), "skip"))
    raw += body(0, 2)
    raw.append(("J", draw(any_b), "far"))  # a nested if -> far
    raw += body(0, 1)
    raw.append(("L", "skip"))
    raw += body(0, 2)
    raw.append(("L", "far"))
    raw += body(1, 3)
    where: dict[str, int] = {}
    for item in raw:
        if isinstance(item, tuple) and item[0] == "L":
            where[item[1]] = sum(1 for x in raw[:raw.index(item)] if not (isinstance(x, tuple) and x[0] == "L"))
    items: list[object] = []
    for item in raw:
        if isinstance(item, tuple) and item[0] == "L":
            continue
        if isinstance(item, tuple):
            items.append(("b", item[1], where[item[2]] - len(items) - 1, draw(st.booleans())))
        else:
            items.append(item)
    return items


def _assert_duplicates(image: bytes, end: int) -> None:
    """The block at CODE spans the generated code and its plan duplicates at least one tail (not vacuous)."""
    from isa.blocks import BLOCK_MAX, _plan, block_entries

    cpu = oracles.make_cpu(isa)
    cpu.write_bytes(0, image)
    entries = block_entries(oracles.CODE, BLOCK_MAX, cpu._decoded_at)
    assert entries[-1][0] + entries[-1][4] == end
    assert any(r[0] == "dup" for r in _plan(entries)[0].values())


TRAP0 = b"\x4e\x40"


@settings(max_examples=examples(100, ci=20), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(dup_flow(ALU), st.integers(0, 31), st.integers(0, 1 << 30), st.data())
def test_duplicated_tails_vs_m68000py(items: list[object], ccr: int, seed: int, data: st.DataObject) -> None:
    """Blocks whose plan duplicates tails (the copies carry their own clock/instruction constants): registers,
    CCR, PC, memory, clocks and instruction count (or the fault kind) equal to m68000-python's. A TRAP #0 after
    the code ends the block there, so our run takes the whole code as one block."""
    code = flow_layout(items, oracles.CODE)
    d = _regs(data.draw)
    m = machine(code + TRAP0, seed, d, ccr)
    end = oracles.CODE + len(code)
    _assert_duplicates(m.memory, end)
    ours, ref = ours_blocks(m, end, 400), ref_run(m, end, 400)
    assert ours == ref, f"{_diff(ours, ref)}\n  code {code.hex(' ')} d={[hex(v) for v in d]} ccr={ccr:#x}"


@settings(max_examples=examples(150, ci=30), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(dup_flow(FLOW_ANY), st.lists(st.sampled_from(EDGE) | st.integers(0, M32), min_size=8, max_size=8),
       st.integers(0, 31), st.integers(0, 1 << 30), st.integers(1, 300), st.integers(1, 4000), st.integers(0, 60))
def test_duplicated_tails_equal_closures(items: list[object], d: list[int], ccr: int, seed: int, max_n: int,
                                         max_c: int, until_k: int) -> None:
    """Duplicated tails over any data instructions (faults inside a copy are unwound through that copy's line
    map; self-modifying writes; limits; until_pc anywhere in the code): blocks and per-instruction closures leave
    everything identical (result or fault with its PC and message, registers, memory, counters)."""
    code = flow_layout(items, oracles.CODE)
    rng = random.Random(seed)
    image = bytes(oracles.base_image(seed, [(oracles.CODE, code + TRAP0 + b"\x4a\xfc" * 4)]))
    _assert_duplicates(image, oracles.CODE + len(code))
    a = [oracles.DATA_LO + 2 * rng.randrange(0, 0x800) for _ in range(7)] + [0x6F00 + 2 * rng.randrange(0, 64)]
    until = oracles.CODE + 2 * until_k if until_k < 40 and 2 * until_k < len(code) else None
    kwargs = dict(max_instructions=max_n, max_cycles=max_c, until_pc=until, stop_at_limit=bool(seed & 1))
    blocks, closures = _run_both(image, d, a, ccr, kwargs)
    assert blocks == closures


def test_firmware_step_is_one_block() -> None:
    """The kalman_accel step (gate: a BGT.S from the then-part to the else-part; branches to .done from every
    depth; the apogee-prediction loop) compiles as one loop-free block with duplicated tails and runs as one
    block call per sample."""
    from firmware_model.firmware.assemble import build_firmware
    from firmware_model.spec.config import BuildConfig
    from firmware_model.firmware.harness import firmware_cpu
    from isa.blocks import BLOCK_MAX, _plan, block_entries

    build = build_firmware(BuildConfig(program="kalman_accel", k=7))
    cpu = firmware_cpu(build)
    entries = block_entries(build.step_address, BLOCK_MAX, cpu._decoded_at)
    role, _, head = _plan(entries)
    assert head is None and entries[-1][2] == "rts"
    assert sum(1 for r in role.values() if r[0] == "dup") >= 5


def test_duplicated_tail_keeps_the_flags_only_the_copy_needs() -> None:
    """The taken path of a duplicated branch needs flags the fall-through path kills: ADDQ sets X N Z V C, BEQ
    jumps from the then-part into a copy of the else-part, whose flag-neutral code reaches the block's exit (all
    flags observable) while the fall-through MOVEQ overwrites N Z V C. CCR after the block must be ADDQ's
    (X Z C), as on m68000-python; a liveness that ignored the copy makes ADDQ compute only its X/C and N/Z
    parts (what the BEQ and the fall-through need) and leaves CMP's V set (CCR $17)."""
    src = """
        cmp.l   d1,d0           ; $80000000 - 1: V set, N Z C clear
        bcs.s   other           ; not taken: the then-part runs
        addq.l  #1,d2           ; $FFFFFFFF + 1 = 0: X Z C set, N V clear
        beq.s   other           ; taken: into a copy of the else-part
        moveq   #1,d3
        bra.s   join
other:  nop
        movea.l d4,a0
join:   nop
"""
    code = isa.assemble(src, origin=oracles.CODE).code
    m = machine(code + TRAP0, 1, [0x80000000, 1, M32, 0, 0x1234, 0, 0, 0], 0)
    end = oracles.CODE + len(code)
    _assert_duplicates(m.memory, end)
    ours, ref = ours_blocks(m, end, 50), ref_run(m, end, 50)
    assert ours[0] is None and ours[4] == 0x15
    assert ours == ref, _diff(ours, ref)


CALL_SRC = """
one:    moveq   #3,d0           ; one block from the entry through its RTS
        add.l   d1,d0
        bne.s   .nz
        not.l   d2
.nz:    move.l  d0,$6000
        rts
two:    lea     .far,a0         ; the entry block ends at a JMP: _run goes on from there
        add.l   d1,d2
        jmp     (a0)
.far:   addq.l  #1,d3
        rts
bad:    moveq   #1,d4           ; a fault inside the entry block (odd address in A1), after a register change
        move.l  (a1),d5
        rts
trap:   addq.l  #1,d6           ; a TRAP in the second block: call raises
        lea     .t,a0
        jmp     (a0)
.t:     trap    #2
"""


@pytest.mark.parametrize("routine", ["one", "two", "bad", "trap"])
@pytest.mark.parametrize("max_cycles", [None, 10, 60])
def test_call_entry_block_equals_closures(routine: str, max_cycles: int | None) -> None:
    """CPU.caller runs a compiled entry block directly (no run-loop set-up) from the second call on; CPU.call
    runs the routine through the run loop: returned clocks, registers, memory, counters, min_sp, PC and any fault
    (class, message, PC) of both equal the closures' path, for a one-block routine, a routine that goes on in a
    second block, a fault inside the entry block, a TRAP after it, and cycle limits that stop inside the
    routine."""
    prog = isa.assemble(CALL_SRC, origin=oracles.CODE)
    address = prog.symbols[routine].address
    out = []
    for blocks, lean in ((True, True), (True, False), (False, False)):
        cpu = oracles.make_cpu(isa)
        cpu.block_compile = blocks
        cpu.load(prog)
        cpu.a[7], cpu.a[1], cpu.d[1] = 0x6F00, 0x6001, 5
        cpu.pc = 0x1234
        run = cpu.caller(address, max_cycles=max_cycles) if lean else None
        seen = []
        for k in range(3):
            cpu.d[1] = (cpu.d[1] - 5 * k) & M32  # 5, 0 (D0 = 3: NE), ...
            try:
                seen.append(("ok", run() if run is not None else cpu.call(address, max_cycles=max_cycles)))
            except CPUFault as exc:
                seen.append((type(exc).__name__, str(exc), exc.pc))
                cpu.a[7] = 0x6F00
            seen.append(_snapshot(cpu))
        out.append(seen)
    assert out[0] == out[2] and out[1] == out[2]
    if routine == "one" and max_cycles is None:
        # MOVEQ 4, ADD.L Dn,Dn 8, BNE.S taken 10, MOVE.L Dn,abs.L 20, RTS 16 (UM tables 8-4, 8-2, 8-10)
        assert out[0][0][0] == "ok" and out[0][2] == ("ok", 4 + 8 + 10 + 20 + 16)


def test_loop_stopped_by_the_budget_at_its_back_edge_has_exact_flags() -> None:
    """A looping block whose flags are dead inside the loop (ORI's, overwritten by the next pass) and a limit that
    ends the loop at its back edge: the block leaves at the head, where SR is observable, so it must hold the last
    ORI's flags (Z set), as the closures do. Found by the thorough profile of
    test_blocks_equal_closures_any_instructions (the block left SR from before the loop: Z clear)."""
    from isa.errors import LimitExceeded

    src = "start: moveq #1,d1\n moveq #0,d0\nloop: ori.b #0,d0\n bra.s loop\n"

    def run(block: bool, n: int) -> tuple:
        cpu = isa.CPU()
        cpu.block_compile = block
        cpu.load(isa.assemble(src, filename="t.s", origin=0x1000))
        cpu.a[7] = 0x8000
        with pytest.raises(LimitExceeded):
            cpu.run(max_instructions=n)
        return cpu.pc, cpu.sr, cpu.instructions, cpu.cycles, list(cpu.d)

    for n in range(1, 40):
        assert run(True, n) == run(False, n), n
        assert run(True, n)[1] & 4 or n < 3, n  # Z: set once an ORI ran

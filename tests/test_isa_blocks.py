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
from isa.cpu import _COND, _COND_EXPR, CPU
from isa.encoder import encode, length
from isa.errors import CPUFault
from isa.operands import Instruction, Mode, Operand, Size
from isa.strategies import instructions
from profiles import examples

import oracles

M32 = 0xFFFFFFFF
EDGE = (0, 1, 2, 7, 0x7F, 0x80, 0xFF, 0x7FFF, 0x8000, 0xFFFF, 0x7FFFFFFF, 0x80000000, 0xFFFFFFFF, 0xFFFF8000)

#: Data-processing rows for the m68000-python comparison (no TRAP/ILLEGAL/jumps/calls, no rows that load an
#: address register with an arbitrary value, which would only turn most blocks into bus errors).
ALU_ROWS = ["move", "moveq", "add", "addi", "addq", "addx", "sub", "subi", "subq", "subx", "neg", "negx", "cmp",
            "cmpa", "cmpi", "tst", "and", "andi", "or", "ori", "eor", "eori", "not", "clr", "ext", "swap", "asl",
            "asr", "lsl", "lsr", "rol", "ror", "roxl", "roxr", "muls", "mulu", "divs", "divu", "scc", "nop"]
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


def ours_blocks(m: oracles.Machine, end: int, limit: int) -> tuple[object, ...]:
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
    assert res.reason == "until_pc", res
    return (None, tuple(cpu.d), tuple(cpu.a), cpu.pc, cpu.sr & 0x1F,
            cpu.read_bytes(0, oracles.EXCLUDED_LO), res.cycles, res.instructions)


_REF: list[oracles.M68000PyRef] = []


def ref_run(m: oracles.Machine, end: int, limit: int) -> tuple[object, ...]:
    """m68000-python stepping from ``m`` until PC == ``end`` or it takes an exception."""
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
        if after.pc == end:
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


@settings(max_examples=examples(150), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(straight_blocks())
def test_straight_blocks_vs_m68000py(case: tuple[bytes, list[int], int, int]) -> None:
    _check_vs_ref(case, 200)


@settings(max_examples=examples(100), deadline=None, suppress_health_check=[HealthCheck.too_slow])
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
            res = cpu.run(**kwargs)  # type: ignore[arg-type]
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


@settings(max_examples=examples(300), deadline=None, suppress_health_check=[HealthCheck.too_slow])
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
    from firmware_model.build import build_firmware
    from firmware_model.config import BuildConfig
    from firmware_model.harness import ACCEL_ADC, BARO_ADC, _Machine
    from firmware_model.inputs import synthetic_flight

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

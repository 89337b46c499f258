"""Speed of our interpreter against m68000-python and Musashi on the SAME machine-code loop.

``make bench`` runs this file. The loop (ALU, shifts, multiply, memory, compare/branch, DBRA) is assembled once
with :func:`isa.assemble`; the bytes are loaded into all three CPUs from identical registers, run to the TRAP #0
at the end, and the final registers (D0-D7, A0-A6) must be identical, so the loop really is the same work.
Prints instructions per second of each (best of ``--reps`` runs) and the ratios. The project's target is
ours >= 10x m68000-python. No assertions on speed: this is a measurement, not a test.

``--firmware`` also measures the firmware harness path (many short ``cpu.call()``s): samples/s of
``kalman_accel`` (k=7) over ``synthetic_flight(7)`` with block compilation off and on (best of ``--reps``), and
checks that both give identical state words and clocks.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import oracles  # noqa: E402  (the shared RAM layout and reference adapters)

import isa  # noqa: E402

LOOP = """
        moveq   #0,d0
        moveq   #1,d2
        moveq   #0,d4
        moveq   #0,d5
        move.w  #{count},d7
        lea     $6000,a0
        lea     $6000,a1
loop:   add.l   d7,d0
        move.l  d0,d1
        lsl.l   #3,d1
        eor.l   d1,d0
        asr.l   #2,d1
        sub.w   d1,d2
        muls.w  d2,d6
        move.l  d0,(a0)+
        move.w  -2(a0),d3
        addq.l  #1,d4
        cmp.w   d3,d4
        bne.s   skip
        addq.l  #1,d5
skip:   and.l   #$00FF00FF,d6
        cmpa.l  #$7000,a0
        bcs.s   nowrap
        movea.l a1,a0
nowrap: dbra    d7,loop
        trap    #0
"""


def program(count: int) -> bytes:
    """Machine code of the loop with ``count + 1`` iterations, placed at :data:`oracles.CODE`."""
    return isa.assemble(LOOP.format(count=count), filename="bench.s", origin=oracles.CODE).code


def machine(code: bytes) -> oracles.Machine:
    """The common starting state: code at CODE, zero registers, A7 in the data region."""
    image = bytes(oracles.base_image(0, [(oracles.CODE, code)]))
    return oracles.Machine([0] * 8, [0] * 7 + [0x6F00], 0, oracles.CODE, image)


def run_ours(m: oracles.Machine) -> tuple[int, float, tuple[int, ...]]:
    """(instructions, seconds, D0-D7 + A0-A6) on our interpreter (a fresh CPU; its compile cost is included)."""
    cpu = oracles.make_cpu(isa)
    cpu.write_bytes(0, m.memory)
    for i in range(8):
        cpu.d[i], cpu.a[i] = m.d[i], m.a[i]
    cpu.pc = m.pc
    t = time.perf_counter()
    result = cpu.run(max_instructions=None)
    dt = time.perf_counter() - t
    assert result.reason == "trap", result
    return result.instructions, dt, tuple(cpu.d) + tuple(cpu.a)[:7]


def run_m68000py(m: oracles.Machine, trap_pc: int) -> tuple[int, float, tuple[int, ...]]:
    """Same on m68000-python: step() until PC reaches the TRAP #0 handler (the TRAP counts as one instruction)."""
    from m68000_python import CPUState

    ref = oracles.M68000PyRef()
    ref.mem[:] = m.memory
    ref.cpu.restore_state(CPUState(d=tuple(m.d), a=tuple(m.a[:7]), usp=m.a[7], ssp=oracles.SSP, sr=0, pc=m.pc,
                                   ir=int.from_bytes(m.memory[m.pc:m.pc + 2], "big"),
                                   irc=int.from_bytes(m.memory[m.pc + 2:m.pc + 4], "big")))
    cpu = ref.cpu
    step = cpu.step
    n = 0
    t = time.perf_counter()
    while True:
        step()
        n += 1
        if cpu.PC == trap_pc:
            break
    dt = time.perf_counter() - t
    return n, dt, tuple(cpu.R[0:15])


def run_musashi(m: oracles.Machine, instructions: int) -> tuple[int, float, tuple[int, ...]] | None:
    """Same on Musashi: one execute() call; the TRAP #0 handler starts with RESET, whose callback ends the run.
    The instruction count is ours (Musashi does not count); the final registers prove the same work was done."""
    try:
        ref = oracles.musashi()
    except ImportError:
        return None
    cpu, mem, R = ref.cpu, ref.mem, ref.Register
    mem.w_block(0, m.memory)
    mem.w16(oracles.HANDLERS + 4 * 32, 0x4E70)  # RESET at the TRAP #0 handler
    cpu.w_sr(0)
    cpu.w_isp(oracles.SSP)
    for i in range(8):
        cpu.w_reg(R.D0 + i, m.d[i])
        cpu.w_reg(R.A0 + i, m.a[i])
    cpu.w_pc(m.pc)

    class Done(Exception):
        pass

    def on_reset() -> None:
        raise Done  # machine68k 0.4.1 has no CPU.end(): an exception in the callback ends execute()

    cpu.set_reset_instr_callback(on_reset)
    t = time.perf_counter()
    try:
        cpu.execute(1 << 30)
        raise RuntimeError("Musashi did not reach the TRAP #0 handler")
    except Done:
        pass
    dt = time.perf_counter() - t
    cpu.set_reset_instr_callback(None)
    regs = tuple(cpu.r_reg(R.D0 + i) for i in range(8)) + tuple(cpu.r_reg(R.A0 + i) for i in range(7))
    return instructions, dt, regs


def firmware(reps: int) -> bool:
    """Print harness samples/s for kalman_accel over synthetic_flight(7), blocks off and on; True if identical."""
    import hashlib

    import numpy as np

    import isa.cpu
    from firmware_model import harness
    from firmware_model.build import build_firmware
    from firmware_model.config import BuildConfig
    from firmware_model.inputs import synthetic_flight

    flight = synthetic_flight(7)
    adc, acc = np.asarray(flight.adc), np.asarray(flight.acc)
    build = build_firmware(BuildConfig(program="kalman_accel", k=7))
    digests = []
    for blocks in (False, True):
        saved = isa.cpu.CPU.block_compile
        isa.cpu.CPU.block_compile = blocks  # class default, read by every CPU the harness makes
        try:
            best = 1e9
            for _ in range(reps):
                t = time.perf_counter()
                trace = harness.run_firmware(build, adc, acc)
                best = min(best, time.perf_counter() - t)
        finally:
            isa.cpu.CPU.block_compile = saved
        digests.append(hashlib.sha256(np.asarray(trace.words).tobytes() + np.asarray(trace.cycles).tobytes())
                       .hexdigest())
        print(f"  firmware kalman_accel, {len(adc)} samples, blocks {'on ' if blocks else 'off'}: "
              f"{len(adc) / best:9,.0f} samples/s  ({int(np.sum(trace.cycles)):,} clocks)")
    same = digests[0] == digests[1]
    print("  state words and clocks identical with and without blocks: " + ("yes" if same else "NO"))
    return same


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; print a table; return 1 if the three final register states differ."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--iterations", type=int, default=4000, help="loop iterations (default 4000)")
    ap.add_argument("--reps", type=int, default=3, help="repetitions; the best time is reported (default 3)")
    ap.add_argument("--firmware", action="store_true", help="also measure the firmware harness (samples/s)")
    args = ap.parse_args(argv)
    code = program(args.iterations - 1)
    m = machine(code)
    trap_pc = oracles.HANDLERS + 4 * 32
    best: dict[str, float] = {}
    regs: dict[str, tuple[int, ...]] = {}
    counts: dict[str, int] = {}
    for _ in range(args.reps):
        n, dt, r = run_ours(m)
        counts["ours"], regs["ours"] = n, r
        best["ours"] = min(best.get("ours", 1e9), dt)
        n2, dt2, r2 = run_m68000py(m, trap_pc)
        counts["m68000-python"], regs["m68000-python"] = n2, r2
        best["m68000-python"] = min(best.get("m68000-python", 1e9), dt2)
        mus = run_musashi(m, n)
        if mus is not None:
            counts["musashi"], regs["musashi"] = mus[0], mus[2]
            best["musashi"] = min(best.get("musashi", 1e9), mus[1])
    print(f"loop: {args.iterations} iterations, {counts['ours']} instructions, best of {args.reps}")
    for name in best:
        print(f"  {name:14s} {counts[name] / best[name]:14,.0f} instructions/s   ({best[name] * 1e3:8.1f} ms)")
    ips = {k: counts[k] / best[k] for k in best}
    print(f"  ours / m68000-python = {ips['ours'] / ips['m68000-python']:.1f}x   (target >= 10x)")
    if "musashi" in ips:
        print(f"  ours / Musashi       = {ips['ours'] / ips['musashi']:.3f}x")
    same = all(r == regs["ours"] for r in regs.values()) and counts["m68000-python"] == counts["ours"]
    print("  final registers D0-D7/A0-A6 identical on all: " + ("yes" if same else "NO"))
    if not same:
        for name, r in regs.items():
            print(f"    {name:14s} " + " ".join(f"{v:08X}" for v in r))
    if args.firmware:
        same = firmware(args.reps) and same
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())

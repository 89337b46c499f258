"""Speed of our 68000 interpreter against m68000-python and Musashi, in ONE run, with ratios (``make bench``).

1. **Loops** (the same machine code on all three; final registers D0-D7/A0-A6 must be identical):
   ``alu`` (ADD/EOR/SUB/CMP, LSL/ASR, Bcc, DBRA), ``memory`` (MOVE.L (A0)+,(A1)+, ADD.L d16(An),Dn, DBRA),
   ``muldiv`` (MULS/MULU/DIVS/DIVU, DBRA). Ours is measured cold (a fresh process-wide code cache: decode and
   block compilation included) and warm (a new CPU on the same code: the steady state), best of ``--reps``.
2. **Firmware**: ``kalman_accel`` (k=7) over ``synthetic_flight(7)``: samples/s of ours through
   :func:`firmware_model.firmware.harness.run_firmware` (cold: first run in this process, no block code from the disk
   cache; warm: best of ``--reps``)
   against Musashi running the same ROM image with a minimal harness (write the two input words, push a return
   address that holds a RESET, set PC to ``step``, execute, read the state words). The state words must be
   identical (Musashi's clock counts are known wrong and are not compared).
3. **Vectors**: wall and CPU time of ``fwemu vectors --all --jobs N --out <tmpdir>`` (N = 1, 2) in a subprocess,
   cold (empty build cache in a fresh folder) and warm (the same folder again); every output must be
   byte-identical to the first.

Targets (issue 10): ours >= 10x m68000-python on each loop; >= 100,000 kalman_accel samples/s through the
harness. No assertion on speed: a measurement, not a test. Exit status 1 if any result differs. Every timed run
is measured in CPU time of the thread that runs it (``time.thread_time``; ``--wall`` for the wall clock): the
machine is shared, and wall time would charge one system for another process's load. Repetitions of the compared
systems are interleaved and the best of each is kept; the garbage collector is off inside the timed runs of every
system. The vectors lines are wall and CPU time of subprocesses.
"""

from __future__ import annotations

import argparse
import filecmp
import gc
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

from firmware_model.runtime.blas_threads import single_threaded_blas  # noqa: E402 - with the single_threaded_blas() call below, which comes before numpy loads

single_threaded_blas()  # before numpy loads: no OpenBLAS pool busy-waiting beside the timed runs

from tests.support import oracles  # noqa: E402 - imported after single_threaded_blas(): numpy must not load first

import isa  # noqa: E402 - imported after single_threaded_blas(): numpy must not load first
from isa import codecache  # noqa: E402 - imported after single_threaded_blas(): numpy must not load first

LOOPS: dict[str, str] = {
    "alu": """
        moveq   #1,d1
        moveq   #0,d2
        moveq   #0,d3
        moveq   #0,d5
        move.w  #{count},d7
loop:   add.l   d7,d0
        eor.l   d0,d1
        lsl.l   #3,d1
        asr.l   #2,d2
        sub.w   d1,d2
        add.l   d1,d2
        cmp.l   d2,d3
        bne.s   skip
        addq.l  #1,d5
skip:   dbra    d7,loop
        trap    #0
""",
    "memory": """
        move.w  #{count},d7
        lea     $0,a0
        lea     $C200,a1
        lea     $6000,a2
loop:   move.l  (a0)+,(a1)+
        add.l   8(a2),d0
        dbra    d7,loop
        trap    #0
""",
    "muldiv": """
        move.w  #{count},d7
        moveq   #3,d3
loop:   move.w  d7,d1
        muls.w  d7,d1
        move.l  d1,d2
        divu.w  #1000,d2
        mulu.w  d2,d3
        move.l  d1,d4
        neg.l   d4
        divs.w  #-3000,d4
        add.l   d4,d5
        dbra    d7,loop
        trap    #0
""",
}
TRAP_PC = oracles.HANDLERS + 4 * 32
#: The clock of every timed run: CPU time of the calling thread (``time.thread_time``), which runs all three
#: systems (ours, m68000-python and Musashi's C extension), so that other processes on a shared machine do not
#: inflate one system's time and not another's (``--wall`` uses the wall clock instead). Not the process's CPU
#: time: until 2026-12-02 it was ``time.process_time``, which also charged a busy-waiting OpenBLAS thread to
#: whichever system ran after a numpy call, and the firmware figures flipped between two values a factor of two
#: apart (Musashi 178 k or 360 k samples/s; docs/history/testing-rounds.md, sixth round).
CLOCK = time.thread_time


def loop_machine(name: str, iterations: int) -> oracles.Machine:
    """Code of loop ``name`` (``iterations`` passes) at CODE, a seeded data image, zero registers."""
    code = isa.assemble(LOOPS[name].format(count=iterations - 1), filename=f"{name}.s", origin=oracles.CODE).code
    image = bytes(oracles.base_image(1, [(oracles.CODE, code)]))
    return oracles.Machine([0] * 8, [0] * 7 + [0x6F00], 0, oracles.CODE, image)


def run_ours(m: oracles.Machine) -> tuple[int, float, tuple[int, ...]]:
    """(instructions, seconds, D0-D7 + A0-A6) on a fresh CPU of ours."""
    cpu = oracles.make_cpu(isa)
    cpu.write_bytes(0, m.memory)
    for i in range(8):
        cpu.d[i], cpu.a[i] = m.d[i], m.a[i]
    cpu.pc = m.pc
    t = CLOCK()
    result = cpu.run(max_instructions=None)
    dt = CLOCK() - t
    assert result.reason == "trap", result
    return result.instructions, dt, tuple(cpu.d) + tuple(cpu.a)[:7]


def run_m68000py(m: oracles.Machine) -> tuple[int, float, tuple[int, ...]]:
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
    t = CLOCK()
    while True:
        step()
        n += 1
        if cpu.PC == TRAP_PC:
            break
    dt = CLOCK() - t
    return n, dt, tuple(cpu.R[0:15])


class Musashi:
    """One machine68k machine with all 16 MiB as RAM (machine68k keeps one global CPU per process). An A-line
    trap opcode (:attr:`stop`) whose handler returns machine68k's end-of-execution object ends ``execute()``."""

    def __init__(self) -> None:
        import machine68k

        self.m = machine68k.Machine(machine68k.CPUType.M68000, 16384)
        self.cpu, self.mem, self.R = self.m.cpu, self.m.mem, machine68k.Register
        self.end = self.m.create_execute_end("stop")
        self.tid = self.m.traps.alloc(lambda *_: self.end)
        self.stop = 0xA000 | self.tid
        self.mem.w32(0, oracles.SSP)
        self.mem.w32(4, 0x100)
        self.mem.w16(0x100, self.stop)  # absorb the reset
        self.cpu.pulse_reset()
        self.run_until_stop()

    def run_until_stop(self) -> None:
        r = self.m.execute(1 << 30)
        if r.result is not self.end:
            raise RuntimeError(f"Musashi did not reach the stop opcode: {r}")

    def loop(self, m: oracles.Machine, instructions: int) -> tuple[int, float, tuple[int, ...]]:
        cpu, mem, R = self.cpu, self.mem, self.R
        mem.w_block(0, m.memory)
        mem.w16(TRAP_PC, self.stop)  # the stop opcode at the TRAP #0 handler
        cpu.w_sr(0)
        cpu.w_isp(oracles.SSP)
        for i in range(8):
            cpu.w_reg(R.D0 + i, m.d[i])
            cpu.w_reg(R.A0 + i, m.a[i])
        cpu.w_pc(m.pc)
        t = CLOCK()
        self.run_until_stop()
        dt = CLOCK() - t
        regs = tuple(cpu.r_reg(R.D0 + i) for i in range(8)) + tuple(cpu.r_reg(R.A0 + i) for i in range(7))
        return instructions, dt, regs

    def cleanup(self) -> None:
        self.m.traps.free(self.tid)
        self.m.cleanup()


def loops(iterations: int, reps: int, musashi: Musashi | None) -> bool:
    """Print the loop table; True if every implementation ended with the same registers on every loop."""
    print(f"loops: {iterations} iterations each, best of {reps}; instructions/s (ours cold = fresh code cache)")
    print(f"  {'loop':7s} {'instr':>7s} {'ours cold':>11s} {'ours warm':>11s} {'m68000-py':>11s} {'Musashi':>12s}"
          f" {'ours/m68k-py':>13s} {'ours/Musashi':>13s}")
    ok = True
    for name in LOOPS:
        m = loop_machine(name, iterations)
        codecache.clear()
        n, cold, regs = run_ours(m)
        warm = py = mus = 1e9
        same = True
        for _ in range(reps):  # interleaved, so that a change of machine load hits every system alike
            r = run_ours(m)
            warm = min(warm, r[1])
            r = run_m68000py(m)
            py = min(py, r[1])
            same = same and r[2] == regs and r[0] == n
            if musashi is not None:
                r = musashi.loop(m, n)
                mus = min(mus, r[1])
                same = same and r[2] == regs
        ok = ok and same
        mus_s = f"{n / mus:12,.0f}" if musashi else f"{'-':>12s}"
        ratio_m = f"{mus / warm:12.3f}x" if musashi else f"{'-':>13s}"
        print(f"  {name:7s} {n:7d} {n / cold:11,.0f} {n / warm:11,.0f} {n / py:11,.0f} {mus_s} {py / warm:12.1f}x"
              f" {ratio_m}" + ("" if same else "   REGISTERS DIFFER"))
    print("  final registers D0-D7/A0-A6 identical on all: " + ("yes" if ok else "NO")
          + "   (target ours/m68k-py >= 10x)")
    return ok


def musashi_firmware(musashi: Musashi, build: object, adc: list[int], acc: list[int]) -> tuple[float, list]:
    """The minimal Musashi harness: the ROM image and zeroed RAM; init once, then per sample write the inputs,
    JSR-equivalent (push a return address holding the stop opcode, PC = step), execute, read the state words."""
    from firmware_model.firmware.assemble import ACCEL_ADC, BARO_ADC, RAM_SIZE, RAM_START, STACK_TOP

    cpu, mem, R = musashi.cpu, musashi.mem, musashi.R
    mem.clear_block(0, RAM_START + RAM_SIZE, 0)
    mem.w_block(0, build.rom_image)  # type: ignore[attr-defined]  # build is typed as object here (a FirmwareBuild)
    ret = 0x8000  # holds the stop opcode: just above the firmware's RAM
    mem.w16(ret, musashi.stop)
    cpu.w_sr(0x2700)
    names = list(build.variables)  # type: ignore[attr-defined]  # build is typed as object here (a FirmwareBuild)
    addr_size = [build.variables[w] for w in names]  # type: ignore[attr-defined]  # build is typed as object here (a FirmwareBuild)
    A7, r32s, r16 = R.A7, mem.r32s, mem.r16
    w_reg, w_pc, w16, w32, execute = cpu.w_reg, cpu.w_pc, mem.w16, mem.w32, musashi.m.execute
    end = musashi.end
    init, step = build.init_address, build.step_address  # type: ignore[attr-defined]  # build is typed as object here (a FirmwareBuild)
    out = []
    t = CLOCK()
    for i, entry in enumerate([init] + [step] * len(adc)):
        j = max(i - 1, 0)
        w16(BARO_ADC, adc[j])
        w16(ACCEL_ADC, acc[j] & 0xFFFF)
        w32(STACK_TOP - 4, ret)
        w_reg(A7, STACK_TOP - 4)
        w_pc(entry)
        if execute(1 << 30).result is not end:
            raise RuntimeError("Musashi: the firmware did not return")
        if i:
            out.append(tuple(r32s(a) if n == 4 else r16(a) for a, n in addr_size))
    dt = CLOCK() - t
    return dt, out


def firmware(reps: int, musashi: Musashi | None) -> bool:
    """Print harness samples/s of ours (cold and warm) and of Musashi; True if the state words agree."""
    import numpy as np

    from firmware_model.firmware import harness
    from firmware_model.firmware.assemble import build_firmware
    from firmware_model.model.streams import synthetic_flight
    from firmware_model.spec.config import BuildConfig

    flight = synthetic_flight(7)
    adc, acc = np.asarray(flight.adc), np.asarray(flight.acc)
    n = len(adc)
    build = build_firmware(BuildConfig(program="kalman_accel", k=7))
    codecache.clear()
    saved = os.environ.get("FWEMU_CACHE_DIR")
    os.environ["FWEMU_CACHE_DIR"] = "off"  # cold: no block code from the disk cache either (firmware_cpu reads it)
    try:
        t = CLOCK()
        trace = harness.run_firmware(build, adc, acc)
        cold = CLOCK() - t
    finally:
        if saved is None:
            del os.environ["FWEMU_CACHE_DIR"]
        else:
            os.environ["FWEMU_CACHE_DIR"] = saved
    warm = best = 1e9
    ok = same = True
    for _ in range(reps):  # interleaved with Musashi
        t = CLOCK()
        again = harness.run_firmware(build, adc, acc)
        warm = min(warm, CLOCK() - t)
        ok = ok and np.array_equal(again.words, trace.words) and np.array_equal(again.cycles, trace.cycles)
        if musashi is not None:
            dt, words = musashi_firmware(musashi, build, adc.tolist(), acc.tolist())
            best = min(best, dt)
            same = same and np.array_equal(np.asarray(words, dtype=np.int64), trace.words)
    print(f"firmware: kalman_accel k=7, synthetic_flight(7), {n} samples, {int(np.sum(trace.cycles)):,} clocks")
    print(f"  ours (harness)  cold {n / cold:11,.0f} samples/s   warm {n / warm:11,.0f} samples/s"
          "   (target >= 100,000)")
    if musashi is not None:
        ok = ok and same
        print(f"  Musashi (minimal harness)       {n / best:11,.0f} samples/s   ours/Musashi = {best / warm:.3f}x"
              f"   state words identical: {'yes' if same else 'NO'}")
    return ok


def vectors(jobs: tuple[int, ...] = (1, 2)) -> bool:
    """Wall and CPU time of `fwemu vectors --all --jobs N` cold (a fresh build cache) and warm (the same cache
    again), for each N; every output must be byte-identical to the first one. CPU time = user + system time of
    the subprocess and its workers (resource.RUSAGE_CHILDREN): on a shared machine the wall time also holds the
    other sessions' load, the CPU time does not."""
    import resource

    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    same = True
    with tempfile.TemporaryDirectory() as tmp:
        first: Path | None = None
        for n in jobs:
            env["FWEMU_CACHE_DIR"] = str(Path(tmp) / f"cache{n}")
            line = []
            for run in ("cold", "warm"):
                out = Path(tmp) / f"{run}{n}"
                r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
                t = time.perf_counter()
                proc = subprocess.run([sys.executable, "-m", "firmware_model.cli.main", "vectors", "--all", "--jobs",
                                       str(n), "--out", str(out)],
                                      env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
                wall = time.perf_counter() - t
                r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
                cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
                if proc.returncode:
                    last = (proc.stderr.strip().splitlines() or ["?"])[-1]
                    print(f"vectors: fwemu vectors --all did not run (exit {proc.returncode}): {last}")
                    return proc.returncode == 2  # a user error (e.g. the shared flight logs absent): not a mismatch
                if first is None:
                    first = out
                else:
                    cmp = filecmp.dircmp(first, out)
                    same = same and not cmp.diff_files and not cmp.left_only and not cmp.right_only and all(
                        not sub.diff_files and not sub.left_only and not sub.right_only
                        for sub in cmp.subdirs.values())
                line.append(f"{run} {wall:5.1f} s wall {cpu:5.1f} s CPU")
            print(f"vectors: fwemu vectors --all --jobs {n}   " + "   ".join(line))
    print(f"  outputs identical: {'yes' if same else 'NO'}   (target <= 6 s on 2 cores)")
    return same


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--iterations", type=int, default=15000,
                    help="loop iterations (default 15000, at most 15600: the memory loop copies 4 bytes each)")
    ap.add_argument("--reps", type=int, default=3, help="repetitions; the best time is reported (default 3)")
    ap.add_argument("--no-firmware", action="store_true", help="skip the firmware harness measurement")
    ap.add_argument("--no-vectors", action="store_true", help="skip the `fwemu vectors --all` wall time")
    ap.add_argument("--loops", action="store_true", help="only the loops")
    ap.add_argument("--firmware", action="store_true", help="only the firmware harness (section 2)")
    ap.add_argument("--wall", action="store_true",
                    help="time with the wall clock instead of the CPU time of the timed thread")
    args = ap.parse_args(argv)
    global CLOCK
    if args.wall:
        CLOCK = time.perf_counter
    print(f"bench_cpu {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}  {platform.machine()} "
          f"{os.cpu_count()} cores  Python {platform.python_version()}  load {os.getloadavg()[0]:.1f}")
    try:
        musashi: Musashi | None = Musashi()
    except ImportError:
        musashi = None
        print("  (machine68k not installed: no Musashi columns)")
    gc.disable()  # no collector pauses from unrelated objects inside the timed runs (all systems alike)
    ok = True if args.firmware else loops(args.iterations, args.reps, musashi)
    if args.firmware or (not args.loops and not args.no_firmware):
        ok = firmware(args.reps, musashi) and ok
    if musashi is not None:
        musashi.cleanup()
    gc.enable()
    if not args.loops and not args.firmware and not args.no_vectors:
        ok = vectors() and ok
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())

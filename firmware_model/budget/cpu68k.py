"""Budget reports for a firmware build (docs/firmware-asm.md, docs/mcu.md): ROM, RAM, cycles per ``step``, CPU load,
numeric headroom.

Measured figures come from running the build on the emulated 68000 (:mod:`firmware_model.firmware.harness`) over a
set of input streams; the static worst-case bound comes from the code itself (:func:`static_step_bound`) and every
measurement must stay under it (checked here and in the tests).

Static bound (clocks, 68000, zero wait states): the longest path through the control-flow graph of ``step``,
each instruction charged its **maximum** clocks (:func:`isa.timing.cycle_range`: both outcomes of a branch, the
largest shift count, the worst MULx/DIVx operand). A loop must carry its limit on its backward branch as
``; @bound N`` = the most times its head instruction runs per call (a missing annotation is an error: we do not
guess loop counts); the loop is charged ``N`` times its longest path from the head to any instruction of its
body, inner loops first. A ``BSR``/``JSR`` to a known address adds the callee's bound. Sound for reducible code
with annotated loops (which a budget gate needs); pessimistic where the worst case of two instructions cannot
happen together.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from firmware_model.firmware.assemble import FirmwareBuild
from firmware_model.firmware.harness import run_firmware
from firmware_model.model.streams import (
    EDGE_KINDS,
    Stream,
    edge_stream,
    pascal_edge_stream,
    synthetic_flight,
    synthetic_pascal_flight,
)
from firmware_model.model.trace import STATE_WORDS
from firmware_model.runtime import markdown as md
from firmware_model.runtime import output
from firmware_model.runtime.errors import UserError
from isa.decoder import decode
from isa.errors import IllegalInstruction
from isa.operands import Mode
from isa.timing import cycle_range, handler_name

#: Default CPU clock for load figures (Hz).
DEFAULT_CLOCK_HZ: float = 8_000_000.0
_BOUND_RE = re.compile(r";.*@bound\s+(\d+)", re.IGNORECASE)
_BRANCHES = ("bra", "bsr", "dbcc", "bcc")


@dataclass(frozen=True)
class StaticBound:
    """Static worst-case clocks of a subroutine: ``cycles`` (the bound), ``instructions`` (reachable instruction
    count, callees included) and ``loops`` (``(branch address, loop start, bound)`` per annotated loop)."""

    cycles: int
    instructions: int
    loops: tuple[tuple[int, int, int], ...] = ()


def _handler(mnemonic: str) -> str:
    return handler_name(mnemonic)


def static_step_bound(build: FirmwareBuild) -> StaticBound:
    """Static upper bound on the clocks of ``build``'s ``step`` (see :func:`static_bound`)."""
    return static_bound(build.program, build.step_address)


def static_bound(program: Any, entry: int) -> StaticBound:  # noqa: C901 - a path analysis over every instruction kind (branches, DBcc, calls, RTS)
    """Static upper bound on the clocks (68000, zero wait states) of the subroutine of ``program`` (an
    :class:`isa.program.Program`) at address ``entry``, from its first instruction up to and including its ``RTS``
    (the caller's ``JSR`` excluded, as in the harness). Method: module docstring.

    Raises :class:`UserError` for code the analysis cannot bound: a loop without ``; @bound N``, an indirect jump
    or call, or a path that leaves the program's code and data."""

    memory: dict[int, int] = {}
    for seg in program.segments:
        if not seg.bss:
            memory.update(zip(range(seg.origin, seg.origin + len(seg.data)), seg.data))
    source_map = program.source_map

    def fetch(address: int) -> int:
        try:
            return (memory[address] << 8) | memory[address + 1]
        except KeyError:
            raise UserError(f"static bound: the code reachable from ${entry:06X} runs outside the program at "
                            f"${address:06X}") from None

    def where(address: int) -> str:
        line = source_map.get(address)
        return f"{line.file}:{line.line}" if line else f"${address:06X}"

    def analyse(start: int, depth: int) -> tuple[int, int, list[tuple[int, int, int]]]:  # noqa: C901 - the walk of static_bound, one branch per kind of control transfer
        if depth > 16:
            raise UserError(f"static bound: calls nested deeper than 16 at {where(start)} (recursion?)")
        reachable: dict[int, Any] = {}
        work = [start]
        while work:
            pc = work.pop()
            if pc in reachable:
                continue
            try:
                dec = decode(fetch, pc)
            except IllegalInstruction as exc:
                raise UserError(f"static bound: cannot decode the code reachable at {where(pc)}: {exc}") from None
            reachable[pc] = dec
            h = _handler(dec.instruction.mnemonic)
            nxt = pc + dec.length
            if h in ("rts",):
                continue
            if h in ("jmp", "jsr") or h in _BRANCHES:
                target = _target(dec, pc, where)
                if h in ("jmp", "bra"):
                    work.append(target)
                    continue
                if h in ("bcc", "dbcc"):
                    work.append(target)
            work.append(nxt)
        # loops: backward branches; each needs an annotation
        loops: list[tuple[int, int, int]] = []
        succ: dict[int, list[int]] = {}
        for pc, dec in reachable.items():
            h = _handler(dec.instruction.mnemonic)
            nxt = pc + dec.length
            if h == "rts":
                succ[pc] = []
            elif h in ("jmp", "bra"):
                succ[pc] = [_target(dec, pc, where)]
            elif h in ("bcc", "dbcc"):
                succ[pc] = [_target(dec, pc, where), nxt]
            else:
                succ[pc] = [nxt]
            for target in succ[pc]:
                if target <= pc:
                    line = source_map.get(pc)
                    match = _BOUND_RE.search(line.text) if line else None
                    if not match:
                        raise UserError(f"static bound: loop at {where(pc)} (back to ${target:06X}) has no "
                                        f"'; @bound N' annotation giving its iteration limit")
                    loops.append((pc, target, int(match.group(1))))
        cost: dict[Any, int] = {}
        count = len(reachable)
        for pc, dec in reachable.items():
            cost[pc] = cycle_range(dec.instruction)[1]
            if _handler(dec.instruction.mnemonic) in ("bsr", "jsr"):
                sub_total, sub_count, sub_loops = analyse(_target(dec, pc, where), depth + 1)
                cost[pc] += sub_total
                count += sub_count
                loops.extend(sub_loops)
        graph: dict[Any, set[Any]] = {pc: set(targets) for pc, targets in succ.items()}
        node_of: dict[int, Any] = {pc: pc for pc in reachable}   # instruction -> node it was collapsed into
        own = [loop for loop in loops if loop[0] in reachable]
        for branch, head, bound in sorted(own, key=lambda loop: loop[0] - loop[1]):   # innermost first
            h_node, b_node = node_of[head], node_of[branch]
            body = {h_node} | (_reaching(graph, b_node, stop=h_node) & _reachable(graph, h_node))
            inner = {n: {m for m in graph[n] if m in body and m != h_node} for n in body}
            if any(m in body and m != h_node for n in graph if n not in body for m in graph[n]):
                raise UserError(f"static bound: the loop at {where(branch)} is entered other than at its head "
                                f"{where(head)}")
            longest = _longest_from(inner, cost, h_node)
            loop_node = ("loop", head, branch)
            cost[loop_node] = bound * max(longest.values())
            graph[loop_node] = {m for n in body for m in graph[n] if m not in body}
            for n in graph:
                if n not in body and graph[n] & body:
                    graph[n] = (graph[n] - body) | {loop_node}
            for n in body:
                del graph[n]
            for pc, n in node_of.items():
                if n in body:
                    node_of[pc] = loop_node
        total = max(_longest_from(graph, cost, node_of[start]).values())
        return total, count, loops

    total, count, loops = analyse(entry, 0)
    return StaticBound(cycles=total, instructions=count, loops=tuple(sorted(set(loops))))


def _reaching(graph: dict[Any, set[Any]], target: Any, stop: Any) -> set[Any]:
    """Nodes from which ``target`` can be reached without passing through ``stop`` (``target`` included)."""
    preds: dict[Any, set[Any]] = {}
    for n, targets in graph.items():
        for m in targets:
            preds.setdefault(m, set()).add(n)
    seen = {target}
    work = [target]
    while work:
        for p in preds.get(work.pop(), ()):
            if p not in seen and p != stop:
                seen.add(p)
                work.append(p)
    return seen


def _reachable(graph: dict[Any, set[Any]], start: Any) -> set[Any]:
    """Nodes reachable from ``start`` (``start`` included)."""
    seen = {start}
    work = [start]
    while work:
        for m in graph[work.pop()]:
            if m in graph and m not in seen:
                seen.add(m)
                work.append(m)
    return seen


def _longest_from(graph: dict[Any, set[Any]], cost: dict[Any, int], start: Any) -> dict[Any, int]:
    """Longest path cost (sum of node costs, both ends included) from ``start`` to every node reachable from it in
    the acyclic ``graph`` (successor sets; successors outside ``graph`` are ignored)."""
    order: list[Any] = []
    state: dict[Any, int] = {}
    stack: list[tuple[Any, bool]] = [(start, False)]
    while stack:   # iterative depth-first post-order -> reverse topological order
        node, done = stack.pop()
        if done:
            state[node] = 2
            order.append(node)
            continue
        if state.get(node):
            if state[node] == 1:
                raise UserError("static bound: a cycle without a '; @bound N' annotation remains")
            continue
        state[node] = 1
        stack.append((node, True))
        stack.extend((m, False) for m in graph[node] if m in graph and state.get(m) != 2)
    best: dict[Any, int] = {start: cost[start]}
    for node in reversed(order):
        if node not in best:
            continue
        for m in graph[node]:
            if m in graph and best[node] + cost[m] > best.get(m, -1):
                best[m] = best[node] + cost[m]
    return best


def _target(dec: Any, pc: int, where: Any) -> int:
    op = dec.instruction.operands[-1]
    if op.mode in (Mode.ABSL, Mode.ABSW, Mode.PCDISP):
        return int(op.value) & 0xFFFFFF
    raise UserError(f"static bound: indirect jump or call at {where(pc)} ({dec.instruction.mnemonic}); "
                    f"the analysis needs a static target")


def default_streams(k: int, bits: int, seed: int = 0, edge_samples: int = 512, pascal: bool = False) -> list[Stream]:
    """The budget's input set: the seeded synthetic flight at dt = 2^-k plus every edge stream
    (:data:`firmware_model.model.streams.EDGE_KINDS`) of ``edge_samples`` samples (``pascal``: the pascal-word flight
    and edge streams, :func:`~firmware_model.model.streams.synthetic_pascal_flight`,
    :func:`~firmware_model.model.streams.pascal_edge_stream`)."""
    if pascal:

        return [synthetic_pascal_flight(k, seed=seed)] + [pascal_edge_stream(kind, edge_samples, k)
                                                          for kind in EDGE_KINDS]
    streams = [synthetic_flight(k, bits, seed=seed)]
    streams += [edge_stream(kind, edge_samples, bits, k) for kind in EDGE_KINDS]
    return streams


@dataclass
class Budget:
    """One build's budget. Cycles are 68000 clocks per ``step`` call (zero wait states); ``load`` is the fraction of
    the CPU at ``clock_hz`` used by ``step`` at 2^K samples/s in the worst measured and the static worst case."""

    program: str
    config: dict[str, Any]
    source_sha256: str
    rom_bytes: int
    ram_variable_bytes: int
    stack_peak_bytes: int
    ram_written_bytes: int
    cycles_min: int
    cycles_median: float
    cycles_max: int
    cycles_max_at: dict[str, Any]
    init_cycles: int
    static_bound: int
    static_loops: list[list[int]]
    sample_rate_hz: float
    clock_hz: float
    load_measured: float
    load_static: float
    headroom: dict[str, dict[str, Any]]
    streams: list[dict[str, Any]] = field(default_factory=list)
    per_sample_cycles: dict[str, list[int]] = field(default_factory=dict, repr=False)

    def to_json(self) -> dict[str, Any]:
        """JSON-ready dict (the per-sample cycles are left out; they go to the CSV/plot)."""
        data = dict(self.__dict__)
        data.pop("per_sample_cycles")
        return data


def measure(build: FirmwareBuild, streams: list[Stream], clock_hz: float = DEFAULT_CLOCK_HZ) -> Budget:
    """Run ``build`` over ``streams`` on the emulated CPU and assemble its :class:`Budget`.

    Raises :class:`UserError` when a measured ``step`` exceeds the static bound (the analysis would be wrong)."""
    if not streams:
        raise UserError("budget: no input streams")
    if not (math.isfinite(clock_hz) and clock_hz > 0):
        raise UserError(f"budget: clock {clock_hz!r} Hz must be a positive number")
    consts = build.consts
    bound = static_step_bound(build)
    all_cycles: list[np.ndarray] = []
    worst = (-1, "", -1)
    stack = ram_written = 0
    init_cycles = 0
    names = [name for name, _ in STATE_WORDS[build.program_name]]
    peak_abs = {name: 0 for name, size in STATE_WORDS[build.program_name] if size == 4}
    stream_info = []
    per_sample: dict[str, list[int]] = {}
    for stream in streams:
        trace = run_firmware(build, stream.adc, stream.acc)
        cyc = np.asarray(trace.cycles, dtype=np.int64).reshape(-1)
        all_cycles.append(cyc)
        per_sample[stream.name] = cyc.tolist()
        i = int(cyc.argmax())
        if cyc[i] > worst[0]:
            worst = (int(cyc[i]), stream.name, i)
        stack = max(stack, int(trace.stack_bytes))
        ram_written = max(ram_written, int(trace.ram_written))
        init_cycles = max(init_cycles, int(np.max(trace.init_cycles)))
        for name in peak_abs:
            col = trace.words[..., names.index(name)]
            peak_abs[name] = max(peak_abs[name], int(np.abs(col).max()))
        stream_info.append({"name": stream.name, "samples": len(stream), "provenance": stream.provenance})
    cycles = np.concatenate(all_cycles)
    if worst[0] > bound.cycles:
        raise UserError(f"budget: {build.program_name} step took {worst[0]} clocks on {worst[1]} sample {worst[2]}, "
                        f"above the static bound {bound.cycles}: the static analysis is wrong")
    rate = 2.0 ** consts.K
    headroom = {name: {"max_abs": peak, "bits_used": max(peak, 1).bit_length() + 1,
                       "headroom_bits": 32 - (max(peak, 1).bit_length() + 1)} for name, peak in peak_abs.items()}
    return Budget(
        program=build.program_name, config={"k": consts.K, "rounding": ("floor", "half_up")[consts.ROUND]},
        source_sha256=build.source_sha256, rom_bytes=build.rom_bytes,
        ram_variable_bytes=build.ram_bytes, stack_peak_bytes=stack, ram_written_bytes=ram_written,
        cycles_min=int(cycles.min()), cycles_median=float(np.median(cycles)), cycles_max=worst[0],
        cycles_max_at={"stream": worst[1], "sample": worst[2]}, init_cycles=init_cycles,
        static_bound=bound.cycles, static_loops=[list(loop) for loop in bound.loops], sample_rate_hz=rate,
        clock_hz=clock_hz, load_measured=worst[0] * rate / clock_hz, load_static=bound.cycles * rate / clock_hz,
        headroom=headroom, streams=stream_info, per_sample_cycles=per_sample)


def render_markdown(budgets: list[Budget]) -> str:
    """A Markdown report of ``budgets`` for people (one table row per build, then per-build details)."""
    lines = ["# Firmware budget", "",
             "68000 clocks per `step` call (zero wait states; from the first instruction of `step` to its `RTS`).",
             "Static bound: every reachable instruction at its maximum clocks, loops times their `@bound` "
             "(see firmware_model/budget/cpu68k.py). Load = clocks x sample rate / CPU clock.", "",
             *md.header(["program", "k", "rounding", "ROM B", "RAM vars B", "stack peak B", "cycles min", "median",
                         "max", "static bound", "load max", "load static"])]
    for b in budgets:
        lines.append(md.row([b.program, b.config["k"], b.config["rounding"], b.rom_bytes, b.ram_variable_bytes,
                             b.stack_peak_bytes, b.cycles_min, f"{b.cycles_median:g}", b.cycles_max, b.static_bound,
                             f"{100 * b.load_measured:.2f}%", f"{100 * b.load_static:.2f}%"]))
    for b in budgets:
        lines += ["", f"## {b.program} (k = {b.config['k']}, {b.config['rounding']})", "",
                  f"- source SHA-256 `{b.source_sha256}`",
                  f"- worst measured step: {b.cycles_max} clocks on `{b.cycles_max_at['stream']}` sample "
                  f"{b.cycles_max_at['sample']}; init {b.init_cycles} clocks",
                  f"- CPU load at {b.clock_hz / 1e6:g} MHz and {b.sample_rate_hz:g} samples/s: "
                  f"{100 * b.load_measured:.2f}% measured worst, {100 * b.load_static:.2f}% static bound",
                  f"- ROM {b.rom_bytes} B (reset vectors, code and constants); RAM variables {b.ram_variable_bytes} B, "
                  f"stack peak {b.stack_peak_bytes} B, distinct RAM bytes written {b.ram_written_bytes}",
                  "- numeric headroom (largest |state| seen against int32):", "",
                  *md.header(["word", "max abs", "bits used (with sign)", "headroom bits"])]
        for name, h in b.headroom.items():
            lines.append(md.row([name, h["max_abs"], h["bits_used"], h["headroom_bits"]]))
        lines += ["", "Inputs: " + ", ".join(f"`{s['name']}` ({s['samples']} samples)" for s in b.streams)]
    return "\n".join(lines) + "\n"


def plot_cycles(budgets: list[Budget], path: Path) -> bool:
    """Plot cycles per sample on the flight stream for each build into ``path`` (PNG). Returns False (and writes
    nothing) when matplotlib is not installed."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    fig, ax = plt.subplots(figsize=(10, 5))
    for b in budgets:
        cyc = b.per_sample_cycles.get("flight")
        if cyc:
            t = np.arange(len(cyc)) / b.sample_rate_hz
            line, = ax.plot(t, cyc, lw=0.8, label=f"{b.program} k={b.config['k']} {b.config['rounding']}")
            ax.axhline(b.static_bound, color=line.get_color(), ls="--", lw=0.8)
    ax.set_xlabel("time from first sample (s)")
    ax.set_ylabel("68000 clocks per step")
    ax.set_title("Cycles per sample on the synthetic flight (dashed: static bound)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def write_reports(budgets: list[Budget], out_dir: Path) -> list[Path]:
    """Write ``budget.md``, ``budget.json``, ``cycles.csv`` and (when matplotlib is there) ``cycles.png`` into
    ``out_dir`` through :func:`firmware_model.runtime.output.staged_folder`: everything goes to a stage folder first and
    is moved into place under the folder lock only when complete, so an error or interrupt leaves the previous report
    and no temporary file. Other files in ``out_dir`` are kept. Returns the files written."""

    out_dir = Path(out_dir)
    with output.staged_folder(out_dir) as tmp:
        (tmp / "budget.md").write_text(render_markdown(budgets))
        (tmp / "budget.json").write_text(json.dumps([b.to_json() for b in budgets], indent=2, sort_keys=True) + "\n")
        rows = ["program,k,rounding,stream,sample,cycles"]
        for b in budgets:
            for stream, cyc in b.per_sample_cycles.items():
                rows += [f"{b.program},{b.config['k']},{b.config['rounding']},{stream},{i},{c}"
                         for i, c in enumerate(cyc)]
        (tmp / "cycles.csv").write_text("\n".join(rows) + "\n")
        plot_cycles(budgets, tmp / "cycles.png")
        names = sorted(p.name for p in tmp.iterdir())
    return [out_dir / name for name in names]


__all__ = ["Budget", "StaticBound", "DEFAULT_CLOCK_HZ", "default_streams", "measure", "render_markdown",
           "plot_cycles", "static_bound", "static_step_bound", "write_reports"]

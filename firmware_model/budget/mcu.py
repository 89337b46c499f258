"""Per-MCU budgets of the C99 port (vectors/c) beside the 68000's: ``fwemu budget --mcu``.

For each firmware build of the 68000 budget, the same inputs (:func:`firmware_model.budget.cpu68k.default_streams`) are
turned into a golden-vector set (the integer model's words, which equal the emulated 68000's), and the C99 port
runs that set on each target through ``vectors/c/mcu/check.sh``, which also checks every word:

* ``avr``: ATmega2560 under simavr, ``-Os``: **cycles** per ``fw_step`` measured with Timer1 (exact; 16 MHz);
* ``m0`` / ``m3`` / ``m4``: Cortex-M0 (BBC micro:bit), M3 (MPS2 AN385), M4 (MPS2 AN386) under qemu-system-arm at
  ``-Os`` and ``-O2``: **instructions** per ``fw_step`` (QEMU ``-icount shift=0`` counts instructions, not cycles;
  the harness counts with SysTick and checks the counting on a function of known length). QEMU does not model
  pipelines, wait states or multi-cycle instructions, so the Cortex-M "load" is a lower bound: instructions at one
  cycle each (a Cortex-M0 takes 1-3 cycles for most instructions, more for loads from slow flash).

Sizes are static: code and constant bytes of ``fw.c`` compiled alone for the target (``size``), the state and
constants structs (symbol sizes), and the stack of ``fw_step``: on ARM the deepest call path from ``fw_step`` by
``gcc -fcallgraph-info=su``; on the AVR (avr-gcc 5 has no call-graph output) the sum of every ``fw.c`` frame by
``-fstack-usage``; neither counts the frames of libgcc helpers (64-bit shifts, multiplies, divides on cores without
them), which are named in the report. A target whose toolchain is missing is reported as skipped, never guessed.
The load is the worst measured step at the sample rate 2^k over the stated clock.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

from firmware_model.runtime import markdown as md
from firmware_model.runtime import output
from firmware_model.runtime.errors import UserError
from firmware_model.spec.build_constants import build_constants
from firmware_model.vectors import cases as vec_cases
from firmware_model.vectors import generate as vectors

#: The port and its MCU scripts (a source checkout: vectors/ is not installed as package data).
C_DIR: Path = Path(__file__).resolve().parents[2] / "vectors" / "c"


@dataclass(frozen=True)
class Target:
    """One MCU target: ``key`` as check.sh takes it, what it is, its stated clock, the unit it measures."""

    key: str
    name: str
    clock_hz: float
    unit: str
    opts: tuple[str, ...]
    tools: tuple[str, ...]
    cc: str
    cflags: tuple[str, ...]
    size: str


TARGETS: tuple[Target, ...] = (
    Target("avr", "ATmega2560 (simavr)", 16e6, "cycles", ("Os",), ("avr-gcc", "simavr", "avr-size"), "avr-gcc",
           ("-mmcu=atmega2560",), "avr-size"),
    Target("m0", "Cortex-M0 (QEMU micro:bit)", 48e6, "instructions", ("Os", "O2"),
           ("arm-none-eabi-gcc", "qemu-system-arm"), "arm-none-eabi-gcc", ("-mcpu=cortex-m0", "-mthumb"),
           "arm-none-eabi-size"),
    Target("m3", "Cortex-M3 (QEMU MPS2 AN385)", 72e6, "instructions", ("Os", "O2"),
           ("arm-none-eabi-gcc", "qemu-system-arm"), "arm-none-eabi-gcc", ("-mcpu=cortex-m3", "-mthumb"),
           "arm-none-eabi-size"),
    Target("m4", "Cortex-M4 (QEMU MPS2 AN386)", 72e6, "instructions", ("Os", "O2"),
           ("arm-none-eabi-gcc", "qemu-system-arm"), "arm-none-eabi-gcc", ("-mcpu=cortex-m4", "-mthumb"),
           "arm-none-eabi-size"),
)

#: Program ids of the C port (fw.h ``fw_program``).
PROGRAM_IDS: dict[str, int] = {"recursive": 0, "kalman_baro": 1, "kalman_accel": 2, "recursive_seed_literal": 3}

_STAT = re.compile(r"^(?:icount|cycles) program (\d+): samples (\d+) min (\d+) mean (\d+) max (\d+) at (\S+) "
                   r"sample (\d+)( OVERFLOW)?$", re.M)


@dataclass
class Measured:
    """Per-step figures of one build on one target and level."""

    samples: int = 0
    min: int | None = None
    mean: float = 0.0
    max: int | None = None
    max_at: str = ""
    passed: bool = False
    overflow: bool = False

    def add(self, samples: int, lo: int, mean: int, hi: int, at: str, overflow: bool) -> None:
        total = self.samples + samples
        self.mean = (self.mean * self.samples + mean * samples) / total if total else 0.0
        self.samples = total
        self.min = lo if self.min is None else min(self.min, lo)
        if self.max is None or hi > self.max:
            self.max, self.max_at = hi, at
        self.overflow |= overflow


@dataclass
class McuBudget:
    """One build on every target: sizes per (target, level) and the measured steps."""

    program: str
    config: dict[str, Any]
    sample_rate_hz: float
    streams: list[str]
    #: the build's altitude table (int32 nodes, docs/firmware-spec.md §2a): flash data beside the constants
    table_bytes: int = 0
    sizes: dict[str, dict[str, Any]] = field(default_factory=dict)
    steps: dict[str, Measured] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)

    def load(self, key: str, opt: str) -> float | None:
        target = next(t for t in TARGETS if t.key == key)
        m = self.steps.get(f"{key}-{opt}")
        if m is None or m.max is None:
            return None
        return m.max * self.sample_rate_hz / target.clock_hz

    def to_json(self) -> dict[str, Any]:
        return {"program": self.program, "config": self.config, "sample_rate_hz": self.sample_rate_hz,
                "streams": self.streams, "table_bytes": self.table_bytes, "sizes": self.sizes, "skipped": self.skipped,
                "steps": {k: {**v.__dict__, "load": self.load(*k.split("-"))} for k, v in self.steps.items()}}


def available(target: Target) -> str | None:
    """None when the target's tools are installed, else the reason it is skipped."""
    missing = [t for t in target.tools if shutil.which(t) is None]
    return f"not installed: {', '.join(missing)}" if missing else None


def _run(args: Sequence[str], **kw: Any) -> subprocess.CompletedProcess[str]:
    return subprocess.run(list(args), capture_output=True, text=True, **kw)


def static_sizes(target: Target, opt: str, work: Path) -> dict[str, Any]:
    """Code/constant bytes of fw.c alone, the state/constants struct sizes and the static stack of fw_step."""
    work.mkdir(parents=True, exist_ok=True)
    obj = work / f"fw-{target.key}-{opt}.o"
    flags = [*target.cflags, f"-{opt}", "-std=c99", "-ffunction-sections", "-fstack-usage", f"-I{C_DIR}"]
    if target.key != "avr":
        flags.append("-fcallgraph-info=su")
    r = _run([target.cc, *flags, "-c", str(C_DIR / "fw.c"), "-o", str(obj)], cwd=work)
    if r.returncode:
        raise UserError(f"budget --mcu: {target.cc} failed on vectors/c/fw.c: {r.stderr.strip().splitlines()[-1:]}")
    size = _run([target.size, "-A", str(obj)]).stdout
    sections = {m.group(1): int(m.group(2)) for m in re.finditer(r"^(\.\S+)\s+(\d+)", size, flags=re.M)}
    code = sum(v for k, v in sections.items() if k.startswith(".text"))
    const = sum(v for k, v in sections.items() if k.startswith(".rodata"))
    ram = sum(v for k, v in sections.items() if k.startswith((".data", ".bss")))
    probe = work / "probe.c"
    probe.write_text('#include "fw.h"\nconst fw_consts fwv_probe_consts = {0};\nfw_state fwv_probe_state;\n')
    pobj = work / f"probe-{target.key}.o"
    r = _run([target.cc, *target.cflags, "-std=c99", f"-I{C_DIR}", "-c", str(probe), "-o", str(pobj)])
    if r.returncode:
        raise UserError(f"budget --mcu: {target.cc} failed on a probe of fw.h: {r.stderr.strip().splitlines()[-1:]}")
    nm = _run([target.cc.replace("gcc", "nm"), "-S", str(pobj)]).stdout
    # "address size type name" lines: the symbol sizes are the struct sizes on this target
    sym = {parts[3]: int(parts[1], 16) for parts in (line.split() for line in nm.splitlines()) if len(parts) == 4}
    su = (work / f"fw-{target.key}-{opt}.su")
    frames = {}
    if su.exists():
        for line in su.read_text().splitlines():
            parts = line.split("\t")
            if len(parts) >= 2:
                frames[parts[0].split(":")[-1]] = int(parts[1])
    if target.key == "avr":
        stack, how = sum(frames.values()), "sum of all fw.c frames (-fstack-usage); libgcc helpers not included"
    else:
        stack, helpers = _callgraph_stack(work / f"fw-{target.key}-{opt}.ci", "fw_step")
        how = "deepest fw.c call path from fw_step (-fcallgraph-info=su)" + (
            f"; libgcc helpers on it not included: {', '.join(helpers)}" if helpers else "")
    return {"code_bytes": code, "const_bytes": const, "static_ram_bytes": ram,
            "state_bytes": sym.get("fwv_probe_state"), "consts_struct_bytes": sym.get("fwv_probe_consts"),
            "stack_bytes": stack, "stack_method": how}


def _callgraph_stack(ci: Path, root: str) -> tuple[int | None, list[str]]:
    """Deepest stack (bytes) from ``root`` in a gcc -fcallgraph-info=su VCG file (no recursion in fw.c), and the
    compiler's helper routines reachable from it (``<built-in>`` nodes: libgcc, no frame size known)."""
    if not ci.exists():
        return None, []
    text = ci.read_text()
    frame: dict[str, int] = {}
    builtin: set[str] = set()
    for m in re.finditer(r'node: \{ title: "([^"]+)" label: "([^"]*)"', text):
        title, label = m.group(1), m.group(2)
        f = re.search(r"(\d+) bytes", label)
        frame[title.split(":")[-1]] = int(f.group(1)) if f else 0
        if "<built-in>" in label:
            builtin.add(title.split(":")[-1])
    calls: dict[str, list[str]] = {}
    for m in re.finditer(r'edge: \{ sourcename: "([^"]+)" targetname: "([^"]+)"', text):
        calls.setdefault(m.group(1).split(":")[-1], []).append(m.group(2).split(":")[-1])

    def deepest(fn: str, seen: frozenset[str]) -> int:
        if fn in seen:
            raise UserError(f"budget --mcu: recursion through {fn} in fw.c: no static stack bound")
        return frame.get(fn, 0) + max((deepest(c, seen | {fn}) for c in calls.get(fn, [])), default=0)

    reach, todo = set(), [root]
    while todo:
        fn = todo.pop()
        if fn not in reach:
            reach.add(fn)
            todo += calls.get(fn, [])
    return deepest(root, frozenset()), sorted(reach & builtin)


def _write_vector_set(builds: Sequence[tuple[Any, Sequence[Any]]], out: Path) -> None:
    """Write a vector set (integer model words) of every build's budget streams into ``out``."""

    specs = []
    for cfg, streams in builds:
        for stream in streams:
            name = vec_cases.case_name(cfg.program, cfg.rounding, cfg.k, cfg.baro_word_bits, "budget_" + stream.name)
            specs.append(vec_cases.CaseSpec(name, cfg, stream))
    results = vectors.generate(specs, "model", progress=False)
    for rel, data in vectors.render_set(results, "budget").items():
        path = out / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)


def measure(builds: Sequence[tuple[Any, Sequence[Any]]], work: Path | None = None,
            progress: bool = False) -> list[McuBudget]:
    """Budgets of ``builds`` ((BuildConfig, streams) pairs) on every available target."""
    if not (C_DIR / "mcu" / "check.sh").is_file():
        raise UserError(f"budget --mcu: the C port is not here ({C_DIR}); run from a source checkout")
    if len({cfg.program for cfg, _ in builds}) != len(builds):
        raise UserError("budget --mcu: one build per program (the port's statistics are per program)")
    own = work is None
    work = Path(tempfile.mkdtemp(prefix="fwemu-mcu-")) if own else Path(work)
    try:
        vec = work / "vectors"
        _write_vector_set(builds, vec)

        out = [McuBudget(cfg.program, cfg.to_dict(), 2.0 ** cfg.k, [s.name for s in streams],
                         table_bytes=4 * build_constants(cfg).ALT_N) for cfg, streams in builds]
        by_program_id = {}
        for b in out:
            by_program_id.setdefault(PROGRAM_IDS[b.program], []).append(b)
        for target in TARGETS:
            why = available(target)
            for opt in target.opts:
                key = f"{target.key}-{opt}"
                if why:
                    for b in out:
                        b.skipped[key] = why
                    continue
                if progress:
                    print(f"budget --mcu: {target.name} -{opt} ...", flush=True)
                sizes = static_sizes(target, opt, work / "sizes")
                env = dict(os.environ)
                if target.key != "avr":
                    env.update(CM_DEFS="-DFWV_ICOUNT", CM_QEMU_ARGS="-icount shift=0")
                r = _run(["bash", str(C_DIR / "mcu" / "check.sh"), target.key, opt, str(vec), str(work / "build")],
                         env=env, timeout=3600)
                ok = r.returncode == 0 and "calibration: known 101 instructions counted as 101" in r.stdout \
                    if target.key != "avr" else r.returncode == 0
                if not ok:
                    raise UserError(f"budget --mcu: the C port failed on {target.name} -{opt}: "
                                    + " | ".join(r.stdout.strip().splitlines()[-3:]))
                for b in out:
                    b.sizes[key] = sizes
                    b.steps[key] = Measured(passed=True)
                for m in _STAT.finditer(r.stdout):
                    for b in by_program_id.get(int(m.group(1)), []):
                        b.steps[key].add(int(m.group(2)), int(m.group(3)), int(m.group(4)), int(m.group(5)),
                                         f"{m.group(6)} sample {m.group(7)}", bool(m.group(8)))
        return out
    finally:
        if own:
            shutil.rmtree(work, ignore_errors=True)


def render_markdown(budgets: Sequence[McuBudget], m68k: Sequence[Any] = ()) -> str:
    """The MCU table: per build and target, code/constant bytes, RAM, worst step and load."""
    lines = ["## Per-MCU budget of the C99 port (vectors/c)", "",
             "Worst step over the budget inputs of each build (the same streams as the 68000 rows), with the input "
             "that gave it. AVR: cycles (Timer1 under simavr, exact). Cortex-M: **instructions** per step counted "
             "by QEMU (`-icount shift=0`), not cycles; the Cortex-M load assumes one cycle per instruction and is a "
             "lower bound. Code/const: `fw.c` alone (all programs), then the constants struct and the build's "
             "altitude table (flash data). RAM: state struct + static stack of `fw_step`.",
             "Typical = the median on the 68000, the mean on the MCUs. The static worst-case bound is the 68000's "
             "(in brackets); the MCU maxima are measured.",
             "", *md.header(["build", "target", "clock", "code B", "const B", "RAM B (state+stack)",
                             "step min / typical / max", "worst input", "load"])]
    m68k_by = {b.program: b for b in m68k}
    for b in budgets:
        cfg = b.config
        build = f"{b.program} k={cfg['k']} {cfg['rounding']}"
        mb = m68k_by.get(b.program)
        if mb is not None:
            lines.append(md.row([build, "MC68000 (ours)", f"{mb.clock_hz / 1e6:g} MHz", f"{mb.rom_bytes} (ROM)", "—",
                                 f"{mb.ram_variable_bytes}+{mb.stack_peak_bytes}",
                                 f"{mb.cycles_min} / {mb.cycles_median:g} / {mb.cycles_max} cycles "
                                 f"[bound {mb.static_bound}]",
                                 f"{mb.cycles_max_at.get('stream', '')} sample {mb.cycles_max_at.get('sample', '')}",
                                 f"{100 * mb.load_measured:.2f} %"]))
        for target in TARGETS:
            for opt in target.opts:
                key = f"{target.key}-{opt}"
                if key in b.skipped:
                    lines.append(f"| {build} | {target.name} -{opt} | | | | | skipped ({b.skipped[key]}) | | |")
                    continue
                s, m = b.sizes[key], b.steps[key]
                load = b.load(target.key, opt)
                bound = " (lower bound)" if target.unit == "instructions" else ""
                lines.append(md.row([build, f"{target.name} -{opt}", f"{target.clock_hz / 1e6:g} MHz", s["code_bytes"],
                                     f"{s['const_bytes']} + {s['consts_struct_bytes']} + {b.table_bytes}",
                                     f"{s['state_bytes']}+{s['stack_bytes']}",
                                     f"{m.min} / {m.mean:.0f} / {m.max} {target.unit}", m.max_at,
                                     ("" if load is None else f"{100 * load:.2f} %") + bound]))
    lines.append("")
    return "\n".join(lines)


def write_reports(budgets: Sequence[McuBudget], out_dir: Path, m68k: Sequence[Any] = ()) -> list[Path]:
    """mcu.md and mcu.json into ``out_dir`` (atomically; other files kept)."""

    out_dir = Path(out_dir)
    with output.staged_folder(out_dir) as tmp:
        (tmp / "mcu.md").write_text(render_markdown(budgets, m68k))
        (tmp / "mcu.json").write_text(json.dumps([b.to_json() for b in budgets], indent=2, sort_keys=True) + "\n")
    return [out_dir / "mcu.md", out_dir / "mcu.json"]

"""``fwemu budget``: cycle, RAM, ROM and headroom budgets of firmware builds run on the emulated 68000."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from firmware_model.budget import cpu68k as budget
from firmware_model.budget import mcu as mcu_budget
from firmware_model.cli.args import nonnegative_int, positive_float
from firmware_model.firmware.assemble import build_firmware
from firmware_model.runtime import output
from firmware_model.runtime.errors import UserError
from firmware_model.spec.config import load_config

#: Programs budgeted by default (the literal Schultz 2002 listing is a counter-example, not firmware anyone ships).
DEFAULT_PROGRAMS: tuple[str, ...] = ("recursive", "kalman_baro", "kalman_accel")


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]  # argparse's private class is not generic at runtime
    """Add the ``budget`` subcommand."""
    p = subparsers.add_parser("budget", help="cycle/RAM/ROM/headroom budget of firmware builds (Markdown + JSON)",
                              description="Run each build on the emulated 68000 over the synthetic flight and "
                                          "every edge stream; write budget.md, budget.json, cycles.csv and "
                                          "cycles.png into --out.")
    p.add_argument("--config", type=Path, help="build config JSON (default: the defaults of each program)")
    p.add_argument("--program", action="append", choices=("recursive", "kalman_baro", "kalman_accel",
                                                           "recursive_seed_literal"),
                   help=f"program to budget (repeatable; default: {', '.join(DEFAULT_PROGRAMS)})")
    p.add_argument("--k", type=int, help="sample period 2^-k s (overrides the config)")
    p.add_argument("--rounding", choices=("floor", "half_up"), help="rounding of right shifts (overrides config)")
    p.add_argument("--clock-mhz", type=positive_float, default=8.0, help="CPU clock for the load figures (default 8)")
    p.add_argument("--seed", type=nonnegative_int, default=0, help="seed of the synthetic flight (default 0)")
    p.add_argument("--out", type=Path, default=Path("out/budget"), help="output directory (default out/budget)")
    p.add_argument("--mcu", action="store_true",
                   help="also run the C99 port on the same inputs on an ATmega2560 (simavr: cycles) and "
                        "Cortex-M0/M3/M4 (qemu-system-arm: instructions); writes mcu.md and mcu.json (targets whose "
                        "tools are missing are reported as skipped)")
    p.set_defaults(func=run_budget)


def run_budget(args: argparse.Namespace) -> int:
    """Budget every requested build, print the Markdown report and write the files. Returns the exit code."""

    output.declare_output(args.out)
    base = load_config(args.config, {"k": args.k, "rounding": args.rounding})
    programs = args.program or ([base.program] if args.config else list(DEFAULT_PROGRAMS))
    configs = [load_config(args.config, {"program": name, "k": args.k, "rounding": args.rounding})
               for name in programs]   # flags override the file; a program other than the file's is an error
    results = []
    builds = []
    show = sys.stderr.isatty()
    for i, (name, cfg) in enumerate(zip(programs, configs), 1):
        if show:
            print(f"\r[{i}/{len(programs)}] {name} k={cfg.k} {cfg.rounding} ...", end="", file=sys.stderr, flush=True)
        build = build_firmware(cfg)
        streams = budget.default_streams(cfg.k, cfg.baro_bits, seed=args.seed, pascal=cfg.pascal)
        results.append(budget.measure(build, streams, clock_hz=args.clock_mhz * 1e6))
        builds.append((cfg, streams))
    if show:
        print(file=sys.stderr)
    if not results:
        raise UserError("budget: nothing to do")
    mcu = None
    if args.mcu:

        mcu = mcu_budget.measure(builds, progress=show)
    written = budget.write_reports(results, args.out)
    print(budget.render_markdown(results), end="")
    if mcu is not None:
        written += mcu_budget.write_reports(mcu, args.out, results)
        print(mcu_budget.render_markdown(mcu, results), end="")
    print("wrote " + ", ".join(str(p) for p in written))
    return 0

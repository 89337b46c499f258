"""``fwemu evaluate``: the apogee table (seed 000 Tables 1-2) over flights, as Markdown, CSV and JSON."""

from __future__ import annotations

import argparse
import shlex
import sys
from dataclasses import replace
from pathlib import Path

from firmware_model.cli_args import positive_int


def add_flight_arguments(p: argparse.ArgumentParser) -> None:
    """FLIGHTS and the options that choose/sense them (shared by evaluate and sweep)."""
    p.add_argument("flights", nargs="*", metavar="FLIGHT",
                   help="flight files (any format the readers take), sim:NAME (a simulated scenario; sim:all: "
                        "every scenario, sensed and sampled by --k/--baro/--accel/--no-noise), "
                        "set:NAME (an evaluation set: eval, logs, sim, quick)")
    p.add_argument("--simulated", action="store_true", help="add every simulated scenario")
    p.add_argument("--logs", action="store_true", help="add every shared real log (../shared/flights)")
    p.add_argument("--k", type=int, action="append", help="sample period 2^-k s (repeatable; default 7); "
                                                         "applies to FLIGHT arguments, not to set: members")
    p.add_argument("--baro", metavar="PRESET", help="barometer preset for FLIGHT arguments")
    p.add_argument("--accel", metavar="PRESET", help="accelerometer preset for FLIGHT arguments")
    p.add_argument("--no-noise", action="store_true", help="noise-free sensors for FLIGHT arguments")
    p.add_argument("--format", help="reader override for FLIGHT files")
    p.add_argument("--rounding", choices=("floor", "half_up"), help="rounding of every build (default floor)")
    p.add_argument("--jobs", "-j", type=positive_int, default=1, metavar="N",
                   help="worker processes (default 1; output identical for any N)")


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the ``evaluate`` subcommand."""
    p = subparsers.add_parser("evaluate", help="the apogee table over flights (Markdown, CSV, JSON)",
                              description="Run every method over every flight; per flight the reference apogee "
                                          "(truth, or the robust parabola of a real log), AltOS's own detection "
                                          "and each method's detection time and error; median/worst |error|.")
    add_flight_arguments(p)
    p.add_argument("--methods", action="append",
                   help="comma-separated methods (default all: rec_half, rec_quarter, rec_eighth, kalman_baro, "
                        "kalman_accel, ideal_kalman)")
    p.add_argument("--tuning", choices=("default", "recommended"), default="default",
                   help="default: the BuildConfig defaults; recommended: firmware_model.tuning.RECOMMENDED per "
                        "program and k (k without an entry keeps the defaults)")
    p.add_argument("--reference", choices=("parabola", "smoother", "auto"), default="parabola",
                   help="real logs' reference apogee: the barometric parabola (default), the UKF smoother's vertical "
                        "velocity zero crossing (needs an accelerometer), or auto (smoother where possible); "
                        "rows where the two disagree beyond their uncertainties are marked")
    p.add_argument("--out", type=Path, default=Path("out/evaluate"), help="output folder (default out/evaluate)")
    p.set_defaults(func=run_evaluate)


def specs_from_args(args: argparse.Namespace) -> list:
    from firmware_model.flights.evalset import resolve_flights

    return resolve_flights(args.flights, simulated=args.simulated, logs=args.logs, ks=args.k or [7],
                           baro=args.baro, accel=args.accel, noise=not args.no_noise, format=args.format)


def progress_printer(label: str):
    show = sys.stderr.isatty()

    def progress(i: int, n: int, name: str) -> None:
        if show:
            end = "\n" if i >= n else ""
            print(f"\r\033[K{label} [{i}/{n}] {name}", end=end, file=sys.stderr, flush=True)

    return progress


def run_evaluate(args: argparse.Namespace) -> int:
    from firmware_model.flights.evaluate import evaluate_many, methods_named, table_files
    from firmware_model.output import staged_folder

    specs = [replace(s, reference=args.reference) for s in specs_from_args(args)]
    methods = methods_named(args.methods)
    overrides = {"rounding": args.rounding} if args.rounding else {}
    command = "fwemu " + " ".join(shlex.quote(a) for a in sys.argv[1:]) if sys.argv[1:2] == ["evaluate"] else None
    results = evaluate_many(specs, methods, overrides, jobs=args.jobs, progress=progress_printer("evaluate"),
                            tuning=args.tuning)
    files = table_files(results, command)
    with staged_folder(args.out) as stage:
        for name, data in files.items():
            (stage / name).write_bytes(data)
    print(files["apogee.md"].decode(), end="")
    print(f"wrote {', '.join(str(args.out / n) for n in files)}")
    return 0

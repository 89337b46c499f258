"""``fwemu evaluate``: the apogee table (Schultz 2002 Tables 1-2) over flights, as Markdown, CSV and JSON."""

from __future__ import annotations

import argparse
import shlex
import sys
from dataclasses import replace
from pathlib import Path

from firmware_model.cli.args import add_flight_arguments, specs_from_args
from firmware_model.flights.evaluation.evaluate import evaluate_many
from firmware_model.flights.evaluation.methods import methods_named
from firmware_model.flights.evaluation.tables import table_files
from firmware_model.runtime.output import staged_folder
from firmware_model.runtime.progress import Progress


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]  # argparse's private class is not generic at runtime
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
                   help="default: the BuildConfig defaults; recommended: firmware_model.spec.tuning.RECOMMENDED per "
                        "program and k (k without an entry keeps the defaults)")
    p.add_argument("--reference", choices=("parabola", "smoother", "auto"), default="parabola",
                   help="real logs' reference apogee: the barometric parabola (default), the UKF smoother's vertical "
                        "velocity zero crossing (needs an accelerometer), or auto (smoother where possible); "
                        "rows where the two disagree beyond their uncertainties are marked")
    p.add_argument("--out", type=Path, default=Path("out/evaluate"), help="output folder (default out/evaluate)")
    p.set_defaults(func=run_evaluate)


def run_evaluate(args: argparse.Namespace) -> int:
    specs = [replace(s, reference=args.reference) for s in specs_from_args(args)]
    methods = methods_named(args.methods)
    overrides = {"rounding": args.rounding} if args.rounding else {}
    command = "fwemu " + " ".join(shlex.quote(a) for a in sys.argv[1:]) if sys.argv[1:2] == ["evaluate"] else None
    results = evaluate_many(specs, methods, overrides, jobs=args.jobs,
                            progress=Progress(0, "evaluate", unit="flights"),
                            tuning=args.tuning, scheduler=args.scheduler)
    files = table_files(results, command)
    with staged_folder(args.out) as stage:
        for name, data in files.items():
            (stage / name).write_bytes(data)
    print(files["apogee.md"].decode(), end="")
    print(f"wrote {', '.join(str(args.out / n) for n in files)}")
    return 0

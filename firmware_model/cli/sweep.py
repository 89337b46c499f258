"""``fwemu sweep``: apogee error against R/q (Schultz 2002 Figure 10) and against k over a set of flights: tables
(Markdown, CSV, JSON) and PNGs."""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

from firmware_model.cli.args import add_flight_arguments, specs_from_args
from firmware_model.flights import plot
from firmware_model.flights.evaluation import sweep
from firmware_model.flights.evaluation.sweep import DEFAULT_RATIOS
from firmware_model.runtime.errors import UserError
from firmware_model.runtime.output import staged_folder


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]  # argparse's private class is not generic at runtime
    """Add the ``sweep`` subcommand."""

    p = subparsers.add_parser("sweep", help="apogee error against R/q (Schultz 2002 Figure 10) and k: table + PNG",
                              description="--ratio: one Kalman method at each R/q on each flight (inputs made "
                                          "once at the first --k); --ks: every method at each k.")
    add_flight_arguments(p)
    p.add_argument("--what", choices=("ratio", "k", "both"), default="both", help="which sweep (default both)")
    p.add_argument("--method", default="kalman_baro", help="ratio sweep: method (default kalman_baro)")
    p.add_argument("--ratios", help="ratio sweep: comma-separated R/q values, or LO:HI:N (log-spaced); "
                                    "default 10:1e8:29")
    p.add_argument("--ks", default="4,5,6,7,8", help="k sweep: comma-separated k (default 4,5,6,7,8)")
    p.add_argument("--methods", action="append", help="k sweep: comma-separated methods (default all)")
    p.add_argument("--out", type=Path, default=Path("out/sweep"), help="output folder (default out/sweep)")
    p.set_defaults(func=run_sweep)


def parse_ratios(text: str | None) -> list[float]:
    if not text:
        return list(DEFAULT_RATIOS)
    try:
        if ":" in text:
            lo, hi, n = text.split(":")
            import numpy as np

            vals = np.logspace(np.log10(float(lo)), np.log10(float(hi)), int(n))
            return [float(v) for v in vals]
        return [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise UserError(f"--ratios {text!r}: expected comma-separated numbers or LO:HI:N") from None


def parse_ks(text: str) -> list[int]:
    try:
        ks = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise UserError(f"--ks {text!r}: expected comma-separated integers") from None
    if not ks or any(not 0 <= k <= 10 for k in ks):
        raise UserError(f"--ks {text!r}: k must be 0..10")
    return ks


def run_sweep(args: argparse.Namespace) -> int:
    specs = specs_from_args(args)
    if not specs:
        raise UserError("sweep: no flights (give FLIGHT arguments, set:NAME, --simulated or --logs)")
    overrides = {"rounding": args.rounding} if args.rounding else {}
    command = "fwemu " + " ".join(shlex.quote(a) for a in sys.argv[1:]) if sys.argv[1:2] == ["sweep"] else None
    files: dict[str, bytes] = {}
    shown = []
    if args.what in ("ratio", "both"):
        res = sweep.ratio_sweep(specs, parse_ratios(args.ratios), args.method, overrides, jobs=args.jobs,
                                scheduler=args.scheduler)
        files["ratio.md"] = sweep.render_markdown(res, command).encode()
        files["ratio.csv"] = sweep.render_csv(res).encode()
        files["ratio.json"] = sweep.render_json(res, command).encode()
        files["ratio.png"] = plot.plot_ratio_sweep(res)
        shown.append(files["ratio.md"].decode())
    if args.what in ("k", "both"):
        res = sweep.k_sweep(specs, parse_ks(args.ks), args.methods, overrides, jobs=args.jobs,
                            scheduler=args.scheduler)
        files["k.md"] = sweep.render_markdown(res, command).encode()
        files["k.csv"] = sweep.render_csv(res).encode()
        files["k.json"] = sweep.render_json(res, command).encode()
        files["k.png"] = plot.plot_k_sweep(res)
        shown.append(files["k.md"].decode())
    with staged_folder(args.out) as stage:
        for name, data in files.items():
            (stage / name).write_bytes(data)
    print("\n".join(shown), end="")
    print(f"wrote {', '.join(str(args.out / n) for n in files)}")
    return 0

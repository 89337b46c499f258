"""``fwemu plot``: PNG of a run (raw and filtered altitude, velocity on a second axis, event markers; Schultz n.d.'s
favourite gnuplot view), from a ``fwemu run`` CSV or straight from a flight (run through the integer model)."""

from __future__ import annotations

import argparse
from pathlib import Path

from firmware_model.flights.evaluation.methods import method_for_firmware
from firmware_model.flights.evaluation.setup import (FlightSpec, altitude_of_counts, flight_inputs, load_record,
    reference_for, sensor_config)
from firmware_model.flights.plot import plot_run
from firmware_model.flights.inputs.runcsv import COLUMNS, RunTable, from_trace
from firmware_model.model.run import run_model
from firmware_model.runtime.errors import UserError
from firmware_model.runtime.output import write_file
from firmware_model.spec.build_constants import build_constants


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]  # argparse's private class is not generic at runtime
    """Add the ``plot`` subcommand."""
    p = subparsers.add_parser("plot", help="PNG of a run: raw/filtered altitude, velocity, events (--zoom: apogee)",
                              description="RUN is a CSV written by `fwemu run`, or a flight (file or sim:NAME), "
                                          "which is then run through --firmware on the integer model.")
    p.add_argument("run", metavar="RUN.csv|FLIGHT")
    p.add_argument("-o", "--out", type=Path, required=True, metavar="FILE.png")
    p.add_argument("--zoom", action="store_true", help="a window around apogee")
    p.add_argument("--halfwidth", type=float, default=5.0, help="zoom half-width in s (default 5)")
    p.add_argument("--firmware", default="kalman_baro", help="for a FLIGHT: program/method (default kalman_baro)")
    p.add_argument("--k", type=int, default=7, help="for a FLIGHT: sample period 2^-k s (default 7)")
    p.add_argument("--format", help="for a FLIGHT: reader override")
    p.add_argument("--reference", type=float, metavar="S", help="reference apogee time to mark (run CSV input)")
    p.add_argument("--title", default=None)
    p.set_defaults(func=run_plot)


def _is_run_csv(path: Path) -> bool:
    try:
        with path.open() as f:
            head = f.readline().strip().split(",")
    except (OSError, UnicodeDecodeError):
        return False
    return tuple(head[:5]) == COLUMNS[:5]


def run_plot(args: argparse.Namespace) -> int:
    if not str(args.out).lower().endswith(".png"):
        raise UserError(f"-o {args.out}: the output must be a .png file")
    ref = args.reference
    altos = None
    own_computer = "AltOS"
    path = Path(args.run)
    if not args.run.startswith("sim:") and not path.exists():
        raise UserError(f"{args.run}: no such file")
    if not args.run.startswith("sim:") and _is_run_csv(path):
        table = RunTable.read_csv(path)
        title = args.title or path.stem
    else:
        import numpy as np

        method = method_for_firmware(args.firmware)
        record = load_record(args.run, args.format)
        inputs = flight_inputs(record, FlightSpec(args.run, k=args.k, format=args.format))
        cfg = method.config(args.k, sensor_config(inputs))
        acc = None if inputs.acc is None else np.asarray(inputs.acc)
        trace = run_model(build_constants(cfg), np.asarray(inputs.adc), acc)
        table = from_trace(trace, cfg, inputs.time_s, inputs.adc, acc, altitude_of_counts(inputs))
        if ref is None:
            ref = reference_for(record).time_s
        own = record.own_apogee()                 # the log's own computer (AltOS, RRC3, CATS, ...)
        altos, own_computer = (None, "AltOS") if own is None else (own[1], own[0])
        title = args.title or f"{record.name}: {method.name}, k={args.k}"
    png = plot_run(table, zoom=args.zoom, title=title, reference_s=ref, altos_s=altos, own_computer=own_computer,
                   zoom_halfwidth_s=args.halfwidth)
    write_file(args.out, png)
    print(f"wrote {args.out}")
    return 0

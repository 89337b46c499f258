"""``fwemu run``: replay one flight through a firmware build on the **emulated 68000** (cycles included), write the
per-sample CSV (Schultz n.d.'s rdaskal3 columns, then events and cycles) and print a summary.

``--model`` runs the bit-exact integer model instead (same words; no cycles). docs/evaluation.md, "fwemu run".
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from firmware_model.cli.args import add_reader_arguments, nonnegative_int
from firmware_model.firmware.assemble import build_firmware
from firmware_model.firmware.harness import run_firmware
from firmware_model.flights.evaluation.methods import ACCEL_PROGRAMS, method_for_firmware, tuning_overrides
from firmware_model.flights.evaluation.setup import (FlightSpec, altitude_of_counts, burnout_time, flight_inputs,
    load_record, reference_for, sensor_config)
from firmware_model.flights.inputs.runcsv import from_trace
from firmware_model.model.run import run_model
from firmware_model.runtime.errors import UserError
from firmware_model.runtime.output import write_file
from firmware_model.runtime.progress import Progress
from firmware_model.spec.build_constants import build_constants
from firmware_model.spec.config import BuildConfig
from firmware_model.spec.tuning import TUNINGS, describe_tuning


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]  # argparse's private class is not generic at runtime
    """Add the ``run`` subcommand."""
    p = subparsers.add_parser(
        "run", help="replay a flight through a firmware build on the emulated 68000 (per-sample CSV + summary)",
        description="Read a flight (AltosUI, CATS, RDAS, generic CSV, or sim:NAME), turn it into firmware inputs "
                    "(sensor model, resampling to 2^-k s, reported), run the firmware on the emulated 68000 and "
                    "write time, raw altitude, filtered altitude, velocity, acceleration, events, cycles per sample.")
    p.add_argument("--firmware", required=True, metavar="NAME",
                   help="program (recursive, kalman_baro, kalman_accel) or evaluation method (rec_half, "
                        "rec_quarter, rec_eighth, kalman_baro, kalman_accel)")
    p.add_argument("--input", required=True, metavar="FILE", help="flight file, or sim:NAME for a simulated scenario")
    p.add_argument("--format", help="reader override (default: detected)")
    add_reader_arguments(p)
    p.add_argument("--config", type=Path, metavar="C",
                   help="build config JSON: its fields override the sensor description and the method's tuning")
    p.add_argument("--tuning", choices=TUNINGS, default="default",
                   help="as fwemu evaluate: default = the BuildConfig defaults; recommended = "
                        "firmware_model.spec.tuning.RECOMMENDED for the program at k (a k without an entry keeps the "
                        "defaults); --config fields override it")
    p.add_argument("--k", type=int, help="sample period 2^-k s (default: the config's, else 7)")
    p.add_argument("--baro", metavar="PRESET", help="barometer sensor preset (default: the record's own sensor)")
    p.add_argument("--accel", metavar="PRESET", help="accelerometer preset (default: the record's own sensor)")
    p.add_argument("--no-noise", action="store_true", help="noise-free sensors")
    p.add_argument("--seed", type=nonnegative_int, default=0, help="sensor-noise seed (default 0)")
    p.add_argument("--resample", choices=("linear", "hold"), default="linear", help="resampling (default linear)")
    p.add_argument("--model", action="store_true", help="run the integer model instead of the emulated CPU")
    p.add_argument("--out", type=Path, metavar="FILE.csv", help="per-sample CSV (default: print the summary only)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run_run)


def _config_fields(path: Path | None) -> dict[str, Any]:
    """The fields written in a config file (validated through BuildConfig.from_file first)."""
    if path is None:
        return {}

    BuildConfig.from_file(path)              # one-line errors naming the file
    return dict(json.loads(path.read_text()))


def run_run(args: argparse.Namespace) -> int:
    """Run one flight through one build; write the CSV and print the summary."""

    method = method_for_firmware(args.firmware)
    fields = _config_fields(args.config)
    k = args.k if args.k is not None else int(fields.get("k", 7))
    spec = FlightSpec(args.input, k=k, baro=args.baro, accel=args.accel, noise=not args.no_noise, seed=args.seed,
                      format=args.format, method=args.resample, sensor=args.sensor, columns=args.columns,
                      site_altitude_m=args.site_altitude_m, flight=args.flight, late=args.late)
    record = load_record(args.input, args.format, **spec.reader_options())
    inputs = flight_inputs(record, spec)
    if method.program in ACCEL_PROGRAMS and not inputs.has_accel:
        raise UserError(f"{args.input}: --firmware {args.firmware} reads the accelerometer and this stream has none "
                        "(the log has none, or --late-start refuse): use kalman_baro")
    fields.pop("k", None)
    fields.pop("program", None)
    cfg = method.config(k, sensor_config(inputs), **{**tuning_overrides(method, k, args.tuning), **fields})
    adc = np.asarray(inputs.adc)
    acc = None if inputs.acc is None else np.asarray(inputs.acc)
    time_s = np.asarray(inputs.time_s, dtype=np.float64)
    show = not args.quiet and sys.stderr.isatty()
    t0 = time.monotonic()
    if args.model:

        trace = run_model(build_constants(cfg), adc, acc)
        engine = "integer model"
    else:

        trace = run_firmware(build_firmware(cfg), adc, acc,
                             progress=Progress(0, f"{cfg.program} on the 68000", show, interval=0.2))
        engine = "emulated 68000"
    elapsed = time.monotonic() - t0
    table = from_trace(trace, cfg, time_s, adc, acc, altitude_of_counts(inputs))
    # the summary first: a failure in it (no reference apogee) must not leave a CSV behind an exit 2 (issue 33)
    text = summary(table, record, inputs, cfg, engine, elapsed, reference_for(record), args.out,
                   describe_tuning(method.program, k, args.tuning, tuning_overrides(method, k, args.tuning)))
    if args.out is not None:
        write_file(args.out, table.to_csv())
    print(text)
    return 0


def summary(table: Any, record: Any, inputs: Any, cfg: Any, engine: str, elapsed: float, ref: Any,
            out: Path | None, tuning: str | None = None) -> str:
    """The text summary of a run (``tuning``: the line :func:`spec.tuning.describe_tuning` wrote)."""
    marks = table.event_times()
    baro = (f"baro 32-bit pascal word, {cfg.units_per_metre:.4g} Pa/m" if getattr(cfg, "pascal", False)
            else f"baro {cfg.baro_bits}-bit, {cfg.units_per_metre:.4g} counts/m")
    lines = [f"{record.name}: {cfg.program} (k={cfg.k}, dt={cfg.dt:g} s, {cfg.rounding}, {baro}) on the {engine}: "
             f"{table.time_s.size} samples in {elapsed:.2f} s"]
    prov = getattr(record, "provenance", {}) or {}
    if prov.get("format"):
        lines.append(f"log: {prov['format']} format" + ("; SYNTHETIC BAROMETER (pressure made from the log's "
                                                         "altitude)" if prov.get("synthetic_baro") else ""))
    lines += [f"  {n}" for n in prov.get("notes", [])]
    if tuning:
        lines.append(tuning)
    report = getattr(inputs, "report", None)
    if report is not None:
        text = report.summary() if callable(getattr(report, "summary", None)) else str(report)
        lines.append("inputs: " + text.replace("\n", "\n  "))

    def at(name: str) -> str:
        t = marks.get(name)
        return "never" if t is None else f"{t:.6f} s"

    lines.append(f"liftoff: {at('LIFTOFF')}")
    phases = table.phase_times()
    if table.phase is not None:
        lines.append("phases (PHASE word): " + (", ".join(f"{name.lower()} {t:.3f} s" for name, t in phases.items())
                                               or "pad only"))
    burn = burnout_time(record, marks.get("LIFTOFF"))
    lines.append("burnout: " + ("— (no accelerometer, or no coast)" if burn is None else
                                f"{burn:.3f} s (axial specific force below 0 after liftoff)"))
    apo = marks.get("APOGEE")
    if apo is None:
        lines.append("apogee: never declared")
    else:
        i = int(np.searchsorted(table.time_s, apo))
        lines.append(f"apogee: {apo:.6f} s at filtered altitude {table.filtered_altitude_m[i]:.1f} m "
                     f"(raw {table.raw_altitude_m[i]:.1f} m)")
    if marks.get("APOGEE_PREDICTED") is not None:
        lines.append(f"apogee predicted at sample {marks['APOGEE_PREDICTED']:.3f} s (APFRAC)")
    if marks.get("ACC_CLIP") is not None:      # docs/firmware-spec.md §5 step 3, §6 steps 4 and 7
        clear = marks.get("CLIP_CLEAR")
        after = (f"speed known again at {clear:.3f} s (CLIP_CLEAR), no apogee evidence before it" if clear is not None
                 else "the speed was never known again (no CLIP_CLEAR): no apogee evidence counted after the clip")
        lines.append(f"accelerometer clip: latched at {marks['ACC_CLIP']:.3f} s (ACC_CLIP, CLIP_N samples at its "
                     f"rail: the integrated speed is a lower bound); {after}")
    kind = "truth" if ref.source == "truth" else f"reference ({ref.source}, ±{ref.uncertainty_s:.3f} s)"
    alt = "" if ref.altitude_m is None else f", {ref.altitude_m:.1f} m"
    lines.append(f"{kind}: {ref.time_s:.3f} s{alt}")
    if apo is not None:
        lines.append(f"error: {apo - ref.time_s:+.3f} s (detection - {kind.split(' ')[0]}; + late)")
    own = record.own_apogee() if hasattr(record, "own_apogee") else None
    if own is not None:
        lines.append(f"{own[0]} apogee (the log's own computer): {own[1]:.3f} s (error {own[1] - ref.time_s:+.3f} s)")
    for name in ("MACH_LOCKOUT", "BARO_INVALID"):
        spans = table.intervals(name)
        if spans:
            shown = ", ".join(f"{a:.3f}-{b:.3f}" for a, b in spans[:8]) + (" ..." if len(spans) > 8 else "")
            lines.append(f"{name.lower()}: {len(spans)} interval(s), {shown} s")
        else:
            lines.append(f"{name.lower()}: none")
    if table.cycles is not None:
        j = int(np.argmax(table.cycles))
        lines.append(f"worst step: {int(table.cycles[j])} clocks at sample {j} ({table.time_s[j]:.3f} s); "
                     f"mean {float(np.mean(table.cycles)):.0f}")
    if out is not None:
        lines.append(f"wrote {out}")
    return "\n".join(lines)

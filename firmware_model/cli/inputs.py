"""``fwemu inputs``: a flight (any readable log, or ``sim:NAME``) as the firmware's integer input stream, the CSV
that ``fwemu vectors --firmware P --input FILE.csv`` takes.

The flight goes through the same steps as ``fwemu run``
(:func:`firmware_model.flights.inputs.firmware_inputs.firmware_inputs`): resampling onto the 2^-k s grid, the barometer
and
accelerometer models (``--baro`` / ``--accel`` presets; default the log's own sensor where its reader names one, else a
TeleMetrum v1 barometer and the default 2048 counts/g accelerometer), sensor noise seeded by ``--seed``. The CSV has
``#`` lines saying where it came from, a header ``time_s,adc[,acc]`` and one row per sample.

The words only mean something under a build config that describes the same sensors: ``--config-out FILE.json``
writes one (the sensors' transfer function and scales, the noise measured on the pad, the program's tuning, and
the fields of ``--config`` on top). Without ``--config-out`` the stream is checked against ``--config`` (default:
the ``BuildConfig`` defaults), and a sensor that build would misread is refused.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import Any

import numpy as np

from firmware_model.cli.args import add_reader_arguments, nonnegative_int
from firmware_model.flights.evaluation.methods import method_for_firmware, tuning_overrides
from firmware_model.flights.evaluation.setup import FlightSpec, flight_inputs, load_record, sensor_config
from firmware_model.model.streams import ACC_PROGRAMS
from firmware_model.runtime import output
from firmware_model.runtime.errors import UserError
from firmware_model.spec.config import PROGRAMS, BuildConfig, load_config, read_config_file
from firmware_model.spec.tuning import TUNINGS

#: Rows written per piece of the streamed CSV.
_ROWS_PER_WRITE: int = 65536


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]  # argparse's private class is not generic at runtime
    """Add the ``inputs`` subcommand (contract in :mod:`firmware_model.cli.main`)."""
    p = subparsers.add_parser(
        "inputs", help="a flight as the firmware's integer input stream (the CSV fwemu vectors --input takes)",
        description=__doc__.split("\n\n")[0].replace("\n", " ") if __doc__ else None)
    p.add_argument("source", metavar="FLIGHT", help="flight file (any format the readers take) or sim:NAME")
    p.add_argument("--program", required=True, choices=[p for p in PROGRAMS if p != "recursive_seed_literal"],
                   help="the firmware program the stream is for (kalman_accel and recursive need an accelerometer)")
    p.add_argument("--k", type=int, help="sample period 2^-k s (default: --config's k, else 7)")
    p.add_argument("--config", metavar="C", help="build config JSON of the port: its k and fields; without "
                                                 "--config-out, the stream must suit it")
    p.add_argument("-o", "--out", required=True, metavar="FILE.csv", help="the input stream CSV to write")
    p.add_argument("--config-out", metavar="FILE.json",
                   help="also write the build config that reads this stream (pass it to fwemu vectors --config)")
    p.add_argument("--tuning", choices=TUNINGS, default="default",
                   help="tuning in --config-out, as fwemu run (default: the BuildConfig defaults)")
    p.add_argument("--format", help="reader override (default: detected)")
    add_reader_arguments(p)
    p.add_argument("--baro", metavar="PRESET", help="barometer preset (default: the record's own sensor)")
    p.add_argument("--accel", metavar="PRESET", help="accelerometer preset (default: the firmware's default)")
    p.add_argument("--no-noise", action="store_true", help="noise-free sensors (with --baro/--accel presets)")
    p.add_argument("--seed", type=nonnegative_int, default=0, help="sensor-noise seed (default 0)")
    p.add_argument("--resample", choices=("linear", "hold"), default="linear", help="resampling (default linear)")
    p.set_defaults(func=run_inputs)


#: Fields of a build config that describe the sensors, i.e. what the words of the stream mean. ``units_per_metre``
#: is not among them: it is the pad's calibration, which a port may set itself.
_SENSOR_FIELDS: tuple[str, ...] = ("baro_kind", "baro_bits", "baro_sign", "baro_pa_per_count", "baro_pa_at_zero",
                                   "accel_counts_per_mps2")


def _mismatches(cfg: BuildConfig, sensor: dict[str, Any], reads_acc: bool) -> list[str]:
    """``field=config value (the stream: value)`` for each sensor field on which ``cfg`` would misread the stream."""
    stream = BuildConfig.from_dict({"baro_kind": "adc", **{k: v for k, v in sensor.items() if k in _SENSOR_FIELDS}},
                                   where="the stream's sensors")
    wrong: list[str] = []
    if cfg.baro_kind != stream.baro_kind:
        wrong.append(f"baro_kind={cfg.baro_kind} (the stream: {stream.baro_kind})")
    elif not cfg.pascal:
        if cfg.baro_bits != stream.baro_bits:
            wrong.append(f"baro_bits={cfg.baro_bits} (the stream: {stream.baro_bits})")
        if cfg.baro_sign != stream.baro_sign:
            wrong.append(f"baro_sign={cfg.baro_sign} (the stream: {stream.baro_sign})")
        for name, mine, theirs in zip(("baro_pa_per_count", "baro_pa_at_zero"), cfg.baro_transfer,
                                      stream.baro_transfer):
            if not math.isclose(mine, theirs, rel_tol=1e-6, abs_tol=1e-6):
                wrong.append(f"{name}={mine:.6g} (the stream: {theirs:.6g})")
    if reads_acc and not math.isclose(cfg.accel_counts_per_mps2, stream.accel_counts_per_mps2, rel_tol=1e-6):
        wrong.append(f"accel_counts_per_mps2={cfg.accel_counts_per_mps2:.6g} "
                     f"(the stream: {stream.accel_counts_per_mps2:.6g})")
    return wrong


def _csv_lines(inputs: Any, with_acc: bool, comments: list[str]) -> Any:
    """The CSV text in pieces: comment lines, the header, then the rows."""
    yield "".join(f"# {line}\n" for line in comments)
    yield "time_s,adc,acc\n" if with_acc else "time_s,adc\n"
    t = np.asarray(inputs.time_s, dtype=np.float64)
    adc = np.asarray(inputs.adc, dtype=np.int64)
    acc = np.asarray(inputs.acc, dtype=np.int64)
    for start in range(0, len(t), _ROWS_PER_WRITE):
        stop = start + _ROWS_PER_WRITE
        # repr of a float is exact and shortest: the grid times are multiples of 2^-k
        cols = [map(repr, t[start:stop].tolist()), map(str, adc[start:stop].tolist())]
        if with_acc:
            cols.append(map(str, acc[start:stop].tolist()))
        yield "".join(",".join(row) + "\n" for row in zip(*cols))


def run_inputs(args: argparse.Namespace) -> int:
    """Write the input stream (and the config with ``--config-out``); print what was written to stderr."""
    output.declare_output(*[p for p in (args.out, args.config_out) if p])
    # flags override the file; a different program is an error (docs/cli.md); validated
    cfg = load_config(args.config, {"program": args.program, "k": args.k})
    method = method_for_firmware(args.program)
    spec = FlightSpec(args.source, k=cfg.k, baro=args.baro, accel=args.accel, noise=not args.no_noise,
                      seed=args.seed, format=args.format, method=args.resample, sensor=args.sensor,
                      columns=args.columns, site_altitude_m=args.site_altitude_m, flight=args.flight, late=args.late)
    record = load_record(args.source, args.format, **spec.reader_options())
    inputs = flight_inputs(record, spec)
    reads_acc = args.program in ACC_PROGRAMS
    if reads_acc and not inputs.has_accel:
        raise UserError(f"{args.source}: --program {args.program} reads the accelerometer and this stream has none "
                        "(the log has none, or --late-start refuse): use kalman_baro")
    sensor = sensor_config(inputs)
    written_cfg: BuildConfig | None = None
    if args.config_out:
        given = read_config_file(args.config) if args.config else {}
        given = {key: value for key, value in given.items() if key not in ("program", "k")}
        # only the sensor fields the file gives are checked: the others are written from the stream
        mine = {"baro_kind": "adc", **sensor, **{key: given[key] for key in _SENSOR_FIELDS if key in given}}
        wrong = _mismatches(BuildConfig.from_dict(mine, where=str(args.config)), sensor, reads_acc)
        if wrong:
            raise UserError(f"{args.config}: {'; '.join(wrong)}: the config's sensors are not the stream's; drop "
                            "these fields (--config-out writes the stream's) or choose --baro/--accel presets")
        written_cfg = method.config(cfg.k, sensor, **{**tuning_overrides(method, cfg.k, args.tuning), **given})
    else:
        wrong = _mismatches(cfg, sensor, reads_acc)
        if wrong:
            where = args.config or "the default build config"
            raise UserError(f"{where}: {'; '.join(wrong)}: that build would misread this stream; pass --config-out "
                            "FILE.json and give it to fwemu vectors --config, or choose --baro/--accel presets")
    comments = [f"fwemu inputs {args.source}: program {args.program}, k={cfg.k} (dt 2^-{cfg.k} s), {inputs.n} samples",
                f"barometer {inputs.baro.name} ({inputs.baro.kind}), accelerometer "
                f"{inputs.accel.name if inputs.has_accel else 'none'}, seed {inputs.seed}, resampling {args.resample}",
                f"liftoff at {inputs.liftoff_s:.3f} s of the record; "
                f"ground pressure {inputs.ground_pressure_pa:.1f} Pa"]
    comments += [f"note: {note}".replace("\n", " ") for note in inputs.report.notes]
    with output.open_atomic(args.out, "w") as f:
        for piece in _csv_lines(inputs, reads_acc or inputs.has_accel, comments):
            f.write(piece)
    print(f"wrote {args.out}: {inputs.n} samples at 2^-{cfg.k} s", file=sys.stderr)
    if written_cfg is not None:
        output.write_file(args.config_out, json.dumps(written_cfg.to_dict(), indent=2) + "\n")
        print(f"wrote {args.config_out}: the build config of these sensors", file=sys.stderr)
    return 0


__all__ = ["register", "run_inputs"]

"""``fwemu check-port``: check a team's own C port against the bit-exact integer model (docs/port-check.md).

* ``fwemu check-port fw.c [more.c ...] --program kalman_accel --k 6 --rounding half_up`` compiles the sources
  with the host compiler (strict flags) and the glue, drives the port and the model with hypothesis streams
  (flights subsonic to supersonic with barometer errors, spikes and clipped sensors; the edge streams; held
  register extremes) and compares every state word of every sample.
* ``--lib LIB.so`` checks a prebuilt library instead; ``--adapter FILE.json`` maps a port with its own names and
  types onto the fw.h API.
* On a difference: the shrunk stream is printed and written as a Unity test, a plain C test and a golden-vector
  case JSON in ``--out`` (default ``port-check``); exit 1. Exit 0: no difference within the budget; exit 2: a
  usage or build error (one line).
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis.configuration import set_hypothesis_home_dir, storage_directory

from firmware_model.cli.args import bounded_int, nonnegative_int, positive_float, positive_int
from firmware_model.runtime import output
from firmware_model.runtime.errors import UserError
from firmware_model.spec.config import PROGRAMS, ROUNDINGS, BuildConfig, load_config
from firmware_model.spec.tuning import recommended_config
from firmware_model.vectors.cases import case_config, pascal_case_config
from firmware_model.vectors.portcheck.adapter import load_adapter
from firmware_model.vectors.portcheck.build import build_port
from firmware_model.vectors.portcheck.check import check_port
from firmware_model.vectors.portcheck.isolate import MEMORY_LIMIT_MB, STREAM_TIMEOUT_S
from firmware_model.vectors.portcheck.repro import describe, write_repro

SENSORS: tuple[str, ...] = ("adc16", "adc12", "pascal")
TUNINGS: tuple[str, ...] = ("default", "recommended")


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]  # argparse's private class is not generic at runtime
    """Add the ``check-port`` subcommand."""
    p = subparsers.add_parser("check-port", help="check a team's C port against the bit-exact model (shrunk "
                                                 "differences as C unit tests)",
                              description=__doc__.splitlines()[0] if __doc__ else None)
    p.add_argument("sources", nargs="*", metavar="SRC.c", help="the port's C sources (compiled with the glue)")
    p.add_argument("--lib", metavar="LIB.so", help="a prebuilt shared library of the port instead of sources")
    p.add_argument("--adapter", metavar="ADAPTER.json", help="map the port's own names and types onto the fw.h "
                                                             "API (docs/port-check.md, Adapter)")
    p.add_argument("-I", dest="include", action="append", default=[], metavar="DIR",
                   help="extra include folder (the sources' folders are included)")
    p.add_argument("--cflags", default="", help="extra compiler flags, after the strict ones")
    p.add_argument("--case", metavar="CASE.json", help="the build of a golden-vector case (its stream is checked "
                                                       "first)")
    p.add_argument("--config", metavar="FILE.json", help="a build config file (flags override it)")
    p.add_argument("--program", choices=PROGRAMS, help="firmware program (default: kalman_baro)")
    p.add_argument("--k", type=int, help="sample period 2^-k s (default 5)")
    p.add_argument("--rounding", choices=ROUNDINGS,
                   help="rounding of every right shift (default: the program's, half_up for kalman_accel, floor "
                        "otherwise)")
    p.add_argument("--sensor", choices=SENSORS, help="barometer: the golden vectors' 16- or 12-bit ADC, or the "
                                                     "pascal word (default adc16)")
    p.add_argument("--tuning", choices=TUNINGS, help="default: the BuildConfig defaults; recommended: "
                                                     "firmware_model.spec.tuning (k 5..7)")
    p.add_argument("--examples", type=positive_int, help="at most N streams (default 1000 unless --time)")
    p.add_argument("--time", type=positive_float, metavar="S", help="stop after S seconds")
    p.add_argument("--seed", type=nonnegative_int, default=0, help="search seed: the same seed replays the same "
                                                                   "streams (default 0)")
    p.add_argument("--out", type=Path, default=Path("port-check"), help="folder for the files of a difference "
                                                                        "(default port-check)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.add_argument("--stream-timeout", type=positive_float, default=STREAM_TIMEOUT_S, metavar="S",
                   help=f"wall-time limit of one stream in the port's child process (default {STREAM_TIMEOUT_S:g} s; "
                        "past it the port is reported as hanging)")
    p.add_argument("--memory", type=bounded_int(16, 1 << 20, "MiB"), default=MEMORY_LIMIT_MB, metavar="MIB",
                   help=f"address-space limit of the port's child process (default {MEMORY_LIMIT_MB} MiB)")
    p.set_defaults(func=run)


def config_from_args(args: argparse.Namespace) -> tuple[BuildConfig, list[Any]]:
    """The build config of the run and the streams to check first (a case's)."""
    streams: list[Any] = []
    if args.case:
        if args.config or any(getattr(args, f) is not None for f in ("program", "k", "rounding", "sensor",
                                                                     "tuning")):
            raise UserError("check-port: --case gives the whole build: drop --config/--program/--k/--rounding/"
                            "--sensor/--tuning")
        path = Path(args.case)
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise UserError(f"{path}: no such case file") from None
        except (OSError, UnicodeDecodeError) as exc:
            raise UserError(f"{path}: cannot read: {exc}") from None
        except json.JSONDecodeError as exc:
            raise UserError(f"{path}:{exc.lineno}:{exc.colno}: invalid JSON: {exc.msg}") from None
        if not isinstance(doc, dict) or not isinstance(doc.get("build_config"), dict):
            raise UserError(f"{path}: not a golden-vector case (no build_config object)")
        cfg = BuildConfig.from_dict(doc["build_config"], where=f"{path}: build_config")
        if isinstance(doc.get("adc"), list) and isinstance(doc.get("acc"), list) and doc["adc"]:
            streams.append((np.asarray(doc["adc"], dtype=np.int64), np.asarray(doc["acc"], dtype=np.int64)))
        return cfg, streams
    program = args.program or "kalman_baro"
    k = 5 if args.k is None else args.k
    if not 0 <= k <= 10:
        raise UserError(f"check-port: --k {k}: must be 0..10")
    rounding = args.rounding or "floor"
    sensor = args.sensor or "adc16"
    if args.config:
        over = {"program": args.program, "k": args.k, "rounding": args.rounding}
        cfg = load_config(args.config, over)
        if args.sensor or args.tuning:
            raise UserError("check-port: --sensor/--tuning go with the flags, not --config (the file is the build)")
        return cfg, streams
    if args.tuning == "recommended":
        base = case_config(program, rounding, k, 12 if sensor == "adc12" else 16) if sensor != "pascal" else \
            pascal_case_config(program, rounding, k)
        sensor_fields = {f: getattr(base, f) for f in ("baro_kind", "baro_bits", "units_per_metre", "baro_sigma",
                                                       "baro_min", "baro_max", "baro_pa_per_count",
                                                       "baro_pa_at_zero")}
        cfg = recommended_config(program, k, **sensor_fields)
        if args.rounding:
            cfg = cfg.replace(rounding=rounding)
        return cfg, streams
    if sensor == "pascal":
        return pascal_case_config(program, rounding, k), streams
    return case_config(program, rounding, k, 12 if sensor == "adc12" else 16), streams


def run(args: argparse.Namespace) -> int:
    """Execute ``fwemu check-port``; returns the exit code."""
    if not args.sources and not args.lib:
        raise UserError("check-port: give the port's C sources (SRC.c ...) or --lib LIB.so")
    if args.sources and args.lib:
        raise UserError("check-port: give C sources or --lib LIB.so, not both")
    cfg, streams = config_from_args(args)
    examples = args.examples if args.examples is not None else (None if args.time else 1000)
    adapter = load_adapter(args.adapter) if args.adapter else None
    output.declare_output(args.out)
    includes = list(args.include) + ([str(Path(args.adapter).resolve().parent)] if args.adapter else [])
    port = build_port(args.sources, lib=args.lib, adapter=adapter, include_dirs=includes, cflags=args.cflags,
                      memory_mb=args.memory, timeout_s=args.stream_timeout)
    home = storage_directory(intent_to_write=False).home_directory
    try:
        if port.workdir is not None:  # hypothesis's caches go with the build, not into the user's current folder
            set_hypothesis_home_dir(port.workdir / ".hypothesis")
        return _check(args, cfg, streams, examples, port)
    finally:
        port.close()           # the port's child process, before its folder goes
        set_hypothesis_home_dir(home)
        if port.workdir is not None:  # the build folder (a fresh temporary one) and hypothesis's caches in it
            shutil.rmtree(port.workdir, ignore_errors=True)


def _check(args: argparse.Namespace, cfg: BuildConfig, streams: list[Any], examples: int | None, port: Any) -> int:
    what = f"{cfg.program} {cfg.rounding} k={cfg.k} {'pascal' if cfg.pascal else f'{cfg.baro_bits}-bit ADC'}"
    last = [0.0]
    tty = sys.stderr.isatty()

    def progress(res: Any) -> None:
        if args.quiet or (not tty and res.seconds - last[0] < 5.0):
            return
        last[0] = res.seconds
        line = (f"check-port: {what}: {res.examples} streams, {res.samples:,} samples, {res.seconds:.1f} s, "
                "no difference yet")
        print(("\r" + line) if tty else line, end="" if tty else "\n", file=sys.stderr, flush=True)

    t0 = time.perf_counter()
    res = check_port(port, cfg, examples=examples, seconds=args.time, seed=args.seed, progress=progress,
                     extra_streams=streams)
    if tty and not args.quiet:
        print("", file=sys.stderr)
    if res.mismatch is None:
        print(f"check-port: {what}: no difference in {res.examples} streams ({res.samples:,} samples, every word "
              f"of every sample) in {time.perf_counter() - t0:.1f} s, seed {args.seed}")
        return 0
    for line in describe(res.mismatch):
        print(line)
    paths = write_repro(res.mismatch, port.adapter, args.out, args.seed)
    if res.mismatch.crash is not None:
        print("  reproduce: build a test file below with your port and run it (under a debugger or with "
              "-fsanitize=address,undefined)")
    print(f"  found after {res.examples_to_failure} streams ({res.samples_to_failure:,} samples, "
          f"{res.seconds_to_failure:.1f} s), shrunk in {res.shrink_seconds:.1f} s; replay: --seed {args.seed}")
    for p in paths:
        print(f"  wrote {p}")
    return 1

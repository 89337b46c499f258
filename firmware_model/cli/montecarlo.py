"""``fwemu montecarlo``: deployment safety as a probability over dispersed flights (docs/montecarlo.md)."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from firmware_model.cli.args import bounded_int, nonnegative_int, positive_int
from firmware_model.runtime.errors import UserError
from firmware_model.flights.readers.generic import generic_csv
from firmware_model.flights.montecarlo.pipeline import replay_configs, replay_record
from firmware_model.flights.montecarlo.run import MAX_FLIGHTS, run_montecarlo
from firmware_model.flights.montecarlo.spec import load_spec, read_spec_file
from firmware_model.runtime.output import declare_output, write_file
from firmware_model.runtime.progress import Progress
from firmware_model.runtime.engine import parse_scheduler


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]  # argparse's private class is not generic at runtime
    """Add the ``montecarlo`` subcommand."""
    p = subparsers.add_parser(
        "montecarlo", help="every method over N dispersed simulated flights: P(early), P(missed), with intervals",
        description="Simulate N flights of a scenario (or rocket + motor) with the dispersions of SPEC, sense them, "
                    "run every method and tuning on the integer model, and write one row per (flight, method, "
                    "tuning) plus a summary: the error distribution and P(> 0.5 s early), P(> 1 s early), "
                    "P(missed), P(fired before burnout) with 95 % Wilson intervals. Flight i is reproducible "
                    "alone from (--seed, i).")
    p.add_argument("spec", type=Path, metavar="SPEC", help="the spec file (.toml or .json; docs/montecarlo.md)")
    p.add_argument("-n", "--flights", type=bounded_int(1, MAX_FLIGHTS, "the cap on flights per run"), default=1000,
                   help=f"number of flights (default 1000; 1..{MAX_FLIGHTS:,})")
    p.add_argument("--seed", type=nonnegative_int, default=0, help="master seed (default 0)")
    p.add_argument("--out", type=Path, default=Path("out/montecarlo"), help="output folder (default out/montecarlo)")
    p.add_argument("--jobs", "-j", type=positive_int, default=1, metavar="N",
                   help="local worker processes (default 1; rows identical for any N)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run on a Dask distributed scheduler (tcp://host:8786), or local:N for a LocalCluster of N "
                        "workers started for the run (needs the 'montecarlo' extra)")
    p.add_argument("--resume", action="store_true", help="continue an interrupted run from the chunks in OUT")
    p.add_argument("--format", choices=("parquet", "csv"), help="rows file (default parquet with pyarrow, else csv)")
    p.add_argument("--replay", type=nonnegative_int, metavar="ID",
                   help="write flight ID alone as a generic CSV with truth (OUT/flight-ID.csv) and stop")
    p.add_argument("--no-figures", action="store_true", help="skip the PNGs")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run_cli)


def _progress(show: bool):
    """The run's progress callback: the one progress bar (:class:`~firmware_model.runtime.progress.Progress`),
    flights/s and ETA over the flights this run computes (chunks resumed from disk are left out of both)."""
    state: dict[str, object] = {}

    def progress(done: int, n: int, seconds: float) -> None:
        if "bar" not in state:
            state["start"] = done
            state["bar"] = Progress(max(n - done, 1), "montecarlo", enabled=show, unit="flights", eta=True)
        start = int(state["start"])  # type: ignore[arg-type]  # state holds the start count and the progress bar under str keys
        state["bar"].update(done - start, n - start)  # type: ignore[union-attr]  # state['bar'] is the Progress set just above

    return progress


def run_cli(args: argparse.Namespace) -> int:
    spec = load_spec(read_spec_file(args.spec), where=str(args.spec))
    if args.replay is not None:
        rec, prm = replay_record(spec, args.seed, args.replay)
        dest = args.out / f"flight-{args.replay}.csv"
        configs = replay_configs(spec, prm)
        declare_output(dest)
        write_file(dest, generic_csv(rec))
        for name, cfg in configs.items():
            write_file(args.out / f"flight-{args.replay}.{name}.json", json.dumps(cfg, indent=1, sort_keys=True) + "\n")
        baro, accel = rec.provenance["baro_preset"], rec.provenance["accel_preset"]
        print(f"wrote {dest} and its {len(configs)} build configs (flight-{args.replay}.<method>-<tuning>.json): "
              f"flight {args.replay} of seed {args.seed}, true apogee {rec.truth.apogee_time_s:.3f} s, "
              f"{rec.truth.apogee_altitude_m:.0f} m")
        m, t = spec["methods"][0], spec["tunings"][0]
        print(f"replay: fwemu run --firmware {m} --model --input {dest} --config "
              f"{args.out / f'flight-{args.replay}.{m}-{t}.json'} --k {spec['k']} --baro {baro} --accel {accel} "
              "--no-noise")
        return 0
    backend = parse_scheduler(args.scheduler, args.jobs)
    if args.scheduler is not None and args.jobs != 1:
        raise UserError("--jobs is for local processes; with --scheduler the cluster's workers run the chunks")
    declare_output(args.out)
    show = not args.quiet and sys.stderr.isatty()
    t0 = time.perf_counter()
    res = run_montecarlo(spec, args.seed, args.flights, args.out, backend, args.format, args.resume,
                         progress=_progress(show), figures=not args.no_figures,
                         note=lambda text: print(f"fwemu: {text}", file=sys.stderr))
    total = time.perf_counter() - t0
    s = res.seconds
    comp = ", ".join(f"{k} {v:.1f}" for k, v in s.items())
    print(f"{res.flights} flights ({res.chunks} chunks, {res.resumed_chunks} resumed) in {total:.1f} s wall "
          f"({res.wall_s:.1f} s running chunks) on {res.backend}; worker seconds: {comp}")
    print(f"rows: {res.rows_path}; summary: {res.folder / 'summary.md'}")
    return 0

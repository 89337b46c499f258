"""``fwemu vectors``: golden vectors for microcontroller ports (docs/vectors.md).

* ``fwemu vectors --all --out vectors`` regenerates the whole committed set (byte-identical on every run).
* ``fwemu vectors --firmware NAME --input FILE.csv [--config FILE.json] --out DIR`` makes a one-case set from a
  user stream (CSV with a header naming ``adc`` and optionally ``acc``).
* ``fwemu vectors --check DIR`` verifies a set against its manifest (exit 1 on any difference).
* ``--unity DIR`` also writes the set in ``--out`` (default ``vectors``) as a Unity test runner
  (:mod:`firmware_model.vectors.unity`); alone, for an existing set.
"""

from __future__ import annotations

import argparse
import sys

from firmware_model.cli.args import positive_int
from firmware_model.runtime import output
from firmware_model.runtime.errors import UserError
from firmware_model.spec.config import PROGRAMS
from firmware_model.vectors import generate as vectors
from firmware_model.vectors import stream as vectors_stream
from firmware_model.vectors.unity import write_unity_runner


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``vectors`` subcommand to the ``fwemu`` parser (contract in :mod:`firmware_model.cli.main`)."""
    p = subparsers.add_parser("vectors", help="golden vectors (JSON + C headers) for firmware ports",
                              description=__doc__.splitlines()[0] if __doc__ else None)
    mode = p.add_mutually_exclusive_group()
    mode.add_argument("--all", action="store_true", help="regenerate the whole committed case matrix")
    mode.add_argument("--firmware", choices=PROGRAMS, help="program for a vector set from a user stream")
    mode.add_argument("--check", metavar="DIR", help="verify a vector set against its manifest.json")
    p.add_argument("--input", metavar="FILE.csv", help="user stream: CSV with columns adc[,acc] (with --firmware)")
    p.add_argument("--config", metavar="FILE.json", help="build config (with --firmware; default BuildConfig)")
    p.add_argument("--out", metavar="DIR", help="output directory (vector set layout, see docs/vectors.md)")
    p.add_argument("--generator", choices=("emulation", "model"), default="emulation",
                   help="emulation: 68000 firmware on the emulated CPU, cross-checked against the integer model "
                        "(default); model: the integer model only (marked as such in every file)")
    p.add_argument("--no-header", action="store_true",
                   help="with --firmware: write the case JSON only, no C header (for streams longer than a C "
                        "header may hold, see docs/vectors.md Limits)")
    p.add_argument("--unity", metavar="DIR", help="also write the set in --out (alone: an existing set, default "
                                                  "vectors) as a Unity test runner DIR/test_vectors_unity.c")
    p.add_argument("--jobs", type=positive_int, default=1, metavar="N",
                   help="worker processes for --all (default 1; output byte-identical to --jobs 1)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute ``fwemu vectors``; returns the exit code."""

    if args.out and not args.check:
        # named before the heavy imports: an interrupt during them also says "previous outputs ... left intact"
        output.declare_output(args.out)

    if args.unity and not (args.all or args.firmware or args.check):
        print(f"wrote {write_unity_runner(args.out or 'vectors', args.unity)}", file=sys.stderr)
        return 0
    if not (args.all or args.firmware or args.check):
        raise UserError("vectors: one of --all, --firmware, --check or --unity is required")
    if args.check:
        if args.unity:
            raise UserError("vectors: --unity goes with --all, --firmware or alone, not with --check")
        problems = vectors.check_set(args.check)
        for line in problems:
            print(f"{args.check}: {line}")
        print(f"{args.check}: {'OK' if not problems else f'{len(problems)} problem(s)'}")
        return 1 if problems else 0
    if not args.out:
        raise UserError("vectors: --out DIR is required")
    if args.all:
        if args.input or args.config or args.no_header:
            raise UserError("vectors: --input/--config/--no-header go with --firmware, not --all (the committed "
                            "matrix is fixed)")
        files = vectors.generate_all(args.out, args.generator, jobs=args.jobs)
        if vectors.LAST_CARRIED:
            print(f"vectors: ../shared/flights absent: kept the {len(vectors.LAST_CARRIED)} committed real-log "
                  f"case(s) unchanged ({', '.join(vectors.LAST_CARRIED)}); everything else regenerated",
                  file=sys.stderr)
    else:
        if not args.input:
            raise UserError("vectors: --firmware needs --input FILE.csv")

        files = vectors_stream.generate_user(args.firmware, args.input, args.out, args.config, args.generator,
                                             header=not args.no_header)
    n_cases = sum(1 for name in files if name.endswith(".json") and name.startswith("cases/"))
    size = sum(data if isinstance(data, int) else len(data) for data in files.values())
    print(f"wrote {n_cases} case(s), {len(files)} files, {size / 1e6:.2f} MB to {args.out}", file=sys.stderr)
    if args.unity:
        print(f"wrote {write_unity_runner(args.out, args.unity)}", file=sys.stderr)
    return 0

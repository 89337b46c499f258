"""Argument types shared by the ``fwemu`` subcommands: values argparse checks before a command runs, so a bad
value is the usual one-line usage error (exit 2) instead of a failure deep inside numpy."""

from __future__ import annotations

import argparse

from firmware_model.flights.evaluation.evalset import resolve_flights


def nonnegative_int(text: str) -> int:
    """An integer >= 0 (seeds: numpy's generators refuse negative seeds)."""
    try:
        value = int(text, 10)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text[:80]!r} is not an integer; allowed: an integer >= 0") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"{value} is out of range; allowed: an integer >= 0")
    return value


def positive_int(text: str) -> int:
    """An integer >= 1 (``--jobs``): 0 and negatives get the same message."""
    try:
        value = int(text, 10)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text[:80]!r} is not an integer; allowed: an integer >= 1") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} is out of range; allowed: an integer >= 1")
    return value


def bounded_int(lo: int, hi: int, what: str = ""):
    """An argparse type: an integer ``lo..hi`` (one message for every value outside; ``what`` names the cap)."""

    def parse(text: str) -> int:
        allowed = f"allowed: an integer {lo:,}..{hi:,}{f' ({what})' if what else ''}"
        try:
            value = int(text, 10)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text[:80]!r} is not an integer; {allowed}") from None
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"{text[:80]} is out of range; {allowed}")
        return value

    return parse


def positive_float(text: str) -> float:
    """A finite number > 0 (clock rates)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"{text} must be a finite number > 0")
    return value


def add_flight_arguments(p: argparse.ArgumentParser) -> None:
    """FLIGHTS and the options that choose/sense them (shared by evaluate and sweep)."""
    p.add_argument("flights", nargs="*", metavar="FLIGHT",
                   help="flight files (any format the readers take), sim:NAME (a simulated scenario; sim:all: "
                        "every scenario, sensed and sampled by --k/--baro/--accel/--no-noise), "
                        "set:NAME (an evaluation set: eval, logs, sim, quick, full, realbaro, ram)")
    p.add_argument("--simulated", action="store_true", help="add every simulated scenario")
    p.add_argument("--logs", action="store_true", help="add every shared real log (../shared/flights)")
    p.add_argument("--k", type=int, action="append", help="sample period 2^-k s (repeatable; default 7); "
                                                         "applies to FLIGHT arguments, not to set: members")
    p.add_argument("--baro", metavar="PRESET", help="barometer preset for FLIGHT arguments")
    p.add_argument("--accel", metavar="PRESET", help="accelerometer preset for FLIGHT arguments")
    p.add_argument("--no-noise", action="store_true", help="noise-free sensors for FLIGHT arguments")
    p.add_argument("--format", help="reader override for FLIGHT files")
    add_reader_arguments(p)
    p.add_argument("--rounding", choices=("floor", "half_up"),
                   help="rounding of every build (default: the program's, half_up for kalman_accel, floor otherwise)")
    p.add_argument("--jobs", "-j", type=positive_int, default=1, metavar="N",
                   help="worker processes (default 1; output identical for any N)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run the flights on a Dask cluster instead: a scheduler ADDRESS (tcp://host:8786) or local:N "
                        "(a LocalCluster of N workers, started for the run); needs the 'montecarlo' extra; output "
                        "identical to --jobs")


def add_reader_arguments(p: argparse.ArgumentParser) -> None:
    """Reader options (issue 21): multi-sensor logs, column maps, the site of altitude-only logs, the flight of a
    multi-flight .eeprom, and what a log that starts after liftoff does with its accelerometer."""
    p.add_argument("--sensor", metavar="NAME",
                   help="sensor of a multi-sensor log (CATS raw: BARO0, BARO1, BARO2; default their median)")
    p.add_argument("--columns", metavar="MAP",
                   help="read a CSV through a column map: time_s=COL,pressure_pa=COL[,accel_g=COL][,state=COL:VALUE] "
                        "(targets: time_s|time_ms, pressure_pa|pressure_hpa|altitude_m|altitude_ft, "
                        "accel_mps2|accel_g, temperature_c, state), or a file with one target=COL per line")
    p.add_argument("--site-altitude", type=float, metavar="M", dest="site_altitude_m",
                   help="launch site altitude above sea level (m) for altitude-only logs (Eggtimer, Raven, an "
                        "altitude column): their pressure comes from the standard atmosphere (default: the log's "
                        "own note of it, else sea level)")
    p.add_argument("--flight", type=int, metavar="N", help="the flight of an AltOS .eeprom holding several "
                                                           "(default: the last)")
    p.add_argument("--late-start", choices=("nominal", "refuse"), default="nominal", dest="late",
                   help="a log that starts after liftoff: its accelerometer's pad value is the sensor's nominal "
                        "1 g (default), or the accelerometer is refused; the report says which")


def specs_from_args(args: argparse.Namespace) -> list:
    return resolve_flights(args.flights, simulated=args.simulated, logs=args.logs, ks=args.k or [7],
                           baro=args.baro, accel=args.accel, noise=not args.no_noise, format=args.format,
                           sensor=args.sensor, columns=args.columns, site_altitude_m=args.site_altitude_m,
                           flight=args.flight, late=args.late)

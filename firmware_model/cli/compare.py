"""``fwemu compare``: fixed (integer model) vs float mirror vs ideal filter on one input, and the floor-bias table.

Statistics per state word and per pair of variants: max |err|, RMS and bias (mean error), in LSB (Q24.8: 1/256
unit, unit = barometer count x BARO_SIGN) and in physical units (m, m/s, m/s^2 via ``units_per_metre``; the
recursive VEL in counts x samples), plus the apogee sample index of each variant.

``--bias-table [--program kalman_baro|kalman_accel]`` prints the bias that floor rounding puts into that Kalman
filter's states vs half_up on a constant-acceleration input (docs/numerics.md, "Floor bias").
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from firmware_model.cli.args import nonnegative_int
from firmware_model.model.float_reference import FloatTrace, ideal_kalman, ideal_recursive, mirror
from firmware_model.model.run import run_model
from firmware_model.model.streams import ACC_PROGRAMS, G0, flight_params_for, read_stream_csv, synthetic_flight
from firmware_model.runtime.errors import UserError
from firmware_model.spec.atmosphere import pressure_pa
from firmware_model.spec.build_constants import build_constants
from firmware_model.spec.config import PROGRAMS, ROUNDINGS, BuildConfig
from firmware_model.spec.tuning import TUNINGS, describe_tuning, load_tuned_config


def register(subparsers: Any) -> None:
    """Add the ``compare`` subcommand to an argparse ``subparsers`` object."""
    p = subparsers.add_parser("compare", help="integer model vs float mirror vs ideal filter error statistics",
                              description=__doc__.splitlines()[0])
    p.add_argument("--config", type=Path, help="build config JSON (flags override its values; a different "
                                               "--program is an error)")
    p.add_argument("--program", choices=PROGRAMS, help="program (default: the config's, else kalman_baro)")
    p.add_argument("--k", type=int, help="sample period 2^-k s (0..10; default: the config's, else 7)")
    p.add_argument("--rounding", choices=ROUNDINGS, help="rounding (default: the config's, else floor)")
    p.add_argument("--tuning", choices=TUNINGS, default="default",
                   help="as fwemu evaluate: default = the BuildConfig defaults; recommended = "
                        "firmware_model.spec.tuning.RECOMMENDED for the program at k (a k without an entry keeps the "
                        "defaults); the config file and the flags override it")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--input", type=Path, help="CSV with an 'adc' column and optionally an 'acc' column")
    src.add_argument("--synthetic", type=nonnegative_int, metavar="SEED",
                     help="a synthetic flight from this seed (default 0)")
    src.add_argument("--bias-table", action="store_true",
                     help="print the floor-vs-half_up bias table of --program (kalman_baro or kalman_accel) "
                          "for k = 5..8 and exit")
    p.set_defaults(func=run)


# ---------------------------------------------------------------------------------------------------- statistics
def error_stats(a: np.ndarray, b: np.ndarray) -> dict[str, float]:
    """max |a - b|, RMS and mean of ``a - b`` (same units as the inputs)."""
    d = np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)
    return {"max": float(np.max(np.abs(d))), "rms": float(np.sqrt(np.mean(d * d))), "bias": float(np.mean(d))}


def _apogee(trace: Any) -> int:
    return int(trace.first_event("APOGEE")) if "EVENTS" in trace.names else -1


def compare(cfg: BuildConfig, adc: np.ndarray, acc: np.ndarray | None) -> dict[str, Any]:
    """Run fixed, mirror and ideal on one stream; return per-pair, per-state statistics (LSB) and apogee indices."""

    consts = build_constants(cfg)
    fixed = run_model(consts, adc, acc)
    mir = mirror(consts, adc, acc)
    if cfg.program in ("kalman_baro", "kalman_accel"):
        ideal = ideal_kalman(cfg, adc, acc)
        states = ("X1", "X2", "X3")
    else:
        est = ideal_recursive(consts, adc)
        ideal = FloatTrace(cfg.program, ("EST",), est[:, None], np.array([est[0]]))
        states = ("EST",)
    variants = {"fixed": fixed, "mirror": mir, "ideal": ideal}
    pairs = (("fixed", "mirror"), ("mirror", "ideal"), ("fixed", "ideal"))
    stats = {f"{p}-{q}": {s: error_stats(variants[p].column(s), variants[q].column(s)) for s in states}
             for p, q in pairs}
    return {"stats": stats, "apogee": {name: _apogee(tr) for name, tr in variants.items()},
            "wrap": (fixed.first_wrap, fixed.wrap_word), "n": int(np.size(adc))}


def _phys(cfg: BuildConfig, state: str) -> tuple[float, str]:
    """(LSB -> physical factor, unit) for a state word."""
    per_m = 256.0 * cfg.units_per_metre
    return {"X1": (1 / per_m, "m"), "X2": (1 / per_m, "m/s"), "X3": (1 / per_m, "m/s^2"),
            "EST": (1 / per_m, "m")}[state]


def format_report(cfg: BuildConfig, result: dict[str, Any]) -> str:
    """Human-readable table of :func:`compare`'s result."""
    lines = [f"program={cfg.program} k={cfg.k} rounding={cfg.rounding} samples={result['n']}",
             f"{'pair':<14}{'state':<6}{'max|err| LSB':>14}{'RMS LSB':>12}{'bias LSB':>12}"
             f"{'max|err|':>12}{'RMS':>12}{'bias':>12}  unit"]
    for pair, per_state in result["stats"].items():
        for state, s in per_state.items():
            f, unit = _phys(cfg, state)
            lines.append(f"{pair:<14}{state:<6}{s['max']:>14.2f}{s['rms']:>12.2f}{s['bias']:>12.2f}"
                         f"{s['max'] * f:>12.4g}{s['rms'] * f:>12.4g}{s['bias'] * f:>12.4g}  {unit}")
    ap = result["apogee"]
    lines.append("apogee sample: " + ", ".join(f"{k}={v}" for k, v in ap.items()))
    first, word = result["wrap"]
    lines.append("wrap-around: " + (f"first at sample {first} in {word}" if first >= 0 else "none"))
    return "\n".join(lines)


# ---------------------------------------------------------------------------------------------------- bias table
#: Programs the floor-bias table is defined for (the Kalman filters; the recursive filters have their own bound).
BIAS_PROGRAMS: tuple[str, ...] = ("kalman_baro", "kalman_accel")


def bias_table(program: str = "kalman_baro", ks: tuple[int, ...] = (5, 6, 7, 8), accel_units: float = 8.0,
               seconds: float = 40.0) -> str:
    """Bias (mean of integer minus float mirror over the second half) of the states of ``program`` on a
    constant-acceleration climb ``h = a t^2 / 2`` metres above a sea-level pad (a = ``accel_units /
    units_per_metre`` m/s^2, the default sensor's counts per metre at the pad) read through the build's sensor
    transfer function (the one its altitude table inverts; default pressure ADC) plus Gaussian noise of 2 counts
    (8 streams, seed 0), for floor and half_up, next to the linear steady-state prediction ``(I - (I-KH)F)^-1
    ((I-KH) u + r)`` with uniform rounding errors (floor: mean -1/2 LSB per shift; half_up: 0) and the prediction
    we started from for the velocity, ``1/2 * 2^k / 256`` units/s = ``2^(k-1)`` LSB.

    (Until this was written the input was ``z = a t^2 / 2 + 1000`` counts into a ``baro_sign = +1`` build, whose
    table maps every count to a pressure below zero, i.e. to one clamped altitude: kalman_baro then tracked a
    constant, and kalman_accel an accelerometer that contradicted it.)

    ``kalman_accel`` also gets a consistent accelerometer stream: at rest (1 g) at sample 0, then 1 g + a, with
    20 counts of noise (seed 1); its prediction adds the second rounded correction per state and the rounding of
    the accelerometer term through the second gain column. The first line names the program and the input."""

    if program not in BIAS_PROGRAMS:
        raise UserError(f"compare --bias-table: the floor-bias table is for {', '.join(BIAS_PROGRAMS)}, "
                        f"not {program}")
    accel = program == "kalman_accel"

    first = BuildConfig(program=program)
    a_mps2 = accel_units / first.units_per_metre
    rows = [f"{program}: h = {a_mps2:.4g}/2 t^2 m above a sea-level pad through the sensor + N(0, 2) counts"
            + (f", acc = 1 g + {a_mps2:.4g} m/s^2 + N(0, 20) counts" if accel else "")
            + f", {seconds:g} s x 8 streams; bias = mean(integer - float mirror) over the second half",
            "",
            "| k | rounding | X1 bias (LSB) | X2 bias (LSB) | X2 bias (m/s) | X3 bias (LSB) "
            "| linear prediction X1, X2, X3 (LSB) | predicted X2, ½·2^k/256 units/s (LSB) |",
            "|---|---|---|---|---|---|---|---|"]
    for k in ks:
        n = int(seconds * 2 ** k)
        t = np.arange(n) / 2 ** k
        rng = np.random.default_rng(0)
        pa_per_count, pa_at_zero = first.baro_transfer           # P = pa_at_zero + pa_per_count * counts
        counts = (np.asarray(pressure_pa(0.5 * a_mps2 * t ** 2)) - pa_at_zero) / pa_per_count
        z = np.clip(np.round(counts[None, :] + rng.normal(0, 2, (8, n))), 0, 65535).astype(np.int64)
        acc = None
        if accel:
            rest = G0 * first.accel_counts_per_mps2
            acc_f = rest + a_mps2 * first.accel_counts_per_mps2 + np.random.default_rng(1).normal(0, 20, (8, n))
            acc_f[:, 0] = rest
            acc = np.clip(np.round(acc_f), -32768, 32767).astype(np.int64)
        for rounding in ROUNDINGS:
            cfg = BuildConfig(program=program, k=k, rounding=rounding)
            consts = build_constants(cfg)
            fx = run_model(consts, z, acc)
            fm = mirror(consts, z, acc)
            half = slice(n // 2, n)
            b = [float(np.mean(fx.column(s)[:, half] - fm.column(s)[:, half])) for s in ("X1", "X2", "X3")]
            dt = 2.0 ** -k
            F = np.array([[1, dt, dt * dt / 2], [0, 1, dt], [0, 0, 1]])
            m = 0.5 if rounding == "floor" else 0.0
            u = -m * np.array([2.0, 1.0, 0.0])
            K1 = np.array([consts.float_gains[g] for g in ("G11", "G21", "G31")])
            if accel:
                K2 = np.array([consts.float_gains[g] for g in ("G12", "G22", "G32")])
                Kf = np.stack([K1, K2], axis=1)
                H = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
                r = -m * 2 * np.ones(3) + K2 * -m      # two rounded corrections per state; rounded acc term
            else:
                Kf = K1[:, None]
                H = np.array([[1.0, 0.0, 0.0]])
                r = -m * np.ones(3)
            IKH = np.eye(3) - Kf @ H
            pred = np.linalg.solve(np.eye(3) - IKH @ F, IKH @ u + r)
            rows.append(f"| {k} | {rounding} | {b[0]:.1f} | {b[1]:.1f} | {b[1] / 256:.3f} | {b[2]:.1f} | "
                        f"{pred[0]:.1f}, {pred[1]:.1f}, {pred[2]:.1f} | {2 ** (k - 1)} |")
    return "\n".join(rows)


def run(args: argparse.Namespace) -> int:
    """Entry point of ``fwemu compare``; prints the report to stdout and returns 0."""
    if args.bias_table:
        if args.input is not None or args.config is not None or args.tuning != "default":
            raise UserError("compare: --bias-table uses its own constant-acceleration input and default builds; "
                            "drop --input/--config/--tuning")
        print(bias_table(args.program or "kalman_baro"))
        return 0
    cfg = load_tuned_config(args.config, {"program": args.program, "k": args.k, "rounding": args.rounding},
                            args.tuning)
    if args.input is not None:
        stream = read_stream_csv(args.input, cfg.baro_word_bits, cfg.k, require_acc=cfg.program in ACC_PROGRAMS)
        true_ap = None
    else:
        stream = synthetic_flight(cfg.k, cfg.baro_bits, 0 if args.synthetic is None else args.synthetic,
                                  flight_params_for(cfg))
        true_ap = stream.truth["apogee_sample"]
    result = compare(cfg, stream.adc, stream.acc)
    print(describe_tuning(cfg.program, cfg.k, args.tuning))
    print(format_report(cfg, result))
    if true_ap is not None:
        print(f"true apogee sample (synthetic): {true_ap}")
    return 0

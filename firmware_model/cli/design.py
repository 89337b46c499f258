"""``fwemu design``: show the gain design and the integer build constants of a build config.

Prints the float (design) gains, the quantized gains (mantissa m, shift s, represented value m/2^s, relative
error), every assembler equate, and the closed-loop poles of the float and quantized filters; ``--json`` prints
:func:`firmware_model.spec.design_report.design_report` instead.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from firmware_model.spec.config import NOISE_MODELS, PROGRAMS, ROUNDINGS, BuildConfig, load_config
from firmware_model.spec.design_report import design_report

#: Units of each gain (multiplying a Q24.8 innovation gives a Q24.8 state).
GAIN_UNITS: dict[str, str] = {
    "G11": "1", "G21": "1/s", "G31": "1/s^2", "G12": "s^2", "G22": "s", "G32": "1",
    "ACC_G": "Q24.8 units/s^2 per count",
}


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``design`` subcommand to the ``fwemu`` parser (contract in :mod:`firmware_model.cli.main`)."""
    p = subparsers.add_parser("design", help="gain design and integer build constants of a build config",
                              description=__doc__.splitlines()[0] if __doc__ else None)
    p.add_argument("--config", metavar="FILE.json", help="build config (JSON object of BuildConfig fields)")
    p.add_argument("--program", choices=PROGRAMS, help="override the program")
    p.add_argument("--k", type=int, metavar="K", help="override k (sample period 2^-k s, 0..10)")
    p.add_argument("--rounding", choices=ROUNDINGS, help="override the rounding of every right shift")
    p.add_argument("--ratio", type=float, metavar="X", help="override R/q (measurement over process noise)")
    p.add_argument("--noise-model", choices=NOISE_MODELS, help="override the process-noise model")
    p.add_argument("--json", action="store_true", help="print the full report as JSON")
    p.set_defaults(func=run)


def config_from_args(args: argparse.Namespace) -> BuildConfig:
    """The build config named by ``--config`` (default config when absent) with the command-line overrides
    applied (flags override the file; a different program is an error: :func:`firmware_model.spec.config.load_config`);
    invalid values raise :class:`~firmware_model.runtime.errors.UserError` naming the field."""
    overrides: dict[str, Any] = {field: getattr(args, attr, None) for attr, field in (
        ("program", "program"), ("k", "k"), ("rounding", "rounding"), ("ratio", "ratio"),
        ("noise_model", "noise_model"))}
    return load_config(args.config, overrides)


def _fmt_pole(p: dict[str, float]) -> str:
    sign = "+" if p["im"] >= 0 else "-"
    return f"{p['re']:.9f} {sign} {abs(p['im']):.9f}j  |{p['abs']:.9f}|"


def format_report(report: dict[str, Any]) -> str:
    """Human-readable text of a :func:`design_report` dict."""
    cfg = report["config"]
    lines = [f"program {cfg['program']}  k={cfg['k']} (dt={report['dt']:g} s)  rounding={cfg['rounding']}"]
    if "noise" in report:
        lines.append(f"noise model {cfg['noise_model']}  ratio R/q={cfg['ratio']:g}  q={report['noise']['q']:.6g}  "
                     f"baro_sigma={cfg['baro_sigma']:g} counts")
    if report["gains"]:
        lines.append("")
        lines.append(f"{'gain':<6} {'units':<26} {'float':>22} {'m':>7} {'s':>3} {'m/2^s':>22} {'rel.error':>11}")
        for name, g in report["gains"].items():
            lines.append(f"{name:<6} {GAIN_UNITS.get(name, ''):<26} {report['float_gains'][name]:>22.15g} "
                         f"{g['m']:>7d} {g['s']:>3d} {g['value']:>22.15g} {g['rel_error']:>11.3e}")
    lines.append("")
    lines.append("equates:")
    for name, value in report["equates"].items():
        lines.append(f"  {name:<10} EQU {value}")
    if "poles" in report:
        lines.append("")
        lines.append("closed-loop poles of (I-KH)F (float design / quantized gains):")
        for pf, pq in zip(report["poles"], report["poles_quantized"]):
            lines.append(f"  {_fmt_pole(pf)}    {_fmt_pole(pq)}")
        lines.append(f"steady-state sigma (a posteriori): alt {report['sigma_post'][0]:.4g} units, "
                     f"vel {report['sigma_post'][1]:.4g} units/s, acc {report['sigma_post'][2]:.4g} units/s^2")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Entry point of ``fwemu design``; returns the exit code."""
    report = design_report(config_from_args(args))
    if args.json:
        json.dump(report, sys.stdout, indent=2)
        sys.stdout.write("\n")
    else:
        print(format_report(report))
    return 0

"""``fwemu simulate``: write a simulated flight as a generic CSV with truth columns (``time_s, pressure_pa,
accel_mps2, true_altitude_m, true_velocity_mps, true_accel_mps2``; the exact true apogee in the header comments),
from a named scenario (:mod:`firmware_model.flights.simulate.scenarios`) or from 1-DOF parameters
(:mod:`firmware_model.flights.simulate.sim1dof`). Deterministic: the same arguments give the same bytes."""

from __future__ import annotations

import argparse
from pathlib import Path

from firmware_model.cli.args import positive_float
from firmware_model.flights.simulate import scenarios
from firmware_model.flights.readers.generic import generic_csv
from firmware_model.flights.simulate.motors import load_motor
from firmware_model.flights.simulate.sim1dof import Launch, Rocket, simulate_1dof
from firmware_model.runtime.errors import UserError
from firmware_model.runtime.output import write_file


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]  # argparse's private class is not generic at runtime
    """Add the ``simulate`` subcommand."""
    p = subparsers.add_parser("simulate", help="write a simulated flight (generic CSV with truth columns)",
                              description="--scenario NAME (see --list), or a 1-DOF rocket: --motor, --dry-mass, "
                                          "--diameter (and launch options).")
    p.add_argument("--scenario", metavar="NAME", help="a named scenario")
    p.add_argument("--list", action="store_true", help="list the scenarios (name, class, description) and exit")
    p.add_argument("--motor", help="1-DOF: motor name (see the list in the error for an unknown name)")
    p.add_argument("--dry-mass", type=positive_float, metavar="KG", help="1-DOF: mass without propellant (kg)")
    p.add_argument("--diameter", type=positive_float, metavar="M", help="1-DOF: reference diameter (m)")
    p.add_argument("--cd-scale", type=positive_float, default=1.0, help="1-DOF: drag-curve scale (default 1)")
    p.add_argument("--site-altitude", type=float, default=0.0, metavar="M", help="1-DOF: launch site altitude (m)")
    p.add_argument("--pad", type=positive_float, default=2.0, metavar="S", help="1-DOF: seconds on the pad (2)")
    p.add_argument("--drogue-delay", type=float, default=0.0, metavar="S", help="1-DOF: drogue delay (s)")
    p.add_argument("--rate", type=positive_float, default=500.0, metavar="HZ", help="1-DOF: record rate (500 Hz)")
    p.add_argument("--name", help="1-DOF: flight name (default: derived)")
    p.add_argument("-o", "--out", type=Path, metavar="FILE.csv", help="output CSV")
    p.set_defaults(func=run_simulate)


def _one_dof(args: argparse.Namespace):
    missing = [opt for opt, v in (("--motor", args.motor), ("--dry-mass", args.dry_mass),
                                  ("--diameter", args.diameter)) if v is None]
    if missing:
        raise UserError(f"simulate: give --scenario NAME, or a 1-DOF rocket (missing {', '.join(missing)})")
    name = args.name or f"1dof-{args.motor}-{args.dry_mass:g}kg-{args.diameter:g}m"
    rocket = Rocket(name=name, dry_mass_kg=args.dry_mass, diameter_m=args.diameter, motor=load_motor(args.motor),
                    cd_scale=args.cd_scale)
    launch = Launch(site_altitude_m=args.site_altitude, pad_s=args.pad, drogue_delay_s=args.drogue_delay,
                    record_hz=args.rate)
    return simulate_1dof([rocket], launch, names=[name])[0]


def run_simulate(args: argparse.Namespace) -> int:
    if args.list:
        cat = scenarios.scenario_catalogue()
        for name in scenarios.scenario_names():
            info = cat[name]
            print(f"{name:30s} {info['mach_class']:10s} {info['simulator']:8s} {info['description']}")
        return 0
    if args.out is None:
        raise UserError("simulate: -o FILE.csv is required (or --list)")
    if args.scenario:
        one_dof_given = [o for o, v in (("--motor", args.motor), ("--dry-mass", args.dry_mass),
                                        ("--diameter", args.diameter)) if v is not None]
        if one_dof_given:
            raise UserError(f"simulate: --scenario and 1-DOF options ({', '.join(one_dof_given)}) exclude each other")
        record = scenarios.simulate_scenario(args.scenario)
    else:
        record = _one_dof(args)

    write_file(args.out, generic_csv(record))
    tr = record.truth
    extra = "" if tr is None or tr.apogee_time_s is None else (
        f": true apogee {tr.apogee_time_s:.3f} s, {tr.apogee_altitude_m:.1f} m AGL")
    print(f"wrote {args.out} ({record.n} rows{extra})")
    return 0

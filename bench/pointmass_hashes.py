"""sha256 of the point-mass simulators' outputs, to show a refactor of the integrators keeps their bytes
(issue 34 item 1; docs/flights-sim.md, "The point-mass integration").

    python -m bench.pointmass_hashes [--engine kernel|python|numpy] [--quick]

Prints one line per 1-DOF scenario (the raw ``simulate_1dof`` record: truth z/v/a, pressure, accelerometer and
the provenance summary), one for a seeded batch of random 1-DOF flights, and one for a small Monte Carlo batch
through :func:`firmware_model.flights.montecarlo.sim.simulate_batch` (wind, inclined rail, temperature offset),
then the hash of all lines. ``--quick`` takes the first 4 scenarios and 4 random flights (for the uncompiled
engines). The Monte Carlo CLI outputs are hashed separately (see docs/flights-sim.md).
"""

from __future__ import annotations

import argparse
import hashlib
import json

import numpy as np

from firmware_model.flights.montecarlo.sim import drag_table, simulate_batch
from firmware_model.flights.simulate.motors import default_drag_curve, load_motor
from firmware_model.flights.simulate.scenarios import get_scenario, scenario_names
from firmware_model.flights.simulate.sim1dof import Box, Launch, rocket_from_unit, simulate_1dof
from tests.support.sim1dof_numpy import simulate_numpy


def _record_hash(rec) -> str:
    h = hashlib.sha256()
    for a in (rec.truth.altitude_m, rec.truth.velocity_mps, rec.truth.accel_mps2, rec.time_s, rec.pressure_pa,
              rec.accel_mps2):
        h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
    h.update(json.dumps(rec.provenance["summary"], sort_keys=True).encode())
    return h.hexdigest()


def _mc_batch_hash() -> str:
    """A small 3-DOF batch: 6 flights of a K400C with wind, wind shear, inclined rails, drogue delays and a
    temperature offset spread over the parameters (:data:`P_COLS` order)."""
    motor = load_motor("K400C")
    mach, cd = default_drag_curve()
    rows = []
    for i in range(6):
        rows.append([3.0 + 0.3 * i, motor.propellant_mass_kg, 0.8 + 0.1 * i, 0.9 + 0.05 * i, 0.9 + 0.05 * i,
                     np.pi * 0.1 ** 2 / 4, 0.4, 200.0 * i, 288.15 / (288.15 + 5.0 * i - 10.0), 2.0 * i,
                     0.7 * i, 0.14 * (i % 3), np.radians(2.0 * i), 1.5 + 0.5 * i, 0.5 * (i % 2), 3.0])
    out = simulate_batch(np.array(rows), motor.time_s, motor.thrust_n, drag_table(mach, cd), 100.0, 1000.0, 120.0)
    h = hashlib.sha256()
    for k in sorted(out):
        h.update(k.encode())
        h.update(np.ascontiguousarray(out[k]).tobytes())
    return h.hexdigest()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--engine", default="kernel", choices=("kernel", "python", "numpy"))
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args()
    names = [s for s in scenario_names() if get_scenario(s).simulator == "1dof"]
    if a.quick:
        names = names[:4]
    lines = []
    for name in names:
        s = get_scenario(name)
        rec = _simulate(a.engine, s.build_rocket(), s.build_launch(), names=[name])[0]
        lines.append(f"{_record_hash(rec)}  1dof {name}")
    n = 4 if a.quick else 24
    h = hashlib.sha256()
    for rec in _random(n, a.engine):
        h.update(_record_hash(rec).encode())
    lines.append(f"{h.hexdigest()}  1dof random_flights({n}, seed=11)")
    lines.append(f"{_mc_batch_hash()}  montecarlo simulate_batch (6 flights)")
    for line in lines:
        print(line)
    print(hashlib.sha256("\n".join(lines).encode()).hexdigest(), " all")


def _random(n: int, engine: str):
    """The rockets and launches of ``random_flights(n, seed=11)``, through ``engine``."""
    rng = np.random.default_rng(11)
    box, rockets, launches = Box(), [], []
    while len(rockets) < n:
        u = rng.random(8)
        r = rocket_from_unit(u, box, name=f"random-11-{len(rockets)}")
        if r is not None:
            rockets.append(r)
            launches.append(Launch(site_altitude_m=float(box.site_altitude_m[0]
                                                         + (box.site_altitude_m[1] - box.site_altitude_m[0]) * u[7])))
    return _simulate(engine, rockets, launches, provenance={"seed": 11})


def _simulate(engine: str, *args, **kw):
    """simulate_1dof through ``engine``; "numpy": the test oracle of tests/support/sim1dof_numpy.py."""
    if engine == "numpy":
        return simulate_numpy(*args, **kw)
    return simulate_1dof(*args, engine=engine, **kw)


if __name__ == "__main__":
    main()

"""Speed of the 1-DOF flight simulator (firmware_model.flights.simulate.sim1dof): its two engines and the numpy
oracle side by side, in one run.

``make bench`` runs this file. Flights are drawn by ``random_flights``' parameter box (subsonic K400C/K828FJ
rockets, ~8-25 s of flight, 1 kHz internal RK4 step, recorded at ``--record-hz``). Measured through the public
``simulate_1dof`` (preparation and FlightRecord construction included):

* flights/s on **one flight** per call: ``kernel`` (numba), ``python`` (the kernel's source uncompiled), ``numpy``
  (the vectorised integrator of tests/support/sim1dof_numpy.py, the engine sim1dof had before issue 34 and now
  the tests' oracle, with a batch of one);
* flights/s on **one call of ``--batch`` flights**: ``kernel`` (a loop over compiled per-flight calls) and
  ``numpy`` (all flights integrated together, arrays over flights);
* that all give the **same bytes** for every flight measured.

Steady state is the best of ``--reps`` calls after a warm-up call. Start-up is measured apart in a fresh process:
the import of sim1dof and the first call (loading numba's cached machine code, or compiling it when the cache is
cold). No assertions on speed; the load average is printed (the machine is shared).
"""

from __future__ import annotations

import argparse
import hashlib
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

from firmware_model.runtime.blas_threads import single_threaded_blas  # noqa: E402 - with the single_threaded_blas() call below, which comes before numpy loads

single_threaded_blas()  # before numpy loads: no OpenBLAS pool busy-waiting on the cores being measured

import numpy as np  # noqa: E402 - imported after single_threaded_blas(): numpy must not load first

from firmware_model.flights.simulate import sim1dof as s1  # noqa: E402 - imported after single_threaded_blas(): numpy must not load first
from tests.support.sim1dof_numpy import simulate_numpy  # noqa: E402 - imported after single_threaded_blas(): numpy must not load first

_STARTUP = """
import time
t0 = time.perf_counter()
from firmware_model.flights.simulate import sim1dof as s1
from firmware_model.flights.simulate.motors import load_motor
t1 = time.perf_counter()
s1.simulate_1dof(s1.Rocket("x", 8.0, 0.1, load_motor("K400C")), s1.Launch(record_hz=100.0))
t2 = time.perf_counter()
print(f"{t1 - t0:.3f} {t2 - t1:.3f}")
"""


def _digest(recs) -> str:
    h = hashlib.sha256()
    for r in recs:
        for a in (r.pressure_pa, r.accel_mps2, r.truth.altitude_m, r.truth.velocity_mps):
            h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def _simulate(engine: str, rockets, launches):
    """simulate_1dof through ``engine``; "numpy": the oracle of tests/support/sim1dof_numpy.py."""
    if engine == "numpy":
        return simulate_numpy(rockets, launches)
    return s1.simulate_1dof(rockets, launches, engine=engine)


def _best(fn, reps: int) -> tuple[float, object]:
    out = fn()
    best = float("inf")
    for _ in range(reps):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--reps", type=int, default=2)
    ap.add_argument("--record-hz", type=float, default=100.0)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    print(f"load average before: {os.getloadavg()}")
    if not s1.HAVE_NUMBA:
        print("numba is not installed: the kernel engine is unavailable (install the 'fast' extra)")
    launch = s1.Launch(record_hz=a.record_hz)
    # the rockets random_flights(batch, seed) draws (the same unit draws and box)
    rng = np.random.default_rng(a.seed)
    rk, lc = [], []
    while len(rk) < a.batch:
        u = rng.random(8)
        r = s1.rocket_from_unit(u, s1.Box(), name=f"b{len(rk)}")
        if r is None:
            continue
        rk.append(r)
        lc.append(s1.Launch(record_hz=a.record_hz, site_altitude_m=float(1500.0 * u[7])))
    secs = sum(r.truth.apogee_time_s + 5.0 for r in _simulate("kernel" if s1.HAVE_NUMBA else "numpy", rk, lc))
    print(f"{a.batch} flights, {secs:.0f} s of flight in all (mean {secs / a.batch:.1f} s), record {a.record_hz:g} Hz,"
          f" internal step {s1._step_count(launch)[1] * 1e3:g} ms")

    engines = ["python", "numpy"] + (["kernel"] if s1.HAVE_NUMBA else [])
    single: dict[str, float] = {}
    digests = {}
    for e in engines:
        t, out = _best(lambda e=e: _simulate(e, rk[0], lc[0]), a.reps)
        single[e] = 1.0 / t
        digests.setdefault("single", set()).add(_digest(out))
    batch: dict[str, float] = {}
    for e in [x for x in engines if x != "python"]:
        t, out = _best(lambda e=e: _simulate(e, rk, lc), max(1, a.reps - 1))
        batch[e] = a.batch / t
        digests.setdefault("batch", set()).add(_digest(out))
    print("\nflights/s (steady state, best of reps)")
    for e, v in single.items():
        print(f"  one flight per call   {e:7s} {v:10.2f}")
    for e, v in batch.items():
        print(f"  {a.batch:4d} flights per call {e:7s} {v:10.2f}")
    if "kernel" in single:
        print(f"ratios: kernel/python (one flight) {single['kernel'] / single['python']:.0f}x, "
              f"kernel/numpy (one flight) {single['kernel'] / single['numpy']:.0f}x, "
              f"kernel/numpy ({a.batch} flights) {batch['kernel'] / batch['numpy']:.1f}x")
    print(f"numpy batch/single speed-up {batch['numpy'] / single['numpy']:.1f}x")
    same = all(len(v) == 1 for v in digests.values())
    print(f"identical bytes across engines: {'yes' if same else 'NO'}")

    env = dict(os.environ, PYTHONPATH=str(ROOT))
    res = subprocess.run([sys.executable, "-c", _STARTUP], capture_output=True, text=True, env=env, cwd=ROOT)
    if res.returncode == 0:
        imp, first = res.stdout.split()
        print(f"start-up in a fresh process: import {imp} s, first simulate_1dof call {first} s "
              f"(numba cache {'warm' if s1.HAVE_NUMBA else 'n/a'})")
    print(f"load average after: {os.getloadavg()}")
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())

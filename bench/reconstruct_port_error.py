"""The reconstruction's vertical channel on the 24 simulated flights with a real barometer's errors
(docs/reconstruction.md, "Real barometers").

    PYTHONPATH=$PWD python bench/reconstruct_port_error.py [--out build/reconstruct-port] [--seed 0] [--only NAME ...]

Per flight: the `chari` IMU, no GPS (what a real log gives), and the project's barometer (MS5607, 100 Hz) whose
pressure gets :func:`~firmware_model.flights.simulate.pressure_errors.real_flight_errors` with a model drawn from
``BARO_ERROR_RANGES`` (a static-port error of 0-0.06 of the dynamic pressure, the transonic dip, the shock jump;
no bursts or ejection spike: these flights deploy nothing). The smoother's apogee time against truth, for the
3-axis filter (vertical-imu) and the axial-as-vertical one (vertical-axial), each run once without the port-error
model (``baro_port_cp`` 0: the barometer's white noise only, as before) and once with it (the real-log setting,
``BARO_PORT_CP``). The first figure is how often the apogee is more than 1 s off.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from firmware_model.flights.simulate.pressure_errors import draw_error_model, real_flight_errors
from firmware_model.flights.record import FlightRecord
from firmware_model.flights.reconstruct.apogee import velocity_zero_crossing
from firmware_model.flights.reconstruct.flightset import flight_set
from firmware_model.flights.reconstruct.run import BARO_PORT_CP
from firmware_model.flights.reconstruct.sensors import baro_altitude, geometric_to_geopotential, imu_preset
from firmware_model.flights.reconstruct.simulated import sensed_flight
from firmware_model.flights.reconstruct.truth import truth_run
from firmware_model.flights.reconstruct.ukf import Measurements, align, run_ukf, unflat
from firmware_model.flights.reconstruct.vertical import run_vertical
from firmware_model.runtime.errors import UserError
from firmware_model.runtime.output import write_file
from firmware_model.spec import atmosphere as atm

G = 9.80665


def _apogee(t, z, vz, Pz, Pv, where) -> float | None:
    sz = np.sqrt(np.clip(Pz, 0, None))
    sv = np.sqrt(np.clip(Pv, 0, None))
    try:
        return velocity_zero_crossing(t, z, vz, sz, sv, where=where).time_s
    except UserError:
        return None


def run_flight(case, seed: int) -> dict:
    truth = truth_run(case)
    s = sensed_flight(truth, imu_preset("chari", accel_range=32 * G), None, seed=seed)
    pres = np.asarray(s.notes["pressure_pa"], dtype=np.float64)
    ok = np.isfinite(pres)
    z = truth.pos[s.truth_idx, 2]
    c = np.asarray(atm.speed_of_sound_mps(geometric_to_geopotential(z + truth.site_asl_m)), dtype=np.float64)
    mach = np.linalg.norm(truth.vel[s.truth_idx], axis=1) / c
    rng = np.random.default_rng(1000 + seed)
    model = draw_error_model(rng)
    rec = FlightRecord(name=case.name, time_s=s.t[ok], pressure_pa=pres[ok], ground_pressure_pa=float(pres[ok][0]),
                       provenance={"source": f"reconstruct:{case.name}", "format": "simulation"})
    bad = real_flight_errors(rec, mach[ok], model, seed=seed)
    p0 = float(np.median(pres[ok][s.t[ok] < truth.t[0] + 3.0]))
    baro = np.full(s.t.size, np.nan)
    baro[ok] = baro_altitude(np.asarray(bad.pressure_pa, dtype=np.float64), p0)
    err = baro[ok] - baro_altitude(pres[ok], p0)
    meas = Measurements(gps=None, baro=baro, baro_sigma=s.meas.baro_sigma)
    out = {"name": case.name, "peak_mach": float(mach.max()), "truth_apogee_s": truth.apogee_time_s,
           "baro_error_min_m": float(err.min()), "baro_error_max_m": float(err.max()), "model": model.to_dict()}
    t = s.t
    al = align(s.imu.accel, s.imu.gyro, s.n_pad, s.noise, s.heading_rad, truth.site_asl_m,
               heading_axis=s.notes.get("heading_axis", "x"))
    f_ax = s.imu.accel[:, 2]
    for label, cp in (("white", 0.0), ("port", BARO_PORT_CP)):
        t0 = time.process_time()
        run = run_ukf(t, s.imu.accel, s.imu.gyro, s.imu.saturated, meas, al, replace(s.noise, baro_port_cp=cp),
                      truth.site_asl_m, earth_rate=s.notes.get("earth_rate"))
        X = unflat(run.xs)
        a = _apogee(t, X["r"][:, 2], X["v"][:, 2], run.Ps[:, 2, 2], run.Ps[:, 5, 5], case.name)
        out[f"imu_{label}_err_s"] = None if a is None else a - truth.apogee_time_s
        out[f"imu_{label}_rejected"] = run.rejected
        v = run_vertical(t, f_ax, baro, s.meas.baro_sigma, truth.site_asl_m, s.n_pad, baro_port_cp=cp)
        a = _apogee(t, v.xs[:, 0], v.xs[:, 1], v.Ps[:, 0, 0], v.Ps[:, 1, 1], case.name)
        out[f"axial_{label}_err_s"] = None if a is None else a - truth.apogee_time_s
        out[f"cpu_{label}_s"] = time.process_time() - t0
    return out


def _stats(errs: list) -> dict:
    e = np.array([np.inf if x is None else abs(x) for x in errs])
    fin = e[np.isfinite(e)]
    return {"median_abs_s": float(np.median(e)), "worst_abs_s": float(e.max()), "over_1s": int((e > 1.0).sum()),
            "over_0.1s": int((e > 0.1).sum()), "no_apogee": int((~np.isfinite(e)).sum()),
            "worst_finite_s": float(fin.max()) if fin.size else None}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("build/reconstruct-port"))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--only", nargs="*")
    a = ap.parse_args(argv)
    cases = [c for c in flight_set() if not a.only or c.name in a.only]
    rows = []
    for i, c in enumerate(cases):
        r = run_flight(c, a.seed + i)
        rows.append(r)
        f = (lambda x: "   none" if x is None else f"{x:+7.3f}")
        print(f"{c.name:32s} M{r['peak_mach']:.2f} baro err {r['baro_error_min_m']:+7.0f}.."
              f"{r['baro_error_max_m']:+5.0f} m"
              f"  imu {f(r['imu_white_err_s'])} -> {f(r['imu_port_err_s'])}"
              f"  axial {f(r['axial_white_err_s'])} -> {f(r['axial_port_err_s'])}", flush=True)
    summary = {k: _stats([r[k] for r in rows]) for k in ("imu_white_err_s", "imu_port_err_s", "axial_white_err_s",
                                                          "axial_port_err_s")}
    summary["baro_port_cp"] = BARO_PORT_CP
    summary["flights"] = len(rows)
    a.out.mkdir(parents=True, exist_ok=True)
    write_file(a.out / "port-error.json", json.dumps({"summary": summary, "flights": rows}, indent=1,
                                                    default=float) + "\n")
    print(json.dumps(summary, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

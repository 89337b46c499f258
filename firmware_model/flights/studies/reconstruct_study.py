"""The consistency study over the simulated flight set (bench/reconstruct_consistency.py runs it; docs/
reconstruction.md reports it): per flight, the filter's and the smoother's errors against truth, the share of
samples inside +-2 sigma, NEES, the smoother's apogee time against truth beside the barometric parabola's, and what
kalman_accel's axial-as-vertical assumption costs on the same flight."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from firmware_model.flights.evaluation.evaluate import evaluate_flight
from firmware_model.flights.evaluation.methods import METHODS
from firmware_model.flights.evaluation.setup import FlightSpec
from firmware_model.flights.record import FlightRecord, Truth
from firmware_model.flights.reconstruct.apogee import velocity_zero_crossing
from firmware_model.flights.reconstruct.rotation import tilt_deg
from firmware_model.flights.reconstruct.sensors import (GpsModel, ImuModel, geometric_to_geopotential)
from firmware_model.flights.reconstruct.simulated import (errors, inside_2sigma, reconstruct_sensed,
                                                          sensed_flight)
from firmware_model.flights.reconstruct.truth import Truth6, TruthCase, truth_run
from firmware_model.flights.reconstruct.ukf import unflat
from firmware_model.flights.reference.apogee_reference import reference_apogee
from firmware_model.spec import atmosphere as atm


def kalman_accel_cost(truth: Truth6, name: str, k: int = 7) -> dict[str, Any]:
    """kalman_accel (bit-exact model, default tuning, noisy default sensors, seed 0) fed the axial specific force
    (what a one-axis accelerometer reads) and, on the same flight, the true vertical specific force; the difference
    of their detection times is what the axial-as-vertical assumption costs."""
    idx = slice(None)
    t = truth.t[idx]
    z_asl = truth.pos[idx, 2] + truth.site_asl_m
    p = np.asarray(atm.pressure_pa(geometric_to_geopotential(z_asl)), dtype=np.float64)
    alt = geometric_to_geopotential(z_asl) - geometric_to_geopotential(truth.pos[0, 2] + truth.site_asl_m)
    tr = Truth(altitude_m=alt, velocity_mps=truth.vel[idx, 2], accel_mps2=truth.acc[idx, 2],
               apogee_time_s=truth.apogee_time_s, apogee_altitude_m=truth.apogee_altitude_m)
    out = {}
    for label, acc in (("axial", truth.f_body[idx, 2]), ("vertical", truth.acc[idx, 2] + 9.80665)):
        rec = FlightRecord(name=name, time_s=t, pressure_pa=p, accel_mps2=np.asarray(acc, float),
                           ground_pressure_pa=float(p[0]), truth=tr,
                           provenance={"source": f"reconstruct:{name}", "format": "simulation"})
        res = evaluate_flight(FlightSpec(source=f"reconstruct:{name}", k=k, noise=True, seed=0),
                              [METHODS["kalman_accel"]], record=rec)
        out[label] = res.error("kalman_accel")
    return out


def run_case(case: TruthCase, imu: ImuModel, gps: GpsModel | None, seed: int = 0, with_cost: bool = False,
             accel_scale: float = 1.0, gyro_sign: float = 1.0) -> dict[str, Any]:
    """One flight of the study; ``accel_scale``/``gyro_sign``: a fault put into the IMU data after the sensor
    model (the teeth tests: the filter is not told)."""
    truth = truth_run(case)
    s = sensed_flight(truth, imu, gps, seed=seed)
    acc = s.imu.accel * accel_scale
    gyr = s.imu.gyro * gyro_sign
    t0 = time.process_time()
    run = reconstruct_sensed(s, truth.site_asl_m, accel=acc, gyro=gyr)
    cpu = time.process_time() - t0
    E = errors(run, s, truth)
    flight = s.t >= 0.0
    out: dict[str, Any] = {"name": case.name, "mach_class": case.mach_class, "max_mach": truth.meta["max_mach"],
                           "apogee_truth_s": truth.apogee_time_s, "apogee_m": truth.apogee_altitude_m,
                           "n_steps": int(s.t.size), "cpu_s": cpu, "rejected": run.rejected}
    for k in ("f", "s"):
        e = getattr(E, k)
        out[f"inside_{k}"] = inside_2sigma(e, flight)
        out[f"nees_{k}"] = e["nees"]
    out["t"] = s.t
    xs = unflat(run.xs)
    sd = np.sqrt(np.einsum("nii->ni", run.Ps))
    ap = velocity_zero_crossing(s.t, xs["r"][:, 2], xs["v"][:, 2], sd[:, 2], sd[:, 5], where=case.name)
    out["smoother_apogee"] = ap.to_dict()
    out["smoother_err_s"] = ap.time_s - truth.apogee_time_s
    xf = unflat(run.xf)
    sf = np.sqrt(np.einsum("nii->ni", run.Pf))
    apf = velocity_zero_crossing(s.t, xf["r"][:, 2], xf["v"][:, 2], sf[:, 2], sf[:, 5], source="filter")
    out["filter_err_s"] = apf.time_s - truth.apogee_time_s
    out["filter_sigma_s"] = apf.sigma_s
    okb = np.isfinite(s.meas.baro)
    rec = FlightRecord(name=case.name, time_s=s.t[okb], pressure_pa=s.notes["pressure_pa"][okb],
                       provenance={"source": f"reconstruct:{case.name}"})
    par = reference_apogee(rec)
    out["parabola"] = {"time_s": par.time_s, "uncertainty_s": par.uncertainty_s}
    out["parabola_err_s"] = par.time_s - truth.apogee_time_s
    out["tilt_max_deg"] = float(tilt_deg(truth.quat[truth.t <= truth.apogee_time_s]).max())
    out["tilt_at_apogee_deg"] = float(np.interp(truth.apogee_time_s, truth.t, tilt_deg(truth.quat)))
    if with_cost:
        out["kalman_accel_err_s"] = kalman_accel_cost(truth, case.name)
    return out


def nees_band_share(results: list[dict[str, Any]], which: str, dof: int = 9, p: float = 0.95
                    ) -> tuple[float, tuple[float, float], np.ndarray]:
    """Share of epochs (from ignition to the shortest flight's end, every IMU step) where the NEES averaged over
    the flights lies in its two-sided ``p`` chi-square band (dof x flights degrees of freedom)."""
    from scipy.stats import chi2
    n = len(results)
    end = min(float(r["t"][-1]) for r in results)
    grid = results[0]["t"]
    grid = grid[(grid >= 0) & (grid <= end)]
    avg = np.mean([np.interp(grid, r["t"], r[f"nees_{which}"]) for r in results], axis=0)
    lo, hi = chi2.ppf([(1 - p) / 2, (1 + p) / 2], dof * n) / n
    return float(np.mean((avg >= lo) & (avg <= hi))), (float(lo), float(hi)), avg

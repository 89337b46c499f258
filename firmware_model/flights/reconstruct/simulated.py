"""Simulated reconstruction runs: truth -> sensors -> filter and smoother -> errors against truth.

:func:`sensed_flight` turns a :class:`~.truth.Truth6` into what the filter sees (IMU, GPS and barometer on the
IMU's steps, the pad's heading with its error drawn from the filter's prior); :func:`reconstruct_truth` runs it and
:func:`errors` compares the result with truth (position, velocity, attitude errors and their sigmas, NEES).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from math import radians
from typing import Any

import numpy as np

from firmware_model.flights.reconstruct.rotation import attitude_error, rotate, tilt_deg
from firmware_model.flights.reconstruct.sensors import (GpsModel, ImuData, ImuModel, baro_altitude, baro_samples,
                                                        baro_sigma_m, gps_samples, imu_samples)
from firmware_model.flights.reconstruct.truth import Truth6
from firmware_model.flights.reconstruct.ukf import FilterNoise, Measurements, Run, align, run_ukf, unflat
from firmware_model.flights.inputs.sensors import BaroSensor

BARO_DEFAULT = BaroSensor.preset("ms5607", noise_pa=3.0)


@dataclass
class Sensed:
    t: np.ndarray
    imu: ImuData
    meas: Measurements
    n_pad: int
    heading_rad: float
    noise: FilterNoise
    truth_idx: np.ndarray              # truth grid index of each IMU step
    notes: dict[str, Any] = field(default_factory=dict)


def filter_noise_for(imu: ImuModel, gps: GpsModel | None, heading_sigma_deg: float = 5.0) -> FilterNoise:
    """The filter's assumptions from the sensors' datasheet figures (never from the drawn values)."""
    return FilterNoise(accel_noise=imu.accel_noise, accel_lsb=imu.accel_lsb,
                       accel_bias_sigma=max(imu.accel_bias, 0.01), accel_scale_sigma=imu.accel_scale,
                       gyro_noise=imu.gyro_noise, gyro_lsb=imu.gyro_lsb,
                       gyro_bias_sigma=max(imu.gyro_bias, radians(0.01)), gyro_scale_sigma=imu.gyro_scale,
                       accel_range=imu.accel_range, heading_sigma=radians(heading_sigma_deg),
                       accel_bias_walk=max(imu.accel_bias_walk, 1e-5), gyro_bias_walk=max(imu.gyro_bias_walk, 1e-7),
                       gps_sigma=(gps.sigma_h_m, gps.sigma_h_m, gps.sigma_v_m) if gps is not None else (4, 4, 4))


def heading_axis_of(truth: Truth6) -> str:
    """"z" for an inclined rail (more than 1 deg from vertical: its azimuth is what a team measures), else "x"."""
    return "z" if tilt_deg(truth.quat[0]) > 1.0 else "x"


def heading_of(truth: Truth6, axis: str) -> float:
    """The true pad heading in :func:`~.ukf.align`'s convention: the azimuth of body ``axis``."""
    ref = rotate(truth.quat[0], np.array([0.0, 0.0, 1.0] if axis == "z" else [1.0, 0.0, 0.0]))
    return float(np.arctan2(ref[0], ref[1]))


def sensed_flight(truth: Truth6, imu: ImuModel, gps: GpsModel | None, baro: BaroSensor | None = BARO_DEFAULT,
                  baro_hz: float = 100.0, seed: int = 0, heading_sigma_deg: float = 5.0,
                  pad_align_s: float = 3.0) -> Sensed:
    rng = np.random.default_rng(seed)
    data = imu_samples(truth, imu, rng)
    t = data.t
    dt_truth = float(truth.t[1] - truth.t[0])
    tidx = np.rint((t - truth.t[0]) / dt_truth).astype(int)
    step_of = {int(i): k for k, i in enumerate(tidx)}
    n = t.size
    gps_arr = None
    if gps is not None:
        tg, pg = gps_samples(truth, gps, rng)
        gps_arr = np.full((n, 3), np.nan)
        for ti, p in zip(np.rint((tg - truth.t[0]) / dt_truth).astype(int), pg):
            k = step_of.get(int(ti))
            if k is not None:
                gps_arr[k] = p
    baro_arr = sig = pres = None
    if baro is not None:
        tb, pb = baro_samples(truth, baro, baro_hz, rng)
        # the reference: the mean pad pressure, whose error (a Gaussian sigma/sqrt(n); the median of whole pascals
        # was quantised: exact at sea level, +-0.5 or 1 Pa now and then) is an offset of every sample: the filter's
        # barometer offset state has it as its prior
        pad_b = pb[tb < truth.t[0] + pad_align_s]
        p0 = float(np.mean(pad_b))
        ref_sigma = float(baro_sigma_m(np.sqrt(baro.noise_pa ** 2 + 1 / 12) / np.sqrt(pad_b.size),
                                       np.array([p0]))[0])
        hb = baro_altitude(pb, p0)
        sb = np.sqrt(baro_sigma_m(baro.noise_pa, pb) ** 2 + baro_sigma_m(1 / np.sqrt(12), pb) ** 2 + 0.05 ** 2)
        baro_arr = np.full(n, np.nan)
        sig = np.full(n, np.nan)
        pres = np.full(n, np.nan)
        for j, ti in enumerate(np.rint((tb - truth.t[0]) / dt_truth).astype(int)):
            k = step_of.get(int(ti))
            if k is not None:
                baro_arr[k], sig[k], pres[k] = hb[j], sb[j], pb[j]
    noise = filter_noise_for(imu, gps, heading_sigma_deg)
    if baro is not None:
        noise = replace(noise, baro_offset_sigma=ref_sigma)
    axis = heading_axis_of(truth)
    heading = heading_of(truth, axis) + rng.normal(0.0, noise.heading_sigma)
    n_pad = int(np.sum(t < truth.t[0] + pad_align_s))
    return Sensed(t=t, imu=data, meas=Measurements(gps=gps_arr, baro=baro_arr, baro_sigma=sig), n_pad=n_pad,
                  heading_rad=heading, noise=noise, truth_idx=tidx,
                  notes={"pressure_pa": pres, "earth_rate": truth.earth_rate, "heading_axis": axis})


def reconstruct_sensed(s: Sensed, site_asl_m: float, smooth: bool = True,
                       accel: np.ndarray | None = None, gyro: np.ndarray | None = None) -> Run:
    acc = s.imu.accel if accel is None else accel
    gyr = s.imu.gyro if gyro is None else gyro
    al = align(acc, gyr, s.n_pad, s.noise, s.heading_rad, site_asl_m, heading_axis=s.notes.get("heading_axis", "x"))
    return run_ukf(s.t, acc, gyr, s.imu.saturated, s.meas, al, s.noise, site_asl_m, smooth=smooth,
                   earth_rate=s.notes.get("earth_rate"))


@dataclass
class Errors:
    """Errors (estimate - truth; attitude: the site-frame rotation vector from estimate to truth) and sigmas on
    the IMU axis, for the filter (``f``) and the smoother (``s``): dicts with ``pos``, ``vel``, ``att`` (n, 3) and
    ``sig_pos`` ... and ``nees`` (n,) over the 9 navigation errors."""

    t: np.ndarray
    f: dict[str, np.ndarray]
    s: dict[str, np.ndarray] | None


def _errs(xs: dict[str, np.ndarray], P: np.ndarray, truth: Truth6, idx: np.ndarray) -> dict[str, np.ndarray]:
    pos = xs["r"] - (truth.pos[idx] - truth.pos[0])
    vel = xs["v"] - truth.vel[idx]
    att = attitude_error(xs["q"], truth.quat[idx])       # truth = exp(e) est -> error of the estimate is -e
    e = np.concatenate([pos, vel, -att], axis=1)
    Pn = P[:, 0:9, 0:9]
    nees = np.einsum("ni,ni->n", e, np.linalg.solve(Pn, e[..., None])[..., 0])
    sd = np.sqrt(np.einsum("nii->ni", P))
    return {"pos": pos, "vel": vel, "att": -att, "sig_pos": sd[:, 0:3], "sig_vel": sd[:, 3:6],
            "sig_att": sd[:, 6:9], "nees": nees}


def errors(run: Run, s: Sensed, truth: Truth6) -> Errors:
    f = _errs(unflat(run.xf), run.Pf, truth, s.truth_idx)
    sm = _errs(unflat(run.xs), run.Ps, truth, s.truth_idx) if run.xs is not None else None
    return Errors(t=s.t, f=f, s=sm)


def inside_2sigma(e: dict[str, np.ndarray], mask: np.ndarray) -> dict[str, float]:
    """Fraction of (sample, axis) pairs with |error| <= 2 sigma, per group, over ``mask``."""
    return {g: float(np.mean(np.abs(e[g][mask]) <= 2 * e[f"sig_{g}"][mask])) for g in ("pos", "vel", "att")}

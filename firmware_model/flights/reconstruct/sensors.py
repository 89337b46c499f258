"""Sensor models for the reconstruction, from 6-DOF truth (:class:`~.truth.Truth6`).

* :class:`ImuModel`: a 3-axis accelerometer (specific force, body frame, m/s^2) and a 3-axis gyroscope (body rates,
  rad/s) sampled at ``rate_hz``. Each output is the mean of the truth over its sample interval (the truth grid is
  1 kHz; a sensor's internal low-pass, and what makes constant-rate integration over a sample exact for constant
  inputs), then per axis: a scale error (1 + s, s drawn once per flight, sigma ``*_scale``), a constant bias (drawn
  once per flight, sigma ``*_bias``), white Gaussian noise (sigma ``*_noise`` per sample), clipping to
  +-``*_range`` and rounding to ``*_lsb``. Saturated samples are flagged.
* :class:`GpsModel`: site-frame position fixes at ``rate_hz`` with Gaussian noise (``sigma_h_m`` per horizontal axis,
  ``sigma_v_m`` vertical), independent dropouts (probability ``dropout``), and the export limits Chari discusses:
  no fix while faster than ``max_speed_mps`` (1,200 mph) or higher than ``max_altitude_m`` (60,000 ft) above sea
  level (either limit; ``cocom=False`` lifts them).
* :func:`baro_samples`: the barometer as the rest of the project models it
(:class:`firmware_model.flights.inputs.sensors.
  BaroSensor`): ISA pressure at the truth's geopotential altitude, through the sensor's noise, rounding and range.

Presets (:data:`IMU_PRESETS`, :data:`GPS_PRESETS`): ``chari`` is the paper's suite (100 Hz IMU with the BNO055's
accelerometer noise, 0.1 m/s^2, no biases as the paper assumes; 10 Hz GPS with 4 m). The paper's text lost the
gyroscope's figure; ``chari`` uses the BNO055's datasheet noise density (0.014 deg/s/sqrt(Hz)) over its 47 Hz
bandwidth, 0.1 deg/s. ``bno055`` adds the datasheet's ranges, resolutions and biases (zero-g offset +-80 mg, zero-rate
offset +-1 deg/s, taken as 1-sigma 0.25 m/s^2 and 0.5 deg/s; scale errors 0.5 %/0.5 %: a biased IMU that pad
alignment must handle). Randomness only from an explicit numpy Generator.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from math import radians
from typing import Any

import numpy as np

from firmware_model.spec import atmosphere as atm
from firmware_model.spec.atmosphere import G0
from firmware_model.runtime.errors import UserError
from firmware_model.flights.reconstruct.truth import EARTH_R, Truth6
from firmware_model.flights.inputs.sensors import BaroSensor


@dataclass(frozen=True)
class ImuModel:
    rate_hz: float = 100.0
    accel_noise: float = 0.1          # m/s^2 per sample (1 sigma)
    accel_bias: float = 0.0           # m/s^2, 1 sigma, constant per flight
    accel_scale: float = 0.0          # relative, 1 sigma
    accel_range: float = 16 * G0      # m/s^2
    accel_lsb: float = 0.0            # m/s^2 (0: no rounding)
    gyro_noise: float = radians(0.1)  # rad/s per sample
    gyro_bias: float = 0.0
    gyro_scale: float = 0.0
    gyro_range: float = radians(2000.0)
    gyro_lsb: float = 0.0
    accel_bias_walk: float = 0.0      # m/s^2/sqrt(s): what the filter assumes of bias drift (the model's biases
    gyro_bias_walk: float = 0.0       # rad/s/sqrt(s)  are constant per flight)
    name: str = "custom"

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class GpsModel:
    rate_hz: float = 10.0
    sigma_h_m: float = 4.0
    sigma_v_m: float = 4.0
    dropout: float = 0.0
    cocom: bool = True
    max_speed_mps: float = 1200 * 0.44704
    max_altitude_m: float = 60000 * 0.3048
    name: str = "custom"

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


IMU_PRESETS: dict[str, ImuModel] = {
    "chari": ImuModel(name="chari"),
    "bno055": ImuModel(accel_bias=0.25, accel_scale=0.005, accel_lsb=0.01, gyro_bias=radians(0.5),
                       gyro_scale=0.005, gyro_lsb=radians(1 / 16), accel_bias_walk=1e-3,
                       gyro_bias_walk=radians(0.005), name="bno055"),
}
GPS_PRESETS: dict[str, GpsModel] = {
    "chari": GpsModel(name="chari"),
    "chari-dropouts": GpsModel(dropout=0.2, name="chari-dropouts"),
}


def imu_preset(name: str, **kw: Any) -> ImuModel:
    if name not in IMU_PRESETS:
        raise UserError(f"IMU preset {name!r}: known: {', '.join(IMU_PRESETS)}")
    return replace(IMU_PRESETS[name], **kw)


def gps_preset(name: str, **kw: Any) -> GpsModel:
    if name not in GPS_PRESETS:
        raise UserError(f"GPS preset {name!r}: known: {', '.join(GPS_PRESETS)}")
    return replace(GPS_PRESETS[name], **kw)


@dataclass
class ImuData:
    """IMU samples: ``t`` (n,), ``accel`` (n, 3) m/s^2, ``gyro`` (n, 3) rad/s, ``saturated`` (n,) bool (any axis of
    the accelerometer at its range); ``truth_bias`` = (accel bias, gyro bias) drawn (None for real logs)."""

    t: np.ndarray
    accel: np.ndarray
    gyro: np.ndarray | None
    saturated: np.ndarray
    truth_bias: tuple[np.ndarray, np.ndarray] | None = None


def _block_mean(t: np.ndarray, x: np.ndarray, rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    dt_truth = float(t[1] - t[0])
    m = int(round(1.0 / (rate_hz * dt_truth)))
    if m < 1 or abs(m * dt_truth * rate_hz - 1.0) > 1e-6:
        raise UserError(f"IMU rate {rate_hz} Hz is not a divisor of the truth rate {1 / dt_truth:g} Hz")
    n = (t.size - 1) // m
    # sample k covers (t[k m], t[(k + 1) m]]: mean of the m truth points after its start (trapezoid-free box)
    blocks = x[1:n * m + 1].reshape(n, m, -1).mean(axis=1)
    return t[m:n * m + 1:m], blocks


def _sensor(x: np.ndarray, noise: float, bias: float, scale: float, rng_: float, lsb: float,
            rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    b = rng.normal(0.0, bias, 3) if bias > 0 else np.zeros(3)
    s = rng.normal(0.0, scale, 3) if scale > 0 else np.zeros(3)
    y = x * (1.0 + s) + b + (rng.normal(0.0, noise, x.shape) if noise > 0 else 0.0)
    sat = np.any(np.abs(y) >= rng_, axis=1)
    y = np.clip(y, -rng_, rng_)
    if lsb > 0:
        y = np.round(y / lsb) * lsb
    return y, b, sat


def imu_samples(truth: Truth6, model: ImuModel, rng: np.random.Generator) -> ImuData:
    t, f = _block_mean(truth.t, truth.f_body, model.rate_hz)
    _, w = _block_mean(truth.t, truth.omega, model.rate_hz)
    acc, ba, sat = _sensor(f, model.accel_noise, model.accel_bias, model.accel_scale, model.accel_range,
                           model.accel_lsb, rng)
    gyr, bg, _ = _sensor(w, model.gyro_noise, model.gyro_bias, model.gyro_scale, model.gyro_range,
                         model.gyro_lsb, rng)
    return ImuData(t=t, accel=acc, gyro=gyr, saturated=sat, truth_bias=(ba, bg))


def gps_samples(truth: Truth6, model: GpsModel, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(t (m,), pos (m, 3)): fixes relative to the pad's position (what a receiver's fix minus the pad's mean fix
    gives); a missing fix is NaN."""
    step = int(round(1.0 / (model.rate_hz * float(truth.t[1] - truth.t[0]))))
    idx = np.arange(0, truth.t.size, step)
    # start on the truth grid's first whole sample at or after its first time, aligned with the IMU grid
    t = truth.t[idx]
    pos = truth.pos[idx] - truth.pos[0]
    noise = rng.normal(size=pos.shape) * np.array([model.sigma_h_m, model.sigma_h_m, model.sigma_v_m])
    out = pos + noise
    lost = rng.random(t.size) < model.dropout if model.dropout > 0 else np.zeros(t.size, bool)
    if model.cocom:
        speed = np.linalg.norm(truth.vel[idx], axis=1)
        lost |= (speed > model.max_speed_mps) | (truth.pos[idx, 2] + truth.site_asl_m > model.max_altitude_m)
    out[lost] = np.nan
    return t, out


def geometric_to_geopotential(z: Any) -> Any:
    return EARTH_R * z / (EARTH_R + z)


def geopotential_to_geometric(h: Any) -> Any:
    return EARTH_R * h / (EARTH_R - h)


def baro_samples(truth: Truth6, sensor: BaroSensor, rate_hz: float, rng: np.random.Generator
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(t, pressure Pa) at ``rate_hz`` through ``sensor``."""
    step = int(round(1.0 / (rate_hz * float(truth.t[1] - truth.t[0]))))
    idx = np.arange(0, truth.t.size, step)
    z_asl = truth.pos[idx, 2] + truth.site_asl_m
    p = np.asarray(atm.pressure_pa(geometric_to_geopotential(z_asl)), dtype=np.float64)
    counts = sensor.counts(p, rng)
    return truth.t[idx], sensor.pressure_of_counts(counts)


def baro_altitude(pressure_pa: np.ndarray, ground_pressure_pa: float) -> np.ndarray:
    """Geometric altitude (m) above the point where the pressure is ``ground_pressure_pa``, ISA."""
    h = np.asarray(atm.altitude_m(np.asarray(pressure_pa, dtype=np.float64)), dtype=np.float64)
    h0 = float(atm.altitude_m(ground_pressure_pa))
    return geopotential_to_geometric(h) - geopotential_to_geometric(h0)


def baro_sigma_m(sigma_pa: float, pressure_pa: np.ndarray) -> np.ndarray:
    """Altitude sigma (m) of a pressure sigma at the given pressure (ISA density)."""
    h = np.asarray(atm.altitude_m(np.asarray(pressure_pa, dtype=np.float64)), dtype=np.float64)
    return sigma_pa / (np.asarray(atm.density_kg_m3(h)) * G0)

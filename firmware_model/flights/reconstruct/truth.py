"""6-DOF truth from RocketPy for the reconstruction: position, velocity, attitude, body rates and specific force.

:func:`truth_run` flies a :class:`~firmware_model.flights.simulate.sim1dof.Rocket` with RocketPy (the same rocket build
as
:mod:`firmware_model.flights.simulate.rocketpy_sim`) and samples its solution on a fine regular grid (``truth_hz``,
default
1 kHz) from ``pad_s`` before ignition to ``after_apogee_s`` after apogee. Frames: RocketPy's launch-site frame,
x east, y north, z up (flat earth, no Coriolis, as RocketPy integrates it), origin at the rail's foot; body frame
as RocketPy's (z along the rocket axis towards the nose). The quaternion ``q = (e0, e1, e2, e3)`` rotates body
vectors into the site frame (its rotation matrix's third column is the rocket axis). Body rates are RocketPy's
``w1, w2, w3`` (body frame, rad/s). Specific force (what an ideal accelerometer at the centre of mass reads, body
frame) = ``R(q)^T (a - g + 2 W x v)``, ``a`` RocketPy's acceleration in its (rotating) site frame, ``g = (0, 0,
-g(z))`` with the gravity model of :mod:`firmware_model.flights.simulate.rocketpy_sim`, ``W`` the earth's rate
(RocketPy adds
the Coriolis term ``-2 W x v`` to ``a``; an accelerometer does not feel it).

Runs take seconds, so :func:`truth_run` keeps them in the user's cache folder
(:func:`firmware_model.runtime.diskcache.cache_dir`, sub-folder ``reconstruct-truth``), keyed by the case and the
sources the run depends on (not by the estimator's code, so changing the filter keeps the cache).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from firmware_model.runtime import diskcache
from firmware_model.spec.atmosphere import G0
from firmware_model.runtime.errors import UserError
from firmware_model.flights.simulate import rocketpy_sim
from firmware_model.flights.simulate.scenarios import Scenario
from firmware_model.flights.simulate.sim1dof import Launch, Rocket, simulate_1dof

EARTH_R: float = 6378137.0
EARTH_RATE: float = 7.2921159e-5   # rad/s
#: Bump when :func:`_simulate` changes what it stores (the cache key; derived quantities are computed on load).
TRUTH_VERSION: str = "truth-2"


def gravity(z_asl: Any) -> Any:
    """RocketPy's gravity here (m/s^2) at geometric height ``z_asl`` above sea level."""
    return G0 * (EARTH_R / (EARTH_R + z_asl)) ** 2


@dataclass(frozen=True)
class TruthCase:
    """A simulated flight for the reconstruction: a scenario-style rocket (``rocket``: :class:`Rocket` fields,
    ``motor`` by name), launch site, wind (m/s towards east / north, constants or RocketPy profiles), rail
    elevation and azimuth, and how the run is sampled."""

    name: str
    rocket: dict[str, Any]
    mach_class: str = "subsonic"
    site_altitude_m: float = 0.0
    wind_u: Any = 0.0
    wind_v: Any = 0.0
    inclination_deg: float = 90.0
    heading_deg: float = 0.0
    drogue_delay_s: float = 1.0
    pad_s: float = 5.0
    after_apogee_s: float = 4.0
    truth_hz: float = 1000.0

    def key(self) -> str:
        h = hashlib.sha256(json.dumps(asdict(self), sort_keys=True, default=str).encode())
        h.update(TRUTH_VERSION.encode())
        here = Path(__file__).resolve()
        sim = here.parent.parent / "simulate"
        for p in (sim / "rocketpy_sim.py", sim / "motors.py", sim / "sim1dof.py"):
            h.update(p.read_bytes())
        for p in sorted((sim / "data").iterdir()):
            if p.is_file():
                h.update(p.name.encode() + p.read_bytes())
        h.update(rocketpy_sim._rocketpy_version().encode())
        return h.hexdigest()[:24]

    def build_rocket(self) -> Rocket:
        # no parachute: after deployment RocketPy flies a 3-DOF point mass whose attitude and rates no longer obey
        # rigid-body kinematics, which no IMU could see; the truth stays a free 6-DOF flight through apogee
        return Scenario(name=self.name, description="", mach_class=self.mach_class,
                        rocket={**self.rocket, "drogue_cd_area_m2": 0.0}).build_rocket()


@dataclass
class Truth6:
    """Sampled truth: ``t`` (n,) s from ignition; ``pos``/``vel``/``acc`` (n, 3) site frame (m, m/s, m/s^2);
    ``quat`` (n, 4) body -> site, scalar first; ``omega`` (n, 3) body rates rad/s; ``f_body`` (n, 3) specific force
    in the body frame; ``earth_rate`` (3,) the earth's rotation in the site frame (RocketPy's Coriolis term);
    ``site_asl_m``; ``apogee_time_s`` / ``apogee_altitude_m`` (geometric, above the site);
    ``liftoff_s``; ``meta`` (case, summary)."""

    t: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray
    quat: np.ndarray
    omega: np.ndarray
    f_body: np.ndarray
    site_asl_m: float
    apogee_time_s: float
    apogee_altitude_m: float
    liftoff_s: float
    earth_rate: np.ndarray = field(default_factory=lambda: np.zeros(3))
    meta: dict[str, Any] = field(default_factory=dict)

    def with_specific_force(self) -> Truth6:
        """Fill ``f_body``: RocketPy integrates in the rotating site frame, ``a = F/m + g - 2 W x v``, so the
        specific force an accelerometer reads is ``a - g + 2 W x v`` (W: earth rate in the site frame), rotated
        into the body frame."""
        # the acceleration is the backward difference of the sampled velocity, so that an IMU's sample means
        # integrate exactly to the truth's velocity (RocketPy's interpolated ax, ay, az and its interpolated
        # velocity disagree by up to 0.1 m/s over a boost: measured by dead reckoning on noise-free samples)
        dt = float(self.t[1] - self.t[0])
        acc = np.empty_like(self.vel)
        acc[1:] = np.diff(self.vel, axis=0) / dt
        acc[0] = acc[1]
        f_site = acc + 2.0 * np.cross(self.earth_rate, self.vel)
        f_site[:, 2] += gravity(self.pos[:, 2] + self.site_asl_m)
        self.f_body = np.einsum("nji,nj->ni", quat_to_matrix(self.quat), f_site)
        return self


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions (scalar first) -> (..., 3, 3) rotation matrices (body -> site)."""
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.empty(q.shape[:-1] + (3, 3))
    out[..., 0, 0] = 1 - 2 * (y * y + z * z)
    out[..., 0, 1] = 2 * (x * y - w * z)
    out[..., 0, 2] = 2 * (x * z + w * y)
    out[..., 1, 0] = 2 * (x * y + w * z)
    out[..., 1, 1] = 1 - 2 * (x * x + z * z)
    out[..., 1, 2] = 2 * (y * z - w * x)
    out[..., 2, 0] = 2 * (x * z - w * y)
    out[..., 2, 1] = 2 * (y * z + w * x)
    out[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return out


def _simulate(case: TruthCase) -> Truth6:
    rp = rocketpy_sim._import_rocketpy()
    rocket = case.build_rocket()
    launch = Launch(site_altitude_m=case.site_altitude_m, pad_s=case.pad_s, descent_s=case.after_apogee_s,
                    drogue_delay_s=case.drogue_delay_s)
    if not (0 < case.inclination_deg <= 90):
        raise UserError(f"truth case {case.name}: inclination {case.inclination_deg} not in (0, 90]")
    env, rk, _length = rocketpy_sim._build(rp, rocket, launch, rocketpy_sim.Airframe(), case.wind_u, case.wind_v)
    est = simulate_1dof(rocket, Launch(site_altitude_m=case.site_altitude_m, record_hz=50.0, internal_hz=200.0))[0]
    max_time = float(est.truth.apogee_time_s) * 1.25 + case.after_apogee_s + 5.0
    fl = rp.Flight(rocket=rk, environment=env, rail_length=5.0, inclination=case.inclination_deg,
                   heading=case.heading_deg, max_time=max_time, max_time_step=0.01, rtol=1e-8,
                   terminate_on_apogee=False, verbose=False, name=case.name)
    t_apo = float(fl.apogee_time)
    t_end = min(t_apo + case.after_apogee_s, float(fl.t_final))
    hz = case.truth_hz
    t_fl = np.arange(0, int(np.floor(t_end * hz + 1e-9)) + 1) / hz
    sol = np.asarray(fl.solution, dtype=np.float64)
    cols = np.stack([np.interp(t_fl, sol[:, 0], sol[:, c]) for c in range(1, 14)], axis=1)
    site = case.site_altitude_m
    pos = cols[:, 0:3] - np.array([0.0, 0.0, site])
    vel = cols[:, 3:6]
    quat = cols[:, 6:10]
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    omega = cols[:, 10:13]
    acc = np.stack([np.asarray(fl.ax(t_fl), float), np.asarray(fl.ay(t_fl), float),
                    np.asarray(fl.az(t_fl), float)], axis=1)
    n_pad = int(round(case.pad_s * hz))
    t = (np.arange(n_pad + t_fl.size) - n_pad) / hz

    def pad(x: np.ndarray, value: np.ndarray | None = None) -> np.ndarray:
        first = x[0] if value is None else value
        return np.concatenate([np.repeat(first[None, :], n_pad, axis=0), x])

    moving = np.nonzero(sol[:, 3] > site + 1e-4)[0]
    liftoff = float(sol[moving[0] - 1, 0]) if moving.size else 0.0
    return Truth6(t=t, pos=pad(pos), vel=pad(vel, np.zeros(3)), acc=pad(acc, np.zeros(3)), quat=pad(quat),
                  omega=pad(omega, np.zeros(3)), f_body=np.zeros((t.size, 3)), site_asl_m=site,
                  earth_rate=np.asarray(env.earth_rotation_vector, dtype=np.float64),
                  apogee_time_s=t_apo, apogee_altitude_m=float(fl.apogee) - site, liftoff_s=liftoff,
                  meta={"case": asdict(case), "max_mach": float(fl.max_mach_number),
                        "out_of_rail_s": float(fl.out_of_rail_time),
                        "apogee_drift_m": float(np.hypot(fl.apogee_x, fl.apogee_y)),
                        "rocketpy_version": rocketpy_sim._rocketpy_version()})


def truth_run(case: TruthCase, cache: bool = True) -> Truth6:
    """The case's truth, from the cache when there (module doc)."""
    folder = diskcache.cache_dir() if cache else None
    path = folder / "reconstruct-truth" / f"{case.name}-{case.key()}.pickle" if folder is not None else None
    if path is not None:
        obj = diskcache.load(path, lambda o: isinstance(o, Truth6))
        if obj is not None:
            return obj.with_specific_force()
    tr = _simulate(case)
    if path is not None:
        diskcache.store(path, tr)
    return tr.with_specific_force()

"""A small analytic 6-DOF truth without RocketPy (tests, examples): a rocket on an inclined rail that burns with a
constant specific force along its axis, spins and cones at constant body rates, then coasts in vacuum through
apogee. Sampled at 1 kHz; velocity and position integrated exactly for the sampled acceleration (trapezoid on
velocity, Simpson-like on position), so it is a consistent :class:`~.truth.Truth6`."""

from __future__ import annotations

import numpy as np

from firmware_model.flights.reconstruct.rotation import exp_rv, qmul, rotate
from firmware_model.flights.reconstruct.truth import Truth6, gravity


def synthetic_truth(thrust_mps2: float = 60.0, burn_s: float = 2.0, coast_s: float = 12.0, pad_s: float = 3.0,
                    elevation_deg: float = 85.0, heading_deg: float = 40.0,
                    body_rate: tuple[float, float, float] = (0.03, -0.02, 1.5), hz: float = 1000.0) -> Truth6:
    n = int(round((pad_s + burn_s + coast_s) * hz)) + 1
    t = np.arange(n) / hz - pad_s
    # initial attitude: body z along the rail (elevation, heading from north towards east)
    tilt = np.radians(90.0 - elevation_deg)
    az = np.radians(heading_deg)
    q_tilt = exp_rv(np.array([-np.cos(az), np.sin(az), 0.0]) * tilt)   # tilts body z towards the heading
    w = np.array(body_rate, dtype=np.float64)
    flying = t >= 0
    q = np.empty((n, 4))
    q[:] = q_tilt
    q[flying] = qmul(q_tilt, exp_rv(np.outer(t[flying], w)))
    omega = np.where(flying[:, None], w, 0.0)
    f_body = np.zeros((n, 3))
    burning = flying & (t < burn_s)
    f_body[burning, 2] = thrust_mps2
    acc = rotate(q, f_body)
    acc[:, 2] -= gravity(0.0)
    acc[~flying] = 0.0
    dt = 1.0 / hz
    vel = np.zeros((n, 3))
    pos = np.zeros((n, 3))
    for i in range(1, n):
        vel[i] = vel[i - 1] + 0.5 * (acc[i - 1] + acc[i]) * dt
        pos[i] = pos[i - 1] + 0.5 * (vel[i - 1] + vel[i]) * dt
    vz = vel[:, 2]
    k = int(np.nonzero((vz[:-1] > 0) & (vz[1:] <= 0))[0][0])
    t_apo = float(t[k] + vz[k] / (vz[k] - vz[k + 1]) * dt)
    tr = Truth6(t=t, pos=pos, vel=vel, acc=acc, quat=q, omega=omega, f_body=np.zeros((n, 3)), site_asl_m=0.0,
                apogee_time_s=t_apo, apogee_altitude_m=float(pos[:, 2].max()), liftoff_s=0.0,
                meta={"synthetic": True})
    return tr.with_specific_force()

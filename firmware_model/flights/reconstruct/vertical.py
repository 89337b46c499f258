"""The vertical channel alone, for a log without a gyroscope (or without the 3 axes): a linear Kalman filter and
Rauch-Tung-Striebel smoother on altitude, vertical velocity and accelerometer bias, with the axial specific force
taken as vertical (the assumption kalman_accel makes) as the control input and the barometric altitude as the
measurement. Linear, so the smoother is the exact RTS. The acceleration noise includes an allowance for the
assumption: ``tilt_allowance`` x |f| (1 - cos 10 deg = 1.5 % of the specific force, by default) on top of the
sensor noise. Barometer rules as in :mod:`.ukf` (speed gate, the static port's error, innovation gate,
re-acquisition after ``reacquire`` rejections in a row)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from firmware_model.flights.reconstruct.truth import gravity
from firmware_model.flights.reconstruct.ukf import _sound, baro_variances


@dataclass
class VerticalRun:
    t: np.ndarray
    xf: np.ndarray      # (n, 3): z, vz, b
    Pf: np.ndarray      # (n, 3, 3)
    xs: np.ndarray
    Ps: np.ndarray
    rejected: dict[str, int]


def run_vertical(t: np.ndarray, f_axial: np.ndarray, baro: np.ndarray, baro_sigma: np.ndarray, site_asl_m: float,
                 n_pad: int, accel_noise: float = 0.3, tilt_allowance: float = 0.015, bias_sigma: float = 0.5,
                 bias_walk: float = 0.01, gate_nis: float = 30.0, baro_max_mach: float = 0.7, reacquire: int = 50,
                 accel_sigma_extra: np.ndarray | None = None, baro_port_cp: float = 0.0,
                 baro_port_tau_s: float = 1.0, speed_trusted_until_s: float = np.inf) -> VerticalRun:
    n = t.size
    g0 = float(gravity(site_asl_m))
    fa = np.where(np.isfinite(f_axial), f_axial, 0.0)
    pad_f = float(np.median(fa[:max(n_pad, 1)])) if n_pad > 0 else g0
    x = np.array([0.0, 0.0, pad_f - g0 if n_pad >= 10 else 0.0])
    P = np.diag([0.5 ** 2, (0.05 if n_pad >= 10 else 2.0) ** 2, bias_sigma ** 2 if n_pad < 10 else 0.05 ** 2])
    XF = np.empty((n, 3))
    XP = np.empty((n, 3))
    PF = np.empty((n, 3, 3))
    PP = np.empty((n, 3, 3))
    FK = np.empty((n, 3, 3))
    XF[0], XP[0], PF[0], PP[0] = x, x, P, P
    FK[0] = np.eye(3)
    rej = {"baro": 0, "baro_mach": 0, "reacquired": 0}
    streak = 0
    for k in range(1, n):
        dt = float(t[k] - t[k - 1])
        F = np.array([[1.0, dt, -0.5 * dt * dt], [0.0, 1.0, -dt], [0.0, 0.0, 1.0]])
        a = fa[k] - float(gravity(x[0] + site_asl_m))
        x = F @ x + np.array([0.5 * dt * dt * a, dt * a, 0.0])
        va = accel_noise ** 2 + (tilt_allowance * abs(fa[k])) ** 2
        if accel_sigma_extra is not None:
            va += accel_sigma_extra[k] ** 2
        Q = va * np.array([[dt ** 4 / 4, dt ** 3 / 2, 0.0], [dt ** 3 / 2, dt * dt, 0.0], [0.0, 0.0, 0.0]])
        Q[2, 2] = bias_walk ** 2 * dt
        P = F @ P @ F.T + Q
        XP[k], PP[k], FK[k] = x, P.copy(), F
        if np.isfinite(baro[k]):
            speed = abs(float(x[1])) if t[k] < speed_trusted_until_s else 0.0
            if speed > baro_max_mach * _sound(x[0] + site_asl_m):
                rej["baro_mach"] += 1
            else:
                g2, r2 = baro_variances(float(baro_sigma[k]), speed, dt, baro_port_cp, baro_port_tau_s)
                S = P[0, 0] + g2
                y = float(baro[k] - x[0])
                if y * y / S > gate_nis and streak >= reacquire:
                    # a barometer that disagrees for `reacquire` samples in a row is not a spike: the estimate
                    # has drifted (accelerometer beyond its range, a wrong bias): widen it and take the sample
                    P[0, 0] += y * y
                    P[1, 1] += (y / 2.0) ** 2
                    PP[k][0, 0] += y * y          # process noise of this step (the smoother sees it)
                    PP[k][1, 1] += (y / 2.0) ** 2
                    S = P[0, 0] + g2
                    rej["reacquired"] += 1
                    streak = 0
                if y * y / S <= gate_nis:
                    streak = 0
                    S = P[0, 0] + r2
                    K = P[:, 0] / S
                    x = x + K * y
                    IKH = np.eye(3)
                    IKH[:, 0] -= K
                    P = IKH @ P @ IKH.T + np.outer(K, K) * r2
                else:
                    rej["baro"] += 1
                    streak += 1
        XF[k], PF[k] = x, P
    XS = XF.copy()
    PS = PF.copy()
    for k in range(n - 2, -1, -1):
        G = np.linalg.solve(PP[k + 1].T, (PF[k] @ FK[k + 1].T).T).T
        XS[k] = XF[k] + G @ (XS[k + 1] - XP[k + 1])
        PS[k] = PF[k] + G @ (PS[k + 1] - PP[k + 1]) @ G.T
    return VerticalRun(t=t, xf=XF, Pf=PF, xs=XS, Ps=PS, rejected=rej)

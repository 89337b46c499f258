"""The reconstruction filter: an unscented Kalman filter with the IMU as control input, GPS and barometer as
measurements, a multiplicative attitude error, and a fixed-interval unscented RTS smoother (docs/reconstruction.md).

State (nominal): site-frame position ``r``, velocity ``v``, attitude quaternion ``q`` (body -> site), accelerometer
and gyroscope biases ``ba``, ``bg`` and scale errors ``sa``, ``sg`` (body frame, per axis: a sensor reads
``(1 + s) x + b``), and the barometer's offset ``bb`` (it reads altitude + bb: the error of the reference
pressure its altitudes are computed from, common to every sample; prior ``FilterNoise.baro_offset_sigma``). Error
state (22): ``dr, dv, dth, dba, dbg, dsa, dsg, dbb`` with the attitude
error a site-frame rotation vector, ``q_true = exp(dth) (x) q`` (Chari's Future Work: a minimal attitude error
instead of adding to a quaternion and renormalising; the quaternion itself is never added to).

* Predict (every IMU sample, interval dt): sigma points of the error state around the nominal (2n points
  +-sqrt(n) columns of chol(P), equal weights 1/(2n): the unscented transform with kappa = 0, whose weights are all
  positive so the predicted covariance stays positive definite), each mapped onto a full state and propagated:
  ``w = (gyro - bg) / (1 + sg)``, ``f = (accel - ba) / (1 + sa)``, ``q' = q (x) exp(w dt)``,
  ``a = R(q (x) exp(w dt / 2)) f + (0, 0, -g(z))``,
  minus the Coriolis term ``2 W x v`` of the earth's rate W (RocketPy integrates in the rotating site frame),
  ``v' = v + a dt``, ``r' = r + v dt + a dt^2 / 2``; the nominal is propagated alongside and the sigma points'
  attitudes are read back as rotation vectors relative to it (``log(q_i (x) q_ref^*)``); mean and covariance of the
  21 errors (the barometer's offset is outside the sigma points: :func:`run_ukf`), plus the process noise of the
  IMU's white noise, quantisation and bias random walks; the predicted mean is the propagated nominal moved by the
  mean error. A saturated accelerometer sample adds ``saturated_sigma`` of acceleration noise for that step.
* Update: GPS position and barometric altitude (+ offset) are linear in the error state, so the unscented transform
  of the measurement is exact and equals the Kalman update (Joseph form); the error is folded into the nominal
  (multiplicatively for the attitude) and reset to zero. Innovations beyond the gate (NIS above ``gate_nis``) are
  rejected and counted; after ``reacquire`` barometer rejections in a row the estimate, not the barometer, is taken
  to be wrong: its altitude and vertical-velocity variances are widened by the innovation and the sample is used
  (counted as ``reacquired``). The barometer is not used while the estimated speed exceeds ``baro_max_mach`` of the
  local speed of sound (real static ports read shock and stagnation pressure there; without GPS the vertical speed,
  the horizontal velocity being unobservable).
* Smoother (Sarkka's unscented RTS): with the stored cross-covariance ``D_k`` of the errors at k and the predicted
  errors at k+1, ``G = D P_pred^-1``; the smoothed error at k is ``G (x_s(k+1) [-] x_pred(k+1))`` added to the
  filtered nominal, ``P_s(k) = P(k) + G (P_s(k+1) - P_pred(k+1)) G^T``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from types import ModuleType
from math import radians
from typing import Any

import numpy as np

from firmware_model.spec import atmosphere as atm
from firmware_model.runtime.errors import UserError
from firmware_model.flights.reconstruct.rotation import exp_rv, log_q, qconj, qmul, rotate, tilt_deg
from firmware_model.flights.reconstruct.truth import gravity

N_ERR = 22
N_DYN = 21          # the errors the sigma points carry (all but the barometer's offset, which no dynamics touch)
N_STATE = 23
SL_R, SL_V, SL_TH, SL_BA, SL_BG = slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12), slice(12, 15)
SL_SA, SL_SG, SL_BB = slice(15, 18), slice(18, 21), slice(21, 22)


@dataclass(frozen=True)
class FilterNoise:
    """What the filter assumes about its sensors (datasheet figures, not the truth's draws)."""

    accel_noise: float = 0.1
    accel_lsb: float = 0.0
    accel_bias_sigma: float = 0.02
    accel_bias_walk: float = 1e-3       # m/s^2/sqrt(s)
    accel_scale_sigma: float = 0.0      # relative, 1 sigma: prior of the scale-factor states (constant per flight)
    gyro_noise: float = radians(0.1)
    gyro_lsb: float = 0.0
    gyro_bias_sigma: float = radians(0.05)
    gyro_bias_walk: float = radians(0.01)
    gyro_scale_sigma: float = 0.0
    accel_range: float = 16 * 9.80665
    saturated_sigma: float = 30.0
    heading_sigma: float = radians(5.0)
    gps_sigma: tuple[float, float, float] = (4.0, 4.0, 4.0)
    baro_offset_sigma: float = 0.0     # m: the barometer's reference error (0: the reference taken as exact)
    gate_nis: float = 30.0
    baro_max_mach: float = 0.7
    reacquire: int = 50
    baro_port_cp: float = 0.0           # static-port error, 1 sigma, as a fraction of the dynamic pressure
    baro_port_tau_s: float = 1.0        # its correlation time
    speed_trusted_until_s: float = math.inf   # after it (a recovery event), no Mach gate and no port error


def baro_port_sigma_m(speed_mps: float, cp: float) -> float:
    """The barometric-altitude error (1 sigma, m) of a static port reading ``cp`` of the dynamic pressure: a
    pressure error ``cp * rho v^2 / 2`` is an altitude error of that over ``rho g``, i.e. ``cp v^2 / (2 g)``."""
    return cp * speed_mps * speed_mps / (2.0 * 9.80665)


def baro_variances(sigma_m: float, speed_mps: float, dt: float, cp: float, tau_s: float) -> tuple[float, float]:
    """(gate variance, update variance) of one barometer sample: the sensor's ``sigma_m`` and the port error
    :func:`baro_port_sigma_m` (``cp``: ``FilterNoise.baro_port_cp``). The gate judges one sample by both. The port
    error follows the dynamic pressure, so it is the same error for ``tau_s``: the update counts it ``tau / dt``
    times over, so that the samples of one correlation time carry one sample's worth of it (averaging them cannot
    remove a bias)."""
    sq = baro_port_sigma_m(speed_mps, cp)
    r2 = sigma_m * sigma_m
    return r2 + sq * sq, r2 + sq * sq * max(1.0, tau_s / dt)


def _baro_row(m: int) -> np.ndarray:
    """H of a barometer sample over ``m`` active errors: altitude, plus the offset when it is a state."""
    h = np.zeros(m)
    h[2] = 1.0
    if m > N_DYN:
        h[N_DYN] = 1.0
    return h


def _scalar_update(P: np.ndarray, h: np.ndarray, y: float, r2: float) -> tuple[np.ndarray, np.ndarray]:
    """(posterior covariance, error) of a scalar measurement ``y = h . e + noise(r2)``: Kalman gain, Joseph form."""
    ph = P @ h
    K = ph / (h @ ph + r2)
    IKH = np.eye(P.shape[0]) - np.outer(K, h)
    return IKH @ P @ IKH.T + np.outer(K, K) * r2, K * y


def _gps_update(P: np.ndarray, y: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(posterior covariance, error) of a GPS position ``y`` (3,) on the first three errors, noise ``R``: Joseph
    form."""
    K = np.linalg.solve(P[0:3, 0:3] + R, P[0:3, :]).T              # (m, 3)
    IKH = np.eye(P.shape[0])
    IKH[:, 0:3] -= K
    return IKH @ P @ IKH.T + K @ R @ K.T, K @ y


def flat(r, v, q, ba, bg, sa=(0.0, 0.0, 0.0), sg=(0.0, 0.0, 0.0), bb=0.0) -> np.ndarray:
    """The flat 23-vector state ``r v q ba bg sa sg bb``."""
    return np.concatenate([r, v, q, ba, bg, sa, sg, [bb]]).astype(np.float64)


def unflat(x: np.ndarray) -> dict[str, np.ndarray]:
    """(..., 23) states -> dict of ``r, v, q, ba, bg, sa, sg, bb`` arrays."""
    return {"r": x[..., 0:3], "v": x[..., 3:6], "q": x[..., 6:10], "ba": x[..., 10:13], "bg": x[..., 13:16],
            "sa": x[..., 16:19], "sg": x[..., 19:22], "bb": x[..., 22]}


def _kernels() -> ModuleType:
    """:mod:`.kernels`, loaded on first use: a lazy load, because importing them imports numba (about 1.5 s), which
    commands that never reconstruct (``fwemu --help``, ``design`` ...) must not pay."""
    from firmware_model.flights.reconstruct import kernels  # lazy: numba (heavy, optional)

    return kernels


def boxplus(x: np.ndarray, dx: np.ndarray) -> np.ndarray:
    """x [+] dx; ``dx`` of the 21 dynamic errors or all 22 (the kernels see the first 22 / 21 entries)."""
    out = np.empty(N_STATE)
    _kernels().boxplus(x, np.ascontiguousarray(dx, dtype=np.float64), out)
    out[22] = x[22] + (dx[21] if len(dx) > N_DYN else 0.0)
    return out


def boxminus(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.empty(N_ERR)
    _kernels().boxminus(a, b, out)
    out[21] = a[22] - b[22]
    return out


def _pad_attitude(f: np.ndarray, heading_rad: float, heading_axis: str) -> np.ndarray:
    """The attitude whose "up" in the body frame is ``f``'s direction (the shortest rotation taking it to the
    site's vertical) turned about the vertical so that body ``heading_axis`` points at ``heading_rad``; ``f`` (3,)
    or (..., 3) (then one attitude per row)."""
    f = np.asarray(f, dtype=np.float64)
    u = f / np.linalg.norm(f, axis=-1, keepdims=True)
    axis = np.cross(u, np.array([0.0, 0.0, 1.0]))
    s = np.linalg.norm(axis, axis=-1)
    ang = np.arctan2(s, u[..., 2])
    q_tilt = exp_rv(axis * (ang / np.where(s > 1e-12, s, 1.0))[..., None])
    ref = rotate(q_tilt, np.array([0.0, 0.0, 1.0] if heading_axis == "z" else [1.0, 0.0, 0.0]))
    az_now = np.arctan2(ref[..., 0], ref[..., 1])           # azimuth from north (y) towards east (x)
    turn = np.zeros(f.shape)
    turn[..., 2] = az_now - np.asarray(heading_rad)
    return qmul(exp_rv(turn), q_tilt)


PRIOR_DRAWS = 1 << 14


def _pad_prior(f: np.ndarray, u: np.ndarray, g: float, q0: np.ndarray, ba0: np.ndarray, heading_rad: float,
               heading_axis: str, sig_b: float, sig_s: float, sig_n: float, sig_h: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """Covariance (9, 9) and mean (9,) of the pad alignment's errors ``dth, dba, dsa`` (:func:`align`): the
    alignment itself applied to draws of the truth given ``f``: bias across ``u`` (sigma ``sig_b``), scale errors
    ``sig_s``, the pad mean's noise ``sig_n``, heading error ``sig_h``, and the bias along ``u`` that makes the true
    force's norm g. Antithetic draws from a fixed seed: the prior is deterministic."""
    z = np.random.default_rng(20240607).standard_normal((PRIOR_DRAWS, 10))
    z = np.concatenate([z, -z])
    b = z[:, 0:3] * sig_b
    b -= np.outer(b @ u, u)                               # across u; along u it follows from |f_true| = g
    s = z[:, 3:6] * sig_s
    n = z[:, 6:9] * sig_n
    w = (f - b - n) / (1.0 + s)
    d = u / (1.0 + s)                                     # f_true = w - beta d, |f_true| = g
    wd = np.einsum("ij,ij->i", w, d)
    c = np.einsum("ij,ij->i", w, w) - g * g
    beta = c / (wd + np.sqrt(wd * wd - np.einsum("ij,ij->i", d, d) * c))
    b += np.outer(beta, u)
    q_t = _pad_attitude(w - beta[:, None] * d, heading_rad + z[:, 9] * sig_h, heading_axis)
    y = np.concatenate([log_q(qmul(q_t, qconj(q0))), b - ba0, s], axis=1)
    return np.cov(y, rowvar=False), y.mean(axis=0)


@dataclass
class Alignment:
    """Pad alignment: the initial nominal and covariance, and what was used."""

    x0: np.ndarray
    P0: np.ndarray
    pad_samples: int
    notes: dict[str, Any] = field(default_factory=dict)


def align(accel: np.ndarray, gyro: np.ndarray, n_pad: int, noise: FilterNoise, heading_rad: float,
          site_asl_m: float, r0: np.ndarray | None = None, r0_sigma: tuple[float, float, float] = (0.5, 0.5, 0.5),
          heading_axis: str = "x") -> Alignment:
    """Initial attitude and biases from the first ``n_pad`` IMU samples (the rocket still on the pad).

    Gyro bias = mean pad rate (earth rate, 7e-5 rad/s, ignored). Tilt from the mean specific force's direction
    (it points up, along -gravity); the heading about the vertical is ``heading_rad`` (the azimuth of the body z axis
    if the rail is inclined, else of body x), sigma ``noise.heading_sigma``. An accelerometer bias across gravity
    cannot be told from tilt on the pad: the prior carries the attitude error it makes through the alignment
    (the tilt, and on an inclined rail the heading too); the bias along gravity is |f| - g, with the scale error's
    share of it in the prior. ``heading_axis``: the body axis whose azimuth ``heading_rad`` is: "z" (the
    rocket's axis: an inclined rail's azimuth) or "x" (the pad roll orientation; for a vertical rail, where the
    axis has no azimuth). The caller decides from what it knows of the rail, never from the measured tilt (an
    accelerometer bias fakes several degrees of it). The barometer's offset starts at 0 with sigma
    ``noise.baro_offset_sigma``."""
    if n_pad < 10:
        raise UserError(f"pad alignment needs at least 10 IMU samples on the pad, got {n_pad}")
    f = accel[:n_pad].mean(axis=0)
    g = float(gravity(site_asl_m))
    fn = float(np.linalg.norm(f))
    u = f / fn                                           # body direction of "up"
    q0 = _pad_attitude(f, heading_rad, heading_axis)
    bg = gyro[:n_pad].mean(axis=0) if gyro is not None else np.zeros(3)
    sig_n = noise.accel_noise / np.sqrt(n_pad)
    ba0 = (fn - g) * u
    # The pad's mean force is f = (1 + s) g u_t + b + n (bias b, scale errors s, the mean's noise n, all independent
    # with the datasheet's sigmas; u_t the true "up" in the body): the alignment reads everything but g u_t as bias
    # along u and as tilt across it, and the truth is what it would give with the true force g u_t and the true
    # heading. The prior is the moment-matched Gaussian of those errors (attitude, bias, scale error) as functions
    # of b, s, n and the heading error (_pad_prior). It used to be their linearisation at f, which holds the tilt
    # to the bias across gravity / g within the pad mean's noise / g (6e-4 rad); but the site-frame tilt error turns
    # with the heading error (a product: 0.087 x 0.025 / 2 = 1e-3 rad at one sigma each), and on an inclined rail
    # the heading follows the tilt across the rail plane through the rail's small tilt (16 deg per 0.25 m/s^2 at
    # 85 deg), not linearly. On the bno055 suite the linear prior's NEES (21 errors) against the truth's draws was
    # 51 on average over the 24 flights; this one's is 14 (15 expected: position and velocity start exact).
    Pj, mu = _pad_prior(f, u, g, q0, ba0, heading_rad, heading_axis, noise.accel_bias_sigma,
                        np.sqrt(noise.accel_scale_sigma ** 2 + 1e-10), np.sqrt(sig_n ** 2 + 1e-8),
                        noise.heading_sigma)
    q0 = qmul(exp_rv(mu[0:3]), q0)
    ba0 = ba0 + mu[3:6]
    P0 = np.zeros((N_ERR, N_ERR))
    P0[SL_R, SL_R] = np.diag(np.square(r0_sigma))
    P0[SL_V, SL_V] = np.eye(3) * 1e-4
    idx = np.r_[6:9, 9:12, 15:18]                        # dth, dba, dsa
    P0[np.ix_(idx, idx)] = Pj
    gb = noise.gyro_noise / np.sqrt(n_pad)
    P0[SL_BG, SL_BG] = np.eye(3) * (gb ** 2 + noise.gyro_bias_walk ** 2 * n_pad * 0.01 + 1e-10)
    P0[SL_SG, SL_SG] = np.eye(3) * (noise.gyro_scale_sigma ** 2 + 1e-10)
    P0[SL_BB, SL_BB] = noise.baro_offset_sigma ** 2
    x0 = flat(np.zeros(3) if r0 is None else np.asarray(r0, float), np.zeros(3), q0, ba0, bg)
    return Alignment(x0=x0, P0=P0, pad_samples=n_pad,
                     notes={"tilt_deg": float(tilt_deg(q0)), "specific_force_mps2": fn, "g_mps2": g})


@dataclass
class Measurements:
    """Measurements on the IMU's steps: ``gps`` (n, 3) site-frame positions relative to the pad (NaN: none this
    step), ``baro`` (n,) geometric altitude above the pad (NaN: none), ``baro_sigma`` (n,) its sigma (m)."""

    gps: np.ndarray | None
    baro: np.ndarray | None
    baro_sigma: np.ndarray | None


@dataclass
class Run:
    """Filter and smoother output on the IMU time axis ``t`` (n,): flat states ``xf``/``xs`` (n, 23) and
    covariances ``Pf``/``Ps`` (n, 22, 22) of the filter and the smoother (None without smoothing); ``rejected``
    measurement counts; ``nis``: (step, kind, NIS, used) per measurement."""

    t: np.ndarray
    xf: np.ndarray
    Pf: np.ndarray
    xs: np.ndarray | None
    Ps: np.ndarray | None
    rejected: dict[str, int]
    nis: list[tuple[int, str, float, bool]]


def _sigma_offsets(P: np.ndarray) -> np.ndarray:
    try:
        L = np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(0.5 * (P + P.T))
        L = V * np.sqrt(np.clip(w, 1e-18, None))
    L = L * np.sqrt(N_DYN)
    return np.ascontiguousarray(np.concatenate([L.T, -L.T], axis=0))          # (2n, n)


def _add_process_noise(P: np.ndarray, k: int, dt: float, va: float, vg: float, saturated: np.ndarray,
                       accel_sigma_extra: np.ndarray | None, noise: FilterNoise) -> None:
    """Add step ``k``'s process noise to ``P`` (the 21 dynamic errors' block) in place: the IMU's white noise and
    quantisation (acceleration ``va`` plus a saturated sample's and ``accel_sigma_extra``'s; rate ``vg``) and the
    bias random walks."""
    acc_var = va
    if saturated[k]:
        acc_var += noise.saturated_sigma ** 2
    if accel_sigma_extra is not None:
        acc_var += accel_sigma_extra[k] ** 2
    q = np.empty(N_DYN)
    q[0:3] = acc_var * dt ** 4 / 4
    q[3:6] = acc_var * dt * dt
    q[6:9] = vg * dt * dt
    q[9:12] = noise.accel_bias_walk ** 2 * dt
    q[12:15] = noise.gyro_bias_walk ** 2 * dt
    q[15:21] = 1e-12 * dt
    P[np.diag_indices(N_DYN)] += q
    c = acc_var * dt ** 3 / 2
    for i in range(3):
        P[i, 3 + i] += c
        P[3 + i, i] += c


def _predict_offset(P: np.ndarray, Paa: np.ndarray, Pa: np.ndarray, Daa: np.ndarray, dt: float
                    ) -> tuple[np.ndarray, np.ndarray]:
    """The predicted covariance and D = cov(error k, predicted error k+1) with the barometer's offset b a state
    (outside the sigma points): from ``P`` (at k, with b), ``Paa`` (its dynamic block), the unscented predict's
    ``Pa`` and ``Daa``: P_ab' = F P_ab, D = [[Daa, P_ab], [(F P_ab)^T, P_bb]]."""
    m = P.shape[0]
    Pab = P[:N_DYN, N_DYN]
    FPab = Daa.T @ np.linalg.solve(Paa, Pab)
    D = np.empty((m, m))
    D[:N_DYN, :N_DYN] = Daa
    D[:N_DYN, N_DYN] = Pab
    D[N_DYN, :N_DYN] = FPab
    D[N_DYN, N_DYN] = P[N_DYN, N_DYN]
    Pn = np.empty((m, m))
    Pn[:N_DYN, :N_DYN] = Pa
    Pn[:N_DYN, N_DYN] = FPab
    Pn[N_DYN, :N_DYN] = FPab
    Pn[N_DYN, N_DYN] = P[N_DYN, N_DYN] + 1e-12 * dt
    return Pn, D


def run_ukf(t: np.ndarray, accel: np.ndarray, gyro: np.ndarray, saturated: np.ndarray, meas: Measurements,
            al: Alignment, noise: FilterNoise, site_asl_m: float, smooth: bool = True,
            earth_rate: np.ndarray | None = None, accel_sigma_extra: np.ndarray | None = None) -> Run:
    """Filter (and smooth) one flight; ``earth_rate``: the earth's rotation in the site frame (rad/s; None: 0);
    ``accel_sigma_extra``: per-step extra acceleration noise (m/s^2), e.g. after a recovery charge fired.

    The barometer's offset is a state only when ``noise.baro_offset_sigma`` > 0 (else it stays 0 and its row and
    column of the covariances 0). It is outside the sigma points (no dynamics touch it): its cross-covariance with
    the other errors is carried by the statistically linearised transition F = D^T P^-1 of the unscented predict."""
    n = t.size
    m = N_ERR if noise.baro_offset_sigma > 0 else N_DYN       # the active errors
    kern = _kernels()
    wE = np.zeros(3) if earth_rate is None else np.asarray(earth_rate, dtype=np.float64)
    accel = np.ascontiguousarray(accel, dtype=np.float64)
    gyro = np.ascontiguousarray(gyro, dtype=np.float64)
    x = al.x0.copy()
    P = al.P0[:m, :m].copy()
    XF = np.empty((n, N_STATE))
    XP = np.empty((n, N_STATE))
    XF[0] = x
    XP[0] = x
    Pf = np.zeros((n, N_ERR, N_ERR))
    Pf[0, :m, :m] = P
    Pp = np.zeros((n, N_ERR, N_ERR))
    Pp[0, :m, :m] = P
    Dk = np.zeros((n, N_ERR, N_ERR))
    w = 1.0 / (2 * N_DYN)
    rejected = {"gps": 0, "baro": 0, "baro_mach": 0, "reacquired": 0}
    streak = 0
    nis_log: list[tuple[int, str, float, bool]] = []
    widened: list[tuple[int, float, float]] = []
    baro_r2: dict[int, float] = {}          # the update variance of each barometer sample used
    va = noise.accel_noise ** 2 + noise.accel_lsb ** 2 / 12
    vg = noise.gyro_noise ** 2 + noise.gyro_lsb ** 2 / 12
    gps_R = np.diag(np.square(noise.gps_sigma))
    h_baro = _baro_row(m)
    ref = np.empty(N_STATE)
    dev = np.empty((2 * N_DYN, N_DYN))
    gps = meas.gps
    baro = meas.baro
    for k in range(1, n):
        dt = float(t[k] - t[k - 1])
        Paa = P[:N_DYN, :N_DYN] if m > N_DYN else P
        chi = _sigma_offsets(Paa)
        kern.predict_points(x, chi, accel[k], gyro[k], dt, site_asl_m, wE, ref, dev)
        ref[22] = x[22]
        mean = dev.mean(axis=0)
        dev -= mean
        Pa = w * (dev.T @ dev)
        _add_process_noise(Pa, k, dt, va, vg, saturated, accel_sigma_extra, noise)
        Daa = w * (chi.T @ dev)
        if m > N_DYN:
            P, Dk[k] = _predict_offset(P, Paa, Pa, Daa, dt)
        else:
            P = Pa
            Dk[k, :m, :m] = Daa
        x = boxplus(ref, mean)
        XP[k] = x
        Pp[k, :m, :m] = P
        # ---- measurements (linear in the error state)
        if gps is not None and gps[k, 0] == gps[k, 0]:
            y = gps[k] - x[0:3]
            S = P[0:3, 0:3] + gps_R
            nis = float(y @ np.linalg.solve(S, y))
            ok = nis <= noise.gate_nis
            nis_log.append((k, "gps", nis, ok))
            if ok:
                P, dx = _gps_update(P, y, gps_R)
                x = boxplus(x, dx)
            else:
                rejected["gps"] += 1
        if baro is not None and baro[k] == baro[k]:
            # without GPS the horizontal velocity is not observable (its estimate may wander): gate on |vz|
            speed = math.sqrt(x[3] * x[3] + x[4] * x[4] + x[5] * x[5]) if gps is not None else abs(x[5])
            if t[k] >= noise.speed_trusted_until_s:
                speed = 0.0                 # the estimate's speed is suspect: neither gate nor port error
            if speed > noise.baro_max_mach * _sound(x[2] + site_asl_m):
                rejected["baro_mach"] += 1
            else:
                # the barometer reads altitude + its offset (h: e_z + e_bb when the offset is a state)
                y = float(baro[k] - x[2] - x[22])
                g2, r2 = baro_variances(float(meas.baro_sigma[k]), speed, dt, noise.baro_port_cp,
                                        noise.baro_port_tau_s)
                S = h_baro @ P @ h_baro + g2
                nis = y * y / S
                if nis > noise.gate_nis and streak >= noise.reacquire:
                    # the widening is process noise of this step: the stored prediction gets it too, so that
                    # the smoother's gain does not carry the jump back through the flight
                    P[2, 2] += y * y
                    P[5, 5] += (y / 2.0) ** 2
                    Pp[k][2, 2] += y * y
                    Pp[k][5, 5] += (y / 2.0) ** 2
                    widened.append((k, y * y, (y / 2.0) ** 2))
                    S = h_baro @ P @ h_baro + g2
                    rejected["reacquired"] += 1
                    streak = 0
                ok = y * y / S <= noise.gate_nis
                streak = 0 if ok else streak + 1
                nis_log.append((k, "baro", nis, ok))
                if ok:
                    baro_r2[k] = r2
                    P, dx = _scalar_update(P, h_baro, y, r2)
                    x = boxplus(x, dx)
                else:
                    rejected["baro"] += 1
        P = 0.5 * (P + P.T)
        XF[k] = x
        Pf[k, :m, :m] = P
    run = Run(t=t, xf=XF, Pf=Pf, xs=None, Ps=None, rejected=rejected, nis=nis_log)
    if smooth:
        XS, Ps = smooth_urts(XF, Pf, XP, Pp, Dk, m)
        used = {(k, kind) for k, kind, _, ok in nis_log if ok}
        run.xs, run.Ps = smooth_posterior_linearised(t, accel, gyro, saturated, meas, al, noise, site_asl_m, wE,
                                                     accel_sigma_extra, XS, Ps, used, widened, Pp, Dk, baro_r2, m)
    return run


def smooth_urts(XF: np.ndarray, Pf: np.ndarray, XP: np.ndarray, Pp: np.ndarray, Dk: np.ndarray, m: int = N_ERR
                ) -> tuple[np.ndarray, np.ndarray]:
    """The unscented RTS pass (module docstring) over the filter's stored states; ``m`` the active errors (21:
    the barometer's offset not a state)."""
    n = XF.shape[0]
    XS = np.empty_like(XF)
    Ps = np.zeros_like(Pf)
    XS[-1] = XF[-1]
    Ps[-1] = Pf[-1]
    for k in range(n - 2, -1, -1):
        Pp1 = Pp[k + 1, :m, :m]
        G = np.linalg.solve(Pp1.T, Dk[k + 1, :m, :m].T).T
        XS[k] = boxplus(XF[k], G @ boxminus(XS[k + 1], XP[k + 1])[:m])
        Pk = Pf[k, :m, :m] + G @ (Ps[k + 1, :m, :m] - Pp1) @ G.T
        Ps[k, :m, :m] = 0.5 * (Pk + Pk.T)
    return XS, Ps


def smooth_posterior_linearised(t: np.ndarray, accel: np.ndarray, gyro: np.ndarray, saturated: np.ndarray,
                                meas: Measurements, al: Alignment, noise: FilterNoise, site_asl_m: float,
                                wE: np.ndarray, accel_sigma_extra: np.ndarray | None, XB: np.ndarray,
                                PB: np.ndarray, used: set[tuple[int, str]], widened: list[tuple[int, float, float]],
                                Pp: np.ndarray, A: np.ndarray, baro_r2: dict[int, float], m: int = N_DYN
                                ) -> tuple[np.ndarray, np.ndarray]:
    """One iteration of posterior linearisation (Garcia-Fernandez, Svensson & Sarkka 2017, "Iterated posterior
    linearization smoother") around the unscented RTS smoother's states ``XB``, ``PB``: each IMU step is replaced by
    its statistical linear regression on sigma points of the *smoothed* distribution at k - 1, in errors around
    the smoothed states (``d_k = A d_{k-1} + b + e``, e with the regression's residual covariance Omega plus the
    process noise); a linear Kalman filter and RTS smoother on those errors, with the measurements the filter used
    (``used``: (step, "gps" | "baro"); ``baro_r2``: the variance each barometer sample was used with) and its
    re-acquisition widenings, give the result. The unscented filter
    linearises each step over its own, wider and possibly wrong, distribution: with a biased IMU the tilt after
    the pad is off by up to 0.06 rad, whose second-order effect on the thrust (1 - cos) the filter reads as an
    axial scale error and the RTS pass carries back linearly. ``m``: the active errors (22: with the barometer's
    offset, which no dynamics touch: the regression is over the 21 dynamic errors (the offset's columns of A are
    exactly 0: a function of the dynamic errors has no linear part in what of the offset they do not explain), its
    row the identity; the barometer reads z + offset). ``Pp``, ``A`` (n, 22, 22): scratch (overwritten; used as
    (n, m, m)). Returns the smoothed flat states and covariances (``PB`` is overwritten with the latter)."""
    n = t.size
    kern = _kernels()
    w = 1.0 / (2 * N_DYN)
    va = noise.accel_noise ** 2 + noise.accel_lsb ** 2 / 12
    vg = noise.gyro_noise ** 2 + noise.gyro_lsb ** 2 / 12
    gps_R = np.diag(np.square(noise.gps_sigma))
    widen = {k: (a, b) for k, a, b in widened}
    h_baro = _baro_row(m)
    off = m > N_DYN
    # the scratch buffers as contiguous (n, m, m) arrays
    Pp = Pp.reshape(-1)[:n * m * m].reshape(n, m, m)
    A = A.reshape(-1)[:n * m * m].reshape(n, m, m)
    # the prior, in errors around XB[0] (the offset's: linear, -XB[0] offset with the prior's variance)
    chi = _sigma_offsets(al.P0[:N_DYN, :N_DYN])
    d0 = np.array([boxminus(boxplus(al.x0, c), XB[0])[:m] for c in chi])
    mu = d0.mean(axis=0)
    P = w * ((d0 - mu).T @ (d0 - mu))
    if off:
        P[N_DYN, N_DYN] = al.P0[N_DYN, N_DYN]
    M = np.empty((n, m))
    Mp = np.empty((n, m))
    Pf = np.empty((n, m, m))
    M[0] = mu
    Pf[0] = P
    dev = np.empty((2 * N_DYN, N_DYN))
    sq = math.sqrt(N_DYN)
    if off:
        A[:] = 0.0
    for k in range(1, n):
        dt = float(t[k] - t[k - 1])
        L = _sigma_offsets(PB[k - 1, :N_DYN, :N_DYN])      # rows +-sqrt(n) l_j, P = sum l_j l_j^T
        kern.slr_points(XB[k - 1], L, accel[k], gyro[k], dt, site_asl_m, wE, XB[k], dev)
        yp, ym = dev[:N_DYN], dev[N_DYN:]
        ybar = dev.mean(axis=0)
        # with the symmetric points: A = (Y+ - Y-)^T Lc^-1 / (2 sqrt(n)) (Lc = the columns l_j), and the residual
        # covariance Omega = S^T S / (4 n), S = Y+ + Y- - 2 ybar (the part no linear map explains)
        Aa = np.linalg.solve(L[:N_DYN] / sq, (yp - ym) / (2 * sq)).T
        S = yp + ym - 2 * ybar
        if off:
            A[k, :N_DYN, :N_DYN] = Aa
            A[k, N_DYN, N_DYN] = 1.0
            # the offset is constant: its error around XB[k] is the one around XB[k - 1] moved by their difference
            mu = A[k] @ mu + np.r_[ybar, XB[k - 1, 22] - XB[k, 22]]
            P = A[k] @ P @ A[k].T
            P[:N_DYN, :N_DYN] += (S.T @ S) / (4 * N_DYN)
            P[N_DYN, N_DYN] += 1e-12 * dt
            _add_process_noise(P[:N_DYN, :N_DYN], k, dt, va, vg, saturated, accel_sigma_extra, noise)
        else:
            A[k] = Aa
            mu = A[k] @ mu + ybar
            P = A[k] @ P @ A[k].T + (S.T @ S) / (4 * N_DYN)
            _add_process_noise(P, k, dt, va, vg, saturated, accel_sigma_extra, noise)
        if k in widen:
            P[2, 2] += widen[k][0]
            P[5, 5] += widen[k][1]
        Mp[k] = mu
        Pp[k] = P
        if (k, "gps") in used:
            P, dm = _gps_update(P, meas.gps[k] - (XB[k, 0:3] + mu[0:3]), gps_R)
            mu = mu + dm
        if (k, "baro") in used:
            # the barometer reads z + offset (the smoothed state's plus its error here)
            yb = float(meas.baro[k] - (XB[k, 2] + XB[k, 22] + h_baro @ mu))
            P, dm = _scalar_update(P, h_baro, yb, baro_r2[k])
            mu = mu + dm
        P = 0.5 * (P + P.T)
        M[k] = mu
        Pf[k] = P
    XS = np.empty_like(XB)
    Ps = PB
    ms = M[-1]
    Ps[-1, :m, :m] = Pf[-1]
    XS[-1] = boxplus(XB[-1], ms)
    for k in range(n - 2, -1, -1):
        G = np.linalg.solve(Pp[k + 1].T, (Pf[k] @ A[k + 1].T).T).T
        ms = M[k] + G @ (ms - Mp[k + 1])
        Pk = Pf[k] + G @ (Ps[k + 1, :m, :m] - Pp[k + 1]) @ G.T
        Ps[k, :m, :m] = 0.5 * (Pk + Pk.T)
        XS[k] = boxplus(XB[k], ms)
    return XS, Ps


_SOS_H = np.arange(-2000.0, 30001.0, 250.0)
_SOS = np.asarray(atm.speed_of_sound_mps(_SOS_H), dtype=np.float64)


def _sound(z: float) -> float:
    return float(np.interp(z, _SOS_H, _SOS))

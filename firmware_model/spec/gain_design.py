"""Steady-state Kalman gain design for the 3-state constant-acceleration model (float64, numpy only).

State ``x = [alt, vel, acc]`` in barometer units (``units`` = barometer counts x BARO_SIGN, so that ``alt``
grows with altitude), ``units/s`` and ``units/s^2``; sample period ``dt = 2^-k`` s::

    F = [[1, dt, dt^2/2],      baro only:    H = [1 0 0],              R = baro_sigma^2            (counts^2)
         [0, 1,  dt    ],      baro + accel: H = [[1 0 0], [0 0 1]],   R = diag(baro_sigma^2, sa^2)
         [0, 0,  1     ]]                    sa = accel_sigma * units_per_metre / accel_counts_per_mps2 (units/s^2)

Process noise ``Q`` per noise model, with ``q = baro_sigma^2 / ratio`` (so that ``R/q`` equals ``ratio`` for the
barometer; docs/gain-design.md explains each ``q``):

* ``accel_only``: ``Q = diag(0, 0, q)``; ``q`` is the variance (units^2/s^4) added to the acceleration state
  **per sample** (Schultz, Schultz n.d.; the Digital Detection of Rocket Apogee notes'
  ``Q = [0 0 0; 0 0 0; 0 0 1]``). Not scaled by dt.
* ``jerk``: continuous white-noise jerk of spectral density ``q`` (units^2/s^5), discretised exactly:
  ``Q = q [[dt^5/20, dt^4/8, dt^3/6], [dt^4/8, dt^3/3, dt^2/2], [dt^3/6, dt^2/2, dt]]`` (ESP June 2001, AltOS).
* ``dwna``: discrete white-noise acceleration increment: ``Q = G G^T q`` with ``G = [dt^2/2, dt, 1]^T``; ``q`` is
  the variance (units^2/s^4) of the per-sample acceleration change, which also moves velocity and altitude.

The gain returned is the **filter-form** (a posteriori) steady-state gain ``K = P H^T (H P H^T + R)^-1`` with
``P`` the a priori (predicted) covariance solving the DARE ``P = F (P - P H^T (H P H^T + R)^-1 H P) F^T + Q``;
the firmware applies it after its predict step: ``x += K (z - H x)``. (The predictor-form gain that
``control.dlqe`` and kapogee use is ``F K``.) The closed-loop matrix is ``(I - K H) F``.

The DARE is solved with the structure-preserving doubling algorithm in time-scaled coordinates
``x' = diag(1, dt, dt^2) x`` (where ``F`` no longer depends on dt, which keeps dt = 2^-10 well conditioned), then
polished with Riccati steps and checked: residual, symmetry, positive (semi)definiteness, and every closed-loop
pole strictly inside the unit circle. A design that fails any check raises :class:`UserError` naming the config.

Every step runs in :mod:`~firmware_model.spec.detmath` (Python floats, no BLAS/LAPACK, no ``np.linalg``), so the
gains, the gate constant derived from ``P`` and every digit written into a case JSON are the same on every machine
(issue 29; docs/numerics.md, "Reproducible bytes"). scipy's ``solve_discrete_are`` stays in the tests as an
independent oracle with a tolerance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from firmware_model.runtime.errors import UserError
from firmware_model.spec.atmosphere import G0, density_kg_m3
from firmware_model.spec import detmath as dm
from firmware_model.spec.config import NOISE_MODELS, BuildConfig

#: Gain names by (measurement, state): Gi1 for the barometer innovation, Gi2 for the accelerometer's.
GAIN_NAMES_BARO: tuple[str, ...] = ("G11", "G21", "G31")
GAIN_NAMES_ACCEL: tuple[str, ...] = ("G12", "G22", "G32")
#: kalman_accel's transonic barometer gains (docs/firmware-spec.md §6 step 5).
GAIN_NAMES_TRANSONIC: tuple[str, ...] = ("G11T", "G21T", "G31T")

#: A closed-loop pole this close to the unit circle (1 - |lambda| below it) means a degenerate design.
POLE_MARGIN: float = 1e-9
#: Relative DARE residual accepted after the solve.
RESIDUAL_TOL: float = 1e-9
_MAX_DOUBLINGS: int = 80


# ---------------------------------------------------------------------------------------------------- models
def transition(dt: float) -> np.ndarray:
    """State transition F of the constant-acceleration model for sample period ``dt`` (s)."""
    return np.array([[1.0, dt, dt * dt / 2.0], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])


def process_noise(model: str, dt: float, q: float) -> np.ndarray:
    """Process-noise covariance Q (3x3, units^2, units^2/s^2, units^2/s^4 blocks) for ``model`` with intensity
    ``q`` (units^2/s^4 per sample for ``accel_only`` and ``dwna``; units^2/s^5 spectral density for ``jerk``)."""
    if model == "accel_only":
        return np.diag([0.0, 0.0, q])
    if model == "jerk":
        return q * np.array([[dt**5 / 20, dt**4 / 8, dt**3 / 6],
                             [dt**4 / 8, dt**3 / 3, dt**2 / 2],
                             [dt**3 / 6, dt**2 / 2, dt]])
    if model == "dwna":
        g = np.array([dt * dt / 2.0, dt, 1.0])
        return q * np.outer(g, g)          # element-wise products: no BLAS
    raise UserError(f"noise_model={model!r}: must be one of {', '.join(NOISE_MODELS)}")


def measurement(with_accel: bool, baro_sigma: float, accel_sigma_units: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """(H, R) for the barometer alone (1x3, 1x1; R in counts^2) or barometer + accelerometer (2x3, 2x2; R =
    diag(baro_sigma^2, accel_sigma_units^2) with the accelerometer sigma already in units/s^2)."""
    if with_accel:
        return np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]), np.diag([baro_sigma**2, accel_sigma_units**2])
    return np.array([[1.0, 0.0, 0.0]]), np.array([[baro_sigma**2]])


# ---------------------------------------------------------------------------------------------------- DARE
@dataclass(frozen=True)
class SteadyState:
    """A steady-state Kalman filter design (all arrays float64, physical units).

    * ``K``: filter-form gain, 3 x m (column j for measurement j); ``P_prior`` / ``P_post``: a priori / a posteriori
      covariance; ``poles``: eigenvalues of (I - K H) F sorted by decreasing modulus; ``iterations``: doublings
      used; ``residual``: relative DARE residual.
    """

    K: np.ndarray
    P_prior: np.ndarray
    P_post: np.ndarray
    poles: np.ndarray
    iterations: int
    residual: float
    F: np.ndarray = field(repr=False)
    H: np.ndarray = field(repr=False)
    Q: np.ndarray = field(repr=False)
    R: np.ndarray = field(repr=False)


def _riccati_step(F: dm.Matrix, H: dm.Matrix, Q: dm.Matrix, R: dm.Matrix, P: dm.Matrix) -> dm.Matrix:
    """One a-priori Riccati step P -> F (P - K S K^T) F^T + Q, K = P H^T S^-1, S = H P H^T + R, symmetrised."""
    S = dm.add(dm.matmul(dm.matmul(H, P), dm.transpose(H)), R)
    K = dm.transpose(dm.solve(S, dm.matmul(H, P)))  # P H^T S^-1 (S symmetric)
    Pp = dm.sub(P, dm.matmul(dm.matmul(K, S), dm.transpose(K)))
    Pn = dm.add(dm.matmul(dm.matmul(F, Pp), dm.transpose(F)), Q)
    return dm.symmetrize(Pn)


def _dare_residual(F: dm.Matrix, H: dm.Matrix, Q: dm.Matrix, R: dm.Matrix, P: dm.Matrix) -> float:
    diff = dm.sub(_riccati_step(F, H, Q, R, P), P)
    return dm.max_abs(diff) / max(dm.max_abs(P), dm.max_abs(Q), 1e-300)


def solve_dare(F: np.ndarray, H: np.ndarray, Q: np.ndarray, R: np.ndarray,
               where: str = "design") -> tuple[np.ndarray, int]:
    """A priori steady-state covariance P of the filter DARE ``P = F (P - P H^T (H P H^T + R)^-1 H P) F^T + Q``
    by the structure-preserving doubling algorithm (SDA; quadratic convergence, so poles near 1 cost ~log2 of
    the time constant), in the machine-independent arithmetic of :mod:`~firmware_model.spec.detmath`. Returns
    (P, doublings). Raises :class:`UserError` naming ``where`` when it does not converge or produces non-finite
    values."""
    P, it = _solve_dare(dm.as_matrix(F), dm.as_matrix(H), dm.as_matrix(Q), dm.as_matrix(R), where)
    return np.array(P, dtype=np.float64), it


def _solve_dare(F: dm.Matrix, H: dm.Matrix, Q: dm.Matrix, R: dm.Matrix, where: str) -> tuple[dm.Matrix, int]:
    n = len(F)
    eye = dm.eye(n)
    A = dm.transpose(F)                  # control-form DARE X = A^T X (I + G X)^-1 A + Hq with A = F^T
    try:
        G = dm.matmul(dm.transpose(H), dm.solve(R, H))
    except dm.SingularMatrixError:
        raise UserError(f"{where}: measurement noise R is singular") from None
    Hq = dm.symmetrize(Q)
    f_scale = max(1.0, dm.max_abs(F))
    for it in range(1, _MAX_DOUBLINGS + 1):
        W = dm.add(eye, dm.matmul(G, Hq))
        try:
            WinvA = dm.solve(W, A)
            WinvG = dm.solve(W, G)
        except dm.SingularMatrixError:
            raise UserError(f"{where}: Riccati doubling hit a singular matrix (degenerate design)") from None
        A_new = dm.matmul(A, WinvA)
        G_new = dm.symmetrize(dm.add(G, dm.matmul(dm.matmul(A, WinvG), dm.transpose(A))))
        H_new = dm.symmetrize(dm.add(Hq, dm.matmul(dm.matmul(dm.transpose(A), Hq), WinvA)))
        if not (dm.all_finite(H_new) and dm.all_finite(G_new) and dm.all_finite(A_new)):
            raise UserError(f"{where}: Riccati doubling diverged (non-finite covariance; degenerate design)")
        change = dm.max_abs(dm.sub(H_new, Hq)) / max(dm.max_abs(H_new), 1e-300)
        A, G, Hq = A_new, G_new, H_new
        if change < 1e-15 and dm.max_abs(A) < 1e-12 * f_scale:
            break
    else:
        raise UserError(f"{where}: Riccati doubling did not converge in {_MAX_DOUBLINGS} doublings "
                        "(degenerate process noise: some state gets no noise and its gain decays to zero)")
    P = Hq
    for _ in range(3):  # polish: the fixed point is attracting, a few steps remove doubling round-off
        P = _riccati_step(F, H, Q, R, P)
    return P, it


def steady_state(F: np.ndarray, H: np.ndarray, Q: np.ndarray, R: np.ndarray, where: str = "design") -> SteadyState:
    """Steady-state filter-form Kalman design for (F, H, Q, R) (any consistent units), with the checks of the
    module docstring, in machine-independent arithmetic (:mod:`~firmware_model.spec.detmath`: the same bits on
    every IEEE-754 machine). ``where`` names the configuration in error messages."""
    F, H, Q, R = (np.atleast_2d(np.asarray(a, dtype=np.float64)) for a in (F, H, Q, R))
    for name, a in (("F", F), ("H", H), ("Q", Q), ("R", R)):
        if not np.all(np.isfinite(a)):
            raise UserError(f"{where}: {name} has non-finite entries")
    Fm, Hm, Qm, Rm = (dm.as_matrix(a) for a in (F, H, Q, R))
    if dm.eigvalsh(Rm)[0] <= 0:
        raise UserError(f"{where}: measurement noise R must be positive definite")
    if dm.eigvalsh(Qm)[0] < -1e-12 * max(dm.max_abs(Qm), 1e-300):
        raise UserError(f"{where}: process noise Q must be positive semidefinite")
    if dm.max_abs(Qm) == 0.0:
        raise UserError(f"{where}: process noise Q is zero (ratio too large?): the gains would decay to zero")
    P, its = _solve_dare(Fm, Hm, Qm, Rm, where)
    S = dm.add(dm.matmul(dm.matmul(Hm, P), dm.transpose(Hm)), Rm)
    K = dm.transpose(dm.solve(S, dm.matmul(Hm, P)))
    n = len(Fm)
    IKH = dm.sub(dm.eye(n), dm.matmul(K, Hm))
    P_post = dm.symmetrize(dm.matmul(IKH, P))
    poles = dm.eigvals3(dm.matmul(IKH, Fm)) if n == 3 else None
    residual = _dare_residual(Fm, Hm, Qm, Rm, P)
    if not dm.all_finite(K) or residual > RESIDUAL_TOL:
        raise UserError(f"{where}: steady-state Riccati solution not found (relative residual {residual:.3g})")
    scale = max(dm.max_abs(P), 1e-300)
    if dm.eigvalsh(P)[0] < -1e-9 * scale:
        raise UserError(f"{where}: Riccati solution is not positive semidefinite (degenerate design)")
    if poles is None:
        raise UserError(f"{where}: the design handles 3 states, got {n}")
    rho = max(_modulus(p) for p in poles)
    if not rho < 1.0 - POLE_MARGIN:
        raise UserError(f"{where}: closed-loop pole |lambda| = {rho:.12f} is not inside the unit circle "
                        f"(degenerate design: a state gets no process noise and its gain decays to zero)")
    return SteadyState(K=np.array(K), P_prior=np.array(P), P_post=np.array(P_post), poles=np.array(poles),
                       iterations=its, residual=residual, F=F, H=H, Q=Q, R=R)


def _modulus(z: complex) -> float:
    """|z| with basic operations only (``abs(complex)`` calls the C library's hypot)."""
    return math.sqrt(z.real * z.real + z.imag * z.imag)


# ---------------------------------------------------------------------------------------------------- from a config
#: The rms of a uniform rounding error of one step: 1/sqrt(12) of the step.
QUANT_RMS: float = 1.0 / math.sqrt(12.0)


def quantization_sigma_counts(cfg: BuildConfig) -> float:
    """The barometer's quantization noise, 1/sqrt(12) of one count (or pascal), in metres at ``quant_alt_m`` above
    the pad, expressed in the design's barometer units (pad counts: x ``units_per_metre``). A count is
    ``pa_per_count / (rho(h) g)`` metres at altitude h and ``units_per_metre`` counts are a metre at the pad, so
    this is ``rho_pad / rho(pad + quant_alt_m) / sqrt(12)``; the pad's density is ``units_per_metre *
    pa_per_count / g`` and its altitude the standard atmosphere's altitude of that density (sea level when the
    density is higher)."""
    rho_pad = cfg.units_per_metre * cfg.baro_transfer[0] / G0
    lo, hi = 0.0, 11000.0
    if float(density_kg_m3(lo)) <= rho_pad:
        z_pad = 0.0
        rho_pad = float(density_kg_m3(0.0))
    else:
        for _ in range(60):                         # bisection: density falls with altitude
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if float(density_kg_m3(mid)) > rho_pad else (lo, mid)
        z_pad = 0.5 * (lo + hi)
    return QUANT_RMS * rho_pad / float(density_kg_m3(z_pad + cfg.quant_alt_m))


def design_baro_sigma(cfg: BuildConfig) -> float:
    """The barometer sigma (counts) the design uses: ``baro_sigma``, at least the quantization floor of
    :func:`quantization_sigma_counts` (issue 20: a noise-free ADC is not a noise-free altimeter)."""
    return max(float(cfg.baro_sigma), quantization_sigma_counts(cfg))


def accel_sigma_units(cfg: BuildConfig) -> float:
    """Accelerometer error in state units: the root sum of squares of accel_sigma (counts, at least the 1/sqrt(12)
    count of its own quantization) and the model error ``accel_model_g`` (g, in counts: the axial reading taken as
    vertical on a tilted flight), times units_per_metre / accel_counts_per_mps2 (units/s^2)."""
    noise = max(cfg.accel_sigma, QUANT_RMS)
    model = cfg.accel_model_g * G0 * cfg.accel_counts_per_mps2
    # sqrt of the sum of squares, not math.hypot: the same bits on every machine (spec/detmath.py)
    return math.sqrt(noise * noise + model * model) * cfg.units_per_metre / cfg.accel_counts_per_mps2


def describe(cfg: BuildConfig) -> str:
    """A short name of the design parameters of ``cfg`` for messages."""
    return (f"build config (program={cfg.program}, k={cfg.k}, noise_model={cfg.noise_model}, ratio={cfg.ratio:g}, "
            f"baro_sigma={cfg.baro_sigma:g}, accel_sigma={cfg.accel_sigma:g})")


def design_kalman(k: int, noise_model: str, ratio: float | None, *, with_accel: bool = False,
                  baro_sigma: float = 1.0, accel_sigma_units: float = 1.0, q: float | None = None,
                  where: str | None = None) -> SteadyState:
    """Steady-state design for dt = 2^-k s (k = 0..10), ``noise_model`` and R/q = ``ratio`` (q = baro_sigma^2 /
    ratio), barometer only or barometer + accelerometer (barometer sigma in counts, accelerometer sigma in
    units/s^2). Alternatively give the process-noise intensity ``q`` itself (units of the model, see the module
    docstring) and ``ratio=None``. Gains in physical units: column 0 for the barometer innovation (per unit:
    1, 1/s, 1/s^2), column 1 for the accelerometer innovation (per units/s^2: s^2, s, 1). Raises
    :class:`UserError` for k outside 0..10, ratio or q <= 0, a bad model or a degenerate design."""
    if (ratio is None) == (q is None):
        raise UserError(f"design (k={k}, noise_model={noise_model}): give exactly one of ratio={ratio!r} and q={q!r}")
    where = where or (f"design (k={k}, noise_model={noise_model}, "
                      + (f"ratio={ratio!r})" if ratio is not None else f"q={q!r})"))
    if isinstance(k, bool) or not isinstance(k, int) or not 0 <= k <= 10:
        raise UserError(f"{where}: k={k!r}: sample period 2^-k needs an integer k in 0..10")
    for name, val in (("ratio", ratio), ("q", q), ("baro_sigma", baro_sigma), ("accel_sigma", accel_sigma_units)):
        if val is None:
            continue
        if isinstance(val, bool) or not isinstance(val, (int, float)) or not math.isfinite(val) or val <= 0:
            raise UserError(f"{where}: {name}={val!r}: must be a finite number > 0")
    if noise_model not in NOISE_MODELS:
        raise UserError(f"{where}: noise_model={noise_model!r}: must be one of {', '.join(NOISE_MODELS)}")
    dt = math.ldexp(1.0, -k)
    norm = baro_sigma**2  # K is invariant under a common scaling of Q and R: solve with R_baro = 1
    if q is None:
        assert ratio is not None  # exactly one of them is None: checked above
        q = norm / ratio
        q_norm = 1.0 / ratio  # not q / norm: the design must depend on the ratio alone, to the last bit
    else:
        q_norm = q / norm
    F = transition(dt)
    Q = process_noise(noise_model, dt, q)
    H, R = measurement(with_accel, baro_sigma, accel_sigma_units)
    # Time-scaled coordinates x' = T x, T = diag(1, dt, dt^2); accelerometer measurement scaled by dt^2 too.
    T = np.array([1.0, dt, dt * dt])
    Sm = np.array([1.0, dt * dt]) if with_accel else np.array([1.0])
    Fs = transition(1.0)
    Qs = process_noise(noise_model, dt, q_norm) * np.outer(T, T)
    Hs = H / T[None, :] * Sm[:, None]
    Rs = R * np.outer(Sm, Sm) / norm  # the barometer entry is exactly 1
    ss = steady_state(Fs, Hs, Qs, Rs, where)
    K = ss.K / T[:, None] * Sm[None, :]
    P_prior = ss.P_prior * norm / np.outer(T, T)
    P_post = ss.P_post * norm / np.outer(T, T)
    return SteadyState(K=K, P_prior=P_prior, P_post=P_post, poles=ss.poles, iterations=ss.iterations,
                       residual=ss.residual, F=F, H=H, Q=Q, R=R)


def design_config(cfg: BuildConfig) -> SteadyState:
    """The steady-state design of a Kalman build config (``kalman_baro``: baro only; ``kalman_accel``: baro +
    accel). Raises :class:`UserError` for a recursive program or a degenerate design."""
    if cfg.program not in ("kalman_baro", "kalman_accel"):
        raise UserError(f"build config: program={cfg.program!r} has no Kalman gains to design")
    return design_kalman(cfg.k, cfg.noise_model, cfg.ratio, with_accel=cfg.program == "kalman_accel",
                         baro_sigma=design_baro_sigma(cfg), accel_sigma_units=accel_sigma_units(cfg),
                         where=describe(cfg))


def transonic_design(cfg: BuildConfig) -> SteadyState:
    """kalman_accel's transonic design: the same process noise q = baro_sigma^2 / ratio, the barometer's variance
    multiplied by ``transonic_r_factor`` (its weight falls, never to zero: a floor, not a lockout)."""
    if cfg.program != "kalman_accel":
        raise UserError(f"build config: program={cfg.program!r} has no transonic gains")
    sigma = design_baro_sigma(cfg)
    return design_kalman(cfg.k, cfg.noise_model, None, q=sigma**2 / cfg.ratio, with_accel=True,
                         baro_sigma=sigma * math.sqrt(cfg.transonic_r_factor),
                         accel_sigma_units=accel_sigma_units(cfg), where=describe(cfg) + " (transonic)")


def innovation_sigma_m(cfg: BuildConfig) -> float:
    """Steady-state standard deviation (m) of the barometer innovation, sqrt(H P H^T + R) of the design, converted
    from barometer units with the pad's ``units_per_metre`` (docs/firmware-spec.md §6 step 4: the gate)."""
    ss = design_config(cfg)
    return math.sqrt(float(ss.P_prior[0, 0] + ss.R[0, 0])) / cfg.units_per_metre


def float_gains(cfg: BuildConfig) -> dict[str, float]:
    """Unquantized gains of ``cfg`` by name: G11 G21 G31 (1, 1/s, 1/s^2), and for kalman_accel G12 G22 G32
    (s^2, s, 1), the transonic G11T G21T G31T and ACC_G (Q24.8 m/s^2 per accelerometer count: the Kalman programs
    run in metres; the gains are the same in metres as in barometer units because K is invariant under a common
    scaling of Q and R). Empty for recursive programs."""
    if cfg.program not in ("kalman_baro", "kalman_accel"):
        return {}
    ss = design_config(cfg)
    gains = {name: float(ss.K[i, 0]) for i, name in enumerate(GAIN_NAMES_BARO)}
    if cfg.program == "kalman_accel":
        gains.update({name: float(ss.K[i, 1]) for i, name in enumerate(GAIN_NAMES_ACCEL)})
        tr = transonic_design(cfg)
        gains.update({name: float(tr.K[i, 0]) for i, name in enumerate(GAIN_NAMES_TRANSONIC)})
        gains["ACC_G"] = 256.0 / cfg.accel_counts_per_mps2
    return gains


def closed_loop_poles(ss: SteadyState, K: np.ndarray | None = None) -> np.ndarray:
    """Eigenvalues of (I - K H) F for the design (or for another gain ``K``, e.g. the quantized one), sorted by
    decreasing modulus (machine-independent: :func:`~firmware_model.spec.detmath.eigvals3`)."""
    K = ss.K if K is None else np.asarray(K, dtype=np.float64)
    Km, Hm = dm.as_matrix(K), dm.as_matrix(ss.H)
    A = dm.matmul(dm.sub(dm.eye(3), dm.matmul(Km, Hm)), dm.as_matrix(ss.F))
    return np.array(dm.eigvals3(A))

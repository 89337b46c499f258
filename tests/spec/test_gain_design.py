"""Gain design (firmware_model.spec.gain_design) checked against independent oracles:

* scipy.linalg.solve_discrete_are (test-only dependency) for every k = 0..10, every noise model, both
  measurement sets and several R/q ratios;
* a long time-varying Kalman recursion written here in textbook form (predict, gain, (I-KH)P) until its gain
  stops changing;
* a Monte Carlo run of the steady-state filter on simulated noise, whose empirical a posteriori error covariance
  must match the design's P_post (this separates filter-form from predictor-form gains);
* degenerate and invalid designs raise UserError naming the field/config.
"""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from firmware_model.spec.config import BuildConfig
from firmware_model.spec.gain_design import (closed_loop_poles, design_config, design_kalman, measurement,
                                             process_noise, steady_state, transition)
from firmware_model.spec.design_report import design_report
from firmware_model.runtime.errors import UserError

scipy_linalg = pytest.importorskip("scipy.linalg", reason="scipy is the DARE oracle (test extra)")

MODELS = ("accel_only", "jerk", "dwna")
BARO_RATIOS = (1e3, 5e4, 1e6)
ACCEL_RATIOS = (30.0, 100.0, 300.0)
BARO_SIGMA = 2.0
ACCEL_SIGMA_UNITS = 0.335  # default config: 20 counts * 3.5 units/m / 208.8 counts per m/s^2


def scipy_filter_gain(F: np.ndarray, H: np.ndarray, Q: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Filter-form steady-state gain from scipy's DARE solution (a priori P): K = P H^T (H P H^T + R)^-1."""
    P = scipy_linalg.solve_discrete_are(F.T, H.T, Q, R)
    return P @ H.T @ np.linalg.inv(H @ P @ H.T + R), P


def textbook_time_varying(F: np.ndarray, H: np.ndarray, Q: np.ndarray, R: np.ndarray, max_steps: int = 400_000
                          ) -> tuple[np.ndarray, int]:
    """Run the time-varying Kalman covariance recursion from a large diffuse prior until the gain has stopped
    changing (relative change < 1e-12 over 64 steps). Returns (K, steps)."""
    P = np.diag([1e4, 1e4, 1e4]) * float(np.max(R))
    I3 = np.eye(3)
    K_old = None
    for n in range(max_steps):
        K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)   # gain from the predicted covariance
        P = (I3 - K @ H) @ P                           # correction: (I - KH) P
        P = F @ P @ F.T + Q                            # prediction
        P = (P + P.T) / 2
        if n % 64 == 0:
            if K_old is not None and np.max(np.abs(K - K_old) / np.maximum(np.abs(K), 1e-300)) < 1e-12:
                return K, n
            K_old = K
    raise AssertionError("time-varying recursion did not converge")


# ---------------------------------------------------------------------------------------------------- vs scipy
@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("with_accel", [False, True], ids=["baro", "baro+accel"])
def test_dare_matches_scipy_for_every_k_and_ratio(model: str, with_accel: bool) -> None:
    """Relative gain agreement 1e-6. Both solvers agree to ~1e-14 at k=0; the difference grows to ~5e-8 at
    k=10 because scipy solves the unscaled problem, whose conditioning grows like dt^-4 (ours is time-scaled);
    the time-varying test below arbitrates."""
    for k in range(11):
        for ratio in ACCEL_RATIOS if with_accel else BARO_RATIOS:
            ss = design_kalman(k, model, ratio, with_accel=with_accel, baro_sigma=BARO_SIGMA,
                               accel_sigma_units=ACCEL_SIGMA_UNITS)
            # the oracle builds its own F, Q, H, R from the documented formulas
            dt = 2.0**-k
            q = BARO_SIGMA**2 / ratio
            F = np.array([[1, dt, dt * dt / 2], [0, 1, dt], [0, 0, 1]])
            if model == "accel_only":
                Q = np.diag([0, 0, q])
            elif model == "jerk":
                Q = q * np.array([[dt**5 / 20, dt**4 / 8, dt**3 / 6], [dt**4 / 8, dt**3 / 3, dt**2 / 2],
                                  [dt**3 / 6, dt**2 / 2, dt]])
            else:
                G = np.array([[dt * dt / 2], [dt], [1.0]])
                Q = q * G @ G.T
            if with_accel:
                H = np.array([[1.0, 0, 0], [0, 0, 1.0]])
                R = np.diag([BARO_SIGMA**2, ACCEL_SIGMA_UNITS**2])
            else:
                H, R = np.array([[1.0, 0, 0]]), np.array([[BARO_SIGMA**2]])
            K_ref, P_ref = scipy_filter_gain(F, H, Q, R)
            np.testing.assert_allclose(ss.K, K_ref, rtol=1e-6, atol=0, err_msg=f"k={k} ratio={ratio}")
            np.testing.assert_allclose(ss.P_prior, P_ref, rtol=1e-6, atol=1e-12 * np.max(np.abs(P_ref)))
            assert np.max(np.abs(ss.poles)) < 1.0
            # the design's own matrices are the documented ones
            np.testing.assert_allclose(ss.Q, Q, rtol=1e-15, atol=0)
            np.testing.assert_array_equal(ss.F, F)


# ---------------------------------------------------------------------------------------------------- vs time-varying
@pytest.mark.parametrize("k,model,with_accel,ratio", [
    (7, "accel_only", False, 5e4),   # the default build
    (0, "dwna", False, 1e3),
    (4, "jerk", False, 1e6),
    (10, "accel_only", False, 1e3),
    (7, "accel_only", True, 100.0),
    (10, "jerk", True, 100.0),
    (2, "dwna", True, 30.0),
])
def test_steady_state_equals_limit_of_time_varying_filter(k: int, model: str, with_accel: bool, ratio: float) -> None:
    ss = design_kalman(k, model, ratio, with_accel=with_accel, baro_sigma=BARO_SIGMA,
                       accel_sigma_units=ACCEL_SIGMA_UNITS)
    K_tv, steps = textbook_time_varying(ss.F, ss.H, ss.Q, ss.R)
    np.testing.assert_allclose(ss.K, K_tv, rtol=1e-7, atol=0, err_msg=f"after {steps} steps")


def test_filter_form_not_predictor_form_and_covariances_consistent() -> None:
    ss = design_config(BuildConfig())
    # P_post = (I - K H) P_prior and P_prior = F P_post F^T + Q (the two halves of one Riccati step)
    np.testing.assert_allclose(ss.P_post, (np.eye(3) - ss.K @ ss.H) @ ss.P_prior, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(ss.P_prior, ss.F @ ss.P_post @ ss.F.T + ss.Q, rtol=1e-9, atol=1e-15)
    # the predictor-form gain F K (control.dlqe, kapogee) differs noticeably in the velocity/altitude rows
    Kp = ss.F @ ss.K
    assert abs(Kp[0, 0] / ss.K[0, 0] - 1) > 1e-3


def test_monte_carlo_error_covariance_matches_p_post() -> None:
    """Simulate the model (process + measurement noise) and run the steady-state filter in filter form.

    * The empirical covariance of the a posteriori error (x - x_hat) must match P_post (8000 chains: ~1.6%
      sampling error per variance; 10% tolerance).
    * Orthogonality: the a posteriori error is uncorrelated with the innovation for the optimal filter-form K
      (|correlation| < 0.05, ~3 sampling sigma); the predictor-form gain F K applied as a filter-form correction gives
      Cov(err, innovation) = (K - F K) S, a correlation of about -0.26 in altitude here (measured), which the same
      estimate must see (so this test has power against the predictor/filter-form mix-up).
    """
    ss = design_kalman(0, "dwna", 1e3, with_accel=False, baro_sigma=BARO_SIGMA)
    rng = np.random.default_rng(20240601)
    n_chains = 8000
    rho = float(np.max(np.abs(ss.poles)))
    steps = int(math.ceil(25 / (1 - rho)))
    dt, q = 1.0, BARO_SIGMA**2 / 1e3
    g = np.array([dt * dt / 2, dt, 1.0]) * math.sqrt(q)  # dwna: w = G n sqrt(q), n ~ N(0, 1)

    def run(K: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        err = np.zeros((n_chains, 3))  # x - x_hat; the estimate's dynamics cancel, only noise drives the error
        innov = np.zeros((n_chains, 1))
        for _ in range(steps):
            w = rng.standard_normal((n_chains, 1)) * g[None, :]
            v = rng.standard_normal((n_chains, 1)) * math.sqrt(ss.R[0, 0])
            prior = err @ ss.F.T + w                     # x - F x_hat
            innov = prior @ ss.H.T + v                   # z - H F x_hat
            err = prior - innov @ K.T                    # x - (F x_hat + K innov)
        return err, innov[:, 0]

    def corr(a: np.ndarray, b: np.ndarray) -> float:
        return float(np.corrcoef(a, b)[0, 1])

    err, innov = run(ss.K)
    np.testing.assert_allclose(np.diag(np.cov(err.T)), np.diag(ss.P_post), rtol=0.10)
    for i in range(3):
        assert abs(corr(err[:, i], innov)) < 0.05, i
    err_p, innov_p = run(ss.F @ ss.K)
    assert corr(err_p[:, 0], innov_p) < -0.2


# ---------------------------------------------------------------------------------------------------- properties
@given(st.integers(0, 10), st.sampled_from(MODELS), st.floats(1e2, 1e7), st.floats(0.05, 50.0))
def test_baro_only_gains_depend_only_on_the_ratio(k: int, model: str, ratio: float, sigma: float) -> None:
    """Scaling R and q together leaves K unchanged: the baro-only design depends on R/q, not on baro_sigma."""
    a = design_kalman(k, model, ratio, baro_sigma=1.0)
    b = design_kalman(k, model, ratio, baro_sigma=sigma)
    np.testing.assert_allclose(a.K, b.K, rtol=1e-9)


@given(st.integers(0, 10), st.sampled_from(MODELS), st.floats(1e3, 1e6))
def test_more_process_noise_means_faster_filter(k: int, model: str, ratio: float) -> None:
    """Lowering R/q (trusting the model less) raises the altitude gain and moves the slowest pole inward."""
    slow = design_kalman(k, model, ratio)
    fast = design_kalman(k, model, ratio / 10)
    assert fast.K[0, 0] > slow.K[0, 0]
    assert np.max(np.abs(fast.poles)) < np.max(np.abs(slow.poles))


def test_poles_match_closed_loop_matrix() -> None:
    ss = design_config(BuildConfig(program="kalman_accel", ratio=100.0))
    A = (np.eye(3) - ss.K @ ss.H) @ ss.F
    np.testing.assert_allclose(np.sort_complex(closed_loop_poles(ss)), np.sort_complex(np.linalg.eigvals(A)),
                               rtol=1e-12)
    assert np.all(np.abs(ss.poles) < 1)


# ---------------------------------------------------------------------------------------------------- errors
def test_position_only_process_noise_is_degenerate() -> None:
    """kapogee's Q (variance added to P[0][0] only): velocity/acceleration gains decay to zero."""
    F = transition(2.0**-7)
    H, R = measurement(False, 2.0)
    with pytest.raises(UserError, match="kapogee-like config.*(degenerate|did not converge|unit circle)"):
        steady_state(F, H, np.diag([8e-5, 0.0, 0.0]), R, where="kapogee-like config")


def test_zero_process_noise_is_degenerate() -> None:
    H, R = measurement(False, 2.0)
    with pytest.raises(UserError, match="Q is zero"):
        steady_state(transition(1.0), H, np.zeros((3, 3)), R, where="cfg")


def test_vanishing_q_from_config_names_ratio() -> None:
    """Issue 33: the config refuses R/q above 1e12 (the process noise vanishes) before the design runs."""
    with pytest.raises(UserError, match="ratio: 1e\\+300 is out of range; allowed: .* <= 1e\\+12"):
        design_config(BuildConfig(ratio=1e300))


@pytest.mark.parametrize("kwargs,field", [
    (dict(k=11), "k=11"), (dict(k=-1), "k=-1"), (dict(ratio=0.0), "ratio=0.0"), (dict(ratio=-5.0), "ratio=-5.0"),
    (dict(noise_model="white"), "noise_model='white'"),
])
def test_bad_design_arguments_name_the_field(kwargs: dict, field: str) -> None:
    args = dict(k=7, noise_model="accel_only", ratio=5e4) | kwargs
    with pytest.raises(UserError, match=field.replace("+", "\\+")):
        design_kalman(args["k"], args["noise_model"], args["ratio"])
    with pytest.raises(UserError, match=field.split("=")[0]):
        BuildConfig(**kwargs)


def test_unknown_noise_model_in_process_noise() -> None:
    with pytest.raises(UserError, match="noise_model='x'"):
        process_noise("x", 1.0, 1.0)


def test_recursive_program_has_no_kalman_design() -> None:
    with pytest.raises(UserError, match="program='recursive'"):
        design_config(BuildConfig(program="recursive"))


# ---------------------------------------------------------------------------------------------------- report
@pytest.mark.parametrize("program", ["kalman_baro", "kalman_accel", "recursive"])
def test_design_report_is_json_and_consistent(program: str) -> None:
    cfg = BuildConfig(program=program, ratio=100.0 if program == "kalman_accel" else 5e4)
    rep = json.loads(json.dumps(design_report(cfg)))
    assert rep["config"]["program"] == program
    assert set(rep["gains"]) == set(rep["float_gains"])
    for name, g in rep["gains"].items():
        assert g["value"] == g["m"] / 2 ** g["s"]
        assert abs(g["rel_error"]) <= 2.0**-15
        assert g["target"] == rep["float_gains"][name]
    if program == "recursive":
        assert rep["gains"] == {} and "poles" not in rep
    else:
        assert len(rep["poles"]) == 3 and all(p["abs"] < 1 for p in rep["poles"])
        assert all(p["abs"] < 1 for p in rep["poles_quantized"])
        # quantization moves the poles by about the gain error, not more
        for pf, pq in zip(rep["poles"], rep["poles_quantized"]):
            assert abs(pf["abs"] - pq["abs"]) < 1e-4


# ---------------------------------------------------------------------------------------------------- CLI
def run_cli(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    """Run ``fwemu`` through its real main() (error handling included) with only the design command loaded,
    so this test does not depend on the other parts' CLI modules."""
    import firmware_model.cli.main as cli

    monkeypatch.setattr(cli, "COMMAND_MODULES", ("firmware_model.cli.design",))
    rc = cli.main(list(argv))
    out, err = capsys.readouterr()
    return rc, out, err


def test_cli_design_text(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    rc, out, err = run_cli(monkeypatch, capsys, "design")
    assert rc == 0 and err == ""
    assert "G11" in out and "G31_S" in out and "closed-loop poles" in out
    c = design_report(BuildConfig())
    assert f"G11_M      EQU {c['gains']['G11']['m']}" in out


def test_cli_design_json_overrides(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
                                   tmp_path) -> None:
    cfg = tmp_path / "b.json"
    cfg.write_text(json.dumps({"program": "kalman_accel", "ratio": 100, "k": 5}))
    rc, out, _ = run_cli(monkeypatch, capsys, "design", "--config", str(cfg), "--k", "6", "--noise-model", "jerk",
                         "--rounding", "half_up", "--json")
    assert rc == 0
    rep = json.loads(out)
    assert rep["config"]["k"] == 6 and rep["config"]["noise_model"] == "jerk" and rep["equates"]["ROUND"] == 1
    assert rep["config"]["ratio"] == 100 and "G32" in rep["gains"]
    assert rep == json.loads(json.dumps(design_report(BuildConfig(program="kalman_accel", ratio=100, k=6,
                                                                  noise_model="jerk", rounding="half_up"))))


@pytest.mark.parametrize("args,content,pattern", [
    (("--k", "11"), None, r"--k: k: 11 is out of range; allowed: an integer 0\.\.10"),
    (("--ratio", "0"), None, r"--ratio: ratio: 0\.0 is out of range; allowed: a number > 0"),
    (("--ratio", "1e300"), None, r"--ratio: ratio: 1e\+300 is out of range"),
    ((), '{"k": 7, "ratoi": 3}', r"b\.json: 'ratoi': unknown field; known: "),
    ((), '{"k": 7,\n "ratio": }', r"b\.json:2:.*invalid JSON"),
])
def test_cli_design_bad_config_is_one_line(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
                                           tmp_path, args: tuple[str, ...], content: str | None,
                                           pattern: str) -> None:
    argv = ["design", *args]
    if content is not None:
        (tmp_path / "b.json").write_text(content)
        argv += ["--config", str(tmp_path / "b.json")]
    rc, out, err = run_cli(monkeypatch, capsys, *argv)
    assert rc == 2 and out == ""
    assert err.startswith("fwemu: error: ") and err.count("\n") == 1 and "Traceback" not in err
    assert re.search(pattern, err), err


@pytest.mark.parametrize("k", [0, 4, 7, 10])
def test_dwna_equals_accel_only_for_baro_only(k: int) -> None:
    """DWNA: x_(n+1) = F (x_n + e3 w_n); accel_only: x_(n+1) = F x_n + e3 w_n. With u_n = x_n + e3 w_n the
    DWNA model is u_(n+1) = F u_n + e3 w_(n+1) (accel_only) and z_n = H u_n + v_n because H e3 = 0 for the
    barometer; w_n is independent of z_0..z_n, so E[x_n | z] = E[u_n | z] and the gains are identical. The
    accelerometer row has H e3 = 1, so with it they must differ."""
    a = design_kalman(k, "accel_only", 5e4)
    b = design_kalman(k, "dwna", 5e4)
    np.testing.assert_allclose(a.K, b.K, rtol=1e-10)
    a2 = design_kalman(k, "accel_only", 100.0, with_accel=True, baro_sigma=2.0, accel_sigma_units=0.335)
    b2 = design_kalman(k, "dwna", 100.0, with_accel=True, baro_sigma=2.0, accel_sigma_units=0.335)
    assert np.max(np.abs(b2.K / a2.K - 1)) > 0.1


@given(st.integers(0, 10), st.sampled_from(MODELS), st.booleans(), st.floats(-8.0, 14.0))
def test_design_succeeds_and_is_a_riccati_fixed_point_over_extreme_ratios(k: int, model: str, with_accel: bool,
                                                                          log_ratio: float) -> None:
    """Every documented model/k works for R/q from 1e-8 to 1e14 (scipy's QZ-based solver fails on some of these):
    the returned P_prior is a fixed point of one textbook Riccati step (computed here, unscaled) and the gain is
    the filter-form gain of that P."""
    ss = design_kalman(k, model, 10.0**log_ratio, with_accel=with_accel, baro_sigma=BARO_SIGMA,
                       accel_sigma_units=ACCEL_SIGMA_UNITS)
    P = ss.P_prior
    S_inv = np.linalg.inv(ss.H @ P @ ss.H.T + ss.R)
    K = P @ ss.H.T @ S_inv
    # the oracle's own rounding: sums of terms that can cancel (baro+accel), so bound by the sum of |terms|
    cancel = np.abs(P) @ np.abs(ss.H.T) @ np.abs(S_inv)
    assert np.all(np.abs(ss.K - K) <= 1e-8 * np.abs(K) + 1e-12 * cancel)
    P_next = ss.F @ ((np.eye(3) - K @ ss.H) @ P) @ ss.F.T + ss.Q
    # per diagonal entry (they span many decades): relative 1e-8, plus the oracle's own rounding where
    # (I - KH) P cancels (e.g. P33 = 4e8 against an accelerometer trusted 1e8 times more than the model)
    F_abs = np.abs(ss.F)
    cancel_p = F_abs @ (np.abs(P) + np.abs(K) @ np.abs(ss.H) @ np.abs(P)) @ F_abs.T + np.abs(ss.Q)
    for i in range(3):
        assert abs(P_next[i, i] - P[i, i]) <= 1e-8 * P[i, i] + 1e-12 * cancel_p[i, i], i
    assert np.all(np.abs(ss.poles) < 1)


@pytest.mark.parametrize("model", MODELS)
def test_design_from_q_equals_design_from_ratio(model: str) -> None:
    """q given directly (units of the model) is the same design as ratio = baro_sigma^2 / q."""
    a = design_kalman(6, model, None, q=3e-4, baro_sigma=BARO_SIGMA, with_accel=True,
                      accel_sigma_units=ACCEL_SIGMA_UNITS)
    b = design_kalman(6, model, BARO_SIGMA**2 / 3e-4, baro_sigma=BARO_SIGMA, with_accel=True,
                      accel_sigma_units=ACCEL_SIGMA_UNITS)
    np.testing.assert_allclose(a.K, b.K, rtol=1e-12)
    np.testing.assert_allclose(a.Q, process_noise(model, 2.0**-6, 3e-4), rtol=1e-15)
    with pytest.raises(UserError, match="exactly one of ratio"):
        design_kalman(6, model, 100.0, q=1.0)
    with pytest.raises(UserError, match="q=-1.0"):
        design_kalman(6, model, None, q=-1.0)

"""Build constants (firmware_model.spec.build_constants): gain quantization bound, threshold conversions, equates.

The quantization bound: m is the nearest integer to g 2^s, so |m - g 2^s| <= 1/2. Without a carry,
|g 2^s| >= 2^14 and |rel_error| = |m - g 2^s| / |g 2^s| <= (1/2) / 2^14 = 2^-15. With a carry (g 2^(s+1) rounded
to 2^15, i.e. |g 2^(s+1)| >= 32767.5), m = 2^14 and |g 2^s| is in [16383.75, 2^14), so |m - g 2^s| <= 1/4 and
|rel_error| <= 0.25 / 16383.75 < 2^-15. The tests check it with exact fractions, not with the code's arithmetic.
"""

from __future__ import annotations

import math
from fractions import Fraction

import pytest
from hypothesis import given
from hypothesis import strategies as st

from firmware_model.spec.config import PROGRAMS, BuildConfig
from firmware_model.spec.build_constants import FirmwareConstants, build_constants
from firmware_model.spec.fixed import QGain, quantize_gain
from firmware_model.spec.gain_design import float_gains
from firmware_model.runtime.errors import UserError
from firmware_model.spec.fixed import mulg

REPRESENTABLE = st.floats(2.0**-33, 32767.0, allow_nan=False, allow_infinity=False)
INT32 = st.integers(-(2**31), 2**31 - 1)


@given(REPRESENTABLE, st.booleans())
def test_quantize_gain_has_15_significant_bits_and_is_nearest(g: float, negative: bool) -> None:
    g = -g if negative else g
    q = quantize_gain("G", g)
    assert 2**14 <= abs(q.m) <= 2**15 - 1 and 0 <= q.s <= 47
    assert q.target == g
    exact_scaled = Fraction(g) * 2**q.s
    assert abs(q.m - exact_scaled) <= Fraction(1, 2)                   # nearest mantissa
    rel = (Fraction(q.m, 2**q.s) - Fraction(g)) / Fraction(g)
    assert abs(rel) <= Fraction(1, 2**15)                              # the derived bound, exactly
    assert math.isclose(q.rel_error, float(rel), rel_tol=1e-12, abs_tol=1e-300)
    assert q.value == q.m / 2**q.s


def test_quantize_gain_carry_case() -> None:
    """g * 2^s rounds up to 2^15: one bit less shift, m = 2^14."""
    g = (2**15 - 0.25) / 2**20
    q = quantize_gain("G", g)
    assert (q.m, q.s) == (2**14, 19)
    assert abs(q.rel_error) <= 2**-15


def test_quantize_gain_exact_powers_of_two() -> None:
    for e in range(-33, 15):
        q = quantize_gain("G", 2.0**e)
        assert q.m == 2**14 and q.s == 14 - e and q.rel_error == 0.0


def test_quantize_gain_zero() -> None:
    assert quantize_gain("G", 0.0) == QGain(0, 0, 0.0)
    assert QGain(0, 0, 0.0).rel_error == 0.0


@pytest.mark.parametrize("g,msg", [
    (32767.5, "too large"), (1e6, "too large"), (-40000.0, "too large"),
    (2.0**-34, "too small"), (-1e-12, "too small"), (float("nan"), "not a finite"), (float("inf"), "not a finite"),
])
def test_unrepresentable_gain_names_the_gain(g: float, msg: str) -> None:
    with pytest.raises(UserError, match=f"gain G21=.*{msg}"):
        quantize_gain("G21", g)


def test_qgain_rejects_out_of_range_fields() -> None:
    with pytest.raises(UserError):
        QGain(32768, 0, 1.0)
    with pytest.raises(UserError):
        QGain(1, 48, 1.0)


@given(INT32, REPRESENTABLE, st.sampled_from(["floor", "half_up"]))
def test_mulg_with_quantized_gain_error_bound(e: int, g: float, mode: str) -> None:
    """|mulg(e, Q(g)) - e g| <= |e g| 2^-15 + 1 (floor) or + 1/2 (half_up), whenever no wrap happens."""
    q = quantize_gain("G", g)
    exact = Fraction(e) * Fraction(g)
    if abs(exact) * (1 + Fraction(1, 2**15)) + 1 >= 2**31:
        return  # would wrap: the bound is about rounding, not overflow
    got = mulg(e, q, mode)
    slack = Fraction(1) if mode == "floor" else Fraction(1, 2)
    assert abs(got - exact) <= abs(exact) / 2**15 + slack


# ---------------------------------------------------------------------------------------------------- build_constants
def test_default_kalman_baro_thresholds_in_documented_units() -> None:
    c = build_constants(BuildConfig())  # the Kalman programs run in metres: Q24.8, 256 per m/s
    assert c.K == 7 and c.ROUND == 0 and c.BARO_SIGN == -1
    assert c.V_LIFT == 7680           # 30 m/s * 256
    assert c.MACH_VLO == 62464        # 244 * 256
    assert c.MACH_VHI == 93696        # 366 * 256
    assert c.MACH_E == 7680           # 30 m * 256
    assert c.CAL_P == 5 and c.GATE_N == 13 and c.APO_N == 8   # round(0.1 * 128) = 13, round(0.06 * 128) = 8
    assert c.ALT_SHIFT == 7 and c.ALT_N == 513                 # 16 - 9 = 7: 2^9 segments + 1 node
    assert (c.BARO_MIN, c.BARO_MAX) == (0, 65535)
    assert c.V_GATE == 1069250        # 40 m/s * (2048 / 9.80665) counts/(m/s^2) * 128 samples/s = 1069249.9
    assert set(c.gains) == {"G11", "G21", "G31"}


def test_recursive_velocity_units_are_accel_counts_times_samples() -> None:
    c = build_constants(BuildConfig(program="recursive", k=5, liftoff_mps=10.0, gate_mps=50.0, shift=4,
                                    threshold_q8=128, rounding="half_up"))
    per_mps = 2048 / 9.80665 * 32
    assert c.V_LIFT == round(10 * per_mps) == 66828   # 66828.12
    assert c.V_GATE == round(50 * per_mps) == 334141  # 334140.6
    assert c.S == 4 and c.THR == 128 and c.ROUND == 1 and c.rounding == "half_up"
    assert c.gains == {} and c.float_gains == {}


def test_kalman_accel_gains_and_acc_g() -> None:
    cfg = BuildConfig(program="kalman_accel", ratio=100.0, units_per_metre=4.0, accel_counts_per_mps2=100.0)
    c = build_constants(cfg)
    assert set(c.gains) == {"G11", "G21", "G31", "G12", "G22", "G32", "ACC_G", "G11T", "G21T", "G31T"}
    assert c.float_gains["ACC_G"] == 256 / 100.0           # Q24.8 m/s^2 per count
    assert c.gains["ACC_G"].value == pytest.approx(2.56, rel=2**-15)
    # transonic barometer weight is lower (barometer variance x transonic_r_factor), never zero
    assert 0 < c.float_gains["G11T"] < c.float_gains["G11"]
    assert c.float_gains == float_gains(cfg)
    for name, q in c.gains.items():
        assert q.target == c.float_gains[name] and abs(q.rel_error) <= 2**-15


@pytest.mark.parametrize("program", PROGRAMS)
@pytest.mark.parametrize("k", [0, 3, 7, 10])
@pytest.mark.parametrize("rounding", ["floor", "half_up"])
def test_equates_are_int32_and_complete(program: str, k: int, rounding: str) -> None:
    cfg = BuildConfig(program=program, k=k, rounding=rounding, ratio=100.0 if program == "kalman_accel" else 5e4,
                      baro_min=100, baro_max=60000)
    c = build_constants(cfg)
    eq = c.equates()
    base = {"K", "ROUND", "BARO_SIGN", "S", "THR", "V_LIFT", "V_GATE", "MACH_VLO", "MACH_VHI", "MACH_E",
            "BARO_MIN", "BARO_MAX", "ALT_SHIFT", "ALT_N", "CAL_P", "E_GATE", "GATE_N", "APO_N", "PASCAL",
            "MACH_N", "DLY_N", "DV", "A_COAST", "COAST_N", "V_DESC", "DU", "A_DRAG", "CLIP_N", "GUARDS", "DG", "V_FALL",
            "H_FLOOR", "DESC_N", "H_STEP"}
    gain_keys = {f"{n}_{p}" for n in c.gains for p in ("M", "S")}
    assert set(eq) == base | gain_keys
    for name, value in eq.items():
        assert type(value) is int and -(2**31) <= value < 2**31, name
    for n, q in c.gains.items():
        assert eq[f"{n}_M"] == q.m and eq[f"{n}_S"] == q.s
        assert -32768 <= q.m <= 32767 and 0 <= q.s <= 47
    assert eq["BARO_MIN"] == 100 and eq["BARO_MAX"] == 60000 and eq["ROUND"] == (rounding == "half_up")
    assert isinstance(c, FirmwareConstants)


def test_threshold_that_overflows_int32_is_a_user_error() -> None:
    """Issue 33: the config refuses a threshold whose state value overflows int32, naming the key the user wrote
    (here V_GATE = gate_mps x accel_counts_per_mps2 x 2^k = 100 x 32,000 x 1,024 = 3.3e9 > 2^31)."""
    with pytest.raises(UserError, match=r"gate_mps: 100 m/s x 3.2768e\+07 .* = 3.277e\+09 does not fit .*signed "
                                        r"32-bit word; allowed: at most 65.536 m/s"):
        BuildConfig(program="recursive", k=10, accel_counts_per_mps2=32000.0, gate_mps=100)
    build_constants(BuildConfig(program="recursive", k=10, accel_counts_per_mps2=32000.0, gate_mps=65.5))


def test_design_gain_below_2_pow_minus_33_is_built_as_zero() -> None:
    """Issue 20: a gain below 2^-33 (no 15-significant-bit mantissa with shift <= 47) is built as (0, 0), its
    design value kept as the target (the model-vs-mirror bound carries its <= 2^-33 error), instead of refusing
    the build: here k = 10 with an accelerometer trusted 10x more than the model (G31 ~ 3.8e-11), and a noise-free
    8-bit barometer with a 1-count accelerometer (G31 ~ 1e-16). quantize_gain itself still refuses it."""
    # accel_model_g 0: the accelerometer as trusted as its noise alone (the default's model error would
    # lift G31 far above 2^-33)
    for cfg in (BuildConfig(program="kalman_accel", k=10, ratio=0.1, accel_model_g=0.0),
                BuildConfig(program="kalman_accel", k=5, baro_bits=8, units_per_metre=3.5 / 256, baro_sigma=0.5,
                            accel_sigma=1.0, ratio=1000.0, accel_model_g=0.0)):
        c = build_constants(cfg)
        g = c.gains["G31"]
        assert (g.m, g.s) == (0, 0) and 0 < abs(g.target) < 2.0**-33
        assert all(q.m != 0 for name, q in c.gains.items() if abs(q.target) >= 2.0**-33)
    with pytest.raises(UserError, match="gain G31=.*too small"):
        quantize_gain("G31", 3.8e-11)


def test_acc_g_too_large_is_a_user_error() -> None:
    cfg = BuildConfig(program="kalman_accel", ratio=100.0, units_per_metre=1.0, accel_counts_per_mps2=0.005)
    with pytest.raises(UserError, match="gain ACC_G=51200.*too large"):
        build_constants(cfg)


def test_build_constants_rejects_non_config() -> None:
    with pytest.raises(UserError, match="BuildConfig"):
        build_constants({"k": 7})  # type: ignore[arg-type]  # a wrong type on purpose: the test checks the error


def test_transonic_gain_below_the_representable_range_is_zero() -> None:
    """A near-noise-free accelerometer makes a transonic barometer gain (barometer variance x 100) smaller than
    2^-33: it is built as 0 (the design value stays in float_gains; the model-vs-mirror bound carries the
    difference) instead of refusing the build, while a regular gain that small is still refused."""
    cfg = BuildConfig(program="kalman_accel", k=5, baro_bits=12, units_per_metre=3.5 / 16, baro_sigma=0.5,
                      accel_sigma=1.0, ratio=50_000.0, accel_model_g=0.0)   # the pre-issue-30 default design
    c = build_constants(cfg)
    tiny = [n for n in ("G11T", "G21T", "G31T") if abs(c.float_gains[n]) < 2.0**-33]
    assert tiny, {n: c.float_gains[n] for n in ("G11T", "G21T", "G31T")}
    for n in tiny:
        assert (c.gains[n].m, c.gains[n].s) == (0, 0) and c.gains[n].target == c.float_gains[n]

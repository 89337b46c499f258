"""Property tests of firmware_model.spec.fixed against exact rational arithmetic (fractions.Fraction + math.floor), an
oracle that shares no code with the helpers (which use shifts and masks)."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from firmware_model.spec.fixed import QGain
from firmware_model.runtime.errors import UserError
from firmware_model.spec.fixed import (Q24_8, FixedPointError, QFormat, fits, from_q, mulg, rs, to_q, wrap, wrap32,
                                  wrapped)

INT64 = st.integers(-(2**63), 2**63 - 1)
BIG = st.integers(-(2**200), 2**200)
INT32 = st.integers(-(2**31), 2**31 - 1)
MODES = st.sampled_from(["floor", "half_up"])


def oracle_rs(x: int, s: int, mode: str) -> int:
    """floor(x / 2^s) or floor(x / 2^s + 1/2), exactly, as rationals."""
    q = Fraction(x, 2**s)
    if mode == "half_up" and s > 0:
        q += Fraction(1, 2)
    return math.floor(q)


def oracle_wrap32(x: int) -> int:
    """The unique y in [-2^31, 2^31) congruent to x mod 2^32 (by division, not masks)."""
    r = x % 2**32  # Python's % is the mathematical residue in [0, 2^32)
    return r - 2**32 if r >= 2**31 else r


# ------------------------------------------------------------------------------------------ wrap32 / wrapped
@given(BIG)
def test_wrap32_python_int_is_the_residue(x: int) -> None:
    y = wrap32(x)
    assert isinstance(y, int)
    assert -(2**31) <= y < 2**31 and (x - y) % 2**32 == 0
    assert y == oracle_wrap32(x)
    assert wrapped(x) == (y != x)


@given(st.lists(INT64, min_size=1, max_size=40))
def test_wrap32_numpy_matches_python(xs: list[int]) -> None:
    arr = np.array(xs, dtype=np.int64)
    out = wrap32(arr)
    assert out.dtype == np.int64
    assert out.tolist() == [oracle_wrap32(x) for x in xs]
    assert wrapped(arr).tolist() == [not -(2**31) <= x < 2**31 for x in xs]
    assert fits(arr) == all(-(2**31) <= x < 2**31 for x in xs)


@given(st.integers(1, 40), BIG)
def test_wrap_bits(bits: int, x: int) -> None:
    y = wrap(x, bits)
    assert -(2 ** (bits - 1)) <= y < 2 ** (bits - 1) and (x - y) % 2**bits == 0
    assert wrapped(x, bits) == (x != y)


def test_wrap32_edges() -> None:
    assert wrap32(2**31) == -(2**31)
    assert wrap32(-(2**31) - 1) == 2**31 - 1
    assert wrap32(np.int64(2**32 + 5)) == 5
    assert wrapped(np.array([2**31 - 1, 2**31, -(2**31), -(2**31) - 1])).tolist() == [False, True, False, True]


# ------------------------------------------------------------------------------------------ rs
@given(BIG, st.integers(0, 80), MODES)
def test_rs_python_int_exact(x: int, s: int, mode: str) -> None:
    assert rs(x, s, mode) == oracle_rs(x, s, mode)


@given(st.lists(INT64, min_size=1, max_size=30), st.integers(0, 70), MODES)
def test_rs_numpy_int64_exact_no_intermediate_overflow(xs: list[int], s: int, mode: str) -> None:
    out = rs(np.array(xs, dtype=np.int64), s, mode)
    assert out.dtype == np.int64
    assert out.tolist() == [oracle_rs(x, s, mode) for x in xs]


@given(st.integers(-(2**20), 2**20), st.integers(1, 40), MODES)
def test_rs_ties(j: int, s: int, mode: str) -> None:
    """x exactly halfway between two multiples of 2^s: floor goes down, half_up goes up (|x| < 2^61)."""
    x = (2 * j + 1) * 2 ** (s - 1)
    expect = j + (1 if mode == "half_up" else 0)
    assert rs(x, s, mode) == expect
    assert rs(np.array([x], dtype=np.int64), s, mode)[0] == expect


def test_rs_int64_extremes() -> None:
    arr = np.array([2**63 - 1, -(2**63), -1, 1, 0], dtype=np.int64)
    for s in (0, 1, 31, 62, 63, 64, 100):
        for mode in ("floor", "half_up"):
            assert rs(arr, s, mode).tolist() == [oracle_rs(int(x), s, mode) for x in arr]


def test_rs_rejects_bad_arguments() -> None:
    with pytest.raises(FixedPointError, match="shift s=-1"):
        rs(5, -1)
    with pytest.raises(FixedPointError, match="rounding mode 'nearest'"):
        rs(5, 1, "nearest")
    with pytest.raises(UserError):  # FixedPointError is the package's UserError
        rs(np.array([1.5]), 1)


# ------------------------------------------------------------------------------------------ mulg
GAINS = st.builds(QGain, st.integers(-32768, 32767), st.integers(0, 47), st.just(0.0))


@given(INT32, GAINS, MODES)
def test_mulg_is_rounded_real_product_wrapped(e: int, g: QGain, mode: str) -> None:
    """mulg(e, m/2^s) equals the real product e*m/2^s rounded per mode, reduced mod 2^32."""
    real = Fraction(e) * Fraction(g.m, 2**g.s)
    rounded = math.floor(real + Fraction(1, 2)) if (mode == "half_up" and g.s > 0) else math.floor(real)
    expect = oracle_wrap32(rounded)
    assert mulg(e, g, mode) == expect
    assert mulg(np.array([e, e], dtype=np.int64), g, mode).tolist() == [expect, expect]


@given(st.lists(INT32, min_size=1, max_size=20), GAINS, MODES)
def test_mulg_numpy_equals_python(es: list[int], g: QGain, mode: str) -> None:
    assert mulg(np.array(es, dtype=np.int64), g, mode).tolist() == [mulg(e, g, mode) for e in es]


def test_mulg_rejects_inexact_int64_product() -> None:
    with pytest.raises(FixedPointError, match="2\\^47"):
        mulg(np.array([2**50], dtype=np.int64), QGain(3, 1, 0.0))


def test_mulg_wraps_at_int32() -> None:
    # (2^31 - 1) * 32767 / 2^0 overflows int32; the exact value mod 2^32 is kept
    e, g = 2**31 - 1, QGain(32767, 0, 32767.0)
    assert mulg(e, g) == oracle_wrap32(e * 32767)
    assert wrapped(e * 32767)


# ------------------------------------------------------------------------------------------ to_q / from_q
FINITE = st.floats(-(2.0**40), 2.0**40, allow_nan=False, allow_infinity=False)


@given(FINITE, st.integers(0, 20), MODES)
def test_to_q_rounds_exactly(x: float, f: int, mode: str) -> None:
    q = to_q(x, f, mode)
    exact = Fraction(x) * 2**f
    if mode == "floor":
        assert q == math.floor(exact)
    else:
        assert q == math.floor(exact + Fraction(1, 2))
        assert abs(Fraction(q) - exact) <= Fraction(1, 2)
    assert to_q(np.array([x]), f, mode).tolist() == [q]


@given(st.integers(-(2**52), 2**52), st.integers(0, 30))
def test_from_q_inverts_to_q(q: int, f: int) -> None:
    assert to_q(from_q(q, f), f) == q
    assert from_q(np.array([q]), f)[0] == Fraction(q, 2**f)


def test_to_q_rejects_non_finite() -> None:
    with pytest.raises(FixedPointError, match="not finite"):
        to_q(float("nan"), 8)
    with pytest.raises(FixedPointError, match="non-finite"):
        to_q(np.array([np.inf]), 8)


# ------------------------------------------------------------------------------------------ QFormat
def test_qformat_q24_8() -> None:
    assert Q24_8.name == "Q24.8" and Q24_8.bits == 32 and Q24_8.lsb == 1 / 256
    assert Q24_8.min_word == -(2**31) and Q24_8.max_word == 2**31 - 1
    assert Q24_8.min_value == -(2.0**23) and Q24_8.max_value == (2**31 - 1) / 256
    assert QFormat(1, 15).describe()["lsb"] == 2.0**-15
    with pytest.raises(FixedPointError):
        QFormat(0, 8)


def test_wrap_helpers_reject_bad_width() -> None:
    with pytest.raises(FixedPointError, match="bits=0"):
        wrapped(5, 0)
    with pytest.raises(FixedPointError, match="bits=0"):
        wrap(5, 0)

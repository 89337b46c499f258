"""firmware_model.spec.detmath against independent oracles: the C library's exp/log (math), numpy/LAPACK's solve,
eigvalsh and eigvals, and exact rational arithmetic. Its point is bits that do not depend on the machine; what is
checked here is that those bits are also accurate."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from firmware_model.spec import detmath as dm

finite = st.floats(min_value=-1e3, max_value=1e3, allow_nan=False, allow_infinity=False)
entries = st.floats(min_value=-10.0, max_value=10.0, allow_nan=False, allow_infinity=False).filter(
    lambda x: x == 0.0 or abs(x) > 1e-6)


def ulps(a: float, b: float) -> float:
    return abs(a - b) / math.ulp(max(abs(a), abs(b)))


@given(st.floats(min_value=-699.0, max_value=699.0, allow_nan=False).filter(lambda x: x != 0.0))
def test_exp_within_a_few_ulps_of_the_c_library(x: float) -> None:
    assert ulps(dm.exp(x), math.exp(x)) <= 4


@given(st.floats(min_value=1e-300, max_value=1e300, allow_nan=False, allow_infinity=False))
def test_log_within_a_few_ulps_of_the_c_library(x: float) -> None:
    want = math.log(x)
    got = dm.log(x)
    assert abs(got - want) <= 4 * math.ulp(abs(want)) + 1e-300


def test_elementary_functions_on_arrays_and_bad_arguments() -> None:
    x = np.linspace(0.01, 50.0, 1001)
    np.testing.assert_allclose(dm.log(x), np.log(x), rtol=1e-15, atol=1e-15)
    np.testing.assert_allclose(dm.exp(np.log(x)), x, rtol=2e-15)
    np.testing.assert_allclose(dm.pow_pos(x, 5.25588), x ** 5.25588, rtol=1e-14)
    assert dm.exp(0.0) == 1.0 and dm.log(1.0) == 0.0
    # numpy's special values, without its warnings
    special = np.array([0.0, -1.0, np.nan, np.inf])
    with np.errstate(all="ignore"):
        np.testing.assert_array_equal(dm.log(special), np.log(special))
    big = np.array([800.0, -800.0, np.nan, np.inf, -np.inf, 705.0, -740.0])
    with np.errstate(all="ignore"):
        want = np.exp(big)
    got = np.asarray(dm.exp(big))
    np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
    np.testing.assert_allclose(got[~np.isnan(want)], want[~np.isnan(want)], rtol=1e-13)
    assert np.isnan(dm.pow_pos(-1.0, 2.5))


@given(st.lists(entries, min_size=9, max_size=9), st.lists(entries, min_size=6, max_size=6))
def test_solve_matches_lapack(a: list[float], b: list[float]) -> None:
    A = np.array(a).reshape(3, 3) + np.eye(3) * 25.0          # well conditioned, non-trivial
    B = np.array(b).reshape(3, 2)
    got = np.array(dm.solve(dm.as_matrix(A), dm.as_matrix(B)))
    np.testing.assert_allclose(got, np.linalg.solve(A, B), rtol=1e-12, atol=1e-13)


def test_solve_reports_a_singular_matrix() -> None:
    with pytest.raises(dm.SingularMatrixError):
        dm.solve([[1.0, 2.0], [2.0, 4.0]], [[1.0], [1.0]])


@given(st.lists(entries, min_size=9, max_size=9))
def test_eigvalsh_matches_lapack(a: list[float]) -> None:
    A = np.array(a).reshape(3, 3)
    A = A + A.T
    got = dm.eigvalsh(dm.as_matrix(A))
    np.testing.assert_allclose(got, np.linalg.eigvalsh(A), atol=1e-12 * max(1.0, np.max(np.abs(A))))


@given(st.lists(entries, min_size=9, max_size=9))
def test_eigvals3_matches_lapack(a: list[float]) -> None:
    A = np.array(a).reshape(3, 3)
    got = np.sort_complex(np.array(dm.eigvals3(dm.as_matrix(A))))
    want = np.sort_complex(np.linalg.eigvals(A))
    # clustered roots are ill-conditioned in any method: compare with the conditioning LAPACK itself gets
    sep = min(abs(want[i] - want[j]) for i in range(3) for j in range(i + 1, 3))
    tol = 1e-9 * max(1.0, np.max(np.abs(A))) / max(sep, 1e-3)
    assert np.max(np.abs(got - want)) <= max(tol, 1e-7), (got, want)


def test_eigvals3_of_a_closed_loop_with_poles_near_one() -> None:
    """A companion matrix with known roots 0.999, 0.998 +- 0.001i (the shape of a slow Kalman design)."""
    roots = [0.999, complex(0.998, 0.001), complex(0.998, -0.001)]
    c = np.poly(roots).real
    A = np.array([[-c[1], -c[2], -c[3]], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    got = dm.eigvals3(dm.as_matrix(A))
    for r in roots:
        assert min(abs(g - r) for g in got) < 1e-6


def test_characteristic_polynomial_is_exact() -> None:
    A = [[0.1, 0.2, 0.3], [0.4, 0.5, 0.6], [0.7, 0.8, 0.9]]
    c2, c1, c0 = dm._char_poly3(A)
    F = [[Fraction(x) for x in row] for row in A]
    assert c2 == -(F[0][0] + F[1][1] + F[2][2])
    assert isinstance(c0, Fraction)


def test_matmul_sums_in_index_order() -> None:
    """(1e16 + 1) - 1e16 in index order is 0 (1 is lost), where a pairwise sum could keep it: the order is fixed."""
    a = [[1e16, 1.0, -1e16]]
    b = [[1.0], [1.0], [1.0]]
    assert dm.matmul(a, b) == [[0.0]]

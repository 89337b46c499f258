"""Arithmetic whose bits do not depend on the machine: every build constant and every float written into a committed
file is computed here or from what is computed here (docs/numerics.md, "Reproducible bytes").

Why: BLAS/LAPACK kernels (OpenBLAS picks one per CPU) and numpy's SIMD transcendental functions (SVML on AVX-512,
its own loops or libm elsewhere) may round differently from one machine to the next. A 1e-10 relative change in the
gain design moved the 11th digit of the diagnostics written into every Kalman case JSON (issue 29), and it could move
an integer of the firmware when a gain lands near a rounding boundary of ``m = round(g 2^s)``.

What is used, and why each is the same everywhere:

* **IEEE-754 basic operations** (+, -, *, /, sqrt) on Python floats, one operation per Python expression step:
  correctly rounded by the standard, never fused into an FMA (CPython evaluates each operator separately), and
  in the order written.
* **numpy element-wise ufuncs** of those same operations (``add``, ``multiply``, ``divide``, ``where``, ``frexp``,
  ``ldexp``, ``rint``): each element is one correctly rounded operation whatever the SIMD width; no reductions
  (whose order depends on the SIMD width) and no ``np.linalg``.
* :func:`exp` and :func:`log` below are written with those operations only (argument reduction by ``frexp``/
  ``ldexp``, which are exact, and fixed polynomials), so they give the same bits on every IEEE-754 machine. They are
  accurate to a few units in the last place, not correctly rounded; what matters here is that they are the same.

Small dense matrices (the 3 x 3 Kalman design) are lists of lists of Python floats: :func:`matmul`, :func:`solve`
(Gaussian elimination with partial pivoting, the first largest pivot), :func:`eigvalsh` (cyclic Jacobi) and
:func:`eigvals3` (the roots of the exact characteristic polynomial of a 3 x 3 matrix, found by bisection in exact
rational arithmetic and deflation).
"""

from __future__ import annotations

import math
from fractions import Fraction
from typing import Sequence

import numpy as np

Matrix = list[list[float]]

# ------------------------------------------------------------------------------------------ elementary functions
#: ln 2 split so that ``n * _LN2_HI`` is exact for |n| < 2^20 (the low 32 bits of its mantissa are zero).
_LN2_HI: float = 6.93147180369123816490e-01
_LN2_LO: float = 1.90821492927058770002e-10
_INV_LN2: float = 1.44269504088896338700e+00
#: 1/k! for the Taylor series of exp on |r| <= ln2/2 (degree 17: the truncation is below 1e-21 relative).
_EXP_COEF: tuple[float, ...] = tuple(1.0 / math.factorial(k) for k in range(17, -1, -1))
#: 2/(2k+1) for log(m) = 2 atanh(s) = sum 2 s^(2k+1)/(2k+1), |s| <= 0.1716 (degree 2*13+1: below 1e-21).
_LOG_COEF: tuple[float, ...] = tuple(2.0 / (2 * k + 1) for k in range(13, -1, -1))
_SQRT_HALF: float = 0.70710678118654752440


def exp(x: np.ndarray | float) -> np.ndarray | float:
    """e^x, element-wise, from basic operations only (module docstring). Like numpy's, but silent: NaN gives NaN,
    x > 709.78 gives inf and x < -745.2 gives 0 (the arguments the project uses are far inside)."""
    a = np.asarray(x, dtype=np.float64)
    ok = np.abs(a) < 700.0                        # False for NaN and inf too
    z = np.where(ok, a, 0.0)
    n = np.rint(z * _INV_LN2)
    r = (z - n * _LN2_HI) - n * _LN2_LO
    p = np.full_like(r, _EXP_COEF[0])
    for c in _EXP_COEF[1:]:
        p = p * r + c
    out = np.ldexp(p, n.astype(np.int64))
    if not np.all(ok):
        with np.errstate(over="ignore", under="ignore"):
            big = np.where(a > 0, np.ldexp(np.ldexp(1.0, 1000), 100), 0.0)   # inf above, 0 below: the limits
        out = np.where(ok, out, np.where(np.isnan(a), np.nan, np.where(np.abs(a) < 745.0, _exp_edge(a), big)))
    return out if out.ndim else float(out)


def _exp_edge(a: np.ndarray) -> np.ndarray:
    """e^a for 700 <= |a| < 745 (near overflow/underflow) as e^(a/2)^2, each half inside the main range."""
    half = np.where(np.abs(a) < 745.0, a / 2.0, 0.0)
    h = np.asarray(exp(half))
    with np.errstate(over="ignore", under="ignore"):
        return h * h


def log(x: np.ndarray | float) -> np.ndarray | float:
    """Natural logarithm, element-wise, from basic operations only (module docstring). Like numpy's, but silent:
    NaN or x < 0 gives NaN, 0 gives -inf, inf gives inf."""
    a = np.asarray(x, dtype=np.float64)
    ok = np.isfinite(a) & (a > 0)
    z = np.where(ok, a, 1.0)
    m, e = np.frexp(z)                            # z = m 2^e exactly, m in [0.5, 1)
    low = m < _SQRT_HALF
    m = np.where(low, m * 2.0, m)                 # m in [sqrt(1/2), sqrt(2)): exact doubling
    e = np.where(low, e - 1, e).astype(np.float64)
    f = m - 1.0                                   # exact (Sterbenz)
    s = f / (2.0 + f)
    s2 = s * s
    p = np.full_like(s, _LOG_COEF[0])
    for c in _LOG_COEF[1:]:
        p = p * s2 + c
    out = (e * _LN2_HI + (s * p + e * _LN2_LO))
    if not np.all(ok):
        out = np.where(ok, out, np.where(a == 0.0, -np.inf, np.where(a == np.inf, np.inf, np.nan)))
    return out if out.ndim else float(out)


def pow_pos(base: np.ndarray | float, y: float) -> np.ndarray | float:
    """``base ** y`` for ``base`` > 0, as ``exp(y log(base))`` (a few ulps times |y log base|); NaN for a base
    below 0 or NaN (as numpy's, silently)."""
    return exp(np.multiply(y, log(base)))


# ------------------------------------------------------------------------------------------ small matrices
def as_matrix(a: np.ndarray | Sequence[Sequence[float]]) -> Matrix:
    """A 2-D array as a list of lists of Python floats (exact)."""
    arr = np.atleast_2d(np.asarray(a, dtype=np.float64))
    return [[float(v) for v in row] for row in arr]


def transpose(a: Matrix) -> Matrix:
    return [list(col) for col in zip(*a)]


def matmul(a: Matrix, b: Matrix) -> Matrix:
    """``a @ b``, each entry summed in index order."""
    bt = transpose(b)
    out = []
    for row in a:
        out_row = []
        for col in bt:
            s = 0.0
            for x, y in zip(row, col):
                s = s + x * y
            out_row.append(s)
        out.append(out_row)
    return out


def add(a: Matrix, b: Matrix) -> Matrix:
    return [[x + y for x, y in zip(ra, rb)] for ra, rb in zip(a, b)]


def sub(a: Matrix, b: Matrix) -> Matrix:
    return [[x - y for x, y in zip(ra, rb)] for ra, rb in zip(a, b)]


def scale(a: Matrix, c: float) -> Matrix:
    return [[x * c for x in row] for row in a]


def eye(n: int) -> Matrix:
    return [[1.0 if i == j else 0.0 for j in range(n)] for i in range(n)]


def symmetrize(a: Matrix) -> Matrix:
    """``(a + a^T) / 2``."""
    n = len(a)
    return [[(a[i][j] + a[j][i]) / 2.0 for j in range(n)] for i in range(n)]


def max_abs(a: Matrix) -> float:
    return max((abs(x) for row in a for x in row), default=0.0)


def all_finite(a: Matrix) -> bool:
    return all(math.isfinite(x) for row in a for x in row)


class SingularMatrixError(ArithmeticError):
    """A pivot of :func:`solve` is exactly zero."""


def solve(a: Matrix, b: Matrix) -> Matrix:
    """``a^-1 b`` by Gaussian elimination with partial pivoting (the first row of largest |pivot|), then back
    substitution. Raises :class:`SingularMatrixError` on an exactly zero pivot."""
    n = len(a)
    m = [list(ra) + list(rb) for ra, rb in zip(a, b)]
    w = len(m[0])
    for c in range(n):
        piv = c
        for r in range(c + 1, n):
            if abs(m[r][c]) > abs(m[piv][c]):
                piv = r
        if m[piv][c] == 0.0 or not math.isfinite(m[piv][c]):
            raise SingularMatrixError("singular matrix")
        m[c], m[piv] = m[piv], m[c]
        pc = m[c][c]
        for r in range(c + 1, n):
            f = m[r][c] / pc
            if f != 0.0:
                row_r, row_c = m[r], m[c]
                for j in range(c, w):
                    row_r[j] = row_r[j] - f * row_c[j]
    x = [[0.0] * (w - n) for _ in range(n)]
    for r in range(n - 1, -1, -1):
        for j in range(w - n):
            s = m[r][n + j]
            for c in range(r + 1, n):
                s = s - m[r][c] * x[c][j]
            x[r][j] = s / m[r][r]
    return x


def eigvalsh(a: Matrix, sweeps: int = 60) -> list[float]:
    """Eigenvalues (ascending) of the symmetric matrix ``(a + a^T)/2`` by the cyclic Jacobi method (Golub & Van Loan
    2013, §8.5), stopped when the off-diagonal part is negligible against the diagonal."""
    s = symmetrize(a)
    n = len(s)
    for _ in range(sweeps):
        off = 0.0
        for i in range(n):
            for j in range(i + 1, n):
                off = off + s[i][j] * s[i][j]
        diag = 0.0
        for i in range(n):
            diag = diag + s[i][i] * s[i][i]
        if off == 0.0 or off <= 1e-36 * diag:
            break
        for p in range(n):
            for q in range(p + 1, n):
                apq = s[p][q]
                if apq == 0.0:
                    continue
                theta = (s[q][q] - s[p][p]) / (2.0 * apq)
                t = (1.0 if theta >= 0.0 else -1.0) / (abs(theta) + math.sqrt(theta * theta + 1.0))
                c = 1.0 / math.sqrt(t * t + 1.0)
                sn = t * c
                for k in range(n):          # columns p, q
                    akp, akq = s[k][p], s[k][q]
                    s[k][p] = c * akp - sn * akq
                    s[k][q] = sn * akp + c * akq
                for k in range(n):          # rows p, q
                    apk, aqk = s[p][k], s[q][k]
                    s[p][k] = c * apk - sn * aqk
                    s[q][k] = sn * apk + c * aqk
    return sorted(s[i][i] for i in range(n))


# ------------------------------------------------------------------------------------------ 3 x 3 eigenvalues
def _char_poly3(a: Matrix) -> tuple[Fraction, Fraction, Fraction]:
    """(c2, c1, c0) of det(lambda I - a) = lambda^3 + c2 lambda^2 + c1 lambda + c0, exactly (the float entries are
    exact rationals)."""
    f = [[Fraction(x) for x in row] for row in a]
    tr = f[0][0] + f[1][1] + f[2][2]
    minors = (f[0][0] * f[1][1] - f[0][1] * f[1][0] + f[0][0] * f[2][2] - f[0][2] * f[2][0]
              + f[1][1] * f[2][2] - f[1][2] * f[2][1])
    det = (f[0][0] * (f[1][1] * f[2][2] - f[1][2] * f[2][1]) - f[0][1] * (f[1][0] * f[2][2] - f[1][2] * f[2][0])
           + f[0][2] * (f[1][0] * f[2][1] - f[1][1] * f[2][0]))
    return -tr, minors, -det


def _bisect_root(c: tuple[Fraction, Fraction, Fraction], lo: float, hi: float) -> float:
    """A root of the monic cubic in [lo, hi] (sign change at the ends), to float resolution: bisection with the
    polynomial evaluated exactly at each float midpoint."""
    c2, c1, c0 = c

    def p(x: float) -> Fraction:
        fx = Fraction(x)
        return ((fx + c2) * fx + c1) * fx + c0

    plo = p(lo)
    if plo == 0:
        return lo
    if p(hi) == 0:
        return hi
    neg_lo = plo < 0
    for _ in range(2200):               # each step halves the interval; ends when no float lies between
        mid = lo + (hi - lo) / 2.0
        if mid <= lo or mid >= hi:
            break
        pm = p(mid)
        if pm == 0:
            return mid
        if (pm < 0) == neg_lo:
            lo = mid
        else:
            hi = mid
    return lo if abs(p(lo)) <= abs(p(hi)) else hi


def eigvals3(a: Matrix) -> list[complex]:
    """The eigenvalues of a real 3 x 3 matrix, sorted by decreasing modulus (ties: by real part, then imaginary part
    descending). Real roots are found by exact bisection of the characteristic polynomial between the real roots of
    its derivative (each to float resolution); a complex pair comes from the quadratic left after dividing out the
    real root."""
    c2, c1, c0 = _char_poly3(a)
    bound = float(1 + max(abs(c2), abs(c1), abs(c0)))          # Cauchy's bound on every root
    # critical points of p: 3x^2 + 2 c2 x + c1 = 0
    disc_d = float(c2 * c2 - 3 * c1)
    breaks = [-bound]
    if disc_d > 0:
        r = math.sqrt(disc_d)
        breaks += sorted([(-float(c2) - r) / 3.0, (-float(c2) + r) / 3.0])
    breaks.append(bound)

    def sign(x: float) -> int:
        fx = Fraction(x)
        v = ((fx + c2) * fx + c1) * fx + c0
        return (v > 0) - (v < 0)

    roots: list[float] = []
    for lo, hi in zip(breaks[:-1], breaks[1:]):
        slo, shi = sign(lo), sign(hi)
        if slo == 0:
            roots.append(lo)
        elif slo != shi and shi != 0:
            roots.append(_bisect_root((c2, c1, c0), lo, hi))
    if sign(breaks[-1]) == 0:
        roots.append(breaks[-1])
    out: list[complex]
    if len(roots) >= 3:
        out = [complex(r, 0.0) for r in roots[:3]]
    else:
        r = roots[0] if roots else _bisect_root((c2, c1, c0), -bound, bound)
        # p(x) = (x - r)(x^2 + b x + c): b = c2 + r, c = c1 + r b
        b = float(c2) + r
        c = float(c1) + r * b
        d = b * b - 4.0 * c
        if d >= 0.0:
            sq = math.sqrt(d)
            q = -(b + (sq if b >= 0 else -sq)) / 2.0
            r1 = q
            r2 = c / q if q != 0.0 else 0.0
            out = [complex(r, 0.0), complex(r1, 0.0), complex(r2, 0.0)]
        else:
            im = math.sqrt(-d) / 2.0
            out = [complex(r, 0.0), complex(-b / 2.0, im), complex(-b / 2.0, -im)]
    return sorted(out, key=lambda z: (-math.sqrt(z.real * z.real + z.imag * z.imag), -z.real, -z.imag))

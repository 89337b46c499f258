"""The firmware's pressure-to-altitude table (docs/firmware-spec.md §2a): a build constant generated from the
barometer's transfer function (counts -> pascals) and the standard atmosphere (:mod:`firmware_model.spec.atmosphere`).

The raw barometer word ``adc`` (0..2^bits-1) indexes the table by its upper bits: ``i = adc >> ALT_SHIFT``,
``f = adc & (2^ALT_SHIFT - 1)``, and the altitude is the linear interpolation between nodes ``T[i]`` and
``T[i+1]`` in exact integer arithmetic::

    alt(adc) = T[i] + rs((T[i+1] - T[i]) * f, ALT_SHIFT, mode)          (Q24.8 metres)

``rs`` is the build's rounding right shift; the product is exact (the 68000 forms it from two 16 x 16 partial
products, docs/firmware-asm.md). The table has ``2^(bits - ALT_SHIFT) + 1`` nodes: node ``j`` sits at count
``j << ALT_SHIFT``; the last node lies one count past full scale so that the last segment interpolates too.

Nodes are the least-squares fit of a *continuous* piecewise-linear function (one hat basis function per node) to
the standard-atmosphere altitude of every count ``0..2^bits-1`` (each count weighted equally), rounded to the
nearest Q24.8 LSB. This is the facts-level method of AltOS (least-squares altitude nodes per segment); the code is
our own. Pressures below ``P_FLOOR_PA`` (a transfer function that reaches 0 Pa or below at low counts) are clamped
to it, so the altitude saturates at about 31 km instead of becoming undefined.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from firmware_model.runtime.errors import UserError
from firmware_model.spec.atmosphere import altitude_m
from firmware_model.spec.config import BuildConfig
from firmware_model.spec.fixed import rs

#: Pressure floor of the table (Pa): counts whose transfer-function pressure is below it read as this pressure.
P_FLOOR_PA: float = 1000.0
#: Pressure floor of a pascal word's table (Pa): the fit follows the atmosphere below the MS5607's 1,000 Pa down to
#: here, so the segment holding 1,000 Pa has no kink (with the ADC floor it had one: 82 m of error at 1,000 Pa).
P_FLOOR_PASCAL_PA: float = 500.0
#: Default segment width: 2^ALT_SHIFT counts per segment (measured in docs/numerics.md, "Altitude table").
DEFAULT_ALT_SHIFT: int = 10


def linear_transfer(pa_per_count: float, pa_at_zero: float, baro_sign: int = -1) -> Callable[[np.ndarray], np.ndarray]:
    """Pressure (Pa) of raw counts for a linear sensor: ``P(c) = pa_at_zero - baro_sign * pa_per_count * c``
    (``baro_sign`` = -1: counts grow with pressure, a pressure ADC; +1: counts grow with altitude)."""
    if not (math.isfinite(pa_per_count) and pa_per_count > 0 and math.isfinite(pa_at_zero)):
        raise UserError(f"barometer transfer: pa_per_count={pa_per_count!r} must be > 0 and pa_at_zero="
                        f"{pa_at_zero!r} finite")

    def pressure_of_counts(c: np.ndarray) -> np.ndarray:
        return pa_at_zero - baro_sign * pa_per_count * np.asarray(c, dtype=np.float64)

    return pressure_of_counts


def exact_altitude_m(pressure_of_counts: Callable[[np.ndarray], np.ndarray], counts: np.ndarray,
                     p_floor: float = P_FLOOR_PA) -> np.ndarray:
    """The standard-atmosphere altitude (m) the table approximates at ``counts`` (pressure clamped at
    ``p_floor``, default ``P_FLOOR_PA``)."""
    p = np.maximum(np.asarray(pressure_of_counts(counts), dtype=np.float64), p_floor)
    return np.asarray(altitude_m(p), dtype=np.float64)


@dataclass(frozen=True)
class AltTable:
    """A generated altitude table: ``nodes`` (Q24.8 m, int), ``shift`` (ALT_SHIFT), ``bits`` (input width)."""

    nodes: tuple[int, ...]
    shift: int
    bits: int

    def __post_init__(self) -> None:
        if len(self.nodes) != (1 << (self.bits - self.shift)) + 1:
            raise UserError(f"altitude table: {len(self.nodes)} nodes for bits={self.bits}, shift={self.shift}")

    @property
    def array(self) -> np.ndarray:
        """The nodes as an int64 array."""
        return np.asarray(self.nodes, dtype=np.int64)

    def lookup(self, adc: np.ndarray, mode: str) -> np.ndarray:
        """The spec's ``alt(adc)`` (Q24.8 m, int64) for integer counts ``adc`` (any shape), rounding ``mode``."""
        a = np.asarray(adc, dtype=np.int64)
        t = self.array
        i = a >> np.int64(self.shift)
        f = a & np.int64((1 << self.shift) - 1)
        lo = t[i]
        return lo + rs((t[i + 1] - lo) * f, self.shift, mode)

    def lookup_float(self, adc: np.ndarray) -> np.ndarray:
        """The float mirror of :meth:`lookup`: the same nodes, interpolation without rounding (word scale)."""
        a = np.asarray(adc, dtype=np.float64)
        t = self.array.astype(np.float64)
        i = np.floor(a / (1 << self.shift)).astype(np.int64)
        f = a - i * float(1 << self.shift)
        return t[i] + (t[i + 1] - t[i]) * f / float(1 << self.shift)

    def rom_bytes(self) -> int:
        """ROM the table takes (4 bytes per node)."""
        return 4 * len(self.nodes)


def fit_table(pressure_of_counts: Callable[[np.ndarray], np.ndarray], bits: int,
              shift: int = DEFAULT_ALT_SHIFT, p_floor: float = P_FLOOR_PA) -> AltTable:
    """Least-squares nodes of the continuous piecewise-linear altitude (m -> Q24.8 LSB, nearest) over every count
    ``0..2^bits-1`` for segments of ``2^shift`` counts (``bits`` 17: a pascal word's table over 0..131071 Pa;
    pressures below ``p_floor`` read as ``p_floor``). Raises :class:`UserError` for a shift outside 1..15 or
    above ``bits`` - 1, or a transfer function that gives non-finite pressures."""
    if not isinstance(bits, int) or not 8 <= bits <= 17:
        raise UserError(f"altitude table: bits={bits!r} must be 8..16 (ADC) or 17 (pascal word)")
    if not isinstance(shift, int) or not 1 <= shift <= min(15, bits - 1):
        raise UserError(f"altitude table: alt_shift={shift!r} must be 1..{min(15, bits - 1)} for a {bits}-bit input")
    counts = np.arange(1 << bits, dtype=np.int64)
    p = np.asarray(pressure_of_counts(counts), dtype=np.float64)
    if not np.all(np.isfinite(p)):
        raise UserError("altitude table: the barometer transfer function gives non-finite pressures")
    y = exact_altitude_m(pressure_of_counts, counts, p_floor) * 256.0
    n_nodes = (1 << (bits - shift)) + 1
    i = counts >> shift
    w = (counts & ((1 << shift) - 1)) / float(1 << shift)     # weight of node i+1
    w0 = 1.0 - w
    # normal equations of the hat basis: tridiagonal (bincount adds its weights one by one, in index order)
    diag = np.bincount(i, w0 * w0, n_nodes) + np.bincount(i + 1, w * w, n_nodes)
    off = np.bincount(i, w0 * w, n_nodes)[:-1]
    rhs = np.bincount(i, w0 * y, n_nodes) + np.bincount(i + 1, w * y, n_nodes)
    nodes = np.array(_solve_tridiagonal([float(v) for v in diag], [float(v) for v in off],
                                        [float(v) for v in rhs]))
    q = np.rint(nodes)
    if np.any(np.abs(q) > (1 << 30)):
        raise UserError("altitude table: a node does not fit Q24.8 comfortably (|alt| >= 4,194 km)")
    return AltTable(tuple(int(v) for v in q), shift, bits)


def _solve_tridiagonal(diag: list[float], off: list[float], rhs: list[float]) -> list[float]:
    """The symmetric tridiagonal system (``diag`` on the diagonal, ``off`` beside it) solved by the Thomas algorithm
    in Python floats: the same bits on every machine (no LAPACK; docs/numerics.md, "Reproducible bytes"). The hat
    basis's Gram matrix is strictly diagonally dominant (each row: 2/3 of a segment on the diagonal against 1/6 on
    each side), so elimination without pivoting is stable. A last node that no count weighs (not reached by the
    segments the config allows, kept for safety) is extrapolated linearly from the two before it."""
    n = len(diag)
    last_free = diag[-1] == 0.0
    m = n - 1 if last_free else n
    c = [0.0] * m
    d = [0.0] * m
    for j in range(m):
        denom = diag[j] - (off[j - 1] * c[j - 1] if j else 0.0)
        if denom == 0.0:
            raise UserError("altitude table: singular normal equations (a segment holds no count)")
        c[j] = off[j] / denom if j < m - 1 else 0.0
        d[j] = (rhs[j] - (off[j - 1] * d[j - 1] if j else 0.0)) / denom
    x = [0.0] * n
    for j in range(m - 1, -1, -1):
        x[j] = d[j] - (c[j] * x[j + 1] if j < m - 1 else 0.0)
    if last_free:
        x[-1] = 2.0 * x[-2] - x[-3]
    return x


def table_error_m(table: AltTable, pressure_of_counts: Callable[[np.ndarray], np.ndarray], mode: str,
                  counts: np.ndarray | None = None) -> np.ndarray:
    """Integer table altitude minus the standard-atmosphere altitude, in metres, at ``counts`` (default: every
    count of the input range)."""
    if counts is None:
        counts = np.arange(1 << table.bits, dtype=np.int64)
    return table.lookup(counts, mode) / 256.0 - exact_altitude_m(pressure_of_counts, counts)


@functools.lru_cache(maxsize=64)
def _cached(pa_per_count: float, pa_at_zero: float, baro_sign: int, bits: int, shift: int,
            p_floor: float) -> AltTable:
    return fit_table(linear_transfer(pa_per_count, pa_at_zero, baro_sign), bits, shift, p_floor)


def table_for(pa_per_count: float, pa_at_zero: float, baro_sign: int, bits: int, shift: int,
              p_floor: float = P_FLOOR_PA) -> AltTable:
    """The (cached) table of a linear sensor (see :func:`linear_transfer`)."""
    return _cached(float(pa_per_count), float(pa_at_zero), int(baro_sign), int(bits), int(shift), float(p_floor))


def table_of_config(cfg: BuildConfig) -> AltTable:
    """The altitude table of a :class:`~firmware_model.spec.config.BuildConfig`: its barometer transfer function
    (the pascal kind's identity over ``table_bits`` = 17, floor :data:`P_FLOOR_PASCAL_PA`; an ADC's linear
    function over ``baro_bits``, floor :data:`P_FLOOR_PA`) and segment shift."""
    a, b = cfg.baro_transfer
    return table_for(a, b, cfg.baro_sign, cfg.table_bits, cfg.alt_shift_bits,
                     P_FLOOR_PASCAL_PA if cfg.pascal else P_FLOOR_PA)


__all__ = ["AltTable", "fit_table", "linear_transfer", "exact_altitude_m", "table_error_m", "table_for",
           "table_of_config", "P_FLOOR_PA", "P_FLOOR_PASCAL_PA", "DEFAULT_ALT_SHIFT"]

"""Fixed-point helpers shared by the integer model, the float mirror and the gain design.

Every function here accepts either Python ``int`` values (exact, arbitrary precision) or numpy integer arrays /
scalars (``int64``; vectorised), and returns the same kind. The definitions follow docs/firmware-spec.md §1:

* :func:`wrap32` reduces an exact integer to signed 32-bit two's complement (what ``add.l`` does).
* :func:`rs` is the rounding right shift ``rs(x, s, mode)`` with ``floor`` (ASR) or ``half_up`` (add 2^(s-1),
  then floor), computed **without** forming ``x + 2^(s-1)`` (``(x >> s) + bit(s-1) of x``, the 68000's
  ``asr`` + ``addx``), so it is exact for every int64 input and never overflows.
* :func:`mulg` is the gain multiply ``wrap32(rs(e * m, s, mode))`` with the exact (48-bit) product ``e * m``.

Q formats: a Qm.n word has ``m`` integer bits (including the sign) and ``n`` fraction bits; its value is
``word / 2**n`` (:class:`QFormat`). The firmware's state words are Q24.8.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction
from typing import Union

import numpy as np

from firmware_model.runtime.errors import UserError

#: Largest gain shift (docs/firmware-spec.md §1 mulg).
MAX_SHIFT: int = 47
#: Mantissa magnitude range for >= 15 significant bits.
M_MIN: int = 1 << 14
M_MAX: int = (1 << 15) - 1


@dataclass(frozen=True)
class QGain:
    """A quantized constant ``g = m / 2**s`` (docs/firmware-spec.md §1 mulg): ``m`` a signed 16-bit mantissa,
    ``s`` a right shift 0..47, ``target`` the float value it approximates."""

    m: int
    s: int
    target: float

    def __post_init__(self) -> None:
        if not -32768 <= self.m <= 32767 or not 0 <= self.s <= MAX_SHIFT:
            raise UserError(f"QGain(m={self.m}, s={self.s}): need -32768 <= m <= 32767 and 0 <= s <= {MAX_SHIFT}")

    @property
    def value(self) -> float:
        """The represented value m / 2^s (exact in float64)."""
        return math.ldexp(float(self.m), -self.s)

    @property
    def exact(self) -> Fraction:
        """The represented value as an exact fraction."""
        return Fraction(self.m, 1 << self.s)

    @property
    def rel_error(self) -> float:
        """(value - target) / target, 0 when target == 0."""
        if self.target == 0:
            return 0.0
        return float((self.exact - Fraction(self.target)) / Fraction(self.target))


def quantize_gain(name: str, g: float) -> QGain:
    """Quantize ``g`` to ``m / 2^s`` with ``2^14 <= |m| <= 2^15 - 1`` (>= 15 significant bits, so
    ``|rel_error| <= 2^-15``), ``m = round(g * 2^s)`` (nearest; exact). ``g == 0`` gives (0, 0).

    Raises :class:`UserError` naming the gain when it is not finite, too large (|g| >= 32767.5, which would need a
    negative shift) or too small (|g| < 2^-33, which would need a shift above 47 for 15 significant bits).
    """
    if not math.isfinite(g):
        raise UserError(f"gain {name}={g!r}: not a finite number")
    if g == 0:
        return QGain(0, 0, 0.0)
    e = math.frexp(abs(g))[1] - 1            # 2^e <= |g| < 2^(e+1)
    s = 14 - e                               # |g| * 2^s in [2^14, 2^15)
    exact = Fraction(g) * (Fraction(2) ** s) if s >= 0 else Fraction(g) / (1 << -s)
    m = _round_half_away(exact)
    if abs(m) > M_MAX:                       # rounded up to 2^15: one bit less of shift, m = +-2^14
        s -= 1
        m = _round_half_away(exact / 2)
    if s < 0:
        raise UserError(f"gain {name}={g!r}: too large for a 16-bit mantissa with shift >= 0 (|g| must be < 32767.5)")
    if s > MAX_SHIFT:
        raise UserError(f"gain {name}={g!r}: too small for 15 significant bits with shift <= {MAX_SHIFT} "
                        f"(|g| must be >= 2^{14 - MAX_SHIFT})")
    return QGain(int(m), int(s), float(g))


def _round_half_away(x: Fraction) -> int:
    """Nearest integer to an exact fraction, ties away from zero."""
    sign = -1 if x < 0 else 1
    return sign * math.floor(abs(x) + Fraction(1, 2))



#: An exact integer (Python int), a numpy integer scalar, or a numpy integer array.
IntLike = Union[int, np.integer, np.ndarray]

#: Rounding modes of every right shift (docs/firmware-spec.md §1).
MODES: tuple[str, ...] = ("floor", "half_up")

INT32_MIN: int = -(1 << 31)
INT32_MAX: int = (1 << 31) - 1
_MASK32: int = (1 << 32) - 1
#: Largest |e| for which ``e * m`` (|m| <= 2^15) is exact in int64.
_MULG_E_LIMIT: int = 1 << 47


class FixedPointError(UserError, ValueError):
    """A fixed-point helper was called with a value outside its documented domain (bad shift, unknown rounding
    mode, an operand that would overflow int64). The message names the argument and value."""


def _check_mode(mode: str) -> None:
    if mode not in MODES:
        raise FixedPointError(f"rounding mode {mode!r}: must be one of {', '.join(MODES)}")


def _check_shift(s: int, name: str = "s") -> int:
    if isinstance(s, bool) or not isinstance(s, (int, np.integer)) or s < 0:
        raise FixedPointError(f"shift {name}={s!r}: must be an integer >= 0")
    return int(s)


def _is_array(x: IntLike) -> bool:
    return isinstance(x, (np.ndarray, np.integer))


def _as_int64(x: IntLike) -> IntLike:
    """Python ints pass through; numpy values become int64 (refusing non-integer dtypes)."""
    if isinstance(x, bool):
        return int(x)
    if isinstance(x, int):
        return x
    arr = np.asarray(x)
    if arr.dtype.kind not in "iub":
        raise FixedPointError(f"expected integer values, got dtype {arr.dtype}")
    if arr.dtype.kind == "u" and arr.dtype.itemsize >= 8 and arr.size and int(arr.max()) > np.iinfo(np.int64).max:
        raise FixedPointError("unsigned 64-bit values above 2^63-1 cannot be represented exactly in int64")
    out = arr.astype(np.int64, copy=False)
    return out if isinstance(x, np.ndarray) else np.int64(out)


# ---------------------------------------------------------------------------------------------------- wrapping
def wrap32(x: IntLike) -> IntLike:
    """Reduce exact integer(s) ``x`` to signed 32-bit two's complement (result in [-2^31, 2^31-1]).

    Units are unchanged (a Q24.8 word stays Q24.8). Python ints of any size are reduced exactly; numpy arrays are
    taken as int64 (an int64 is itself exact, so the reduction is exact too).
    """
    x = _as_int64(x)
    if _is_array(x):
        return ((x + np.int64(1 << 31)) & np.int64(_MASK32)) - np.int64(1 << 31)
    return ((x + (1 << 31)) & _MASK32) - (1 << 31)


def wrap(x: IntLike, bits: int) -> IntLike:
    """Reduce ``x`` to signed ``bits``-bit two's complement (1 <= bits <= 63 for arrays, any for Python ints)."""
    if isinstance(bits, bool) or not isinstance(bits, int) or bits < 1:
        raise FixedPointError(f"bits={bits!r}: must be an integer >= 1")
    x = _as_int64(x)
    half = 1 << (bits - 1)
    if _is_array(x):
        if bits >= 64:
            return x
        return ((x + np.int64(half)) & np.int64((1 << bits) - 1)) - np.int64(half)
    return ((x + half) & ((1 << bits) - 1)) - half


def wrapped(exact: IntLike, bits: int = 32) -> Union[bool, np.ndarray]:
    """Whether reducing the exact integer(s) to signed ``bits`` bits changes the value (i.e. a 68000 ``.l``
    operation producing it would have overflowed). Returns a bool, or a bool array for array input."""
    if isinstance(bits, bool) or not isinstance(bits, int) or bits < 1:
        raise FixedPointError(f"bits={bits!r}: must be an integer >= 1")
    exact = _as_int64(exact)
    lo, hi = -(1 << (bits - 1)), (1 << (bits - 1)) - 1
    if _is_array(exact):
        if bits >= 64:
            return np.zeros(np.shape(exact), dtype=bool)
        return np.asarray((exact < lo) | (exact > hi))
    return bool(not lo <= exact <= hi)


def fits(x: IntLike, bits: int = 32) -> bool:
    """True when every value in ``x`` fits signed ``bits``-bit two's complement (no wrap needed)."""
    return not bool(np.any(wrapped(x, bits)))


# ---------------------------------------------------------------------------------------------------- shifts
def rs(x: IntLike, s: int, mode: str = "floor") -> IntLike:
    """Rounding right shift of exact integer(s) ``x`` by ``s`` bits (docs/firmware-spec.md §1).

    * ``floor``: ``floor(x / 2^s)`` (ASR).
    * ``half_up``: ``floor((x + 2^(s-1)) / 2^s)`` for ``s >= 1`` (ties go toward +inf), ``x`` for ``s == 0``.

    The Q format of the result has ``s`` fewer fraction bits than ``x`` (or the same fraction bits and a value
    scaled by 2^-s). No intermediate wrap: computed as ``(x >> s) + ((x >> (s-1)) & 1)``, exact for all int64.
    """
    _check_mode(mode)
    s = _check_shift(s)
    x = _as_int64(x)
    if s == 0:
        return x
    if _is_array(x):
        # numpy shifts by >= 64 are undefined; for an int64, a shift by 63 already gives floor (0 or -1).
        s_hi = min(s, 63)
        q = x >> np.int64(s_hi)
        if mode == "half_up":
            q = q + ((x >> np.int64(min(s - 1, 63))) & np.int64(1))
        return q
    q = x >> s
    if mode == "half_up":
        q += (x >> (s - 1)) & 1
    return q


def mulg(e: IntLike, gain: QGain, mode: str = "floor") -> IntLike:
    """Gain multiply ``wrap32(rs(e * m, s, mode))`` with ``gain = (m, s)`` representing ``m / 2^s``.

    ``e`` is an integer (normally a wrapped int32 Q24.8 innovation); the product ``e * m`` is exact (48 bits for
    int32 ``e``). The result has the Q format of ``e`` scaled by the gain. For numpy input ``|e|`` must be below
    2^47 so that the product is exact in int64 (checked).
    """
    _check_mode(mode)
    m, s = int(gain.m), _check_shift(gain.s, "gain.s")
    e = _as_int64(e)
    if _is_array(e):
        if np.size(e) and (np.max(e) >= _MULG_E_LIMIT or np.min(e) <= -_MULG_E_LIMIT):
            raise FixedPointError(f"mulg: |e| must be below 2^47 for an exact int64 product (got {np.max(np.abs(e))})")
        return wrap32(rs(e * np.int64(m), s, mode))
    return wrap32(rs(e * m, s, mode))


# ---------------------------------------------------------------------------------------------------- conversion
def to_q(x: Union[float, np.ndarray], frac_bits: int, mode: str = "half_up") -> IntLike:
    """Quantize real value(s) ``x`` to a Q word with ``frac_bits`` fraction bits: ``round(x * 2^frac_bits)``.

    ``mode`` is ``half_up`` (nearest, ties toward +inf; default) or ``floor``. The result is exact (the scaling by
    a power of two and the fraction test are exact in binary floating point). Python floats give a Python int;
    arrays give int64 (values beyond +-2^63 raise :class:`FixedPointError`). NaN/inf raise.
    """
    _check_mode(mode)
    if isinstance(frac_bits, bool) or not isinstance(frac_bits, int):
        raise FixedPointError(f"frac_bits={frac_bits!r}: must be an integer")
    if isinstance(x, np.ndarray):
        y = np.ldexp(np.asarray(x, dtype=np.float64), frac_bits)
        if not np.all(np.isfinite(y)):
            raise FixedPointError("to_q: non-finite value(s)")
        fl = np.floor(y)
        if mode == "half_up":
            fl = fl + ((y - fl) >= 0.5)
        if np.size(fl) and (fl.max() >= 2.0**63 or fl.min() < -(2.0**63)):
            raise FixedPointError(f"to_q: value(s) out of int64 range at {frac_bits} fraction bits")
        return fl.astype(np.int64)
    xf = float(x)
    if not math.isfinite(xf):
        raise FixedPointError(f"to_q: value {x!r} is not finite")
    ys = math.ldexp(xf, frac_bits)
    q = math.floor(ys)
    if mode == "half_up" and (ys - q) >= 0.5:
        q += 1
    return q


def from_q(q: IntLike, frac_bits: int) -> Union[float, np.ndarray]:
    """Real value(s) of Q word(s) ``q`` with ``frac_bits`` fraction bits: ``q / 2^frac_bits`` (float64; exact
    while |q| < 2^53)."""
    if isinstance(q, (int, np.integer)) and not isinstance(q, np.ndarray):
        return math.ldexp(float(int(q)), -frac_bits)
    return np.ldexp(np.asarray(q, dtype=np.float64), -frac_bits)


# ---------------------------------------------------------------------------------------------------- Q formats
@dataclass(frozen=True)
class QFormat:
    """A signed fixed-point format Qm.n: ``int_bits`` integer bits including the sign, ``frac_bits`` fraction
    bits; a word ``w`` has the value ``w / 2^frac_bits``."""

    int_bits: int
    frac_bits: int

    def __post_init__(self) -> None:
        if self.int_bits < 1 or self.frac_bits < 0 or self.int_bits + self.frac_bits > 64:
            raise FixedPointError(f"QFormat Q{self.int_bits}.{self.frac_bits}: need int_bits >= 1, frac_bits >= 0, "
                                  "at most 64 bits in all")

    @property
    def bits(self) -> int:
        """Total word width in bits."""
        return self.int_bits + self.frac_bits

    @property
    def name(self) -> str:
        """``Q<int>.<frac>``, e.g. ``Q24.8``."""
        return f"Q{self.int_bits}.{self.frac_bits}"

    @property
    def lsb(self) -> float:
        """Value of one least significant bit (2^-frac_bits)."""
        return math.ldexp(1.0, -self.frac_bits)

    @property
    def min_word(self) -> int:
        """Smallest word (-2^(bits-1))."""
        return -(1 << (self.bits - 1))

    @property
    def max_word(self) -> int:
        """Largest word (2^(bits-1) - 1)."""
        return (1 << (self.bits - 1)) - 1

    @property
    def min_value(self) -> float:
        """Smallest representable value."""
        return math.ldexp(float(self.min_word), -self.frac_bits)

    @property
    def max_value(self) -> float:
        """Largest representable value."""
        return math.ldexp(float(self.max_word), -self.frac_bits)

    def describe(self) -> dict[str, object]:
        """A JSON-ready description for reports and golden-vector metadata."""
        return {"name": self.name, "int_bits": self.int_bits, "frac_bits": self.frac_bits, "bits": self.bits,
                "lsb": self.lsb, "min": self.min_value, "max": self.max_value}


#: The firmware's state format.
Q24_8: QFormat = QFormat(24, 8)

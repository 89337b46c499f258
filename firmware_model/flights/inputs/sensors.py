"""Sensor models: what the firmware's input registers would hold for a given pressure and specific force.

* :class:`BaroSensor`, kind ``"adc"``: an analog pressure sensor through an N-bit ADC (8..16 bits), a linear
  transfer function ``counts = counts_per_pa * P + offset_counts`` (``counts_per_pa`` < 0 for a sensor whose
  output falls with pressure); the sensor's pressure range ``p_min_pa..p_max_pa`` (its output saturates outside),
  Gaussian noise referred to pressure (``noise_pa``) and to the ADC (``noise_counts``), rounding to the nearest
  count, clipping to 0..2^bits-1.
* :class:`BaroSensor`, kind ``"pascal"``: a digital sensor (MS5607-like) reporting integer pascals over its range
  (MS5607: 1,000..120,000 Pa); noise ``noise_pa``. How the firmware consumes that 32-bit word is the firmware's
  business (issue 9); this only models the sensor. ``bits`` is 32 (the word), ``counts_per_pa`` = 1.
* :class:`AccelSensor`: range (+-g), bits, scale (counts per m/s^2 of specific force, positive = nose up), offset,
  Gaussian noise, rounding, clipping to the range and to the signed ``bits``-bit word.

Randomness only from an explicit ``numpy.random.Generator`` (or an int seed turned into one); the global RNG is
never used. With zero noise the result does not depend on the generator.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from firmware_model.runtime.errors import UserError
from firmware_model.spec.atmosphere import G0, altitude_m, density_kg_m3

BARO_KINDS: tuple[str, ...] = ("adc", "pascal")


def _rng(rng: np.random.Generator | int | None) -> np.random.Generator:
    if isinstance(rng, np.random.Generator):
        return rng
    if rng is None:
        raise UserError("sensor noise needs a numpy Generator or an int seed (rng=None given)")
    return np.random.default_rng(int(rng))


def _finite(name: str, value: float) -> None:
    if not isinstance(value, (int, float)) or not math.isfinite(value):
        raise UserError(f"sensor: {name}={value!r} must be a finite number")


@dataclass(frozen=True)
class BaroSensor:
    """A barometer. Build one with a preset (:meth:`preset`) or :meth:`adc_linear`; fields as in the module doc."""

    kind: str = "adc"
    bits: int = 16
    counts_per_pa: float = 0.294768            # TeleMetrum v1 (MP3H6115A): 0.009/kPa x 2047 x 16
    offset_counts: float = -3111.44            # -0.095 x 2047 x 16
    p_min_pa: float = 15_000.0
    p_max_pa: float = 115_000.0
    noise_pa: float = 0.0
    noise_counts: float = 0.0
    name: str = "custom"

    def __post_init__(self) -> None:
        if self.kind not in BARO_KINDS:
            raise UserError(f"barometer: kind={self.kind!r} must be one of {', '.join(BARO_KINDS)}")
        if self.kind == "adc":
            if not isinstance(self.bits, int) or not 8 <= self.bits <= 16:
                raise UserError(f"barometer: bits={self.bits!r}: an ADC barometer has 8..16 bits")
        else:
            if self.bits != 32 or self.counts_per_pa != 1.0 or self.offset_counts != 0.0:
                raise UserError("barometer: a 'pascal' sensor reports integer pascals in a 32-bit word "
                                "(bits=32, counts_per_pa=1, offset_counts=0)")
        for name in ("counts_per_pa", "offset_counts", "p_min_pa", "p_max_pa", "noise_pa", "noise_counts"):
            _finite(name, getattr(self, name))
        if self.counts_per_pa == 0:
            raise UserError("barometer: counts_per_pa must not be 0")
        if not 0 < self.p_min_pa < self.p_max_pa:
            raise UserError(f"barometer: range {self.p_min_pa}..{self.p_max_pa} Pa must satisfy 0 < min < max")
        if self.noise_pa < 0 or self.noise_counts < 0:
            raise UserError("barometer: noise must be >= 0")

    # ------------------------------------------------------------------ constructors
    @classmethod
    def adc_linear(cls, bits: int, p_min_pa: float = 15_000.0, p_max_pa: float = 115_000.0, sign: int = -1,
                   **kw: Any) -> BaroSensor:
        """An ideal ``bits``-bit ADC sensor spanning ``p_min_pa..p_max_pa`` over the full count range;
        ``sign`` = -1: counts rise with pressure (fall as the rocket climbs; BuildConfig ``baro_sign`` -1)."""
        full = (1 << bits) - 1
        slope = full / (p_max_pa - p_min_pa)
        if sign == -1:
            cpp, off = slope, -slope * p_min_pa
        elif sign == 1:
            cpp, off = -slope, slope * p_max_pa
        else:
            raise UserError(f"barometer: sign={sign!r} must be +1 or -1")
        kw.setdefault("name", f"adc{bits}")
        return cls(kind="adc", bits=bits, counts_per_pa=cpp, offset_counts=off, p_min_pa=p_min_pa,
                   p_max_pa=p_max_pa, **kw)

    @classmethod
    def preset(cls, name: str, **kw: Any) -> BaroSensor:
        """A named sensor (:data:`BARO_PRESETS`); ``kw`` overrides fields (e.g. ``noise_counts``)."""
        try:
            base = BARO_PRESETS[name]
        except KeyError:
            raise UserError(f"barometer preset {name!r}: known: {', '.join(BARO_PRESETS)}") from None
        return replace(base, **kw) if kw else base

    # ------------------------------------------------------------------ the model
    @property
    def full_scale(self) -> int:
        """Largest count (2^bits - 1; for a pascal sensor the top of its range)."""
        return (1 << self.bits) - 1 if self.kind == "adc" else int(self.p_max_pa)

    @property
    def sign(self) -> int:
        """BuildConfig ``baro_sign``: -1 when counts fall as the rocket climbs (counts rise with pressure)."""
        return -1 if self.counts_per_pa > 0 else 1

    def ideal_counts(self, pressure_pa: Any) -> np.ndarray:
        """The noise-free, unrounded, unclipped transfer function (float counts)."""
        p = np.clip(np.asarray(pressure_pa, dtype=np.float64), self.p_min_pa, self.p_max_pa)
        return self.counts_per_pa * p + self.offset_counts

    def counts(self, pressure_pa: Any, rng: np.random.Generator | int | None = None) -> np.ndarray:
        """Integer counts (int64) for pressures (Pa): pressure noise, range saturation, transfer, ADC noise,
        rounding to nearest (half to even), clipping to 0..2^bits-1 (ADC) or to the range (pascal)."""
        p = np.asarray(pressure_pa, dtype=np.float64)
        if not np.all(np.isfinite(p)):
            raise UserError("barometer: pressure must be finite (NaN/inf given)")
        gen = _rng(rng) if (self.noise_pa > 0 or self.noise_counts > 0) else None
        if self.noise_pa > 0:
            p = p + gen.standard_normal(p.shape) * self.noise_pa
        x = self.ideal_counts(p)
        if self.noise_counts > 0:
            x = x + gen.standard_normal(p.shape) * self.noise_counts
        if self.kind == "adc":
            return np.clip(np.rint(x), 0, self.full_scale).astype(np.int64)
        return np.clip(np.rint(x), math.ceil(self.p_min_pa), math.floor(self.p_max_pa)).astype(np.int64)

    def pressure_of_counts(self, counts: Any) -> np.ndarray:
        """The inverse transfer function: pressure (Pa, float) whose ideal reading is ``counts``."""
        return (np.asarray(counts, dtype=np.float64) - self.offset_counts) / self.counts_per_pa

    def counts_per_metre(self, ground_pressure_pa: float) -> float:
        """|d counts / d altitude| at ``ground_pressure_pa``: |counts_per_pa| x rho x g0, rho the standard density at
        the standard altitude of that pressure (BuildConfig ``units_per_metre``)."""
        h = float(altitude_m(ground_pressure_pa))
        return abs(self.counts_per_pa) * float(density_kg_m3(h)) * G0

    def to_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in ("name", "kind", "bits", "counts_per_pa", "offset_counts", "p_min_pa",
                                              "p_max_pa", "noise_pa", "noise_counts")}


#: Barometer presets. ``telemetrum_v1``: the exact formula of ../shared/flights/README.md
#: ``raw = round((P/1000*0.009 - 0.095)*2047*16)`` (MP3H6115A, 15..115 kPa, cc1111 ADC as a 16-bit word);
#: ``mpx4115_<N>bit``: the same class of sensor (0.009/kPa of the ADC's reference, -0.095 offset) on an ideal
#: N-bit ADC (``mpx4115_10bit`` is the RDAS-like 108.6 Pa per count); ``ms5607``: integer pascals, 10..1200 mbar.
BARO_PRESETS: dict[str, BaroSensor] = {
    "telemetrum_v1": BaroSensor(name="telemetrum_v1"),
    **{f"mpx4115_{b}bit": BaroSensor(kind="adc", bits=b, counts_per_pa=0.009e-3 * ((1 << b) - 1),
                                     offset_counts=-0.095 * ((1 << b) - 1), p_min_pa=15_000.0,
                                     p_max_pa=115_000.0, name=f"mpx4115_{b}bit") for b in (8, 10, 12, 16)},
    "ms5607": BaroSensor(kind="pascal", bits=32, counts_per_pa=1.0, offset_counts=0.0, p_min_pa=1_000.0,
                         p_max_pa=120_000.0, name="ms5607"),
}


@dataclass(frozen=True)
class AccelSensor:
    """An axial accelerometer: ``counts = offset_counts + counts_per_mps2 * f + noise``, rounded to nearest,
    then clipped to the sensor range ``+-range_g`` (expressed in counts) and to the signed ``bits``-bit word.
    ``f`` is specific force along the axis, m/s^2 (+g0 on the pad). Default: the firmware's default build,
    2048 counts per g, +-16 g, 16 bits."""

    bits: int = 16
    range_g: float = 16.0
    counts_per_mps2: float = 2048.0 / G0
    offset_counts: float = 0.0
    noise_counts: float = 0.0
    name: str = "custom"

    def __post_init__(self) -> None:
        if not isinstance(self.bits, int) or not 2 <= self.bits <= 16:
            raise UserError(f"accelerometer: bits={self.bits!r} must be 2..16 (a signed 16-bit input register)")
        for name in ("range_g", "counts_per_mps2", "offset_counts", "noise_counts"):
            _finite(name, getattr(self, name))
        if self.range_g <= 0 or self.counts_per_mps2 <= 0 or self.noise_counts < 0:
            raise UserError("accelerometer: range_g and counts_per_mps2 must be > 0, noise_counts >= 0")
        word = 1 << (self.bits - 1)
        if not -word <= self.offset_counts <= word - 1:
            raise UserError(f"accelerometer: offset_counts={self.offset_counts!r} outside the {self.bits}-bit word "
                            f"{-word}..{word - 1}")
        if self.range_g * G0 * self.counts_per_mps2 < 1.0:
            raise UserError("accelerometer: the range spans less than one count (range_g x g0 x counts_per_mps2 < 1)")

    @classmethod
    def preset(cls, name: str, **kw: Any) -> AccelSensor:
        try:
            base = ACCEL_PRESETS[name]
        except KeyError:
            raise UserError(f"accelerometer preset {name!r}: known: {', '.join(ACCEL_PRESETS)}") from None
        return replace(base, **kw) if kw else base

    @property
    def count_limits(self) -> tuple[int, int]:
        """(lowest, highest) count the sensor can output: its range around the offset, inside the word."""
        word_lo, word_hi = -(1 << (self.bits - 1)), (1 << (self.bits - 1)) - 1
        span = self.range_g * G0 * self.counts_per_mps2
        lo = max(word_lo, math.ceil(self.offset_counts - span))
        hi = min(word_hi, math.floor(self.offset_counts + span))
        return lo, hi

    def counts(self, specific_force_mps2: Any, rng: np.random.Generator | int | None = None) -> np.ndarray:
        """Integer counts (int64) for axial specific forces (m/s^2)."""
        f = np.asarray(specific_force_mps2, dtype=np.float64)
        if not np.all(np.isfinite(f)):
            raise UserError("accelerometer: specific force must be finite (NaN/inf given)")
        x = self.offset_counts + self.counts_per_mps2 * f
        if self.noise_counts > 0:
            x = x + _rng(rng).standard_normal(f.shape) * self.noise_counts
        lo, hi = self.count_limits
        return np.clip(np.rint(x), lo, hi).astype(np.int64)

    def specific_force_of_counts(self, counts: Any) -> np.ndarray:
        """Inverse: specific force (m/s^2) whose ideal reading is ``counts``."""
        return (np.asarray(counts, dtype=np.float64) - self.offset_counts) / self.counts_per_mps2

    def to_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in ("name", "bits", "range_g", "counts_per_mps2", "offset_counts",
                                              "noise_counts")}


#: Accelerometer presets: ``default`` = the firmware's default build (2048 counts/g, +-16 g, 16 bits);
#: ``adxl375``: +-200 g, 20.5 counts/g (ADXL375 datasheet, 49 mg/LSB), 13 bits; ``mma2202_12bit``: a +-50 g
#: analog part on a 12-bit ADC (TeleMetrum v1 class: 2048 counts over 100 g around mid-scale, as a signed word).
ACCEL_PRESETS: dict[str, AccelSensor] = {
    "default": AccelSensor(name="default"),
    "adxl375": AccelSensor(bits=13, range_g=200.0, counts_per_mps2=20.5 / G0, name="adxl375"),
    "mma2202_12bit": AccelSensor(bits=12, range_g=50.0, counts_per_mps2=(4096 / 100.0) / G0, name="mma2202_12bit"),
}

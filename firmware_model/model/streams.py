"""Deterministic synthetic input streams for the firmware: edge-case patterns and a simple seeded flight.

Every stream is integer samples at the firmware's sample period ``dt = 2^-k`` s:

* ``adc``: barometer ADC counts, unsigned ``bits``-bit (0 .. 2^bits - 1);
* ``acc``: accelerometer counts, signed 16-bit (-32768 .. 32767), positive = upward specific force, so a rocket on
  the pad reads +1 g (``accel_counts_per_mps2 * 9.80665`` counts plus the sensor offset).

Randomness comes only from a :class:`numpy.random.Generator` seeded explicitly (``numpy.random.default_rng(seed)``);
the global RNG is never touched, so the same arguments give the same stream on every machine and numpy version
that keeps the PCG64 / ``standard_normal`` stream stable.

The flight here is deliberately simple (constant-thrust boost, ballistic coast with quadratic drag, apogee, drogue
descent); the full simulator with a thrust curve and Mach-dependent drag lives elsewhere.
"""

from __future__ import annotations

import csv
import dataclasses
import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from firmware_model.runtime.errors import UserError
from firmware_model.runtime.hashing import sha256_file
from firmware_model.spec.atmosphere import G0, rounded_troposphere_pressure_pa
from firmware_model.spec.config import BuildConfig

#: Edge-case stream kinds, in generation order.
EDGE_KINDS: tuple[str, ...] = ("constant", "step", "ramp", "adc_min", "adc_max", "alternating", "ties")

ACC_MIN: int = -32768
ACC_MAX: int = 32767


@dataclass(frozen=True)
class Stream:
    """One input stream.

    * ``name``: short identifier (``edge_step``, ``flight`` ...).
    * ``adc``: int64 array (n,), barometer counts 0 .. 2^bits-1; ``acc``: int64 array (n,), accelerometer counts.
    * ``k``: sample period 2^-k s; ``bits``: barometer ADC width.
    * ``provenance``: JSON-ready description of how the stream was made (generator, parameters, seed).
    * ``truth``: JSON-ready true values where known (e.g. ``apogee_s``, the true apogee time in s from the first
      sample, and ``apogee_sample``), empty for edge streams.
    """

    name: str
    adc: np.ndarray
    acc: np.ndarray
    k: int
    bits: int
    provenance: dict[str, Any]
    truth: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.adc.shape[0])


def _check_common(k: int, bits: int, n: int | None = None) -> None:
    if not isinstance(k, int) or not 0 <= k <= 10:
        raise UserError(f"input stream: k={k!r}: sample period 2^-k needs an integer k in 0..10")
    if not isinstance(bits, int) or not 8 <= bits <= 16:
        raise UserError(f"input stream: bits={bits!r}: barometer ADC width must be 8..16")
    if n is not None and (not isinstance(n, int) or n < 4):
        raise UserError(f"input stream: n={n!r}: need at least 4 samples")


def edge_stream(kind: str, n: int, bits: int, k: int) -> Stream:
    """An edge-case stream of ``n`` samples for a ``bits``-bit barometer ADC at dt = 2^-k s.

    Kinds (``full`` = 2^bits - 1, ``mid`` = full // 2, 1 g = 2048 accelerometer counts):

    * ``constant``: adc = mid, acc = 2048 throughout (a rocket resting on the pad).
    * ``step``: adc = mid for the first quarter, then mid - full // 8 (a pressure drop: altitude step up); acc 2048
      then 20480 (10 g).
    * ``ramp``: adc falls by 3 counts per sample from mid (clamped at 0); acc rises by 97 counts per sample from
      2048 (clamped at 32767).
    * ``adc_min``: adc = 0, acc = -32768 (both registers at their minimum).
    * ``adc_max``: adc = full, acc = 32767 (both at their maximum).
    * ``alternating``: adc alternates full, 0, full, ...; acc alternates 32767, -32768 (worst-case noise).
    * ``ties``: adc toggles between two adjacent codes (mid, mid + 1) in the pattern 0,1,1,0 and acc between 2048
      and 2049, so the filters sit on half-LSB values and exercise the rounding of ties.

    No randomness. Raises :class:`UserError` for an unknown kind or bad sizes.
    """
    _check_common(k, bits, n)
    full = (1 << bits) - 1
    mid = full // 2
    i = np.arange(n, dtype=np.int64)
    one_g = 2048
    if kind == "constant":
        adc = np.full(n, mid, np.int64)
        acc = np.full(n, one_g, np.int64)
    elif kind == "step":
        adc = np.where(i < n // 4, mid, mid - full // 8).astype(np.int64)
        acc = np.where(i < n // 4, one_g, 10 * one_g).astype(np.int64)
    elif kind == "ramp":
        adc = np.clip(mid - 3 * i, 0, full)
        acc = np.clip(one_g + 97 * i, ACC_MIN, ACC_MAX)
    elif kind == "adc_min":
        adc = np.zeros(n, np.int64)
        acc = np.full(n, ACC_MIN, np.int64)
    elif kind == "adc_max":
        adc = np.full(n, full, np.int64)
        acc = np.full(n, ACC_MAX, np.int64)
    elif kind == "alternating":
        adc = np.where(i % 2 == 0, full, 0).astype(np.int64)
        acc = np.where(i % 2 == 0, ACC_MAX, ACC_MIN).astype(np.int64)
    elif kind == "ties":
        pattern = np.array([0, 1, 1, 0], np.int64)[i % 4]
        adc = mid + pattern
        acc = one_g + pattern
    else:
        raise UserError(f"edge stream: unknown kind {kind!r}; known: {', '.join(EDGE_KINDS)}")
    return Stream(name=f"edge_{kind}", adc=adc.astype(np.int64), acc=acc.astype(np.int64), k=k, bits=bits,
                  provenance={"generator": "fwemu.inputs.edge_stream", "kind": kind, "n": n, "bits": bits, "k": k,
                              "seed": None})


#: The pascal kind's edge values (Pa): sea level, the MS5607's range.
PA_SEA, PA_LO, PA_HI = 101325, 1000, 120000


def pascal_edge_stream(kind: str, n: int, k: int) -> Stream:
    """:func:`edge_stream` for a pascal build (the signed 32-bit word ``BARO_PA``): the same kinds and
    accelerometer, the barometer in pascals: ``constant`` 101,325; ``step`` 101,325 then 86,325 (~1.3 km up);
    ``ramp`` falling 12 Pa per sample (~1 m) from 101,325, clamped at 1,000; ``adc_min``/``adc_max`` the register's
    extremes -2^31 / 2^31-1 (invalid words); ``alternating`` 120,000 / 1,000 (the valid range's ends: the worst
    innovation); ``ties`` 101,325 + 0,1,1,0. No randomness."""
    base = edge_stream(kind, n, 16, k)
    i = np.arange(n, dtype=np.int64)
    pa = {"constant": np.full(n, PA_SEA), "step": np.where(i < n // 4, PA_SEA, PA_SEA - 15000),
          "ramp": np.clip(PA_SEA - 12 * i, PA_LO, PA_HI), "adc_min": np.full(n, -(1 << 31)),
          "adc_max": np.full(n, (1 << 31) - 1), "alternating": np.where(i % 2 == 0, PA_HI, PA_LO),
          "ties": PA_SEA + np.array([0, 1, 1, 0], np.int64)[i % 4]}[kind]
    return Stream(name=base.name, adc=np.asarray(pa, dtype=np.int64), acc=base.acc, k=k, bits=32,
                  provenance={"generator": "fwemu.inputs.pascal_edge_stream", "kind": kind, "n": n,
                              "baro_kind": "pascal", "k": k, "seed": None})


@dataclass(frozen=True)
class FlightParams:
    """A simple vertical flight and its sensors (SI units unless stated).

    * Vehicle: ``boost_accel_g`` net upward acceleration during the burn (g), ``burn_s`` burn time, ``drag_per_m``
      quadratic drag coefficient (1/m: deceleration = drag_per_m * v * |v|), ``drogue_mps`` descent rate under the
      drogue (deployed ``drogue_delay_s`` after apogee), ``pad_s`` time on the pad before ignition,
      ``after_apogee_s`` how long the stream continues after apogee, ``pad_altitude_m`` above sea level.
    * Transonic barometer error: while the speed is inside ``transonic_band_mps`` (lo, hi) the barometer reads
      ``transonic_error_m`` metres too high (the pressure dip ahead of the shock; 0 = none).
    * Transonic dip (issue 20, real supersonic logs): around each time the true speed crosses Mach 1
      (:data:`MACH1_MPS`) the barometer reads ``dip_m`` metres low (a raised cosine ``dip_s`` long), then
      ``jump_m`` metres high for 0.1 s when the shock passes the port (:func:`transonic_dip_error`; 0 = none).
    * Barometer: ``units_per_metre`` counts per metre near the pad, ``baro_sign`` (-1: pressure ADC, counts fall as
      altitude grows), ``pad_fraction`` pad reading as a fraction of full scale, ``baro_sigma`` noise (counts rms).
    * Accelerometer: ``accel_counts_per_mps2``, ``accel_offset`` (counts at zero specific force), ``accel_sigma``
      noise (counts rms).
    """

    boost_accel_g: float = 10.0
    burn_s: float = 0.8
    drag_per_m: float = 0.0012
    drogue_mps: float = 20.0
    drogue_delay_s: float = 0.5
    pad_s: float = 0.5
    after_apogee_s: float = 3.0
    pad_altitude_m: float = 0.0
    units_per_metre: float = 3.5
    baro_sign: int = -1
    pad_fraction: float = 0.85
    baro_sigma: float = 2.0
    accel_counts_per_mps2: float = 2048.0 / G0
    accel_offset: float = 0.0
    accel_sigma: float = 20.0
    transonic_error_m: float = 0.0
    transonic_band_mps: tuple[float, float] = (290.0, 375.0)
    dip_m: float = 0.0
    dip_s: float = 1.5
    jump_m: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready parameters."""
        return {name: (list(v) if isinstance(v := getattr(self, name), tuple) else v)
                for name in self.__dataclass_fields__}


#: Speed of sound (m/s, 15 C) at which :func:`transonic_dip_error` places its dips.
MACH1_MPS: float = 340.3


def transonic_dip_error(t: np.ndarray, v: np.ndarray, dip_m: float, dip_s: float, jump_m: float) -> np.ndarray:
    """The barometric altitude error (m) of a transonic passage as real supersonic logs show it: around every
    sample where the velocity ``v`` crosses :data:`MACH1_MPS` (or, when it never does, at its peak) the reading is
    low by a raised cosine of depth ``dip_m`` and length ``dip_s`` (the port sees the pressure behind a shock),
    then high by ``jump_m`` for 0.1 s (the shock passing the port). ``t`` the sample times (s)."""
    err = np.zeros_like(np.asarray(t, dtype=np.float64))
    if dip_m == 0.0 and jump_m == 0.0:
        return err
    above = v > MACH1_MPS
    cross: list[Any] = list(np.flatnonzero(above[1:] != above[:-1]) + 1) or [int(np.argmax(v))]
    for c in cross:
        tc = t[c]
        inside = np.abs(t - tc) < dip_s / 2
        err -= np.where(inside, dip_m * 0.5 * (1 + np.cos(2 * math.pi * (t - tc) / dip_s)), 0.0)
        err += np.where((t >= tc + dip_s / 2) & (t < tc + dip_s / 2 + 0.1), jump_m, 0.0)
    return err


def pressure_pa(h_m: np.ndarray | float) -> np.ndarray | float:
    """Pressure (Pa) of the synthetic flights at altitude ``h_m`` metres above sea level
    (:func:`~firmware_model.spec.atmosphere.rounded_troposphere_pressure_pa`)."""
    return rounded_troposphere_pressure_pa(h_m)


def _trajectory(p: FlightParams, dt: float, sub: int) -> tuple[np.ndarray, np.ndarray, float]:
    """Integrate the flight at dt/sub; return (height m above pad, kinematic acceleration m/s^2) at every sample
    and the true apogee time (s from the first sample)."""
    h = v = t = 0.0
    h_out: list[float] = []
    a_out: list[float] = []
    apogee_t: float | None = None
    h_step = dt / sub
    t_end = math.inf

    def accel(t: float, v: float) -> float:
        t_rel = t - p.pad_s
        if t_rel < 0:
            return 0.0
        if t_rel < p.burn_s:
            return p.boost_accel_g * G0 - p.drag_per_m * v * abs(v)
        if apogee_t is None or t < apogee_t + p.drogue_delay_s:
            return -G0 - p.drag_per_m * v * abs(v)
        return (-p.drogue_mps - v) * 2.0          # drogue: first-order approach to the descent rate

    while t < t_end:
        h_out.append(h)                           # the state at the sample instant
        a_out.append(accel(t, v))
        for _ in range(sub):
            v_new = v + accel(t, v) * h_step
            if apogee_t is None and t - p.pad_s > p.burn_s and v > 0 >= v_new:
                apogee_t = t + h_step * v / (v - v_new)
                t_end = apogee_t + p.after_apogee_s
            h += (v + v_new) * 0.5 * h_step
            v = v_new
            t += h_step
        if t > 3600:
            raise UserError("synthetic flight: no apogee within an hour (check boost_accel_g and drag_per_m)")
    assert apogee_t is not None
    return np.array(h_out), np.array(a_out), apogee_t


def true_trajectory(k: int, params: FlightParams | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """The noise-free truth behind :func:`synthetic_flight` at dt = 2^-k s (same integration, same samples).

    Returns ``(height_m, speed_mps, apogee_s)``: height above the pad (m) at every sample instant, the speed
    ``|dh/dt|`` (m/s, ``numpy.gradient`` of the height, the quantity the transonic barometer error is keyed on:
    the error applies where ``transonic_band_mps[0] < speed < transonic_band_mps[1]``) and the true apogee time
    (s from the first sample). No randomness.
    """
    _check_common(k, 16)
    p = params or FlightParams()
    dt = 2.0 ** -k
    h, _, apogee_t = _trajectory(p, dt, 8)
    speed = np.abs(np.gradient(h, dt)) if h.shape[0] > 1 else np.zeros_like(h)
    return h, speed, apogee_t


def synthetic_flight(k: int, bits: int = 16, seed: int = 0, params: FlightParams | None = None,
                     name: str = "flight") -> Stream:
    """A seeded synthetic flight at dt = 2^-k s for a ``bits``-bit barometer.

    Physics: pad, constant-acceleration boost, coast under gravity and quadratic drag, apogee, drogue descent
    (:class:`FlightParams`), integrated with 8 sub-steps per sample. Barometer: ISA pressure at the altitude,
    mapped linearly to counts so that one metre near the pad is ``units_per_metre`` counts (``baro_sign`` = -1:
    counts fall as the rocket climbs), plus Gaussian noise ``baro_sigma``, rounded to the nearest count and clipped
    to 0..2^bits-1. Accelerometer: specific force ``(a + g)`` times ``accel_counts_per_mps2`` plus offset and noise,
    rounded and clipped to int16. Noise from ``numpy.random.default_rng(seed)`` (barometer noise drawn first, then
    accelerometer noise).
    """
    _check_common(k, bits)
    p = params or FlightParams()
    if p.baro_sign not in (1, -1):
        raise UserError(f"synthetic flight: baro_sign={p.baro_sign!r} must be +1 or -1")
    if not 0.0 <= p.pad_fraction <= 1.0:
        raise UserError(f"synthetic flight: pad_fraction={p.pad_fraction!r} must be in [0, 1]")
    dt = 2.0 ** -k
    h, a, apogee_t = _trajectory(p, dt, 8)
    speed = np.abs(np.gradient(h, dt)) if h.shape[0] > 1 else np.zeros_like(h)   # as true_trajectory()
    full = (1 << bits) - 1
    p_pad = float(pressure_pa(p.pad_altitude_m))
    counts_per_pa = p.units_per_metre / (p_pad - float(pressure_pa(p.pad_altitude_m + 1.0)))
    pad_counts = p.pad_fraction * full
    rng = np.random.default_rng(seed)
    baro_noise = rng.standard_normal(h.shape[0]) * p.baro_sigma
    acc_noise = rng.standard_normal(h.shape[0]) * p.accel_sigma
    lo, hi = p.transonic_band_mps
    h_baro = h + np.where((speed > lo) & (speed < hi), p.transonic_error_m, 0.0)
    h_baro = h_baro + transonic_dip_error(np.arange(h.shape[0]) * dt, np.gradient(h, dt) if h.shape[0] > 1
                                          else np.zeros_like(h), p.dip_m, p.dip_s, p.jump_m)
    drop = (p_pad - pressure_pa(p.pad_altitude_m + h_baro)) * counts_per_pa  # counts, grows with altitude
    baro = pad_counts + p.baro_sign * drop + baro_noise
    adc = np.clip(np.rint(baro), 0, full).astype(np.int64)
    acc_f = p.accel_offset + (a + G0) * p.accel_counts_per_mps2 + acc_noise
    acc = np.clip(np.rint(acc_f), ACC_MIN, ACC_MAX).astype(np.int64)
    prov = {"generator": "fwemu.inputs.synthetic_flight", "k": k, "bits": bits, "seed": seed,
            "params": p.to_dict(), "rng": "numpy.random.default_rng(seed) PCG64, baro noise then accel noise"}
    truth = {"apogee_s": round(apogee_t, 6), "apogee_sample": int(math.floor(apogee_t / dt)),
             "apogee_height_m": round(float(h.max()), 3), "max_speed_mps": None}
    v = np.diff(h) / dt
    truth["max_speed_mps"] = round(float(v.max()), 3) if v.size else 0.0
    return Stream(name=name, adc=adc, acc=acc, k=k, bits=bits, provenance=prov, truth=truth)


def synthetic_pascal_flight(k: int, seed: int = 0, params: FlightParams | None = None, noise_pa: float = 3.0,
                            name: str = "flight") -> Stream:
    """:func:`synthetic_flight` for a digital barometer (``baro_kind`` pascal, docs/firmware-spec.md §2): the same
    trajectory and accelerometer, the barometer word = the ISA pressure at ``pad_altitude_m`` + height (+ the
    transonic error) in integer pascals plus Gaussian noise ``noise_pa`` (Pa rms), rounded to the nearest pascal
    and clipped to the MS5607's 1,000..120,000 Pa. ``units_per_metre``/``baro_sigma``/``pad_fraction`` of
    ``params`` are not used. Noise from ``numpy.random.default_rng(seed)`` (barometer first, then accelerometer)."""
    _check_common(k, 16)
    p = params or FlightParams()
    if not (math.isfinite(noise_pa) and noise_pa >= 0):
        raise UserError(f"synthetic pascal flight: noise_pa={noise_pa!r} must be a finite number >= 0")
    dt = 2.0 ** -k
    h, a, apogee_t = _trajectory(p, dt, 8)
    speed = np.abs(np.gradient(h, dt)) if h.shape[0] > 1 else np.zeros_like(h)
    rng = np.random.default_rng(seed)
    baro_noise = rng.standard_normal(h.shape[0]) * noise_pa
    acc_noise = rng.standard_normal(h.shape[0]) * p.accel_sigma
    lo, hi = p.transonic_band_mps
    h_baro = h + np.where((speed > lo) & (speed < hi), p.transonic_error_m, 0.0)
    h_baro = h_baro + transonic_dip_error(np.arange(h.shape[0]) * dt, np.gradient(h, dt) if h.shape[0] > 1
                                          else np.zeros_like(h), p.dip_m, p.dip_s, p.jump_m)
    pa = np.clip(np.rint(pressure_pa(p.pad_altitude_m + h_baro) + baro_noise), 1000, 120000).astype(np.int64)
    acc_f = p.accel_offset + (a + G0) * p.accel_counts_per_mps2 + acc_noise
    acc = np.clip(np.rint(acc_f), ACC_MIN, ACC_MAX).astype(np.int64)
    prov = {"generator": "fwemu.inputs.synthetic_pascal_flight", "k": k, "baro_kind": "pascal", "seed": seed,
            "noise_pa": noise_pa, "params": p.to_dict(),
            "rng": "numpy.random.default_rng(seed) PCG64, baro noise then accel noise"}
    v = np.diff(h) / dt
    truth = {"apogee_s": round(apogee_t, 6), "apogee_sample": int(math.floor(apogee_t / dt)),
             "apogee_height_m": round(float(h.max()), 3), "max_speed_mps": round(float(v.max()), 3) if v.size else 0.0}
    return Stream(name=name, adc=pa, acc=acc, k=k, bits=32, provenance=prov, truth=truth)


# ------------------------------------------------------------------------------------ validation and user files
#: What the barometer input register holds (docs/firmware-spec.md §2): ``BARO_ADC`` an unsigned 16-bit word,
#: ``BARO_PA`` (the pascal kind) a signed 32-bit word.
BARO_WORD_RANGE: dict[bool, tuple[int, int, str]] = {False: (0, 0xFFFF, "16-bit input register BARO_ADC"),
                                                     True: (-(1 << 31), (1 << 31) - 1,
                                                            "signed 32-bit pascal register BARO_PA")}


def as_input_streams(adc: Any, acc: Any = None, pascal: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Validate barometer and accelerometer samples as the firmware's input registers hold them and return
    them as int64 arrays of shape ``(streams, n)``.

    ``adc``: integers 0..65535 (raw counts; ``pascal``: the signed 32-bit pascal word, -2^31..2^31-1), shape
    ``(n,)`` or ``(streams, n)``; ``acc``: integers -32768..32767 (counts), the same shape, ``None`` = all zero.
    Raises :class:`UserError` naming the array, the (stream and) sample and the value: wrong shape, empty stream,
    non-integer or out-of-range samples.

    Integer arrays already in range take a fast path (a min/max scan, no copy when they are int64): the result
    may then share memory with the arguments, which every caller only reads."""
    lo, hi, what = BARO_WORD_RANGE[bool(pascal)]
    fast = _in_range_streams(adc, acc, lo, hi)
    if fast is not None:
        return fast
    adc2 = _as_streams(adc, "adc", lo, hi, what)
    if acc is None:
        return adc2, np.zeros_like(adc2)
    acc2 = _as_streams(acc, "acc", -0x8000, 0x7FFF)
    if acc2.shape != adc2.shape:
        raise UserError(f"acc: shape {np.shape(acc)} differs from adc shape {np.shape(adc)}")
    return adc2, acc2


def _in_range_streams(adc: Any, acc: Any, lo: int, hi: int) -> tuple[np.ndarray, np.ndarray] | None:
    """The common case of :func:`as_input_streams`: integer arrays of a valid shape whose values are all in range,
    as int64 ``(streams, n)`` views (no copy for int64 input); None for anything else (the full check then names
    the bad sample)."""
    a = adc if isinstance(adc, np.ndarray) else None
    b = acc if acc is None or isinstance(acc, np.ndarray) else None
    if not (a is not None and a.dtype.kind in "iu" and a.ndim in (1, 2) and a.shape[-1] >= 1
            and (acc is None or (b is not None and b.dtype.kind in "iu" and b.shape == a.shape))):
        return None
    if int(a.min()) < lo or int(a.max()) > hi:
        return None
    if b is not None and (int(b.min()) < -0x8000 or int(b.max()) > 0x7FFF):
        return None
    a2 = np.atleast_2d(a.astype(np.int64, copy=False))
    b2 = np.zeros_like(a2) if b is None else np.atleast_2d(b.astype(np.int64, copy=False))
    return a2, b2


def _as_streams(values: Any, name: str, lo: int, hi: int, what: str = "16-bit input register") -> np.ndarray:
    arr = np.asarray(values)
    if arr.ndim not in (1, 2):
        raise UserError(f"{name}: expected shape (n,) or (streams, n), got {arr.shape}")
    if arr.shape[-1] < 1:
        raise UserError(f"{name}: empty stream (at least one sample is needed: init reads sample 0)")
    if arr.dtype.kind == "f":
        if not np.all(np.isfinite(arr)) or not np.all(arr == np.round(arr)):
            bad = np.argwhere(~np.isfinite(arr) | (arr != np.round(arr)))[0]
            raise UserError(f"{name}: sample {tuple(int(i) for i in bad)} = {arr[tuple(bad)]!r} is not an integer")
    elif arr.dtype.kind == "O":
        try:
            ints = [int(v) for v in arr.ravel()]
        except (TypeError, ValueError):
            raise UserError(f"{name}: expected integer samples, got dtype {arr.dtype}") from None
        for j, v in enumerate(ints):
            if not lo <= v <= hi:
                where = np.unravel_index(j, arr.shape)
                raise UserError(f"{name}: sample {tuple(int(i) for i in where)} = {v} outside {lo}..{hi} ({what})")
        arr = np.array(ints, dtype=np.int64).reshape(arr.shape)
    elif arr.dtype.kind not in "iub":
        raise UserError(f"{name}: expected integer samples, got dtype {arr.dtype}")
    if arr.dtype.kind == "u" and arr.dtype.itemsize == 8 and arr.size and int(arr.max()) > hi:
        j = int(np.argmax(arr.ravel() > hi))
        where = np.unravel_index(j, arr.shape)
        raise UserError(f"{name}: sample {tuple(int(i) for i in where)} = {int(arr.ravel()[j])} outside "
                        f"{lo}..{hi} ({what})")
    out = np.atleast_2d(arr.astype(np.int64))
    outside = (out < lo) | (out > hi)
    if outside.any():
        s, i = (int(v) for v in np.argwhere(outside)[0])
        at = f"sample {i}" if arr.ndim == 1 else f"stream {s} sample {i}"
        raise UserError(f"{name}: {at} = {int(out[s, i])} outside {lo}..{hi} ({what})")
    return out


def supersonic_params_for(cfg: BuildConfig) -> FlightParams:
    """A supersonic flight with the transonic signature of real logs (issue 20) for the golden vectors: 12 g for
    3.5 s, peak ~375 m/s (Mach 1.1), a 500 m barometer dip of 1.5 s around each Mach 1 crossing and a 150 m jump
    after it; the sensors of ``cfg``."""
    return dataclasses.replace(flight_params_for(cfg), boost_accel_g=12.0, burn_s=3.5, drag_per_m=0.0002,
                               dip_m=500.0, dip_s=1.5, jump_m=150.0, after_apogee_s=2.0)


def flight_params_for(cfg: BuildConfig, fast: bool = False) -> FlightParams:
    """The synthetic flight's sensor parameters matching ``cfg`` (same counts/metre, noise, baro sign).
    ``fast``: a transonic flight (14 g for 2 s, peak ~300 m/s, with a 60 m barometer error in 290..375 m/s) that
    exercises the Mach lockout of kalman_accel (kalman_baro has none: docs/firmware-spec.md §6)."""
    sensors: dict[str, Any] = dict(units_per_metre=cfg.units_per_metre, baro_sign=cfg.baro_sign,
                                   baro_sigma=cfg.baro_sigma, accel_counts_per_mps2=cfg.accel_counts_per_mps2,
                                   accel_sigma=cfg.accel_sigma)
    if fast:
        return FlightParams(boost_accel_g=14.0, burn_s=2.5, drag_per_m=0.0004, transonic_error_m=60.0, **sensors)
    return FlightParams(**sensors)


#: Programs whose firmware reads the accelerometer register (a user CSV for them must have an ``acc`` column).
ACC_PROGRAMS: tuple[str, ...] = ("recursive", "kalman_accel")
#: Samples per chunk when a CSV is read in chunks (:func:`iter_stream_csv`).
CSV_CHUNK: int = 65536


@dataclass
class CsvInfo:
    """What :func:`iter_stream_csv` learned about a user CSV: ``n`` samples, whether it has an ``acc`` column,
    the SHA-256 of the file's bytes (filled in when the last chunk has been read) and its provenance dict."""

    path: Path
    bits: int
    k: int
    has_acc: bool = False
    n: int = 0
    sha256: str = ""

    def provenance(self) -> dict[str, Any]:
        return {"generator": "user CSV", "file": self.path.name, "sha256": self.sha256, "n": self.n,
                "bits": self.bits, "k": self.k, "seed": None, "columns": "adc,acc" if self.has_acc else "adc"}


def _open_input(path: Path) -> BinaryIO:
    """``path`` opened for reading bytes, or a one-line :class:`UserError` saying why not."""
    try:
        return path.open("rb")
    except FileNotFoundError:
        raise UserError(f"{path}: no such input file") from None
    except IsADirectoryError:
        raise UserError(f"{path}: is a folder, not an input file") from None
    except OSError as exc:
        raise UserError(f"{path}: cannot read: {exc.strerror or exc}") from None


def _text_lines(f: BinaryIO, path: Path) -> Iterator[str]:
    """The lines of ``f`` decoded one by one, so that an undecodable byte is reported with its line (a UTF-8
    byte-order mark at the start, as Excel's "CSV UTF-8" writes, is dropped)."""
    for raw_no, raw in enumerate(f, start=1):
        if raw_no == 1 and raw.startswith(b"\xef\xbb\xbf"):
            raw = raw[3:]
        try:
            yield raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise UserError(f"{path}:{raw_no}: not UTF-8 text (byte 0x{raw[exc.start]:02x})") from None


def _header_columns(where: str, cells: list[str], require_acc: bool) -> tuple[list[str], int, int | None]:
    """(lower-case column names, index of ``adc``, index of ``acc`` or None) of the header row ``cells`` (stripped)
    at ``where`` (file:line), or the :class:`UserError` that names the problem."""
    header = [c.lower() for c in cells]
    if "adc" not in header:
        shown = ", ".join(repr(c) for c in cells[:8]) + (", ..." if len(cells) > 8 else "")
        raise UserError(f"{where}: header must name an 'adc' column (and optionally 'acc'); got {shown[:200]}")
    dupes = sorted({c for c in header if c and header.count(c) > 1})
    if dupes:
        raise UserError(f"{where}: duplicate column {dupes[0]!r} in the header")
    i_acc = header.index("acc") if "acc" in header else None
    if require_acc and i_acc is None:
        raise UserError(f"{where}: this program reads the accelerometer: the header needs an 'acc' column "
                        f"(counts, -32768..32767)")
    return header, header.index("adc"), i_acc


def iter_stream_csv(path: str | Path, bits: int, k: int, require_acc: bool = False, chunk: int = CSV_CHUNK,  # noqa: C901 - one loop that validates every row of a user CSV with a message per problem
                    info: CsvInfo | None = None):  # -> Iterator[tuple[np.ndarray, np.ndarray]]
    """Read a user stream from CSV in chunks of up to ``chunk`` samples, in constant memory: yields
    ``(adc, acc)`` int64 arrays. The file: UTF-8 (a byte-order mark, as Excel writes, is accepted), ``#`` lines
    and blank lines ignored, a header row naming ``adc`` and optionally ``acc`` (other columns ignored; each name
    at most once), then one integer sample per row. ``require_acc``: the program reads the accelerometer, so a
    missing ``acc`` column is an error (it would silently read zeros). Pass a :class:`CsvInfo` as ``info`` to
    learn the count, columns and SHA-256. Errors (:class:`UserError`) name the file and line: missing or
    duplicate columns, wrong field count, non-integer or out-of-range values (adc 0..2^bits-1, or for ``bits`` =
    32, a pascal build's word, -2^31..2^31-1; acc -32768..32767), undecodable bytes, an empty file, no samples."""
    path = Path(path)
    info = info if info is not None else CsvInfo(path, bits, k)
    # bits = 32: the pascal kind's signed 32-bit word (BuildConfig.baro_word_bits)
    adc_lo, full = (-(1 << 31), (1 << 31) - 1) if bits == 32 else (0, (1 << bits) - 1)
    what = " (signed 32-bit pascal word)" if bits == 32 else f" ({bits}-bit barometer ADC)"
    f = _open_input(path)
    lineno = 0
    header: list[str] | None = None
    i_adc = 0
    i_acc: int | None = None
    adc: list[int] = []
    acc: list[int] = []
    try:
        with f:
            reader = csv.reader(_text_lines(f, path))

            def numbered_rows():  # (line number, row); a CSV syntax error names its line
                while True:
                    try:
                        row = next(reader)
                    except StopIteration:
                        return
                    except csv.Error as exc:
                        raise UserError(f"{path}:{reader.line_num}: malformed CSV: {exc}") from None
                    yield reader.line_num, row

            rows = numbered_rows()
            for lineno, row in rows:
                cells = [c.strip() for c in row]
                if not cells or all(c == "" for c in cells) or cells[0].startswith("#"):
                    continue
                header, i_adc, i_acc = _header_columns(f"{path}:{lineno}", cells, require_acc)
                info.has_acc = i_acc is not None
                break
            # The data rows, the same rules as the header loop above (a row whose cells are all blank, or
            # whose first cell starts with '#', is skipped; then the field count; then adc, then acc), written
            # for speed: a cell is stripped only when looked at, and a blank row is recognised when its adc
            # cell does not parse.
            ncols = len(header) if header is not None else 0
            blank = str.isspace
            for lineno, row in rows:  # the data rows (none when the file ended before a header)
                if not row:
                    continue
                c0 = row[0].strip()
                if c0.startswith("#"):
                    continue
                if len(row) != ncols:
                    if all(not c or blank(c) for c in row):
                        continue
                    raise UserError(f"{path}:{lineno}: expected {ncols} fields, got {len(row)}")
                cell = c0 if i_adc == 0 else row[i_adc].strip()
                try:
                    v = int(cell, 10)
                except ValueError:
                    if all(not c or blank(c) for c in row):
                        continue
                    raise UserError(f"{path}:{lineno}: adc={cell[:40]!r} is not an integer") from None
                if not adc_lo <= v <= full:
                    raise UserError(f"{path}:{lineno}: adc={v} outside [{adc_lo}, {full}]{what}")
                adc.append(v)
                if i_acc is None:
                    acc.append(0)
                else:
                    cell = row[i_acc].strip()
                    try:
                        v = int(cell, 10)
                    except ValueError:
                        raise UserError(f"{path}:{lineno}: acc={cell[:40]!r} is not an integer") from None
                    if not -32768 <= v <= 32767:
                        raise UserError(f"{path}:{lineno}: acc={v} outside [-32768, 32767]")
                    acc.append(v)
                if len(adc) >= chunk:
                    info.n += len(adc)
                    yield np.array(adc, np.int64), np.array(acc, np.int64)
                    adc, acc = [], []
    except OSError as exc:
        raise UserError(f"{path}:{lineno + 1}: cannot read: {exc.strerror or exc}") from None
    if header is None:
        raise UserError(f"{path}: empty file (need a header row with 'adc' and at least one sample)")
    if adc:
        info.n += len(adc)
        yield np.array(adc, np.int64), np.array(acc, np.int64)
    if info.n == 0:
        raise UserError(f"{path}: no samples after the header")
    info.sha256 = sha256_file(path)


def read_stream_csv(path: str | Path, bits: int, k: int, require_acc: bool = False) -> Stream:
    """The whole user CSV as one :class:`Stream` (see :func:`iter_stream_csv` for the format and the errors)."""
    path = Path(path)
    info = CsvInfo(path, bits, k)
    parts = list(iter_stream_csv(path, bits, k, require_acc, info=info))
    adc = np.concatenate([a for a, _ in parts])
    acc = np.concatenate([b for _, b in parts])
    return Stream(name=_identifier(path.stem), adc=adc, acc=acc, k=k, bits=bits, provenance=info.provenance())


def _identifier(text: str) -> str:
    out = "".join(c if c.isalnum() else "_" for c in text.lower()).strip("_")
    return out if out and out[0].isalpha() else f"s_{out}"



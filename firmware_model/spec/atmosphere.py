"""The 1976 US / ICAO standard atmosphere from 0 to 32 km geopotential altitude, in float64, vectorised.

One implementation for the whole project: the flight simulators (truth pressure from altitude), the sensor models,
the reference apogee of real logs (barometric altitude from pressure) and the firmware's pressure-to-altitude
table generator all use it. Tests check it against an independent implementation (PyPI ``ambiance``).

Layers (geopotential altitude h, m; base temperature K; lapse rate K/m):
    0 .. 11,000 m: 288.15 K, -0.0065;  11,000 .. 20,000 m: 216.65 K, 0;  20,000 .. 32,000 m: 216.65 K, +0.001.
Below 0 m the troposphere law is extended (a launch site below sea level, or a high-pressure day); above 32 km the
last layer is extended. Altitudes here are geopotential; the difference to geometric altitude is 0.16 % at 10 km,
below every sensor error that matters here, and the firmware is judged against the same function it was built with.

Exponentials, logarithms and powers come from :mod:`~firmware_model.spec.detmath` (basic IEEE operations only), not
from numpy's SIMD or the C library's: the altitude table, the design's quantization floor and the synthetic and
simulated flights of the golden vectors get the same bits on every machine (issue 29).
"""

from __future__ import annotations

import numpy as np

from firmware_model.spec import detmath

#: Standard gravity (m/s^2), sea-level pressure (Pa) and temperature (K), gas constant of dry air (J/(kg K)),
#: ratio of specific heats.
G0: float = 9.80665
P0_PA: float = 101325.0
T0_K: float = 288.15
R_AIR: float = 287.05287
GAMMA: float = 1.4

#: (base altitude m, base temperature K, lapse rate K/m) per layer.
_LAYERS: tuple[tuple[float, float, float], ...] = (
    (0.0, 288.15, -0.0065),
    (11_000.0, 216.65, 0.0),
    (20_000.0, 216.65, 0.001),
)


def _base_pressures() -> tuple[float, ...]:
    p = [P0_PA]
    for (h0, t0, lapse), (h1, _, _) in zip(_LAYERS[:-1], _LAYERS[1:]):
        p.append(_layer_pressure(h1 - h0, p[-1], t0, lapse))
    return tuple(p)


def _layer_pressure(dh, pb, tb, lapse):
    if lapse == 0.0:
        return pb * detmath.exp(-G0 * dh / (R_AIR * tb))
    return pb * detmath.pow_pos(1.0 + lapse * dh / tb, -G0 / (R_AIR * lapse))


_P_BASE: tuple[float, ...] = _base_pressures()


def _layer_index_h(h: np.ndarray) -> np.ndarray:
    return np.clip(np.searchsorted([l[0] for l in _LAYERS[1:]], h, side="right"), 0, len(_LAYERS) - 1)


def temperature_k(altitude_m):
    """Standard temperature (K) at geopotential altitude(s) ``altitude_m``."""
    h = np.asarray(altitude_m, dtype=np.float64)
    idx = _layer_index_h(h)
    h0 = np.array([l[0] for l in _LAYERS])[idx]
    t0 = np.array([l[1] for l in _LAYERS])[idx]
    lapse = np.array([l[2] for l in _LAYERS])[idx]
    return t0 + lapse * (h - h0)


def pressure_pa(altitude_m):
    """Standard static pressure (Pa) at geopotential altitude(s) ``altitude_m``."""
    h = np.asarray(altitude_m, dtype=np.float64)
    idx = _layer_index_h(h)
    out = np.empty_like(h)
    for i, (h0, t0, lapse) in enumerate(_LAYERS):
        sel = idx == i
        if np.any(sel):
            out[sel] = _layer_pressure(h[sel] - h0, _P_BASE[i], t0, lapse)
    return out if out.ndim else float(out)


def altitude_m(pressure):
    """Geopotential altitude (m) of standard static pressure(s) ``pressure`` (Pa, > 0): the inverse of
    :func:`pressure_pa`."""
    p = np.asarray(pressure, dtype=np.float64)
    if np.any(~(p > 0)):
        raise ValueError("altitude_m: pressure must be > 0 Pa")
    # layers by pressure: base pressures fall with altitude
    idx = np.clip(np.searchsorted(-np.array(_P_BASE[1:]), -p, side="right"), 0, len(_LAYERS) - 1)
    out = np.empty_like(p)
    for i, (h0, t0, lapse) in enumerate(_LAYERS):
        sel = idx == i
        if not np.any(sel):
            continue
        ratio = p[sel] / _P_BASE[i]
        if lapse == 0.0:
            out[sel] = h0 - R_AIR * t0 / G0 * detmath.log(ratio)
        else:
            out[sel] = h0 + t0 / lapse * (detmath.pow_pos(ratio, -R_AIR * lapse / G0) - 1.0)
    return out if out.ndim else float(out)


def density_kg_m3(altitude_m_):
    """Standard air density (kg/m^3) at geopotential altitude(s)."""
    return np.asarray(pressure_pa(altitude_m_)) / (R_AIR * temperature_k(altitude_m_))


def speed_of_sound_mps(altitude_m_):
    """Standard speed of sound (m/s) at geopotential altitude(s)."""
    return np.sqrt(GAMMA * R_AIR * temperature_k(altitude_m_))


#: Constants of the rounded troposphere law below (1/m, exponent).
_ROUNDED_A: float = 2.25577e-5
_ROUNDED_N: float = 5.25588


def rounded_troposphere_pressure_pa(altitude_m):
    """``P0 (1 - 2.25577e-5 h)^5.25588``: the troposphere law with rounded constants (within 0.25 % of
    :func:`pressure_pa` up to 12 km). Not a second standard atmosphere: it is the fixed pressure law of the
    synthetic flights in :mod:`firmware_model.model.streams`, kept because the committed golden vectors were made
    with it (the standard law moves 4 ADC samples of those flights by one count)."""
    return P0_PA * detmath.pow_pos(1.0 - _ROUNDED_A * np.asarray(altitude_m, dtype=np.float64), _ROUNDED_N)

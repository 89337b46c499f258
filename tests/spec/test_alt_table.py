"""The firmware's pressure-to-altitude table (firmware_model.spec.alt_table, docs/firmware-spec.md §2a) against an
independent standard atmosphere (PyPI ``ambiance``, test-only), over the WHOLE input range of the barometer word.

Bound per count (docs/numerics.md, "Altitude table"): ``|alt_int(c) - H(P(c))| <= D^2/8 * max|h''| + 1/256 m +
0.02 m``, with D = 2^ALT_SHIFT counts, max|h''| the largest second difference (m/count^2) of the exact altitude
over the count's segment and its two neighbours (the classical error bound of the interpolating polyline; the
least-squares polyline measured at most 0.9 of it), 1/256 m for the node and interpolation rounding, and 0.02 m
for the two atmosphere implementations' own difference (measured 0.011 m). Pressures below the table floor
(P_FLOOR_PA) are clamped; above ambiance's range (177,837 Pa, ~ -4.6 km) only our atmosphere is compared.
"""

from __future__ import annotations

import dataclasses
import functools
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware_model.spec.config import TELEMETRUM_PA_AT_ZERO, TELEMETRUM_PA_PER_COUNT
from firmware_model.spec.alt_table import (P_FLOOR_PA, AltTable,
                                      exact_altitude_m, fit_table, linear_transfer, table_error_m)
from firmware_model.spec.atmosphere import altitude_m
from firmware_model.spec.config import BuildConfig
from firmware_model.spec.build_constants import build_constants
from firmware_model.runtime.errors import UserError
from tests.support.profiles import examples

ambiance = pytest.importorskip("ambiance")
AMBIANCE_P_MAX = 177_837.0


def _bound_m(tf, table: AltTable) -> np.ndarray:
    bits, s = table.bits, table.shift
    hx = exact_altitude_m(tf, np.arange((1 << bits) + 1))
    d2 = np.abs(np.diff(hx, 2))
    d2 = np.concatenate([[d2[0]], d2, [d2[-1]]])
    nseg = len(table.nodes) - 1
    seg_max = np.zeros(nseg)
    np.maximum.at(seg_max, np.minimum(np.arange(len(d2)) >> s, nseg - 1), d2)
    around = np.maximum(seg_max, np.maximum(np.roll(seg_max, 1), np.roll(seg_max, -1)))
    counts = np.arange(1 << bits)
    return (2.0 ** s) ** 2 / 8 * around[counts >> s] + 1 / 256 + 0.02


def _check_against_ambiance(tf, table: AltTable, mode: str) -> float:
    counts = np.arange(1 << table.bits)
    p = np.maximum(np.asarray(tf(counts), dtype=np.float64), P_FLOOR_PA)
    got = table.lookup(counts, mode) / 256.0
    bound = _bound_m(tf, table)
    inside = p <= AMBIANCE_P_MAX
    ref = np.empty_like(got)
    ref[inside] = ambiance.Atmosphere.from_pressure(p[inside]).H          # geopotential, as ours
    ref[~inside] = altitude_m(p[~inside])
    err = np.abs(got - ref)
    bad = np.flatnonzero(err > bound)
    assert bad.size == 0, (bad[:5], err[bad[:5]], bound[bad[:5]], p[bad[:5]])
    return float(err.max())


@settings(max_examples=examples(6), deadline=None)
@given(bits=st.sampled_from((12, 14, 16)), seg=st.integers(6, 10), scale=st.floats(0.5, 3.0),
       p_top=st.floats(-90_000.0, 60_000.0), sign=st.sampled_from((-1, 1)), mode=st.sampled_from(("floor", "half_up")))
def test_table_error_bounded_against_ambiance_over_the_whole_input_range(bits, seg, scale, p_top, sign, mode):
    """Random linear sensors (Pa per count from half to three times TeleMetrum's, scaled to the ADC width; any
    pressure at count 0, including ones that clamp at the floor; both directions) and segment counts 2^6..2^10."""
    a = TELEMETRUM_PA_PER_COUNT * scale * 2.0 ** (16 - bits)
    b = p_top if sign == -1 else p_top + a * ((1 << bits) - 1) + 60_000.0   # sign +1: pressure falls with counts
    tf = linear_transfer(a, b, sign)
    table = fit_table(tf, bits, max(1, bits - seg))
    _check_against_ambiance(tf, table, mode)


@pytest.mark.parametrize("mode", ["floor", "half_up"])
def test_default_telemetrum_table_error(mode):
    """The default build's table (TeleMetrum v1, 16 bits, 513 nodes): max 0.86 m against ambiance over every
    count (-6 km .. 16 km); measured 0.036 m from -1 km to 5 km and 0.17 m up to 11 km (docs/numerics.md,
    "Altitude table"), asserted with a little room."""
    cfg = BuildConfig(program="kalman_baro")
    c = build_constants(cfg)
    tf = linear_transfer(*cfg.baro_transfer, cfg.baro_sign)
    table = AltTable(c.ALT_TABLE, c.ALT_SHIFT, 16)
    assert len(table.nodes) == 513 and table.rom_bytes() == 2052
    worst = _check_against_ambiance(tf, table, mode)
    assert worst <= 0.86
    counts = np.arange(1 << 16)
    h = exact_altitude_m(tf, counts)
    err = np.abs(table_error_m(table, tf, mode))
    assert err[(h > -1000) & (h < 5_000)].max() <= 0.04
    assert err[(h > -1000) & (h < 11_000)].max() <= 0.18


def test_bound_has_teeth_a_wrong_node_breaks_it():
    """One node 1 m off (or a table of the wrong ADC width) fails the same check."""
    tf = linear_transfer(TELEMETRUM_PA_PER_COUNT, TELEMETRUM_PA_AT_ZERO, -1)
    table = fit_table(tf, 16, 7)
    nodes = list(table.nodes)
    nodes[300] += 256
    with pytest.raises(AssertionError):
        _check_against_ambiance(tf, dataclasses.replace(table, nodes=tuple(nodes)), "floor")
    wrong = fit_table(linear_transfer(TELEMETRUM_PA_PER_COUNT * 1.01, TELEMETRUM_PA_AT_ZERO, -1), 16, 7)
    with pytest.raises(AssertionError):
        _check_against_ambiance(tf, wrong, "floor")


@functools.lru_cache(maxsize=1)
def _telemetrum_table():
    """The TeleMetrum 16-bit table, fitted once (0.13 s a fit) for every example below: the examples vary the
    inputs, not the table."""
    return fit_table(linear_transfer(TELEMETRUM_PA_PER_COUNT, TELEMETRUM_PA_AT_ZERO, -1), 16, 7)


@settings(max_examples=examples(40), deadline=None)
@given(adc=st.lists(st.integers(0, 65535), min_size=1, max_size=64), mode=st.sampled_from(("floor", "half_up")))
def test_lookup_is_the_spec_formula_in_exact_rationals(adc, mode):
    """alt(adc) = ALT[i] + rs((ALT[i+1] - ALT[i]) * f, s, mode), recomputed with Fractions (floor / half-up of
    the exact quotient), independent of the numpy code."""
    table = _telemetrum_table()
    got = table.lookup(np.array(adc), mode)
    for a, g in zip(adc, got):
        i, f = a // 128, a % 128
        lo, hi = table.nodes[i], table.nodes[i + 1]
        q = Fraction((hi - lo) * f, 128)
        r = (q.numerator // q.denominator) if mode == "floor" else int((q + Fraction(1, 2)).__floor__())
        assert int(g) == lo + r


def test_bad_table_parameters_are_user_errors():
    tf = linear_transfer(TELEMETRUM_PA_PER_COUNT, TELEMETRUM_PA_AT_ZERO, -1)
    with pytest.raises(UserError, match="alt_shift"):
        fit_table(tf, 16, 16)
    with pytest.raises(UserError, match="pa_per_count"):
        linear_transfer(0.0, 1000.0)
    with pytest.raises(UserError, match="alt_shift"):
        BuildConfig(alt_shift=12, baro_bits=12)
    with pytest.raises(UserError, match="cal_p"):
        BuildConfig(cal_p=9)


def test_recommended_tuning_builds():
    """The README's recommended builds exist for k = 5..7 and assemble into constants; unknown ones are errors."""
    from firmware_model.spec.tuning import RECOMMENDED, recommended_config

    for program, per_k in RECOMMENDED.items():
        for k in per_k:
            cfg = recommended_config(program, k, baro_bits=16)
            assert cfg.k == k and build_constants(cfg).program == program
    assert recommended_config("kalman_accel", 6).rounding == "half_up"
    with pytest.raises(UserError, match="k=9"):
        recommended_config("kalman_baro", 9)
    with pytest.raises(UserError, match="program"):
        recommended_config("nope", 6)

"""Public hypothesis strategies for property tests of firmware ports (documented in docs/numerics.md,
"Strategies").

Firmware teams use these to drive their own port (C, assembly, ...) against :func:`firmware_model.model.run.run_model`
with the same inputs the project tests use::

    from hypothesis import given
    from firmware_model.flights import strategies as fst

    @given(fst.build_configs(programs=("kalman_baro",)), fst.adc_streams(max_len=300))
    def test_port(cfg, adc): ...

Every stream is a 1-D numpy ``int64`` array of raw register values: barometer ADC counts in ``0..2^bits-1``,
accelerometer counts (signed, two's complement) in ``-2^(bits-1)..2^(bits-1)-1``. Strategies shrink toward short,
constant streams.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np
from hypothesis import assume
from hypothesis import strategies as st

from firmware_model.flights.simulate.pressure_errors import (BARO_ERROR_RANGES, ISSUE20_PARAMS, draw_error_model,
                                                    real_flight_errors)
from firmware_model.flights.simulate.sim1dof import Box, Launch, mach_of, rocket_from_unit, simulate_1dof
from firmware_model.spec.atmosphere import pressure_pa
from firmware_model.spec.config import PROGRAMS, ROUNDINGS, BuildConfig

__all__ = ["build_configs", "adc_streams", "accel_streams", "edge_streams", "flight_like_streams", "flights",
           "supersonic_flights", "ram_flights", "pascal_streams", "pascal_flight_streams"]


def build_configs(programs: Sequence[str] = PROGRAMS, k: Iterable[int] = range(4, 9),
                  rounding: Sequence[str] = ROUNDINGS, **fixed: object) -> st.SearchStrategy[BuildConfig]:
    """Valid :class:`~firmware_model.spec.config.BuildConfig` values.

    Draws ``program`` from ``programs``, ``k`` (sample period 2^-k s) from ``k``, ``rounding`` from ``rounding``,
    the recursive shift S from 1..8 and threshold from {32, 64, 128} (Q24.8: 1/8, 1/4, 1/2 LSB), and for Kalman
    programs ``noise_model`` from all models and ``ratio`` (R/q) from 1e3..1e6 for ``kalman_baro`` (10..1e4 for
    ``kalman_accel``), log-uniformly. Keyword arguments in ``fixed`` pin fields (e.g. ``baro_bits=12``).
    """
    programs = tuple(programs)
    ks = tuple(k)
    roundings = tuple(rounding)

    @st.composite
    def _cfg(draw: st.DrawFn) -> BuildConfig:
        program = draw(st.sampled_from(programs))
        fields: dict[str, object] = {"program": program, "k": draw(st.sampled_from(ks)),
                                     "rounding": draw(st.sampled_from(roundings))}
        if program in ("recursive", "recursive_seed_literal"):
            fields["shift"] = draw(st.integers(1, 8))
            fields["threshold_q8"] = draw(st.sampled_from((32, 64, 128)))
        else:
            fields["noise_model"] = draw(st.sampled_from(("accel_only", "jerk", "dwna")))
            lo, hi = (3.0, 6.0) if program == "kalman_baro" else (1.0, 4.0)
            fields["ratio"] = float(10.0 ** draw(st.floats(lo, hi)))
        fields.update(fixed)
        return BuildConfig(**fields)  # type: ignore[arg-type]  # **fields of mixed BuildConfig field types

    return _cfg()


def _array(values: Sequence[int]) -> np.ndarray:
    return np.asarray(values, dtype=np.int64)


def adc_streams(bits: int = 16, min_len: int = 1, max_len: int = 200) -> st.SearchStrategy[np.ndarray]:
    """Barometer streams: ``min_len..max_len`` samples, each uniformly anywhere in ``0..2^bits-1`` (raw counts;
    no smoothness assumed: the worst case for headroom and rounding)."""
    hi = (1 << bits) - 1
    return st.lists(st.integers(0, hi), min_size=min_len, max_size=max_len).map(_array)


def accel_streams(bits: int = 16, min_len: int = 1, max_len: int = 200) -> st.SearchStrategy[np.ndarray]:
    """Accelerometer streams: ``min_len..max_len`` signed samples in ``-2^(bits-1)..2^(bits-1)-1`` counts (two's
    complement register values; positive = upward)."""
    lo, hi = -(1 << (bits - 1)), (1 << (bits - 1)) - 1
    return st.lists(st.integers(lo, hi), min_size=min_len, max_size=max_len).map(_array)


def edge_streams(bits: int = 16, length: int = 64, shifts: Sequence[int] = (5,)) -> st.SearchStrategy[np.ndarray]:
    """Edge-case barometer streams of ``length`` samples (counts in ``0..2^bits-1``):

    * ``constant`` (any value, including 0 and the ADC maximum), ``min`` / ``max`` (all 0 / all 2^bits-1);
    * ``step`` between two arbitrary levels at an arbitrary sample (full-scale steps included);
    * ``ramp`` with an arbitrary start and slope (counts/sample), clipped to the ADC range;
    * ``alternating`` between two levels (full scale 0 / max included: the worst-case innovation);
    * ``ties``: steps and alternations between levels ``a``, ``b`` with ``b - a = 2^(2S-9) * odd`` for a shift S
      in ``shifts`` (S >= 5), so that the recursive filter's next ``rs(EST, S)`` drops exactly ``100...0``: a
      ``half_up`` tie (``floor`` and ``half_up`` differ there by one LSB).
    """
    hi = (1 << bits) - 1
    level = st.one_of(st.sampled_from((0, hi, hi // 2, (hi + 1) // 2)), st.integers(0, hi))

    def constant(c: int) -> np.ndarray:
        return np.full(length, c, dtype=np.int64)

    def step(a: int, b: int, at: int) -> np.ndarray:
        out = np.full(length, a, dtype=np.int64)
        out[min(at, length - 1):] = b
        return out

    def ramp(a: int, slope: int) -> np.ndarray:
        return np.clip(a + slope * np.arange(length, dtype=np.int64), 0, hi)

    def alternating(a: int, b: int) -> np.ndarray:
        out = np.full(length, a, dtype=np.int64)
        out[1::2] = b
        return out

    @st.composite
    def tie_pair(draw: st.DrawFn) -> tuple[int, int]:
        # After a step a -> b the recursive filter holds EST = (a << 8) + ((b - a) << (8 - S)); its next shift
        # rs(EST, S) drops exactly 100...0 (a half_up tie) when b - a = 2^(2S-9) * odd (S >= 5).
        s = draw(st.sampled_from(tuple(shifts)))
        unit = 1 << max(0, 2 * s - 9)
        a = draw(level)
        odd = 2 * draw(st.integers(0, max(0, (hi // unit - 1) // 2))) + 1
        d = unit * odd if s >= 5 else draw(st.integers(0, hi))
        b = a + d if a + d <= hi else a - d
        if b < 0:
            b = a + unit if a + unit <= hi else a - unit
        return a, max(0, min(hi, b))

    tie = tie_pair()
    return st.one_of(
        level.map(constant),
        st.sampled_from((0, hi)).map(constant),
        st.builds(step, level, level, st.integers(0, length - 1)),
        st.builds(ramp, level, st.integers(-(hi // max(length, 1)) - 1, hi // max(length, 1) + 1)),
        st.builds(alternating, level, level),
        st.builds(alternating, st.just(0), st.just(hi)),
        st.builds(lambda ab, at: step(ab[0], ab[1], at), tie, st.integers(0, length - 1)),
        tie.map(lambda ab: alternating(*ab)),
    )


def flight_like_streams(cfg: BuildConfig | None = None, max_len: int = 400, noise_counts: float = 2.0,
                        min_len: int = 8) -> st.SearchStrategy[tuple[np.ndarray, np.ndarray]]:
    """Quick synthetic flights ``(adc, acc)`` for ``cfg`` (default :class:`BuildConfig()`) of ``min_len``..``max_len``
    samples at 2^-k s: pad, constant boost, drag-free coast under -g, descent (until the pad level, then rest),
    with the apogee at 40..80 % of the stream (the boost acceleration follows from the drawn times), then
    altitude -> barometer counts (``units_per_metre``, ``baro_sign``, centred so that the trajectory stays
    inside ``0..2^baro_bits-1``) plus Gaussian noise of ``noise_counts`` (from a drawn seed) and the
    accelerometer (``accel_counts_per_mps2`` x specific force; 1 g on the pad, clipped to 16 bits). Not a
    simulator (see firmware_model's flight inputs for that): a shape with an apogee that hypothesis can shrink.
    The slowest shape drawn (apogee at 40 %, 15 % on the pad, burning half the climb) coasts for 1/8 of the
    stream, i.e. reaches g x duration / 8 (1.23 m/s per second of stream): to pass a filter's liftoff speed
    (30 m/s by default) or velocity gate (40 m/s) and reach apogee at every k, ``min_len`` must be tens of seconds
    of samples (tests/firmware/test_cpu_vs_model.py ``flight_lengths``).
    """
    if not 1 <= min_len <= max_len:
        raise ValueError(f"flight_like_streams: min_len={min_len} must be in 1..max_len={max_len}")
    cfg = cfg or BuildConfig()

    @st.composite
    def _flight(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray]:
        n = draw(st.integers(min_len, max_len))
        dt = cfg.dt
        g = 9.80665
        duration = n * dt
        t_pad = draw(st.floats(0.02, 0.15)) * duration
        t_apogee = draw(st.floats(0.4, 0.8)) * duration
        t_burn = draw(st.floats(0.15, 0.5)) * (t_apogee - t_pad)
        v_burn = g * (t_apogee - t_pad - t_burn)
        a_boost = v_burn / t_burn + g           # net (a_boost - g) * t_burn = v_burn: apogee at t_apogee
        seed = draw(st.integers(0, 2**32 - 1))
        t = np.arange(n) * dt
        tb = np.clip(t - t_pad, 0.0, t_burn)
        tc = np.clip(t - t_pad - t_burn, 0.0, None)
        h = 0.5 * (a_boost - g) * tb ** 2 + v_burn * tc - 0.5 * g * tc ** 2
        h = np.maximum(h, 0.0)
        thrust = (t >= t_pad) & (t < t_pad + t_burn)
        spec = np.where(t < t_pad, g, np.where(thrust, a_boost, 0.0))  # specific force sensed (m/s^2)
        rng = np.random.default_rng(seed)
        full = (1 << cfg.baro_bits) - 1
        span = h.max() * cfg.units_per_metre
        counts = cfg.baro_sign * h * cfg.units_per_metre
        centre = full / 2 - cfg.baro_sign * min(span, full) / 2
        adc = np.clip(np.round(centre + counts + rng.normal(0.0, noise_counts, n)), 0, full).astype(np.int64)
        acc = np.clip(np.round(spec * cfg.accel_counts_per_mps2 + rng.normal(0.0, 1.0, n)), -32768, 32767)
        return adc, acc.astype(np.int64)

    return _flight()


def flights(mach: tuple[float, float] = (0.15, 0.8), motors: Sequence[str] = ("K400C", "K828FJ"),
            site_altitude_m: tuple[float, float] = (0.0, 1500.0), pad_s: tuple[float, float] = (0.5, 2.0),
            descent_s: float = 5.0, record_hz: float = 200.0, internal_hz: float = 1000.0):
    """Simulated flights (:class:`firmware_model.flights.FlightRecord` with truth) from the 1-DOF model
    (:mod:`firmware_model.flights.simulate.sim1dof`) over a parameter box: a shipped motor (``motors``) scaled in thrust
    (0.3..1) and time (0.7..1.5), dry mass between the bounds that keep thrust/weight >= 4 and the drag-free
    burnout speed inside ``mach`` x 340 m/s, diameter 54..160 mm, Cd x 0.8..1.3, drogue CdA 0.2..0.8 m^2, launch
    site ``site_altitude_m``, ``pad_s`` on the pad, ``descent_s`` after apogee, recorded at ``record_hz``. Flights
    whose simulated peak Mach lies outside ``mach`` are rejected, so the default box is subsonic (peak Mach <= 0.8);
    widen ``mach`` (and ``motors``, e.g. add "M1670", "M6400") for transonic/supersonic flights. No pressure
    errors or sensor model: apply :mod:`firmware_model.flights.simulate.pressure_errors` and the sensor models on top.
    About 7 ms per 20 s flight with the 'fast' extra (numba; bench/bench_sim1dof.py), ~0.3 s without."""
    from hypothesis import assume

    box = Box(motors=tuple(motors), mach=tuple(mach), site_altitude_m=tuple(site_altitude_m))
    unit = st.floats(0.0, 1.0, exclude_max=True, allow_nan=False)

    @st.composite
    def _flight(draw: st.DrawFn):
        u = [draw(unit) for _ in range(8)]
        rocket = rocket_from_unit(u, box, name="hypothesis")
        assume(rocket is not None)
        site = box.site_altitude_m[0] + (box.site_altitude_m[1] - box.site_altitude_m[0]) * u[7]
        pad = draw(st.floats(pad_s[0], pad_s[1], allow_nan=False))
        rec = simulate_1dof(rocket, Launch(site_altitude_m=site, pad_s=pad, descent_s=descent_s,
                                           record_hz=record_hz, internal_hz=internal_hz))[0]
        assume(mach[0] <= rec.provenance["summary"]["max_mach"] <= mach[1])
        return rec

    return _flight()


def supersonic_flights(mach: tuple[float, float] = (0.95, 2.0),
                       motors: Sequence[str] = ("L1350", "M1670", "M6400", "M2245"),
                       site_altitude_m: tuple[float, float] = (0.0, 1500.0), pad_s: tuple[float, float] = (0.5, 2.0),
                       descent_s: float = 3.0, record_hz: float = 100.0, internal_hz: float = 1000.0,
                       drogue_delay_s: tuple[float, float] = (0.0, 1.0), ram: bool = False):
    """Fast 1-DOF flights (peak Mach in ``mach``, default 0.95..2: transonic and supersonic) **with the barometer
    errors of real flight** (:func:`firmware_model.flights.simulate.pressure_errors.real_flight_errors`): every
    parameter
    of the error model drawn uniformly from :data:`~firmware_model.flights.simulate.pressure_errors.BARO_ERROR_RANGES`
    (transonic dip, shock jump of either sign, noise bursts at burnout and deployment, ejection spike), the noise
    seeded by the draw, a drogue delay in ``drogue_delay_s``. Rockets as :func:`flights` over ``motors`` (scaled
    in thrust and time). Each example is a :class:`FlightRecord` whose ``truth`` is the error-free flight and
    whose ``provenance["effects"][-1]`` lists the error model and its largest dip; the Mach series is
    ``sim1dof.mach_of(record)``. ``ram``: the ram error in boost of issue 30 drawn too (else off, as in issue
    20's draws; :func:`ram_flights` draws it alone or with the rest). About 0.1 s per flight with numba."""
    box = Box(motors=tuple(motors), mach=tuple(mach), site_altitude_m=tuple(site_altitude_m))
    unit = st.floats(0.0, 1.0, exclude_max=True, allow_nan=False)

    @st.composite
    def _flight(draw: st.DrawFn):
        u = [draw(unit) for _ in range(8)]
        rocket = rocket_from_unit(u, box, name="hypothesis-supersonic")
        assume(rocket is not None)
        site = box.site_altitude_m[0] + (box.site_altitude_m[1] - box.site_altitude_m[0]) * u[7]
        pad = draw(st.floats(pad_s[0], pad_s[1], allow_nan=False))
        delay = draw(st.floats(drogue_delay_s[0], drogue_delay_s[1], allow_nan=False))
        rec = simulate_1dof(rocket, Launch(site_altitude_m=site, pad_s=pad, descent_s=descent_s,
                                           drogue_delay_s=delay, record_hz=record_hz, internal_hz=internal_hz))[0]
        assume(mach[0] <= rec.provenance["summary"]["max_mach"] <= mach[1])
        model = draw_error_model(u=[draw(unit) for _ in (BARO_ERROR_RANGES if ram else ISSUE20_PARAMS)], ram=ram)
        seed = draw(st.integers(0, 2**32 - 1))
        return real_flight_errors(rec, mach_of(rec), model=model, seed=seed)

    return _flight()


def ram_flights(mach: tuple[float, float] = (0.95, 2.0), motors: Sequence[str] = ("L1350", "M1670", "M6400", "M2245"),
                site_altitude_m: tuple[float, float] = (0.0, 1500.0), descent_s: float = 3.0,
                record_hz: float = 100.0, others: bool = True):
    """Fast 1-DOF flights (as :func:`supersonic_flights`) **with the ram error in boost** of issue 30
    (:func:`firmware_model.flights.simulate.pressure_errors.ram_coefficient`): ``ram_cp``, ``ram_mach_on`` and
    ``ram_fade_s`` drawn uniformly over their :data:`~firmware_model.flights.simulate.pressure_errors.BARO_ERROR_RANGES`
    (0.01-0.20 of q from Mach 0.6-0.9, fading 0-0.5 s after burnout); ``others``: the issue-20 errors drawn too
    (else off: the ram signature alone). Flights whose peak Mach stays below the drawn onset are rejected (the
    error would never switch on). Each example is a :class:`FlightRecord` with ``truth`` error-free and
    ``provenance["effects"][-1]["ram"]`` the error's times, peak and the lowest barometric height it reads."""
    box = Box(motors=tuple(motors), mach=tuple(mach), site_altitude_m=tuple(site_altitude_m))
    unit = st.floats(0.0, 1.0, exclude_max=True, allow_nan=False)
    quiet = {"cp_port": 0.0, "dip_cp": 0.0, "jump_m": 0.0, "burst_sigma_m": 0.0, "ejection_m": 0.0}

    @st.composite
    def _flight(draw: st.DrawFn):
        u = [draw(unit) for _ in range(8)]
        rocket = rocket_from_unit(u, box, name="hypothesis-ram")
        assume(rocket is not None)
        site = box.site_altitude_m[0] + (box.site_altitude_m[1] - box.site_altitude_m[0]) * u[7]
        rec = simulate_1dof(rocket, Launch(site_altitude_m=site, pad_s=1.0, descent_s=descent_s,
                                           record_hz=record_hz))[0]
        assume(mach[0] <= rec.provenance["summary"]["max_mach"] <= mach[1])
        model = draw_error_model(u=[draw(unit) for _ in BARO_ERROR_RANGES], ram=True)
        if not others:
            model = type(model)(**{**model.to_dict(), **quiet})
        m = mach_of(rec)
        # the error must switch on during the boost
        assume(float(np.max(m[rec.time_s <= rec.provenance["summary"]["burnout_s"]])) > model.ram_mach_on + 0.1)
        return real_flight_errors(rec, m, model=model, seed=draw(st.integers(0, 2**32 - 1)))

    return _flight()


#: Pascal words worth hitting on purpose: the default valid range's edges and one past them, the table's ends,
#: 0, the z << 8 exactness limit (2^23) and the int32 extremes.
PASCAL_EDGES: tuple[int, ...] = (0, 1, 999, 1000, 1001, 120000, 120001, 131071, 131072, (1 << 23) - 1, 1 << 23,
                                 -1, -1000, (1 << 31) - 1, -(1 << 31))


def pascal_streams(min_len: int = 1, max_len: int = 200, lo: int = 1000,
                   hi: int = 120000) -> st.SearchStrategy[np.ndarray]:
    """Pascal-word streams (``baro_kind`` pascal, docs/firmware-spec.md §2: a signed 32-bit register) over the
    whole word range: each sample a valid pascal in ``lo..hi``, a word inside the table (0..2^17-1), an edge of
    :data:`PASCAL_EDGES` or any 32-bit word (invalid: negative, huge); or a random walk inside ``lo..hi`` with
    such words mixed in."""
    word = st.one_of(st.integers(lo, hi), st.integers(0, (1 << 17) - 1), st.sampled_from(PASCAL_EDGES),
                     st.integers(-(1 << 31), (1 << 31) - 1))
    uniform = st.lists(word, min_size=min_len, max_size=max_len).map(_array)

    @st.composite
    def walk(draw: st.DrawFn) -> np.ndarray:
        n = draw(st.integers(max(min_len, 1), max_len))
        start = draw(st.integers(lo, hi))
        steps = draw(st.lists(st.integers(-400, 400), min_size=n, max_size=n))
        out = np.clip(start + np.cumsum(np.asarray(steps, dtype=np.int64)), lo, hi)
        for _ in range(draw(st.integers(0, 4))):
            out[draw(st.integers(0, n - 1))] = draw(word)
        return out

    return st.one_of(uniform, walk())


def pascal_flight_streams(cfg: BuildConfig | None = None, max_len: int = 400,
                          ) -> st.SearchStrategy[tuple[np.ndarray, np.ndarray]]:
    """Quick flights as :func:`flight_like_streams` for a pascal build: the same trajectory shape, scaled to an
    apogee of 30 m..12 km above a pad at 0..3 km, barometer = ISA pressure in integer pascals plus 0..8 Pa of
    noise, clipped to the MS5607's 1,000..120,000 Pa, with up to two single-sample spikes of +-2 kPa."""

    cfg = cfg or BuildConfig(baro_kind="pascal")
    shape = BuildConfig(k=cfg.k, accel_counts_per_mps2=cfg.accel_counts_per_mps2, units_per_metre=1.0, baro_sign=1)
    base = flight_like_streams(shape, max_len=max_len, noise_counts=0.0)

    @st.composite
    def _flight(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray]:
        h_counts, acc = draw(base)
        h = h_counts.astype(np.float64) - float(h_counts.min())
        top = float(h.max())
        apogee = draw(st.floats(30.0, 12_000.0))
        h = h * (apogee / top) if top > 0 else h
        pad = draw(st.floats(0.0, 3000.0))
        noise = draw(st.floats(0.0, 8.0))
        rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
        pa = np.rint(np.asarray(pressure_pa(pad + h)) + rng.normal(0.0, noise, h.shape[0]))
        pa = np.clip(pa, 1000, 120000).astype(np.int64)
        for _ in range(draw(st.integers(0, 2))):
            i = draw(st.integers(0, len(pa) - 1))
            pa[i] = min(120000, max(1000, int(pa[i]) + draw(st.sampled_from((-2000, 2000)))))
        return pa, acc

    return _flight()

"""The point-mass RK4 integration shared by the 1-DOF simulator and the Monte Carlo's 3-DOF flight
(docs/flights-sim.md, "The point-mass integration").

Both simulators integrate a point mass under thrust, drag and constant gravity with classic RK4 at a fixed step,
in scalar per-flight loops compiled with numba. What they share lives here, written once:

* the grid: :func:`step_size` (the largest step <= 1/internal_hz that divides the record period);
* the tables: the standard atmosphere (density, speed of sound) on a 1 m grid (:func:`atmosphere_tables`) and a
  drag curve resampled on a uniform Mach grid (:func:`drag_table`), with their scalar lookups
  (:func:`table_coord`, :func:`table_at`, :func:`cd_at`);
* the forces: the drag force :func:`drag_force`;
* the step: an RK4 stage's state (:func:`rk4_stage`), the weighted sum of the four slopes (:func:`rk4_step`), and
  the apogee found inside a step (:func:`apogee_in_step`).

The scalar helpers are plain Python, so the simulators' loops also run uncompiled (tests, ``NUMBA_DISABLE_JIT``).
:func:`register_for_numba` makes them callable from numba-compiled code (``numba.extending.register_jitable``) the
first time a simulator compiles its loop: importing numba costs about a second, which only a simulation should pay
(docs/architecture.md). Each helper's arithmetic is written in the order the simulators had before they shared it:
moving an operand changes the last bits of a flight, and the flights' bytes are pinned
(``bench/pointmass_hashes.py``).

Thrust and mass at a time are not shared: the 1-DOF simulator tabulates its (scaled) motor at the half steps with
``numpy.interp``, the Monte Carlo scales one base motor table per flight inside its loop; the two give different
last bits, and each keeps its own.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
from math import ceil
from pathlib import Path

import numpy as np

from firmware_model.spec import atmosphere as atm

#: Atmosphere table range (m, geopotential above sea level) and spacing used inside the integrators.
TABLE_LO_M, TABLE_HI_M, TABLE_STEP_M = -1000.0, 40_000.0, 1.0
#: The uniform Mach grid onto which every drag curve is resampled (O(1) lookup), 0..MACH_MAX.
MACH_STEP, MACH_MAX = 0.01, 4.0

#: Whether the optional 'fast' extra (numba) is installed; found without importing it.
HAVE_NUMBA: bool = importlib.util.find_spec("numba") is not None


def step_size(record_hz: float, internal_hz: float) -> tuple[int, float]:
    """(steps per record period ``m``, step ``h`` = 1 / (record_hz m)) with ``m = ceil(internal_hz / record_hz)``:
    the largest step <= 1/internal_hz that divides the record period. Both rates must be > 0 (callers check)."""
    m = max(1, ceil(internal_hz / record_hz - 1e-9))
    return m, 1.0 / (record_hz * m)


@functools.lru_cache(maxsize=1)
def atmosphere_tables() -> tuple[np.ndarray, np.ndarray]:
    """(density, speed of sound) of the standard atmosphere from TABLE_LO_M to TABLE_HI_M every TABLE_STEP_M (the
    loops interpolate linearly between them: relative error < 1e-8). Shared by every caller: not to be changed."""
    h = np.arange(TABLE_LO_M, TABLE_HI_M + TABLE_STEP_M / 2, TABLE_STEP_M)
    return atm.density_kg_m3(h), atm.speed_of_sound_mps(h)


def drag_table(mach: np.ndarray, cd: np.ndarray) -> np.ndarray:
    """Cd on the uniform Mach grid 0..MACH_MAX step MACH_STEP (+1 guard entry), held constant outside the given
    table."""
    grid = np.arange(0.0, MACH_MAX + MACH_STEP / 2, MACH_STEP)
    out = np.empty(grid.size + 1)
    out[:-1] = np.interp(grid, mach, cd)
    out[-1] = out[-2]
    return out


# ---------------------------------------------------------------------------------------------------------------
# Scalar helpers, compiled into the simulators' loops (register_for_numba)


def table_coord(alt_m):
    """The fractional index of altitude ``alt_m`` (m above sea level) in the atmosphere tables."""
    return (alt_m - TABLE_LO_M) * (1.0 / TABLE_STEP_M)


def table_at(tab, u):
    """Linear interpolation in ``tab`` at fractional index ``u`` (clamped at both ends)."""
    n = tab.shape[0]
    uc = min(max(u, 0.0), n - 1.000001)
    i = int(uc)
    f = min(max(u - i, 0.0), 1.0)
    return tab[i] * (1.0 - f) + tab[i + 1] * f


def cd_at(cd_tab, speed, c):
    """Cd of a :func:`drag_table` row at airspeed ``speed`` (m/s, >= 0) and speed of sound ``c``: linear in Mach,
    the last entry held above MACH_MAX."""
    x = speed / c * (1.0 / MACH_STEP)
    i0 = min(int(x), cd_tab.shape[0] - 2)
    fr = min(x - i0, 1.0)
    return cd_tab[i0] * (1.0 - fr) + cd_tab[i0 + 1] * fr


def drag_force(rho, v, speed, k):
    """``0.5 rho v speed k``: the drag force (N) along ``v`` for a drag area ``k`` (Cd x area, m^2), with
    ``speed`` = |airspeed|; left to right, as the simulators evaluate it."""
    return 0.5 * rho * v * speed * k


def rk4_stage(y, h, k, s):
    """The state of RK4 stage ``s`` (1, 2 or 3) from ``y`` and the previous stage's slope ``k``."""
    if s == 3:
        return y + h * k
    return y + 0.5 * h * k


def rk4_step(y, h, k):
    """``y`` after one step: the weighted sum of the four slopes ``k[0..3]``."""
    return y + h / 6.0 * (k[0] + 2.0 * k[1] + 2.0 * k[2] + k[3])


def apogee_in_step(t, h, z, v, v_new):
    """(time, altitude) of the apogee inside the step from ``t`` where the vertical speed goes from ``v`` > 0 to
    ``v_new`` <= 0: the zero crossing of v interpolated linearly, the altitude from the step's quadratic."""
    tau = v / (v - v_new) * h
    acc = (v_new - v) / h
    return t + tau, z + v * tau + 0.5 * acc * tau * tau


#: The helpers a compiled loop may call.
SCALAR_HELPERS = (table_coord, table_at, cd_at, drag_force, rk4_stage, rk4_step, apogee_in_step)


def njit_cached(fn, **options):
    """``numba.njit(cache=True, **options)(fn)`` whose on-disk cache also goes stale when this module changes.

    numba checks a cached function against its own source file only (numba issue 6845), while a simulator's loop
    has the helpers above compiled into it: without this, an edited helper would keep running from the cache of
    an unchanged simulator module. The cache index's source stamp becomes (numba's stamp, sha256 of this file);
    should numba's internals move, the function is compiled in every process instead (never stale)."""
    import numba  # lazy: heavy, optional

    disp = numba.njit(cache=True, **options)(fn)
    try:
        index = disp._cache._cache_file
        index._source_stamp = (index._source_stamp, source_digest())
    except AttributeError:  # pragma: no cover - numba internals moved (or NUMBA_DISABLE_JIT: nothing is cached)
        if not numba.config.DISABLE_JIT:
            from numba.core.caching import NullCache

            disp._cache = NullCache()
    return disp


@functools.cache
def source_digest() -> bytes:
    """sha256 of this module's source (part of the compiled loops' cache stamp, :func:`njit_cached`)."""
    return hashlib.sha256(Path(__file__).read_bytes()).digest()


def register_for_numba(*functions) -> bool:
    """Make :data:`SCALAR_HELPERS` and ``functions`` (a simulator's own helpers) callable from numba-compiled
    code, the module's names staying the plain Python functions; each function is registered once. The scalar
    helpers are inlined by numba into every use (``inline="always"``); a simulator's own helpers, larger and called
    once per stage, stay calls (inlining them too made the Monte Carlo kernel's compile 2.7 s longer for no
    measurable speed; docs/flights-sim.md). False (nothing done) without numba. Call it before compiling a loop
    that uses them."""
    if not HAVE_NUMBA:
        return False
    from numba.extending import register_jitable  # lazy: heavy, optional

    for fn in SCALAR_HELPERS + functions:
        if fn not in _REGISTERED:
            register_jitable(inline="always" if fn in SCALAR_HELPERS else "never")(fn)
            _REGISTERED.add(fn)
    return True


_REGISTERED: set = set()

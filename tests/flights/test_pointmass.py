"""The point-mass integration shared by sim1dof and the Monte Carlo (firmware_model/flights/simulate/pointmass.py,
docs/flights-sim.md "The point-mass integration"): its helpers against closed forms, and the compiled loops' cache
going stale when the shared module changes. The simulators' bytes are held by tests/flights/test_sim.py (the numpy
oracle) and test_montecarlo.py (the 3-DOF flight against sim1dof), and before/after a change by
bench/pointmass_hashes.py."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware_model.flights.simulate import pointmass as pm
from firmware_model.spec import atmosphere as atm
from tests.support.imports import ROOT
from tests.support.profiles import examples


@settings(max_examples=examples(200), deadline=None)
@given(decel=st.floats(1.0, 60.0), frac=st.floats(0.01, 0.99), h=st.sampled_from([1e-3, 1 / 256, 1 / 64]),
       z=st.floats(0.0, 9000.0), t=st.floats(0.0, 60.0))
def test_apogee_in_a_step_of_constant_deceleration_is_the_closed_form(decel, frac, h, z, t):
    """Under a constant deceleration the vertical speed is linear in time and the altitude quadratic, so the
    step's interpolation must give the exact apogee: time v0/a after the step's start, height v0^2/(2a) above."""
    v0 = decel * h * frac              # the speed at the step's start, reaching 0 at frac of the step
    v_new = v0 - decel * h
    t_apo, z_apo = pm.apogee_in_step(t, h, z, v0, v_new)
    assert t_apo == pytest.approx(t + v0 / decel, rel=1e-12, abs=1e-12)
    assert z_apo == pytest.approx(z + v0 * v0 / (2.0 * decel), rel=1e-12, abs=1e-9)


@settings(max_examples=examples(200), deadline=None)
@given(alt=st.floats(-1500.0, 45_000.0))
def test_atmosphere_lookup_matches_the_standard_atmosphere_and_clamps(alt):
    """The 1 m tables interpolated linearly give the module's density and speed of sound within 1e-8 relative
    inside their range (docs/flights-sim.md), and the end values outside it."""
    rho_tab, c_tab = pm.atmosphere_tables()
    u = pm.table_coord(alt)
    inside = min(max(alt, pm.TABLE_LO_M), pm.TABLE_HI_M)
    assert pm.table_at(rho_tab, u) == pytest.approx(float(atm.density_kg_m3(np.array([inside]))[0]), rel=1e-8)
    assert pm.table_at(c_tab, u) == pytest.approx(float(atm.speed_of_sound_mps(np.array([inside]))[0]), rel=1e-8)


@settings(max_examples=examples(100), deadline=None)
@given(mach=st.floats(0.0, 6.0), c=st.floats(280.0, 350.0))
def test_drag_coefficient_is_linear_in_mach_and_held_beyond_the_table(mach, c):
    """A drag curve linear in Mach is reproduced at any Mach inside the grid (resampling and lookup are linear),
    and held at its last value above it."""
    tab = pm.drag_table(np.array([0.0, 4.0]), np.array([0.3, 0.7]))
    want = 0.3 + 0.1 * min(mach, pm.MACH_MAX)
    assert pm.cd_at(tab, mach * c, c) == pytest.approx(want, rel=1e-9)


def test_rk4_step_integrates_a_cubic_exactly():
    """RK4 is exact for dy/dt = polynomial of degree <= 3 in t (the slopes at t, t+h/2, t+h/2, t+h)."""
    f = lambda t: 1.0 - 3.0 * t + 2.0 * t * t + 0.5 * t ** 3
    primitive = lambda t: t - 1.5 * t * t + 2.0 / 3.0 * t ** 3 + 0.125 * t ** 4
    t0, h = 0.7, 0.25
    k = np.array([f(t0), f(t0 + h / 2), f(t0 + h / 2), f(t0 + h)])
    assert pm.rk4_step(2.0, h, k) == pytest.approx(2.0 + primitive(t0 + h) - primitive(t0), rel=1e-14)
    assert pm.rk4_stage(2.0, h, 4.0, 1) == pm.rk4_stage(2.0, h, 4.0, 2) == 2.0 + 0.5 * h * 4.0
    assert pm.rk4_stage(2.0, h, 4.0, 3) == 2.0 + h * 4.0


_STALE = """
import json
from firmware_model.flights.simulate import pointmass as pm, sim1dof as s1
from firmware_model.flights.simulate.motors import load_motor
b = s1._prepare([s1.Rocket("x", 8.0, 0.1, load_motor("K400C"))], [s1.Launch(record_hz=100.0)])
pm.register_for_numba()
def run():
    k = pm.njit_cached(s1._kernel_py, nogil=True)
    s1._integrate_kernel(b, k)
    return [sum(k.stats.cache_hits.values()), sum(k.stats.cache_misses.values())]
out = [run(), run()]
pm.source_digest = lambda: b"pointmass.py as edited"      # what a change of the shared helpers looks like
out.append(run())
print(json.dumps(out))
"""


@pytest.mark.skipif(not pm.HAVE_NUMBA, reason="numba (the 'fast' extra) is not installed")
def test_compiled_loop_cache_goes_stale_when_pointmass_changes(tmp_path):
    """numba checks a cached function against its own file only; the simulators' loops have pointmass's helpers
    compiled in, so njit_cached adds pointmass.py's digest to the stamp: same digest, the cache is loaded; another
    digest (an edited pointmass.py), it is compiled again rather than run stale."""
    env = dict(os.environ, PYTHONPATH=str(ROOT), NUMBA_CACHE_DIR=str(tmp_path / "numba"))
    env.pop("NUMBA_DISABLE_JIT", None)
    res = subprocess.run([sys.executable, "-c", _STALE], capture_output=True, text=True, env=env, cwd=ROOT,
                         timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    first, again, edited = json.loads(res.stdout.strip().splitlines()[-1])
    assert first == [0, 1]         # nothing cached yet: compiled
    assert again == [1, 0]         # the same sources: loaded from the cache
    assert edited == [0, 1]        # pointmass.py changed: compiled again

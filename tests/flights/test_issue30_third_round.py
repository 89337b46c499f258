"""Issue 30, third round (docs/firmware-spec.md History, "Steady re-base and the drag misread at the top"): teeth for
the two changes on flights of the project's own Monte Carlo specs (seed 1), each run on the bit-exact integer model
with the build the Monte Carlo plans for it.

* kalman_accel's accelerometer model error, 0.15 g: near apogee the flight path is far from vertical, so the axial
  drag the accelerometer reads is mostly horizontal, and the design that takes it as vertical misreads it by
  D (1 - sin gamma), the whole drag. With 0.05 g (the second round's design) these `ram-pressure.toml` flights fire
  more than 1 s early; with the default none does.
* the steady re-base (``H_STEP``): a re-base sets X1 to one sample, and a single-sample pressure spike at that sample
  of a clipped `supersonic.toml` flight put X1 170 m off; with the test off (H_STEP = INT32_MAX) kalman_accel fires
  more than 1 s early, with it not.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from firmware_model.flights.montecarlo import pipeline
from firmware_model.flights.montecarlo.spec import load_spec, read_spec_file
from firmware_model.model.run import run_model
from firmware_model.spec.build_constants import build_constants
from firmware_model.spec.config import BuildConfig
from firmware_model.spec.fixed import INT32_MAX

SPECS = Path(__file__).resolve().parents[2] / "docs" / "montecarlo"
#: Flights the 0.05 g design fired more than 1 s early (measured: -1.19, -1.11, -1.37, -1.34 s): 10-bit barometers
#: near their tops at 5-7 km (17 m a count, about a count of noise), air 9-24 K warmer than standard; over the last
#: second before the detection the filter's acceleration read 0.8-2.2 m/s^2 more than g.
RAM_EARLY_FLIGHTS: tuple[int, ...] = (14, 389, 6518, 5361)
#: The clipped supersonic flight whose clip-clear re-base landed on a 170 m spike.
SPIKE_AT_REBASE_FLIGHT: int = 6248


def _errors(spec_name: str, flights: tuple[int, ...], **change: object) -> list[float]:
    """Detection - true apogee (s) of kalman_accel (default tuning) on ``flights`` of seed 1; ``change``:
    ``accel_model_g`` (a config field) or ``H_STEP`` (a constant) replaced."""
    spec = load_spec(read_spec_file(SPECS / f"{spec_name}.toml"))
    plan = pipeline.plan_for(spec)
    sensed = pipeline.sense_chunk(spec, 1, list(flights))
    errors = []
    for i, prm in enumerate(sensed.params):
        cfg = plan.configs[("kalman_accel", "default", str(prm["baro"]), str(prm["accel"]))]
        if "accel_model_g" in change:
            cfg = dataclasses.replace(cfg, accel_model_g=change["accel_model_g"])
        consts = build_constants(cfg)
        if "H_STEP" in change:
            consts = dataclasses.replace(consts, H_STEP=change["H_STEP"])
        n = int(sensed.n[i])
        tr = run_model(consts, sensed.adc[i, :n], sensed.acc[i, :n])
        ia = tr.first_event("APOGEE")
        assert ia is not None, (spec_name, int(sensed.ids[i]))
        errors.append((ia + int(sensed.offset[i])) * plan.dt - float(sensed.events[i, 1]))
    return errors


@pytest.fixture(autouse=True)
def _fresh_plans(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(pipeline, "_PLANS", {})       # the builds are planned once per spec and process


def test_model_error_covers_the_drag_misread_at_the_top() -> None:
    assert BuildConfig(program="kalman_accel").accel_model_g == 0.15
    old = _errors("ram-pressure", RAM_EARLY_FLIGHTS, accel_model_g=0.05)
    assert sum(e < -1.0 for e in old) >= 3, old
    new = _errors("ram-pressure", RAM_EARLY_FLIGHTS)
    assert all(-1.0 <= e <= 1.0 for e in new), new


def test_steady_rebase_has_teeth() -> None:
    off = _errors("supersonic", (SPIKE_AT_REBASE_FLIGHT,), H_STEP=INT32_MAX)
    assert off[0] < -1.0, off
    on = _errors("supersonic", (SPIKE_AT_REBASE_FLIGHT,))
    assert -1.0 <= on[0] <= 1.0, on

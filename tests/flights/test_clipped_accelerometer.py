"""Issue 20, second change (docs/firmware-spec.md History "Clipped accelerometer"): on the simulated M6400 flight
(51 g for 1.3 s on the default +-16 g accelerometer, Mach 1.54 at burnout, a 5.9 km apogee with the barometer errors
of real flight), the accelerometer programs fired 26-27 s early at Mach 1.1 before the change. With it they fire
within a second or two of the truth; with the clip logic switched off through the build (clip_s far longer than any
burn: ACC_CLIP never set) they fire in the transonic passage again. The rows are those of `set:full`."""

from __future__ import annotations

import pytest

from firmware_model.flights.evaluation.evalset import named_set
from firmware_model.flights.evaluation.evaluate import evaluate_flight
from firmware_model.flights.evaluation.methods import methods_named


def _row(label: str):
    return next(s for s in named_set("full") if s.label == label)


@pytest.mark.parametrize("label, method, tuning", [
    ("rb-m6400-m167 [8-bit, clean, k5]", "rec_quarter", "recommended"),
    ("rb-m6400-m167 [16-bit, noisy, k5]", "rec_quarter", "recommended"),
    # kalman_accel at the default tuning: at the recommended one its accelerometer model error (docs/gain-design.md)
    # lets the barometer pull the clipped velocity up on its own (+2.6 s late without the clip logic, measured)
    ("rb-m6400-m167 [8-bit, clean, k5]", "kalman_accel", "default"),
])
def test_clipped_m6400_flight_fires_near_apogee_and_not_without_the_clip_logic(label: str, method: str,
                                                                               tuning: str) -> None:
    spec = _row(label)
    methods = methods_named([method])
    on = evaluate_flight(spec, methods, tuning=tuning)
    off = evaluate_flight(spec, methods, overrides={"clip_s": 1000.0}, tuning=tuning)
    truth = on.reference.time_s
    t_on, t_off = on.detections[method].time_s, off.detections[method].time_s
    assert t_on is not None and -1.0 <= t_on - truth <= 2.0, (t_on, truth)
    assert t_off is not None and t_off - truth < -5.0, (t_off, truth)


@pytest.mark.parametrize("label", ["rb-m6400-m167 [8-bit, clean, k5]", "rb-m6400-m167 [16-bit, noisy, k5]"])
def test_clipped_m6400_flight_kalman_accel_recommended_fires_near_apogee(label: str) -> None:
    spec = _row(label)
    on = evaluate_flight(spec, methods_named(["kalman_accel"]), tuning="recommended")
    t = on.detections["kalman_accel"].time_s
    assert t is not None and -1.0 <= t - on.reference.time_s <= 2.0, (t, on.reference.time_s)

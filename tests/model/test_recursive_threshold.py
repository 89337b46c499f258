"""The recursive filter's noise-sized apogee threshold (issue 30, third round; docs/firmware-spec.md §3 ``THR``).

``THR = max(threshold_q8, ceil(threshold_sigmas * 256 * baro_sigma * sqrt(a / (2 - a))))``, a = 2^-S: the filtered
word's noise. The variance factor a / (2 - a) is checked against the integer model's own EST on white noise (the
filter as the firmware runs it, not the formula again), and the threshold's effect on a flight where the fixed
1/8 LSB fired on noise more than 1 s before apogee.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from firmware_model.flights.evaluation.evalset import k_set
from firmware_model.flights.evaluation.evaluate import evaluate_flight
from firmware_model.flights.evaluation.methods import METHODS
from firmware_model.model.run import run_model
from firmware_model.runtime.errors import UserError
from firmware_model.spec.build_constants import build_constants, recursive_threshold
from firmware_model.spec.config import BuildConfig
from firmware_model.spec.tuning import RECOMMENDED


def _cfg(**fields: object) -> BuildConfig:
    base = dict(program="recursive", k=6, shift=4, threshold_q8=128, baro_bits=16, baro_sign=1)
    base.update(fields)
    return BuildConfig.from_dict(base, where="test")


def test_off_by_default_and_threshold_q8_is_the_floor() -> None:
    assert BuildConfig().threshold_sigmas == 0.0
    assert build_constants(_cfg(baro_sigma=40.0)).THR == 128                  # off: threshold_q8 alone
    assert build_constants(_cfg(baro_sigma=0.01, threshold_sigmas=3.0)).THR == 128   # quiet sensor: the floor
    # 3 sigma of 8 counts through S = 4: 3 * 256 * 8 * sqrt((1/16) / (31/16)) = 6144 / sqrt(31) = 1103.5...
    assert build_constants(_cfg(baro_sigma=8.0, threshold_sigmas=3.0)).THR == 1104
    assert 6144 / math.sqrt(31) == pytest.approx(1103.5, abs=0.1)


def test_threshold_beyond_q24_8_range_is_a_user_error() -> None:
    with pytest.raises(UserError, match="threshold_sigmas"):
        recursive_threshold(_cfg(baro_sigma=60000.0, threshold_sigmas=100.0, shift=1))


def test_filtered_noise_matches_the_model_est() -> None:
    """sigma(EST) / sigma(z) = sqrt(a / (2 - a)) measured on the integer model's EST, white z of 40 counts."""
    rng = np.random.default_rng(20261204)
    for shift in (3, 4, 5):
        n = 200_000
        z = np.clip(np.round(30000 + 40.0 * rng.standard_normal(n)), 0, 65535).astype(np.int64)
        cfg = _cfg(shift=shift, gate_sigmas=0.0)   # no rate gate: the filter alone
        tr = run_model(build_constants(cfg), z, np.zeros(n, dtype=np.int64))
        est = np.asarray(tr.column("EST"), dtype=np.float64)[2000:] / 256.0
        a = 2.0**-shift
        predicted = 40.0 * math.sqrt(a / (2.0 - a))
        # ~n / 2^S independent samples: the estimate's relative standard error is below 1 %
        assert np.std(est) == pytest.approx(predicted, rel=0.04), shift


def test_recommended_tuning_carries_three_sigmas() -> None:
    assert all(entry["threshold_sigmas"] == 3.0 for entry in RECOMMENDED["recursive"].values())


def test_noise_threshold_has_teeth() -> None:
    """sub-k400-900m on a noisy 10-bit barometer at k = 5 (a row of set:full): the recommended shift with the fixed
    1/8 LSB fires on the filtered noise more than 1 s before apogee; with 3 sigmas of that noise it does not."""
    specs, _ = k_set(ks=(5,), with_logs=False)
    spec = next(s for s in specs if s.label == "sub-k400-900m [10-bit, noisy, k5]")
    method = METHODS["rec_eighth"]
    without = evaluate_flight(spec, [method], overrides={"threshold_sigmas": 0.0}, tuning="recommended")
    with_thr = evaluate_flight(spec, [method], tuning="recommended")
    e0, e3 = without.error("rec_eighth"), with_thr.error("rec_eighth")
    assert e0 is not None and e0 < -1.0
    assert e3 is not None and -1.0 <= e3 <= 1.5

"""Hypothesis profiles shared by every test module.

* ``ci`` (default): deterministic (derandomized), moderate example counts, no deadline. What ``make test`` runs.
* ``thorough``: random seeds and 20x the examples; ``make test-thorough`` (``HYPOTHESIS_PROFILE=thorough``).

Tests that need an explicit example count call :func:`examples` so that the thorough profile scales it.
"""

from __future__ import annotations

import os

from hypothesis import HealthCheck, settings

_COMMON = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
settings.register_profile("ci", derandomize=True, print_blob=True, **_COMMON)
settings.register_profile("thorough", max_examples=2000, print_blob=True, **_COMMON)

PROFILE: str = os.environ.get("HYPOTHESIS_PROFILE", "ci")
#: Factor applied by :func:`examples` per profile.
SCALE: dict[str, int] = {"ci": 1, "thorough": 20}


def examples(n: int) -> int:
    """Example count for a test that wants ``n`` examples under the ``ci`` profile (scaled for ``thorough``)."""
    return n * SCALE.get(PROFILE, 1)

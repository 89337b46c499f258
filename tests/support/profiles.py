"""Hypothesis profiles shared by every test module.

* ``ci`` (default): deterministic (derandomized), moderate example counts, no deadline. What ``make test`` runs.
* ``thorough``: random seeds and 20x the examples; ``make test-thorough`` (``HYPOTHESIS_PROFILE=thorough``).

Tests that need an explicit example count call :func:`examples` so that the thorough profile scales it. A long
property run (seconds per hundred examples) may name a smaller count for ``ci`` (issue 10: long property runs move
behind ``thorough``, which keeps their examples): ``examples(150, ci=30)`` runs 30 examples under ``ci`` and still
20 x 150 = 3,000 under ``thorough``, as before (docs/history/testing-rounds.md, third round, has the table).
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


def examples(n: int, ci: int | None = None) -> int:
    """Example count for a test that wants ``n`` examples under the ``ci`` profile (scaled for ``thorough``).
    ``ci`` (< ``n``): a long property run's count under the default ``ci`` profile only; every other profile
    still scales ``n``, so ``thorough`` runs what it ran before."""
    if ci is not None:
        if not 0 < ci < n:
            raise ValueError(f"examples({n}, ci={ci}): the ci count must be between 1 and {n - 1}")
        if PROFILE == "ci":
            return ci
    return n * SCALE.get(PROFILE, 1)

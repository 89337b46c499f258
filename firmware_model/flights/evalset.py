"""The evaluation set behind the README's apogee table, and how command-line FLIGHT arguments become
:class:`~firmware_model.flights.evaluate.FlightSpec` rows (docs/evaluation.md, "The evaluation set").

* ``set:eval`` (:func:`evaluation_set`): every simulated scenario (:func:`flights.scenarios.scenario_names`) at the
  default sensing (16-bit MPX4115-class ADC, noisy, k = 7), then variations over a fixed subset of scenarios
  (8/10/12/16-bit ADCs, TeleMetrum v1, noise-free and noisy, k = 4..8), then every shared real log at k = 7
  (their own sensor, no added noise: they carry real noise).
* ``set:sim`` the simulated part, ``set:logs`` the logs, ``set:quick`` a few short flights (tests, smoke runs).

**Pascal sensor**: the MS5607-like digital barometer reports pascals in a 32-bit word; today's firmware reads a
16-bit barometer word (``BuildConfig.baro_bits`` 8..16), so the set cannot include it yet. :func:`pascal_supported`
is the hook: when the field-ready firmware of issue 9 accepts a pascal input (a ``BuildConfig`` that takes the
sensor's ``config_overrides()`` for ``ms5607``), the pascal rows of :data:`PASCAL_VARIANTS` join the set
automatically; until then :func:`evaluation_set` lists them in ``skipped`` with the reason.
"""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path
from typing import Iterable, Sequence

from firmware_model.errors import UserError
from firmware_model.flights.evaluate import FlightSpec

#: The shared real logs (relative to the shared flights folder), in table order.
SHARED_LOGS: tuple[str, ...] = (
    "altosui/prometheus-2022-06-24-telemetrum.csv",
    "altosui/prometheus-2022-06-24-telemega.csv",
    "altosui/2012-04-07-serial-882-flight-001.csv",
    "altosui/2012-05-28-serial-319-flight-005.csv",
    "altosui/2012-10-20-serial-068-flight-004.csv",
    "cats/hedy-baro.csv",
)

#: Default sensing of the simulated rows: (barometer preset, accelerometer preset, noisy, k).
DEFAULT_SIM: tuple[str, str, bool, int] = ("mpx4115_16bit", "default", True, 7)

#: Variations (barometer preset, accelerometer preset, noisy, k), applied to :data:`VARIED_SCENARIOS` picks.
VARIANTS: tuple[tuple[str, str, bool, int], ...] = (
    ("mpx4115_16bit", "default", False, 7),
    ("mpx4115_12bit", "default", True, 7),
    ("mpx4115_10bit", "default", True, 6),
    ("mpx4115_8bit", "default", True, 5),
    ("mpx4115_8bit", "default", False, 4),
    ("telemetrum_v1", "mma2202_12bit", True, 8),
    ("mpx4115_16bit", "adxl375", True, 4),
    ("mpx4115_12bit", "default", False, 8),
)
PASCAL_VARIANTS: tuple[tuple[str, str, bool, int], ...] = (
    ("ms5607", "default", True, 7),
    ("ms5607", "default", False, 6),
)


def shared_dir() -> Path | None:
    """The shared flights folder: ``$FWEMU_SHARED_FLIGHTS``, else ``<repo>/../shared/flights``; None if absent."""
    env = os.environ.get("FWEMU_SHARED_FLIGHTS")
    if env:
        return Path(env) if Path(env).is_dir() else None
    here = Path(__file__).resolve().parents[2] / ".." / "shared" / "flights"
    return here.resolve() if here.is_dir() else None


def shared_logs() -> list[Path]:
    """The shared logs that exist (empty when the folder is absent)."""
    base = shared_dir()
    if base is None:
        return []
    return [base / rel for rel in SHARED_LOGS if (base / rel).is_file()]


def log_label(path: Path) -> str:
    name = path.stem
    return "hedy (CATS)" if name == "hedy-baro" else name


def pascal_supported() -> bool:
    """True when the firmware can take a pascal barometer (issue 9's field-ready inputs): a BuildConfig accepts a
    32-bit barometer word."""
    from firmware_model.config import BuildConfig

    try:
        BuildConfig(baro_bits=32)
    except (UserError, TypeError):
        return False
    return True


def _scenario_names() -> list[str]:
    from firmware_model.flights.scenarios import scenario_names

    return list(scenario_names())


def _spec(name: str, variant: tuple[str, str, bool, int], seed: int, label: str | None = None) -> FlightSpec:
    baro, accel, noisy, k = variant
    return FlightSpec(f"sim:{name}", k=k, baro=baro, accel=accel, noise=noisy, seed=seed,
                      label=label or name)


def simulated_set(names: Sequence[str] | None = None, with_variants: bool = True) -> tuple[list[FlightSpec],
                                                                                          list[str]]:
    """Simulated rows and the rows skipped (with reasons)."""
    names = list(names) if names is not None else _scenario_names()
    specs = [_spec(n, DEFAULT_SIM, seed=i) for i, n in enumerate(names)]
    skipped: list[str] = []
    if with_variants and names:
        variants = list(VARIANTS)
        pascal = list(PASCAL_VARIANTS)
        if pascal_supported():
            variants += pascal
        else:
            skipped += [f"{n}: {v[0]} (pascal sensor): today's firmware reads a 16-bit barometer word; needs the "
                        f"field-ready firmware of issue 9" for n, v in zip(names[::3], pascal)]
        # spread the variations over the scenarios: every third scenario, cycling through the variants
        picks = names[::max(1, len(names) // len(variants))] if len(names) >= len(variants) else names
        for j, variant in enumerate(variants):
            n = picks[j % len(picks)]
            b, _, noisy, k = variant
            specs.append(_spec(n, variant, seed=1000 + j, label=f"{n} [{b}, {'noisy' if noisy else 'clean'}, k{k}]"))
    return specs, skipped


def logs_set(k: int = 7) -> list[FlightSpec]:
    """Every shared log at ``k``, its own sensor, no added noise."""
    return [FlightSpec(str(p), k=k, noise=False, label=log_label(p)) for p in shared_logs()]


def evaluation_set() -> tuple[list[FlightSpec], list[str]]:
    """The README table's rows and the rows skipped (with reasons)."""
    sim, skipped = simulated_set()
    return sim + logs_set(), skipped


#: ``set:quick``: short flights for tests and smoke runs.
QUICK_SCENARIOS: int = 3


def quick_set() -> list[FlightSpec]:
    names = _scenario_names()[:QUICK_SCENARIOS]
    return [_spec(n, DEFAULT_SIM, seed=i) for i, n in enumerate(names)]


def named_set(name: str) -> list[FlightSpec]:
    """``eval``, ``sim``, ``logs``, ``quick``."""
    if name == "eval":
        return evaluation_set()[0]
    if name == "sim":
        return simulated_set()[0]
    if name == "logs":
        return logs_set()
    if name == "quick":
        return quick_set()
    raise UserError(f"set:{name}: unknown evaluation set; known: eval, sim, logs, quick")


def resolve_flights(items: Iterable[str], simulated: bool = False, logs: bool = False, ks: Sequence[int] = (7,),
                    baro: str | None = None, accel: str | None = None, noise: bool = True,
                    format: str | None = None) -> list[FlightSpec]:
    """FLIGHT arguments -> rows: files and ``sim:NAME`` at each k in ``ks`` with the given sensing (files keep
    their own sensor and get no added noise unless a preset is named), ``set:NAME`` as defined, then every
    scenario (``simulated``) and every shared log (``logs``)."""
    specs: list[FlightSpec] = []
    for k in ks:
        if not isinstance(k, int) or not 0 <= k <= 10:
            raise UserError(f"--k {k!r}: must be an integer 0..10")
    for item in items:
        if item.startswith("set:"):
            specs += named_set(item[4:])
            continue
        if item.startswith("sim:"):
            names = _scenario_names()
            if item[4:] not in names:
                raise UserError(f"{item}: unknown scenario; known: {', '.join(names)}")
            for k in ks:
                specs.append(FlightSpec(item, k=k, baro=baro or DEFAULT_SIM[0], accel=accel or DEFAULT_SIM[1],
                                        noise=noise, label=_label(item[4:], k, ks)))
            continue
        path = Path(item)
        if not path.is_file():
            raise UserError(f"{item}: no such flight file (or use sim:NAME / set:NAME)")
        for k in ks:
            own = baro is None and accel is None
            specs.append(FlightSpec(item, k=k, baro=baro, accel=accel, noise=noise and not own, format=format,
                                    label=_label(log_label(path), k, ks)))
    if simulated:
        for k in ks:
            specs += [replace(s, k=k, label=_label(s.label or s.name, k, ks))
                      for s in simulated_set(with_variants=False)[0]]
    if logs:
        for k in ks:
            specs += [replace(s, label=_label(s.label or s.name, k, ks)) for s in logs_set(k)]
    return specs


def _label(name: str, k: int, ks: Sequence[int]) -> str:
    return name if len(ks) == 1 else f"{name} k{k}"


__all__ = ["SHARED_LOGS", "DEFAULT_SIM", "VARIANTS", "PASCAL_VARIANTS", "shared_dir", "shared_logs",
           "pascal_supported", "simulated_set", "logs_set", "evaluation_set", "quick_set", "named_set",
           "resolve_flights"]

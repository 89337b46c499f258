"""The evaluation set behind the README's apogee table, and how command-line FLIGHT arguments become
:class:`~firmware_model.flights.evaluation.setup.FlightSpec` rows (docs/evaluation.md, "The evaluation sets").

* ``set:eval`` (:func:`evaluation_set`): every simulated scenario (:func:`flights.scenarios.scenario_names`) with
  each of the sensings its catalogue tags suggest (:func:`scenario_variants`: 8/10/12/16-bit MPX4115-class ADCs,
  the MS5607-like pascal sensor, noise-free and noisy, k = 4..8), then every shared real log at k = 7 (the
  TeleMetrum v1 transfer function, no added noise: the logs carry real noise).
* ``set:sim`` the simulated part, ``set:logs`` the logs, ``set:quick`` a few short flights (tests, smoke runs).
* ``set:full`` (:func:`k_set`): every scenario x each distinct tagged sensing x k = 5, 6, 7, and every shared log
  x k = 5, 6, 7 (issue 20's before/after set); ``set:realbaro`` the same for the scenarios with the barometer
  errors of real flight only; ``set:ram`` the scenarios with issue 30's ram error in boost, no logs.

**Pascal sensor**: the MS5607-like digital barometer reports pascals in a 32-bit word, which the firmware reads
since issue 9 item 1 (``BuildConfig.baro_kind`` pascal, docs/firmware-spec.md §2). :func:`pascal_supported` (true
when BuildConfig has the ``baro_kind`` field that ``FirmwareInputs.config_overrides()`` passes for a pascal
sensor) lets the pascal rows join the set; a build without it lists them in ``skipped`` with the reason.
"""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path
from typing import Any, Iterable, Sequence

from firmware_model.flights.evaluation.setup import FlightSpec
from firmware_model.flights.simulate.scenarios import get_scenario, scenario_names
from firmware_model.runtime.errors import UserError
from firmware_model.spec.config import BuildConfig

#: The shared real logs (relative to the shared flights folder), in table order.
SHARED_LOGS: tuple[str, ...] = (
    "altosui/prometheus-2022-06-24-telemetrum.csv",
    "altosui/prometheus-2022-06-24-telemega.csv",
    "altosui/2012-04-07-serial-882-flight-001.csv",
    "altosui/2012-05-28-serial-319-flight-005.csv",
    "altosui/2012-10-20-serial-068-flight-004.csv",
    "cats/hedy-baro.csv",
    # issue 21: the other formats. One row per file that holds a flight's barometer; a file read through its
    # partner (hedy-imu, piccard-cats-imu_raw) is covered by that row; companions (events, states) are not logs.
    "euroc21/piccard-telemega.csv",
    "euroc21/piccard-telemega-serial-6733-flight-0004.eeprom",
    "euroc21/piccard-telemetrum-nosecone-serial-5877-flight-0002.eeprom",
    "euroc21/piccard-cats-baro_raw.csv",
    "euroc21/sta-carl2-rrc3.csv",
    "euroc21/sta-carl2-eggtimer.csv",
    "euroc21/lynx-pressure_ms5803.csv",
    "euroc21/lynx-pressure_static_port.csv",
    "euroc21/lynx-eggtimer.csv",
    "euroc21/euler-eggtimer.csv",
    "rocketpy/juno3-rrc3.csv",
    "rocketpy/ndrt-2020-raven.csv",
    "ncsu/jackpot-launch-3-firm.csv",
)

#: Default sensing of a ``sim:NAME`` argument: (barometer preset, accelerometer preset, noisy, k).
DEFAULT_SIM: tuple[str, str, bool, int] = ("mpx4115_16bit", "default", True, 7)

#: Scenario tag -> sensor preset (:data:`firmware_model.flights.inputs.sensors.BARO_PRESETS`).
BARO_TAGS: dict[str, str] = {"analog-8": "mpx4115_8bit", "analog-10": "mpx4115_10bit",
                             "analog-12": "mpx4115_12bit", "analog-16": "mpx4115_16bit", "ms5607": "ms5607",
                             "telemetrum": "telemetrum_v1"}
NOISE_TAGS: dict[str, bool] = {"none": False, "noisy": True}


def shared_dir() -> Path | None:
    """The shared flights folder: ``$FWEMU_SHARED_FLIGHTS``, else ``<repo>/../shared/flights``; None if absent."""
    env = os.environ.get("FWEMU_SHARED_FLIGHTS")
    if env:
        return Path(env) if Path(env).is_dir() else None
    here = Path(__file__).resolve().parents[3] / ".." / "shared" / "flights"
    return here.resolve() if here.is_dir() else None


def shared_logs() -> list[Path]:
    """The shared logs that exist (empty when the folder is absent)."""
    base = shared_dir()
    if base is None:
        return []
    return [base / rel for rel in SHARED_LOGS if (base / rel).is_file()]


def log_label(path: Path) -> str:
    name = path.stem
    if name == "hedy-baro":
        return "hedy (CATS)"
    if name == "piccard-cats-baro_raw":
        return "piccard (CATS raw)"
    return name


def pascal_supported() -> bool:
    """True when the firmware can take a pascal barometer (issue 9's field-ready inputs): BuildConfig has a
    ``baro_kind`` field (what :meth:`FirmwareInputs.config_overrides` passes for a pascal sensor)."""
    import dataclasses

    return "baro_kind" in {f.name for f in dataclasses.fields(BuildConfig)}


def _scenario_names() -> list[str]:
    return list(scenario_names())


def scenario_variants(name: str) -> list[tuple[str, str, bool, int]]:
    """The sensings of scenario ``name`` from its catalogue tags (``baro``, ``noise``, ``k`` lists), zipped with
    cycling (row i takes the i-th entry of each list, modulo its length) so every listed value appears once:
    ``max(len)`` rows, not the product."""

    tags = get_scenario(name).tags or {}
    baros = [BARO_TAGS.get(b, b) for b in tags.get("baro", ["analog-16"])] or ["mpx4115_16bit"]
    noises = [NOISE_TAGS.get(n, True) for n in tags.get("noise", ["noisy"])] or [True]
    ks = [int(k) for k in tags.get("k", [7])] or [7]
    rows = max(len(baros), len(noises), len(ks))
    return [(baros[i % len(baros)], "default", noises[i % len(noises)], ks[i % len(ks)]) for i in range(rows)]


def _row_label(name: str, variant: tuple[str, str, bool, int]) -> str:
    baro, _, noisy, k = variant
    short = baro.replace("mpx4115_", "").replace("bit", "-bit")
    return f"{name} [{short}, {'noisy' if noisy else 'clean'}, k{k}]"


def simulated_set(names: Sequence[str] | None = None, with_variants: bool = True) -> tuple[list[FlightSpec],
                                                                                          list[str]]:
    """Simulated rows (every scenario x its tagged sensings; ``with_variants=False``: the first only) and the rows
    skipped with the reason (pascal sensors until :func:`pascal_supported`)."""
    names = list(names) if names is not None else _scenario_names()
    specs: list[FlightSpec] = []
    skipped: list[str] = []
    pascal_ok = pascal_supported()
    for i, n in enumerate(names):
        variants = scenario_variants(n)
        if not with_variants:
            adc = [v for v in variants if v[0] != "ms5607"] or [DEFAULT_SIM]
            variants = adc[:1]
        for j, v in enumerate(variants):
            if v[0] == "ms5607" and not pascal_ok:
                skipped.append(f"{_row_label(n, v)}: the pascal sensor needs the field-ready firmware of issue 9 "
                               f"(today's firmware reads a 16-bit barometer word)")
                continue
            specs.append(FlightSpec(f"sim:{n}", k=v[3], baro=v[0], accel=v[1], noise=v[2], seed=100 * i + j,
                                    label=_row_label(n, v)))
    return specs, skipped


def logs_set(k: int = 7) -> list[FlightSpec]:
    """Every shared log at ``k``, its own sensor, no added noise."""
    return [FlightSpec(str(p), k=k, noise=False, label=log_label(p)) for p in shared_logs()]


def _has_ram(name: str) -> bool:
    """The scenario carries issue 30's ram error in boost."""
    model = get_scenario(name).error_model()
    return model is not None and model.ram_cp > 0


def k_set(ks: Sequence[int] = (5, 6, 7), only_real_baro: bool = False, only_ram: bool = False,
          with_logs: bool = True) -> tuple[list[FlightSpec], list[str]]:
    """Every scenario (``only_real_baro``: only those with the barometer errors of real flight,
    ``Scenario.baro_errors``; ``only_ram``: only those with issue 30's ram error in boost) with each distinct
    sensing its tags suggest (barometer, accelerometer, noise; the tagged k is replaced) at every k of ``ks``, then
    (``with_logs``) every shared log at each k. ``set:full`` and ``set:realbaro``: the sets the issue-20
    before/after tables are made on; ``set:ram`` the issue-30 scenarios alone (no logs). Returns (rows, skipped
    rows). A scenario keeps its row seeds whichever subset it is listed in."""
    specs: list[FlightSpec] = []
    skipped: list[str] = []
    pascal_ok = pascal_supported()
    for i, n in enumerate(_scenario_names()):
        if only_real_baro and get_scenario(n).baro_errors is None:
            continue
        if only_ram and not _has_ram(n):
            continue
        sensings: list[tuple[str, str, bool]] = []
        for v in scenario_variants(n):
            if v[:3] not in sensings:
                sensings.append(v[:3])
        for j, sensing in enumerate(sensings):
            for k in ks:
                vk = (*sensing, k)
                if sensing[0] == "ms5607" and not pascal_ok:
                    skipped.append(f"{_row_label(n, vk)}: the pascal sensor needs the field-ready firmware")
                    continue
                specs.append(FlightSpec(f"sim:{n}", k=k, baro=sensing[0], accel=sensing[1], noise=sensing[2],
                                        seed=100 * i + j, label=_row_label(n, vk)))
    for k in ks if with_logs else ():
        specs += [replace(s, label=f"{s.label} k{k}") for s in logs_set(k)]
    return specs, skipped


def evaluation_set() -> tuple[list[FlightSpec], list[str]]:
    """The README table's rows and the rows skipped (with reasons)."""
    sim, skipped = simulated_set()
    return sim + logs_set(), skipped


#: ``set:quick``: a few short flights (tests, smoke runs).
QUICK_SCENARIOS: tuple[str, ...] = ("sub-k400-300m", "sub-k400-900m", "trans-m1670-m105")


def quick_set() -> list[FlightSpec]:
    names = [n for n in QUICK_SCENARIOS if n in _scenario_names()] or _scenario_names()[:3]
    return [FlightSpec(f"sim:{n}", k=6, baro="mpx4115_16bit", accel="default", noise=True, seed=i, label=n)
            for i, n in enumerate(names)]


def named_set(name: str) -> list[FlightSpec]:
    """``eval``, ``sim``, ``logs``, ``quick``, ``full``, ``realbaro``, ``ram`` (:func:`k_set`)."""
    if name == "eval":
        return evaluation_set()[0]
    if name == "sim":
        return simulated_set()[0]
    if name == "logs":
        return logs_set()
    if name == "quick":
        return quick_set()
    if name == "full":
        return k_set()[0]
    if name == "realbaro":
        return k_set(only_real_baro=True)[0]
    if name == "ram":
        return k_set(only_ram=True, with_logs=False)[0]
    raise UserError(f"set:{name}: unknown evaluation set; known: eval, sim, logs, quick, full, realbaro, ram")


def resolve_flights(items: Iterable[str], simulated: bool = False, logs: bool = False, ks: Sequence[int] = (7,),
                    baro: str | None = None, accel: str | None = None, noise: bool = True,
                    format: str | None = None, **reader: Any) -> list[FlightSpec]:
    """FLIGHT arguments -> rows: files and ``sim:NAME`` (``sim:all``: every scenario) at each k in ``ks`` with the given
    sensing (files keep their own sensor and get no added noise unless a preset is named), ``set:NAME`` as defined, then
    every scenario (``simulated``) and every shared log (``logs``). ``reader``: reader options for the FLIGHT files
    (``sensor``, ``columns``, ``site_altitude_m``, ``flight``) and ``late`` (a late start's accelerometer, also for
    ``logs``)."""
    specs: list[FlightSpec] = []
    for k in ks:
        if not isinstance(k, int) or not 0 <= k <= 10:
            raise UserError(f"--k {k!r}: must be an integer 0..10")
    # ``sim:all``: every scenario as a FLIGHT argument (so --k, --baro, --accel, --no-noise apply, unlike set:sim)
    items = [x for item in items for x in ([f"sim:{n}" for n in _scenario_names()] if item == "sim:all" else [item])]
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
        if path.is_dir():
            raise UserError(f"{item}: is a folder, not a flight file (name the log files in it)")
        if path.exists() and not path.is_file():
            raise UserError(f"{item}: is not a regular file (a FIFO or a device), not a flight file")
        if not path.is_file():
            raise UserError(f"{item}: no such flight file (or use sim:NAME / set:NAME)")
        for k in ks:
            own = baro is None and accel is None
            specs.append(FlightSpec(item, k=k, baro=baro, accel=accel, noise=noise and not own, format=format,
                                    label=_label(log_label(path), k, ks),
                                    **{key: v for key, v in reader.items() if v is not None}))
    late = reader.get("late") or "nominal"
    if simulated:
        for k in ks:
            specs += [replace(s, k=k, label=_label(s.label or s.name, k, ks))
                      for s in simulated_set(with_variants=False)[0]]
    if logs:
        for k in ks:
            specs += [replace(s, label=_label(s.label or s.name, k, ks), late=late) for s in logs_set(k)]
    return specs


def _label(name: str, k: int, ks: Sequence[int]) -> str:
    return name if len(ks) == 1 else f"{name} k{k}"


__all__ = ["SHARED_LOGS", "DEFAULT_SIM", "BARO_TAGS", "NOISE_TAGS", "shared_dir", "shared_logs",
           "pascal_supported", "scenario_variants", "simulated_set", "logs_set", "k_set", "evaluation_set",
           "quick_set", "named_set",
           "resolve_flights"]

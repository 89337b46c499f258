"""Recommended tuning per program and k for the field-ready firmware (README "Field-ready firmware", the table
that justifies it; measured on the 6 shared logs and the 28 simulated scenarios of ``firmware_model.flights``).

Since issue 30 the Kalman programs' :class:`~firmware_model.spec.config.BuildConfig` defaults *are* the recommended
designs (``config.PROGRAM_DEFAULTS``: a default a user gets without asking must be safe), so for them the two tunings
build the same firmware; the recursive filter's defaults are Schultz 2002's (S = 5, 1/4 LSB) and its recommendation
differs. These overrides are what the evaluation recommends. ``recommended_config("kalman_accel", 6)`` gives a ready
build config.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from firmware_model.runtime.errors import UserError
from firmware_model.spec.config import PROGRAM_DEFAULTS, BuildConfig, from_sources, load_config, read_config_file

#: The tunings the commands take (``--tuning``): the BuildConfig defaults, or :data:`RECOMMENDED`.
TUNINGS: tuple[str, ...] = ("default", "recommended")

#: Overrides of the BuildConfig defaults per program, for k = 5..7 (the evaluated range).
RECOMMENDED: dict[str, dict[int, dict[str, Any]]] = {
    # The Kalman entries are the programs' defaults since issue 30 (config.PROGRAM_DEFAULTS, one source), spelled out
    # so that describe_tuning says what they set. kalman_baro, R/q 1,000: worst |error| 0.45-0.55 s against
    # 1.0-1.2 s at 50,000, medians 0.05-0.13 s (README table)
    "kalman_baro": {k: dict(PROGRAM_DEFAULTS["kalman_baro"]) for k in (5, 6, 7)},
    # half_up: floor biases the metres state (X2 -1.9 m/s at k = 7 on a still pad, docs/numerics.md); R/q 1,000;
    # a 0.15 g accelerometer model error (the axial reading as vertical: on a tilted flight, and near apogee where the
    # flight path is far from vertical the whole drag; without a model error the Monte Carlo's windy subsonic flights
    # fired more than 1 s early 8.1 % of the time, with 0.05 g 22 of 10,000 ram-pressure flights; docs/gain-design.md)
    "kalman_accel": {k: dict(PROGRAM_DEFAULTS["kalman_accel"]) for k in (5, 6, 7)},
    # S = k - 2 (a lag of 2^(k-2) samples = 0.25 s at every k), THR = 1/2 LSB (issue 30: at 1/4 and 1/8 LSB the
    # barometer's noise and an 8-bit ADC's steps fired 4 and 19 runs of set:full more than 1 s early, 1/2 LSB none;
    # docs/evaluation.md) and at least 3 sigmas of the filtered barometer noise (issue 30, third round: at a fixed
    # 1/2 LSB a 7-8 Pa barometer near 8 km fired 8 of 10,000 ram-pressure Monte Carlo flights more than 1 s
    # early at k = 6, where S = 4 leaves 0.18 of the noise in EST; with it 0); the rate gate, its re-base and the
    # 0.06 s apogee evidence after an accelerometer clip at their defaults (docs/history/evaluation-rounds.md,
    # "Recursive filter, field-ready")
    "recursive": {k: {"shift": k - 2, "threshold_q8": 128, "threshold_sigmas": 3.0} for k in (5, 6, 7)},
}


def recommended_config(program: str, k: int, **overrides: Any) -> BuildConfig:
    """The recommended build of ``program`` at ``k`` (5..7), with ``overrides`` applied last (sensor fields:
    ``baro_bits``, ``units_per_metre``, ...). Raises :class:`UserError` for a program or k without a
    recommendation."""
    if program not in RECOMMENDED:
        raise UserError(f"tuning: no recommendation for program {program!r}; known: {', '.join(RECOMMENDED)}")
    if k not in RECOMMENDED[program]:
        evaluated = ", ".join(map(str, RECOMMENDED[program]))
        raise UserError(f"tuning: no recommendation for k={k!r} (evaluated: {evaluated})")
    fields = dict(RECOMMENDED[program][k])
    fields.update(overrides)
    return BuildConfig(program=program, k=k, **fields)


def tuning_fields(program: str, k: int, tuning: str = "default") -> dict[str, Any]:
    """The BuildConfig fields ``tuning`` sets for ``program`` at ``k``: none for ``default``; for ``recommended``
    :data:`RECOMMENDED`'s entry (empty for a program or k without one: the defaults are kept)."""
    if tuning not in TUNINGS:
        raise UserError(f"--tuning {tuning!r}: known: {', '.join(TUNINGS)}")
    if tuning == "default":
        return {}
    return dict(RECOMMENDED.get(program, {}).get(k, {}))


def describe_tuning(program: str, k: int, tuning: str, applied: dict[str, Any] | None = None) -> str:
    """One line for a command's output: which tuning, and what it set (``applied``: the fields the command took
    from it, when a method's own fields kept some out; default all of :func:`tuning_fields`)."""
    if tuning == "default":
        return "tuning: default (the BuildConfig defaults)"
    fields = tuning_fields(program, k, tuning) if applied is None else applied
    if not fields:
        return f"tuning: recommended has no entry for {program} at k={k}: the defaults are kept"
    return "tuning: recommended (" + ", ".join(f"{name}={value}" for name, value in fields.items()) + ")"


def load_tuned_config(path: str | Path | None, overrides: dict[str, Any] | None, tuning: str = "default",
                      flag_names: dict[str, str] | None = None) -> BuildConfig:
    """:func:`config.load_config` with a tuning under it: the BuildConfig defaults, then the tuning's fields for
    the program and k that the file and flags choose, then the file, then the flags (so anything written in
    the file or given as a flag wins over the tuning)."""
    cfg = load_config(path, overrides, flag_names)
    tuned = tuning_fields(cfg.program, cfg.k, tuning)
    if not tuned:
        return cfg
    data = read_config_file(path) if path is not None else {}
    given = {key: value for key, value in (overrides or {}).items() if value is not None}
    where = str(path) if path is not None else "build config"
    return from_sources(data, given, where, None, flag_names, under=tuned)


__all__ = ["RECOMMENDED", "TUNINGS", "recommended_config", "tuning_fields", "describe_tuning", "load_tuned_config"]

"""The evaluation's methods and detection: a **method** is a firmware program with its tuning (:data:`METHODS`),
run on the bit-exact integer model or the float mirror (:func:`run_method`); its **detection** is the first sample
whose ``EVENTS`` word has ``APOGEE`` set (:func:`detect_from_events`). The tunings ``--tuning`` selects
(:func:`tuning_overrides`). docs/evaluation.md."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Iterable

import numpy as np

from firmware_model.model.float_reference import mirror
from firmware_model.model.run import run_model
from firmware_model.model.trace import EVENT_BITS
from firmware_model.runtime.errors import UserError
from firmware_model.spec.build_constants import build_constants
from firmware_model.spec.config import BuildConfig
from firmware_model.spec.tuning import TUNINGS as TUNING_NAMES
from firmware_model.spec.tuning import tuning_fields


# ---------------------------------------------------------------------------------------------------- methods
@dataclass(frozen=True)
class Method:
    """One apogee-detection method: a firmware ``program`` with ``tuning`` (BuildConfig fields), or the float ideal
    Kalman filter (``engine="ideal"``, built on the kalman_baro config)."""

    name: str
    label: str
    program: str
    tuning: tuple[tuple[str, Any], ...] = ()
    engine: str = "model"      # "model": run_model (bit-exact integer); "ideal": float mirror, design gains

    def config(self, k: int, sensor: dict[str, Any] | None = None, **overrides: Any) -> BuildConfig:
        """The method's BuildConfig at ``k``: the sensor description, then the tuning, then ``overrides``."""
        fields = dict(sensor or {})
        fields.update(dict(self.tuning))
        fields.update({key: value for key, value in overrides.items() if value is not None})
        fields["program"] = self.program
        fields["k"] = k
        return BuildConfig.from_dict(fields, where=f"method {self.name}")


#: The methods of the apogee table, in column order.
METHODS: dict[str, Method] = {m.name: m for m in (
    Method("rec_half", "recursive 1/2 LSB", "recursive", (("threshold_q8", 128),)),
    Method("rec_quarter", "recursive 1/4 LSB", "recursive", (("threshold_q8", 64),)),
    Method("rec_eighth", "recursive 1/8 LSB", "recursive", (("threshold_q8", 32),)),
    Method("kalman_baro", "kalman_baro", "kalman_baro"),
    Method("kalman_accel", "kalman_accel", "kalman_accel"),
    Method("ideal_kalman", "ideal float Kalman", "kalman_baro", engine="ideal"),
)}
DEFAULT_METHODS: tuple[str, ...] = tuple(METHODS)
#: Programs that read the accelerometer (liftoff, velocity): n/a on a log without one, not "miss".
ACCEL_PROGRAMS: frozenset[str] = frozenset({"recursive", "kalman_accel"})


def methods_named(names: Iterable[str] | None) -> list[Method]:
    """The :class:`Method` objects for ``names`` (default: all, in table order); unknown names are a UserError."""
    if not names:
        return list(METHODS.values())
    out = []
    for name in names:
        for part in str(name).split(","):
            part = part.strip()
            if not part:
                continue
            if part not in METHODS:
                raise UserError(f"unknown method {part!r}; known: {', '.join(METHODS)}")
            out.append(METHODS[part])
    return out


# ---------------------------------------------------------------------------------------------------- detection
@dataclass(frozen=True)
class Detection:
    """What one method did on one flight (times on the flight's own axis, s).

    ``sample``: index of the APOGEE sample (-1: never fired); ``time_s`` its time or None; ``predicted_s``: the
    low-rate prediction (APOGEE_PREDICTED sample time + APFRAC/65536 dt) or None; ``liftoff_s``: first LIFTOFF
    sample; ``wrap``: the integer model's first wrapped sample and word (``""`` when none); ``failed``: why the
    method could not run on this flight (e.g. the gain design refused the build), ``""`` when it ran."""

    method: str
    sample: int
    time_s: float | None
    predicted_s: float | None = None
    liftoff_s: float | None = None
    wrap: str = ""
    failed: str = ""


def _first(events: np.ndarray, bit: int) -> int:
    hit = (np.asarray(events).astype(np.int64) & bit) != 0
    return int(hit.argmax()) if hit.any() else -1


def detect_from_events(method: str, events: np.ndarray, time_s: np.ndarray, dt: float,
                       apfrac: np.ndarray | None = None, wrap: str = "") -> Detection:
    """A :class:`Detection` from a per-sample ``EVENTS`` column (and ``APFRAC``) on the time axis ``time_s``."""

    i = _first(events, EVENT_BITS["APOGEE"])
    lift = _first(events, EVENT_BITS["LIFTOFF"])
    pred = None
    if apfrac is not None:
        j = _first(events, EVENT_BITS["APOGEE_PREDICTED"])
        if j >= 0:
            pred = float(time_s[j]) + float(apfrac[j]) / 65536.0 * dt
    return Detection(method, i, float(time_s[i]) if i >= 0 else None, pred,
                     float(time_s[lift]) if lift >= 0 else None, wrap)


def run_method(method: Method, cfg: BuildConfig, adc: np.ndarray, acc: np.ndarray | None,
               time_s: np.ndarray) -> Detection:
    """Run ``method`` built as ``cfg`` over one stream (``adc``/``acc`` counts at dt = 2^-k, sample i at
    ``time_s[i]``) and read its apogee. Firmware methods run the bit-exact integer model."""
    if method.engine == "ideal":

        trace = mirror(build_constants(cfg), adc, acc, gains="design")
        return detect_from_events(method.name, trace.column("EVENTS"), time_s, cfg.dt, trace.column("APFRAC"))

    trace = run_model(build_constants(cfg), adc, acc)
    apfrac = trace.column("APFRAC") if "APFRAC" in trace.names else None
    wrap = f"sample {trace.first_wrap} {trace.wrap_word}" if trace.first_wrap >= 0 else ""
    return detect_from_events(method.name, trace.column("EVENTS"), time_s, cfg.dt, apfrac, wrap)



TUNINGS: tuple[str, ...] = TUNING_NAMES


def tuning_overrides(method: Method, k: int, tuning: str = "default") -> dict[str, Any]:
    """BuildConfig fields ``tuning`` sets for ``method`` at ``k`` (empty for ``default``), less the fields that
    define the method (its own threshold: ``rec_quarter`` stays at 1/4 LSB under a tuning that recommends 1/2)."""
    own = dict(method.tuning)
    return {key: value for key, value in tuning_fields(method.program, k, tuning).items() if key not in own}



#: ``--firmware recursive``: the program with no threshold of its own, so that the BuildConfig default (1/4 LSB,
#: the build ``rec_quarter`` names) or the tuning's recommendation (1/2 LSB) applies.
_RECURSIVE = Method("recursive", "recursive", "recursive")


def method_for_firmware(name: str) -> "Method":
    """The evaluation :class:`Method` for a program or method name (``recursive``: the program, its threshold from
    the defaults or the tuning; a method name keeps its own threshold under any tuning)."""
    if name == "recursive":
        return _RECURSIVE
    if name not in METHODS or METHODS[name].engine != "model":
        known = ["recursive"] + [m for m, v in METHODS.items() if v.engine == "model"]
        raise UserError(f"--firmware {name!r}: unknown; known: {', '.join(known)}")
    return METHODS[name]

"""Apogee evaluation: run every firmware method over flights and build the apogee table (docs/evaluation.md;
Schultz 2002 Tables 1-2). docs/evaluation.md has the decisions and the findings.

A **method** is a firmware program with its tuning (:data:`METHODS`): the recursive filter at 1/2, 1/4 and 1/8 LSB
(``threshold_q8`` 128 / 64 / 32), ``kalman_baro``, ``kalman_accel``, and the ideal float Kalman filter (since issue
30 the float64 mirror of kalman_baro, :func:`firmware_model.model.float_reference.mirror` with the unquantized design
gains: no rounding, no gain quantization, the same altitude table interpolated in float and the same flight logic
and physical guards, so that its row measures what quantization costs, not a missing guard; until issue 30 it was
:func:`~firmware_model.model.float_reference.ideal_kalman` with "X2 < 0 after liftoff" and no phase logic, which
fired in boost wherever the barometer lied). Each method's :class:`BuildConfig` is the flight's
sensor description (``FirmwareInputs.config_overrides()``: ADC width, counts per metre, noise, accelerometer
scale) plus the method's tuning plus any user overrides.

Firmware methods run on the bit-exact integer model (:func:`firmware_model.model.run.run_model`; it equals the
emulated 68000 word for word, which the tests and ``fwemu run`` check). **Detection time** = the time (on the
flight's own axis) of the first sample whose ``EVENTS`` word has ``APOGEE`` set: the sample at which a real board
would fire the charge. The low-rate prediction (``APOGEE_PREDICTED`` + ``APFRAC``) is reported separately as
``predicted_s`` = time of the predicting sample + APFRAC/65536 x dt; it is *not* added to the detection time.
**Error** = detection time - reference time (positive = late).

**Reference**: for simulated flights the true apogee (``Truth.apogee_time_s``, uncertainty 0); for real logs the
robust parabola of :func:`firmware_model.flights.reference.apogee_reference.reference_apogee` with its uncertainty.
AltOS's own detection (AltosUI logs: ``record.events["altos_apogee"]``, the first ``drogue`` row) is reported beside,
with its error against the same reference.

**Dangerous detections** (issue 20): a detection more than :data:`EARLY_S` (1 s) before the reference is marked
``‼`` in its cell; per method the summary counts them first, then the detections made before burnout and those
made while the rocket flew faster than :data:`FAST_MACH` (Mach 0.8, where the transonic barometer error starts).
Burnout and Mach come from the truth of simulated flights (the scenario's airspeed Mach), and are estimated on
real logs (:func:`flight_context`: the accelerometer integrated from liftoff, else the barometric altitude's
slope).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from firmware_model.flights.evaluation.methods import (
    ACCEL_PROGRAMS,
    METHODS,
    TUNINGS,
    Detection,
    Method,
    methods_named,
    run_method,
    tuning_overrides,
)
from firmware_model.flights.evaluation.setup import (
    EARLY_S,
    FAST_MACH,
    FlightSpec,
    Reference,
    flight_context,
    flight_inputs,
    load_record,
    reference_for,
    sensor_config,
)
from firmware_model.flights.record import FlightRecord
from firmware_model.runtime.errors import UserError
from firmware_model.runtime.pool import ordered_map


@dataclass
class FlightResult:
    """One row of the apogee table."""

    name: str
    source: str
    k: int
    sensor: str
    reference: Reference
    altos_s: float | None
    detections: dict[str, Detection]
    n_samples: int
    report: str = ""
    notes: list[str] = field(default_factory=list)
    own_computer: str = "AltOS"     # who made ``altos_s``: the log's own flight computer (AltOS, RRC3, CATS, ...)
    burnout_s: float | None = None                                # truth/estimate, None when unknown
    mach_at: dict[str, float | None] = field(default_factory=dict)  # method (and "altos") -> Mach at detection
    mach_source: str = ""                                        # "truth" / "accelerometer estimate" / ...

    def error(self, method: str) -> float | None:
        """Detection time - reference time (s, late positive) of ``method`` (``"altos"`` for AltOS; against an
        interval reference: :meth:`Reference.judge`), or None (no detection, or :meth:`censored`)."""
        t = self.altos_s if method == "altos" else (self.detections[method].time_s if method in self.detections
                                                     else None)
        return None if t is None or self.censored(method) else self.reference.judge(t)

    def censored(self, method: str) -> bool:
        """True when ``method`` ran but had not fired by the log's recovery charge (fired after it, or never): what
        it read after the charge would not exist had it been the computer in the rocket. Its error is then only
        bounded below (:meth:`error_bound`): "later than the log's computer"."""
        charge = self.reference.charge_s
        if charge is None:
            return False
        if method == "altos":
            return self.altos_s is not None and self.altos_s > charge
        d = self.detections.get(method)
        return d is not None and not d.failed and (d.time_s is None or d.time_s > charge)

    def error_bound(self, method: str) -> float | None:
        """A censored method's lower bound on its error: the charge judged as a detection; None otherwise."""
        if not self.censored(method) or self.reference.charge_s is None:
            return None
        return self.reference.judge(self.reference.charge_s)

    def to_dict(self) -> dict[str, Any]:
        ref = asdict(self.reference)
        return {"name": self.name, "source": self.source, "k": self.k, "sensor": self.sensor,
                "n_samples": self.n_samples, "reference": ref,
                "altos": None if self.altos_s is None else {"time_s": self.altos_s, "error_s": self.error("altos"),
                                                            "computer": self.own_computer,
                                                            "censored": self.censored("altos")},
                "methods": {m: dict(asdict(d), error_s=self.error(m), censored=self.censored(m),
                                    error_lower_bound_s=self.error_bound(m)) for m, d in self.detections.items()},
                "report": self.report, "notes": self.notes, "burnout_s": self.burnout_s,
                "mach_at_detection": self.mach_at, "mach_source": self.mach_source,
                "flags": {m: self.flags(m) for m in list(self.detections) + (["altos"] if self.altos_s is not None
                                                                              else [])}}

    def detection_time(self, method: str) -> float | None:
        if method == "altos":
            return self.altos_s
        d = self.detections.get(method)
        return None if d is None or d.failed else d.time_s

    def flags(self, method: str) -> dict[str, bool]:
        """``early_1s``: more than :data:`EARLY_S` before the reference; ``before_burnout``: at or before burnout;
        ``fast``: at Mach >= :data:`FAST_MACH`."""
        t = self.detection_time(method)
        e = self.error(method)
        mach = self.mach_at.get(method)
        return {"early_1s": e is not None and e < -EARLY_S,
                "before_burnout": t is not None and self.burnout_s is not None and t <= self.burnout_s,
                "fast": mach is not None and mach >= FAST_MACH}


def _report_text(report: Any) -> str:
    if report is None:
        return ""
    for attr in ("summary", "text"):
        value = getattr(report, attr, None)
        if callable(value):
            return str(value())
        if isinstance(value, str):
            return value
    return str(report)


def _sensor_text(inputs: Any, spec: FlightSpec, record: FlightRecord | None = None) -> str:
    """``<barometer preset> / <accelerometer preset>, noisy|clean|log noise``, then ``SYNTHETIC baro`` for an
    altitude-only log, the sensor of a multi-sensor log, and ``no accel`` when the stream has none."""
    baro = getattr(getattr(inputs, "baro", None), "name", None) or spec.baro or "default"
    accel = getattr(getattr(inputs, "accel", None), "name", None) or spec.accel or "default"
    baro = baro.replace("mpx4115_", "").replace("bit", "-bit")
    if spec.source.startswith("sim:"):
        noise = "noisy" if spec.noise else "clean"
    else:
        noise = "log noise" + (" + added" if spec.noise and (spec.baro or spec.accel) else "")
    extra = ""
    if record is not None:
        prov = record.provenance
        if prov.get("synthetic_baro"):
            extra += ", SYNTHETIC baro (from altitude)"
        if prov.get("sensor") and prov.get("format") == "cats_raw":
            extra += f", {prov['sensor']} of {'/'.join(prov.get('sensors', []))}"
        if not getattr(inputs, "has_accel", True):
            extra += ", no accel"
    return f"{baro}/{accel}, {noise}{extra}"


def evaluate_flight(spec: FlightSpec, methods: Sequence[Method] | None = None,
                    overrides: dict[str, Any] | None = None, record: FlightRecord | None = None,
                    tuning: str = "default") -> FlightResult:
    """Evaluate one flight: read/simulate it, make its firmware inputs, run every method, compare with the
    reference. ``overrides``: BuildConfig fields applied to every method (e.g. ``rounding``)."""
    methods = list(methods or METHODS.values())
    record = record if record is not None else load_record(spec.source, spec.format, **spec.reader_options())
    inputs = flight_inputs(record, spec)
    return evaluate_inputs(record, inputs, spec, methods, overrides, tuning)


#: Tunings ``fwemu evaluate/run/compare --tuning`` know: the BuildConfig defaults, or
#: ``firmware_model.spec.tuning.RECOMMENDED`` (per program and k; a k it has no entry for keeps the defaults;
#: ideal_kalman takes kalman_baro's).

def evaluate_inputs(record: FlightRecord, inputs: Any, spec: FlightSpec, methods: Sequence[Method],
                    overrides: dict[str, Any] | None = None, tuning: str = "default") -> FlightResult:
    """:func:`evaluate_flight` on inputs already made (``inputs``: adc, acc, time_s, config_overrides()).
    ``tuning``: see :data:`TUNINGS`; ``overrides`` apply after it."""
    sensor = sensor_config(inputs)
    adc = np.asarray(inputs.adc)
    acc = None if getattr(inputs, "acc", None) is None else np.asarray(inputs.acc)
    time_s = np.asarray(inputs.time_s, dtype=np.float64)
    detections = {}
    notes: list[str] = []
    has_accel = bool(getattr(inputs, "has_accel", True))
    for method in methods:
        if method.program in ACCEL_PROGRAMS and not has_accel:
            detections[method.name] = Detection(method.name, -1, None, failed="the log has no accelerometer")
            notes.append(f"{method.name}: not run: the log has no accelerometer")
            continue
        try:
            cfg = method.config(spec.k, sensor, **{**tuning_overrides(method, spec.k, tuning), **(overrides or {})})
            det = run_method(method, cfg, adc, acc, time_s)
        except UserError as exc:   # e.g. a gain below 2^-33 at this k and ADC: say so in the row, go on
            det = Detection(method.name, -1, None, failed=str(exc))
            notes.append(f"{method.name}: not run: {exc}")
        if det.wrap:
            notes.append(f"{method.name}: integer wrap at {det.wrap}")
        detections[method.name] = det
    own = record.own_apogee()
    notes += [f"log: {n}" for n in record.provenance.get("notes", []) if _worth_noting(n)]
    burn, mach, mach_source = flight_context(record, spec.source)
    mach_at: dict[str, float | None] = {}
    rec_t = np.asarray(record.time_s, dtype=np.float64)
    for name, t in [(m, d.time_s) for m, d in detections.items()] + [("altos", None if own is None else own[1])]:
        if t is not None and mach is not None:
            mach_at[name] = float(np.interp(t, rec_t, mach))
    return FlightResult(spec.name, spec.source, spec.k, _sensor_text(inputs, spec, record),
                        reference_for(record, spec.reference),
                        None if own is None else own[1], detections, int(adc.shape[0]),
                        _report_text(getattr(inputs, "report", None)), notes,
                        "AltOS" if own is None else own[0], burn, mach_at, mach_source)


def _worth_noting(note: str) -> bool:
    """Reader notes that change what the firmware sees (copied into the evaluation's notes)."""
    return any(w in note for w in ("SYNTHETIC", "REFUSED", "WARNING", "median of", "barometer: ", "cut short",
                                   "sorted", "nominal calibration"))


def _evaluate_job(job: tuple[FlightSpec, tuple[str, ...], tuple[tuple[str, Any], ...], str]) -> FlightResult:
    spec, names, overrides, tuning = job
    return evaluate_flight(spec, methods_named(names), dict(overrides), tuning=tuning)


def evaluate_many(specs: Sequence[FlightSpec], methods: Sequence[Method] | None = None,
                  overrides: dict[str, Any] | None = None, jobs: int = 1,
                  progress: Callable[[int, int, str], None] | None = None,
                  tuning: str = "default", scheduler: str | None = None) -> list[FlightResult]:
    """Evaluate every flight (``jobs`` > 1: that many processes; ``scheduler``: a Dask cluster instead,
    :func:`firmware_model.runtime.pool.ordered_map`); results in the order of ``specs`` whatever the order of
    completion, so the table is byte-identical to ``jobs=1``."""
    methods = list(methods or METHODS.values())
    names = tuple(m.name for m in methods)
    ov = tuple(sorted((overrides or {}).items()))
    n = len(specs)
    if progress:
        progress(0, n, specs[0].name if specs else "")

    def done(i: int, res: FlightResult) -> None:
        if progress:
            progress(i + 1, n, res.name)

    if tuning not in TUNINGS:
        raise UserError(f"--tuning {tuning!r}: known: {', '.join(TUNINGS)}")
    return ordered_map(_evaluate_job, [(spec, names, ov, tuning) for spec in specs], jobs, done, scheduler)

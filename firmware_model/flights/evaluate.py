"""Apogee evaluation: run every firmware method over flights and build the apogee table (docs/evaluation.md; Schultz 2002
Tables 1-2). docs/evaluation.md has the decisions and the findings.

A **method** is a firmware program with its tuning (:data:`METHODS`): the recursive filter at 1/2, 1/4 and 1/8 LSB
(``threshold_q8`` 128 / 64 / 32), ``kalman_baro``, ``kalman_accel``, and the float ideal Kalman filter
(:func:`firmware_model.model.float_reference.ideal_kalman`, barometer only, time-varying gains from the pad covariance, the same
apogee rule as the firmware: velocity below zero after liftoff). Each method's :class:`BuildConfig` is the flight's
sensor description (``FirmwareInputs.config_overrides()``: ADC width, counts per metre, noise, accelerometer
scale) plus the method's tuning plus any user overrides.

Firmware methods run on the bit-exact integer model (:func:`firmware_model.model.run.run_model`; it equals the
emulated 68000 word for word, which the tests and ``fwemu run`` check). **Detection time** = the time (on the
flight's own axis) of the first sample whose ``EVENTS`` word has ``APOGEE`` set: the sample at which a real board
would fire the charge. The low-rate prediction (``APOGEE_PREDICTED`` + ``APFRAC``) is reported separately as
``predicted_s`` = time of the predicting sample + APFRAC/65536 x dt; it is *not* added to the detection time.
**Error** = detection time - reference time (positive = late).

**Reference**: for simulated flights the true apogee (``Truth.apogee_time_s``, uncertainty 0); for real logs the
robust parabola of :func:`firmware_model.flights.apogee_reference.reference_apogee` with its uncertainty. AltOS's own
detection (AltosUI logs: ``record.events["altos_apogee"]``, the first ``drogue`` row) is reported beside, with its
error against the same reference.
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import asdict, dataclass, field
from typing import Any, Callable, Iterable, Sequence

import numpy as np

from firmware_model.flights.apogee_reference import reference_apogee
from firmware_model.flights.firmware_inputs import firmware_inputs
from firmware_model.flights.readers import read_flight
from firmware_model.flights.record import FlightRecord
from firmware_model.flights.scenarios import simulate_scenario
from firmware_model.flights.sensors import AccelSensor, BaroSensor
from firmware_model.model.float_reference import ideal_kalman
from firmware_model.model.run import run_model
from firmware_model.model.trace import EVENT_BITS
from firmware_model.runtime import markdown as md
from firmware_model.runtime.errors import UserError
from firmware_model.runtime.pool import ordered_map
from firmware_model.spec.atmosphere import altitude_m
from firmware_model.spec.build_constants import build_constants
from firmware_model.spec.config import BuildConfig
from firmware_model.spec.tuning import RECOMMENDED


# ---------------------------------------------------------------------------------------------------- methods
@dataclass(frozen=True)
class Method:
    """One apogee-detection method: a firmware ``program`` with ``tuning`` (BuildConfig fields), or the float ideal
    Kalman filter (``engine="ideal"``, built on the kalman_baro config)."""

    name: str
    label: str
    program: str
    tuning: tuple[tuple[str, Any], ...] = ()
    engine: str = "model"      # "model": run_model (bit-exact integer); "ideal": reference.ideal_kalman

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

        trace = ideal_kalman(cfg, adc, acc)
        return detect_from_events(method.name, trace.column("EVENTS"), time_s, cfg.dt)

    trace = run_model(build_constants(cfg), adc, acc)
    apfrac = trace.column("APFRAC") if "APFRAC" in trace.names else None
    wrap = f"sample {trace.first_wrap} {trace.wrap_word}" if trace.first_wrap >= 0 else ""
    return detect_from_events(method.name, trace.column("EVENTS"), time_s, cfg.dt, apfrac, wrap)


# ---------------------------------------------------------------------------------------------------- references
@dataclass(frozen=True)
class Reference:
    """The apogee a flight's detections are judged against."""

    time_s: float
    altitude_m: float | None
    uncertainty_s: float
    source: str                 # "truth" or the reference_apogee rule
    notes: str = ""             # the rule's warning and how the fit was made, readable
    usable: bool = True         # False when the reference carries a warning (not a free flight near its peak)


def reference_for(record: FlightRecord) -> Reference:
    """Truth for simulated flights, the robust parabola (:func:`flights.reference.reference_apogee`) otherwise."""
    truth = record.truth
    if truth is not None and truth.apogee_time_s is not None:
        return Reference(float(truth.apogee_time_s), None if truth.apogee_altitude_m is None
                         else float(truth.apogee_altitude_m), 0.0, "truth")

    ref = reference_apogee(record)
    parts = []
    if ref.notes.get("deployment_cut"):
        parts.append(f"fitted up to the log's deployment at {ref.notes['deployment_s']:.2f} s")
    if "warning" in ref.notes:
        parts.append(str(ref.notes["warning"]))
    return Reference(float(ref.time_s), float(ref.altitude_m), float(ref.uncertainty_s), str(ref.source),
                     "; ".join(parts), "warning" not in ref.notes)


# ---------------------------------------------------------------------------------------------------- one flight
@dataclass(frozen=True)
class FlightSpec:
    """One row of the apogee table: where the flight comes from and how it is sensed and sampled.

    * ``source``: a file (any format :func:`flights.readers.read_flight` takes) or ``sim:NAME`` (a scenario of
      :mod:`flights.scenarios`);
    * ``k``: sample period 2^-k s; ``baro`` / ``accel``: sensor preset names of :mod:`flights.sensors` (None: the
      default for the record); ``noise``: add sensor noise (seeded by ``seed``) or not;
    * ``label``: row name (default: derived); ``format``: reader override for files.
    """

    source: str
    k: int = 7
    baro: str | None = None
    accel: str | None = None
    noise: bool = True
    seed: int = 0
    label: str | None = None
    format: str | None = None
    method: str = "linear"

    @property
    def name(self) -> str:
        if self.label:
            return self.label
        from pathlib import Path

        base = self.source[4:] if self.source.startswith("sim:") else Path(self.source).stem
        return base


def load_record(source: str, format: str | None = None) -> FlightRecord:
    """A :class:`FlightRecord` from ``sim:NAME`` (simulated scenario) or a file path."""
    if source.startswith("sim:"):

        return simulate_scenario(source[4:])

    return read_flight(source, format=format)


#: Sensor noise of a "noisy" :class:`FlightSpec` with a named preset: pressure noise (Pa rms, about 0.3 m at sea
#: level, MP3H6115A-class), ADC noise (counts rms), accelerometer noise (counts rms). "noise-free" = all zero.
NOISE_PA: float = 4.0
NOISE_ADC_COUNTS: float = 0.5
NOISE_ACCEL_COUNTS: float = 20.0


def sensors_for(spec: FlightSpec) -> tuple[Any, Any]:
    """The (BaroSensor, AccelSensor) of ``spec`` (None = the default of :func:`flights.inputs.firmware_inputs`)."""

    baro = accel = None
    if spec.baro is not None:
        noise = {"noise_pa": NOISE_PA} if spec.noise else {"noise_pa": 0.0, "noise_counts": 0.0}
        if spec.noise and BaroSensor.preset(spec.baro).kind == "adc":
            noise["noise_counts"] = NOISE_ADC_COUNTS
        baro = BaroSensor.preset(spec.baro, **noise)
    if spec.accel is not None:
        accel = AccelSensor.preset(spec.accel, noise_counts=NOISE_ACCEL_COUNTS if spec.noise else 0.0)
    return baro, accel


def sensor_config(inputs: Any) -> dict[str, Any]:
    """BuildConfig fields of a flight's sensing: ``inputs.config_overrides()`` (ADC width, sign, counts per metre,
    accelerometer scale, and the barometer's transfer function from which the Kalman programs' altitude table is
    generated: ``baro_pa_per_count``, ``baro_pa_at_zero``), plus the noise the Kalman design assumes, **measured on the pad part of the stream** (the
    samples before ``inputs.liftoff_s``, as a designer measures a sensor on the bench): ``baro_sigma`` = standard
    deviation of the barometer words, at least 0.5 count (quantization); ``accel_sigma`` likewise for the
    accelerometer, at least 1 count. Barometer-only gains depend on R/q alone, so this matters only for
    kalman_accel (the weight of the barometer against the accelerometer)."""
    out = dict(inputs.config_overrides())
    t = np.asarray(inputs.time_s, dtype=np.float64)
    lift = getattr(inputs, "liftoff_s", None)
    pad = t < (lift if lift is not None else t[0] + 1.0) - 0.05
    if pad.sum() >= 8:
        out["baro_sigma"] = max(0.5, float(np.std(np.asarray(inputs.adc)[pad])))
        if getattr(inputs, "has_accel", True) and inputs.acc is not None:
            out["accel_sigma"] = max(1.0, float(np.std(np.asarray(inputs.acc)[pad])))
    return out


def altitude_of_counts(inputs: Any) -> Any:
    """ADC value -> metres above the pad through the sensor's inverse transfer function and the standard atmosphere
    (None when the inputs carry no sensor model)."""
    baro = getattr(inputs, "baro", None)
    ground = getattr(inputs, "ground_pressure_pa", None)
    if baro is None or ground is None or not hasattr(baro, "pressure_of_counts"):
        return None

    h0 = float(altitude_m(ground))
    lo, hi = float(baro.p_min_pa), float(baro.p_max_pa)

    def alt(counts: Any) -> np.ndarray:
        p = np.clip(baro.pressure_of_counts(counts), lo * 0.5, hi * 1.5)
        return np.asarray(altitude_m(p), dtype=np.float64) - h0

    return alt


def flight_inputs(record: FlightRecord, spec: FlightSpec) -> Any:
    """The firmware inputs of ``record`` under ``spec`` (:func:`flights.inputs.firmware_inputs`)."""

    baro, accel = sensors_for(spec)
    return firmware_inputs(record, spec.k, baro=baro, accel=accel, method=spec.method, seed=spec.seed)


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

    def error(self, method: str) -> float | None:
        """Detection time - reference time (s, late positive) of ``method`` (``"altos"`` for AltOS), or None."""
        t = self.altos_s if method == "altos" else (self.detections[method].time_s if method in self.detections
                                                     else None)
        return None if t is None else t - self.reference.time_s

    def to_dict(self) -> dict[str, Any]:
        ref = asdict(self.reference)
        return {"name": self.name, "source": self.source, "k": self.k, "sensor": self.sensor,
                "n_samples": self.n_samples, "reference": ref,
                "altos": None if self.altos_s is None else {"time_s": self.altos_s, "error_s": self.error("altos")},
                "methods": {m: dict(asdict(d), error_s=self.error(m)) for m, d in self.detections.items()},
                "report": self.report, "notes": self.notes}


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


def _sensor_text(inputs: Any, spec: FlightSpec) -> str:
    """``<barometer preset> / <accelerometer preset>, noisy|clean|log noise``."""
    baro = getattr(getattr(inputs, "baro", None), "name", None) or spec.baro or "default"
    accel = getattr(getattr(inputs, "accel", None), "name", None) or spec.accel or "default"
    baro = baro.replace("mpx4115_", "").replace("bit", "-bit")
    if spec.source.startswith("sim:"):
        noise = "noisy" if spec.noise else "clean"
    else:
        noise = "log noise" + (" + added" if spec.noise and (spec.baro or spec.accel) else "")
    return f"{baro}/{accel}, {noise}"


def evaluate_flight(spec: FlightSpec, methods: Sequence[Method] | None = None,
                    overrides: dict[str, Any] | None = None, record: FlightRecord | None = None,
                    tuning: str = "default") -> FlightResult:
    """Evaluate one flight: read/simulate it, make its firmware inputs, run every method, compare with the
    reference. ``overrides``: BuildConfig fields applied to every method (e.g. ``rounding``)."""
    methods = list(methods or METHODS.values())
    record = record if record is not None else load_record(spec.source, spec.format)
    inputs = flight_inputs(record, spec)
    return evaluate_inputs(record, inputs, spec, methods, overrides, tuning)


#: Tunings ``fwemu evaluate --tuning`` knows: the BuildConfig defaults, or ``firmware_model.spec.tuning.RECOMMENDED``
#: (per program and k; a k it has no entry for keeps the defaults; ideal_kalman takes kalman_baro's).
TUNINGS: tuple[str, ...] = ("default", "recommended")


def tuning_overrides(method: Method, k: int, tuning: str = "default") -> dict[str, Any]:
    """BuildConfig fields ``tuning`` sets for ``method`` at ``k`` (empty for ``default``)."""
    if tuning == "default":
        return {}
    if tuning != "recommended":
        raise UserError(f"--tuning {tuning!r}: known: {', '.join(TUNINGS)}")

    return dict(RECOMMENDED.get(method.program, {}).get(k, {}))


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
    for method in methods:
        try:
            cfg = method.config(spec.k, sensor, **{**tuning_overrides(method, spec.k, tuning), **(overrides or {})})
            det = run_method(method, cfg, adc, acc, time_s)
        except UserError as exc:   # e.g. a gain below 2^-33 at this k and ADC: say so in the row, go on
            det = Detection(method.name, -1, None, failed=str(exc))
            notes.append(f"{method.name}: not run: {exc}")
        if det.wrap:
            notes.append(f"{method.name}: integer wrap at {det.wrap}")
        detections[method.name] = det
    altos = record.events.get("altos_apogee") if record.events else None
    return FlightResult(spec.name, spec.source, spec.k, _sensor_text(inputs, spec), reference_for(record),
                        None if altos is None else float(altos), detections, int(adc.shape[0]),
                        _report_text(getattr(inputs, "report", None)), notes)


def _evaluate_job(job: tuple[FlightSpec, tuple[str, ...], tuple[tuple[str, Any], ...], str]) -> FlightResult:
    spec, names, overrides, tuning = job
    return evaluate_flight(spec, methods_named(names), dict(overrides), tuning=tuning)


def evaluate_many(specs: Sequence[FlightSpec], methods: Sequence[Method] | None = None,
                  overrides: dict[str, Any] | None = None, jobs: int = 1,
                  progress: Callable[[int, int, str], None] | None = None,
                  tuning: str = "default") -> list[FlightResult]:
    """Evaluate every flight (``jobs`` > 1: that many processes); results in the order of ``specs`` whatever the
    order of completion, so the table is byte-identical to ``jobs=1``."""
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
    return ordered_map(_evaluate_job, [(spec, names, ov, tuning) for spec in specs], jobs, done)


# ---------------------------------------------------------------------------------------------------- the table
@dataclass(frozen=True)
class MethodSummary:
    """Median and worst |error| of one method over the flights it was run on (detections only), and the misses."""

    method: str
    label: str
    n: int
    detected: int
    median_abs_s: float | None
    worst_abs_s: float | None
    worst_flight: str | None
    median_s: float | None
    early: int
    late: int
    most_early_s: float | None = None          # the most negative error (None: nothing fired early)
    most_early_flight: str | None = None
    worst_usable_abs_s: float | None = None    # worst |error| over flights whose reference is usable
    worst_usable_flight: str | None = None
    unusable: int = 0                          # detections on flights whose reference carries a warning


def summarize(results: Sequence[FlightResult], method: str, label: str) -> MethodSummary:
    """Summary of ``method`` (``"altos"`` for AltOS) over the flights where it ran (``n``); ``detected`` of them
    fired; median/worst over the detections; flights where the build was refused are left out of ``n``."""
    if method == "altos":
        ran = [r for r in results if r.altos_s is not None]
    else:
        ran = [r for r in results if method in r.detections and not r.detections[method].failed]
    trio = [(r.error(method), r.name, r.reference.usable) for r in ran]
    trio = [t for t in trio if t[0] is not None]
    got = [(e, name) for e, name, _ in trio]
    if not got:
        return MethodSummary(method, label, len(ran), 0, None, None, None, None, 0, 0)
    a = np.array([abs(e) for e, _ in got])
    worst = int(np.argmax(a))
    early = min(got)
    usable = [(abs(e), name) for e, name, ok in trio if ok]
    wu = max(usable) if usable else (None, None)
    return MethodSummary(method, label, len(ran), len(got), float(np.median(a)), float(a[worst]), got[worst][1],
                         float(np.median([e for e, _ in got])), sum(e < 0 for e, _ in got),
                         sum(e > 0 for e, _ in got), float(early[0]) if early[0] < 0 else None,
                         early[1] if early[0] < 0 else None, None if wu[0] is None else float(wu[0]), wu[1],
                         len(got) - len(usable))


def table_methods(results: Sequence[FlightResult]) -> list[tuple[str, str]]:
    """(name, label) of the columns: AltOS (when any flight has it), then the methods in table order."""
    present: list[str] = []
    for r in results:
        for m in r.detections:
            if m not in present:
                present.append(m)
    cols = [("altos", "AltOS")] if any(r.altos_s is not None for r in results) else []
    order = [m for m in METHODS if m in present] + [m for m in present if m not in METHODS]
    return cols + [(m, METHODS[m].label if m in METHODS else m) for m in order]


def _fmt(x: float | None, digits: int = 3) -> str:
    return "—" if x is None else f"{x:.{digits}f}"


def _fmt_err(x: float | None) -> str:
    return "miss" if x is None else f"{x:+.3f}"


def render_markdown(results: Sequence[FlightResult], command: str | None = None) -> str:
    """The apogee table (Schultz 2002 Tables 1-2 style) and the per-method summary, as Markdown."""
    cols = table_methods(results)
    head = ["flight", "k", "sensor", "reference apogee s (±unc, source)", "alt m"] + [label for _, label in cols]
    lines = md.header(head)
    for r in results:
        ref = r.reference
        cells = [r.name, str(r.k), r.sensor,
                 f"{ref.time_s:.3f} ±{ref.uncertainty_s:.3f} ({ref.source}){'' if ref.usable else ' ⚠'}",
                 _fmt(ref.altitude_m, 0)]
        for m, _ in cols:
            if m == "altos":
                cells.append("—" if r.altos_s is None else f"{r.altos_s:.2f} ({_fmt_err(r.error('altos'))})")
            elif m not in r.detections:
                cells.append("—")
            else:
                d = r.detections[m]
                if d.failed:
                    cells.append("n/a")
                else:
                    cells.append("miss" if d.time_s is None else f"{d.time_s:.3f} ({_fmt_err(r.error(m))})")
        lines.append(md.row(cells))
    out = ["Detection time s (error s = detection - reference; + late, miss = never fired). ⚠: the reference "
           "carries a warning (the fit is not a free flight near its peak, docs/flights.md); such rows are left out "
           "of the summary's last column only.", ""] + lines
    out += [""] + md.header(["method", "flights", "detected", "median abs error s", "worst abs error s (flight)",
                             "median error s", "early / late", "most early s (flight)",
                             "worst abs error s, usable references"])
    for m, label in cols:
        s = summarize(results, m, label)
        worst = "—" if s.worst_abs_s is None else f"{s.worst_abs_s:.3f} ({s.worst_flight})"
        miss = s.n - s.detected
        worst += f"; {miss} missed" if miss else ""
        skipped = sum(1 for r in results if m in r.detections and r.detections[m].failed)
        worst += f"; {skipped} n/a" if skipped else ""
        most_early = "—" if s.most_early_s is None else f"{s.most_early_s:+.3f} ({s.most_early_flight})"
        usable = "—" if s.worst_usable_abs_s is None else f"{s.worst_usable_abs_s:.3f} ({s.worst_usable_flight})"
        usable += f"; {s.unusable} on flagged references left out" if s.unusable else ""
        out.append(md.row([label, s.n, s.detected, _fmt(s.median_abs_s), worst, _fmt(s.median_s),
                           f"{s.early} / {s.late}", most_early, usable]))
    if command:
        out += ["", f"Regenerate: `{command}`"]
    return "\n".join(out) + "\n"


def render_csv(results: Sequence[FlightResult]) -> str:
    """One row per flight: reference, AltOS, each method's detection time and error (empty = none)."""
    cols = table_methods(results)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    head = ["flight", "source", "k", "sensor", "n_samples", "ref_time_s", "ref_altitude_m", "ref_uncertainty_s",
            "ref_source"]
    for m, _ in cols:
        head += [f"{m}_time_s", f"{m}_error_s"]
    w.writerow(head)

    def num(x: float | None) -> str:
        return "" if x is None else repr(round(float(x), 6))

    for r in results:
        row = [r.name, r.source, r.k, r.sensor, r.n_samples, num(r.reference.time_s), num(r.reference.altitude_m),
               num(r.reference.uncertainty_s), r.reference.source]
        for m, _ in cols:
            t = r.altos_s if m == "altos" else (r.detections[m].time_s if m in r.detections else None)
            row += [num(t), num(r.error(m))]
        w.writerow(row)
    return buf.getvalue()


def render_json(results: Sequence[FlightResult], command: str | None = None) -> str:
    """Every flight's result plus the per-method summary, JSON (sorted keys, stable)."""
    cols = table_methods(results)
    doc = {"schema": "fwemu-apogee-table/1", "command": command,
           "rule": {"detection": "time of the first sample with EVENTS.APOGEE set (APFRAC prediction not added; "
                                 "reported as predicted_s)",
                    "error": "detection time - reference time, s (positive = late)"},
           "flights": [r.to_dict() for r in results],
           "summary": {m: asdict(summarize(results, m, label)) for m, label in cols}}
    return json.dumps(_clean(doc), indent=1, sort_keys=True) + "\n"


def _clean(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        x = float(obj)
        return round(x, 6) if math.isfinite(x) else None
    return obj


def table_files(results: Sequence[FlightResult], command: str | None = None) -> dict[str, bytes]:
    """``apogee.md``, ``apogee.csv``, ``apogee.json`` contents."""
    return {"apogee.md": render_markdown(results, command).encode(),
            "apogee.csv": render_csv(results).encode(),
            "apogee.json": render_json(results, command).encode()}


__all__ = ["Method", "METHODS", "DEFAULT_METHODS", "methods_named", "Detection", "detect_from_events", "run_method",
           "Reference", "reference_for", "FlightSpec", "load_record", "flight_inputs", "FlightResult",
           "evaluate_flight", "evaluate_inputs", "evaluate_many", "MethodSummary", "summarize", "render_markdown",
           "render_csv", "render_json", "table_files"]


def method_for_firmware(name: str) -> "Method":
    """The evaluation :class:`Method` for a program or method name (``recursive`` = ``rec_quarter``)."""
    if name == "recursive":
        name = "rec_quarter"
    if name not in METHODS or METHODS[name].engine != "model":
        known = ["recursive"] + [m for m, v in METHODS.items() if v.engine == "model"]
        raise UserError(f"--firmware {name!r}: unknown; known: {', '.join(known)}")
    return METHODS[name]

"""Apogee evaluation: run every firmware method over flights and build the apogee table (docs/evaluation.md; Schultz 2002
Tables 1-2). docs/evaluation.md has the decisions and the findings.

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
robust parabola of :func:`firmware_model.flights.reference.apogee_reference.reference_apogee` with its uncertainty. AltOS's own
detection (AltosUI logs: ``record.events["altos_apogee"]``, the first ``drogue`` row) is reported beside, with its
error against the same reference.

**Dangerous detections** (issue 20): a detection more than :data:`EARLY_S` (1 s) before the reference is marked
``‼`` in its cell; per method the summary counts them first, then the detections made before burnout and those
made while the rocket flew faster than :data:`FAST_MACH` (Mach 0.8, where the transonic barometer error starts).
Burnout and Mach come from the truth of simulated flights (the scenario's airspeed Mach), and are estimated on
real logs (:func:`flight_context`: the accelerometer integrated from liftoff, else the barometric altitude's
slope).
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import asdict, dataclass, field
from typing import Any, Callable, Iterable, Sequence

import numpy as np

from firmware_model.flights.reference.apogee_reference import reference_apogee
from firmware_model.flights.reference.charge import recovery_charge
from firmware_model.flights.inputs.firmware_inputs import firmware_inputs
from firmware_model.flights.readers import read_flight
from firmware_model.flights.record import FlightRecord
from firmware_model.flights.reconstruct.reference import MODES as SMOOTHER_MODES
from firmware_model.flights.reconstruct.reference import smoother_reference
from firmware_model.flights.simulate.scenarios import scenario_mach, simulate_scenario
from firmware_model.flights.inputs.sensors import AccelSensor, BaroSensor
from firmware_model.flights.simulate.sim1dof import mach_of
from firmware_model.model.float_reference import mirror
from firmware_model.model.run import run_model
from firmware_model.model.trace import EVENT_BITS
from firmware_model.runtime import markdown as md
from firmware_model.runtime.errors import UserError
from firmware_model.runtime.pool import ordered_map
from firmware_model.spec import atmosphere as atm
from firmware_model.spec.atmosphere import altitude_m
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
    disagree: bool = False      # the smoother's and the parabola's apogees differ beyond their uncertainties
    lower_s: float | None = None    # "apogee lies in [lower_s, upper_s]" (an interval reference), else None
    upper_s: float | None = None
    charge_s: float | None = None   # the log's recovery charge (flights.charge): later detections are censored
    charge: str = ""                # its evidence, readable

    def judge(self, t: float) -> float:
        """Error of a detection at ``t``: t - time_s, or against the interval (0 inside it, else the distance to
        the nearer end, signed)."""
        if self.lower_s is None or self.upper_s is None:
            return t - self.time_s
        return t - self.lower_s if t < self.lower_s else (t - self.upper_s if t > self.upper_s else 0.0)


def reference_for(record: FlightRecord, mode: str = "parabola") -> Reference:
    """Truth for simulated flights; otherwise the robust parabola (:func:`flights.reference.reference_apogee`),
    or with ``mode`` "smoother" the reconstruction's apogee (:mod:`flights.reconstruct.reference`), "auto": the
    smoother where the log has an accelerometer and it reconstructs, else the parabola."""
    truth = record.truth
    if truth is not None and truth.apogee_time_s is not None:
        return Reference(float(truth.apogee_time_s), None if truth.apogee_altitude_m is None
                         else float(truth.apogee_altitude_m), 0.0, "truth")
    if mode not in SMOOTHER_MODES:
        raise UserError(f"--reference {mode!r}: known: {', '.join(SMOOTHER_MODES)}")
    charge = recovery_charge(record)
    censor = {} if charge is None else {"charge_s": charge.time_s, "charge": f"{charge.evidence}: {charge.detail}"}
    if mode == "smoother" or (mode == "auto" and record.has_accel):
        try:
            sm = smoother_reference(record)
            return Reference(sm.time_s, sm.altitude_m, sm.uncertainty_s, f"smoother {sm.mode}", sm.note,
                             True, sm.disagree, **censor)
        except UserError:
            if mode == "smoother":
                raise

    ref = reference_apogee(record)
    parts = []
    if ref.notes.get("deployment_cut"):
        parts.append(f"fitted up to the log's recovery charge at {ref.notes['deployment_s']:.2f} s "
                     f"({censor.get('charge', '')})")
    for key in ("interval", "after_charge", "warning"):
        if key in ref.notes:
            parts.append(str(ref.notes[key]))
    lo, hi = ref.interval_s if ref.interval_s is not None else (None, None)
    return Reference(float(ref.time_s), float(ref.altitude_m), float(ref.uncertainty_s), str(ref.source),
                     "; ".join(parts), "warning" not in ref.notes, lower_s=lo, upper_s=hi, **censor)


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
    reference: str = "parabola"             # real logs: "parabola", "smoother" or "auto" (reference_for)
    sensor: str | None = None               # reader options (flights.readers.read_flight): multi-sensor logs,
    columns: str | None = None              # a column map,
    site_altitude_m: float | None = None    # the site of an altitude-only log,
    flight: int | None = None               # the flight of a multi-flight .eeprom
    late: str = "nominal"                   # a log starting after liftoff: "nominal" 1 g pad, or "refuse" the accel

    def reader_options(self) -> dict[str, Any]:
        return {"sensor": self.sensor, "columns": self.columns, "site_altitude_m": self.site_altitude_m,
                "flight": self.flight}

    @property
    def name(self) -> str:
        if self.label:
            return self.label
        from pathlib import Path

        base = self.source[4:] if self.source.startswith("sim:") else Path(self.source).stem
        return base


def load_record(source: str, format: str | None = None, **options: Any) -> FlightRecord:
    """A :class:`FlightRecord` from ``sim:NAME`` (simulated scenario) or a file path (``options``: the reader's,
    :func:`flights.readers.read_flight`)."""
    if source.startswith("sim:"):

        return simulate_scenario(source[4:])

    return read_flight(source, format=format, **options)


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
    return firmware_inputs(record, spec.k, baro=baro, accel=accel, method=spec.method, seed=spec.seed,
                           late=spec.late)


#: A detection more than this many seconds before the reference is dangerous (issue 20; the charge fires on the
#: way up).
EARLY_S: float = 1.0
#: Mach number above which the table counts a detection as "fast" (the transonic barometer error starts near it).
FAST_MACH: float = 0.8


def burnout_time(record: FlightRecord, liftoff_s: float | None) -> float | None:
    """First time at or after liftoff at which the axial specific force, averaged over 5 log rows, falls below
    0 m/s^2 (thrust gone, drag decelerating the coasting rocket), or None without an accelerometer. (Not "after the
    peak": on real logs the largest reading can be the ejection charge's shock at apogee.)"""
    f = record.specific_force_mps2()
    if f is None or liftoff_s is None:
        return None
    t = np.asarray(record.time_s)
    f = np.where(np.isfinite(f), f, np.nan)
    if f.size < 5:
        return None
    mean5 = np.convolve(np.nan_to_num(f, nan=1.0), np.ones(5) / 5.0, mode="valid")   # row i..i+4
    hit = np.nonzero((t[: mean5.size] >= liftoff_s) & (mean5 < 0.0))[0]
    return float(t[hit[0]]) if hit.size else None


def _liftoff_estimate(record: FlightRecord) -> float | None:
    """The log's own boost event, else the first time the 5-row mean specific force exceeds 2 g."""
    ev = record.events or {}
    for name in ("altos_boost", "liftoff"):
        if name in ev:
            return float(ev[name])
    f = record.specific_force_mps2()
    if f is None or f.size < 5:
        return None
    mean5 = np.convolve(np.nan_to_num(f, nan=0.0), np.ones(5) / 5.0, mode="valid")
    hit = np.nonzero(mean5 > 2 * atm.G0)[0]
    return float(record.time_s[hit[0]]) if hit.size else None


def flight_context(record: FlightRecord, source: str = "") -> tuple[float | None, np.ndarray | None, str]:
    """(burnout time, Mach per record sample, where they come from) of a flight.

    Simulated (truth): the simulator's burnout (``provenance.summary.burnout_s``) and its airspeed Mach (scenario
    flights: :func:`flights.scenarios.scenario_mach`; other records with truth: |v|/c). Real logs: burnout =
    :func:`burnout_time` from the liftoff estimate; speed = the axial specific force minus g integrated from
    liftoff until it first falls to zero (after that the rocket is past apogee and slow: 0), else (no
    accelerometer) the slope of the barometric altitude over 0.5 s; Mach = speed / standard speed of sound at the
    pad altitude + the barometric altitude (clipped at the pad)."""
    t = np.asarray(record.time_s, dtype=np.float64)
    if record.truth is not None and record.truth.velocity_mps is not None:
        burn = (record.provenance.get("summary") or {}).get("burnout_s") if record.provenance else None
        if source.startswith("sim:"):
            mach = np.asarray(scenario_mach(source[4:]), dtype=np.float64)
        else:
            mach = np.asarray(mach_of(record), dtype=np.float64)
        return (None if burn is None else float(burn)), mach, "truth"
    p = np.asarray(record.pressure_pa, dtype=np.float64)
    ok = np.isfinite(p) & (p > 0)
    if ok.sum() < 2:
        return None, None, "unknown"
    p_f = np.interp(t, t[ok], p[ok])
    ground = record.ground_pressure_pa or float(np.median(p_f[: max(1, min(50, p_f.size // 20))]))
    pad_m = float(atm.altitude_m(ground))
    h = np.clip(np.asarray(atm.altitude_m(p_f)) - pad_m, 0.0, None)
    c = np.asarray(atm.speed_of_sound_mps(pad_m + h))
    lift = _liftoff_estimate(record)
    f = record.specific_force_mps2()
    if f is not None and lift is not None:
        f = np.where(np.isfinite(f), f, atm.G0)
        v = np.zeros_like(t)
        i0 = int(np.searchsorted(t, lift))
        if i0 < t.size - 1:
            v[i0 + 1:] = np.cumsum(0.5 * ((f[i0 + 1:] - atm.G0) + (f[i0:-1] - atm.G0)) * np.diff(t[i0:]))
        v[:i0 + 1] = 0.0
        down = np.nonzero((t > lift + 0.5) & (v <= 0))[0]
        if down.size:
            v[down[0]:] = 0.0
        return burnout_time(record, lift), np.clip(v, 0.0, None) / c, "accelerometer estimate"
    win = 0.5
    j = np.clip(np.searchsorted(t, t + win / 2), 0, t.size - 1)
    i = np.clip(np.searchsorted(t, t - win / 2), 0, t.size - 1)
    hh = np.asarray(atm.altitude_m(p_f)) - pad_m
    v = np.where(t[j] > t[i], (hh[j] - hh[i]) / np.maximum(t[j] - t[i], 1e-9), 0.0)
    return None, np.abs(v) / c, "barometric estimate"


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
TUNINGS: tuple[str, ...] = TUNING_NAMES


def tuning_overrides(method: Method, k: int, tuning: str = "default") -> dict[str, Any]:
    """BuildConfig fields ``tuning`` sets for ``method`` at ``k`` (empty for ``default``), less the fields that
    define the method (its own threshold: ``rec_quarter`` stays at 1/4 LSB under a tuning that recommends 1/2)."""
    own = dict(method.tuning)
    return {key: value for key, value in tuning_fields(method.program, k, tuning).items() if key not in own}


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
    early_1s: int = 0                          # detections > EARLY_S before the reference (usable references)
    early_1s_flagged: int = 0                  # the same on flights whose reference carries a warning
    most_early_1s_flight: str | None = None    # the flight of the most early of those
    before_burnout: int = 0                    # detections at or before burnout (truth or estimate)
    fast: int = 0                              # detections at Mach >= FAST_MACH
    burnout_known: int = 0                     # flights (that ran) whose burnout is known
    censored: int = 0                          # not fired by the log's recovery charge (error only bounded below)
    median_abs_bound_s: float | None = None    # median |error| with the censored rows at their bounds (a lower
                                               # bound of the true median); None without censored rows


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
    early_usable = [r for r in ran if r.flags(method)["early_1s"] and r.reference.usable]
    danger = {"early_1s": len(early_usable),
              "early_1s_flagged": sum(1 for r in ran if r.flags(method)["early_1s"] and not r.reference.usable),
              "most_early_1s_flight": min(early_usable, key=lambda r: r.error(method)).name if early_usable else None,
              "before_burnout": sum(1 for r in ran if r.flags(method)["before_burnout"]),
              "fast": sum(1 for r in ran if r.flags(method)["fast"]),
              "burnout_known": sum(1 for r in ran if r.burnout_s is not None)}
    bounds = [r.error_bound(method) for r in ran if r.censored(method)]
    danger["censored"] = len(bounds)
    if bounds:
        danger["median_abs_bound_s"] = float(np.median([abs(e) for e, _ in got] + [max(b or 0.0, 0.0)
                                                                                    for b in bounds]))
    if not got:
        return MethodSummary(method, label, len(ran), 0, None, None, None, None, 0, 0, **danger)
    a = np.array([abs(e) for e, _ in got])
    worst = int(np.argmax(a))
    early = min(got)
    usable = [(abs(e), name) for e, name, ok in trio if ok]
    wu = max(usable) if usable else (None, None)
    return MethodSummary(method, label, len(ran), len(got), float(np.median(a)), float(a[worst]), got[worst][1],
                         float(np.median([e for e, _ in got])), sum(e < 0 for e, _ in got),
                         sum(e > 0 for e, _ in got), float(early[0]) if early[0] < 0 else None,
                         early[1] if early[0] < 0 else None, None if wu[0] is None else float(wu[0]), wu[1],
                         len(got) - len(usable), **danger)


def table_methods(results: Sequence[FlightResult]) -> list[tuple[str, str]]:
    """(name, label) of the columns: AltOS (when any flight has it), then the methods in table order."""
    present: list[str] = []
    for r in results:
        for m in r.detections:
            if m not in present:
                present.append(m)
    cols = [("altos", "own computer")] if any(r.altos_s is not None for r in results) else []
    order = [m for m in METHODS if m in present] + [m for m in present if m not in METHODS]
    return cols + [(m, METHODS[m].label if m in METHODS else m) for m in order]


def _fmt(x: float | None, digits: int = 3) -> str:
    return "—" if x is None else f"{x:.{digits}f}"


def _fmt_err(x: float | None) -> str:
    return "miss" if x is None else f"{x:+.3f}"


def _fmt_censored(r: FlightResult, method: str) -> str:
    b = r.error_bound(method)
    return "(later than the log's computer" + ("" if b is None else f": ≥ {b:+.3f}") + ")"


def _danger_marks(r: FlightResult, method: str) -> str:
    f = r.flags(method)
    marks = []
    if f["early_1s"]:
        marks.append("‼")
    if f["before_burnout"]:
        marks.append("boost")
    if f["fast"]:
        marks.append(f"M{r.mach_at[method]:.2f}")
    return (" " + " ".join(marks)) if marks else ""


def render_markdown(results: Sequence[FlightResult], command: str | None = None) -> str:
    """The apogee table (Schultz 2002 Tables 1-2 style) and the per-method summary, as Markdown. The first figures:
    how many detections of each method came more than 1 s early."""
    cols = table_methods(results)
    sums = [(label, summarize(results, m, label)) for m, label in cols]
    head = ["flight", "k", "sensor", "reference apogee s (±unc, source)", "alt m"] + [label for _, label in cols]
    lines = md.header(head)
    for r in results:
        ref = r.reference
        when = (f"[{ref.lower_s:.3f}, {ref.upper_s:.3f}]" if ref.lower_s is not None and ref.upper_s is not None
                else f"{ref.time_s:.3f} ±{ref.uncertainty_s:.3f}")
        cells = [r.name, str(r.k), r.sensor,
                 f"{when} ({ref.source}){'' if ref.usable else ' ⚠'}"
                 f"{' ≠ parabola' if ref.disagree else ''}"
                 + ("" if ref.charge_s is None else f"; charge {ref.charge_s:.2f} ({ref.charge.split(':')[0]})"),
                 _fmt(ref.altitude_m, 0)]
        for m, _ in cols:
            if m == "altos":
                cells.append("—" if r.altos_s is None else
                             f"{r.own_computer} {r.altos_s:.2f} ({_fmt_err(r.error('altos'))})"
                             f"{_danger_marks(r, 'altos')}" if not r.censored("altos") else
                             f"{r.own_computer} {r.altos_s:.2f} {_fmt_censored(r, 'altos')}")
            elif m not in r.detections:
                cells.append("—")
            else:
                d = r.detections[m]
                if d.failed:
                    cells.append("n/a")
                elif r.censored(m):
                    cells.append(("miss" if d.time_s is None else f"{d.time_s:.3f}") + f" {_fmt_censored(r, m)}")
                else:
                    cells.append("miss" if d.time_s is None else
                                 f"{d.time_s:.3f} ({_fmt_err(r.error(m))}){_danger_marks(r, m)}")
        lines.append(md.row(cells))
    headline = "; ".join(f"{label} {s.early_1s} of {s.n}" + (f" (+{s.early_1s_flagged} on flagged references)"
                                                             if s.early_1s_flagged else "") for label, s in sums)
    out = [f"**Detections more than {EARLY_S:g} s before the reference apogee**: {headline}.", "",
           "Detection time s (error s = detection - reference; + late, miss = never fired). ‼: more than "
           f"{EARLY_S:g} s early; boost: at or before burnout; M: Mach at the detection when >= {FAST_MACH:g} "
           "(burnout and Mach: truth for simulated flights, estimated on logs). ⚠: the reference "
           "carries a warning (the fit is not a free flight near its peak, docs/flights.md); such rows are left out "
           "of the summary's last column and of its first count. [a, b]: the reference is an interval (0 error "
           "inside it, else the distance to its nearer end). charge: the log's recovery charge "
           "(docs/evaluation.md, \"The reference apogee and the log's own charge\"); a method that had not fired "
           "by then is \"later than the log's computer\": censored, its error only bounded below (≥), left out of "
           "the medians and counted apart." + (" ≠ parabola: the smoother's and the "
           "parabola's apogees differ by more than their uncertainties (the reference's notes in apogee.json give "
           "both)." if any(r.reference.disagree for r in results) else ""), ""] + lines
    out += [""] + md.header(["method", f"> {EARLY_S:g} s early (flight)", "before burnout",
                             f"above Mach {FAST_MACH:g}", "flights", "detected", "censored (later than the charge)",
                             "median abs error s",
                             "worst abs error s (flight)", "median error s", "early / late", "most early s (flight)",
                             "worst abs error s, usable references"])
    for (m, label), (_, s) in zip(cols, sums):
        worst = "—" if s.worst_abs_s is None else f"{s.worst_abs_s:.3f} ({s.worst_flight})"
        miss = s.n - s.detected - s.censored
        worst += f"; {miss} missed" if miss else ""
        skipped = sum(1 for r in results if m in r.detections and r.detections[m].failed)
        worst += f"; {skipped} n/a" if skipped else ""
        most_early = "—" if s.most_early_s is None else f"{s.most_early_s:+.3f} ({s.most_early_flight})"
        usable = "—" if s.worst_usable_abs_s is None else f"{s.worst_usable_abs_s:.3f} ({s.worst_usable_flight})"
        usable += f"; {s.unusable} on flagged references left out" if s.unusable else ""
        early = f"{s.early_1s}" + (f" ({s.most_early_1s_flight})" if s.most_early_1s_flight else "")
        early += f"; +{s.early_1s_flagged} flagged" if s.early_1s_flagged else ""
        burn = f"{s.before_burnout}" + (f" of {s.burnout_known} known" if s.burnout_known < s.n else "")
        med = _fmt(s.median_abs_s) + ("" if s.median_abs_bound_s is None else
                                      f" (≥ {s.median_abs_bound_s:.3f} with the censored at their bounds)")
        out.append(md.row([label, early, burn, s.fast, s.n, s.detected, s.censored, med, worst,
                           _fmt(s.median_s), f"{s.early} / {s.late}", most_early, usable]))
    if command:
        out += ["", f"Regenerate: `{command}`"]
    return "\n".join(out) + "\n"


def render_csv(results: Sequence[FlightResult]) -> str:
    """One row per flight: reference, AltOS, each method's detection time and error (empty = none)."""
    cols = table_methods(results)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    head = ["flight", "source", "k", "sensor", "n_samples", "ref_time_s", "ref_altitude_m", "ref_uncertainty_s",
            "ref_source", "ref_lower_s", "ref_upper_s", "charge_s"]
    for m, _ in cols:
        head += [f"{m}_time_s", f"{m}_error_s"]
    head += ["burnout_s", "mach_source"] + [f"{m}_mach" for m, _ in cols] + [f"{m}_early_1s" for m, _ in cols]
    head += [f"{m}_censored" for m, _ in cols]
    w.writerow(head)

    def num(x: float | None) -> str:
        return "" if x is None else repr(round(float(x), 6))

    for r in results:
        row = [r.name, r.source, r.k, r.sensor, r.n_samples, num(r.reference.time_s), num(r.reference.altitude_m),
               num(r.reference.uncertainty_s), r.reference.source, num(r.reference.lower_s),
               num(r.reference.upper_s), num(r.reference.charge_s)]
        for m, _ in cols:
            t = r.altos_s if m == "altos" else (r.detections[m].time_s if m in r.detections else None)
            row += [num(t), num(r.error(m))]
        row += [num(r.burnout_s), r.mach_source] + [num(r.mach_at.get(m)) for m, _ in cols]
        row += [int(r.flags(m)["early_1s"]) for m, _ in cols]
        row += [int(r.censored(m)) for m, _ in cols]
        w.writerow(row)
    return buf.getvalue()


def render_json(results: Sequence[FlightResult], command: str | None = None) -> str:
    """Every flight's result plus the per-method summary, JSON (sorted keys, stable)."""
    cols = table_methods(results)
    doc = {"schema": "fwemu-apogee-table/1", "command": command,
           "rule": {"detection": "time of the first sample with EVENTS.APOGEE set (APFRAC prediction not added; "
                                 "reported as predicted_s)",
                    "error": "detection time - reference time, s (positive = late)",
                    "early_1s": f"error < -{EARLY_S:g} s", "before_burnout": "detection time <= burnout_s",
                    "censored": "a real log's method that had not fired by the log's recovery charge "
                                "(reference.charge_s): error None, error_lower_bound_s its bound",
                    "interval": "reference.lower_s..upper_s set: error 0 inside, else to the nearer end",
                    "fast": f"Mach at the detection >= {FAST_MACH:g}"},
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


__all__ = ["EARLY_S", "FAST_MACH", "burnout_time", "flight_context", "Method", "METHODS", "DEFAULT_METHODS", "methods_named", "Detection", "detect_from_events", "run_method",
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

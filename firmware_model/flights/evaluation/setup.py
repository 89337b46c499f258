"""Flight setup for the evaluation, ``fwemu run`` and ``fwemu plot``: which flight (:class:`FlightSpec`, a log or a
scenario), its record (:func:`load_record`), the sensors and the firmware inputs (:func:`flight_inputs`,
:func:`sensor_config`), the reference apogee (:func:`reference_for`), and burnout and speed for the danger marks
(:func:`flight_context`). docs/evaluation.md."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from firmware_model.flights.inputs.firmware_inputs import firmware_inputs
from firmware_model.flights.inputs.sensors import AccelSensor, BaroSensor
from firmware_model.flights.readers import read_flight
from firmware_model.flights.reconstruct.reference import MODES as SMOOTHER_MODES
from firmware_model.flights.reconstruct.reference import smoother_reference
from firmware_model.flights.record import FlightRecord
from firmware_model.flights.reference.apogee_reference import reference_apogee
from firmware_model.flights.reference.charge import recovery_charge
from firmware_model.flights.simulate.scenarios import scenario_mach, simulate_scenario
from firmware_model.flights.simulate.sim1dof import mach_of
from firmware_model.runtime.errors import UserError
from firmware_model.spec import atmosphere as atm
from firmware_model.spec.atmosphere import altitude_m


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
    generated: ``baro_pa_per_count``, ``baro_pa_at_zero``), plus the noise the Kalman design assumes, **measured on the
    pad part of the stream** (the
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
    accelerometer) the slope of the barometric altitude over the 0.5 s before the sample; Mach = speed / standard
    speed of sound at the pad altitude + the barometric altitude (clipped at the pad)."""
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
    # The slope over the 0.5 s before each sample (the sample itself left out), not centred on it: a detection is
    # judged by the speed the data showed until then, and the charge's own row and the rows after it carry its
    # pressure pulse (juno3-rrc3's RRC3 charge row reads 191 hPa against 580 hPa: Mach 63 from a centred window).
    win = 0.5
    j = np.maximum(np.arange(t.size) - 1, 0)
    i = np.clip(np.searchsorted(t, t - win), 0, t.size - 1)
    hh = np.asarray(atm.altitude_m(p_f)) - pad_m
    v = np.where(t[j] > t[i], (hh[j] - hh[i]) / np.maximum(t[j] - t[i], 1e-9), 0.0)
    return None, np.abs(v) / c, "barometric estimate"

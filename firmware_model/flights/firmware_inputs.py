"""A flight record -> the firmware's input streams at dt = 2^-k (barometer word and accelerometer word per sample).

:func:`firmware_inputs` resamples the record onto the 2^-k grid (:mod:`.resample`, reported), then runs the
sensor models (:mod:`.sensors`) on the resampled pressure and specific force, noise drawn from
``numpy.random.default_rng(seed)`` (barometer first, then accelerometer).

Pad time: the firmware's ``init`` reads sample 0 as the pad (ground level, the accelerometer's 1 g), and a pad
calibration averaging 2^p samples needs more (docs/firmware-spec.md). By default the stream starts
:data:`DEFAULT_PAD_S` = 2.0 s before liftoff (:func:`~firmware_model.flights.apogee_reference.liftoff_time`). Real logs
often start later (AltosUI logs begin 0.3 s before boost): grid samples before the log's first row are filled with
the **pad values** (median pressure and specific force of the rows before liftoff, else of the first row) and the
report counts them (``before_log``) and says so in a note. Noise is added to them like to every other sample.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from firmware_model.flights.apogee_reference import ground_pressure, liftoff_time
from firmware_model.flights.record import FlightRecord
from firmware_model.flights.resample import ResampleReport, resample
from firmware_model.flights.sensors import AccelSensor, BaroSensor
from firmware_model.runtime.errors import UserError
from firmware_model.spec.atmosphere import G0
from firmware_model.spec.config import BuildConfig

#: Seconds of pad before liftoff in the default stream.
DEFAULT_PAD_S: float = 2.0


@dataclass
class FirmwareInputs:
    """The firmware's inputs for one flight.

    * ``adc``: int64 (n,) barometer words (ADC counts, or pascals for a ``pascal`` sensor);
    * ``acc``: int64 (n,) accelerometer words (zeros when the record has no accelerometer: ``has_accel`` False);
    * ``time_s``: (n,) the grid, record time of each sample (exact multiples of 2^-k);
    * ``k``, ``report`` (:class:`ResampleReport`), ``baro``, ``accel`` (the sensors), ``seed``;
    * ``liftoff_s``, ``ground_pressure_pa``: what the stream was built around;
    * ``truth``: the record's truth arrays resampled onto the grid (``altitude_m``, ``velocity_mps``,
      ``accel_mps2``; None where absent), for plots and evaluation;
    * ``clipped``: samples at a sensor's output limits (``baro``, ``accel``), also noted in the report.
    """

    adc: np.ndarray
    acc: np.ndarray
    time_s: np.ndarray
    k: int
    report: ResampleReport
    baro: BaroSensor
    accel: AccelSensor
    seed: int
    has_accel: bool
    liftoff_s: float
    ground_pressure_pa: float
    pressure_pa: np.ndarray = field(repr=False, default=None)          # resampled, noise-free
    specific_force_mps2: np.ndarray | None = field(repr=False, default=None)
    truth: dict[str, np.ndarray | None] = field(default_factory=dict, repr=False)
    clipped: dict[str, int] = field(default_factory=dict)       # samples at a sensor's limits, per sensor

    @property
    def n(self) -> int:
        return int(self.adc.shape[0])

    def units_per_metre(self) -> float:
        """Barometer counts per metre at the pad (counts_per_pa x rho x g0 at the ground pressure)."""
        return self.baro.counts_per_metre(self.ground_pressure_pa)

    def config_overrides(self) -> dict[str, Any]:
        """BuildConfig fields consistent with the sensors: ``baro_bits`` and the transfer function
        ``baro_pa_per_count`` / ``baro_pa_at_zero`` (ADC sensors only: a pascal word is not an 8..16-bit ADC, issue
        9; the Kalman programs' altitude table is generated from it), ``baro_sign``, ``units_per_metre``,
        ``accel_counts_per_mps2``, ``k``. Only
        fields that :class:`~firmware_model.spec.config.BuildConfig` has are returned."""

        out: dict[str, Any] = {"k": self.k, "baro_sign": self.baro.sign, "units_per_metre": self.units_per_metre(),
                               "accel_counts_per_mps2": self.accel.counts_per_mps2}
        if self.baro.kind == "adc":
            out["baro_bits"] = self.baro.bits
            # the field-ready Kalman programs' altitude table is built from this transfer function
            # (BuildConfig baro_pa_per_count / baro_pa_at_zero: P(c) = pa_at_zero - baro_sign * pa_per_count * c)
            out["baro_pa_per_count"] = 1.0 / abs(self.baro.counts_per_pa)
            out["baro_pa_at_zero"] = -self.baro.offset_counts / self.baro.counts_per_pa
        else:
            out["baro_kind"] = "pascal"
        names = {f.name for f in dataclasses.fields(BuildConfig)}
        return {k: v for k, v in out.items() if k in names}

    def provenance(self) -> dict[str, Any]:
        """JSON-ready description (sensors, seed, resampling)."""
        return {"k": self.k, "seed": self.seed, "baro": self.baro.to_dict(), "accel": self.accel.to_dict(),
                "has_accel": self.has_accel, "liftoff_s": self.liftoff_s,
                "ground_pressure_pa": self.ground_pressure_pa, "resample": self.report.to_dict()}


def _pad_value(t: np.ndarray, y: np.ndarray, liftoff: float) -> float:
    ok = np.isfinite(y)
    before = ok & (t < liftoff)
    if before.any():
        return float(np.median(y[before]))
    return float(y[ok][0])


def firmware_inputs(record: FlightRecord, k: int, baro: BaroSensor | None = None, accel: AccelSensor | None = None,
                    method: str = "linear", seed: int = 0, t_start: float | None = None,
                    t_end: float | None = None, pad_s: float = DEFAULT_PAD_S) -> FirmwareInputs:
    """Build the firmware's input streams for ``record`` at dt = 2^-k.

    ``baro``: default TeleMetrum v1 (16-bit word, the exact README formula); ``accel``: default the firmware's
    default build (2048 counts/g, +-16 g). ``t_start`` default ``liftoff - pad_s``; ``t_end`` default the log's last
    row. ``seed``: noise generator seed (used only if a sensor has noise)."""
    baro = baro or BaroSensor.preset("telemetrum_v1")
    accel = accel or AccelSensor.preset("default")
    t = np.asarray(record.time_s, dtype=np.float64)
    lift = liftoff_time(record)
    a = lift - pad_s if t_start is None else float(t_start)
    b = float(t[-1]) if t_end is None else float(t_end)
    if b <= a:
        raise UserError(f"{record.name}: empty time span {a} .. {b} s")
    f = record.specific_force_mps2()
    cols: dict[str, np.ndarray | None] = {"pressure_pa": np.asarray(record.pressure_pa, dtype=np.float64),
                                          "accel_mps2": f}
    tr = record.truth
    for name in ("altitude_m", "velocity_mps", "accel_mps2"):
        cols[f"true_{name}"] = None if tr is None else getattr(tr, name)
    g, out, report = resample(t, cols, k, method=method, t_start=a, t_end=b)
    before = g < t[0]
    pads = {"pressure_pa": _pad_value(t, cols["pressure_pa"], lift)}
    if f is not None:
        pads["accel_mps2"] = _pad_value(t, f, lift)
    if before.any():
        for name, value in pads.items():
            out[name][before] = value
        if tr is not None:
            for name, value in (("true_altitude_m", 0.0), ("true_velocity_mps", 0.0), ("true_accel_mps2", 0.0)):
                if out[name] is not None:
                    out[name][before] = value
        report.notes.append(f"{int(before.sum())} samples before the log's first row (t < {t[0]:g} s) filled with "
                            f"the pad values (pressure {pads['pressure_pa']:.1f} Pa"
                            + (f", specific force {pads['accel_mps2']:.3f} m/s^2)" if f is not None else ")"))
    rng = np.random.default_rng(seed)
    adc = baro.counts(out["pressure_pa"], rng)
    clipped = {"baro": int(np.sum((adc <= (0 if baro.kind == "adc" else np.ceil(baro.p_min_pa)))
                                  | (adc >= baro.full_scale)))}
    if f is not None:
        acc = accel.counts(out["accel_mps2"], rng)
        lo, hi = accel.count_limits
        clipped["accel"] = int(np.sum((acc <= lo) | (acc >= hi)))
    else:
        acc = np.zeros_like(adc)
        report.notes.append("record without accelerometer: acc = 0 on every sample")
    for name, count in clipped.items():
        if count:
            report.notes.append(f"{count} {name} samples at the sensor's limits (clipped)")
    return FirmwareInputs(adc=adc, acc=acc, time_s=g, k=int(k), report=report, baro=baro, accel=accel, seed=seed,
                          has_accel=f is not None, liftoff_s=lift, ground_pressure_pa=ground_pressure(record),
                          pressure_pa=out["pressure_pa"], specific_force_mps2=out["accel_mps2"],
                          truth={n: out[f"true_{n}"] for n in ("altitude_m", "velocity_mps", "accel_mps2")},
                          clipped=clipped)


__all__ = ["DEFAULT_PAD_S", "FirmwareInputs", "firmware_inputs", "G0"]

"""A flight record -> the firmware's input streams at dt = 2^-k (barometer word and accelerometer word per sample).

:func:`firmware_inputs` resamples the record onto the 2^-k grid (:mod:`.resample`, reported), then runs the
sensor models (:mod:`.sensors`) on the resampled pressure and specific force, noise drawn from
``numpy.random.default_rng(seed)`` (barometer first, then accelerometer).

Pad time: the firmware's ``init`` reads sample 0 as the pad (ground level, the accelerometer's 1 g), and a pad
calibration averaging 2^p samples needs more (docs/firmware-spec.md). By default the stream starts :data:`DEFAULT_PAD_S`
= 2.0 s before liftoff (:func:`~firmware_model.flights.reference.apogee_reference.liftoff_time`). Real logs often start
later (AltosUI logs begin 0.3 s before boost): grid samples before the log's first row are filled with the **pad
values** (median pressure and specific force of the rows before liftoff, else of the first row) and the report counts
them (``before_log``) and says so in a note. Noise is added to them like to every other sample.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from firmware_model.flights.reference.apogee_reference import ground_pressure, liftoff_time
from firmware_model.flights.readers._common import show
from firmware_model.flights.record import FlightRecord
from firmware_model.flights.inputs.resample import ResampleReport, resample
from firmware_model.flights.inputs.sensors import AccelSensor, BaroSensor
from firmware_model.runtime.errors import UserError
from firmware_model.spec.atmosphere import G0
from firmware_model.spec.config import BuildConfig

#: Seconds of pad before liftoff in the default stream.
DEFAULT_PAD_S: float = 2.0
#: Longest interval between two log rows the resampler bridges (interpolates / holds across) inside the stream's
#: span; a longer one (a clock jump, a logger pause) is refused naming its line. docs/flights.md, "Gaps".
MAX_GAP_S: float = 2.0
#: Most grid samples one stream may hold (2^24: 128 MiB per float64 column), whatever the log's time span.
MAX_SAMPLES: int = 1 << 24
#: What to do with the accelerometer of a log that starts after liftoff: "nominal" = its pad value is the
#: sensor's nominal 1 g; "refuse" = the stream has no accelerometer.
LATE_START: tuple[str, ...] = ("nominal", "refuse")


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


def _where(record: FlightRecord, i: int) -> str:
    """``file:line`` of row ``i`` when the record knows its lines, else ``name: row i``."""
    src = record.provenance.get("source", record.name)
    lines = record.row_lines
    if lines is not None and 0 <= i < len(lines):
        return f"{src}:{int(lines[i])}"
    return f"{src}: row {i}"


def check_span(record: FlightRecord, a: float, b: float, k: int, max_gap_s: float = MAX_GAP_S) -> None:
    """Refuse, before anything is allocated, a stream whose span holds a gap longer than ``max_gap_s`` between two
    rows (``file:line`` of the row after it) or more than :data:`MAX_SAMPLES` grid samples."""
    t = np.asarray(record.time_s, dtype=np.float64)
    d = np.diff(t)
    inside = (t[1:] > a) & (t[:-1] < b)
    big = np.nonzero((d > max_gap_s) & inside)[0]
    if big.size:
        i = int(big[0]) + 1
        raise UserError(f"{_where(record, i)}: time jumps by {show(round(float(d[i - 1]), 6))} s "
                        f"({show(float(t[i - 1]))} -> {show(float(t[i]))} s): more than the {show(max_gap_s)} s the "
                        f"resampler bridges" + (f" ({big.size} such gaps)" if big.size > 1 else "")
                        + "; cut the log before it or fix the clock")
    n = (b - a) * float(1 << int(k)) if 0 <= int(k) <= 16 else 0.0
    if n > MAX_SAMPLES:
        raise UserError(f"{record.provenance.get('source', record.name)}: {show(round(b - a, 3))} s at 2^-{k} s is "
                        f"{n:.3g} samples, more than {MAX_SAMPLES}: shorten the span (t_end)")


def _end_before_gap(record: FlightRecord, a: float, b: float, max_gap_s: float) -> tuple[float, str]:
    """The default end of the stream: the log's last row, or the row before the first gap longer than ``max_gap_s`` when
    that gap comes 3 s or more after the lowest pressure (the apogee) of the rows before it: a logger that slows down or
    pauses after the flight (an AltOS nose cone still logging 37 minutes later) ends the stream there, said in the
    report. A gap before the apogee is left to :func:`check_span` (refused)."""
    t = np.asarray(record.time_s, dtype=np.float64)
    p = np.asarray(record.pressure_pa, dtype=np.float64)
    d = np.diff(t)
    big = np.nonzero((d > max_gap_s) & (t[1:] > a))[0]
    if not big.size:
        return b, ""
    i = int(big[0])
    ok = np.isfinite(p[: i + 1])
    if not ok.any() or t[i] <= a:
        return b, ""
    top = int(np.argmin(np.where(ok, p[: i + 1], np.inf)))
    if t[top] + 3.0 > t[i]:     # the reference fits up to 2.5 s either side of the peak
        return b, ""
    return float(t[i]), (f"the stream ends at {show(float(t[i]))} s ({_where(record, i)}): the next row comes "
                         f"{show(round(float(d[i]), 6))} s later (more than the {show(max_gap_s)} s bridged), after "
                         f"the flight's highest point ({t[top]:.2f} s)")


def late_start(record: FlightRecord, lift: float) -> str | None:
    """Why the log is judged to start after liftoff (no pad to calibrate on), or None when it has a pad: fewer
    than 10 rows before liftoff, or a median specific force over them more than 0.15 g from 1 g."""
    t = np.asarray(record.time_s, dtype=np.float64)
    before = t < lift
    if int(before.sum()) < 10:
        return f"{int(before.sum())} rows before liftoff ({lift:g} s)"
    f = record.specific_force_mps2()
    if f is not None:
        ok = before & np.isfinite(f)
        if ok.any():
            g = float(np.median(f[ok])) / G0
            if abs(g - 1.0) > 0.15:
                return (f"the accelerometer reads {g:.2f} g before liftoff, not 1 g: already accelerating, "
                        "or not the rocket's axis")
    return None


def firmware_inputs(record: FlightRecord, k: int, baro: BaroSensor | None = None, accel: AccelSensor | None = None,
                    method: str = "linear", seed: int = 0, t_start: float | None = None,
                    t_end: float | None = None, pad_s: float = DEFAULT_PAD_S, max_gap_s: float = MAX_GAP_S,
                    late: str = "nominal") -> FirmwareInputs:
    """Build the firmware's input streams for ``record`` at dt = 2^-k.

    ``baro``: default the record's own sensor where the reader names a preset (``provenance["baro_preset"]``:
    AltOS .eeprom -> ``ms5607``, the device's integer pascals), else TeleMetrum v1 (16-bit word, the exact README
    formula); ``accel``: default the firmware's default build (2048 counts/g, +-16 g). ``t_start`` default
    ``liftoff - pad_s``; ``t_end`` default the log's last row. ``seed``: noise generator seed (used only if a
    sensor has noise). ``max_gap_s``: see :func:`check_span`. ``late``: a log that starts after liftoff
    (:func:`late_start`) gets its accelerometer's pad value from the sensor's nominal 1 g (``"nominal"``) or no
    accelerometer (``"refuse"``); the report says which."""
    if late not in LATE_START:
        raise UserError(f"late start {late!r}: known: {', '.join(LATE_START)}")
    baro = baro or BaroSensor.preset(record.provenance.get("baro_preset") or "telemetrum_v1")
    accel = accel or AccelSensor.preset("default")
    t = np.asarray(record.time_s, dtype=np.float64)
    lift = liftoff_time(record)
    a = lift - pad_s if t_start is None else float(t_start)
    b = float(t[-1]) if t_end is None else float(t_end)
    cut_note = ""
    if t_end is None:
        b, cut_note = _end_before_gap(record, a, b, max_gap_s)
    if b <= a:
        raise UserError(f"{record.name}: empty time span {show(a)} .. {show(b)} s")
    check_span(record, a, b, k, max_gap_s)
    f = record.specific_force_mps2()
    late_why = late_start(record, lift)
    if late_why and f is not None and late == "refuse":
        f = None
    cols: dict[str, np.ndarray | None] = {"pressure_pa": np.asarray(record.pressure_pa, dtype=np.float64),
                                          "accel_mps2": f}
    tr = record.truth
    for name in ("altitude_m", "velocity_mps", "accel_mps2"):
        cols[f"true_{name}"] = None if tr is None else getattr(tr, name)
    try:
        g, out, report = resample(t, cols, k, method=method, t_start=a, t_end=b)
    except UserError as exc:      # name the log (issue 33: a shifted time column gave a message without a file)
        src = record.provenance.get("source", record.name)
        hint = (" (no accelerometer sample inside the barometer's time span: a shifted or mismatched time column?)"
                if "accel_mps2" in str(exc) else "")
        raise UserError(f"{src}: {exc}{hint}") from None
    before = g < t[0]
    pads = {"pressure_pa": _pad_value(t, cols["pressure_pa"], lift)}
    if f is not None:
        pads["accel_mps2"] = G0 if late_why else _pad_value(t, f, lift)
    if late_why:
        report.notes.append(f"the log starts after liftoff ({late_why}): "
                            + ("accelerometer REFUSED (no accelerometer in the stream)" if late == "refuse" and
                               record.specific_force_mps2() is not None else
                               "accelerometer pad value = the sensor's nominal 1 g" if f is not None else
                               "no accelerometer")
                            + "; ground pressure from the first rows (the rocket may already be above the pad)")
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
    if cut_note:
        report.notes.append(cut_note)
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


__all__ = ["DEFAULT_PAD_S", "FirmwareInputs", "LATE_START", "MAX_GAP_S", "MAX_SAMPLES", "check_span",
           "firmware_inputs", "late_start", "G0"]

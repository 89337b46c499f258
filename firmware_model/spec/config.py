"""Build configuration of a firmware program: the user-facing, physical-units description from which the integer
build constants (docs/firmware-spec.md §3) are derived by :mod:`firmware_model.spec.build_constants`.

Everything here is in SI units or raw sensor counts; nothing here is in Q formats. Validation errors are
:class:`~firmware_model.runtime.errors.UserError` naming the field and the value.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from firmware_model.runtime.errors import UserError
from firmware_model.spec.atmosphere import G0 as _G0

#: TeleMetrum v1 (MP3H6115A through a 16-bit-scaled ADC; the AltosUI log notes in docs/flights.md):
#: raw = (P/1000*0.009 - 0.095)*32752, i.e. P(raw) = PA_AT_ZERO + PA_PER_COUNT * raw.
TELEMETRUM_PA_PER_COUNT: float = 1000.0 / (0.009 * 2047 * 16)
TELEMETRUM_PA_AT_ZERO: float = 0.095 / 0.009 * 1000.0

#: Firmware programs, in the order of docs/firmware-spec.md.
PROGRAMS: tuple[str, ...] = ("recursive", "kalman_baro", "kalman_accel", "recursive_seed_literal")
#: Rounding modes for every right shift (docs/firmware-spec.md §1).
ROUNDINGS: tuple[str, ...] = ("floor", "half_up")
#: Process-noise models for the gain design (docs/gain-design.md).
NOISE_MODELS: tuple[str, ...] = ("accel_only", "jerk", "dwna")
#: Barometer input kinds (docs/firmware-spec.md §2): a 16-bit ADC word, or a digital sensor's 32-bit pascal word.
BARO_KINDS: tuple[str, ...] = ("adc", "pascal")
#: The pascal kind's table covers words 0..2^PA_TABLE_BITS - 1 Pa (docs/firmware-spec.md §2a).
PA_TABLE_BITS: int = 17
#: Default valid range of a pascal word (the MS5607's 10..1200 mbar).
PA_DEFAULT_RANGE: tuple[int, int] = (1000, 120000)
#: Default table segment shift of the pascal kind: nodes every 2^7 = 128 Pa (1,025 nodes; docs/numerics.md).
PA_DEFAULT_ALT_SHIFT: int = 7


#: The altitude table's node cap: 4 bytes a node, 2,049 nodes = 8,196 bytes, the most the 68000's 16 KB ROM holds
#: next to the program (docs/numerics.md "Altitude table"). It also bounds the table fit's memory (quadratic in the
#: node count: 2^15 + 1 nodes asked for 8 GiB, issue 33).
MAX_TABLE_NODES: int = 2049
#: log2(MAX_TABLE_NODES - 1): the smallest alt_shift is table_bits - this.
MAX_TABLE_SHIFT_SPAN: int = 11
#: Kalman state units per m/s (and per m/s^2): Q24.8 metres.
KALMAN_UNITS_PER_MPS: float = 256.0
#: Fields in barometer counts that cannot exceed the sensor's whole range (2^table_bits).
WHOLE_RANGE_FIELDS: tuple[str, ...] = ("baro_sigma", "units_per_metre")
#: At most this many characters of a bad value are echoed in an error message.
ECHO_CHARS: int = 80

#: Physical bounds shared by several fields (issue 33): every number a config holds is checked against one, so no
#: input can overflow a float in the design or an int32 in the build. Each is far outside what a rocket does.
MAX_SPEED_MPS: float = 3000.0        # Mach ~9; the amateur altitude records peak near Mach 5
MAX_ACCEL_MPS2: float = 1000.0 * 9.80665   # 1,000 g
MAX_SECONDS: float = 3600.0          # an hour: longer than any boost, coast or descent
MAX_QUANT_ALT_M: float = 30000.0     # the altitude table's floor (1,000 Pa) lies near 31 km


def echo(value: Any) -> str:
    """``repr(value)`` cut to :data:`ECHO_CHARS` characters (a 5 MB string must not become a 5 MB error line)."""
    text = repr(value)
    if len(text) <= ECHO_CHARS:
        return text
    return text[:ECHO_CHARS - 20] + f"...({len(text):,} chars)"


class ConfigError(UserError):
    """A build-config field that failed validation: ``key`` is the field the user wrote, ``detail`` says what was
    wrong and what is allowed; the message is ``WHERE: key: detail``."""

    def __init__(self, key: str, detail: str, where: str | None = None) -> None:
        self.key, self.detail = key, detail
        super().__init__(f"{where or 'build config'}: {key}: {detail}")

    def at(self, where: str) -> ConfigError:
        """The same error located at ``where`` (a file, ``file:line``)."""
        return ConfigError(self.key, self.detail, where)


@dataclass(frozen=True)
class Rule:
    """The type and range of one field: ``kind`` int | number | choice; ``lo``/``hi`` inclusive bounds (``lo_open``:
    the lower bound excluded); ``choices`` for a choice; ``null`` when ``None`` is allowed; ``unit`` and ``why``
    for the message."""

    kind: str
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    choices: tuple[Any, ...] = ()
    null: bool = False
    unit: str = ""
    why: str = ""

    def allowed(self) -> str:
        if self.kind == "choice":
            text = " or ".join(", ".join(map(str, self.choices)).rsplit(", ", 1))
        else:
            word = "an integer" if self.kind == "int" else "a number"
            lo = "" if self.lo is None else f"{'>' if self.lo_open else '>='} {self.lo:,.10g}"
            hi = "" if self.hi is None else f"<= {self.hi:,.10g}"
            if self.kind == "int" and self.lo is not None and self.hi is not None:
                text = f"{word} {self.lo:,.0f}..{self.hi:,.0f}"
            else:
                text = f"{word} {' and '.join(b for b in (lo, hi) if b)}".rstrip()
            text += f" {self.unit}" if self.unit else ""
        text += " or null" if self.null else ""
        return text + (f" ({self.why})" if self.why else "")

    def check(self, name: str, value: Any, where: str | None) -> None:
        if value is None and self.null:
            return
        if self.kind == "choice":
            if isinstance(value, bool) or value not in self.choices or not isinstance(value, type(self.choices[0])):
                raise ConfigError(name, f"{echo(value)} is not an allowed value; allowed: {self.allowed()}", where)
            return
        if isinstance(value, bool) or not isinstance(value, (int, float)) or (
                self.kind == "int" and not isinstance(value, int)):
            kind = "true/false" if isinstance(value, bool) else type(value).__name__
            kind = {"str": "text", "NoneType": "null", "dict": "an object", "list": "a list"}.get(kind, kind)
            raise ConfigError(name, f"{echo(value)} is {kind}; allowed: {self.allowed()}", where)
        if isinstance(value, float) and not math.isfinite(value):
            raise ConfigError(name, f"{echo(value)} is not finite; allowed: {self.allowed()}", where)
        low = self.lo is not None and (value <= self.lo if self.lo_open else value < self.lo)
        if low or (self.hi is not None and value > self.hi):
            raise ConfigError(name, f"{echo(value)} is out of range; allowed: {self.allowed()}", where)


_SPEED = Rule("number", 0.0, MAX_SPEED_MPS, unit="m/s", why="Mach ~9 and above is not a rocket")
_ACCEL = Rule("number", 0.0, MAX_ACCEL_MPS2, unit="m/s^2", why="1,000 g")
_SECONDS = Rule("number", 0.0, MAX_SECONDS, unit="s")

#: The build config's schema (issue 33): type and physical range of every field; cross-field rules (the
#: barometer's range, the table's node cap, int32 thresholds) are in :meth:`BuildConfig.validate`.
FIELDS: dict[str, Rule] = {
    "program": Rule("choice", choices=PROGRAMS),
    "k": Rule("int", 0, 10, why="sample period 2^-k s"),
    "rounding": Rule("choice", choices=ROUNDINGS),
    "baro_kind": Rule("choice", choices=BARO_KINDS),
    "baro_bits": Rule("int", 8, 16, unit="bits", why="barometer ADC width"),
    "baro_sign": Rule("choice", choices=(-1, 1)),
    "units_per_metre": Rule("number", 1e-3, float(1 << PA_TABLE_BITS), unit="counts per metre",
                            why="at most the sensor's whole range in one metre"),
    "accel_counts_per_mps2": Rule("number", 1e-3, 32767.0, unit="counts per m/s^2",
                                  why="a 16-bit word spanning at least 1 m/s^2"),
    "shift": Rule("int", 1, 8, why="recursive filter shift S: ADC << (8-S) must be a left shift"),
    "threshold_q8": Rule("int", 1, 1 << 20, why="apogee threshold, Q24.8"),
    "threshold_sigmas": Rule("number", 0.0, 100.0, why="apogee threshold in sigmas of the filtered noise; 0 = off"),
    "gate_mps": _SPEED,
    "noise_model": Rule("choice", choices=NOISE_MODELS),
    "ratio": Rule("number", 0.0, 1e12, lo_open=True, why="R/q; above 1e12 the process noise vanishes"),
    "baro_sigma": Rule("number", 0.0, float(1 << PA_TABLE_BITS), lo_open=True, unit="counts",
                       why="at most the sensor's whole range"),
    "accel_sigma": Rule("number", 0.0, 65536.0, lo_open=True, unit="counts",
                        why="at most the 16-bit accelerometer word's range"),
    "accel_model_g": Rule("number", 0.0, 100.0, unit="g"),
    "mach_lo_mps": _SPEED,
    "mach_hi_mps": _SPEED,
    "mach_innov_m": Rule("number", 0.0, 1e5, unit="m"),
    "baro_min": Rule("int", null=True, why="raw barometer word; the range is checked below"),
    "baro_max": Rule("int", null=True, why="raw barometer word; the range is checked below"),
    "liftoff_mps": _SPEED,
    "baro_pa_per_count": Rule("number", 0.0, 1e5, lo_open=True, null=True, unit="Pa",
                              why="one count is at most an atmosphere"),
    "baro_pa_at_zero": Rule("number", -1e6, 1e6, null=True, unit="Pa", why="ten atmospheres either way"),
    "alt_shift": Rule("int", 1, 15, null=True, why="altitude-table segment 2^alt_shift counts"),
    "cal_p": Rule("int", 0, 8, null=True, why="pad calibration over 2^cal_p samples"),
    "gate_sigmas": Rule("number", 0.0, 1000.0, why="innovation gate in sigmas; 0 = no gate"),
    "gate_hold_s": _SECONDS,
    "apogee_hold_s": _SECONDS,
    "transonic_r_factor": Rule("number", 1.0, 1e6),
    "baro_rate_mps": _SPEED,
    "mach_settle_s": _SECONDS,
    "mach_delay_s": Rule("number", 0.0, MAX_SECONDS, null=True, unit="s", why="null: the program's default"),
    "coast_mps2": _ACCEL,
    "coast_s": _SECONDS,
    "drag_mps2": _ACCEL,
    "thrust_mps2": _ACCEL,
    "descent_mps": _SPEED,
    "clip_drag_mps2": _ACCEL,
    "clip_s": _SECONDS,
    "quant_alt_m": Rule("number", 0.0, MAX_QUANT_ALT_M, unit="m", why="above the pad; the table ends near 31 km"),
    "guards": Rule("int", 0, 15, why="bit mask of the physical guards: 1 thrust, 2 gravity, 4 floor, 8 descent"),
    "floor_m": Rule("number", 0.0, 10000.0, unit="m", why="the apogee floor above the pad"),
    "fall_margin_mps": Rule("number", 0.0, 1000.0, unit="m/s"),
    "descent_hold_s": Rule("number", 0.0, 60.0, unit="s", why="the descent guard's bound on the wait"),
}

#: kalman_baro's default Mach delay (s, issue 30; docs/history/evaluation-rounds.md "Issue 30"): no apogee until
#: this long after liftoff, longer than the burns of the supersonic flights whose port reads ram pressure (up to 6 s).
BARO_MACH_DELAY_S: float = 8.0

#: The defaults that depend on the program (issue 30: "a default a user gets without asking must be safe"): a field left
#: ``None`` (not given, or ``null`` in a file) takes its program's value here, else :data:`COMMON_DEFAULTS`. The Kalman
#: programs' defaults are the designs the evaluation recommends (docs/history/evaluation-rounds.md "Issue 30, second
#: round"): R/q 1,000 and, for kalman_accel, half_up rounding and a 0.15 g accelerometer model error (the designs they
#: replaced, Schultz 2002's R/q 50,000 without a model error, fired kalman_baro more than 1 s early on 16 runs of
#: set:full and kalman_accel on 8.6 % of the transonic Monte Carlo). spec.tuning.RECOMMENDED takes them from here.
PROGRAM_DEFAULTS: dict[str, dict[str, Any]] = {
    "kalman_baro": {"ratio": 1000.0},
    "kalman_accel": {"ratio": 1000.0, "rounding": "half_up", "accel_model_g": 0.15},
}
#: The program-dependent fields' values for every other program (the recursive programs, Schultz 2002's listing).
COMMON_DEFAULTS: dict[str, Any] = {"ratio": 50_000.0, "rounding": "floor", "accel_model_g": 0.0}


@dataclass(frozen=True)
class BuildConfig:
    """One firmware build.

    Sensor description:
      * ``baro_kind``: ``adc`` (an analog sensor through an ADC: the 16-bit register ``BARO_ADC``) or ``pascal`` (a
        digital sensor, MS5607-like, reporting integer pascals in the signed 32-bit register ``BARO_PA``;
        docs/firmware-spec.md §2). For ``pascal``: ``baro_bits`` is ignored (the word is 32-bit), the transfer
        function is the identity (``baro_pa_per_count``/``baro_pa_at_zero`` must be null), ``baro_min``/``baro_max``
        are pascals (default 1,000..120,000, inside 0..2^17-1), ``baro_sign`` -1 (pressure falls as the rocket
        climbs), ``units_per_metre`` is pascals per metre at the pad, ``baro_sigma`` pascals.
      * ``baro_bits``: barometer ADC width (bits, 8..16); ``baro_sign``: -1 for a pressure ADC (falls as the rocket
        climbs), +1 for a reading that grows with altitude.
      * ``units_per_metre``: barometer counts per metre of altitude near the pad (> 0). For a pressure ADC this is
        counts/Pa x rho*g; it converts the velocity thresholds into state units (Q24.8 counts/s).
      * ``accel_counts_per_mps2``: accelerometer counts per m/s^2 (> 0; positive counts = upward acceleration).
    Filter:
      * ``k``: sample period dt = 2^-k s (0..10). ``rounding``: ``floor`` or ``half_up`` (``None``: the program's
        default, :data:`PROGRAM_DEFAULTS`: half_up for kalman_accel, floor for every other program).
      * recursive: ``shift`` S (weight 2^-S, 1..8), ``threshold_q8`` (apogee threshold below the extreme in Q24.8
        units of 1/256 count: 128 = 1/2 LSB, 64 = 1/4, 32 = 1/8), ``threshold_sigmas`` (the threshold is at least
        this many standard deviations of the filtered barometer noise, ``baro_sigma * sqrt(2^-S / (2 - 2^-S))``
        counts: a fall of the filter's output below its extreme smaller than its own noise is not evidence; 0, the
        default, leaves ``threshold_q8`` alone; docs/firmware-spec.md §3 ``THR``), ``gate_mps`` (velocity gate, m/s;
        default 40 since issue 30: a rocket that coasts h metres after burnout had at least sqrt(2 g h) at burnout,
        so 40 m/s arms every flight that coasts 82 m or more; Schultz 2002's ~200 ft/s (61 m/s, the default before)
        never armed a 293 m flight with a long burn that peaked at 60.8 m/s).
      * Kalman: ``noise_model`` (``accel_only``, ``jerk``, ``dwna``), ``ratio`` (R/q, measurement variance over
        process-noise intensity; ``None``: 1,000 for the Kalman programs, :data:`PROGRAM_DEFAULTS`), ``baro_sigma``
        (barometer noise, counts), ``accel_sigma`` (accelerometer noise,
        counts), ``mach_lo_mps``/``mach_hi_mps`` (Mach-lockout velocity window, m/s), ``mach_innov_m`` (innovation
        that triggers lockout, m), ``baro_min``/``baro_max`` (valid raw ADC range; ``None`` = full range).
      * all: ``liftoff_mps`` (liftoff velocity threshold, m/s).
    Field-ready Kalman inputs (docs/firmware-spec.md §2a, §6; the Kalman programs run in metres):
      * ``baro_pa_per_count``, ``baro_pa_at_zero``: the barometer's linear transfer function, ``P(c) =
        baro_pa_at_zero - baro_sign * baro_pa_per_count * c`` (Pa); ``None`` = TeleMetrum v1's MP3H6115A
        (3.3925 Pa/count at 16 bits, scaled by 2^(16-bits); 10,555.6 Pa at count 0).
      * ``alt_shift``: altitude-table segment width 2^alt_shift counts (``None`` = bits - 9: 513 nodes).
      * ``cal_p``: pad calibration over 2^cal_p valid samples (0..8; ``None`` = min(8, max(0, k - 2)), a quarter
        second of pad).
      * ``gate_sigmas``: innovation gate in steady-state innovation sigmas (0 = no gate); ``gate_hold_s``: how long
        (s) the gate may stay closed before it opens (GATE_N = max(1, round(gate_hold_s * 2^k))).
      * ``apogee_hold_s``: X2 < 0 this long (APO_N = max(1, round(apogee_hold_s * 2^k)) samples) declares apogee.
      * ``transonic_r_factor``: kalman_accel's barometer variance factor above ``mach_lo_mps`` (>= 1).
    Recursive field-ready logic (docs/firmware-spec.md §5): ``cal_p`` (ACC0 averaged over 2^cal_p pad samples),
    ``gate_sigmas``/``gate_hold_s`` and ``baro_rate_mps`` (barometer rate gate: a sample further than
    ``baro_rate_mps * units_per_metre * dt + gate_sigmas * sqrt(2) * baro_sigma`` counts from the last used one is
    not used, for up to GATE_N samples), ``apogee_hold_s`` (after an accelerometer clip, apogee needs this long of
    evidence).
    Flight logic of issue 20 (docs/firmware-spec.md §4a, §6 steps 4, 7-9):
      * ``mach_lo_mps``: kalman_accel's Mach threshold (default 244 m/s, Mach 0.72 at 15 C): above it (accelerometer-
        driven velocity) the barometer is not used; ``mach_settle_s``: it stays unused this long after the speed
        falls back below (MACH_N = max(1, round(mach_settle_s * 2^k))), then X1 is re-based on the barometer.
      * ``mach_delay_s``: Kalman programs declare no apogee until this long after liftoff (the "Mach delay" of
        barometric altimeters; DLY_N = round(mach_delay_s * 2^k)); ``None`` (default) = the program's own:
        :data:`BARO_MACH_DELAY_S` for kalman_baro (issue 30: a barometer alone cannot see a port reading ram
        pressure in boost while the height it reports stays above the floor and falls no faster than gravity
        allows), 0 for kalman_accel (its thrust guard sees the boost).
      * ``drag_mps2``: the drag deceleration bound; the velocity bound VB falls by at most (g + drag_mps2) * dt per
        sample (DV), and apogee needs VB < 0 (a reversal faster than that is a sensor error); ``thrust_mps2``: VB
        rises by at most thrust_mps2 * dt per sample (DU), so a velocity spike of the estimate cannot hold apogee off.
      * ``coast_mps2``/``coast_s``: PHASE = COAST after the acceleration stayed below -coast_mps2 for coast_s
        (COAST_N samples); apogee only from COAST (Kalman). ``descent_mps``: DESCENT after apogee below -descent_mps.
      * ``accel_model_g``: kalman_accel's design adds this model error (g, rms) to the accelerometer's noise: the
        axial reading is taken as the vertical acceleration, which on a flight tilted by theta misreads a drag or
        thrust D by D (1 - cos theta) (0.06 D at 20 degrees) in boost and by D (1 - sin gamma), the whole drag, near
        apogee where the flight path gamma is far from vertical, plus scale errors; ``None``: 0.15 g for kalman_accel
        (0.05 g in issue 30's second round, 0 before it), 0 otherwise (docs/gain-design.md).
      * ``clip_s``: ACC_CLIP needs the accelerometer at its rail (32767) for this long in boost (CLIP_N samples; a
        thrust above the range holds it there for the burn, a shock for milliseconds); ``clip_drag_mps2``: after
        ACC_CLIP, a drag reading at or below this (A_DRAG = g + it, in the program's units) is "drag-low": no
        apogee evidence counts until the drag reading has been low for 2^k samples (recursive) or a 2^(k+1)-sample
        drag-low window has re-based the velocity on the barometer (kalman_accel; docs/firmware-spec.md §5, §6).
    Physical guards of issue 30 (docs/firmware-spec.md §6 steps 4, 8, 9; Kalman programs):
      * ``guards``: which are built, a bit mask (default 15, all): 1 **thrust** (kalman_accel: while PHASE is BOOST,
        i.e. until the raw accelerometer has read below -coast_mps2 for coast_s, the barometer is not fused),
        2 **gravity** (below zero the velocity bound VB falls by g dt per sample only, and apogee evidence needs
        X2 >= VB - fall_margin_mps: a falling rocket cannot accelerate downward faster than gravity), 4 **floor**
        (apogee evidence needs the filtered and the barometric height at least ``floor_m`` above the pad), 8
        **descent** (apogee evidence needs the barometer to read below the highest altitude it has read, or that
        reading to be ``descent_hold_s`` old: apogee is the top, after it the barometer reads lower).
        Switching one off is for ablation and teeth tests, not for flight.
      * ``floor_m`` (0..10,000 m, default 30): the floor; ``fall_margin_mps`` (default 15 m/s): how far the velocity
        estimate may lie below the free-fall bound (filter noise and lag) before its evidence is discarded.
      * ``descent_hold_s`` (0..60 s, default 4): how long the barometer's highest reading may hold apogee evidence
        back (DESC_N samples; bounds the wait on a barometer that stops moving). A sensor of L metres a count shows
        the descent within sqrt(2 L / g) of the top and holds its top count up to twice that: 4 s covers L <= 19.6 m.
      * ``quant_alt_m``: the Kalman design's barometer sigma is at least the barometer's quantization step /
        sqrt(12) in metres at this height above the pad (docs/gain-design.md "Quantization floor").
    """

    program: str = "kalman_baro"
    k: int = 7
    rounding: str = None  # type: ignore[assignment]  # None: the program's default, filled in by __post_init__
    baro_bits: int = 16
    baro_sign: int = -1
    units_per_metre: float = 3.5
    accel_counts_per_mps2: float = 2048.0 / 9.80665
    shift: int = 5
    threshold_q8: int = 64
    threshold_sigmas: float = 0.0
    gate_mps: float = 40.0
    noise_model: str = "accel_only"
    ratio: float = None  # type: ignore[assignment]  # None: the program's default, filled in by __post_init__
    baro_sigma: float = 2.0
    accel_sigma: float = 20.0
    accel_model_g: float = None  # type: ignore[assignment]  # None: the program's default (__post_init__)
    mach_lo_mps: float = 244.0
    mach_hi_mps: float = 366.0
    mach_innov_m: float = 30.0
    baro_min: int | None = None
    baro_max: int | None = None
    liftoff_mps: float = 30.0
    baro_pa_per_count: float | None = None
    baro_pa_at_zero: float | None = None
    alt_shift: int | None = None
    cal_p: int | None = None
    gate_sigmas: float = 6.0
    gate_hold_s: float = 0.1
    apogee_hold_s: float = 0.06
    transonic_r_factor: float = 100.0
    baro_kind: str = "adc"
    baro_rate_mps: float = 400.0
    mach_settle_s: float = 0.5
    mach_delay_s: float | None = None
    coast_mps2: float = 9.80665 / 2.0
    coast_s: float = 1.0
    drag_mps2: float = 5.0 * 9.80665
    thrust_mps2: float = 30.0 * 9.80665
    descent_mps: float = 5.0
    clip_drag_mps2: float = 0.25 * 9.80665
    clip_s: float = 0.25
    quant_alt_m: float = 3000.0
    guards: int = 15
    floor_m: float = 30.0
    fall_margin_mps: float = 15.0
    descent_hold_s: float = 4.0
    extra: dict[str, Any] = field(default_factory=dict, compare=False, hash=False)
    #: where the config came from (its file), for messages; not a setting (not in :meth:`to_dict`)
    source: str | None = field(default=None, compare=False, hash=False, repr=False)

    def __post_init__(self) -> None:
        own = PROGRAM_DEFAULTS.get(self.program, {}) if isinstance(self.program, str) else {}   # a bad one: validate
        for name, value in (COMMON_DEFAULTS | own).items():
            if getattr(self, name) is None:
                object.__setattr__(self, name, value)   # frozen: the one place a field is filled in
        self.validate()

    # ------------------------------------------------------------------ validation
    def validate(self) -> None:
        """Raise :class:`ConfigError` (a :class:`UserError`) for the first field whose value has the wrong type,
        lies outside its physical range (:data:`FIELDS`) or, combined with the others, would not fit the firmware's
        integers or its ROM. The message reads ``WHERE: key: what was wrong; what is allowed`` (WHERE = ``source``,
        the file the config came from, else "build config"); the value is echoed at most :data:`ECHO_CHARS`
        characters."""
        for name, rule in FIELDS.items():
            rule.check(name, getattr(self, name), self.source)
        if not isinstance(self.extra, dict):
            raise ConfigError("extra", f"{echo(self.extra)} is not a JSON object; allowed: free-form notes carried "
                              "into the vectors' build_config", self.source)
        if self.mach_lo_mps >= self.mach_hi_mps:
            raise ConfigError("mach_lo_mps", f"{echo(self.mach_lo_mps)} is not below mach_hi_mps="
                              f"{echo(self.mach_hi_mps)}; allowed: mach_lo_mps < mach_hi_mps", self.source)
        if self.pascal:
            if self.baro_sign != -1:
                raise ConfigError("baro_sign", "a pascal word falls as the rocket climbs; allowed: baro_sign -1",
                                  self.source)
            for name in ("baro_pa_per_count", "baro_pa_at_zero"):
                if getattr(self, name) is not None:
                    raise ConfigError(name, "a pascal barometer reports pascals (identity transfer function); "
                                      "allowed: null", self.source)
        tb = self.table_bits
        # the table has 2^(tb - alt_shift) + 1 nodes of 4 bytes: the 68000's 16 KB ROM holds at most
        # MAX_TABLE_NODES of them, and the table's least-squares fit (spec/alt_table.py) takes memory growing with
        # the square of the node count: the cap bounds both before any allocation
        lo_shift = max(1, tb - MAX_TABLE_SHIFT_SPAN)
        hi_shift = min(15, tb - 1)
        if self.alt_shift is not None and not lo_shift <= self.alt_shift <= hi_shift:
            raise ConfigError("alt_shift", f"{echo(self.alt_shift)} gives a table of 2^({tb}-alt_shift)+1 nodes "
                              f"outside 3..{MAX_TABLE_NODES:,} (the {MAX_TABLE_NODES:,}-node cap: 4 bytes a node must "
                              f"fit the 16 KB ROM); allowed: {lo_shift}..{hi_shift} or null for a {tb}-bit "
                              f"{'pascal word' if self.pascal else 'ADC'}", self.source)
        full = (1 << tb) - 1
        lo, hi = self.baro_range
        if not 0 <= lo <= hi <= full:
            key = "baro_min" if self.baro_min is not None and not 0 <= lo <= min(hi, full) else "baro_max"
            raise ConfigError(key, f"valid {'pascal' if self.pascal else 'ADC'} range [{lo}, {hi}] is empty or "
                              f"leaves the input; allowed: 0 <= baro_min <= baro_max <= {full}", self.source)
        for name in WHOLE_RANGE_FIELDS:
            value = getattr(self, name)
            if value > full + 1:
                raise ConfigError(name, f"{echo(value)} exceeds the {tb}-bit barometer's whole range; allowed: "
                                  f"(0, {full + 1}] for this sensor", self.source)
        self._check_fits_int32()

    def _check_fits_int32(self) -> None:
        """The velocity and acceleration thresholds times their state scale must fit the firmware's signed
        32-bit words (docs/gain-design.md): the recursive programs count velocity in accelerometer counts x
        samples (``accel_counts_per_mps2 * 2^k`` per m/s), so a fast gate on a fine accelerometer at a high k
        can overflow; the key named is the one the user wrote."""
        recursive = self.program in ("recursive", "recursive_seed_literal")
        v_scale = self.recursive_units_per_mps if recursive else KALMAN_UNITS_PER_MPS
        a_scale = self.accel_counts_per_mps2 if recursive else KALMAN_UNITS_PER_MPS
        what = "accel_counts_per_mps2 x 2^k" if recursive else "256 (Q24.8)"
        a_what = "accel_counts_per_mps2" if recursive else what
        checks = [("gate_mps", 0.0, self.recursive_units_per_mps, "m/s", "accel_counts_per_mps2 x 2^k"),
                  ("liftoff_mps", 0.0, v_scale, "m/s", what),
                  ("descent_mps", 0.0, v_scale, "m/s", what),
                  ("coast_mps2", 0.0, a_scale, "m/s^2", a_what),
                  ("clip_drag_mps2", _G0, a_scale, "m/s^2", a_what)]
        for name, offset, scale, unit, label in checks:
            value = (getattr(self, name) + offset) * scale
            if abs(value) >= 2**31 - 1:
                raise ConfigError(name, f"{echo(getattr(self, name))} {unit} x {scale:,.6g} state units per {unit} "
                                  f"({label}) = {value:.4g} does not fit the firmware's signed 32-bit word; allowed: "
                                  f"at most {(2**31 - 2) / scale - offset:.6g} {unit} with this sensor and k",
                                  self.source)

    # ------------------------------------------------------------------ derived
    @property
    def mach_delay(self) -> float:
        """The Mach delay in seconds: ``mach_delay_s``, or the program's default when it is ``None``."""
        if self.mach_delay_s is not None:
            return float(self.mach_delay_s)
        return BARO_MACH_DELAY_S if self.program == "kalman_baro" else 0.0

    @property
    def dt(self) -> float:
        """Sample period in seconds (2^-k)."""
        return 2.0 ** -self.k

    @property
    def recursive_units_per_mps(self) -> float:
        """The recursive programs' velocity scale: accelerometer counts x samples per m/s
        (``accel_counts_per_mps2 * 2^k``: VEL is the running sum of ``acc - ACC0``)."""
        return self.accel_counts_per_mps2 * 2.0**self.k

    @property
    def pascal(self) -> bool:
        """True for the pascal barometer kind (a digital sensor's 32-bit word, docs/firmware-spec.md §2)."""
        return self.baro_kind == "pascal"

    @property
    def table_bits(self) -> int:
        """Width of the words the altitude table covers: ``baro_bits`` (ADC) or :data:`PA_TABLE_BITS` (pascal)."""
        return PA_TABLE_BITS if self.pascal else self.baro_bits

    @property
    def baro_word_bits(self) -> int:
        """Width of the barometer register: ``baro_bits`` (ADC) or 32 (the pascal word)."""
        return 32 if self.pascal else self.baro_bits

    @property
    def baro_word_range(self) -> tuple[int, int]:
        """What the barometer input register can hold: 0..2^bits-1 (ADC) or the signed 32-bit range (pascal)."""
        return (-(1 << 31), (1 << 31) - 1) if self.pascal else (0, (1 << self.baro_bits) - 1)

    @property
    def baro_range(self) -> tuple[int, int]:
        """Valid raw barometer range (inclusive), with ``None`` bounds replaced by the ADC's full range (pascal:
        :data:`PA_DEFAULT_RANGE`)."""
        full = (1 << self.baro_bits) - 1
        dlo, dhi = PA_DEFAULT_RANGE if self.pascal else (0, full)
        lo = dlo if self.baro_min is None else self.baro_min
        hi = dhi if self.baro_max is None else self.baro_max
        return lo, hi

    @property
    def baro_transfer(self) -> tuple[float, float]:
        """``(pa_per_count, pa_at_zero)`` of the barometer with the TeleMetrum defaults filled in; the pascal
        kind's identity (1 Pa per count, 0 Pa at word 0: with ``baro_sign`` -1, ``P(c) = c``)."""
        if self.pascal:
            return 1.0, 0.0
        a = (TELEMETRUM_PA_PER_COUNT * 2.0 ** (16 - self.baro_bits) if self.baro_pa_per_count is None
             else float(self.baro_pa_per_count))
        b = TELEMETRUM_PA_AT_ZERO if self.baro_pa_at_zero is None else float(self.baro_pa_at_zero)
        return a, b

    @property
    def cal_p_bits(self) -> int:
        """The pad-calibration exponent with the default (a quarter second: min(8, max(0, k - 2))) filled in."""
        return min(8, max(0, self.k - 2)) if self.cal_p is None else int(self.cal_p)

    @property
    def alt_shift_bits(self) -> int:
        """The altitude-table segment shift with the default (ADC: bits - 9, at least 1; pascal:
        :data:`PA_DEFAULT_ALT_SHIFT`) filled in."""
        if self.alt_shift is not None:
            return int(self.alt_shift)
        return PA_DEFAULT_ALT_SHIFT if self.pascal else max(1, self.baro_bits - 9)

    def replace(self, **changes: Any) -> BuildConfig:
        """Return a copy with ``changes`` applied (validated)."""
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        """The config as a JSON-ready dict (``extra`` omitted when empty, ``baro_kind`` when ``adc``: the ADC
        builds' configs read as before the pascal kind existed)."""
        data = dataclasses.asdict(self)
        del data["source"]
        if not data["extra"]:
            del data["extra"]
        if data["baro_kind"] == "adc":
            del data["baro_kind"]
        return data

    @classmethod
    def from_dict(cls, data: dict[str, Any], where: str = "build config") -> BuildConfig:
        """Build a config from a dict, rejecting unknown keys with a message naming ``where`` and the key."""
        names = {f.name for f in dataclasses.fields(cls)} - {"source"}
        unknown = sorted(set(data) - names)
        if unknown:
            raise UserError(f"{where}: {echo(unknown[0])[:ECHO_CHARS]}: unknown field; known: "
                            f"{', '.join(sorted(names))}")
        return cls(**data, source=where)

    @classmethod
    def from_file(cls, path: str | Path) -> BuildConfig:
        """Read a config from a JSON file (see :func:`read_config_file`); errors name the file."""
        return from_sources(read_config_file(path), {}, str(path), _text_of(path))


#: Smallest tuning ratio R/q inside the documented input range (docs/numerics.md: no wrap-around above it).
MIN_RATIO: dict[str, float] = {"kalman_baro": 1e3, "kalman_accel": 10.0}


def check_documented_range(cfg: BuildConfig, where: str = "build config") -> None:
    """Refuse user settings outside the documented input range (docs/numerics.md "No wrap-around"): a Kalman
    tuning ratio R/q below :data:`MIN_RATIO` (gains so large that the states can wrap around int32)."""
    low = MIN_RATIO.get(cfg.program)
    if low is not None and cfg.ratio < low:
        raise ConfigError("ratio", f"{echo(cfg.ratio)} is below the documented range for {cfg.program}; allowed: "
                          f"R/q >= {low:g} (below it the integer states can wrap around, docs/numerics.md)", where)


def _line_of_key(text: str, key: str, occurrence: int) -> int:
    """1-based line of the ``occurrence``-th ``"key":`` in ``text`` (0 when not found)."""
    import re

    hits = [m.start() for m in re.finditer(re.escape(json.dumps(key)) + r"\s*:", text)]
    if len(hits) >= occurrence:
        return text.count("\n", 0, hits[occurrence - 1]) + 1
    return 0


def read_config_file(path: str | Path) -> dict[str, Any]:
    """The JSON object of a build-config file. UTF-8 (a byte-order mark is accepted); duplicate keys, a
    non-object top level, invalid JSON or undecodable bytes raise :class:`UserError` naming the file (and line)."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise UserError(f"{path}: no such build config file") from None
    except IsADirectoryError:
        raise UserError(f"{path}: is a folder, not a build config file") from None
    except OSError as exc:
        raise UserError(f"{path}: cannot read: {exc.strerror or exc}") from None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        raise UserError(f"{path}:{line}: not UTF-8 text (byte 0x{raw[exc.start]:02x})") from None
    dupes: list[str] = []

    def pairs(items: list[tuple[str, Any]]) -> dict[str, Any]:
        seen: dict[str, Any] = {}
        for key, value in items:
            if key in seen and not dupes:
                dupes.append(key)
            seen[key] = value
        return seen

    try:
        data = json.loads(text, object_pairs_hook=pairs)
    except json.JSONDecodeError as exc:
        raise UserError(f"{path}:{exc.lineno}:{exc.colno}: invalid JSON: {exc.msg}") from None
    except RecursionError:
        raise UserError(f"{path}: invalid JSON: nested too deeply") from None
    if dupes:
        line = _line_of_key(text, dupes[0], 2)
        raise UserError(f"{path}{f':{line}' if line else ''}: duplicate key {dupes[0]!r} (JSON keys must be unique)")
    if not isinstance(data, dict):
        raise UserError(f"{path}: a build config must be a JSON object")
    return data


def load_config(path: str | Path | None = None, overrides: dict[str, Any] | None = None,
                flag_names: dict[str, str] | None = None) -> BuildConfig:
    """The build config of a command: the file ``path`` (default: the :class:`BuildConfig` defaults), then the
    command-line ``overrides`` (``None`` values = not given) on top. One rule for every command: **flags override
    the file**, except that a flag naming a different ``program`` than the file is a contradiction and an error
    (a config file is tuned for the program it names). ``flag_names`` maps a field to its flag for messages
    (``{"program": "--firmware"}``). The result is validated and checked against the documented range
    (:func:`check_documented_range`)."""
    given = {key: value for key, value in (overrides or {}).items() if value is not None}
    names = {"program": "--program"} | (flag_names or {})
    where = str(path) if path is not None else "build config"
    data: dict[str, Any] = {}
    if path is not None:
        data = read_config_file(path)
        if "program" in data and "program" in given and data["program"] != given["program"]:
            raise UserError(f"{path}: program={data['program']!r} contradicts {names['program']} "
                            f"{given['program']}; a build config is tuned for one program: drop one of them")
    return from_sources(data, given, where, _text_of(path) if path is not None else None, names)


def _text_of(path: str | Path) -> str | None:
    try:
        return Path(path).read_bytes().decode("utf-8-sig")
    except (OSError, UnicodeDecodeError):
        return None


def from_sources(data: dict[str, Any], given: dict[str, Any], where: str, text: str | None = None,
                 flag_names: dict[str, str] | None = None, under: dict[str, Any] | None = None) -> BuildConfig:
    """The config of ``under`` (e.g. a tuning's fields), then the file's ``data``, then the flags ``given``, validated
    and checked against the documented range (:func:`check_documented_range`); a field that fails is reported where
    the user wrote it: ``FILE:LINE: key: ...`` for a key of the file (``text`` its contents, for the line), ``--flag:
    ...`` for a flag, ``WHERE: key: ...`` otherwise."""
    try:
        cfg = BuildConfig.from_dict((under or {}) | data | given, where=where)
        check_documented_range(cfg, where)
        return cfg
    except ConfigError as exc:
        if exc.key in given:
            flag = (flag_names or {}).get(exc.key, "--" + exc.key.replace("_", "-"))
            raise exc.at(f"{flag} (over {where})" if data else flag) from None
        if exc.key in data and text is not None:
            line = _line_of_key(text, exc.key, 1)
            raise exc.at(f"{where}:{line}" if line else where) from None
        raise

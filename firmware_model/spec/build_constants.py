"""Integer build constants of a firmware program (docs/firmware-spec.md §3), derived from a
:class:`~firmware_model.spec.config.BuildConfig`.

Every program (model, assembly via :meth:`FirmwareConstants.equates`, C port, golden vectors) reads its constants
from :func:`build_constants`. Conversions (documented in docs/gain-design.md), all rounded to the nearest integer
(ties away from zero):

* Kalman velocities (``V_LIFT`` for Kalman programs, ``MACH_VLO``, ``MACH_VHI``): ``v_mps * 256`` (Q24.8 m/s: the
  Kalman programs run in metres since the altitude table); ``MACH_E = mach_innov_m * 256`` (Q24.8 m, unused).
* Kalman field-ready constants: ``ALT_SHIFT``/``ALT_TABLE`` (:mod:`firmware_model.spec.alt_table`), ``CAL_P = cal_p``
  (default a quarter second), ``E_GATE = gate_sigmas * sqrt(S) * 256`` (S the steady-state innovation variance in m^2,
  :func:`firmware_model.spec.gain_design.innovation_sigma_m`; INT32_MAX when ``gate_sigmas`` = 0), ``GATE_N`` /
  ``APO_N`` = max(1, round(seconds * 2^k)).
* Recursive velocities (``V_LIFT`` for recursive programs, ``V_GATE``): ``v_mps * accel_counts_per_mps2 * 2^K``
  (accelerometer counts x samples: VEL is the running sum of ``acc - ACC0``).
* ``THR = max(threshold_q8, ceil(threshold_sigmas * 256 * baro_sigma * sqrt(a / (2 - a))))`` with a = 2^-S (the
  filtered word's noise: :func:`recursive_threshold`; ``threshold_sigmas`` 0, the default: ``threshold_q8``);
  ``BARO_MIN``/``BARO_MAX`` = ``cfg.baro_range`` (ADC counts, or pascals for the pascal kind); ``ROUND`` 0 floor /
  1 half_up; ``PASCAL`` = 1 for ``baro_kind`` pascal, else 0.
* Gains: :func:`quantize_gain` (16-bit mantissa, >= 15 significant bits).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

from firmware_model.runtime.errors import UserError
from firmware_model.spec.alt_table import table_of_config
from firmware_model.spec.atmosphere import G0
from firmware_model.spec.config import KALMAN_UNITS_PER_MPS, BuildConfig
from firmware_model.spec.fixed import INT32_MAX, INT32_MIN, MAX_SHIFT, QGain, _round_half_away, quantize_gain
from firmware_model.spec.gain_design import describe, float_gains, innovation_sigma_m


def recursive_threshold(cfg: BuildConfig, where: str = "config") -> int:
    """THR (Q24.8 counts): ``threshold_q8``, raised to ``threshold_sigmas`` standard deviations of the recursive
    filter's output noise when that is larger. EST = EST + (z - EST) 2^-S is a one-pole low-pass: white input noise
    of variance sigma^2 leaves sigma^2 a / (2 - a) in it (a = 2^-S), so EST's fall below its own running maximum
    by less than a few of its sigmas is what noise does on a flat top, not a descent (docs/firmware-spec.md §3)."""
    if cfg.threshold_sigmas == 0:
        return cfg.threshold_q8
    a = math.ldexp(1.0, -cfg.shift)
    noise_q8 = cfg.threshold_sigmas * 256.0 * cfg.baro_sigma * math.sqrt(a / (2.0 - a))
    if not noise_q8 < float(1 << 20):
        raise UserError(f"{where}: threshold_sigmas={cfg.threshold_sigmas!r} x baro_sigma={cfg.baro_sigma!r}: "
                        f"the threshold {noise_q8:.6g} is beyond 2^20 (Q24.8)")
    return max(cfg.threshold_q8, math.ceil(noise_q8))


def _round_int(name: str, value: float, where: str) -> int:
    """Round a physical threshold to the nearest integer (ties away from zero), checking it fits int32."""
    if not math.isfinite(value):
        raise UserError(f"{where}: {name}={value!r} is not finite")
    r = _round_half_away(Fraction(value))
    if not INT32_MIN <= r <= INT32_MAX:
        raise UserError(f"{where}: {name}={r} does not fit a signed 32-bit word (reduce the velocity/innovation "
                        "threshold or the units scale)")
    return r


@dataclass(frozen=True)
class FirmwareConstants:
    """The integer constants of one build (docs/firmware-spec.md §3). Velocities/innovations are integers in the
    units of the spec; gains are :class:`QGain`; ``float_gains`` are the unquantized design gains (same keys)."""

    program: str
    K: int
    ROUND: int
    BARO_SIGN: int
    S: int
    THR: int
    V_LIFT: int
    V_GATE: int
    gains: dict[str, QGain]
    MACH_VLO: int
    MACH_VHI: int
    MACH_E: int
    BARO_MIN: int
    BARO_MAX: int
    float_gains: dict[str, float] = field(default_factory=dict)
    ALT_SHIFT: int = 0
    ALT_TABLE: tuple[int, ...] = ()
    CAL_P: int = 0
    E_GATE: int = INT32_MAX
    GATE_N: int = 1
    APO_N: int = 1
    PASCAL: int = 0
    MACH_N: int = 1
    DLY_N: int = 0
    DV: int = 1
    A_COAST: int = 0
    COAST_N: int = 1
    V_DESC: int = 0
    DU: int = 1
    A_DRAG: int = 0
    CLIP_N: int = 1
    GUARDS: int = 0
    DG: int = 1
    V_FALL: int = 0
    H_FLOOR: int = 0
    DESC_N: int = 0
    H_STEP: int = INT32_MAX

    @property
    def ALT_N(self) -> int:
        """Number of altitude-table nodes (0 for the recursive programs)."""
        return len(self.ALT_TABLE)

    def data_source(self) -> str:
        """Assembly text of the build's ROM data (the altitude table ``ALT``, docs/firmware-spec.md §2a),
        appended to the program source by the build; empty for programs without a table."""
        if not self.ALT_TABLE:
            return ""
        lines = ["", "        section data", "        even",
                 f"* altitude table: {self.ALT_N} nodes, Q24.8 m, node j at count j << {self.ALT_SHIFT} "
                 "(generated by firmware_model.spec.alt_table)"]
        for j in range(0, self.ALT_N, 8):
            vals = ",".join(str(v) for v in self.ALT_TABLE[j:j + 8])
            lines.append(("ALT     dc.l    " if j == 0 else "        dc.l    ") + vals)
        return "\n".join(lines) + "\n"

    @property
    def rounding(self) -> str:
        """The rounding mode name (``floor`` or ``half_up``)."""
        return "half_up" if self.ROUND else "floor"

    def equates(self) -> dict[str, int]:
        """Assembler symbols (all int32): K ROUND BARO_SIGN S THR V_LIFT V_GATE MACH_VLO MACH_VHI MACH_E BARO_MIN
        BARO_MAX ALT_SHIFT ALT_N CAL_P E_GATE GATE_N APO_N PASCAL (1: the barometer is the 32-bit pascal word
        ``BARO_PA``) MACH_N DLY_N DV A_COAST COAST_N V_DESC DU A_DRAG CLIP_N (issue 20's flight logic) GUARDS DG
        V_FALL H_FLOOR DESC_N H_STEP (issue 30's physical guards) and, per gain, ``<NAME>_M`` and ``<NAME>_S``. (The
        table nodes themselves are ROM data: :meth:`data_source`.)"""
        eq = {name: int(getattr(self, name)) for name in
              ("K", "ROUND", "BARO_SIGN", "S", "THR", "V_LIFT", "V_GATE", "MACH_VLO", "MACH_VHI", "MACH_E",
               "BARO_MIN", "BARO_MAX", "ALT_SHIFT", "ALT_N", "CAL_P", "E_GATE", "GATE_N", "APO_N", "PASCAL",
               "MACH_N", "DLY_N", "DV", "A_COAST", "COAST_N", "V_DESC", "DU", "A_DRAG", "CLIP_N",
               "GUARDS", "DG", "V_FALL", "H_FLOOR", "DESC_N", "H_STEP")}
        for name, g in self.gains.items():
            eq[f"{name}_M"] = int(g.m)
            eq[f"{name}_S"] = int(g.s)
        for name, value in eq.items():
            if not INT32_MIN <= value <= INT32_MAX:
                raise UserError(f"equate {name}={value} does not fit a signed 32-bit word")
        return eq


def build_constants(cfg: BuildConfig) -> FirmwareConstants:
    """Derive the integer build constants of ``cfg`` (gain design + quantization + threshold conversion).

    Raises :class:`UserError` naming the config and field for a degenerate design, an unrepresentable gain or a
    threshold that does not fit int32."""
    if not isinstance(cfg, BuildConfig):
        raise UserError(f"build_constants needs a BuildConfig, got {type(cfg).__name__}")
    try:
        return _build_constants(cfg)
    except UserError as exc:
        if cfg.source is None:
            raise
        raise UserError(f"{cfg.source}: {exc}") from None  # the file the config came from, then the design's words


def _build_constants(cfg: BuildConfig) -> FirmwareConstants:
    where = describe(cfg)
    fg = float_gains(cfg)
    gains: dict[str, QGain] = {}
    for name, g in fg.items():
        if 0 < abs(g) < 2.0 ** (14 - MAX_SHIFT):
            # a gain below 2^-33 (issue 20: e.g. G31 of kalman_accel with a noise-free accelerometer and an 8-bit
            # barometer, ~1e-16): its correction is below any representable one; it is 0 (the error, <= 2^-33 per
            # unit of innovation, is in the model-vs-mirror bound), so such a sensor gets gains, not an error
            gains[name] = QGain(0, 0, float(g))
            continue
        try:
            gains[name] = quantize_gain(name, g)
        except UserError as exc:
            raise UserError(f"{where}: {exc}") from None
    kalman_v = KALMAN_UNITS_PER_MPS                    # Q24.8 m/s per m/s (the Kalman programs run in metres)
    rec_v = cfg.recursive_units_per_mps                # accel counts x samples per m/s
    recursive = cfg.program in ("recursive", "recursive_seed_literal")
    lo, hi = cfg.baro_range
    kalman: dict[str, Any] = {}

    def samples(name: str, seconds: float, low: int) -> int:
        return min(32767, max(low, _round_int(name, seconds * 2.0**cfg.k, where)))

    # issue 20: phases (coast, descent) in every program but the Schultz 2002 listing, in the program's units
    phases: dict[str, Any] = {} if cfg.program == "recursive_seed_literal" else dict(
        A_COAST=_round_int("A_COAST", cfg.coast_mps2 * (cfg.accel_counts_per_mps2 if recursive else kalman_v), where),
        COAST_N=samples("COAST_N", cfg.coast_s, 1),
        V_DESC=_round_int("V_DESC", cfg.descent_mps * (rec_v if recursive else kalman_v), where),
        A_DRAG=_round_int("A_DRAG", (G0 + cfg.clip_drag_mps2) * (cfg.accel_counts_per_mps2 if recursive else kalman_v),
                          where),
        CLIP_N=samples("CLIP_N", cfg.clip_s, 1))
    if not recursive:
        phases.update(DLY_N=samples("DLY_N", cfg.mach_delay, 0), MACH_N=samples("MACH_N", cfg.mach_settle_s, 1),
                      DV=max(1, _round_int("DV", (G0 + cfg.drag_mps2) * kalman_v * cfg.dt, where)),
                      DU=max(1, _round_int("DU", cfg.thrust_mps2 * kalman_v * cfg.dt, where)),
                      # issue 30: the physical guards (docs/firmware-spec.md §6 steps 4, 8, 9)
                      GUARDS=cfg.guards,
                      DG=max(1, _round_int("DG", G0 * kalman_v * cfg.dt, where)),
                      V_FALL=_round_int("V_FALL", cfg.fall_margin_mps * kalman_v, where),
                      H_FLOOR=_round_int("H_FLOOR", cfg.floor_m * 256.0, where),
                      DESC_N=min(65535, _round_int("DESC_N", cfg.descent_hold_s * 2.0**cfg.k, where)),
                      # issue 30, third round: kalman_accel re-bases X1 only on a steady sample (§6 step 4)
                      H_STEP=INT32_MAX if cfg.gate_sigmas == 0 else max(1, _round_int(
                          "H_STEP", (cfg.baro_rate_mps * cfg.dt + cfg.gate_sigmas * math.sqrt(2.0) * cfg.baro_sigma
                                     / cfg.units_per_metre) * 256.0, where)))
    if cfg.program == "recursive":
        # §5 steps 1, 5, 6: pad calibration of ACC0, the barometer rate gate (raw counts per sample), the apogee
        # evidence after an accelerometer clip
        d_gate = INT32_MAX if cfg.gate_sigmas == 0 else max(1, _round_int(
            "E_GATE", cfg.baro_rate_mps * cfg.units_per_metre * cfg.dt
            + cfg.gate_sigmas * math.sqrt(2.0) * cfg.baro_sigma, where))
        kalman = dict(CAL_P=cfg.cal_p_bits, E_GATE=d_gate,
                      GATE_N=min(32767, max(1, _round_int("GATE_N", cfg.gate_hold_s * 2.0**cfg.k, where))),
                      APO_N=min(32767, max(1, _round_int("APO_N", cfg.apogee_hold_s * 2.0**cfg.k, where))))
    if not recursive:

        table = table_of_config(cfg)
        e_gate = INT32_MAX if cfg.gate_sigmas == 0 else _round_int(
            "E_GATE", cfg.gate_sigmas * innovation_sigma_m(cfg) * 256.0, where)
        kalman = dict(ALT_SHIFT=table.shift, ALT_TABLE=table.nodes, CAL_P=cfg.cal_p_bits, E_GATE=e_gate,
                      GATE_N=min(32767, max(1, _round_int("GATE_N", cfg.gate_hold_s * 2.0**cfg.k, where))),
                      APO_N=min(32767, max(1, _round_int("APO_N", cfg.apogee_hold_s * 2.0**cfg.k, where))))
    return FirmwareConstants(
        program=cfg.program,
        K=cfg.k,
        ROUND=1 if cfg.rounding == "half_up" else 0,
        BARO_SIGN=cfg.baro_sign,
        S=cfg.shift,
        THR=recursive_threshold(cfg, where),
        V_LIFT=_round_int("V_LIFT", cfg.liftoff_mps * (rec_v if recursive else kalman_v), where),
        V_GATE=_round_int("V_GATE", cfg.gate_mps * rec_v, where),
        gains=gains,
        MACH_VLO=_round_int("MACH_VLO", cfg.mach_lo_mps * kalman_v, where),
        MACH_VHI=_round_int("MACH_VHI", cfg.mach_hi_mps * kalman_v, where),
        MACH_E=_round_int("MACH_E", cfg.mach_innov_m * kalman_v, where),
        BARO_MIN=lo,
        BARO_MAX=hi,
        float_gains=fg,
        PASCAL=1 if cfg.pascal else 0,
        **kalman,
        **phases,
    )

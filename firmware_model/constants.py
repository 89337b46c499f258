"""Integer build constants of a firmware program (docs/firmware-spec.md §3), derived from a
:class:`~firmware_model.config.BuildConfig`.

Every program (model, assembly via :meth:`FirmwareConstants.equates`, C port, golden vectors) reads its constants
from :func:`build_constants`. Conversions (documented in docs/gain-design.md), all rounded to the nearest integer
(ties away from zero):

* Kalman velocities (``V_LIFT`` for Kalman programs, ``MACH_VLO``, ``MACH_VHI``): ``v_mps * 256`` (Q24.8 m/s: the
  Kalman programs run in metres since the altitude table); ``MACH_E = mach_innov_m * 256`` (Q24.8 m, unused).
* Kalman field-ready constants: ``ALT_SHIFT``/``ALT_TABLE`` (:mod:`firmware_model.alt_table`), ``CAL_P = cal_p`` (default a quarter second),
  ``E_GATE = gate_sigmas * sqrt(S) * 256`` (S the steady-state innovation variance in m^2,
  :func:`firmware_model.design.innovation_sigma_m`; INT32_MAX when ``gate_sigmas`` = 0), ``GATE_N`` /
  ``APO_N`` = max(1, round(seconds * 2^k)).
* Recursive velocities (``V_LIFT`` for recursive programs, ``V_GATE``): ``v_mps * accel_counts_per_mps2 * 2^K``
  (accelerometer counts x samples: VEL is the running sum of ``acc - ACC0``).
* ``THR = threshold_q8``; ``BARO_MIN``/``BARO_MAX`` = ``cfg.baro_range`` (ADC counts, or pascals for the pascal
  kind); ``ROUND`` 0 floor / 1 half_up; ``PASCAL`` = 1 for ``baro_kind`` pascal, else 0.
* Gains: :func:`quantize_gain` (16-bit mantissa, >= 15 significant bits).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from fractions import Fraction

from firmware_model.config import BuildConfig
from firmware_model.design import describe, float_gains
from firmware_model.errors import UserError

#: Largest gain shift (docs/firmware-spec.md §1 mulg).
MAX_SHIFT: int = 47
#: Mantissa magnitude range for >= 15 significant bits.
M_MIN: int = 1 << 14
M_MAX: int = (1 << 15) - 1
INT32_MIN: int = -(1 << 31)
INT32_MAX: int = (1 << 31) - 1
#: Standard gravity (m/s^2): the plausibility bound DV is (G0 + drag_mps2) * dt.
G0: float = 9.80665


@dataclass(frozen=True)
class QGain:
    """A quantized constant ``g = m / 2**s`` (docs/firmware-spec.md §1 mulg): ``m`` a signed 16-bit mantissa,
    ``s`` a right shift 0..47, ``target`` the float value it approximates."""

    m: int
    s: int
    target: float

    def __post_init__(self) -> None:
        if not -32768 <= self.m <= 32767 or not 0 <= self.s <= MAX_SHIFT:
            raise UserError(f"QGain(m={self.m}, s={self.s}): need -32768 <= m <= 32767 and 0 <= s <= {MAX_SHIFT}")

    @property
    def value(self) -> float:
        """The represented value m / 2^s (exact in float64)."""
        return math.ldexp(float(self.m), -self.s)

    @property
    def exact(self) -> Fraction:
        """The represented value as an exact fraction."""
        return Fraction(self.m, 1 << self.s)

    @property
    def rel_error(self) -> float:
        """(value - target) / target, 0 when target == 0."""
        if self.target == 0:
            return 0.0
        return float((self.exact - Fraction(self.target)) / Fraction(self.target))


def quantize_gain(name: str, g: float) -> QGain:
    """Quantize ``g`` to ``m / 2^s`` with ``2^14 <= |m| <= 2^15 - 1`` (>= 15 significant bits, so
    ``|rel_error| <= 2^-15``), ``m = round(g * 2^s)`` (nearest; exact). ``g == 0`` gives (0, 0).

    Raises :class:`UserError` naming the gain when it is not finite, too large (|g| >= 32767.5, which would need a
    negative shift) or too small (|g| < 2^-33, which would need a shift above 47 for 15 significant bits).
    """
    if not math.isfinite(g):
        raise UserError(f"gain {name}={g!r}: not a finite number")
    if g == 0:
        return QGain(0, 0, 0.0)
    e = math.frexp(abs(g))[1] - 1            # 2^e <= |g| < 2^(e+1)
    s = 14 - e                               # |g| * 2^s in [2^14, 2^15)
    exact = Fraction(g) * (Fraction(2) ** s) if s >= 0 else Fraction(g) / (1 << -s)
    m = _round_half_away(exact)
    if abs(m) > M_MAX:                       # rounded up to 2^15: one bit less of shift, m = +-2^14
        s -= 1
        m = _round_half_away(exact / 2)
    if s < 0:
        raise UserError(f"gain {name}={g!r}: too large for a 16-bit mantissa with shift >= 0 (|g| must be < 32767.5)")
    if s > MAX_SHIFT:
        raise UserError(f"gain {name}={g!r}: too small for 15 significant bits with shift <= {MAX_SHIFT} "
                        f"(|g| must be >= 2^{14 - MAX_SHIFT})")
    return QGain(int(m), int(s), float(g))


def _round_half_away(x: Fraction) -> int:
    """Nearest integer to an exact fraction, ties away from zero."""
    sign = -1 if x < 0 else 1
    return sign * math.floor(abs(x) + Fraction(1, 2))


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
                 "(generated by firmware_model.alt_table)"]
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
        ``BARO_PA``) MACH_N DLY_N DV A_COAST COAST_N V_DESC DU (issue 20's flight logic) and, per gain,
        ``<NAME>_M`` and ``<NAME>_S``. (The
        table nodes themselves are ROM data: :meth:`data_source`.)"""
        eq = {name: int(getattr(self, name)) for name in
              ("K", "ROUND", "BARO_SIGN", "S", "THR", "V_LIFT", "V_GATE", "MACH_VLO", "MACH_VHI", "MACH_E",
               "BARO_MIN", "BARO_MAX", "ALT_SHIFT", "ALT_N", "CAL_P", "E_GATE", "GATE_N", "APO_N", "PASCAL",
               "MACH_N", "DLY_N", "DV", "A_COAST", "COAST_N", "V_DESC", "DU")}
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
    kalman_v = 256.0                                   # Q24.8 m/s per m/s (the Kalman programs run in metres)
    rec_v = cfg.accel_counts_per_mps2 * 2.0**cfg.k     # accel counts x samples per m/s
    recursive = cfg.program in ("recursive", "recursive_seed_literal")
    lo, hi = cfg.baro_range
    kalman = {}

    def samples(name: str, seconds: float, low: int) -> int:
        return min(32767, max(low, _round_int(name, seconds * 2.0**cfg.k, where)))

    # issue 20: phases (coast, descent) in every program but the seed listing, in the program's units
    phases = {} if cfg.program == "recursive_seed_literal" else dict(
        A_COAST=_round_int("A_COAST", cfg.coast_mps2 * (cfg.accel_counts_per_mps2 if recursive else kalman_v), where),
        COAST_N=samples("COAST_N", cfg.coast_s, 1),
        V_DESC=_round_int("V_DESC", cfg.descent_mps * (rec_v if recursive else kalman_v), where))
    if not recursive:
        phases.update(DLY_N=samples("DLY_N", cfg.mach_delay_s, 0), MACH_N=samples("MACH_N", cfg.mach_settle_s, 1),
                      DV=max(1, _round_int("DV", (G0 + cfg.drag_mps2) * kalman_v * cfg.dt, where)),
                      DU=max(1, _round_int("DU", cfg.thrust_mps2 * kalman_v * cfg.dt, where)))
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
        from firmware_model.alt_table import table_of_config
        from firmware_model.design import innovation_sigma_m

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
        THR=cfg.threshold_q8,
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

"""The design report of a build: the float design, the quantized integer constants and what quantization does to
the filter (closed-loop poles), as one JSON-ready dict (``fwemu design --json``).

It sits above both :mod:`firmware_model.spec.gain_design` (float gains) and
:mod:`firmware_model.spec.build_constants` (integer constants, which import the design), so neither of those imports
the other back.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from firmware_model.spec.build_constants import build_constants
from firmware_model.spec.config import BuildConfig
from firmware_model.spec.gain_design import GAIN_NAMES_ACCEL, GAIN_NAMES_BARO, closed_loop_poles, design_config


def _poles_json(poles: np.ndarray) -> list[dict[str, float]]:
    return [{"re": float(p.real), "im": float(p.imag),
             "abs": math.sqrt(float(p.real) * float(p.real) + float(p.imag) * float(p.imag))} for p in poles]


def design_report(cfg: BuildConfig) -> dict[str, Any]:
    """A JSON-ready report of the build: config, float gains, quantized gains (m, s, value, rel_error), equates,
    the closed-loop poles of the float and of the quantized design, and the steady-state standard deviations
    (a posteriori, in units, units/s, units/s^2)."""
    consts = build_constants(cfg)
    report: dict[str, Any] = {
        "config": cfg.to_dict(),
        "dt": cfg.dt,
        "float_gains": dict(consts.float_gains),
        "gains": {name: {"m": g.m, "s": g.s, "value": g.value, "target": g.target, "rel_error": g.rel_error}
                  for name, g in consts.gains.items()},
        "equates": consts.equates(),
    }
    if cfg.program in ("kalman_baro", "kalman_accel"):
        ss = design_config(cfg)
        cols = [GAIN_NAMES_BARO] + ([GAIN_NAMES_ACCEL] if cfg.program == "kalman_accel" else [])
        Kq = np.array([[consts.gains[col[i]].value for col in cols] for i in range(3)])
        report["noise"] = {"model": cfg.noise_model, "q": cfg.baro_sigma**2 / cfg.ratio,
                           "R": ss.R.tolist(), "Q": ss.Q.tolist()}
        report["poles"] = _poles_json(ss.poles)
        report["poles_quantized"] = _poles_json(closed_loop_poles(ss, Kq))
        report["sigma_post"] = [float(math.sqrt(max(v, 0.0))) for v in np.diag(ss.P_post)]
        report["doublings"] = ss.iterations
        report["residual"] = ss.residual
    return report

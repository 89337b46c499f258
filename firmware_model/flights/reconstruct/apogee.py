"""The reference apogee from a reconstruction: the moment the smoothed vertical velocity crosses zero.

:func:`velocity_zero_crossing`: the downward zero crossing of ``vz`` nearest the highest estimated altitude,
linearly interpolated between samples; its sigma is ``sigma_vz / |a_z|`` (a velocity error dv moves the crossing
by dv / |a_z|), with ``sigma_vz`` the estimate's own sigma at the crossing and ``a_z`` the slope of ``vz`` over
+-0.25 s around it (about -g at a free apogee). The altitude at that moment and its sigma come with it.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from firmware_model.runtime.errors import UserError


@dataclass(frozen=True)
class ApogeeEstimate:
    time_s: float
    sigma_s: float
    altitude_m: float
    sigma_altitude_m: float
    vz_slope_mps2: float
    source: str

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def velocity_zero_crossing(t: np.ndarray, z: np.ndarray, vz: np.ndarray, sig_z: np.ndarray, sig_vz: np.ndarray,
                           source: str = "smoother", where: str = "flight",
                           before_s: float | None = None) -> ApogeeEstimate:
    """``before_s``: a recovery event (a charge, a shock); crossings before it are preferred, the highest point
    among them, because after it the log's section is kicked and its barometer sees the ejection's pressure (a
    section that climbs a few metres after the charge is not the rocket's apogee)."""
    t = np.asarray(t, float)
    vz = np.asarray(vz, float)
    z = np.asarray(z, float)
    down = np.nonzero((vz[:-1] > 0) & (vz[1:] <= 0))[0]
    if down.size == 0:
        raise UserError(f"{where}: the reconstructed vertical velocity never crosses zero downwards (no apogee)")
    if before_s is not None and np.any(t[down + 1] <= before_s):
        down = down[t[down + 1] <= before_s]
        ip = int(np.argmax(np.where(t <= before_s, z, -np.inf)))
    else:
        ip = int(np.argmax(z))
    k = int(down[np.argmin(np.abs(down - ip))])
    frac = vz[k] / (vz[k] - vz[k + 1])
    tc = float(t[k] + frac * (t[k + 1] - t[k]))
    near = np.abs(t - tc) <= 0.25
    if before_s is not None and tc <= before_s:
        near &= t <= before_s                       # the slope of the free flight, not of the kick after it
    if near.sum() >= 3:
        slope = float(np.polyfit(t[near] - tc, vz[near], 1)[0])
    else:
        slope = float((vz[k + 1] - vz[k]) / (t[k + 1] - t[k]))
    if slope >= 0:
        raise UserError(f"{where}: vertical velocity at its zero crossing is not decreasing (slope {slope:.2f})")
    sv = float(sig_vz[k] + frac * (sig_vz[k + 1] - sig_vz[k]))
    alt = float(z[k] + frac * (z[k + 1] - z[k]))
    sz = float(sig_z[k] + frac * (sig_z[k + 1] - sig_z[k]))
    return ApogeeEstimate(time_s=tc, sigma_s=sv / abs(slope), altitude_m=alt, sigma_altitude_m=sz,
                          vz_slope_mps2=slope, source=source)

"""The smoother's reference apogee for ``fwemu evaluate --reference smoother|auto`` (docs/reconstruction.md).

:func:`smoother_reference` reconstructs a real log (:func:`~.run.reconstruct_log`, from the record's source file)
and returns the time its smoothed vertical velocity crosses zero, with ``2 sigma`` as the uncertainty, beside the
barometric parabola's (:func:`firmware_model.flights.reference.apogee_reference.reference_apogee`). The two *disagree*
when their
times differ by more than the parabola's uncertainty plus the smoother's 2 sigma.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from firmware_model.runtime.errors import UserError
from firmware_model.flights.record import FlightRecord
from firmware_model.flights.reconstruct.run import reconstruct_log
from firmware_model.flights.reference.apogee_reference import ReferenceApogee, reference_apogee

MODES: tuple[str, ...] = ("parabola", "smoother", "auto")


@dataclass(frozen=True)
class SmootherReference:
    time_s: float
    altitude_m: float
    uncertainty_s: float        # 2 sigma
    mode: str                   # the reconstruction's mode (vertical-imu, vertical-axial, full)
    parabola: ReferenceApogee | None
    disagree: bool
    note: str


def smoother_reference(record: FlightRecord) -> SmootherReference:
    src = record.provenance.get("source")
    if not src or not Path(str(src)).is_file():
        raise UserError(f"{record.name}: the smoother reference needs the flight's log file (source {src!r})")
    if not record.has_accel:
        raise UserError(f"{src}: no accelerometer: the smoother reference needs one (use --reference parabola)")
    r = reconstruct_log(src, record.provenance.get("format"))
    unc = 2.0 * r.apogee.sigma_s
    try:
        par = reference_apogee(record)
    except UserError:
        par = None
    disagree = par is not None and abs(r.apogee.time_s - par.time_s) > par.uncertainty_s + unc
    note = f"smoother ({r.mode}) {r.apogee.time_s:.3f} +-{unc:.3f} s (2 sigma)"
    if par is not None:
        note += (f"; parabola {par.time_s:.3f} +-{par.uncertainty_s:.3f} s: "
                 + (f"DISAGREE by {r.apogee.time_s - par.time_s:+.3f} s" if disagree else "agree"))
    return SmootherReference(time_s=r.apogee.time_s, altitude_m=r.apogee.altitude_m, uncertainty_s=unc,
                             mode=r.mode, parabola=par, disagree=disagree, note=note)

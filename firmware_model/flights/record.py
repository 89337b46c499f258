"""The flight record: one flight in SI units, whatever it came from (docs/flights.md).

Every reader and simulator returns a :class:`FlightRecord`; sensor models, resampling, the reference apogee and the
evaluation take one. Arrays are float64, one value per log row, on the record's own (possibly irregular) time axis;
a quantity the source does not have is ``None``, never zeros. Missing single values inside a present column are NaN.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from firmware_model.runtime.errors import UserError


#: Static pressures a flight log may hold (Pa): above 0, at most two atmospheres.
PRESSURE_RANGE_PA: tuple[float, float] = (0.0, 200_000.0)
#: The largest specific force a flight log may hold (m/s^2): 10,000 g, past any motor or ejection shock.
MAX_ACCEL_MPS2: float = 10_000.0 * 9.80665


@dataclass(frozen=True)
class Truth:
    """What really happened, where known (simulators): arrays on the record's time axis plus the true apogee.

    ``altitude_m`` is geopotential altitude above the launch site (AGL, m), ``velocity_mps`` vertical velocity (m/s,
    up positive), ``accel_mps2`` vertical kinematic acceleration (m/s^2, up positive; -g in free fall).
    ``apogee_time_s`` / ``apogee_altitude_m``: time (on the record's axis) and altitude AGL of the true apogee.
    """

    altitude_m: np.ndarray | None = None
    velocity_mps: np.ndarray | None = None
    accel_mps2: np.ndarray | None = None
    apogee_time_s: float | None = None
    apogee_altitude_m: float | None = None


@dataclass(frozen=True)
class FlightRecord:
    """One flight.

    * ``name``: short identifier (file stem or simulator case name).
    * ``time_s``: (n,) strictly increasing seconds; 0 is the log's own origin (AltosUI: boost), so it may start < 0.
    * ``pressure_pa``: (n,) static pressure as the barometer saw it (Pa), NaN where a row has none.
    * ``temperature_c``: (n,) or None.
    * ``accel_mps2``: (n,) or None: **axial specific force** (what an accelerometer along the rocket's axis reads:
      about +9.81 on the pad, about -0 in free fall after burnout with no drag), m/s^2.
    * ``accel_counts``: (n,) raw accelerometer counts, or None; with ``accel_calibration`` =
      ``{"counts_per_mps2": .., "offset_counts": ..}`` saying how counts map to specific force.
    * ``ground_pressure_pa``: pressure at the launch site if the source states it (else estimated from the pad).
    * ``truth``: a :class:`Truth` (simulators), or None (real logs).
    * ``events``: the log's own flight-computer events, name -> time (s on the record's axis), e.g.
      ``{"altos_apogee": 21.37}`` (AltosUI: the first row in state ``drogue``), ``{"altos_boost": 0.0}``.
    * ``provenance``: JSON-ready dict: ``source`` (file path or simulator), ``format``, ``licence``, and any reader
      notes (e.g. rate changes, repeated timestamps dropped, empty fields); ``own_computer``: the name of the
      flight computer that wrote the log when it declared an apogee (``events["own_apogee"]``);
      ``synthetic_baro``: True when ``pressure_pa`` was made from an altitude column (standard atmosphere).
    * ``row_lines``: (n,) the file's 1-based line number of each row, or None (simulators), so that later stages
      (resampling) can name a line.
    """

    name: str
    time_s: np.ndarray
    pressure_pa: np.ndarray
    accel_mps2: np.ndarray | None = None
    temperature_c: np.ndarray | None = None
    accel_counts: np.ndarray | None = None
    accel_calibration: dict[str, float] | None = None
    ground_pressure_pa: float | None = None
    truth: Truth | None = None
    events: dict[str, float] = field(default_factory=dict)
    provenance: dict[str, Any] = field(default_factory=dict)
    row_lines: np.ndarray | None = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        t = np.asarray(self.time_s, dtype=np.float64)
        n = t.shape[0] if t.ndim == 1 else -1
        where = self.provenance.get("source", self.name)
        if t.ndim != 1 or n < 2:
            raise UserError(f"{where}: a flight needs at least 2 samples, got {t.size}")
        if not np.all(np.isfinite(t)):
            raise UserError(f"{where}: time is not finite at row {int(np.argmin(np.isfinite(t)))}")
        bad = np.nonzero(np.diff(t) <= 0)[0]
        if bad.size:
            raise UserError(f"{where}: time does not increase at row {int(bad[0]) + 1} "
                            f"({t[bad[0]]} -> {t[bad[0] + 1]})")
        for name in ("pressure_pa", "accel_mps2", "temperature_c", "accel_counts"):
            arr = getattr(self, name)
            if arr is not None and np.asarray(arr).shape != (n,):
                raise UserError(f"{where}: {name} has shape {np.asarray(arr).shape}, time has ({n},)")
        self._check_plausible(t, where)

    def _check_plausible(self, t: np.ndarray, where: str) -> None:
        """Issue 33: a pressure outside :data:`PRESSURE_RANGE_PA` (1e308 Pa reached the barometer model) or an
        acceleration beyond :data:`MAX_ACCEL_MPS2` is an error naming the file's line (``row_lines``) or the row. (A
        clock jump is judged later, where the flight is known: :mod:`firmware_model.flights.inputs.firmware_inputs`
        refuses one before apogee naming its line and ends the stream at one after it, with a note: docs/flights.md
        "Gaps".)"""
        def at(i: int) -> str:
            if self.row_lines is not None and len(self.row_lines) == len(t):
                return f"{where}:{int(self.row_lines[i])}"
            return f"{where}: row {i}"

        if self.pressure_pa is not None:
            p = np.asarray(self.pressure_pa, dtype=np.float64)
            lo, hi = PRESSURE_RANGE_PA
            bad = np.nonzero(~np.isnan(p) & ~((p > lo) & (p <= hi)))[0]
            if bad.size:
                i = int(bad[0])
                how = (" (from the altitude column through the standard atmosphere)"
                       if self.provenance.get("synthetic_baro") else "")
                raise UserError(f"{at(i)}: pressure: {p[i]:.6g} Pa{how} is out of range; allowed: more than "
                                f"{lo:g} and at most {hi:,.0f} Pa")
        if self.accel_mps2 is not None:
            a = np.asarray(self.accel_mps2, dtype=np.float64)
            bad = np.nonzero(~np.isnan(a) & ~(np.abs(a) <= MAX_ACCEL_MPS2))[0]
            if bad.size:
                i = int(bad[0])
                raise UserError(f"{at(i)}: acceleration: {a[i]:.6g} m/s^2 is out of range; allowed: at most "
                                f"{MAX_ACCEL_MPS2:,.0f} m/s^2 (10,000 g) either way")

    def own_apogee(self) -> tuple[str, float] | None:
        """The log's own flight computer's apogee: ``(computer, time_s)``, or None when the log has none.
        AltosUI / .eeprom: AltOS's first ``drogue`` state (``events["altos_apogee"]``); other readers put theirs in
        ``events["own_apogee"]`` and name the computer in ``provenance["own_computer"]``."""
        ev = self.events or {}
        if "own_apogee" in ev:
            return str(self.provenance.get("own_computer", "own computer")), float(ev["own_apogee"])
        if "altos_apogee" in ev:
            return "AltOS", float(ev["altos_apogee"])
        return None

    @property
    def n(self) -> int:
        """Number of rows."""
        return int(np.asarray(self.time_s).shape[0])

    @property
    def has_accel(self) -> bool:
        """True when the record has an accelerometer (specific force or counts)."""
        return self.accel_mps2 is not None or self.accel_counts is not None

    def specific_force_mps2(self) -> np.ndarray | None:
        """Axial specific force (m/s^2): ``accel_mps2``, else counts through ``accel_calibration``, else None."""
        if self.accel_mps2 is not None:
            return np.asarray(self.accel_mps2, dtype=np.float64)
        if self.accel_counts is None:
            return None
        cal = self.accel_calibration or {}
        if "counts_per_mps2" not in cal:
            raise UserError(f"{self.name}: accelerometer counts without a calibration (counts_per_mps2)")
        counts = np.asarray(self.accel_counts, dtype=np.float64)
        return (counts - cal.get("offset_counts", 0.0)) / cal["counts_per_mps2"]

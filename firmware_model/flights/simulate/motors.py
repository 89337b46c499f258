"""Motor thrust curves and the drag curve shipped with the simulators (``firmware_model/flights/simulate/data/``).

The files are verbatim copies from the RocketPy repository (MIT; see ``data/README.md`` for each file's path and
commit). A motor is a :class:`ThrustCurve`: a piecewise-linear thrust table from ignition (t = 0, thrust 0) to
burnout (thrust 0), with its propellant mass; both simulators use the same table, and the 1-DOF model loses mass
in proportion to the impulse delivered so far (``propellant_left = m_prop * (1 - I(t) / I_total)``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path

import numpy as np

from firmware_model.runtime.errors import UserError

DATA_DIR: Path = Path(__file__).resolve().parent / "data"

#: Motor name -> file in ``data/`` (RASP .eng format).
MOTOR_FILES: dict[str, str] = {
    "K400C": "AeroTech_K400C.eng",
    "K828FJ": "AeroTech_K828FJ.eng",
    "L1350": "Cesaroni_4263L1350-P.eng",
    "M1670": "Cesaroni_M1670.eng",
    "M2245": "Cesaroni_9977M2245-P.eng",
    "M6400": "Cesaroni_8634M6400-P.eng",
}

#: The default power-off drag curve (Mach, Cd): RocketPy's "Calisto" example rocket.
DRAG_FILE: str = "calisto_power_off_drag.csv"


@dataclass(frozen=True, eq=False)
class ThrustCurve:
    """A solid motor: ``time_s`` (from ignition, starts at 0, strictly increasing) and ``thrust_n`` (>= 0, 0 at
    both ends), ``propellant_mass_kg``, ``total_mass_kg`` (loaded), ``diameter_m``, ``length_m``, and where it
    came from (``source``, ``licence``)."""

    name: str
    time_s: np.ndarray
    thrust_n: np.ndarray
    propellant_mass_kg: float
    total_mass_kg: float
    diameter_m: float
    length_m: float
    source: str = ""
    licence: str = ""

    @property
    def burn_time_s(self) -> float:
        """Time of the last table point (thrust 0)."""
        return float(self.time_s[-1])

    @property
    def total_impulse_ns(self) -> float:
        """Total impulse (N s) of the piecewise-linear table."""
        return float(np.sum(0.5 * (self.thrust_n[1:] + self.thrust_n[:-1]) * np.diff(self.time_s)))

    @property
    def dry_mass_kg(self) -> float:
        """Empty motor (case) mass."""
        return self.total_mass_kg - self.propellant_mass_kg

    def scaled(self, thrust: float = 1.0, time: float = 1.0, name: str | None = None) -> "ThrustCurve":
        """The same shape with thrust multiplied by ``thrust`` and time by ``time``; propellant (and case) mass
        scale with the impulse (``thrust * time``), so the specific impulse is kept. A documented synthetic motor
        for parameter sweeps; its ``source`` says what it was derived from."""
        if not (thrust > 0 and time > 0):
            raise UserError(f"motor {self.name}: scale factors must be > 0 (thrust={thrust}, time={time})")
        f = thrust * time
        return replace(self, name=name or f"{self.name}x{thrust:g}/{time:g}", time_s=self.time_s * time,
                       thrust_n=self.thrust_n * thrust, propellant_mass_kg=self.propellant_mass_kg * f,
                       total_mass_kg=self.total_mass_kg * f,
                       source=f"{self.source}; scaled: thrust x{thrust:g}, time x{time:g}")

    def thrust_at(self, t) -> np.ndarray:
        """Thrust (N) at time(s) ``t`` since ignition (0 before ignition and after burnout)."""
        return np.interp(t, self.time_s, self.thrust_n, left=0.0, right=0.0)

    def impulse_at(self, t) -> np.ndarray:
        """Impulse delivered (N s) by time(s) ``t``: the exact integral of the piecewise-linear table."""
        t = np.asarray(t, dtype=np.float64)
        tk, fk = self.time_s, self.thrust_n
        cum = np.concatenate([[0.0], np.cumsum(0.5 * (fk[1:] + fk[:-1]) * np.diff(tk))])
        tc = np.clip(t, tk[0], tk[-1])
        i = np.clip(np.searchsorted(tk, tc, side="right") - 1, 0, len(tk) - 2)
        d = tc - tk[i]
        slope = (fk[i + 1] - fk[i]) / (tk[i + 1] - tk[i])
        return cum[i] + fk[i] * d + 0.5 * slope * d * d

    def propellant_at(self, t) -> np.ndarray:
        """Propellant mass left (kg) at time(s) ``t``: proportional to the impulse still to be delivered."""
        t = np.asarray(t, dtype=np.float64)
        left = self.propellant_mass_kg * (1.0 - self.impulse_at(t) / self.total_impulse_ns)
        return np.where(t >= self.burn_time_s, 0.0, left)   # exactly empty after burnout


def parse_eng(text: str, where: str) -> ThrustCurve:
    """Parse a RASP ``.eng`` motor file (comments ``;``; header ``name diameter_mm length_mm delays prop_kg
    total_kg maker``; then ``time thrust`` rows). A (0, 0) point is prepended when the table starts later, and
    duplicate times are rejected. Errors name ``where`` and the line."""
    header = None
    rows: list[tuple[float, float]] = []
    for lineno, raw in enumerate(text.splitlines(), 1):
        line = raw.split(";", 1)[0].strip().lstrip("\ufeff")
        if not line:
            continue
        parts = line.split()
        if header is None:
            if len(parts) < 7:
                raise UserError(f"{where}:{lineno}: RASP header needs 7 fields, got {len(parts)}")
            try:
                header = (parts[0], float(parts[1]), float(parts[2]), float(parts[4]), float(parts[5]))
            except ValueError:
                raise UserError(f"{where}:{lineno}: unparseable RASP header {line!r}") from None
            continue
        try:
            t, f = float(parts[0]), float(parts[1])
        except (ValueError, IndexError):
            raise UserError(f"{where}:{lineno}: unparseable thrust row {line!r}") from None
        if rows and t <= rows[-1][0]:
            raise UserError(f"{where}:{lineno}: time does not increase ({rows[-1][0]} -> {t})")
        if f < 0:
            raise UserError(f"{where}:{lineno}: negative thrust {f}")
        rows.append((t, f))
    if header is None or len(rows) < 2:
        raise UserError(f"{where}: no RASP header or fewer than 2 thrust rows")
    if rows[0][0] > 0:
        rows.insert(0, (0.0, 0.0))
    if rows[-1][1] != 0.0:
        raise UserError(f"{where}: the last thrust row must be 0 N (burnout), got {rows[-1][1]}")
    name, dia_mm, len_mm, prop, total = header
    arr = np.array(rows, dtype=np.float64)
    return ThrustCurve(name=name, time_s=arr[:, 0], thrust_n=arr[:, 1], propellant_mass_kg=prop,
                       total_mass_kg=total, diameter_m=dia_mm / 1000.0, length_m=len_mm / 1000.0)


def motor_names() -> list[str]:
    """Names of the shipped motors."""
    return list(MOTOR_FILES)


@lru_cache(maxsize=None)
def load_motor(name: str) -> ThrustCurve:
    """A shipped motor by name (see :data:`MOTOR_FILES` and ``data/README.md``)."""
    if name not in MOTOR_FILES:
        raise UserError(f"unknown motor {name!r}; shipped: {', '.join(MOTOR_FILES)}")
    path = DATA_DIR / MOTOR_FILES[name]
    m = parse_eng(path.read_text(encoding="utf-8"), str(path))
    return replace(m, name=name, source=f"RocketPy repository data/motors/.../{MOTOR_FILES[name]}",
                   licence="MIT (RocketPy)")


@lru_cache(maxsize=None)
def default_drag_curve() -> tuple[np.ndarray, np.ndarray]:
    """(Mach, Cd) of the default power-off drag curve (Mach 0.01 .. 2.0; Cd held constant outside)."""
    path = DATA_DIR / DRAG_FILE
    arr = np.loadtxt(path, delimiter=",", dtype=np.float64)
    mach, cd = arr[:, 0].copy(), arr[:, 1].copy()
    mach.flags.writeable = False
    cd.flags.writeable = False
    return mach, cd

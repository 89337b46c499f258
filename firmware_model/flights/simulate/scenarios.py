"""The catalogue of named simulated flights for evaluation (docs/flights-sim.md, "Scenarios").

Each :class:`Scenario` is physics only (a rocket, a launch, the simulator, and the static-pressure error effects of
:mod:`.pressure_errors`: the barometer errors of real flight (``baro_errors``, the ``rb-`` and ``rp-rb-``
scenarios), the step (Kumar-style, not realistic; ``transonic``) or single-sample spikes); sensor models (ADC
bits, noise) and k are applied later by the evaluation, which may use the suggested ``tags``.
``simulate_scenario(name)`` is deterministic (same name, same bytes), cached in the process, and RocketPy
scenarios are also cached on disk (``$FWEMU_CACHE`` or ``~/.cache/fwemu/flights``), keyed by a hash of the
scenario's physics (rocket, launch, simulator settings), the simulator sources and the motor/drag data files
(pressure effects are applied after the cache, so changing them does not re-run RocketPy).

Classes by peak Mach: ``subsonic`` < 0.9, ``transonic`` 0.9..1.2, ``supersonic`` 1.3..2.0 (checked by the tests).
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from firmware_model.flights.simulate.motors import DATA_DIR, load_motor
from firmware_model.flights.simulate.pressure_errors import (BaroErrorModel, draw_error_model, pressure_spikes,
                                                    real_flight_errors, transonic_pressure_error)
from firmware_model.flights.record import FlightRecord, Truth
from firmware_model.flights.simulate.rocketpy_sim import simulate_rocketpy_with_mach
from firmware_model.flights.simulate.sim1dof import Launch, Rocket, mach_of, simulate_1dof
from firmware_model.runtime.errors import UserError

#: Mach-class bounds (peak Mach) asserted by the tests.
MACH_CLASSES: dict[str, tuple[float, float]] = {"subsonic": (0.0, 0.9), "transonic": (0.9, 1.2),
                                                "supersonic": (1.3, 2.0)}


@dataclass(frozen=True)
class Scenario:
    """A named simulated flight. ``rocket``: :class:`Rocket` fields (``motor`` by name); ``launch``:
    :class:`Launch` fields; ``simulator``: "1dof" or "rocketpy" (then ``rocketpy`` holds wind/rail settings for
    :func:`firmware_model.flights.simulate.rocketpy_sim.simulate_rocketpy`); ``transonic``/``spikes``: keyword arguments
    of the pressure-error functions, or None; ``baro_errors``: the barometer errors of real flight
    (:func:`.pressure_errors.real_flight_errors`): ``{"model": {BaroErrorModel fields}, "seed": n}`` (fields not
    named keep their defaults) or ``{"draw": n, "seed": n}`` (every parameter drawn from
    :data:`.pressure_errors.BARO_ERROR_RANGES` by ``numpy.random.default_rng(draw)``; with ``"ram": true`` the
    ram error in boost of issue 30 is drawn too, else it stays off), or None; ``mach_class``: the peak-Mach class
    it is meant to be in; ``tags``: suggested sensor and k settings for the evaluation; ``log_start_s``: the log
    starts this long after liftoff, already in boost (no pad rows, as an AltosUI export that starts at -0.30 s in
    state ``boost``; the record then states no ground pressure, as such a log does not), or None (2 s of pad)."""

    name: str
    description: str
    mach_class: str
    rocket: dict[str, Any]
    launch: dict[str, Any] = field(default_factory=dict)
    simulator: str = "1dof"
    rocketpy: dict[str, Any] = field(default_factory=dict)
    transonic: dict[str, Any] | None = None
    spikes: dict[str, Any] | None = None
    tags: dict[str, Any] = field(default_factory=dict)
    baro_errors: dict[str, Any] | None = None
    log_start_s: float | None = None

    def build_rocket(self) -> Rocket:
        kw = dict(self.rocket)
        motor = load_motor(kw.pop("motor"))
        scale = kw.pop("motor_scale", None)
        if scale:
            motor = motor.scaled(*scale)
        return Rocket(name=self.name, motor=motor, **kw)

    def build_launch(self) -> Launch:
        return Launch(**{"record_hz": 1000.0, **self.launch})

    def definition(self) -> dict[str, Any]:
        """JSON-ready definition."""
        return {"name": self.name, "mach_class": self.mach_class, "rocket": self.rocket, "launch": self.launch,
                "simulator": self.simulator, "rocketpy": self.rocketpy, "transonic": self.transonic,
                "spikes": self.spikes, "baro_errors": self.baro_errors, "log_start_s": self.log_start_s}

    def physics(self) -> dict[str, Any]:
        """The part of the definition the simulator sees (what the cache key hashes)."""
        return {"name": self.name, "rocket": self.rocket, "launch": self.launch, "simulator": self.simulator,
                "rocketpy": self.rocketpy}

    def error_model(self) -> BaroErrorModel | None:
        """The :class:`BaroErrorModel` of ``baro_errors`` (None without)."""
        if self.baro_errors is None:
            return None
        if "draw" in self.baro_errors:
            return draw_error_model(np.random.default_rng(int(self.baro_errors["draw"])),
                                    ram=bool(self.baro_errors.get("ram", False)))
        return BaroErrorModel(**self.baro_errors.get("model", {}))


def _s(name, description, mach_class, rocket, tags, **kw) -> Scenario:
    return Scenario(name=name, description=description, mach_class=mach_class, rocket=rocket, tags=tags, **kw)


_TS = {}  # the step (Kumar-style, not realistic) with the module's default magnitude (+60 m)
_SPIKES = {"count": 4, "magnitude_pa": 1500.0, "seed": 7}
#: The barometer errors of real flight with only the ram error in boost (issue 30) left to switch on: the two
#: unseen flights' signature alone (their other errors are not described in the issue).
_RAM_ONLY = {"cp_port": 0.0, "dip_cp": 0.0, "jump_m": 0.0, "burst_sigma_m": 0.0, "ejection_m": 0.0}

_CATALOGUE: tuple[Scenario, ...] = (
    # --- subsonic -------------------------------------------------------------------------------------------
    _s("sub-k400-300m", "heavy K400C rocket, ~300 m, slow coast", "subsonic",
       {"motor": "K400C", "dry_mass_kg": 14.0, "diameter_m": 0.10},
       {"baro": ["analog-16", "ms5607"], "noise": ["none", "noisy"], "k": [6, 8]}),
    _s("sub-k400-900m", "K400C sport rocket, ~900 m", "subsonic",
       {"motor": "K400C", "dry_mass_kg": 8.0, "diameter_m": 0.10},
       {"baro": ["analog-10", "analog-12"], "noise": ["noisy"], "k": [5, 6]}),
    _s("sub-k400-1900m", "light K400C rocket, ~1.9 km, Mach 0.7", "subsonic",
       {"motor": "K400C", "dry_mass_kg": 4.0, "diameter_m": 0.10},
       {"baro": ["analog-8", "analog-16"], "noise": ["none", "noisy"], "k": [4, 6]}),
    _s("sub-k828-600m-highsite", "heavy K828FJ rocket from a 1,200 m high desert site", "subsonic",
       {"motor": "K828FJ", "dry_mass_kg": 16.0, "diameter_m": 0.10}, {"baro": ["analog-10", "ms5607"],
                                                                      "noise": ["noisy"], "k": [6, 7]},
       launch={"site_altitude_m": 1200.0}),
    _s("sub-k828-1400m", "K828FJ minimum-diameter-ish rocket, ~1.4 km", "subsonic",
       {"motor": "K828FJ", "dry_mass_kg": 10.0, "diameter_m": 0.08},
       {"baro": ["analog-12"], "noise": ["none", "noisy"], "k": [5, 8]}),
    _s("sub-l1350-1900m-delay", "heavy L1350 rocket, drogue opens 1 s after apogee", "subsonic",
       {"motor": "L1350", "dry_mass_kg": 18.0, "diameter_m": 0.10},
       {"baro": ["analog-16"], "noise": ["noisy"], "k": [6]}, launch={"drogue_delay_s": 1.0}),
    _s("sub-m1670-3200m", "M1670 rocket to ~3.3 km at Mach 0.78", "subsonic",
       {"motor": "M1670", "dry_mass_kg": 18.0, "diameter_m": 0.10},
       {"baro": ["analog-10", "analog-16", "ms5607"], "noise": ["noisy"], "k": [6, 7]}),
    _s("sub-k400-900m-spikes", "sub-k400-900m with four +-1500 Pa single-sample pressure spikes", "subsonic",
       {"motor": "K400C", "dry_mass_kg": 8.0, "diameter_m": 0.10},
       {"baro": ["analog-12", "ms5607"], "noise": ["noisy"], "k": [6]}, spikes=_SPIKES),
    _s("sub-scaled-k400-1300m", "a half-thrust, 1.6x-longer synthetic motor (K400C shape), slow boost", "subsonic",
       {"motor": "K400C", "motor_scale": (0.5, 1.6), "dry_mass_kg": 5.0, "diameter_m": 0.08},
       {"baro": ["analog-8", "analog-10"], "noise": ["none"], "k": [4, 5]}),
    # --- transonic ------------------------------------------------------------------------------------------
    _s("trans-l1350-m094", "L1350 rocket peaking at Mach ~0.94: near-sonic, no step", "transonic",
       {"motor": "L1350", "dry_mass_kg": 10.0, "diameter_m": 0.13},
       {"baro": ["analog-10", "analog-16"], "noise": ["noisy"], "k": [6]}),
    _s("trans-m1670-m105", "M1670 rocket through Mach 1.05 with the +60 m step (Kumar-style, not realistic)",
       "transonic",
       {"motor": "M1670", "dry_mass_kg": 12.0, "diameter_m": 0.127},
       {"baro": ["analog-10", "analog-16", "ms5607"], "noise": ["none", "noisy"], "k": [5, 6, 7]}, transonic=_TS),
    _s("trans-m1670-m105-clean", "trans-m1670-m105 without the pressure step (the pair isolates the effect)",
       "transonic", {"motor": "M1670", "dry_mass_kg": 12.0, "diameter_m": 0.127},
       {"baro": ["analog-16"], "noise": ["noisy"], "k": [6]}),
    _s("trans-k828-m118", "light K828FJ rocket at Mach ~1.18 with the Kumar-style step", "transonic",
       {"motor": "K828FJ", "dry_mass_kg": 3.0, "diameter_m": 0.10},
       {"baro": ["analog-12"], "noise": ["noisy"], "k": [6, 8]}, transonic=_TS),
    _s("trans-m6400-m109", "short-burn M6400 rocket at Mach ~1.1 with a ramped 100 m step", "transonic",
       {"motor": "M6400", "dry_mass_kg": 20.0, "diameter_m": 0.10},
       {"baro": ["analog-16", "ms5607"], "noise": ["noisy"], "k": [6]},
       transonic={"altitude_step_m": 100.0, "shape": "ramp", "width_mach": 0.06}),
    _s("trans-l1350-m098-spikes", "L1350 rocket at Mach ~0.98 with single-sample pressure spikes", "transonic",
       {"motor": "L1350", "dry_mass_kg": 10.0, "diameter_m": 0.10},
       {"baro": ["analog-10"], "noise": ["noisy"], "k": [5, 6]}, spikes={**_SPIKES, "seed": 11}),
    # --- supersonic -----------------------------------------------------------------------------------------
    _s("sup-l1350-m137", "light L1350 rocket at Mach ~1.37 with the Kumar-style step", "supersonic",
       {"motor": "L1350", "dry_mass_kg": 6.0, "diameter_m": 0.10},
       {"baro": ["analog-10", "analog-16"], "noise": ["noisy"], "k": [6, 7]}, transonic=_TS),
    _s("sup-m1670-m145", "M1670 rocket at Mach ~1.45 with the Kumar-style step, 4.9 km", "supersonic",
       {"motor": "M1670", "dry_mass_kg": 8.0, "diameter_m": 0.10},
       {"baro": ["analog-12", "ms5607"], "noise": ["none", "noisy"], "k": [5, 6]}, transonic=_TS),
    _s("sup-m6400-m167", "M6400 rocket at Mach ~1.67 with a 120 m step", "supersonic",
       {"motor": "M6400", "dry_mass_kg": 12.0, "diameter_m": 0.10},
       {"baro": ["analog-16"], "noise": ["noisy"], "k": [6, 8]}, transonic={"altitude_step_m": 120.0}),
    _s("sup-m6400-m167-clean", "sup-m6400-m167 without the pressure step", "supersonic",
       {"motor": "M6400", "dry_mass_kg": 12.0, "diameter_m": 0.10},
       {"baro": ["analog-16", "ms5607"], "noise": ["noisy"], "k": [6]}),
    _s("sup-m2245-m170-8700m", "M2245 in 80 mm to ~8.7 km at Mach ~1.7 with the Kumar-style step", "supersonic",
       {"motor": "M2245", "dry_mass_kg": 12.0, "diameter_m": 0.08},
       {"baro": ["analog-16", "ms5607"], "noise": ["noisy"], "k": [6, 7]}, transonic=_TS),
    _s("sup-m2245-m19-9400m", "M2245 in 80 mm to ~9.4 km at Mach ~1.9 with hysteresis (on 1.0, off 0.95)",
       "supersonic", {"motor": "M2245", "dry_mass_kg": 10.0, "diameter_m": 0.08},
       {"baro": ["analog-16", "ms5607"], "noise": ["none", "noisy"], "k": [5, 6]},
       transonic={"mach_on": 1.0, "mach_off": 0.95}),
    _s("sup-m2245-m19-9400m-spikes", "sup-m2245-m19-9400m (no step) with single-sample spikes near apogee",
       "supersonic", {"motor": "M2245", "dry_mass_kg": 10.0, "diameter_m": 0.08},
       {"baro": ["ms5607"], "noise": ["noisy"], "k": [6]},
       spikes={"count": 3, "magnitude_pa": 800.0, "seed": 3, "window_s": (35.0, 45.0)}),
    # --- RocketPy 6-DOF: wind, rail inclination --------------------------------------------------------------
    _s("rp-k400-670m-wind10", "RocketPy: K400C sport rocket, 10 m/s wind, rail at 80 deg into the wind", "subsonic",
       {"motor": "K400C", "dry_mass_kg": 8.0, "diameter_m": 0.10},
       {"baro": ["analog-10", "ms5607"], "noise": ["noisy"], "k": [5, 6]}, simulator="rocketpy",
       rocketpy={"wind_u": -10.0, "inclination_deg": 80.0, "heading_deg": 90.0}),
    _s("rp-k828-1400m-wind5", "RocketPy: K828FJ rocket, 5 m/s crosswind, rail at 85 deg", "subsonic",
       {"motor": "K828FJ", "dry_mass_kg": 10.0, "diameter_m": 0.08},
       {"baro": ["analog-12", "analog-16"], "noise": ["none", "noisy"], "k": [6, 7]}, simulator="rocketpy",
       rocketpy={"wind_v": 5.0, "inclination_deg": 85.0, "heading_deg": 90.0}),
    _s("rp-m1670-m105-vertical", "RocketPy: the M1670 cross-check rocket, vertical, no wind, Kumar-style step",
       "transonic", {"motor": "M1670", "dry_mass_kg": 12.0, "diameter_m": 0.127},
       {"baro": ["analog-16", "ms5607"], "noise": ["noisy"], "k": [6]}, simulator="rocketpy",
       rocketpy={"inclination_deg": 90.0}, transonic=_TS),
    _s("rp-m1670-m105-wind4", "RocketPy: M1670 rocket, 4 m/s wind, rail at 86 deg, Kumar-style step", "transonic",
       {"motor": "M1670", "dry_mass_kg": 12.0, "diameter_m": 0.127},
       {"baro": ["analog-10", "analog-16"], "noise": ["noisy"], "k": [5, 6]}, simulator="rocketpy",
       rocketpy={"wind_u": 4.0, "inclination_deg": 86.0, "heading_deg": 45.0}, transonic=_TS),
    _s("rp-l1350-m137-windprofile", "RocketPy: L1350 rocket at Mach ~1.35, wind rising 2 -> 15 m/s with height, "
       "rail at 84 deg, Kumar-style step", "supersonic", {"motor": "L1350", "dry_mass_kg": 6.0, "diameter_m": 0.10},
       {"baro": ["analog-12", "ms5607"], "noise": ["noisy"], "k": [6, 7]}, simulator="rocketpy",
       rocketpy={"wind_u": [[0.0, 2.0], [1000.0, 8.0], [6000.0, 15.0]], "inclination_deg": 84.0,
                 "heading_deg": 270.0}, transonic=_TS),
    _s("rp-m2245-m17-8700m-wind3", "RocketPy: M2245 in 80 mm to ~8.7 km, 3 m/s wind, rail at 88 deg, step",
       "supersonic", {"motor": "M2245", "dry_mass_kg": 12.0, "diameter_m": 0.08},
       {"baro": ["analog-16", "ms5607"], "noise": ["noisy"], "k": [6, 8]}, simulator="rocketpy",
       rocketpy={"wind_u": 3.0, "inclination_deg": 88.0, "heading_deg": 0.0}, transonic=_TS),
    # --- barometer errors of real flight (pressure_errors.real_flight_errors; docs/flights.md) --------------------
    # transonic dip, shock jump, noise bursts at burnout and deployment, ejection spike; defaults or drawn from the
    # ranges of the shared and unseen logs; every one at k = 5, 6, 7 with 8-16-bit ADCs and the pascal sensor
    _s("rb-l1350-m094", "L1350 rocket peaking at Mach ~0.94: port error and transonic dip, no shock", "transonic",
       {"motor": "L1350", "dry_mass_kg": 10.0, "diameter_m": 0.13},
       {"baro": ["analog-10", "analog-16", "ms5607"], "noise": ["noisy"], "k": [5, 6, 7]},
       baro_errors={"model": {}, "seed": 1}),
    _s("rb-m1670-m105", "M1670 rocket hovering at Mach ~1.05 (piccard-like): default real-flight errors",
       "transonic", {"motor": "M1670", "dry_mass_kg": 12.0, "diameter_m": 0.127},
       {"baro": ["analog-8", "analog-12", "analog-16"], "noise": ["noisy", "none"], "k": [5, 6, 7]},
       baro_errors={"model": {}, "seed": 2}),
    _s("rb-m1670-m105-jumpdown", "as rb-m1670-m105, deep dip (0.10 q) and a -300 m shock jump", "transonic",
       {"motor": "M1670", "dry_mass_kg": 12.0, "diameter_m": 0.127},
       {"baro": ["analog-16", "ms5607", "analog-10"], "noise": ["noisy"], "k": [5, 6, 7]},
       baro_errors={"model": {"dip_cp": 0.10, "jump_m": -300.0}, "seed": 3}),
    _s("rb-k828-m118", "light K828FJ rocket at Mach ~1.18, errors drawn from the ranges", "transonic",
       {"motor": "K828FJ", "dry_mass_kg": 3.0, "diameter_m": 0.10},
       {"baro": ["analog-12", "analog-8", "ms5607"], "noise": ["noisy"], "k": [5, 6, 7]},
       baro_errors={"draw": 104, "seed": 4}),
    _s("rb-m6400-m109", "short-burn M6400 rocket at Mach ~1.1, weakest errors of the ranges", "transonic",
       {"motor": "M6400", "dry_mass_kg": 20.0, "diameter_m": 0.10},
       {"baro": ["analog-16", "analog-10"], "noise": ["noisy"], "k": [5, 6, 7]},
       baro_errors={"model": {"cp_port": 0.0, "dip_cp": 0.02, "jump_m": 50.0, "burst_sigma_m": 10.0,
                              "ejection_m": 20.0}, "seed": 5}),
    _s("rb-l1350-m137", "light L1350 rocket at Mach ~1.37, default real-flight errors", "supersonic",
       {"motor": "L1350", "dry_mass_kg": 6.0, "diameter_m": 0.10},
       {"baro": ["analog-10", "analog-16", "ms5607"], "noise": ["noisy"], "k": [5, 6, 7]},
       baro_errors={"model": {}, "seed": 6}),
    _s("rb-m1670-m145-delay", "M1670 at Mach ~1.45, drogue 1 s after apogee, -250 m ejection, 120 m bursts",
       "supersonic", {"motor": "M1670", "dry_mass_kg": 8.0, "diameter_m": 0.10},
       {"baro": ["analog-12", "ms5607", "analog-16"], "noise": ["noisy"], "k": [5, 6, 7]},
       launch={"drogue_delay_s": 1.0},
       baro_errors={"model": {"ejection_m": -250.0, "burst_sigma_m": 120.0, "burst_s": 0.6}, "seed": 7}),
    _s("rb-m6400-m167", "M6400 rocket at Mach ~1.67, errors drawn from the ranges", "supersonic",
       {"motor": "M6400", "dry_mass_kg": 12.0, "diameter_m": 0.10},
       {"baro": ["analog-16", "analog-8", "analog-12"], "noise": ["noisy", "none"], "k": [5, 6, 7]},
       baro_errors={"draw": 108, "seed": 8}),
    _s("rb-m2245-m19-9400m", "M2245 in 80 mm to ~9.4 km at Mach ~1.9, strongest errors of the ranges",
       "supersonic", {"motor": "M2245", "dry_mass_kg": 10.0, "diameter_m": 0.08},
       {"baro": ["analog-16", "ms5607", "analog-12"], "noise": ["noisy"], "k": [5, 6, 7]},
       baro_errors={"model": {"cp_port": 0.06, "dip_cp": 0.10, "dip_mach_off": 1.5, "jump_m": 400.0,
                              "jump_decay_s": 1.0, "burst_sigma_m": 120.0, "ejection_m": 300.0}, "seed": 9}),
    _s("rb-l1350-m145-highsite", "light L1350 rocket from a 1,200 m site at Mach ~1.45, errors drawn", "supersonic",
       {"motor": "L1350", "dry_mass_kg": 6.0, "diameter_m": 0.10},
       {"baro": ["analog-10", "analog-16", "ms5607"], "noise": ["noisy"], "k": [5, 6, 7]},
       launch={"site_altitude_m": 1200.0}, baro_errors={"draw": 110, "seed": 10}),
    _s("rp-rb-m1670-m105-wind4", "RocketPy: M1670 rocket, 4 m/s wind, rail at 86 deg, default real-flight errors",
       "transonic", {"motor": "M1670", "dry_mass_kg": 12.0, "diameter_m": 0.127},
       {"baro": ["analog-16", "analog-10", "ms5607"], "noise": ["noisy"], "k": [5, 6, 7]}, simulator="rocketpy",
       rocketpy={"wind_u": 4.0, "inclination_deg": 86.0, "heading_deg": 45.0}, baro_errors={"model": {}, "seed": 11}),
    _s("rp-rb-l1350-m137-windprofile", "RocketPy: L1350 rocket at Mach ~1.35, wind 2 -> 15 m/s, rail at 84 deg, "
       "errors drawn", "supersonic", {"motor": "L1350", "dry_mass_kg": 6.0, "diameter_m": 0.10},
       {"baro": ["analog-12", "ms5607", "analog-8"], "noise": ["noisy"], "k": [5, 6, 7]}, simulator="rocketpy",
       rocketpy={"wind_u": [[0.0, 2.0], [1000.0, 8.0], [6000.0, 15.0]], "inclination_deg": 84.0,
                 "heading_deg": 270.0}, baro_errors={"draw": 112, "seed": 12}),
    _s("rp-rb-m2245-m17-wind3", "RocketPy: M2245 in 80 mm to ~8.7 km, 3 m/s wind, -350 m shock jump",
       "supersonic", {"motor": "M2245", "dry_mass_kg": 12.0, "diameter_m": 0.08},
       {"baro": ["analog-16", "ms5607", "analog-12"], "noise": ["noisy"], "k": [5, 6, 7]}, simulator="rocketpy",
       rocketpy={"wind_u": 3.0, "inclination_deg": 88.0, "heading_deg": 0.0},
       baro_errors={"model": {"jump_m": -350.0, "dip_cp": 0.09}, "seed": 13}),
    _s("rp-rb-m6400-m167-vertical", "RocketPy: M6400 rocket at Mach ~1.67, vertical, default real-flight errors",
       "supersonic", {"motor": "M6400", "dry_mass_kg": 12.0, "diameter_m": 0.10},
       {"baro": ["analog-10", "analog-16", "ms5607"], "noise": ["noisy"], "k": [5, 6, 7]}, simulator="rocketpy",
       rocketpy={"inclination_deg": 90.0}, baro_errors={"model": {}, "seed": 14}),
    # --- the ram error in boost (issue 30; pressure_errors part 6, docs/flights-sim.md "Ram error in boost") ------
    # the port reads ram_cp x q above static from Mach ram_mach_on until burnout (+ ram_fade_s): the barometric
    # height falls below the pad while the rocket climbs at Mach 1-2. "-boostlog": the log starts in boost (no pad
    # rows). Every one at k = 5, 6, 7 with 10-16-bit ADCs and the pascal sensor.
    _s("ram-m1670-m156-easymega-boostlog", "issue 30's EasyMega flight: 5.8 s burn at ~12 g from a 1,350 m site "
       "to 8.4 km, port +0.17 q from Mach 0.7 to burnout (+0.5 s fade; 86 -> 95 kPa at 4.2 s), log starting in "
       "boost", "supersonic", {"motor": "M1670", "motor_scale": (1.0, 1.49), "dry_mass_kg": 12.0, "diameter_m": 0.08},
       {"baro": ["ms5607", "analog-16"], "noise": ["noisy"], "k": [5, 6, 7]}, launch={"site_altitude_m": 1350.0},
       baro_errors={"model": {**_RAM_ONLY, "ram_cp": 0.17, "ram_mach_on": 0.7, "ram_fade_s": 0.5}, "seed": 30},
       log_start_s=0.2),
    _s("ram-l1350-m114-telemega", "issue 30's TeleMega-class flight: 2.8 s burn at ~16 g to 4.5 km, port +0.09 q "
       "from Mach 0.75 to burnout (1.9 kPa over the pad, -160 m, at Mach 1.1)", "transonic",
       {"motor": "L1350", "motor_scale": (0.95, 0.85), "dry_mass_kg": 7.0, "diameter_m": 0.075},
       {"baro": ["ms5607", "analog-12"], "noise": ["noisy"], "k": [5, 6, 7]},
       baro_errors={"model": {**_RAM_ONLY, "ram_cp": 0.09, "ram_mach_on": 0.75, "ram_fade_s": 0.2}, "seed": 31}),
    _s("ram-l1350-m137-weak", "light L1350 rocket at Mach ~1.37: default real-flight errors plus the weakest ram "
       "error (0.02 q from Mach 0.8, gone at burnout)", "supersonic",
       {"motor": "L1350", "dry_mass_kg": 6.0, "diameter_m": 0.10},
       {"baro": ["analog-10", "analog-16"], "noise": ["noisy"], "k": [5, 6, 7]},
       baro_errors={"model": {"ram_cp": 0.02, "ram_mach_on": 0.8, "ram_fade_s": 0.0}, "seed": 32}),
    _s("ram-m1670-m145-boostlog", "M1670 at Mach ~1.45: default real-flight errors plus a 0.06 q ram error from "
       "Mach 0.7, log starting in boost", "supersonic", {"motor": "M1670", "dry_mass_kg": 8.0, "diameter_m": 0.10},
       {"baro": ["analog-12", "ms5607"], "noise": ["noisy"], "k": [5, 6, 7]},
       baro_errors={"model": {"ram_cp": 0.06, "ram_mach_on": 0.7, "ram_fade_s": 0.2}, "seed": 33}, log_start_s=0.3),
    _s("ram-m6400-m167-strong", "short-burn M6400 rocket at Mach ~1.67: default real-flight errors plus the "
       "strongest ram error (0.20 q from Mach 0.6, 0.5 s fade)", "supersonic",
       {"motor": "M6400", "dry_mass_kg": 12.0, "diameter_m": 0.10},
       {"baro": ["analog-16", "analog-10"], "noise": ["noisy"], "k": [5, 6, 7]},
       baro_errors={"model": {"ram_cp": 0.20, "ram_mach_on": 0.6, "ram_fade_s": 0.5}, "seed": 34}),
    _s("ram-k828-m118-drawn", "light K828FJ rocket at Mach ~1.18, every error drawn from the ranges, ram included",
       "transonic", {"motor": "K828FJ", "dry_mass_kg": 3.0, "diameter_m": 0.10},
       {"baro": ["analog-10", "analog-12"], "noise": ["noisy"], "k": [5, 6, 7]},
       baro_errors={"draw": 301, "ram": True, "seed": 35}),
    _s("ram-m2245-m17-highsite-drawn-boostlog", "M2245 in 80 mm from a 1,200 m site at Mach ~1.7, every error "
       "drawn (ram included), log starting in boost", "supersonic",
       {"motor": "M2245", "dry_mass_kg": 12.0, "diameter_m": 0.08},
       {"baro": ["analog-16", "ms5607"], "noise": ["noisy"], "k": [5, 6, 7]}, launch={"site_altitude_m": 1200.0},
       baro_errors={"draw": 302, "ram": True, "seed": 36}, log_start_s=0.15),
    _s("rp-ram-m2245-m17-wind3-boostlog", "RocketPy: M2245 in 80 mm to ~8.7 km, 3 m/s wind, rail at 88 deg, "
       "default real-flight errors plus a 0.12 q ram error, log starting in boost", "supersonic",
       {"motor": "M2245", "dry_mass_kg": 12.0, "diameter_m": 0.08},
       {"baro": ["ms5607", "analog-16"], "noise": ["noisy"], "k": [5, 6, 7]}, simulator="rocketpy",
       rocketpy={"wind_u": 3.0, "inclination_deg": 88.0, "heading_deg": 0.0},
       baro_errors={"model": {"ram_cp": 0.12, "ram_mach_on": 0.7, "ram_fade_s": 0.3}, "seed": 37}, log_start_s=0.2),
    _s("rp-ram-l1350-m137-windprofile-drawn", "RocketPy: L1350 rocket at Mach ~1.35, wind 2 -> 15 m/s, rail at "
       "84 deg, every error drawn (ram included)", "supersonic", {"motor": "L1350", "dry_mass_kg": 6.0,
                                                                 "diameter_m": 0.10},
       {"baro": ["analog-12", "analog-10"], "noise": ["noisy"], "k": [5, 6, 7]}, simulator="rocketpy",
       rocketpy={"wind_u": [[0.0, 2.0], [1000.0, 8.0], [6000.0, 15.0]], "inclination_deg": 84.0,
                 "heading_deg": 270.0}, baro_errors={"draw": 303, "ram": True, "seed": 38}),
    _s("rp-ram-m1670-m156-easymega", "RocketPy: the EasyMega flight's rocket, rail at 87 deg, 5 m/s wind, "
       "port +0.17 q from Mach 0.7 to burnout, with pad rows", "supersonic",
       {"motor": "M1670", "motor_scale": (1.0, 1.49), "dry_mass_kg": 12.0, "diameter_m": 0.08},
       {"baro": ["analog-16", "analog-10"], "noise": ["noisy"], "k": [5, 6, 7]}, simulator="rocketpy",
       launch={"site_altitude_m": 1350.0}, rocketpy={"wind_u": 5.0, "inclination_deg": 87.0, "heading_deg": 90.0},
       baro_errors={"model": {**_RAM_ONLY, "ram_cp": 0.17, "ram_mach_on": 0.7, "ram_fade_s": 0.5}, "seed": 39}),
    # appended last so that every earlier scenario keeps its row seeds (evalset: 100 x catalogue index): the
    # parameters shared by the ram-pressure Monte Carlo's flights on which kalman_baro still fired in boost with
    # the guards of issue 30 at the default tuning (docs/evaluation.md, "Issue 30")
    _s("ram-m1670-m156-moderate", "the EasyMega flight's rocket from a 950 m site: a moderate ram error (0.09 q "
       "from Mach 0.8, 0.2 s fade) under weak issue-20 errors (no port error, 0.03 q dip)", "supersonic",
       {"motor": "M1670", "motor_scale": (1.0, 1.49), "dry_mass_kg": 12.0, "diameter_m": 0.08},
       {"baro": ["analog-12", "ms5607"], "noise": ["noisy"], "k": [5, 6, 7]}, launch={"site_altitude_m": 950.0},
       baro_errors={"model": {"ram_cp": 0.09, "ram_mach_on": 0.8, "ram_fade_s": 0.2, "cp_port": 0.0,
                              "dip_cp": 0.03}, "seed": 40}),
)

_BY_NAME: dict[str, Scenario] = {s.name: s for s in _CATALOGUE}
assert len(_BY_NAME) == len(_CATALOGUE), "duplicate scenario names"


def scenario_names() -> list[str]:
    """Names of every scenario, in catalogue order."""
    return [s.name for s in _CATALOGUE]


def get_scenario(name: str) -> Scenario:
    """The :class:`Scenario` called ``name``."""
    try:
        return _BY_NAME[name]
    except KeyError:
        raise UserError(f"unknown scenario {name!r}; known: {', '.join(scenario_names())}") from None


def scenario_catalogue() -> dict[str, dict[str, Any]]:
    """name -> {description, mach_class, simulator, transonic, spikes, baro_errors, tags}: the catalogue as data."""
    return {s.name: {"description": s.description, "mach_class": s.mach_class, "simulator": s.simulator,
                     "transonic": s.transonic is not None, "spikes": s.spikes is not None,
                     "baro_errors": s.baro_errors is not None, "tags": s.tags}
            for s in _CATALOGUE}


def _apply_effects(s: Scenario, rec: FlightRecord, mach: np.ndarray) -> FlightRecord:
    model = s.error_model()
    if model is not None:
        rec = real_flight_errors(rec, mach=mach, model=model, seed=int(s.baro_errors.get("seed", 0)))
    if s.transonic is not None:
        rec = transonic_pressure_error(rec, mach=mach, **s.transonic)
    if s.spikes is not None:
        rec = pressure_spikes(rec, **s.spikes)
    prov = dict(rec.provenance)
    prov["scenario"] = s.name
    prov["description"] = s.description
    prov["mach_class"] = s.mach_class
    return FlightRecord(**{**rec.__dict__, "provenance": prov})


def cache_dir() -> Path:
    """Where RocketPy scenario results are cached."""
    env = os.environ.get("FWEMU_CACHE")
    return Path(env) if env else Path.home() / ".cache" / "fwemu" / "flights"


def cache_key(s: Scenario) -> str:
    """Content hash of a scenario's physics: :meth:`Scenario.physics`, the cache format, the simulator sources and
    the data files (not the pressure effects: they are applied to the cached record)."""
    h = hashlib.sha256(json.dumps(s.physics(), sort_keys=True, default=str).encode())
    h.update(CACHE_FORMAT.encode())
    here = Path(__file__).resolve().parent
    for src in ("sim1dof.py", "rocketpy_sim.py", "motors.py"):
        p = here / src
        if p.exists():
            h.update(p.read_bytes())
    for p in sorted(DATA_DIR.iterdir()):
        if p.is_file():
            h.update(p.name.encode())
            h.update(p.read_bytes())
    return h.hexdigest()[:24]


#: Version of the cache file layout (save_record/load_record); part of the cache key.
CACHE_FORMAT = "fwemu-scenario-npz/1"

_ARRAYS = ("time_s", "pressure_pa", "accel_mps2")
_TRUTH = ("altitude_m", "velocity_mps", "accel_mps2")


def save_record(rec: FlightRecord, mach: np.ndarray, path: Path) -> None:
    """Write a simulated record (+ its Mach series) to ``path`` (.npz) atomically."""
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays = {k: np.asarray(getattr(rec, k)) for k in _ARRAYS}
    arrays.update({f"truth_{k}": np.asarray(getattr(rec.truth, k)) for k in _TRUTH})
    arrays["mach"] = np.asarray(mach)
    meta = {"name": rec.name, "ground_pressure_pa": rec.ground_pressure_pa, "events": rec.events,
            "provenance": rec.provenance, "apogee_time_s": rec.truth.apogee_time_s,
            "apogee_altitude_m": rec.truth.apogee_altitude_m}
    arrays["meta"] = np.frombuffer(json.dumps(meta, sort_keys=True).encode(), dtype=np.uint8)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name + ".", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, **arrays)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def load_record(path: Path) -> tuple[FlightRecord, np.ndarray]:
    """Read what :func:`save_record` wrote."""
    with np.load(path) as z:
        meta = json.loads(bytes(z["meta"]).decode())
        truth = Truth(**{k: z[f"truth_{k}"].copy() for k in _TRUTH}, apogee_time_s=meta["apogee_time_s"],
                      apogee_altitude_m=meta["apogee_altitude_m"])
        rec = FlightRecord(name=meta["name"], time_s=z["time_s"].copy(), pressure_pa=z["pressure_pa"].copy(),
                           accel_mps2=z["accel_mps2"].copy(), ground_pressure_pa=meta["ground_pressure_pa"],
                           truth=truth, events=meta["events"], provenance=meta["provenance"])
        return rec, z["mach"].copy()


def _simulate_physics(s: Scenario) -> tuple[FlightRecord, np.ndarray]:
    if s.simulator == "1dof":
        rec = simulate_1dof(s.build_rocket(), s.build_launch(), names=[s.name])[0]
        return rec, mach_of(rec)
    if s.simulator == "rocketpy":
        path = cache_dir() / f"{s.name}-{cache_key(s)}.npz"
        if path.exists():
            try:
                return load_record(path)
            except Exception:  # noqa: BLE001 - a damaged cache entry is recomputed
                pass
        rec, mach = simulate_rocketpy_with_mach(s.build_rocket(), s.build_launch(), name=s.name, **s.rocketpy)
        try:
            save_record(rec, mach, path)
        except OSError:
            pass  # a read-only cache is not an error
        return rec, mach
    raise UserError(f"scenario {s.name}: unknown simulator {s.simulator!r}")


def start_in_boost(rec: FlightRecord, mach: np.ndarray, after_liftoff_s: float) -> tuple[FlightRecord, np.ndarray]:
    """The record as a log that starts ``after_liftoff_s`` after liftoff (the simulator's ``summary.liftoff_s``),
    already in boost: the rows before are dropped (time, pressure, accelerometer, truth and Mach alike) and the
    ground pressure is no longer stated, so that whatever reads it must take its pad from the first rows, as a
    reader of such a log does (an AltosUI export starting at -0.30 s in state ``boost`` has no pad rows). The
    truth keeps the true pad as its zero and the true apogee."""
    summ = rec.provenance.get("summary") or {}
    lift = float(summ.get("liftoff_s", 0.0))
    t = np.asarray(rec.time_s)
    i0 = int(np.searchsorted(t, lift + float(after_liftoff_s)))
    if not 0 < i0 < t.size - 2:
        raise UserError(f"{rec.name}: cannot start the log {after_liftoff_s} s after liftoff ({lift:g} s)")
    cut = lambda a: None if a is None else np.asarray(a)[i0:].copy()
    truth = Truth(altitude_m=cut(rec.truth.altitude_m), velocity_mps=cut(rec.truth.velocity_mps),
                  accel_mps2=cut(rec.truth.accel_mps2), apogee_time_s=rec.truth.apogee_time_s,
                  apogee_altitude_m=rec.truth.apogee_altitude_m)
    prov = dict(rec.provenance)
    prov["log_start"] = {"after_liftoff_s": float(after_liftoff_s), "first_row_s": float(t[i0]),
                         "true_ground_pressure_pa": rec.ground_pressure_pa,
                         "first_row_height_m": float(rec.truth.altitude_m[i0]),
                         "first_row_velocity_mps": float(rec.truth.velocity_mps[i0])}
    out = FlightRecord(**{**rec.__dict__, "time_s": cut(rec.time_s), "pressure_pa": cut(rec.pressure_pa),
                          "accel_mps2": cut(rec.accel_mps2), "temperature_c": cut(rec.temperature_c),
                          "ground_pressure_pa": None, "truth": truth, "provenance": prov})
    return out, cut(mach)


def finish_record(s: Scenario, rec: FlightRecord, mach: np.ndarray) -> tuple[FlightRecord, np.ndarray]:
    """The simulated physics -> the scenario's record and Mach series: the pressure effects, then the late start
    of a log that starts in boost (``log_start_s``)."""
    rec = _apply_effects(s, rec, mach)
    if s.log_start_s is not None:
        rec, mach = start_in_boost(rec, mach, s.log_start_s)
    return rec, mach


@lru_cache(maxsize=None)
def _simulate_cached(name: str) -> tuple[FlightRecord, np.ndarray]:
    s = get_scenario(name)
    rec, mach = finish_record(s, *_simulate_physics(s))
    # the cached arrays are shared by every caller: make them read-only so nobody changes a later caller's flight
    for a in (rec.time_s, rec.pressure_pa, rec.accel_mps2, mach, rec.truth.altitude_m, rec.truth.velocity_mps,
              rec.truth.accel_mps2):
        a.flags.writeable = False
    return rec, mach


def simulate_scenario(name: str) -> FlightRecord:
    """The scenario's flight record (physics + pressure effects; no sensor model). Deterministic and cached in
    the process: its arrays are shared and read-only (copy before changing them)."""
    return _simulate_cached(name)[0]


def scenario_mach(name: str) -> np.ndarray:
    """The scenario's Mach number per record sample (airspeed Mach)."""
    return _simulate_cached(name)[1]


def _effect_label(e: dict[str, Any]) -> str:
    if e["effect"] == "real_flight_errors":
        ram = e.get("ram")
        if ram and not any(e["model"][p] for p in ("cp_port", "dip_cp", "jump_m", "burst_sigma_m", "ejection_m")):
            return (f"ram only ({e['model']['ram_cp']:.2f} q from Mach {e['model']['ram_mach_on']:.2f}: "
                    f"height {ram['lowest_height_m']:+.0f} m at {ram['lowest_height_time_s']:.1f} s)")
        out = (f"real-flight errors (dip {e['max_dip_m']:.0f} m at Mach {e['max_dip_mach']:.2f}, "
               f"jump {e['model']['jump_m']:+.0f} m")
        if ram:
            out += (f"; ram {e['model']['ram_cp']:.2f} q from Mach {e['model']['ram_mach_on']:.2f}: "
                    f"height {ram['lowest_height_m']:+.0f} m at {ram['lowest_height_time_s']:.1f} s")
        return out + ")"
    if e["effect"] == "transonic_pressure_error":
        return f"step {e['altitude_step_m']:+.0f} m (Kumar-style)"
    return e["effect"].replace("pressure_", "")


def scenario_table() -> str:
    """The catalogue as a Markdown table: simulator, class, peak Mach, apogee altitude and time, effects."""
    lines = ["| scenario | simulator | class | peak Mach | apogee (m AGL) | apogee time (s) | pressure effects |",
             "|---|---|---|---|---|---|---|"]
    for n in scenario_names():
        s = get_scenario(n)
        r = simulate_scenario(n)
        summ = r.provenance["summary"]
        eff = ", ".join(_effect_label(e) for e in r.provenance.get("effects", [])) or "-"
        if "log_start" in r.provenance:
            eff += f"; log starts {r.provenance['log_start']['after_liftoff_s']:g} s after liftoff"
        lines.append(f"| {n} | {s.simulator} | {s.mach_class} | {summ['max_mach']:.2f} | "
                     f"{r.truth.apogee_altitude_m:.0f} | {r.truth.apogee_time_s:.2f} | {eff} |")
    return "\n".join(lines)


if __name__ == "__main__":
    print(scenario_table())

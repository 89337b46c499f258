"""The simulated flights the reconstruction is judged on: eight rockets (subsonic to Mach ~1.9, 0.9-9 km) x three
launches (vertical in calm air; rail at 85 deg with a 5 m/s crosswind; rail at 80 deg in Chari's wind, 5 m/s
towards north and 8 m/s towards east). Rockets reuse the scenario catalogue's motors and masses."""

from __future__ import annotations

from firmware_model.flights.reconstruct.truth import TruthCase

ROCKETS: dict[str, tuple[str, dict]] = {
    "k400-900m": ("subsonic", {"motor": "K400C", "dry_mass_kg": 8.0, "diameter_m": 0.10}),
    "k828-1400m": ("subsonic", {"motor": "K828FJ", "dry_mass_kg": 10.0, "diameter_m": 0.08}),
    "m1670-3200m": ("subsonic", {"motor": "M1670", "dry_mass_kg": 18.0, "diameter_m": 0.10}),
    "l1350-m094": ("transonic", {"motor": "L1350", "dry_mass_kg": 10.0, "diameter_m": 0.13}),
    "l1350-m137": ("supersonic", {"motor": "L1350", "dry_mass_kg": 6.0, "diameter_m": 0.10}),
    "m1670-m145": ("supersonic", {"motor": "M1670", "dry_mass_kg": 8.0, "diameter_m": 0.10}),
    "m2245-m17": ("supersonic", {"motor": "M2245", "dry_mass_kg": 12.0, "diameter_m": 0.08}),
    "m2245-m19": ("supersonic", {"motor": "M2245", "dry_mass_kg": 10.0, "diameter_m": 0.08}),
}
LAUNCHES: dict[str, dict] = {
    "vertical": {"inclination_deg": 90.0},
    "rail85-cross5": {"inclination_deg": 85.0, "heading_deg": 90.0, "wind_v": 5.0},
    "rail80-chari-wind": {"inclination_deg": 80.0, "heading_deg": 30.0, "wind_u": 8.0, "wind_v": 5.0},
}


def flight_set() -> list[TruthCase]:
    return [TruthCase(name=f"{r}-{l}", rocket=rk, mach_class=mc, **lk)
            for r, (mc, rk) in ROCKETS.items() for l, lk in LAUNCHES.items()]


def case_named(name: str) -> TruthCase:
    for c in flight_set():
        if c.name == name:
            return c
    raise KeyError(name)

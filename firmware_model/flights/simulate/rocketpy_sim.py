"""RocketPy 6-DOF flights with truth (optional extra ``flights``; docs/flights-sim.md, "RocketPy").

The same :class:`~firmware_model.flights.simulate.sim1dof.Rocket` description as the 1-DOF model (dry mass, diameter,
motor
table, Cd(M) curve, drogue), plus a generic airframe for the 6-DOF parts RocketPy needs (length, a von Karman nose,
four trapezoidal fins, inertia of a uniform cylinder; :class:`Airframe`). Offline: RocketPy's own ISA standard
atmosphere (no downloads) or a "custom_atmosphere" (still ISA pressure and temperature) with constant or
piecewise-linear wind; launch-rail length, inclination and heading; gravity g0 (R/(R+h))^2 with g0 = 9.80665 m/s^2
and R = 6,378,137 m (RocketPy's datum radius), so that RocketPy's geometric altitude maps onto the geopotential
altitude of the atmosphere module and the 1-DOF model (which uses constant g0 on geopotential altitude).

* Motor: a RocketPy ``GenericMotor`` from the same thrust table, propellant mass and case mass; its exhaust velocity
  is constant (total impulse / propellant mass), so its mass loss is proportional to the impulse, as in 1-DOF.
* Drag: the rocket's Cd(M) curve (times ``cd_scale``) as both RocketPy's power-off and power-on drag.
* Recorded on the regular grid ``t_k = (k - n_pad) / record_hz`` (t = 0 at ignition, ``pad_s`` of pad before):
  ``pressure_pa`` = the ISA pressure at the rocket's geopotential altitude, from :mod:`firmware_model.spec.atmosphere`:
  the function RocketPy's standard atmosphere samples (RocketPy's ``Environment.pressure`` is that function
  interpolated linearly on a coarse height grid: up to 28 Pa (~2.4 m) off between grid points, measured at
  500 m; docs/flights-sim.md), so truth altitude and pressure stay consistent;
  ``accel_mps2`` = axial specific force = ``(a - g) . e_axis``: RocketPy's inertial acceleration (``ax, ay, az``)
  minus gravity (0, 0, -g0), projected on the body axis (the third column of the attitude matrix from the
  quaternion ``e0..e3``); on the pad it is ``g0 * sin(elevation of the rail)``.
* Truth (the :class:`Truth` contract: geopotential altitude AGL): RocketPy's geometric z above sea level converted
  with RocketPy's own earth radius ``H = R z / (R + z)`` minus the site's H; vertical velocity ``vz``; vertical
  acceleration ``az``; apogee time and altitude from RocketPy's ``apogee_time``/``apogee``.
* Mach: RocketPy's ``mach_number`` (airspeed, wind included), returned by :func:`simulate_rocketpy_with_mach`
  for the transonic pressure effect.

The integration runs until ``descent_s`` after apogee (the end time comes from a 1-DOF run of the same rocket plus
a margin); the record is cut at RocketPy's apogee + ``descent_s``. RocketPy is deterministic (no noise is added:
parachute trigger noise is 0), so the same inputs give the same bytes; a test checks it.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from math import radians, sin

import numpy as np

from firmware_model.flights.record import FlightRecord, Truth
from firmware_model.flights.simulate.sim1dof import Launch, Rocket, simulate_1dof
from firmware_model.runtime.errors import UserError
from firmware_model.spec import atmosphere as atm
from firmware_model.spec.atmosphere import G0


def _import_rocketpy():
    try:
        import rocketpy
    except ImportError:
        raise UserError("RocketPy flights need the 'rocketpy' package: install the flights extra "
                        "(pip install 'fwemu[flights]')") from None
    return rocketpy


@dataclass(frozen=True)
class Airframe:
    """The 6-DOF-only geometry (defaults scale with the diameter d): body length ``length_cal`` x d (at least the
    motor length + 4 d), von Karman nose ``nose_cal`` x d, four fins (root ``fin_root_cal`` x d, tip
    ``fin_tip_cal`` x d, span ``fin_span_cal`` x d) flush with the tail, the airframe's centre of mass at
    ``com_fraction`` of the length from the tail; uniform-cylinder inertia."""

    length_cal: float = 15.0
    nose_cal: float = 4.0
    fin_root_cal: float = 2.0
    fin_tip_cal: float = 1.0
    fin_span_cal: float = 1.3
    com_fraction: float = 0.55


def _build(rp, rocket: Rocket, launch: Launch, airframe: Airframe, wind_u, wind_v):
    d = rocket.diameter_m
    r = d / 2
    motor = rocket.motor
    body_mass = rocket.dry_mass_kg - motor.dry_mass_kg
    if body_mass <= 0:
        raise UserError(f"RocketPy: rocket {rocket.name}: dry mass {rocket.dry_mass_kg} kg is not more than the "
                        f"motor's case {motor.dry_mass_kg:.3f} kg")
    length = max(airframe.length_cal * d, motor.length_m + 4 * d)
    earth_r = 6378137.0   # RocketPy's default datum radius (the one its ISA uses for geopotential height)
    env = rp.Environment(gravity=lambda h: G0 * (earth_r / (earth_r + h)) ** 2, latitude=0.0, longitude=0.0,
                         elevation=launch.site_altitude_m)
    if abs(float(env.earth_radius) - earth_r) > 1e-3:
        raise UserError(f"RocketPy: unexpected earth radius {env.earth_radius}")
    if wind_u == 0 and wind_v == 0:
        env.set_atmospheric_model(type="standard_atmosphere")
    else:
        env.set_atmospheric_model(type="custom_atmosphere", wind_u=wind_u, wind_v=wind_v)
    table = np.column_stack([motor.time_s, motor.thrust_n])
    m_len = motor.length_m
    case_inertia_t = motor.dry_mass_kg * (3 * (motor.diameter_m / 2) ** 2 + m_len ** 2) / 12
    case_inertia_a = motor.dry_mass_kg * (motor.diameter_m / 2) ** 2 / 2
    gm = rp.GenericMotor(thrust_source=table, burn_time=(0.0, float(motor.time_s[-1])),
                         chamber_radius=motor.diameter_m / 2 * 0.9, chamber_height=m_len * 0.9,
                         chamber_position=m_len / 2, propellant_initial_mass=motor.propellant_mass_kg,
                         nozzle_radius=motor.diameter_m / 4, dry_mass=motor.dry_mass_kg,
                         center_of_dry_mass_position=m_len / 2,
                         dry_inertia=(case_inertia_t, case_inertia_t, case_inertia_a), nozzle_position=0.0,
                         interpolation_method="linear", coordinate_system_orientation="nozzle_to_combustion_chamber")
    mach, cd = rocket.drag_curve()
    drag = rp.Function(np.column_stack([mach, cd]).tolist(), "Mach Number", "Drag Coefficient",
                       interpolation="linear", extrapolation="constant")
    i_t = body_mass * (3 * r * r + length * length) / 12
    i_a = body_mass * r * r / 2
    rk = rp.Rocket(radius=r, mass=body_mass, inertia=(i_t, i_t, i_a), power_off_drag=drag, power_on_drag=drag,
                   center_of_mass_without_motor=airframe.com_fraction * length,
                   coordinate_system_orientation="tail_to_nose")
    rk.add_motor(gm, position=0.0)
    rk.add_nose(length=airframe.nose_cal * d, kind="von karman", position=length)
    rk.add_trapezoidal_fins(n=4, root_chord=airframe.fin_root_cal * d, tip_chord=airframe.fin_tip_cal * d,
                            span=airframe.fin_span_cal * d, position=airframe.fin_root_cal * d)
    if rocket.drogue_cd_area_m2 > 0:
        rk.add_parachute("drogue", cd_s=rocket.drogue_cd_area_m2, trigger="apogee", sampling_rate=100,
                         lag=launch.drogue_delay_s, noise=(0, 0, 0))
    return env, rk, length


def simulate_rocketpy_with_mach(rocket: Rocket, launch: Launch = Launch(), name: str | None = None,
                                wind_u: float | list = 0.0, wind_v: float | list = 0.0,
                                inclination_deg: float = 90.0, heading_deg: float = 0.0,
                                rail_length_m: float = 5.0, airframe: Airframe = Airframe(),
                                rtol: float = 1e-8, max_time_step: float = 0.01) -> tuple[FlightRecord, np.ndarray]:
    """Simulate ``rocket`` with RocketPy and return ``(record, mach)`` (``mach`` per record sample). ``wind_u``
    (towards east) / ``wind_v`` (towards north), m/s: constants or RocketPy's ``[[height_asl_m, value], ...]``
    profiles; ``inclination_deg``: rail elevation above the horizontal (90 = vertical); ``heading_deg``: rail
    azimuth from north."""
    rp = _import_rocketpy()
    if not (0 < inclination_deg <= 90 and rail_length_m > 0):
        raise UserError(f"RocketPy: inclination must be in (0, 90] deg and the rail > 0 m "
                        f"(got {inclination_deg}, {rail_length_m})")
    env, rk, length = _build(rp, rocket, launch, airframe, wind_u, wind_v)
    est = simulate_1dof(rocket, Launch(**{**asdict(launch), "record_hz": 50.0, "internal_hz": 200.0}))[0]
    max_time = float(est.truth.apogee_time_s) * 1.25 + launch.descent_s + 5.0
    fl = rp.Flight(rocket=rk, environment=env, rail_length=rail_length_m, inclination=inclination_deg,
                   heading=heading_deg, max_time=max_time, max_time_step=max_time_step, rtol=rtol,
                   terminate_on_apogee=False, verbose=False, name=name or rocket.name)
    t_apo = float(fl.apogee_time)
    if not (0 < t_apo < max_time - launch.descent_s):
        raise UserError(f"RocketPy: {rocket.name}: no apogee within {max_time:.1f} s (apogee time {t_apo})")
    t_end = min(t_apo + launch.descent_s, float(fl.t_final))
    hz = launch.record_hz
    n_pad = int(round(launch.pad_s * hz))
    t_fl = np.arange(0, int(np.floor(t_end * hz + 1e-9)) + 1) / hz
    site_asl = launch.site_altitude_m
    sol = np.asarray(fl.solution, dtype=np.float64)

    def at(col: int) -> np.ndarray:
        return np.interp(t_fl, sol[:, 0], sol[:, col])

    moving = np.nonzero(sol[:, 3] > site_asl + 1e-4)[0]
    first_motion = float(sol[moving[0] - 1, 0]) if moving.size else float("nan")
    z_asl = at(3)
    vz = at(6)
    e0, e1, e2, e3 = at(7), at(8), at(9), at(10)
    nq = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2 + e3 * e3)
    e0, e1, e2, e3 = e0 / nq, e1 / nq, e2 / nq, e3 / nq
    # third column of the body-to-inertial rotation matrix: the rocket's axis in the inertial frame
    axis = np.stack([2 * (e1 * e3 + e0 * e2), 2 * (e2 * e3 - e0 * e1), 1 - 2 * (e1 * e1 + e2 * e2)])
    acc = np.stack([np.asarray(fl.ax(t_fl)), np.asarray(fl.ay(t_fl)), np.asarray(fl.az(t_fl))])
    spec = (acc[0] * axis[0] + acc[1] * axis[1] + (acc[2] + G0) * axis[2])
    earth_r = float(env.earth_radius)
    geo = lambda h: earth_r * h / (earth_r + h)
    site = launch.site_altitude_m
    alt = geo(z_asl) - geo(site)
    pressure = np.asarray(atm.pressure_pa(geo(z_asl)), dtype=np.float64)
    mach = np.asarray(fl.mach_number(t_fl), dtype=np.float64)
    p0 = float(atm.pressure_pa(geo(site)))
    pad_spec = G0 * sin(radians(inclination_deg))
    t_rec = (np.arange(n_pad + t_fl.size) - n_pad) / hz
    cat = lambda pad_value, x: np.concatenate([np.full(n_pad, pad_value), x])
    burn_i = int(round(rocket.motor.burn_time_s * hz))
    vmag = np.sqrt(at(4) ** 2 + at(5) ** 2 + vz ** 2)
    summary = {
        "liftoff_s": first_motion, "out_of_rail_s": float(fl.out_of_rail_time),
        "out_of_rail_velocity_mps": float(fl.out_of_rail_velocity),
        "burnout_s": rocket.motor.burn_time_s,
        "burnout_velocity_mps": float(vz[burn_i]) if burn_i < vz.size else float("nan"),
        "burnout_speed_mps": float(vmag[burn_i]) if burn_i < vz.size else float("nan"),
        "burnout_altitude_m": float(alt[burn_i]) if burn_i < alt.size else float("nan"),
        "max_velocity_mps": float(np.max(vz)), "max_mach": float(fl.max_mach_number),
        "apogee_time_s": t_apo, "apogee_altitude_m": float(geo(float(fl.apogee)) - geo(site)),
        "apogee_drift_m": float(np.hypot(fl.apogee_x, fl.apogee_y)),
        "static_margin_cal": float(rk.static_margin(0)),
        "landed_s": None,
    }
    prov = {
        "source": "firmware_model.flights.simulate.rocketpy_sim", "format": "simulation", "simulator": "RocketPy 6-DOF",
        "rocketpy_version": _rocketpy_version(),
        "licence": "MIT (this project; RocketPy and its motor/drag data, MIT)",
        "integrator": f"RocketPy LSODA, rtol={rtol:g}, max_time_step={max_time_step:g} s; sampled by linear "
                      f"interpolation of its solution", "record_hz": hz, "rocket": rocket.describe(),
        "launch": asdict(launch), "airframe": {**asdict(airframe), "length_m": length},
        "wind_u": wind_u, "wind_v": wind_v, "inclination_deg": inclination_deg, "heading_deg": heading_deg,
        "rail_length_m": rail_length_m, "summary": summary,
        "accel_definition": "(RocketPy ax, ay, az + g0) . body axis from e0..e3",
    }
    rec = FlightRecord(
        name=name or rocket.name, time_s=t_rec, pressure_pa=cat(p0, pressure), accel_mps2=cat(pad_spec, spec),
        ground_pressure_pa=p0,
        truth=Truth(altitude_m=cat(0.0, alt), velocity_mps=cat(0.0, vz), accel_mps2=cat(0.0, acc[2]),
                    apogee_time_s=t_apo, apogee_altitude_m=summary["apogee_altitude_m"]),
        provenance=prov)
    return rec, cat(0.0, mach)


def simulate_rocketpy(rocket: Rocket, launch: Launch = Launch(), **kw) -> FlightRecord:
    """:func:`simulate_rocketpy_with_mach` without the Mach series."""
    return simulate_rocketpy_with_mach(rocket, launch, **kw)[0]


def _rocketpy_version() -> str:
    try:
        from importlib.metadata import version
        return version("rocketpy")
    except Exception:  # pragma: no cover  # noqa: BLE001 - any failure to read the metadata: version unknown
        return "unknown"

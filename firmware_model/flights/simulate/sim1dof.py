"""A fast 1-DOF point-mass rocket model with truth (docs/flights-sim.md).

Physics (vertical axis, up positive; each flight of a batch integrated alone, by the same loop):

    dz/dt = v
    dv/dt = T(t)/m(t) - 0.5 rho(h) v|v| (Cd(M) A + CdA_drogue [after deploy]) / m(t) - g0

* ``T(t)``: the motor's piecewise-linear thrust table (t = 0 is ignition); ``m(t) = m_dry + m_prop(t)`` with the
  propellant left proportional to the impulse still to come (:meth:`ThrustCurve.propellant_at`).
* ``rho``, the speed of sound ``c`` (Mach ``M = |v|/c``) and the recorded pressure come from
  :mod:`firmware_model.spec.atmosphere` at ``site_altitude_m + z``; inside the integrator density and speed of sound
  are looked up in tables of that module's functions at 1 m spacing (linear interpolation; relative error
  < 1e-8; :mod:`.pointmass`), the recorded pressure is the module's exact function.
* ``Cd(M)``: a (Mach, Cd) table (default: RocketPy's Calisto power-off curve) times ``cd_scale``, held constant
  outside the table; ``A = pi d^2 / 4``.
* ``g0`` = 9.80665 m/s^2 constant: altitudes are geopotential, the convention of the atmosphere module.
* Pad: ``pad_s`` seconds of the rocket at rest before ignition, then it stays held (rail/pad hold; the rail is
  vertical and frictionless) until thrust exceeds weight.
* Recovery: a drogue of drag area ``drogue_cd_area_m2`` opens ``drogue_delay_s`` after the true apogee (full
  area at once); the record ends ``descent_s`` after apogee (or at landing: z = 0, at rest).

Integration (the RK4 step, tables and drag of :mod:`.pointmass`, shared with the Monte Carlo's 3-DOF flight):
classic RK4 with a fixed step ``h = 1 / (record_hz * ceil(internal_hz / record_hz))`` (the largest
step <= 1/internal_hz that divides the record period; internal_hz defaults to 1000); states are recorded every
``ceil(internal_hz / record_hz)`` steps, on the regular grid ``t_k = (k - n_pad) / record_hz`` (t = 0 at
ignition). The model is deterministic: same parameters, same bytes (no randomness inside; :func:`random_flights`
draws parameters from a seeded ``numpy.random.Generator``).

Recorded: ``pressure_pa`` (static pressure at the rocket), ``accel_mps2`` = axial specific force (the rocket's axis
stays vertical, so it is ``dv/dt + g0``: +g0 on the pad and while held, ``-drag/m`` in the coast, about +g0 under
the drogue at terminal speed), and :class:`Truth` (altitude AGL, vertical velocity, acceleration ``dv/dt``, apogee
time and altitude from the internal-step zero crossing of v, interpolated linearly in v).
"""

from __future__ import annotations

import functools
from dataclasses import asdict, dataclass
from math import ceil, pi
from typing import Sequence

import numpy as np

from firmware_model.flights.record import FlightRecord, Truth
from firmware_model.flights.simulate import pointmass as pm
from firmware_model.flights.simulate.motors import ThrustCurve, default_drag_curve, load_motor
from firmware_model.runtime.errors import UserError
from firmware_model.runtime.output import interrupts_deferred
from firmware_model.spec import atmosphere as atm

G0 = atm.G0


@dataclass(frozen=True, eq=False)
class Rocket:
    """A rocket for the simulators: ``dry_mass_kg`` is everything but propellant (airframe, recovery, empty motor
    case); ``diameter_m`` the reference diameter; ``motor`` its :class:`ThrustCurve`; drag ``cd(M) =
    cd_scale * interp(M, cd_mach, cd_values)`` (default RocketPy's Calisto power-off curve); the drogue drag area
    ``drogue_cd_area_m2`` (Cd x area)."""

    name: str
    dry_mass_kg: float
    diameter_m: float
    motor: ThrustCurve
    cd_scale: float = 1.0
    cd_mach: np.ndarray | None = None
    cd_values: np.ndarray | None = None
    drogue_cd_area_m2: float = 0.5

    def drag_curve(self) -> tuple[np.ndarray, np.ndarray]:
        """(Mach, Cd) including ``cd_scale``."""
        if self.cd_mach is None:
            mach, cd = default_drag_curve()
        else:
            mach, cd = np.asarray(self.cd_mach, dtype=np.float64), np.asarray(self.cd_values, dtype=np.float64)
        return mach, cd * self.cd_scale

    @property
    def area_m2(self) -> float:
        return pi * self.diameter_m ** 2 / 4.0

    @property
    def liftoff_mass_kg(self) -> float:
        return self.dry_mass_kg + self.motor.propellant_mass_kg

    def describe(self) -> dict:
        """JSON-ready summary (for provenance)."""
        return {"name": self.name, "dry_mass_kg": self.dry_mass_kg, "diameter_m": self.diameter_m,
                "motor": self.motor.name, "motor_source": self.motor.source,
                "total_impulse_ns": round(self.motor.total_impulse_ns, 3),
                "propellant_mass_kg": self.motor.propellant_mass_kg, "cd_scale": self.cd_scale,
                "drag_curve": "default (RocketPy Calisto power-off)" if self.cd_mach is None else "custom",
                "drogue_cd_area_m2": self.drogue_cd_area_m2}


@dataclass(frozen=True)
class Launch:
    """Where and how a flight is recorded: launch-site altitude (m above standard sea level; the ground pressure
    is the standard pressure there), seconds on the pad before ignition, seconds recorded after apogee, drogue
    delay after the true apogee, record rate and internal integration rate."""

    site_altitude_m: float = 0.0
    pad_s: float = 2.0
    descent_s: float = 5.0
    drogue_delay_s: float = 0.0
    record_hz: float = 500.0
    internal_hz: float = 1000.0
    max_time_s: float = 300.0


def _resampled_drag(rockets: Sequence[Rocket]) -> np.ndarray:
    """Every rocket's drag curve (cd_scale included) on the common uniform Mach grid (:func:`.pointmass.drag_table`),
    one row per rocket."""
    return np.array([pm.drag_table(*r.drag_curve()) for r in rockets])


def _step_count(launch: Launch) -> tuple[int, float]:
    if not (launch.record_hz > 0 and launch.internal_hz > 0):
        raise UserError(f"1-DOF: record_hz and internal_hz must be > 0 (got {launch.record_hz}, {launch.internal_hz})")
    return pm.step_size(launch.record_hz, launch.internal_hz)


@dataclass
class _Batch:
    """Everything the integrators need, as arrays over flights (column i = flight i)."""

    h: float
    m_per: int
    max_steps: int
    site: np.ndarray
    descent: np.ndarray
    delay: np.ndarray
    dry: np.ndarray
    area: np.ndarray
    cda_d: np.ndarray
    cd_tab: np.ndarray      # (nf, n_mach + 1) on the uniform Mach grid
    thrust: np.ndarray      # (nj, nf) at half steps from ignition
    mass: np.ndarray        # (nj, nf)
    rho_tab: np.ndarray
    c_tab: np.ndarray


def _prepare(rockets: list[Rocket], launches: list[Launch]) -> _Batch:
    nf = len(rockets)
    rates = {(l.record_hz, l.internal_hz) for l in launches}
    if len(rates) != 1:
        raise UserError(f"1-DOF: one record_hz/internal_hz per batch, got {sorted(rates)}")
    for r in rockets:
        if not (r.dry_mass_kg > 0 and r.diameter_m > 0 and r.cd_scale >= 0 and r.drogue_cd_area_m2 >= 0):
            raise UserError(f"1-DOF: rocket {r.name}: masses and diameter must be > 0, drag >= 0")
    for l in launches:
        if not (-1000.0 <= l.site_altitude_m <= 5000.0):
            raise UserError(f"1-DOF: site altitude must be -1000..5000 m, got {l.site_altitude_m}")
        if not (l.pad_s >= 0 and l.descent_s >= 0 and l.drogue_delay_s >= 0 and l.max_time_s > 0):
            raise UserError(f"1-DOF: pad_s, descent_s, drogue_delay_s must be >= 0 and max_time_s > 0: {l}")
    m_per, h = _step_count(launches[0])
    max_time = max(l.max_time_s for l in launches)
    dry = np.array([r.dry_mass_kg for r in rockets])
    burn = max(r.motor.burn_time_s for r in rockets)
    nj = 2 * int(ceil(burn / h)) + 3
    tj = np.arange(nj) * (h / 2)
    thrust = np.empty((nj, nf))
    mass = np.empty((nj, nf))
    for i, r in enumerate(rockets):
        thrust[:, i] = r.motor.thrust_at(tj)
        mass[:, i] = dry[i] + r.motor.propellant_at(tj)
    weak = np.nonzero(np.max(thrust - mass * G0, axis=0) <= 0.0)[0]
    if weak.size:
        r = rockets[int(weak[0])]
        raise UserError(f"1-DOF: rocket {r.name}: thrust never exceeds weight (peak {r.motor.thrust_n.max():.0f} N, "
                        f"lift-off mass {r.liftoff_mass_kg:.2f} kg): it would never leave the pad")
    rho_tab, c_tab = pm.atmosphere_tables()
    return _Batch(h=h, m_per=m_per, max_steps=int(ceil(max_time / h)),
                  site=np.array([l.site_altitude_m for l in launches], dtype=np.float64),
                  descent=np.array([l.descent_s for l in launches], dtype=np.float64),
                  delay=np.array([l.drogue_delay_s for l in launches], dtype=np.float64),
                  dry=dry, area=np.array([r.area_m2 for r in rockets]),
                  cda_d=np.array([r.drogue_cd_area_m2 for r in rockets]), cd_tab=_resampled_drag(rockets),
                  thrust=thrust, mass=mass, rho_tab=rho_tab, c_tab=c_tab)


def _kernel_py(grid, fl, tabs, rec, events):
    """One flight, scalar RK4 (compiled with numba when it is installed). ``grid`` = (step h, steps per record,
    max steps); ``fl`` = (site altitude, descent_s, drogue delay, dry mass, area, drogue CdA); ``tabs`` = (drag
    row, thrust and mass at half steps, density, speed of sound); fills ``rec`` = (z, v, a) and ``events`` =
    [n_rec, t_apo, z_apo, t_lift, t_land, vmax, mach_max, end_t] (events[0] = -1: not finished in time)."""
    h, m_per, max_steps = grid
    site, descent, delay, dry, area, cda_d = fl
    cd_row, thrust, mass, rho_tab, c_tab = tabs
    zrec, vrec, arec = rec
    z = 0.0
    v = 0.0
    apo = False
    landed = False
    t_apo = z_apo = t_lift = t_land = np.nan
    vmax = 0.0
    mach_max = 0.0
    end_t = np.inf
    n_rec = 0
    n = 0
    kz = np.empty(4)
    kv = np.empty(4)
    while True:
        t = n * h
        j = 2 * n
        drogue = 1.0 if (apo and t >= t_apo + delay) else 0.0
        for s in range(4):
            zz = z if s == 0 else pm.rk4_stage(z, h, kz[s - 1], s)
            vv = v if s == 0 else pm.rk4_stage(v, h, kv[s - 1], s)
            kz[s] = 0.0 if landed else vv
            jj = j + (s + 1) // 2          # thrust and mass at t, t + h/2, t + h/2, t + h
            if jj < thrust.shape[0]:
                tm = thrust[jj]
                mm = mass[jj]
            else:
                tm = 0.0
                mm = dry
            u = pm.table_coord(site + zz)
            rho = pm.table_at(rho_tab, u)
            c = pm.table_at(c_tab, u)
            cd = pm.cd_at(cd_row, abs(vv), c)
            a = (tm - pm.drag_force(rho, vv, abs(vv), cd * area + drogue * cda_d)) / mm - G0
            if landed or ((not apo) and zz <= 0.0 and vv <= 0.0 and a < 0.0):
                a = 0.0                     # landed, or held on the pad until thrust exceeds weight
            kv[s] = a
        if n % m_per == 0:
            zrec[n_rec] = z
            vrec[n_rec] = v
            arec[n_rec] = kv[0]
            n_rec += 1
            if t >= end_t:
                break
        if n >= max_steps or n_rec >= zrec.shape[0]:
            events[0] = -1.0
            return
        z_new = pm.rk4_step(z, h, kz)
        v_new = pm.rk4_step(v, h, kv)
        if np.isnan(t_lift) and v_new > 0.0:
            t_lift = t + h
        if (not apo) and v > 0.0 and v_new <= 0.0:
            t_apo, z_apo = pm.apogee_in_step(t, h, z, v, v_new)
            apo = True
            end_t = t_apo + descent
        if z_new < 0.0:
            if not apo:
                z_new = 0.0
                v_new = max(v_new, 0.0)
            elif not landed:
                t_land = t + h
                end_t = min(end_t, t + h)
                landed = True
        if landed:
            z_new = 0.0
            v_new = 0.0
        vmax = max(vmax, v_new)
        mach_max = max(mach_max, abs(v_new) / pm.table_at(c_tab, pm.table_coord(site + z_new)))
        z = z_new
        v = v_new
        n += 1
    events[0] = n_rec
    events[1] = t_apo
    events[2] = z_apo
    events[3] = t_lift
    events[4] = t_land
    events[5] = vmax
    events[6] = mach_max
    events[7] = end_t


#: Whether the optional 'fast' extra (numba) is installed; found without importing it.
HAVE_NUMBA: bool = pm.HAVE_NUMBA


@functools.cache
def compiled_kernel():
    """:func:`_kernel_py` compiled by numba (the same source), or None without numba. A lazy load
    (docs/architecture.md): importing numba costs about a second, which only a simulation should pay."""
    if not pm.register_for_numba():
        return None
    return pm.njit_cached(_kernel_py, nogil=True)


def _integrate_kernel(b: _Batch, kernel):
    """Every flight of ``b`` through ``kernel`` (:func:`_kernel_py` or its compiled form), one call per flight.
    Returns the recorded (z, v, a) per flight and the per-flight event arrays (t_apo, z_apo, t_lift, t_land, vmax,
    mach_max, end_t)."""
    nf = b.dry.size
    max_rec = b.max_steps // b.m_per + 2
    out = []
    ev = np.empty((nf, 8))
    for i in range(nf):
        zr, vr, ar = np.empty(max_rec), np.empty(max_rec), np.empty(max_rec)
        e = ev[i]
        fl = (b.site[i], b.descent[i], b.delay[i], b.dry[i], b.area[i], b.cda_d[i])
        tabs = (np.ascontiguousarray(b.cd_tab[i]), np.ascontiguousarray(b.thrust[:, i]),
                np.ascontiguousarray(b.mass[:, i]), b.rho_tab, b.c_tab)
        kernel((b.h, b.m_per, b.max_steps), fl, tabs, (zr, vr, ar), e)
        if e[0] < 0:
            raise UserError(f"1-DOF: flight {i} not finished after {b.max_steps * b.h:g} s")
        k = int(e[0])
        out.append((zr[:k], vr[:k], ar[:k]))
    return out, ev[:, 1], ev[:, 2], ev[:, 3], ev[:, 4], ev[:, 5], ev[:, 6], ev[:, 7]


#: Integrator used by :func:`simulate_1dof` by default: "kernel" (numba-compiled scalar RK4 per flight; needs the
#: 'fast' extra), else "python" (the same loop uncompiled; same bytes, tested).
DEFAULT_ENGINE: str = "kernel" if HAVE_NUMBA else "python"


def simulate_1dof(rockets: Sequence[Rocket] | Rocket, launch: Launch | Sequence[Launch] = Launch(),
                  names: Sequence[str] | None = None, provenance: dict | None = None,
                  engine: str | None = None) -> list[FlightRecord]:
    """Simulate every rocket (with its launch: one for all, or one per rocket; ``record_hz`` and ``internal_hz``
    must be common) and return one :class:`FlightRecord` each. ``engine``: "kernel" runs the numba-compiled
    per-flight loop (the default when numba is installed), "python" the same loop uncompiled (the default
    without numba)."""
    if isinstance(rockets, Rocket):
        rockets = [rockets]
    rockets = list(rockets)
    nf = len(rockets)
    if nf == 0:
        return []
    launches = [launch] * nf if isinstance(launch, Launch) else list(launch)
    if len(launches) != nf:
        raise UserError(f"1-DOF: {nf} rockets but {len(launches)} launches")
    b = _prepare(rockets, launches)
    engine = DEFAULT_ENGINE if engine is None else engine
    if engine == "kernel":
        if not HAVE_NUMBA:
            raise UserError("1-DOF: engine 'kernel' needs numba (install the 'fast' extra) or use engine='python'")
        with interrupts_deferred():  # the first call compiles (seconds): an interrupt waits for it
            res = _integrate_kernel(b, compiled_kernel())
    elif engine == "python":
        res = _integrate_kernel(b, _kernel_py)
    else:
        raise UserError(f"1-DOF: unknown engine {engine!r} (kernel, python)")
    return _records(rockets, launches, b, res, names, provenance)


def _records(rockets: list[Rocket], launches: list[Launch], b: _Batch, res, names: Sequence[str] | None = None,
            provenance: dict | None = None) -> list[FlightRecord]:
    """The :class:`FlightRecord` of every flight from an integrator's result ``res`` (:func:`_integrate_kernel`'s
    form) on the batch ``b``: the pad rows, the record up to its end, the pressure, truth and provenance."""
    series, t_apo, z_apo, t_lift, t_land, vmax, mach_max, end_t = res
    recs = []
    for i, (r, l) in enumerate(zip(rockets, launches)):
        Z, V, A = series[i]
        n_pad = int(round(l.pad_s * l.record_hz))
        n_fl = min(int(np.floor(end_t[i] * l.record_hz + 1e-9)) + 1, Z.shape[0])
        zi = np.concatenate([np.zeros(n_pad), Z[:n_fl]])
        vi = np.concatenate([np.zeros(n_pad), V[:n_fl]])
        ai = np.concatenate([np.zeros(n_pad), A[:n_fl]])
        t_rec = (np.arange(zi.size) - n_pad) / l.record_hz
        burn_t = r.motor.burn_time_s
        bi = n_pad + int(round(burn_t * l.record_hz))
        provenance_i = {
            "source": "firmware_model.flights.simulate.sim1dof", "format": "simulation",
            "simulator": "1-DOF point mass",
            "licence": "MIT (this project; motor and drag tables from RocketPy, MIT)",
            "integrator": f"RK4, fixed step {b.h * 1e3:.6g} ms", "record_hz": l.record_hz,
            "rocket": r.describe(), "launch": asdict(l),
            "summary": {
                "liftoff_s": float(t_lift[i]), "burnout_s": burn_t,
                "burnout_velocity_mps": float(vi[bi]) if bi < vi.size else float("nan"),
                "burnout_altitude_m": float(zi[bi]) if bi < zi.size else float("nan"),
                "max_velocity_mps": float(vmax[i]), "max_mach": float(mach_max[i]),
                "apogee_time_s": float(t_apo[i]), "apogee_altitude_m": float(z_apo[i]),
                "landed_s": None if np.isnan(t_land[i]) else float(t_land[i]),
            },
        }
        if provenance:
            provenance_i.update(provenance)
        recs.append(FlightRecord(
            name=names[i] if names else r.name,
            time_s=t_rec,
            pressure_pa=np.asarray(atm.pressure_pa(l.site_altitude_m + zi), dtype=np.float64),
            accel_mps2=ai + G0,
            ground_pressure_pa=float(atm.pressure_pa(l.site_altitude_m)),
            truth=Truth(altitude_m=zi, velocity_mps=vi, accel_mps2=ai,
                        apogee_time_s=float(t_apo[i]), apogee_altitude_m=float(z_apo[i])),
            provenance=provenance_i,
        ))
    return recs


def mach_of(record: FlightRecord) -> np.ndarray:
    """Mach number of a 1-DOF record from its truth (|vertical velocity| is the airspeed of a vertical flight in
    still air) and the standard speed of sound at the site altitude (from ``ground_pressure_pa``) + AGL."""
    if record.truth is None or record.truth.velocity_mps is None or record.truth.altitude_m is None:
        raise UserError(f"{record.name}: Mach needs truth altitude and velocity (a simulated flight)")
    site = atm.altitude_m(record.ground_pressure_pa) if record.ground_pressure_pa else 0.0
    return np.abs(record.truth.velocity_mps) / atm.speed_of_sound_mps(site + record.truth.altitude_m)


# ---------------------------------------------------------------------------------------------------------------
# Parameter boxes and seeded draws


@dataclass(frozen=True)
class Box:
    """A parameter box for random 1-DOF flights. Motors are shipped curves scaled in thrust and time; the dry mass
    is drawn between the bounds that keep the lift-off thrust-to-weight >= ``min_thrust_to_weight`` and the
    drag-free burnout speed estimate (rocket equation minus gravity loss) inside ``mach``; ``mach`` is then
    checked on the simulated flight by the callers that need it (drag only lowers the speed)."""

    motors: tuple[str, ...] = ("K400C", "K828FJ")
    thrust_scale: tuple[float, float] = (0.3, 1.0)
    time_scale: tuple[float, float] = (0.7, 1.5)
    mach: tuple[float, float] = (0.15, 0.8)
    diameter_m: tuple[float, float] = (0.054, 0.16)
    cd_scale: tuple[float, float] = (0.8, 1.3)
    site_altitude_m: tuple[float, float] = (0.0, 1500.0)
    min_thrust_to_weight: float = 4.0
    drogue_cd_area_m2: tuple[float, float] = (0.2, 0.8)


def mass_bounds(motor: ThrustCurve, mach_lo: float, mach_hi: float, min_tw: float) -> tuple[float, float] | None:
    """Dry-mass interval (kg) for ``motor`` where the drag-free burnout speed lies in ``[mach_lo, mach_hi]`` x
    340 m/s and the mean-thrust-to-weight is >= ``min_tw``; None when empty."""
    i_tot, mp, tb = motor.total_impulse_ns, motor.propellant_mass_kg, motor.burn_time_s
    ve = i_tot / mp
    f_mean = i_tot / tb

    def dv(md: float) -> float:
        return ve * np.log((md + mp) / md) - G0 * tb

    m_hi = f_mean / (min_tw * G0) - mp
    if m_hi <= 0.05:
        return None
    lo, hi = 0.05, m_hi

    def solve(target: float) -> float:  # dv decreasing in md: smallest md with dv <= target
        a, b = 1e-3, 1e4
        for _ in range(80):
            mid = 0.5 * (a + b)
            if dv(mid) > target:
                a = mid
            else:
                b = mid
        return b

    m_lo = max(lo, solve(mach_hi * 340.0))
    m_top = min(hi, solve(mach_lo * 340.0))
    return (m_lo, m_top) if m_lo < m_top else None


def rocket_from_unit(u: Sequence[float], box: Box = Box(), name: str = "random") -> Rocket | None:
    """Map 8 numbers in [0, 1) to a rocket in ``box`` (motor index, thrust and time scale, mass fraction,
    diameter, cd scale, drogue; the 8th is the site altitude, used by the caller). None if the box has no mass
    for that motor scaling."""
    motor_name = box.motors[min(int(u[0] * len(box.motors)), len(box.motors) - 1)]
    lerp = lambda r, x: r[0] + (r[1] - r[0]) * x
    motor = load_motor(motor_name).scaled(lerp(box.thrust_scale, u[1]), lerp(box.time_scale, u[2]))
    mb = mass_bounds(motor, box.mach[0], box.mach[1], box.min_thrust_to_weight)
    if mb is None:
        return None
    dry = mb[0] + (mb[1] - mb[0]) * u[3]
    dry = max(dry, motor.dry_mass_kg + 0.3)
    if dry > mb[1]:
        return None
    return Rocket(name=name, dry_mass_kg=float(dry), diameter_m=float(lerp(box.diameter_m, u[4])), motor=motor,
                  cd_scale=float(lerp(box.cd_scale, u[5])), drogue_cd_area_m2=float(lerp(box.drogue_cd_area_m2, u[6])))


def random_flights(n: int, seed: int, box: Box = Box(), launch: Launch = Launch()) -> list[FlightRecord]:
    """``n`` flights with parameters drawn from ``box`` by ``numpy.random.default_rng(seed)``, simulated in one
    batch. Deterministic: the same ``(n, seed, box, launch)`` gives the same bytes."""
    rng = np.random.default_rng(seed)
    rockets, launches = [], []
    tries = 0
    while len(rockets) < n:
        tries += 1
        if tries > 50 * n + 100:
            raise UserError(f"1-DOF: the parameter box {box} yields no rockets")
        u = rng.random(8)
        r = rocket_from_unit(u, box, name=f"random-{seed}-{len(rockets)}")
        if r is None:
            continue
        rockets.append(r)
        lo, hi = box.site_altitude_m
        launches.append(Launch(**{**asdict(launch), "site_altitude_m": float(lo + (hi - lo) * u[7])}))
    return simulate_1dof(rockets, launches, provenance={"seed": seed})

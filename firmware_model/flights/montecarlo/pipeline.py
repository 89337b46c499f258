"""The Monte Carlo task: a chunk of flight ids + the spec -> one row per (flight, method, tuning) (docs/montecarlo.md).

Per chunk, everything batched over its flights:

1. draw each flight's parameters from its own generator (:func:`.spec.draw`);
2. simulate every flight at once (:func:`.sim.simulate_batch`), recorded directly on the firmware's grid
   dt = 2^-k (no resampling needed: the integration step divides dt), with ``pad_s`` of pad before ignition;
3. sense (vectorised over the chunk): static pressure of the (temperature-shifted) atmosphere, the pressure-error
   model (:data:`PRESSURE_ERROR_MODELS`), spikes, barometer gain/offset/noise and ADC transfer, accelerometer
   gain/offset/noise/range -- the same transfer functions as :mod:`firmware_model.flights.inputs.sensors`, with each
   flight's noise drawn from its own generator at its own length;
4. run every (method, tuning) on the bit-exact integer model over all streams of the chunk at once
   (:func:`firmware_model.model.run_model`; streams shorter than the chunk's longest are held at their last value
   and nothing after a flight's own end is read, the model being causal);
5. the first APOGEE sample is the detection; the error is its time minus the true apogee time.

The firmware build of a method is fixed for the whole run, as on a real deployment: it is made for the nominal sensor
preset at the nominal site, its noise figures measured on the pad of the nominal flight
(:func:`firmware_model.flights.evaluation.setup.sensor_config`, as ``fwemu evaluate`` does); the dispersed flights then
fly with it. A spec that draws the sensor preset (``baro``/``accel`` = choice) gets one build per preset.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any, Callable

import numpy as np

from firmware_model.flights.simulate import pressure_errors
from firmware_model.flights.evaluation.methods import METHODS, tuning_overrides
from firmware_model.flights.evaluation.setup import sensor_config
from firmware_model.flights.inputs.firmware_inputs import firmware_inputs
from firmware_model.flights.montecarlo.sim import P_COLS, T0_K, drag_table, simulate_batch
from firmware_model.flights.montecarlo.spec import draw, fingerprint, flight_rng, slot_names
from firmware_model.flights.simulate.motors import load_motor
from firmware_model.flights.record import FlightRecord, Truth
from firmware_model.flights.inputs.sensors import AccelSensor, BaroSensor
from firmware_model.flights.simulate.sim1dof import Launch, Rocket, simulate_1dof
from firmware_model.model.run import run_model
from firmware_model.model.trace import EVENT_BITS
from firmware_model.runtime.errors import UserError
from firmware_model.spec import atmosphere as atm
from firmware_model.spec.build_constants import build_constants

G0 = atm.G0


# --------------------------------------------------------------------------------------------- pressure errors
def _hysteresis(mach: np.ndarray, on: np.ndarray, off: np.ndarray) -> np.ndarray:
    """(nf, n) 0/1: on from the first sample at or above ``on`` until the first later sample below ``off``, per
    row (the "step" shape of :func:`firmware_model.flights.simulate.pressure_errors.supersonic_fraction`)."""
    out = np.zeros(mach.shape)
    state = np.zeros(mach.shape[0], dtype=bool)
    for j in range(mach.shape[1]):       # a loop over samples, vectorised over flights
        m = mach[:, j]
        state = np.where(state, m >= off, m >= on)
        out[:, j] = state
    return out


def _step_model(p: np.ndarray, mach: np.ndarray, prm: dict[str, np.ndarray]) -> np.ndarray:
    """Schultz n.d.'s transonic step: while supersonic the barometer reads the standard pressure of an altitude
    ``altitude_step_m`` higher (``width_mach`` > 0: blended over that Mach width around the switch, as the "ramp"
    shape of :mod:`firmware_model.flights.simulate.pressure_errors`)."""
    on, off, width = prm["mach_on"][:, None], prm["mach_off"][:, None], prm["width_mach"][:, None]
    frac = _hysteresis(mach, prm["mach_on"], prm["mach_off"])
    if np.any(width > 0):
        rising = np.diff(mach, axis=1, prepend=mach[:, :1]) >= 0
        centre = np.where(rising, on, off)
        ramp = np.clip((mach - (centre - width / 2)) / np.where(width > 0, width, 1.0), 0.0, 1.0)
        frac = np.where(width > 0, ramp, frac)
    sel = frac > 0
    if not sel.any():
        return p
    out = p.copy()
    step = np.broadcast_to(prm["altitude_step_m"][:, None], p.shape)
    out[sel] = atm.pressure_pa(atm.altitude_m(p[sel]) + step[sel] * frac[sel])
    return out


def _dip_model(p: np.ndarray, mach: np.ndarray, prm: dict[str, np.ndarray]) -> np.ndarray:
    """The transonic dip (:data:`firmware_model.flights.montecarlo.spec.PRESSURE_ERROR_PARAMS`): inside the Mach
    band the barometer reads the standard pressure of ``dip_m`` lower (pressure high), on every passage through
    the band (accelerating and slowing); outside it the true pressure (the jump back at the band's edge)."""
    band = (mach >= prm["mach_lo"][:, None]) & (mach <= prm["mach_hi"][:, None])
    if not band.any():
        return p
    out = p.copy()
    dip = np.broadcast_to(prm["dip_m"][:, None], p.shape)
    out[band] = atm.pressure_pa(atm.altitude_m(p[band]) - dip[band])
    return out


def _real_flight_model(p: np.ndarray, mach: np.ndarray, prm: dict[str, np.ndarray]) -> np.ndarray:
    """The barometer errors of real flight (:func:`firmware_model.flights.simulate.pressure_errors.real_flight_errors`,
    issue 20), batched over flights with per-flight parameters: the port error and the transonic dip
    (:func:`~firmware_model.flights.simulate.pressure_errors.pressure_coefficient` of the Mach number, times ``q``), and
    the altitude jump at each crossing of ``jump_mach`` (the shock passing the port), rising over ``jump_rise_s`` and
    relaxing with ``jump_decay_s``; with the parameters of "real_flight_ram" also issue 30's ram error in boost
    (:func:`~firmware_model.flights.simulate.pressure_errors.ram_coefficient`, ending at each flight's burnout
    ``_burnout_s``, on the stream's time axis). Not here: the noise bursts and the ejection spike of the deterministic
    model (the Monte Carlo's spikes stand in for them)."""
    dt = float(prm["_dt"][0])
    col = {k: v[:, None] for k, v in prm.items() if not k.startswith("_")}
    shape = SimpleNamespace(**col)
    t = np.arange(p.shape[1]) * dt
    cp = pressure_errors.pressure_coefficient(mach, shape)
    if "ram_cp" in col:     # "real_flight_ram": issue 30's ram error in boost, until each flight's own burnout
        cp = cp + pressure_errors.ram_coefficient(t[None, :], mach, prm["_burnout_s"][:, None], shape)
    out = p + cp * pressure_errors.dynamic_pressure_pa(p, mach)
    d = mach - col["jump_mach"]
    cross = np.sign(d[:, 1:]) * np.sign(d[:, :-1]) < 0
    if cross.any():
        offset = np.zeros(p.shape)
        for f, j in zip(*np.nonzero(cross)):
            tc = t[j] + dt * d[f, j] / (d[f, j] - d[f, j + 1])
            tau = t - tc
            rise = np.clip(tau / prm["jump_rise_s"][f], 0.0, 1.0)
            decay = np.exp(-np.clip(tau - prm["jump_rise_s"][f], 0.0, None) / prm["jump_decay_s"][f])
            offset[f] += prm["jump_m"][f] * np.where(tau >= 0, rise * decay, 0.0)
        sel = offset != 0
        out[sel] = atm.pressure_pa(atm.altitude_m(out[sel]) + offset[sel])
    return out


#: name -> f(pressure (nf, n), airspeed Mach (nf, n), {param: (nf,) values}) -> pressure. The parameters are
#: declared in :data:`firmware_model.flights.montecarlo.spec.PRESSURE_ERROR_PARAMS` under the same name.
PRESSURE_ERROR_MODELS: dict[str, Callable[[np.ndarray, np.ndarray, dict[str, np.ndarray]], np.ndarray]] = {
    "none": lambda p, mach, prm: p,
    "step": _step_model,
    "transonic_dip": _dip_model,
    "real_flight": _real_flight_model,
    "real_flight_ram": _real_flight_model,
}


# --------------------------------------------------------------------------------------------- the plan
def _centre(dist: Any) -> Any:
    """A distribution's nominal value: the constant, the normal's mean, the uniform's midpoint, the first choice."""
    if not isinstance(dist, dict):
        return dist
    if "normal" in dist:
        return dist["normal"][0]
    if "uniform" in dist:
        return 0.5 * (dist["uniform"][0] + dist["uniform"][1])
    return dist["choice"][0]


def _choices(dist: Any) -> list[Any]:
    return list(dict.fromkeys(dist["choice"])) if isinstance(dist, dict) and "choice" in dist else [dist]


@dataclass
class Plan:
    """What every chunk of one spec shares (built once per process): the nominal rocket, the motor table, the drag
    table, the nominal flight, the record length bound and the firmware builds."""

    spec: dict[str, Any]
    rocket: Rocket
    cd_tab: np.ndarray
    dt: float
    n_pad: int
    max_time_s: float
    nominal_apogee_s: float
    builds: dict[tuple[str, str, str, str], Any]     # (method, tuning, baro, accel) -> constants or error text
    configs: dict[tuple[str, str, str, str], Any]    # the BuildConfig of each build that was made


def _rocket(spec: dict[str, Any]) -> Rocket:
    kw = dict(spec["rocket"])
    motor = load_motor(kw.pop("motor"))
    scale = kw.pop("motor_scale", None)
    if scale:
        motor = motor.scaled(*scale)
    return Rocket(name=spec["name"], motor=motor, **kw)


def _nominal_sensors(spec: dict[str, Any], baro_name: str, accel_name: str) -> tuple[BaroSensor, AccelSensor]:
    d = spec["dispersions"]
    baro = BaroSensor.preset(baro_name)
    noise = {"noise_pa": float(_centre(d["baro_noise_pa"]))}
    if baro.kind == "adc":
        noise["noise_counts"] = float(_centre(d["baro_noise_counts"]))
    return BaroSensor.preset(baro_name, **noise), AccelSensor.preset(
        accel_name, noise_counts=float(_centre(d["accel_noise_counts"])))


_PLANS: dict[str, Plan] = {}


def plan_for(spec: dict[str, Any]) -> Plan:
    """The :class:`Plan` of ``spec`` (cached per process, keyed by the spec's fingerprint)."""
    key = fingerprint(spec)
    if key in _PLANS:
        return _PLANS[key]
    d = spec["dispersions"]
    rocket = _rocket(spec)
    mach, cd = rocket.drag_curve()
    k = spec["k"]
    dt = 2.0 ** -k
    n_pad = int(round(spec["pad_s"] / dt))
    site = float(_centre(d["site_altitude_m"]))
    nominal = simulate_1dof(rocket, Launch(site_altitude_m=site, pad_s=spec["pad_s"], descent_s=spec["descent_s"],
                                           record_hz=1.0 / dt, internal_hz=spec["internal_hz"]))[0]
    t_apo = float(nominal.truth.apogee_time_s)
    max_time = spec["max_time_s"] or (1.6 * t_apo + spec["descent_s"] + 10.0)
    builds: dict[tuple[str, str, str, str], Any] = {}
    configs: dict[tuple[str, str, str, str], Any] = {}
    for baro_name in _choices(d["baro"]):
        for accel_name in _choices(d["accel"]):
            baro, accel = _nominal_sensors(spec, baro_name, accel_name)
            inputs = firmware_inputs(nominal, k, baro=baro, accel=accel, seed=0, pad_s=spec["pad_s"])
            sensor = sensor_config(inputs)
            for mname in spec["methods"]:
                method = METHODS[mname]
                for tuning in spec["tunings"]:
                    try:
                        cfg = method.config(k, sensor, **tuning_overrides(method, k, tuning))
                        builds[(mname, tuning, baro_name, accel_name)] = build_constants(cfg)
                        configs[(mname, tuning, baro_name, accel_name)] = cfg
                    except UserError as exc:
                        builds[(mname, tuning, baro_name, accel_name)] = f"build refused: {exc}"
    plan = Plan(spec, rocket, drag_table(mach, cd), dt, n_pad, float(max_time), t_apo, builds, configs)
    _PLANS[key] = plan
    return plan


# --------------------------------------------------------------------------------------------- one chunk
@dataclass
class Sensed:
    """A chunk's flights after simulation and sensing (arrays over flights; streams (nf, n_max))."""

    ids: np.ndarray
    params: list[dict[str, Any]]
    n: np.ndarray               # stream length per flight (pad + record from liftoff)
    offset: np.ndarray          # record index (t = index x dt since ignition) of stream sample 0
    finished: np.ndarray        # bool
    adc: np.ndarray             # (nf, n_max) int64
    acc: np.ndarray
    pressure: np.ndarray        # (nf, n_max) float, what the barometer was exposed to (errors and spikes in)
    events: np.ndarray          # simulator events (nf, 7)
    burnout_s: np.ndarray
    z: np.ndarray               # truth on the stream grid (nf, n_max)
    vz: np.ndarray
    az: np.ndarray
    fax: np.ndarray
    ground_pa: np.ndarray


def _sim_params(plan: Plan, prm: dict[str, Any]) -> list[float]:
    r = plan.rocket
    ts = float(prm["burn_time_scale"])
    imp = float(prm["impulse_scale"])
    rail = float(prm["rail_length_m"])
    if not (ts > 0 and imp > 0 and prm["dry_mass_scale"] > 0 and prm["cd_scale"] >= 0 and rail > 0):
        raise UserError(f"montecarlo: a draw gave impulse_scale={imp}, burn_time_scale={ts}, dry_mass_scale="
                        f"{prm['dry_mass_scale']}, cd_scale={prm['cd_scale']}, rail_length_m={rail}: scales and "
                        "the rail must be > 0 (clip the normal with min = ...)")
    values = {"dry_kg": r.dry_mass_kg * prm["dry_mass_scale"], "prop_kg": r.motor.propellant_mass_kg * imp,
              "time_scale": ts, "thrust_scale": imp / ts, "cd_scale": prm["cd_scale"], "area_m2": r.area_m2,
              # no drogue unless asked: the record is what the flight computer under test sees until it fires
              # its own charge (a drogue opened at the true apogee would jolt its accelerometer before it fired)
              "drogue_cda_m2": r.drogue_cd_area_m2 if plan.spec["drogue_at_apogee"] else 0.0,
              "site_m": prm["site_altitude_m"],
              "tscale": T0_K / (T0_K + prm["temperature_offset_k"]), "wind_mps": prm["wind_speed_mps"],
              "wind_dir_rad": math.radians(prm["wind_direction_deg"]), "wind_exp": prm["wind_shear_exponent"],
              "incl_rad": math.radians(prm["rail_inclination_deg"]), "rail_m": rail,
              "drogue_delay_s": prm["drogue_delay_s"], "descent_s": plan.spec["descent_s"]}
    return [float(values[c]) for c in P_COLS]


def sense_chunk(spec: dict[str, Any], seed: int, flight_ids: list[int] | tuple[int, ...],
                timing: dict[str, float] | None = None) -> Sensed:
    """Steps 1-3 of the module docstring for ``flight_ids`` (``timing``: seconds of "sim" and "sensing" added)."""
    t0, c0 = time.perf_counter(), time.process_time()
    plan = plan_for(spec)
    ids = np.asarray(flight_ids, dtype=np.int64)
    nf = ids.size
    rngs = [flight_rng(seed, int(f)) for f in ids]
    params = [draw(spec, g) for g in rngs]
    P = np.array([_sim_params(plan, p) for p in params])
    rec_hz = 1.0 / plan.dt
    sim = simulate_batch(P, plan.rocket.motor.time_s, plan.rocket.motor.thrust_n, plan.cd_tab, rec_hz,
                         spec["internal_hz"], plan.max_time_s)
    ev = sim["events"]
    t1, c1 = time.perf_counter(), time.process_time()
    n_rec = np.abs(ev[:, 0]).astype(np.int64)
    finished = ev[:, 0] > 0
    # the stream starts pad_s before liftoff, as flights.firmware_inputs.firmware_inputs does (liftoff: the record
    # sample before the vertical velocity first exceeds 0.01 m/s, flights.reference.liftoff_time's rule), so a replayed
    # flight gives `fwemu run` the very same samples
    up = sim["vz"] > 0.01
    lift = np.where(up.any(axis=1), np.maximum(up.argmax(axis=1) - 1, 0), 0)
    offset = lift - plan.n_pad                     # record index of stream sample 0 (< 0: before ignition)
    n = n_rec - offset
    n_max = int(n.max())
    # stream sample j <- record sample clip(j + offset, 0, n_rec - 1): before ignition the held state at ignition,
    # after a flight's end its last sample (never read)
    j = np.arange(n_max)[None, :]
    src = np.clip(j + offset[:, None], 0, np.maximum(n_rec - 1, 0)[:, None])
    rows = np.arange(nf)[:, None]
    z, vz, az, fax, mach = (sim[c][rows, src] for c in ("z", "vz", "az", "fax", "mach"))
    site = P[:, P_COLS.index("site_m")][:, None]
    tsc = P[:, P_COLS.index("tscale")][:, None]
    pressure = atm.pressure_pa(tsc * (site + z))
    ground = atm.pressure_pa(tsc[:, 0] * site[:, 0])
    pe = spec["pressure_error"]
    pe_prm = {p: np.array([float(prm[f"pressure_error.{p}"]) for prm in params]) for p in pe["params"]}
    pe_prm["_dt"] = np.full(nf, plan.dt)        # the stream's sample period (time-dependent models)
    burn = P[:, P_COLS.index("time_scale")] * plan.rocket.motor.burn_time_s      # since ignition
    pe_prm["_burnout_s"] = burn - offset * plan.dt     # on the stream's axis (stream sample 0 at t = 0)
    pressure = PRESSURE_ERROR_MODELS[pe["model"]](pressure, mach, pe_prm)
    # spikes, then sensor noise, each flight from its own generator at its own length
    nb1 = np.zeros((nf, n_max))
    nb2 = np.zeros((nf, n_max))
    na = np.zeros((nf, n_max))
    lift_idx = plan.n_pad                          # spikes only after liftoff
    for i, g in enumerate(rngs):
        ni = int(n[i])
        count = int(g.poisson(max(float(params[i]["spike_rate"]), 0.0)))
        if count:
            where = g.integers(lift_idx, ni, size=count)
            signs = g.choice(np.array([-1.0, 1.0]), size=count)
            pressure[i, where] += signs * float(params[i]["spike_magnitude_pa"])
        nb1[i, :ni] = g.standard_normal(ni)
        nb2[i, :ni] = g.standard_normal(ni)
        na[i, :ni] = g.standard_normal(ni)
    if np.any(pressure <= 0):
        raise UserError("montecarlo: a pressure spike made the pressure <= 0 (spike_magnitude_pa too large)")
    col = lambda name: np.array([float(p[name]) for p in params])[:, None]
    adc = np.empty((nf, n_max), dtype=np.int64)
    acc = np.empty((nf, n_max), dtype=np.int64)
    for (bname, aname), idx in _groups(params).items():
        baro = BaroSensor.preset(bname)
        ps = col("baro_gain")[idx] * pressure[idx] + col("baro_offset_pa")[idx] + col("baro_noise_pa")[idx] * nb1[idx]
        x = baro.ideal_counts(ps)
        if baro.kind == "adc":
            x = x + col("baro_noise_counts")[idx] * nb2[idx]
            adc[idx] = np.clip(np.rint(x), 0, baro.full_scale).astype(np.int64)
        else:
            adc[idx] = np.clip(np.rint(x), math.ceil(baro.p_min_pa), math.floor(baro.p_max_pa)).astype(np.int64)
        accel = AccelSensor.preset(aname)
        xa = col("accel_offset_counts")[idx] + col("accel_gain")[idx] * accel.counts_per_mps2 * fax[idx] \
            + col("accel_noise_counts")[idx] * na[idx]
        for r, i in enumerate(idx):
            rg = params[i]["accel_range_g"]
            lo, hi = (AccelSensor.preset(aname, range_g=float(rg)) if rg is not None else accel).count_limits
            acc[i] = np.clip(np.rint(xa[r]), lo, hi).astype(np.int64)
    if timing is not None:
        _add(timing, "sim", t0, c0, t1, c1)
        _add(timing, "sensing", t1, c1, time.perf_counter(), time.process_time())
    return Sensed(ids, params, n, offset, finished, adc, acc, pressure, ev, burn, z, vz, az, fax, ground)


def _groups(params: list[dict[str, Any]]) -> dict[tuple[str, str], np.ndarray]:
    out: dict[tuple[str, str], list[int]] = {}
    for i, p in enumerate(params):
        out.setdefault((str(p["baro"]), str(p["accel"])), []).append(i)
    return {key: np.array(v, dtype=np.int64) for key, v in out.items()}


#: Row columns before the parameters (one row per flight, method, tuning).
ROW_COLUMNS: tuple[str, ...] = ("flight", "method", "tuning", "status", "fired", "detect_s", "error_s",
                                "apogee_s", "apogee_m", "burnout_s", "liftoff_s", "max_mach", "early_05", "early_1",
                                "missed", "before_burnout")


def _add(timing: dict[str, float], phase: str, t0: float, c0: float, t1: float, c1: float) -> None:
    """Wall seconds under ``phase``, the process's CPU seconds under ``phase_cpu``."""
    timing[phase] = timing.get(phase, 0.0) + (t1 - t0)
    timing[f"{phase}_cpu"] = timing.get(f"{phase}_cpu", 0.0) + (c1 - c0)


def run_task(task: dict[str, Any]) -> dict[str, Any]:
    """The engine's task function: ``{"spec", "seed", "flights", "threads"}`` -> ``{"rows": run_chunk's columns,
    "seconds": {"sim", "sensing", "model", "rows"} (wall) and "cpu" (the process's CPU seconds)}``. ``threads``
    (optional): numba threads in this worker (1 when several workers share the machine); the rows do not depend on
    it."""
    threads = task.get("threads")
    if threads:
        try:
            import numba  # lazy: the optional 'fast' extra

            numba.set_num_threads(min(int(threads), numba.config.NUMBA_NUM_THREADS))
        except ImportError:  # pragma: no cover
            pass
    timing: dict[str, float] = {}
    cpu = time.process_time()
    rows = run_chunk(task, timing)
    timing["cpu"] = time.process_time() - cpu
    return {"rows": rows, "seconds": timing}


def run_chunk(task: dict[str, Any], timing: dict[str, float] | None = None) -> dict[str, Any]:
    """``{"spec", "seed", "flights"}`` -> columns (name -> numpy array), one row per (flight, method, tuning) in
    flight, method, tuning order. Plain data in, plain data out."""
    spec, seed, flights = task["spec"], int(task["seed"]), task["flights"]
    plan = plan_for(spec)
    timing = {} if timing is None else timing
    s = sense_chunk(spec, seed, flights, timing)
    t0, c0 = time.perf_counter(), time.process_time()
    nf = s.ids.size
    apo_bit = EVENT_BITS["APOGEE"]
    j = np.arange(s.adc.shape[1])[None, :]
    inside = j < s.n[:, None]
    groups = _groups(s.params)
    combos = [(m, t) for m in spec["methods"] for t in spec["tunings"]]
    first = {c: np.full(nf, -1, dtype=np.int64) for c in combos}
    status = {c: np.array(["ok" if f else "unfinished" for f in s.finished], dtype=object) for c in combos}
    for (bname, aname), idx in groups.items():
        adc_g = np.ascontiguousarray(s.adc[idx])
        acc_g = np.ascontiguousarray(s.acc[idx])
        for c in combos:
            consts = plan.builds[(c[0], c[1], bname, aname)]
            if isinstance(consts, str):
                status[c][idx] = "build_failed"
                continue
            tr = run_model(consts, adc_g, acc_g)
            hit = ((tr.column("EVENTS") & apo_bit) != 0) & inside[idx]
            first[c][idx] = np.where(hit.any(axis=1), hit.argmax(axis=1), -1)
            del tr
    t1, c1 = time.perf_counter(), time.process_time()
    _add(timing, "model", t0, c0, t1, c1)
    t_apo, z_apo, t_lift, max_mach = s.events[:, 1], s.events[:, 2], s.events[:, 3], s.events[:, 4]
    nc = len(combos)
    rep = lambda a: np.repeat(np.asarray(a), nc)  # per flight -> per row
    f = np.stack([first[c] for c in combos], axis=1).reshape(-1)      # rows: flight-major, then combo
    fired = f >= 0
    t = np.where(fired, (f + rep(s.offset)) * plan.dt, np.nan)
    err = t - rep(t_apo)
    with np.errstate(invalid="ignore"):
        cols: dict[str, Any] = {
            "flight": rep(s.ids).astype(np.int64),
            "method": np.array([c[0] for c in combos] * nf, dtype=object),
            "tuning": np.array([c[1] for c in combos] * nf, dtype=object),
            "status": np.stack([status[c] for c in combos], axis=1).reshape(-1),
            "fired": fired, "detect_s": t, "error_s": err, "apogee_s": rep(t_apo), "apogee_m": rep(z_apo),
            "burnout_s": rep(s.burnout_s), "liftoff_s": rep(t_lift), "max_mach": rep(max_mach),
            "early_05": fired & (err < -0.5), "early_1": fired & (err < -1.0), "missed": ~fired,
            "before_burnout": fired & (t < rep(s.burnout_s)),
        }
    for p in slot_names(spec):
        vals = [s.params[i][p] for i in range(nf)]
        if any(isinstance(v, str) for v in vals):
            cols[f"p_{p}"] = rep(np.array([str(v) for v in vals], dtype=object))
        else:
            cols[f"p_{p}"] = rep(np.array([math.nan if v is None else float(v) for v in vals]))
    _add(timing, "rows", t1, c1, time.perf_counter(), time.process_time())
    return cols


# --------------------------------------------------------------------------------------------- replay
def replay_record(spec: dict[str, Any], seed: int, flight: int) -> tuple[FlightRecord, dict[str, Any]]:
    """Flight ``flight`` alone, as a :class:`FlightRecord` for ``fwemu run``/``plot``: time on the firmware grid
    (t = 0 at ignition), ``pressure_pa`` = what the barometer reported, converted back to pascals through its
    transfer function (so reading it with the same preset and no added noise gives the same ADC words), likewise
    ``accel_mps2``; truth (altitude, vertical velocity and acceleration, apogee). Also returns the parameters."""
    s = sense_chunk(spec, seed, [flight])
    plan = plan_for(spec)
    ni = int(s.n[0])
    prm = s.params[0]
    baro, accel = BaroSensor.preset(str(prm["baro"])), AccelSensor.preset(str(prm["accel"]))
    t = (np.arange(ni) + int(s.offset[0])) * plan.dt
    rec = FlightRecord(
        name=f"{spec['name']}-mc{seed}-{flight}", time_s=t, pressure_pa=baro.pressure_of_counts(s.adc[0, :ni]),
        accel_mps2=accel.specific_force_of_counts(s.acc[0, :ni]), ground_pressure_pa=float(s.ground_pa[0]),
        truth=Truth(altitude_m=s.z[0, :ni].copy(), velocity_mps=s.vz[0, :ni].copy(), accel_mps2=s.az[0, :ni].copy(),
                    apogee_time_s=float(s.events[0, 1]), apogee_altitude_m=float(s.events[0, 2])),
        provenance={"source": f"fwemu montecarlo --replay {flight} (seed {seed})", "format": "simulation",
                    "licence": "MIT (this project)", "spec": spec["name"], "parameters": prm,
                    "baro_preset": baro.name, "accel_preset": accel.name})
    return rec, prm


def replay_configs(spec: dict[str, Any], prm: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """``"<method>-<tuning>"`` -> the build config (``BuildConfig.to_dict()``) the Monte Carlo ran that method
    with on a flight drawn with ``prm``'s sensor presets: ``fwemu run --config`` with it runs the same build."""
    plan = plan_for(spec)
    out = {}
    for (m, t, b, a), cfg in plan.configs.items():
        if b == str(prm["baro"]) and a == str(prm["accel"]):
            out[f"{m}-{t}"] = cfg.to_dict()
    return out


__all__ = ["PRESSURE_ERROR_MODELS", "Plan", "ROW_COLUMNS", "Sensed", "plan_for", "replay_configs", "replay_record",
           "run_chunk", "run_task", "sense_chunk"]

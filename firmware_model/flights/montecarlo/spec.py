"""The Monte Carlo spec: a nominal flight plus dispersions, read from a small TOML or JSON file (docs/montecarlo.md).

A spec is plain data (a dict of numbers, strings and lists) so that it travels to worker processes and Dask
workers as is; :func:`load_spec` checks it and fills the defaults, :func:`fingerprint` hashes it.

Randomness: flight ``f`` of a run with master seed ``S`` draws everything from one generator,
``numpy.random.default_rng(SeedSequence(S, spawn_key=(f,)))``: first :data:`N_SLOTS` uniforms (two per
parameter, in the fixed slot order of :data:`PARAMETERS`, then the pressure-error model's parameters), then the
spike count and positions, then the barometer noise, then the accelerometer noise (each of the flight's own
length). So a flight is reproducible alone from ``(S, f)``, whatever chunk or worker computes it, and a parameter's
draw does not change when another parameter's distribution does (common random numbers between specs).

Distributions (one per parameter; a plain number is a constant):

* ``{normal = [mean, sd]}`` (Box-Muller on the parameter's two uniforms), optional ``min``/``max`` clip it;
* ``{uniform = [lo, hi]}``;
* ``{choice = [a, b, ...]}`` (equal weights; numbers, or preset names for ``baro``/``accel``).
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import tomllib

from firmware_model.flights.evaluate import METHODS
from firmware_model.flights.pressure_errors import DEFAULT_TRANSONIC_STEP_M
from firmware_model.flights.scenarios import get_scenario
from firmware_model.flights.sensors import ACCEL_PRESETS, BARO_PRESETS
from firmware_model.runtime.errors import UserError

#: Dispersed parameters in their fixed slot order (never reorder: append). name -> (default, meaning).
PARAMETERS: dict[str, tuple[Any, str]] = {
    "impulse_scale": (1.0, "motor total impulse x (propellant mass scales with it: same Isp)"),
    "burn_time_scale": (1.0, "motor burn time x (thrust / this, so the impulse is impulse_scale's)"),
    "dry_mass_scale": (1.0, "dry mass x"),
    "cd_scale": (1.0, "drag coefficient x (on top of the rocket's own cd_scale)"),
    "wind_speed_mps": (0.0, "wind speed at 10 m AGL"),
    "wind_direction_deg": (0.0, "where the wind blows to, from the rail's heading (0: tailwind, 180: headwind)"),
    "wind_shear_exponent": (0.0, "power law u(z) = u10 (z/10 m)^a (0: the same wind at every height)"),
    "rail_inclination_deg": (0.0, "rail angle from vertical"),
    "rail_length_m": (3.0, "rail length (the rocket follows the rail until it has moved this far)"),
    "site_altitude_m": (None, "launch site altitude (default: the scenario's)"),
    "temperature_offset_k": (0.0, "air temperature minus the standard atmosphere's, at every height"),
    "baro_noise_pa": (4.0, "barometer noise, Pa rms (referred to pressure)"),
    "baro_noise_counts": (0.5, "barometer ADC noise, counts rms (ADC sensors)"),
    "baro_offset_pa": (0.0, "barometer offset error, Pa"),
    "baro_gain": (1.0, "barometer gain error (reads gain x pressure)"),
    "accel_noise_counts": (20.0, "accelerometer noise, counts rms"),
    "accel_offset_counts": (0.0, "accelerometer offset error, counts"),
    "accel_gain": (1.0, "accelerometer gain error"),
    "accel_range_g": (None, "accelerometer clipping range, g (default: the preset's)"),
    "spike_rate": (0.0, "mean number of single-sample pressure spikes per flight (Poisson)"),
    "spike_magnitude_pa": (1500.0, "spike size, Pa (sign random per spike)"),
    "baro": (None, "barometer preset (the build is made for it; a choice disperses the sensor part)"),
    "accel": (None, "accelerometer preset (as baro)"),
    "drogue_delay_s": (None, "drogue opening after the true apogee, with drogue_at_apogee = true (default: the "
                             "scenario's)"),
}
PARAM_NAMES: tuple[str, ...] = tuple(PARAMETERS)
#: Parameters whose values are preset names, not numbers.
PRESET_PARAMS: dict[str, dict[str, Any]] = {"baro": BARO_PRESETS, "accel": ACCEL_PRESETS}

# --------------------------------------------------------------------------------------------- pressure errors
#: Pluggable static-pressure error models: name -> {parameter: default}. A model is a function of
#: (pressure, Mach, per-flight parameters) registered in :mod:`.pipeline` under the same name; its parameters are
#: dispersed like the others (slots after :data:`PARAMETERS`, in this declared order). "step" is Schultz n.d.'s step
#: in pressure altitude above Mach 1 (:func:`firmware_model.flights.pressure_errors.transonic_pressure_error`);
#: "transonic_dip" is a stand-in for the signatures of real supersonic logs (the barometric altitude falls by
#: 100-800 m during the transonic passage, pressure reading high, and jumps back when the shock passes the port:
#: ../shared/flights/README.md): while the airspeed Mach is inside [mach_lo, mach_hi] the barometer reads the
#: standard pressure of ``dip_m`` lower; "real_flight" is issue 20's model of
#: what real barometers read near Mach 1 (port error, transonic dip, shock jump; parameters and ranges as
#: :class:`firmware_model.flights.pressure_errors.BaroErrorModel` and ``BARO_ERROR_RANGES``); "real_flight_ram" adds
#: issue 30's ram error in boost (``ram_cp`` q from ``ram_mach_on`` until each flight's burnout, fading over
#: ``ram_fade_s``); "none" is no error. Another model (e.g. a measured transonic signature) is added by declaring its parameters
#: here and its function in :data:`firmware_model.flights.montecarlo.pipeline.PRESSURE_ERROR_MODELS`.
PRESSURE_ERROR_PARAMS: dict[str, dict[str, float]] = {
    "none": {},
    "step": {"altitude_step_m": DEFAULT_TRANSONIC_STEP_M, "mach_on": 1.0, "mach_off": 1.0, "width_mach": 0.0},
    "transonic_dip": {"dip_m": 400.0, "mach_lo": 0.9, "mach_hi": 1.1},
    # the barometer errors of real flight (issue 20; defaults: pressure_errors.BaroErrorModel)
    "real_flight": {"cp_port": 0.04, "dip_cp": 0.06, "dip_mach_on": 0.8, "dip_mach_peak": 1.0, "dip_mach_off": 1.25,
                    "jump_m": 200.0, "jump_mach": 1.0, "jump_rise_s": 0.1, "jump_decay_s": 0.4},
    # the same plus issue 30's ram error in boost (a model of its own, so that "real_flight" specs keep their slots
    # and therefore their draws and noise; defaults: between the two flights, 0.08-0.18 of q)
    "real_flight_ram": {"cp_port": 0.04, "dip_cp": 0.06, "dip_mach_on": 0.8, "dip_mach_peak": 1.0,
                        "dip_mach_off": 1.25, "jump_m": 200.0, "jump_mach": 1.0, "jump_rise_s": 0.1,
                        "jump_decay_s": 0.4, "ram_cp": 0.1, "ram_mach_on": 0.7, "ram_fade_s": 0.2},
}

#: Integer-model methods (evaluate's METHODS without the float ideal Kalman filter).
MODEL_METHODS: tuple[str, ...] = tuple(name for name, m in METHODS.items() if m.engine == "model")
TUNINGS: tuple[str, ...] = ("default", "recommended")

_TOP_KEYS = {"scenario", "rocket", "launch", "k", "methods", "tunings", "pad_s", "descent_s", "internal_hz",
             "dispersions", "pressure_error", "chunk_flights", "max_time_s", "drogue_at_apogee"}


def _where(where: str, key: str) -> str:
    return f"{where}: {key}"


def _check_dist(where: str, name: str, value: Any) -> Any:
    """Validate one distribution; returns it normalised (constants as numbers/strings)."""
    presets = PRESET_PARAMS.get(name)
    if isinstance(value, bool):
        raise UserError(f"{_where(where, name)}: {value!r} is not a number or a distribution")
    if isinstance(value, (int, float)):
        if presets is not None or not math.isfinite(value):
            raise UserError(f"{_where(where, name)}: {value!r} is not valid here")
        return float(value)
    if isinstance(value, str):
        if presets is None or value not in presets:
            raise UserError(f"{_where(where, name)}: {value!r}: "
                            + (f"known presets: {', '.join(presets)}" if presets else "a number or a distribution"))
        return value
    if not isinstance(value, dict):
        raise UserError(f"{_where(where, name)}: {value!r} is not a number or a distribution")
    kinds = [k for k in ("normal", "uniform", "choice") if k in value]
    extra = set(value) - {"normal", "uniform", "choice", "min", "max"}
    if len(kinds) != 1 or extra:
        raise UserError(f"{_where(where, name)}: {value!r}: give exactly one of normal = [mean, sd], "
                        "uniform = [lo, hi], choice = [...] (plus min/max for normal)")
    kind = kinds[0]
    args = value[kind]
    if not isinstance(args, list) or not args:
        raise UserError(f"{_where(where, name)}: {kind} needs a list, got {args!r}")
    if kind == "choice":
        return {"choice": [_check_dist(where, name, a) for a in args]}
    if presets is not None:
        raise UserError(f"{_where(where, name)}: a preset is drawn with choice = [...], not {kind}")
    if len(args) != 2 or not all(isinstance(a, (int, float)) and not isinstance(a, bool) and math.isfinite(a)
                                 for a in args):
        raise UserError(f"{_where(where, name)}: {kind} = {args!r}: needs two finite numbers")
    a, b = float(args[0]), float(args[1])
    if kind == "normal" and b < 0:
        raise UserError(f"{_where(where, name)}: normal sd {b} < 0")
    if kind == "uniform" and b < a:
        raise UserError(f"{_where(where, name)}: uniform [{a}, {b}]: hi < lo")
    out: dict[str, Any] = {kind: [a, b]}
    for lim in ("min", "max"):
        if lim in value:
            if kind != "normal" or not isinstance(value[lim], (int, float)):
                raise UserError(f"{_where(where, name)}: {lim} only clips a normal distribution (a number)")
            out[lim] = float(value[lim])
    return out


def read_spec_file(path: str | Path) -> dict[str, Any]:
    """The raw spec dict of a ``.toml`` or ``.json`` file (a UserError naming the file and line when it does not
    parse)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise UserError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise UserError(f"{path}: not UTF-8 text") from None
    if path.suffix.lower() == ".json":
        try:
            raw = json.loads(text)
        except json.JSONDecodeError as exc:
            raise UserError(f"{path}:{exc.lineno}: {exc.msg}") from None
    else:
        try:
            raw = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise UserError(f"{path}: {exc}") from None
    if not isinstance(raw, dict):
        raise UserError(f"{path}: the spec must be a table/object")
    return raw


def load_spec(raw: dict[str, Any], where: str = "spec") -> dict[str, Any]:
    """Check a raw spec and return the complete one (every default filled in; plain data, JSON-ready)."""
    unknown = set(raw) - _TOP_KEYS
    if unknown:
        raise UserError(f"{where}: unknown key(s) {', '.join(sorted(unknown))}; known: {', '.join(sorted(_TOP_KEYS))}")
    if ("scenario" in raw) == ("rocket" in raw):
        raise UserError(f"{where}: give either scenario = NAME or a [rocket] table (motor, dry_mass_kg, diameter_m)")
    transonic: dict[str, Any] | None = None
    if "scenario" in raw:
        s = get_scenario(str(raw["scenario"]))
        rocket = {k: v for k, v in s.rocket.items()}
        launch = dict(s.launch)
        transonic = s.transonic
        name = s.name
    else:
        rocket = dict(raw["rocket"])
        launch = dict(raw.get("launch", {}))
        name = str(rocket.pop("name", "custom"))
    if "launch" in raw and "scenario" in raw:
        launch.update(raw["launch"])
    for key in ("motor", "dry_mass_kg", "diameter_m"):
        if key not in rocket:
            raise UserError(f"{where}: rocket: missing {key}")
    allowed_rocket = {"motor", "motor_scale", "dry_mass_kg", "diameter_m", "cd_scale", "drogue_cd_area_m2"}
    bad = set(rocket) - allowed_rocket
    if bad:
        raise UserError(f"{where}: rocket: unknown key(s) {', '.join(sorted(bad))}")
    if "motor_scale" in rocket:
        rocket["motor_scale"] = [float(x) for x in rocket["motor_scale"]]
    bad = set(launch) - {"site_altitude_m", "drogue_delay_s"}
    if bad:
        raise UserError(f"{where}: launch: unknown key(s) {', '.join(sorted(bad))} (site_altitude_m, drogue_delay_s)")

    k = raw.get("k", 6)
    if not isinstance(k, int) or isinstance(k, bool) or not 3 <= k <= 10:
        raise UserError(f"{where}: k = {k!r}: an integer 3..10 (sample period 2^-k s)")
    methods = raw.get("methods", list(MODEL_METHODS))
    if not isinstance(methods, list) or not methods or any(m not in MODEL_METHODS for m in methods):
        raise UserError(f"{where}: methods = {methods!r}: a list of {', '.join(MODEL_METHODS)}")
    tunings = raw.get("tunings", list(TUNINGS))
    if not isinstance(tunings, list) or not tunings or any(t not in TUNINGS for t in tunings):
        raise UserError(f"{where}: tunings = {tunings!r}: a list of {', '.join(TUNINGS)}")
    if "recommended" in tunings and k not in (5, 6, 7):
        raise UserError(f"{where}: the recommended tuning exists for k = 5..7 only (k = {k})")

    def num(key: str, default: float, lo: float, hi: float) -> float:
        v = raw.get(key, default)
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not lo <= v <= hi:
            raise UserError(f"{where}: {key} = {v!r}: a number in {lo}..{hi}")
        return float(v)

    disp_raw = raw.get("dispersions", {})
    if not isinstance(disp_raw, dict):
        raise UserError(f"{where}: [dispersions] must be a table")
    bad = set(disp_raw) - set(PARAMETERS)
    if bad:
        raise UserError(f"{where}: dispersions: unknown parameter(s) {', '.join(sorted(bad))}; known: "
                        f"{', '.join(PARAMETERS)}")
    disp: dict[str, Any] = {}
    defaults = {"site_altitude_m": float(launch.get("site_altitude_m", 0.0)), "baro": "mpx4115_12bit",
                "accel": "default", "drogue_delay_s": float(launch.get("drogue_delay_s", 0.0))}
    for pname, (default, _) in PARAMETERS.items():
        if pname in disp_raw:
            disp[pname] = _check_dist(f"{where}: dispersions", pname, disp_raw[pname])
        elif pname == "accel_range_g":
            disp[pname] = None            # the drawn accelerometer preset's own range
        else:
            disp[pname] = defaults.get(pname, default)

    pe_raw = raw.get("pressure_error")
    if pe_raw is None:
        pe_raw = {"model": "step", **(transonic or {})} if transonic is not None else {"model": "none"}
        if transonic is not None and pe_raw.get("shape", "step") == "ramp":
            pe_raw["width_mach"] = pe_raw.get("width_mach", 0.04)
        pe_raw.pop("shape", None)
    if not isinstance(pe_raw, dict) or pe_raw.get("model") not in PRESSURE_ERROR_PARAMS:
        raise UserError(f"{where}: [pressure_error] needs model = one of {', '.join(PRESSURE_ERROR_PARAMS)}")
    model = pe_raw["model"]
    pdefs = PRESSURE_ERROR_PARAMS[model]
    bad = set(pe_raw) - {"model"} - set(pdefs)
    if bad:
        raise UserError(f"{where}: pressure_error ({model}): unknown parameter(s) {', '.join(sorted(bad))}; known: "
                        f"{', '.join(pdefs) or 'none'}")
    pe = {"model": model, "params": {p: _check_dist(f"{where}: pressure_error", p, pe_raw.get(p, d))
                                     for p, d in pdefs.items()}}
    chunk = raw.get("chunk_flights", 250)
    if not isinstance(chunk, int) or isinstance(chunk, bool) or not 1 <= chunk <= 100_000:
        raise UserError(f"{where}: chunk_flights = {chunk!r}: an integer 1..100000")
    drogue = raw.get("drogue_at_apogee", False)
    if not isinstance(drogue, bool):
        raise UserError(f"{where}: drogue_at_apogee = {drogue!r}: true or false")
    return {"name": name, "rocket": rocket, "k": k, "drogue_at_apogee": drogue, "methods": methods, "tunings": tunings,
            "pad_s": num("pad_s", 2.0, 0.5, 60.0), "descent_s": num("descent_s", 5.0, 0.5, 120.0),
            "internal_hz": num("internal_hz", 256.0, 64.0, 20_000.0),
            "max_time_s": num("max_time_s", 0.0, 0.0, 3600.0),
            "dispersions": disp, "pressure_error": pe, "chunk_flights": chunk}


def fingerprint(spec: dict[str, Any]) -> str:
    """sha256 of the spec's canonical JSON (what a resume must match, with the seed and the code version)."""
    return hashlib.sha256(json.dumps(spec, sort_keys=True).encode()).hexdigest()


# --------------------------------------------------------------------------------------------- draws
def slot_names(spec: dict[str, Any]) -> tuple[str, ...]:
    """Every dispersed quantity in slot order: :data:`PARAMETERS`, then ``pressure_error.<param>``."""
    return PARAM_NAMES + tuple(f"pressure_error.{p}" for p in PRESSURE_ERROR_PARAMS[spec["pressure_error"]["model"]])


def distributions(spec: dict[str, Any]) -> dict[str, Any]:
    """slot name -> its distribution (or constant)."""
    out = dict(spec["dispersions"])
    out.update({f"pressure_error.{p}": d for p, d in spec["pressure_error"]["params"].items()})
    return out


def is_dispersed(dist: Any) -> bool:
    return isinstance(dist, dict) and not ("normal" in dist and dist["normal"][1] == 0) \
        and not ("uniform" in dist and dist["uniform"][0] == dist["uniform"][1]) \
        and not ("choice" in dist and len(set(map(str, dist["choice"]))) == 1)


def flight_rng(seed: int, flight: int) -> np.random.Generator:
    """The one generator of flight ``flight`` of a run seeded ``seed`` (see the module docstring)."""
    return np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(int(flight),)))


def _value(dist: Any, u1: float, u2: float) -> Any:
    if not isinstance(dist, dict):
        return dist
    if "uniform" in dist:
        lo, hi = dist["uniform"]
        return lo + (hi - lo) * u1
    if "choice" in dist:
        c = dist["choice"]
        return c[min(int(u1 * len(c)), len(c) - 1)]
    mean, sd = dist["normal"]
    # Box-Muller; 1 - u1 is in (0, 1] so the log is finite
    x = mean + sd * math.sqrt(-2.0 * math.log(1.0 - u1)) * math.cos(2.0 * math.pi * u2)
    if "min" in dist:
        x = max(x, dist["min"])
    if "max" in dist:
        x = min(x, dist["max"])
    return x


def draw(spec: dict[str, Any], rng: np.random.Generator) -> dict[str, Any]:
    """One flight's parameter values (slot name -> value), consuming exactly 2 x len(slots) uniforms of ``rng``."""
    names = slot_names(spec)
    u = rng.random(2 * len(names))
    dists = distributions(spec)
    return {name: _value(dists[name], float(u[2 * i]), float(u[2 * i + 1])) for i, name in enumerate(names)}


__all__ = ["MODEL_METHODS", "PARAMETERS", "PRESSURE_ERROR_PARAMS", "TUNINGS", "distributions", "draw",
           "fingerprint", "flight_rng", "is_dispersed", "load_spec", "read_spec_file", "slot_names"]

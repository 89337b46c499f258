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

from firmware_model.flights.evaluation.methods import METHODS
from firmware_model.flights.simulate.motors import MOTOR_FILES
from firmware_model.flights.simulate.pressure_errors import DEFAULT_TRANSONIC_STEP_M
from firmware_model.flights.simulate.scenarios import get_scenario
from firmware_model.flights.inputs.sensors import ACCEL_PRESETS, BARO_PRESETS
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

#: Physical range of every numeric parameter (issue 33): a constant, a uniform's ends and a normal's mean +- 6 sd
#: (after its min/max) must lie inside, so no draw leaves what a flight, a sensor or the simulator can be; a draw
#: of a normal's tail beyond 6 sd (p = 2e-9) is clipped to the range (:func:`draw`). name -> (lo, hi, unit, why).
PARAM_RANGES: dict[str, tuple[float, float, str, str]] = {
    "impulse_scale": (0.1, 10.0, "x", "a factor"),
    "burn_time_scale": (0.1, 10.0, "x", "a factor"),
    "dry_mass_scale": (0.1, 10.0, "x", "a factor"),
    "cd_scale": (0.1, 10.0, "x", "a factor"),
    "wind_speed_mps": (0.0, 50.0, "m/s", "a 100 kt gale; launches stop near 9 m/s"),
    "wind_direction_deg": (-720.0, 720.0, "deg", ""),
    "wind_shear_exponent": (0.0, 1.0, "", "the power law's exponent; 1/7 over open land"),
    "rail_inclination_deg": (0.0, 30.0, "deg", "from vertical; safety codes allow 20"),
    "rail_length_m": (0.1, 50.0, "m", ""),
    "site_altitude_m": (-500.0, 6000.0, "m", "above sea level"),
    "temperature_offset_k": (-100.0, 100.0, "K", "from the standard atmosphere"),
    "baro_noise_pa": (0.0, 10_000.0, "Pa", ""),
    "baro_noise_counts": (0.0, 10_000.0, "counts", ""),
    "baro_offset_pa": (-20_000.0, 20_000.0, "Pa", ""),
    "baro_gain": (0.5, 2.0, "", "a barometer reading half or twice the pressure is broken, not dispersed"),
    "accel_noise_counts": (0.0, 32767.0, "counts", ""),
    "accel_offset_counts": (-32767.0, 32767.0, "counts", ""),
    "accel_gain": (0.5, 2.0, "", "as baro_gain"),
    "accel_range_g": (1.0, 1000.0, "g", ""),
    "spike_rate": (0.0, 1000.0, "per flight", "the cap on spikes a flight's arrays are made for"),
    "spike_magnitude_pa": (0.0, 50_000.0, "Pa", ""),
    "drogue_delay_s": (0.0, 60.0, "s", ""),
}
#: The pressure-error models' parameter ranges (as :data:`PARAM_RANGES`).
PRESSURE_ERROR_RANGES: dict[str, tuple[float, float, str, str]] = {
    "altitude_step_m": (-5000.0, 5000.0, "m", ""), "mach_on": (0.0, 5.0, "", ""), "mach_off": (0.0, 5.0, "", ""),
    "width_mach": (0.0, 1.0, "", ""), "dip_m": (-5000.0, 5000.0, "m", ""), "mach_lo": (0.0, 5.0, "", ""),
    "mach_hi": (0.0, 5.0, "", ""), "cp_port": (-1.0, 1.0, "", "of the dynamic pressure"),
    "dip_cp": (-1.0, 1.0, "", "of the dynamic pressure"), "dip_mach_on": (0.0, 5.0, "", ""),
    "dip_mach_peak": (0.0, 5.0, "", ""), "dip_mach_off": (0.0, 5.0, "", ""), "jump_m": (-5000.0, 5000.0, "m", ""),
    "jump_mach": (0.0, 5.0, "", ""), "jump_rise_s": (0.001, 10.0, "s", ""), "jump_decay_s": (0.001, 10.0, "s", ""),
}
#: A normal's reach checked against the range, in sd (two-sided tail 2e-9).
NORMAL_REACH_SD: float = 6.0
#: [rocket] and [launch] fields: name -> (lo, hi, unit).
ROCKET_RANGES: dict[str, tuple[float, float, str]] = {
    "dry_mass_kg": (0.01, 10_000.0, "kg"), "diameter_m": (0.005, 2.0, "m"), "cd_scale": (0.1, 10.0, "x"),
    "drogue_cd_area_m2": (0.0, 100.0, "m^2")}
LAUNCH_RANGES: dict[str, tuple[float, float, str]] = {
    "site_altitude_m": (-500.0, 6000.0, "m"), "drogue_delay_s": (0.0, 60.0, "s")}
#: The motor's thrust and time scale factors.
MOTOR_SCALE_RANGE: tuple[float, float] = (0.1, 10.0)
#: Values echoed in messages are cut to this many characters.
ECHO_CHARS: int = 80


def echo(value: Any) -> str:
    """``repr(value)``, at most :data:`ECHO_CHARS` characters."""
    text = repr(value)
    return text if len(text) <= ECHO_CHARS else text[:ECHO_CHARS - 20] + f"...({len(text):,} chars)"


def clip(text: str) -> str:
    """``text`` cut to :data:`ECHO_CHARS` characters (no quotes)."""
    return text if len(text) <= ECHO_CHARS else text[:ECHO_CHARS - 20] + f"...({len(text):,} chars)"


def _number(where: str, value: Any, lo: float, hi: float, unit: str = "", why: str = "") -> float:
    """``value`` as a float, or a UserError ``WHERE: VALUE is ...; allowed: a number LO..HI UNIT (WHY)``."""
    allowed = f"allowed: a number {lo:g}..{hi:g}{' ' + unit if unit else ''}{f' ({why})' if why else ''}"
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise UserError(f"{where}: {echo(value)} is not a number; {allowed}")
    if not math.isfinite(value) or not lo <= value <= hi:
        raise UserError(f"{where}: {echo(value)} is out of range; {allowed}")
    return float(value)


def _table(where: str, value: Any) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise UserError(f"{where}: {echo(value)} is not a table; allowed: a [table] of key = value")
    return value

# --------------------------------------------------------------------------------------------- pressure errors
#: Pluggable static-pressure error models: name -> {parameter: default}. A model is a function of
#: (pressure, Mach, per-flight parameters) registered in :mod:`.pipeline` under the same name; its parameters are
#: dispersed like the others (slots after :data:`PARAMETERS`, in this declared order). "step" is Schultz n.d.'s step
#: in pressure altitude above Mach 1 (:func:`firmware_model.flights.simulate.pressure_errors.transonic_pressure_error`);
#: "transonic_dip" is a stand-in for the signatures of real supersonic logs (the barometric altitude falls by
#: 100-800 m during the transonic passage, pressure reading high, and jumps back when the shock passes the port:
#: ../shared/flights/README.md): while the airspeed Mach is inside [mach_lo, mach_hi] the barometer reads the
#: standard pressure of ``dip_m`` lower; "real_flight" is issue 20's model of
#: what real barometers read near Mach 1 (port error, transonic dip, shock jump; parameters and ranges as
#: :class:`firmware_model.flights.simulate.pressure_errors.BaroErrorModel` and ``BARO_ERROR_RANGES``);
#: "real_flight_ram" adds
#: issue 30's ram error in boost (``ram_cp`` q from ``ram_mach_on`` until each flight's burnout, fading over
#: ``ram_fade_s``); "none" is no error. Another model (e.g. a measured transonic signature) is added by declaring its
#: parameters here and its function in :data:`firmware_model.flights.montecarlo.pipeline.PRESSURE_ERROR_MODELS`.
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


def _check_dist(where: str, name: str, value: Any,  # noqa: C901 - one check per distribution kind and field, each with its own message
                rng: tuple[float, float, str, str] | None = None) -> Any:
    """Validate one distribution against the parameter's physical range ``rng``; returns it normalised (constants
    as numbers/strings). ``where`` names the spec and the table (``FILE: dispersions``)."""
    presets = PRESET_PARAMS.get(name)
    at = _where(where, name)
    if isinstance(value, bool):
        raise UserError(f"{at}: {echo(value)} is true/false; allowed: a number or a distribution")
    if isinstance(value, (int, float)):
        if presets is not None:
            raise UserError(f"{at}: {echo(value)} is a number; allowed: a preset name ({', '.join(presets)}) "
                            "or choice = [...]")
        if rng is None:
            return _number(at, value, -math.inf, math.inf)
        return _number(at, value, *rng)
    if isinstance(value, str):
        if presets is None or value not in presets:
            raise UserError(f"{at}: {echo(value)} is "
                            + (f"not a preset; allowed: {', '.join(presets)}" if presets else
                               "text; allowed: a number or a distribution"))
        return value
    if not isinstance(value, dict):
        raise UserError(f"{at}: {echo(value)} is not a number or a distribution; allowed: a number, "
                        "{normal = [mean, sd]}, {uniform = [lo, hi]} or {choice = [...]}")
    kinds = [k for k in ("normal", "uniform", "choice") if k in value]
    extra = set(value) - {"normal", "uniform", "choice", "min", "max"}
    if len(kinds) != 1 or extra:
        raise UserError(f"{at}: {echo(value)}: give exactly one of normal = [mean, sd], "
                        "uniform = [lo, hi], choice = [...] (plus min/max for normal)")
    kind = kinds[0]
    args = value[kind]
    if not isinstance(args, list) or not args:
        raise UserError(f"{at}: {kind} needs a list, got {echo(args)}")
    if kind == "choice":
        if len(args) > 1000:
            raise UserError(f"{at}: choice of {len(args):,} values; allowed: at most 1,000")
        return {"choice": [_check_dist(where, name, a, rng) for a in args]}
    if presets is not None:
        raise UserError(f"{at}: a preset is drawn with choice = [...], not {kind}")
    if len(args) != 2 or not all(isinstance(a, (int, float)) and not isinstance(a, bool) and math.isfinite(a)
                                 for a in args):
        raise UserError(f"{at}: {kind} = {echo(args)}: needs two finite numbers")
    a, b = float(args[0]), float(args[1])
    if kind == "normal" and b < 0:
        raise UserError(f"{at}: normal sd {b} < 0; allowed: sd >= 0")
    if kind == "uniform" and b < a:
        raise UserError(f"{at}: uniform [{a}, {b}]: hi < lo; allowed: lo <= hi")
    out: dict[str, Any] = {kind: [a, b]}
    for lim in ("min", "max"):
        if lim in value:
            if kind != "normal":
                raise UserError(f"{at}: {lim} only clips a normal distribution")
            out[lim] = _number(f"{at}: {lim}", value[lim], -math.inf, math.inf)
    if "min" in out and "max" in out and out["min"] > out["max"]:
        raise UserError(f"{at}: min {out['min']:g} > max {out['max']:g}; allowed: min <= max")
    if rng is not None:
        lo, hi, unit, why = rng
        if kind == "uniform":
            ends = (a, b)
        else:
            ends = (max(a - NORMAL_REACH_SD * b, out.get("min", -math.inf)),
                    min(a + NORMAL_REACH_SD * b, out.get("max", math.inf)))
            ends = (min(ends), max(ends))
        for end in ends:
            if not lo <= end <= hi:
                reach = "" if kind == "uniform" else f" (mean +- {NORMAL_REACH_SD:g} sd after min/max)"
                raise UserError(f"{at}: {kind} = {echo(args)} reaches {end:g}{reach}, out of range; allowed: values "
                                f"in {lo:g}..{hi:g}{' ' + unit if unit else ''}{f' ({why})' if why else ''}"
                                + ("; clip it with min/max" if kind == "normal" else ""))
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


def _pressure_error(pe_raw: Any, where: str, transonic: dict[str, Any] | None) -> dict[str, Any]:
    """The spec's checked [pressure_error] table ({"model", "params"}) from its raw value ``pe_raw``; when absent,
    the scenario's ``transonic`` error (a step or ramp), or none."""
    if pe_raw is None:
        pe_raw = {"model": "step", **(transonic or {})} if transonic is not None else {"model": "none"}
        if transonic is not None and pe_raw.get("shape", "step") == "ramp":
            pe_raw["width_mach"] = pe_raw.get("width_mach", 0.04)
        pe_raw.pop("shape", None)
    if not isinstance(pe_raw, dict) or not isinstance(pe_raw.get("model"), str) \
            or pe_raw.get("model") not in PRESSURE_ERROR_PARAMS:
        got = pe_raw.get("model") if isinstance(pe_raw, dict) else pe_raw
        raise UserError(f"{where}: pressure_error: model: {echo(got)}"
                        f"; allowed: a [pressure_error] table with model = one of {', '.join(PRESSURE_ERROR_PARAMS)}")
    model = pe_raw["model"]
    pdefs = PRESSURE_ERROR_PARAMS[model]
    bad = set(pe_raw) - {"model"} - set(pdefs)
    if bad:
        raise UserError(f"{where}: pressure_error ({model}): unknown parameter(s) "
                        f"{clip(', '.join(sorted(map(str, bad))))}; known: "
                        f"{', '.join(pdefs) or 'none'}")
    return {"model": model, "params": {p: _check_dist(f"{where}: pressure_error", p, pe_raw.get(p, d),
                                                      PRESSURE_ERROR_RANGES.get(p))
                                       for p, d in pdefs.items()}}


def load_spec(raw: dict[str, Any], where: str = "spec") -> dict[str, Any]:  # noqa: C901 - checks each section and key of a spec in turn, one error message each
    """Check a raw spec and return the complete one (every default filled in; plain data, JSON-ready)."""
    unknown = set(raw) - _TOP_KEYS
    if unknown:
        raise UserError(f"{where}: unknown key(s) {clip(', '.join(sorted(map(str, unknown))))}; known: "
                        f"{', '.join(sorted(_TOP_KEYS))}")
    if ("scenario" in raw) == ("rocket" in raw):
        raise UserError(f"{where}: give either scenario = NAME or a [rocket] table (motor, dry_mass_kg, diameter_m)")
    transonic: dict[str, Any] | None = None
    if "scenario" in raw:
        if not isinstance(raw["scenario"], str):
            raise UserError(f"{where}: scenario: {echo(raw['scenario'])} is not a name; allowed: a scenario name "
                            "(fwemu simulate --list)")
        try:
            s = get_scenario(raw["scenario"])
        except UserError as exc:
            raise UserError(f"{where}: scenario: {str(exc)[:400]}") from None
        rocket = {k: v for k, v in s.rocket.items()}
        launch = dict(s.launch)
        transonic = s.transonic
        name = s.name
    else:
        rocket = dict(_table(f"{where}: rocket", raw["rocket"]))
        launch = dict(_table(f"{where}: launch", raw.get("launch", {})))
        name = rocket.pop("name", "custom")
        if not isinstance(name, str) or not name.strip() or len(name) > 80:
            raise UserError(f"{where}: rocket: name: {echo(name)}; allowed: text of 1..80 characters")
    if "launch" in raw and "scenario" in raw:
        launch.update(_table(f"{where}: launch", raw["launch"]))
    for key in ("motor", "dry_mass_kg", "diameter_m"):
        if key not in rocket:
            raise UserError(f"{where}: rocket: missing {key}")
    allowed_rocket = {"motor", "motor_scale", "dry_mass_kg", "diameter_m", "cd_scale", "drogue_cd_area_m2"}
    bad = set(rocket) - allowed_rocket
    if bad:
        raise UserError(f"{where}: rocket: unknown key(s) {clip(', '.join(sorted(map(str, bad))))}; known: "
                        f"{', '.join(sorted(allowed_rocket))}")
    if not isinstance(rocket["motor"], str) or rocket["motor"] not in MOTOR_FILES:
        raise UserError(f"{where}: rocket: motor: {echo(rocket['motor'])} is not a shipped motor; allowed: "
                        f"{', '.join(MOTOR_FILES)}")
    for key, (lo, hi, unit) in ROCKET_RANGES.items():
        if key in rocket:
            rocket[key] = _number(f"{where}: rocket: {key}", rocket[key], lo, hi, unit)
    if "motor_scale" in rocket:
        ms = rocket["motor_scale"]
        if not isinstance(ms, (list, tuple)) or len(ms) != 2:
            raise UserError(f"{where}: rocket: motor_scale: {echo(ms)} is not a pair; allowed: [thrust, time] "
                            f"factors, each {MOTOR_SCALE_RANGE[0]:g}..{MOTOR_SCALE_RANGE[1]:g}")
        rocket["motor_scale"] = [_number(f"{where}: rocket: motor_scale", x, *MOTOR_SCALE_RANGE, "x") for x in ms]
    bad = set(launch) - set(LAUNCH_RANGES)
    if bad:
        raise UserError(f"{where}: launch: unknown key(s) {clip(', '.join(sorted(map(str, bad))))}; known: "
                        f"{', '.join(LAUNCH_RANGES)}")
    for key, (lo, hi, unit) in LAUNCH_RANGES.items():
        if key in launch:
            launch[key] = _number(f"{where}: launch: {key}", launch[key], lo, hi, unit)

    k = raw.get("k", 6)
    if not isinstance(k, int) or isinstance(k, bool) or not 3 <= k <= 10:
        raise UserError(f"{where}: k: {echo(k)}; allowed: an integer 3..10 (sample period 2^-k s)")
    methods = raw.get("methods", list(MODEL_METHODS))
    if not isinstance(methods, list) or not methods or any(m not in MODEL_METHODS for m in methods):
        raise UserError(f"{where}: methods: {echo(methods)}; allowed: a list of {', '.join(MODEL_METHODS)}")
    tunings = raw.get("tunings", list(TUNINGS))
    if not isinstance(tunings, list) or not tunings or any(t not in TUNINGS for t in tunings):
        raise UserError(f"{where}: tunings: {echo(tunings)}; allowed: a list of {', '.join(TUNINGS)}")
    if "recommended" in tunings and k not in (5, 6, 7):
        raise UserError(f"{where}: the recommended tuning exists for k = 5..7 only (k = {k})")

    def num(key: str, default: float, lo: float, hi: float) -> float:
        v = raw.get(key, default)
        return _number(f"{where}: {key}", v, lo, hi)

    disp_raw = raw.get("dispersions", {})
    _table(f"{where}: dispersions", disp_raw)
    bad = set(disp_raw) - set(PARAMETERS)
    if bad:
        raise UserError(f"{where}: dispersions: unknown parameter(s) {clip(', '.join(sorted(map(str, bad))))}; "
                        f"known: {', '.join(PARAMETERS)}")
    disp: dict[str, Any] = {}
    defaults = {"site_altitude_m": float(launch.get("site_altitude_m", 0.0)), "baro": "mpx4115_12bit",
                "accel": "default", "drogue_delay_s": float(launch.get("drogue_delay_s", 0.0))}
    for pname, (default, _) in PARAMETERS.items():
        if pname in disp_raw:
            disp[pname] = _check_dist(f"{where}: dispersions", pname, disp_raw[pname], PARAM_RANGES.get(pname))
        elif pname == "accel_range_g":
            disp[pname] = None            # the drawn accelerometer preset's own range
        else:
            disp[pname] = defaults.get(pname, default)

    pe = _pressure_error(raw.get("pressure_error"), where, transonic)
    chunk = raw.get("chunk_flights", 250)
    if not isinstance(chunk, int) or isinstance(chunk, bool) or not 1 <= chunk <= 100_000:
        raise UserError(f"{where}: chunk_flights: {echo(chunk)}; allowed: an integer 1..100000")
    drogue = raw.get("drogue_at_apogee", False)
    if not isinstance(drogue, bool):
        raise UserError(f"{where}: drogue_at_apogee: {echo(drogue)}; allowed: true or false")
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
    out = {name: _value(dists[name], float(u[2 * i]), float(u[2 * i + 1])) for i, name in enumerate(names)}
    for name, value in out.items():     # a normal's tail beyond NORMAL_REACH_SD sd: held inside the range
        rng = PARAM_RANGES.get(name) or PRESSURE_ERROR_RANGES.get(name.removeprefix("pressure_error."))
        if rng is not None and isinstance(value, float):
            out[name] = min(max(value, rng[0]), rng[1])
    return out


__all__ = ["MODEL_METHODS", "PARAMETERS", "PRESSURE_ERROR_PARAMS", "TUNINGS", "distributions", "draw",
           "fingerprint", "flight_rng", "is_dispersed", "load_spec", "read_spec_file", "slot_names"]

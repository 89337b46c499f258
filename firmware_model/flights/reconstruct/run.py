"""One reconstruction, of a real log or a simulated flight: what ``fwemu reconstruct`` and ``fwemu evaluate
--reference smoother`` call.

Modes (``Reconstruction.mode``):

* ``full``: IMU (3-axis accelerometer + gyroscope), GPS and barometer: position, velocity and attitude (simulated
  flights with GPS);
* ``vertical-imu``: 3-axis IMU and barometer, no GPS: the same filter (attitude from the gyroscope, specific force
  rotated into the site frame), but only the vertical channel is observable and reported;
* ``vertical-axial``: no gyroscope (or no usable 3-axis IMU): altitude and vertical velocity from the axial
  accelerometer taken as vertical and the barometer (:mod:`.vertical`).

The apogee (:mod:`.apogee`) comes from the smoother of the best mode available; a log gets both vertical modes when
it has a gyroscope, so their difference (what the axial-as-vertical assumption does on that flight) is reported.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from math import radians
from pathlib import Path
from typing import Any

import numpy as np

from firmware_model.runtime.errors import UserError
from firmware_model.flights.reconstruct.apogee import ApogeeEstimate, velocity_zero_crossing
from firmware_model.flights.reconstruct.logs import read_imu_log
from firmware_model.flights.reconstruct.rotation import tilt_deg
from firmware_model.flights.reconstruct.sensors import baro_altitude, geopotential_to_geometric, gps_preset, imu_preset
from firmware_model.flights.reconstruct.simulated import errors, reconstruct_sensed, sensed_flight
from firmware_model.flights.reconstruct.truth import gravity, truth_run
from firmware_model.flights.reconstruct.flightset import case_named, flight_set
from firmware_model.flights.reconstruct.ukf import FilterNoise, Measurements, align, run_ukf, unflat
from firmware_model.flights.reconstruct.vertical import run_vertical
from firmware_model.flights.simulate.pressure_errors import BARO_ERROR_RANGES
from firmware_model.flights.reference.apogee_reference import ground_pressure, liftoff_time, noise_scale
from firmware_model.flights.reference.charge import accelerometer_shock, recovery_charge
from firmware_model.spec import atmosphere as atm

G = 9.80665
#: Acceleration noise (m/s^2) added after the log's own recovery-charge event.
AFTER_DEPLOY_SIGMA: float = 20.0
#: A real barometer's static-port error, 1 sigma, as a fraction of the dynamic pressure: the top of the range the
#: project's barometer model draws from (measured on the shared logs: docs/flights.md).
BARO_PORT_CP: float = BARO_ERROR_RANGES["cp_port"][1]
#: A real log's second pass ends this long (s) after the first pass's apogee. After the recovery the log's section
#: hangs on its harness or tumbles; an IMU model of free flight does not describe it, and through the gyroscope
#: (a chain tight enough to carry an attitude across minutes) the smoother moved the ascent by what the descent
#: misread: on hedy, 210 s of descent put the smoothed pad tilt at 50 deg (the pad says 5) and the apogee 0.18 s
#: later than with the log cut anywhere from 36 to 130 s after liftoff (33.45-33.56 s).
TAIL_S: float = 10.0
#: The heading prior of a real log (deg). Without GPS the heading is not observable and does not enter the vertical
#: channel (a rotation about the vertical leaves vertical components alone); the prior only has to keep the sigma
#: points (+-sqrt(21) sigma) inside +-180 deg, where the rotation-vector error wraps: 60 deg put them at +-275 deg.
#: On the logs here that moved the apogees by at most 7 ms (hedy, Piccard's TeleMega and CATS).
HEADING_SIGMA_DEG: float = 10.0

@dataclass
class Reconstruction:
    name: str
    mode: str
    t: np.ndarray
    columns: dict[str, np.ndarray]          # per-sample outputs (CSV columns)
    apogee: ApogeeEstimate
    apogee_axial: ApogeeEstimate | None = None
    truth: dict[str, Any] | None = None     # simulated: truth arrays and the errors
    notes: list[str] = field(default_factory=list)
    cpu_s: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)


def _sd(P: np.ndarray) -> np.ndarray:
    return np.sqrt(np.clip(np.einsum("nii->ni", P), 0.0, None))


def _ukf_columns(run, which: str) -> dict[str, np.ndarray]:
    X = unflat(run.xf if which == "f" else run.xs)
    sd = _sd(run.Pf if which == "f" else run.Ps)
    cols = {}
    for i, a in enumerate("xyz"):
        cols[f"{which}_{a}_m"] = X["r"][:, i]
        cols[f"{which}_v{a}_mps"] = X["v"][:, i]
        cols[f"{which}_sigma_{a}_m"] = sd[:, i]
        cols[f"{which}_sigma_v{a}_mps"] = sd[:, 3 + i]
    for i in range(4):
        cols[f"{which}_q{i}"] = X["q"][:, i]
    for i, a in enumerate("xyz"):
        cols[f"{which}_sigma_att_{a}_deg"] = np.degrees(sd[:, 6 + i])
    cols[f"{which}_tilt_deg"] = tilt_deg(X["q"])
    return cols


def reconstruct_sim(name: str, imu: str = "chari", gps: str | None = "chari", seed: int = 0) -> Reconstruction:
    """A flight of the simulated set (:func:`~.flightset.flight_set`), sensed with the named presets."""
    try:
        case = case_named(name)
    except KeyError:
        raise UserError(f"sim:{name}: unknown simulated flight; known: "
                        f"{', '.join(c.name for c in flight_set())}") from None
    truth = truth_run(case)
    s = sensed_flight(truth, imu_preset(imu, accel_range=32 * G), gps_preset(gps) if gps else None, seed=seed)
    t0 = time.process_time()
    run = reconstruct_sensed(s, truth.site_asl_m)
    cpu = time.process_time() - t0
    E = errors(run, s, truth)
    cols = {**_ukf_columns(run, "f"), **_ukf_columns(run, "s")}
    X = unflat(run.xs)
    sd = _sd(run.Ps)
    ap = velocity_zero_crossing(s.t, X["r"][:, 2], X["v"][:, 2], sd[:, 2], sd[:, 5], where=f"sim:{name}")
    idx = s.truth_idx
    tr = {"pos": truth.pos[idx] - truth.pos[0], "vel": truth.vel[idx], "tilt_deg": tilt_deg(truth.quat[idx]),
          "apogee_time_s": truth.apogee_time_s, "errors": E}
    for i, a in enumerate("xyz"):
        cols[f"truth_{a}_m"] = tr["pos"][:, i]
        cols[f"truth_v{a}_mps"] = tr["vel"][:, i]
    cols["truth_tilt_deg"] = tr["tilt_deg"]
    mode = "full" if gps else "vertical-imu"
    if not gps:
        cols = _vertical_only(cols)
    return Reconstruction(name=name, mode=mode, t=s.t, columns=cols, apogee=ap, truth=tr, cpu_s=cpu,
                          notes=[f"simulated: RocketPy 6-DOF, IMU preset {imu} (range 32 g), GPS "
                                 f"{gps or 'none'}, seed {seed}"] + ([] if gps else ["no GPS: vertical channel only"]))


def residual_scale(t: np.ndarray, baro: np.ndarray, z: np.ndarray, sz: np.ndarray, sig: np.ndarray,
                   t_apo: float, half_s: float = 5.0) -> float:
    """How much a real log's smoothed altitude disagrees with its barometer near apogee beyond what the model
    expects: sqrt(mean NIS) of ``baro - z`` (variance ``sz^2 + sig^2``) within ``half_s`` of the apogee, at least 1.
    The filter's sigmas assume white barometer noise and a well-modelled accelerometer; a real log's errors are
    neither, and this factor widens the apogee's sigma by the misfit it leaves."""
    m = np.isfinite(baro) & (np.abs(t - t_apo) <= half_s)
    if m.sum() < 5:
        return 1.0
    nis = (baro[m] - z[m]) ** 2 / (sz[m] ** 2 + sig[m] ** 2)
    return max(1.0, float(np.sqrt(np.mean(nis))))


def _refit_sigma(t: np.ndarray, baro: np.ndarray, z: np.ndarray, vz: np.ndarray, sig: np.ndarray) -> np.ndarray:
    """The barometer's sigma after liftoff for a second pass: the robust scale (1.4826 MAD) of the first pass's
    residuals ``baro - z`` from the end of the fast flight (|vz| < 100 m/s) to the end of the log, at least the pad's
    figure. A real barometer in flight is noisier than on the pad (airflow over the port, ejection)."""
    moving = np.nonzero(np.abs(vz) > 5.0)[0]
    if moving.size == 0:
        return sig
    start = int(moving[0])
    m = np.isfinite(baro) & (np.arange(t.size) >= start) & (np.abs(vz) < 100.0)
    if m.sum() < 20:
        return sig
    r = baro[m] - z[m]
    mad = 1.4826 * float(np.median(np.abs(r - np.median(r))))
    out = sig.copy()
    out[start:] = np.maximum(sig[start:], mad)
    return out


#: A pause in a log longer than this (s) after liftoff ends the reconstruction there.
MAX_GAP_S: float = 1.0


def _end_at_gap(t: np.ndarray, lift_s: float) -> int:
    """The number of rows before the first pause longer than :data:`MAX_GAP_S` after liftoff (all rows without)."""
    gaps = np.nonzero((np.diff(t) > MAX_GAP_S) & (t[:-1] > lift_s))[0]
    return int(gaps[0]) + 1 if gaps.size else int(t.size)


def first_shock(t: np.ndarray, f: np.ndarray | None, after_s: float) -> float | None:
    """The first accelerometer shock after ``after_s``
    (:func:`firmware_model.flights.reference.charge.accelerometer_shock`:
    above 8 g and 4 times the median |f| of its neighbours, at least two on each side, so that a single sample at a
    5 samples/s tail counts): an ejection charge, a separation or a break-up. None without one, or without an
    accelerometer."""
    shock = accelerometer_shock(t, f, after_s)
    return None if shock is None else shock[0]


def _first_apogee(t: np.ndarray, z: np.ndarray, vz: np.ndarray, where: str, before_s: float | None) -> float:
    """The first pass's apogee time (its sigma is not needed); the end of the log if it has none."""
    zeros = np.zeros(t.size)
    try:
        return velocity_zero_crossing(t, z, vz, zeros, zeros, where=where, before_s=before_s).time_s
    except UserError:
        return float(t[-1])


def _scaled(ap: ApogeeEstimate, k: float) -> ApogeeEstimate:
    return ApogeeEstimate(time_s=ap.time_s, sigma_s=ap.sigma_s * k, altitude_m=ap.altitude_m,
                          sigma_altitude_m=ap.sigma_altitude_m * k, vz_slope_mps2=ap.vz_slope_mps2,
                          source=ap.source + (f", sigma x{k:.1f} (barometer misfit)" if k > 1.05 else ""))


def _vertical_only(cols: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The columns without the horizontal position and velocity (not observable without GPS)."""
    horizontal = ("_x_m", "_y_m", "_vx_mps", "_vy_mps")
    return {k: v for k, v in cols.items() if not (k.endswith(horizontal) and not k.startswith("truth_"))}


def _imu_setup(acc: np.ndarray, gyr: np.ndarray, pad: np.ndarray, n_pad: int, site: float, trust_s: float,
               notes: list[str]) -> tuple[FilterNoise, Any, np.ndarray]:
    """A real log's 3-axis filter: its noise (pad figures, priors for an unknown IMU), the alignment (from the pad,
    or the rail taken as vertical without one) and the saturated samples."""
    fn = FilterNoise(accel_noise=max(float(np.median(np.std(acc[pad], axis=0))) if n_pad >= 10 else 0.3, 0.1),
                     accel_bias_sigma=0.3, accel_scale_sigma=0.01, gyro_noise=radians(0.3),
                     gyro_bias_sigma=radians(0.5), gyro_scale_sigma=0.01, heading_sigma=radians(HEADING_SIGMA_DEG),
                     baro_port_cp=BARO_PORT_CP, speed_trusted_until_s=trust_s)
    if n_pad >= 10:
        al = align(acc, gyr, n_pad, fn, 0.0, site)
    else:
        fake = np.tile([0.0, 0.0, float(gravity(site))], (10, 1))
        al = align(fake, np.zeros((10, 3)), 10, fn, 0.0, site)
        al.P0[6:8, 6:8] += np.eye(2) * radians(5.0) ** 2
        al.P0[12:15, 12:15] = np.eye(3) * fn.gyro_bias_sigma ** 2
        al.P0[3:6, 3:6] = np.eye(3) * 2.0 ** 2
        notes.append(f"only {n_pad} pad samples: no pad alignment; the rail taken as vertical +-5 deg, "
                     "gyro bias unknown (+-0.5 deg/s)")
    sat = np.any(np.abs(acc) >= np.nanmax(np.abs(acc)) * 0.999, axis=1) & (np.abs(acc).max(axis=1) > 8 * G)
    return fn, al, sat


def _fill(x: np.ndarray) -> np.ndarray:
    x = np.array(x, dtype=np.float64)
    for j in range(x.shape[1]):
        ok = np.isfinite(x[:, j])
        if not ok.any():
            raise UserError("IMU column without a single number")
        x[~ok, j] = np.interp(np.nonzero(~ok)[0], np.nonzero(ok)[0], x[ok, j])
    return x


def _recovery(rec: Any, t: np.ndarray, f_ax: np.ndarray | None, lift: float, deploy_s: float | None,
              notes: list[str]) -> tuple[float | None, np.ndarray, float | None, float]:
    """The log's recovery events, with a note each in ``notes``: (the recovery charge's time, ``deploy_s`` when
    given, else the log's own charge, or None; the first pass's extra accelerometer sigma per row, nonzero after
    the charge; the first recovery event the log shows (charge or accelerometer shock), or None; the time until
    which the estimate's speed is trusted, that event's or infinity)."""
    charge = None if deploy_s is not None else recovery_charge(rec)
    deploy = deploy_s if deploy_s is not None else (None if charge is None else charge.time_s)
    extra = np.zeros(t.size)
    if deploy is not None:
        extra[t > deploy] = AFTER_DEPLOY_SIGMA
        whence = "given" if charge is None else f"{charge.evidence}: {charge.detail}, log at {charge.rate_hz:.0f}/s"
        notes.append(f"recovery charge at {deploy:.2f} s ({whence}): accelerometer trusted to "
                     f"+-{AFTER_DEPLOY_SIGMA:g} m/s^2 only after it (ejection, parachute, tumbling)")
    else:
        notes.append(f"no recovery charge in the log: accelerometer trusted to +-{AFTER_DEPLOY_SIGMA:g} m/s^2 only "
                     "after each channel's first-pass apogee (another computer's recovery, or tumbling)")
    shock = first_shock(t, f_ax, lift + 0.2)
    # the first recovery event the log shows, if any; the estimate's speed is trusted until then
    event = min((x for x in (deploy, shock) if x is not None), default=None)
    trust_s = np.inf if event is None else float(event)
    port = f"barometer: static-port error {BARO_PORT_CP:g} of the dynamic pressure (1 sigma, correlated over 1 s)"
    if event is not None:
        why = "an accelerometer shock" if event == shock else "the recovery charge"
        port += (f" until {event:.2f} s ({why}: the speed estimate is suspect after it; neither the port error "
                 "nor the Mach gate applies)")
    notes.append(port)
    return deploy, extra, event, trust_s


def reconstruct_log(path: str | Path, format: str | None = None,
                    deploy_s: float | None = None) -> Reconstruction:
    """A real log (module docstring): vertical channel, from the 3-axis IMU where the log has a gyroscope.
    ``deploy_s``: when a recovery charge fired (s on the log's axis), overriding the log's own events (e.g. the
    other flight computer's charge, which this one felt but did not log)."""
    log = read_imu_log(path, format)
    rec = log.record
    where = rec.provenance.get("source", str(path))
    t = np.asarray(rec.time_s, dtype=np.float64)
    p = np.asarray(rec.pressure_pa, dtype=np.float64)
    lift = liftoff_time(rec)
    f_ax = rec.specific_force_mps2()
    acc_log, gyr_log, tilt_log = log.accel, log.gyro, log.tilt_log
    end = _end_at_gap(t, lift)
    gap_note = []
    if end < t.size:
        gap_note = [f"the log pauses for {t[end] - t[end - 1]:.1f} s at {t[end - 1]:.2f} s: reconstructed up to there "
                    f"(no filter can propagate across a gap; {t.size - end} later rows left out)"]
        t, p = t[:end], p[:end]
        f_ax, acc_log, gyr_log, tilt_log = (None if x is None else x[:end] for x in (f_ax, acc_log, gyr_log, tilt_log))
    p0 = ground_pressure(rec)
    site = float(geopotential_to_geometric(float(atm.altitude_m(p0))))
    hb = baro_altitude(np.where(p > 0, p, np.nan), p0)
    pad = t < lift - 0.2
    noise_m = max(noise_scale(np.where(np.isfinite(hb), hb, 0.0), pad), 0.3) if pad.sum() >= 10 else 1.0
    sig = np.full(t.size, noise_m)
    notes = list(log.notes) + gap_note + [f"barometer sigma {noise_m:.2f} m (pad noise, at least 0.3 m); liftoff "
                                          f"{lift:.2f} s"]
    n_pad = int(pad.sum())
    deploy, extra, event, trust_s = _recovery(rec, t, f_ax, lift, deploy_s, notes)

    def after(tt: np.ndarray, first_apogee_s: float) -> tuple[np.ndarray, float]:
        """The second pass's extra acceleration noise and end of trust in the estimate's speed: the charge's, or
        without one (this computer fired none; the rocket's recovery was another's, or it tumbled) from the first
        pass's apogee on."""
        out = np.zeros(tt.size)
        out[tt > (deploy if deploy is not None else first_apogee_s)] = AFTER_DEPLOY_SIGMA
        return out, (trust_s if deploy is not None else min(trust_s, first_apogee_s))

    t0 = time.process_time()
    # ---- first passes, on the whole log: each channel's apogee, and the barometer's sigma from its residuals
    firsts: list[float] = []
    if f_ax is not None:
        vert = run_vertical(t, f_ax, hb, sig, site, n_pad, accel_sigma_extra=extra, baro_port_cp=BARO_PORT_CP,
                            speed_trusted_until_s=trust_s)
        sig_v = _refit_sigma(t, hb, vert.xs[:, 0], vert.xs[:, 1], sig)
        first_v = _first_apogee(t, vert.xs[:, 0], vert.xs[:, 1], where, event)
        firsts.append(first_v)
    imu = acc_log is not None and gyr_log is not None
    if imu:
        acc, gyr = _fill(acc_log), _fill(gyr_log)
        fn, al, sat = _imu_setup(acc, gyr, pad, n_pad, site, trust_s, notes)
        run = run_ukf(t, acc, gyr, sat, Measurements(gps=None, baro=hb, baro_sigma=sig), al, fn, site,
                      accel_sigma_extra=extra)
        X1 = unflat(run.xs)
        sig_u = _refit_sigma(t, hb, X1["r"][:, 2], X1["v"][:, 2], sig)
        first_u = _first_apogee(t, X1["r"][:, 2], X1["v"][:, 2], where, event)
        firsts.append(first_u)
    if not firsts:
        raise UserError(f"{where}: no accelerometer: nothing to reconstruct (the barometric parabola is the only "
                        "reference for this log)")
    # ---- the second passes end TAIL_S after the first passes' apogee (module constant's comment)
    cut = int(np.searchsorted(t, max(firsts) + TAIL_S, side="right"))
    if cut < t.size:
        notes.append(f"reconstructed to {t[cut - 1]:.2f} s, {TAIL_S:g} s after the first pass's apogee: the descent "
                     f"({t.size - cut} rows) is the barometer's (an IMU on a harness or tumbling is not free flight, "
                     "and the gyroscope would carry what it misreads back through the ascent)")
        t, hb = t[:cut], hb[:cut]
        f_ax, tilt_log = (None if x is None else x[:cut] for x in (f_ax, tilt_log))
    cols: dict[str, np.ndarray] = {"baro_altitude_m": hb}
    ap_axial = None
    if f_ax is not None:
        extra2, trust2 = after(t, first_v)
        vert = run_vertical(t, f_ax, hb, sig_v[:cut], site, n_pad, accel_sigma_extra=extra2,
                            baro_port_cp=BARO_PORT_CP, speed_trusted_until_s=trust2)
        sdv = _sd(vert.Ps)
        cols.update({"axial_z_m": vert.xs[:, 0], "axial_vz_mps": vert.xs[:, 1], "axial_sigma_z_m": sdv[:, 0],
                     "axial_sigma_vz_mps": sdv[:, 1]})
        ap_axial = velocity_zero_crossing(t, vert.xs[:, 0], vert.xs[:, 1], sdv[:, 0], sdv[:, 1],
                                          source="smoother (axial as vertical)", where=where, before_s=event)
        k_ax = residual_scale(t, hb, vert.xs[:, 0], sdv[:, 0], sig_v[:cut], ap_axial.time_s)
        ap_axial = _scaled(ap_axial, k_ax)
        notes.append(f"axial-as-vertical channel: barometer sigma in flight {sig_v[-1]:.2f} m (from the first pass's "
                     f"residuals), misfit near apogee x{k_ax:.2f}; rejected {vert.rejected}")
    if imu:
        extra2, trust2 = after(t, first_u)
        run = run_ukf(t, acc[:cut], gyr[:cut], sat[:cut], Measurements(gps=None, baro=hb, baro_sigma=sig_u[:cut]),
                      al, replace(fn, speed_trusted_until_s=trust2), site, accel_sigma_extra=extra2)
        cols.update(_vertical_only({**_ukf_columns(run, "f"), **_ukf_columns(run, "s")}))
        X = unflat(run.xs)
        sd = _sd(run.Ps)
        ap = velocity_zero_crossing(t, X["r"][:, 2], X["v"][:, 2], sd[:, 2], sd[:, 5], where=where, before_s=event)
        k_imu = residual_scale(t, hb, X["r"][:, 2], sd[:, 2], sig_u[:cut], ap.time_s)
        ap = _scaled(ap, k_imu)
        notes.append(f"3-axis IMU channel: barometer sigma in flight {sig_u[-1]:.2f} m (from the first pass's "
                     f"residuals), misfit near apogee x{k_imu:.2f}")
        mode = "vertical-imu"
        notes.append("no GPS used: vertical channel only (horizontal position and heading are not observable)")
        notes.append(f"measurements rejected: {run.rejected}")
        if tilt_log is not None:
            cols["log_tilt_deg"] = tilt_log
    else:
        assert ap_axial is not None
        ap = ap_axial
        mode = "vertical-axial"
        notes.append("no gyroscope: vertical channel only, axial specific force taken as vertical")
    cpu = time.process_time() - t0
    return Reconstruction(name=rec.name, mode=mode, t=t, columns=cols, apogee=ap, apogee_axial=ap_axial,
                          notes=notes, cpu_s=cpu, extra={"record": rec})

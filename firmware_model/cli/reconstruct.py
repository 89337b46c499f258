"""``fwemu reconstruct``: post-flight reconstruction of one flight (a real log with an accelerometer, or sim:NAME
from the simulated set) with the UKF and smoother of :mod:`firmware_model.flights.reconstruct`: per-sample state
and sigmas as CSV, a JSON summary, and PNGs (estimate error with +-2 sigma against truth for simulated flights,
trajectory, altitude / vertical velocity / tilt)."""

from __future__ import annotations

import argparse
import csv
import io
import json
import math
from pathlib import Path

import numpy as np

from firmware_model.flights.reference.apogee_reference import reference_apogee
from firmware_model.flights.reconstruct.plots import plot_errors, plot_states, plot_trajectory
from firmware_model.flights.reconstruct.run import Reconstruction, reconstruct_log, reconstruct_sim
from firmware_model.runtime.errors import UserError
from firmware_model.runtime.output import staged_folder


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]  # argparse's private class is not generic at runtime
    p = subparsers.add_parser("reconstruct", help="UKF + smoother reconstruction of one flight (CSV, JSON, PNG)",
                              description=__doc__.split("\n\n")[0].replace("``", ""))
    p.add_argument("flight", metavar="FLIGHT", help="a flight log (AltosUI CSV, CATS pair, ...) or sim:NAME")
    p.add_argument("--out", type=Path, help="output folder (default out/reconstruct/NAME)")
    p.add_argument("--format", help="reader override for a log")
    p.add_argument("--deploy-s", type=float, metavar="S",
                   help="time a recovery charge fired (s on the log's axis), instead of the log's own event")
    p.add_argument("--imu", default="chari", help="sim: IMU preset (chari, bno055; default chari)")
    p.add_argument("--gps", default="chari",
                   help="sim: GPS preset (chari, chari-dropouts), or none (vertical channel only)")
    p.add_argument("--seed", type=int, default=0, help="sim: sensor noise seed")
    p.add_argument("--no-plots", action="store_true", help="CSV and JSON only")
    p.set_defaults(func=run_reconstruct)


def states_csv(r: Reconstruction) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    names = list(r.columns)
    w.writerow(["time_s"] + names)
    cols = [np.asarray(r.columns[n], dtype=np.float64) for n in names]
    for i, t in enumerate(r.t):
        w.writerow([f"{t:.4f}"] + ["" if not math.isfinite(c[i]) else f"{c[i]:.6g}" for c in cols])
    return buf.getvalue()


def summary(r: Reconstruction, parabola: dict | None) -> dict:
    out = {"name": r.name, "mode": r.mode, "apogee": r.apogee.to_dict(),
           "apogee_axial_as_vertical": r.apogee_axial.to_dict() if r.apogee_axial else None,
           "cpu_s": r.cpu_s, "samples": int(r.t.size), "notes": r.notes}
    if r.truth is not None:
        out["truth_apogee_time_s"] = r.truth["apogee_time_s"]
        out["apogee_error_s"] = r.apogee.time_s - r.truth["apogee_time_s"]
    if parabola is not None:
        out["parabola"] = parabola
    return out


def _plots(r: Reconstruction) -> dict[str, bytes]:
    c = r.columns
    files = {}
    marks = {"smoother apogee": r.apogee.time_s}
    if r.truth is not None:
        E = r.truth["errors"]
        files["errors.png"] = plot_errors(r.t, E.f, E.s, f"{r.name}: estimate error and +-2 sigma "
                                          "(grey: filter, blue: smoother)", r.truth["apogee_time_s"])
        marks["truth"] = r.truth["apogee_time_s"]
    full = r.mode == "full"
    if "s_z_m" in c:
        rr = np.stack([c.get("s_x_m", np.zeros(r.t.size)), c.get("s_y_m", np.zeros(r.t.size)), c["s_z_m"]], axis=1)
        rt = r.truth["pos"] if r.truth is not None else None
        files["trajectory.png"] = plot_trajectory(rr, rt, f"{r.name}: trajectory ({r.mode})", horizontal=full)
        z, sz, vz, svz = c["s_z_m"], c["s_sigma_z_m"], c["s_vz_mps"], c["s_sigma_vz_mps"]
        tilt = c["s_tilt_deg"]
    else:
        z, sz, vz, svz = c["axial_z_m"], c["axial_sigma_z_m"], c["axial_vz_mps"], c["axial_sigma_vz_mps"]
        tilt = None
    extra = {}
    if "baro_altitude_m" in c:
        extra.update({"baro_t": r.t, "baro_altitude": c["baro_altitude_m"]})
    if "log_tilt_deg" in c:
        extra.update({"tilt_log_t": r.t, "tilt_log": c["log_tilt_deg"]})
    files["states.png"] = plot_states(r.t, z, sz, vz, svz, tilt, f"{r.name}: smoother, {r.mode}", marks,
                                      tilt_truth=c.get("truth_tilt_deg"), extra=extra)
    return files


def run_reconstruct(args: argparse.Namespace) -> int:
    src = str(args.flight)
    parabola = None
    if src.startswith("sim:"):
        r = reconstruct_sim(src[4:], imu=args.imu, gps=None if args.gps == "none" else args.gps, seed=args.seed)
    else:
        r = reconstruct_log(src, args.format, deploy_s=args.deploy_s)
        try:
            ref = reference_apogee(r.extra["record"])
            # the rule of evaluate --reference: they disagree beyond the parabola's uncertainty plus 2 sigma
            parabola = {"time_s": ref.time_s, "uncertainty_s": ref.uncertainty_s,
                        "agree": abs(r.apogee.time_s - ref.time_s) <= ref.uncertainty_s + 2 * r.apogee.sigma_s}
        except UserError as exc:
            parabola = {"error": str(exc)}
    out = args.out or Path("out/reconstruct") / r.name
    files = {"states.csv": states_csv(r).encode(),
             "summary.json": (json.dumps(summary(r, parabola), indent=1, default=float) + "\n").encode()}
    if not args.no_plots:
        files.update(_plots(r))
    with staged_folder(out) as stage:
        for name, data in files.items():
            (stage / name).write_bytes(data)
    a = r.apogee
    print(f"{r.name}: {r.mode}; apogee {a.time_s:.3f} s +- {a.sigma_s:.3f} (1 sigma), {a.altitude_m:.1f} m; "
          f"{r.t.size} samples in {r.cpu_s:.2f} s CPU")
    if r.truth is not None:
        print(f"  truth {r.truth['apogee_time_s']:.3f} s: error {1e3 * (a.time_s - r.truth['apogee_time_s']):+.2f} ms")
    if parabola and "time_s" in parabola:
        print(f"  parabola {parabola['time_s']:.3f} s +- {parabola['uncertainty_s']:.3f}: "
              + ("agree" if parabola["agree"] else "DISAGREE beyond their uncertainties"))
    for n in r.notes:
        print(f"  {n}")
    print(f"wrote {', '.join(str(out / n) for n in files)}")
    return 0

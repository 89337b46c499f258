"""The reconstruction's consistency study over the 24 simulated flights (docs/reconstruction.md).

    PYTHONPATH=$PWD python bench/reconstruct_consistency.py [--out build/reconstruct-study] [--img docs/img]
        [--suite chari|bno055] [--fault none|gyro-sign|accel-scale] [--only NAME ...] [--no-cost]

Per flight: share of samples (ignition to the end) with truth inside +-2 sigma for position, velocity, attitude
(filter and smoother), mean NEES, the smoother's apogee time against truth (error, sigma, covered at 2 sigma), the
barometric parabola's (error, its uncertainty, covered), kalman_accel's detection error fed the axial and the true
vertical specific force, and CPU seconds. Then the NEES averaged over the flights against its 95 % chi-square band.
Truth runs are cached (firmware_model.runtime.diskcache.cache_dir()/reconstruct-truth); the first run takes minutes.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from firmware_model.flights.plot import _png, _pyplot
from firmware_model.flights.reconstruct.flightset import flight_set
from firmware_model.flights.reconstruct.sensors import gps_preset, imu_preset
from firmware_model.flights.studies.reconstruct_study import nees_band_share, run_case
from firmware_model.runtime.output import write_file

G = 9.80665


def suite(name: str):
    # 32 g range: 12 of the 24 flights peak above the BNO055's 16 g (the paper's rocket did not)
    return imu_preset(name, accel_range=32 * G), gps_preset("chari")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("build/reconstruct-study"))
    ap.add_argument("--img", type=Path, default=None, help="write the NEES figure here too")
    ap.add_argument("--suite", default="chari")
    ap.add_argument("--fault", choices=("none", "gyro-sign", "accel-scale"), default="none")
    ap.add_argument("--only", nargs="*")
    ap.add_argument("--no-cost", action="store_true", help="skip the kalman_accel runs")
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args(argv)
    imu, gps = suite(a.suite)
    fault = {"none": {}, "gyro-sign": {"gyro_sign": -1.0}, "accel-scale": {"accel_scale": 1.01}}[a.fault]
    cases = [c for c in flight_set() if not a.only or c.name in a.only]
    res = []
    for i, c in enumerate(cases):
        try:
            r = run_case(c, imu, gps, seed=a.seed + i, with_cost=not a.no_cost, **fault)
        except Exception as exc:  # noqa: BLE001 - a diverged faulty run is a result, not a crash
            print(f"{c.name}: {exc}", file=sys.stderr)
            r = {"name": c.name, "failed": str(exc)}
        res.append(r)
        if "failed" not in r:
            print(f"{c.name:32s} F {r['inside_f']['pos']:.3f} {r['inside_f']['vel']:.3f} {r['inside_f']['att']:.3f}"
                  f"  S {r['inside_s']['pos']:.3f} {r['inside_s']['vel']:.3f} {r['inside_s']['att']:.3f}"
                  f"  apo {r['smoother_err_s']*1e3:+7.2f} ms (2s {2e3*r['smoother_apogee']['sigma_s']:.2f})"
                  f"  par {r['parabola_err_s']*1e3:+7.2f} ms  cpu {r['cpu_s']:.2f}s", flush=True)
    ok = [r for r in res if "failed" not in r]
    summary = {"suite": a.suite, "fault": a.fault, "imu": imu.to_dict(), "gps": gps.to_dict(), "flights": len(res),
               "failed": [r["name"] for r in res if "failed" in r]}
    if ok:
        for k in ("f", "s"):
            for g in ("pos", "vel", "att"):
                v = np.array([r[f"inside_{k}"][g] for r in ok])
                summary[f"inside_{k}_{g}"] = {"mean": float(v.mean()), "min": float(v.min()),
                                              "flights_below_0.9": int((v < 0.9).sum())}
            share, band, avg = nees_band_share(ok, k)
            summary[f"nees_{k}"] = {"share_in_band": share, "band": band, "mean": float(avg.mean()),
                                    "per_flight_mean": [float(np.mean(r[f"nees_{k}"][r["t"] >= 0])) for r in ok]}
        e = np.array([r["smoother_err_s"] for r in ok])
        sg = np.array([r["smoother_apogee"]["sigma_s"] for r in ok])
        pe = np.array([r["parabola_err_s"] for r in ok])
        pu = np.array([r["parabola"]["uncertainty_s"] for r in ok])
        fe = np.array([r["filter_err_s"] for r in ok])
        summary["smoother_apogee"] = {"median_abs_s": float(np.median(np.abs(e))),
                                      "worst_abs_s": float(np.abs(e).max()),
                                      "covered_2sigma": float(np.mean(np.abs(e) <= 2 * sg)),
                                      "covered_1sigma": float(np.mean(np.abs(e) <= sg)),
                                      "median_sigma_s": float(np.median(sg))}
        summary["filter_apogee"] = {"median_abs_s": float(np.median(np.abs(fe))),
                                    "worst_abs_s": float(np.abs(fe).max())}
        summary["parabola_apogee"] = {"median_abs_s": float(np.median(np.abs(pe))),
                                      "worst_abs_s": float(np.abs(pe).max()),
                                      "covered": float(np.mean(np.abs(pe) <= pu)),
                                      "median_uncertainty_s": float(np.median(pu))}
        cpu = np.array([r["cpu_s"] for r in ok])
        steps = np.array([r["n_steps"] for r in ok])
        summary["cpu_s_per_1000_steps"] = float(np.median(cpu / steps * 1000))
    rows = []
    for r in ok:
        row = {k: v for k, v in r.items() if k not in ("t", "nees_f", "nees_s")}
        rows.append(row)
    a.out.mkdir(parents=True, exist_ok=True)
    tag = f"{a.suite}-{a.fault}"
    write_file(a.out / f"study-{tag}.json", json.dumps({"summary": summary, "flights": rows}, indent=1,
                                                      default=float) + "\n")
    print(json.dumps(summary, indent=1, default=float))
    if ok:
        plt = _pyplot()
        fig, axs = plt.subplots(1, 2, figsize=(11, 3.6))
        for ax, k, lab in ((axs[0], "f", "filter"), (axs[1], "s", "smoother")):
            share, band, avg = nees_band_share(ok, k)
            n = len(ok)
            grid = ok[0]["t"][(ok[0]["t"] >= 0)][: avg.size]
            ax.plot(grid, avg, lw=0.8)
            ax.axhline(band[0], color="k", ls="--", lw=0.7)
            ax.axhline(band[1], color="k", ls="--", lw=0.7)
            ax.set_title(f"{lab}: NEES averaged over {n} flights, {100 * share:.0f} % of epochs in the 95 % band")
            ax.set_xlabel("time from ignition (s)")
            ax.set_yscale("log")
        axs[0].set_ylabel("average NEES (9 dof)")
        fig.tight_layout()
        png = _png(fig)
        write_file(a.out / f"nees-{tag}.png", png)
        if a.img is not None:
            write_file(a.img / f"reconstruct-nees-{tag}.png", png)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The reconstruction's consistency flight by flight, over noise seeds (docs/reconstruction.md, "Flight by flight:
seeds").

    PYTHONPATH=$PWD python bench/reconstruct_seeds.py [--seeds 20] [--suite chari] [--only NAME ...]
        [--out build/reconstruct-seeds] [--baro-ref pad|true]

(20 seeds x 24 flights: about 3 minutes of one core once the truth runs are cached.)

The consistency study (bench/reconstruct_consistency.py) flies each of the 24 flights with one noise seed; one
flight's errors are correlated in time, so its share of samples inside +-2 sigma is a noisy figure. Here each flight
is flown with ``--seeds`` N seeds: seed j of the flight with index i in the flight set is ``j + i``, which is what
``reconstruct_consistency.py --seed j`` gives that flight (j = 0 is the study's own run; ``--only`` does not change
a flight's seed here). The same truth, sensors, filter and smoother as the study (its ``run_case`` without the
apogee and kalman_accel parts).

Per flight and group (position, velocity, attitude; filter and smoother), over the N seeds: the mean share of
(sample, axis) pairs from ignition to the end with |error| <= 2 sigma, its standard deviation, the lowest share and
the number of seeds below 0.9. The NEES over the 9 navigation errors, averaged over the N seeds at each IMU step:
its time mean, and the share of steps where it lies in its 95 % chi-square band (9 N degrees of freedom, divided by
N), with the share above and below the band; the 3-dof NEES of each group (time and seed mean, 3 if consistent).
Each seed also records its barometer reference's error (``baro_ref_err_m``: the offset of every barometer
altitude); ``--baro-ref true`` replaces the reference by the true pad pressure without telling the filter (a
diagnosis). Writes ``seeds-<suite>.json`` (every seed's figures), ``seeds-<suite>.npz`` (per flight, per step: the
seed-averaged NEES and inside-shares, truth speed and Mach, for looking at phases of flight) and prints a markdown
table.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from firmware_model.flights.reconstruct.flightset import flight_set
from firmware_model.flights.reconstruct.sensors import (baro_altitude, geometric_to_geopotential, gps_preset,
                                                        imu_preset)
from firmware_model.flights.reconstruct.simulated import errors, inside_2sigma, reconstruct_sensed, sensed_flight
from firmware_model.flights.reconstruct.truth import truth_run
from firmware_model.runtime.output import write_file
from firmware_model.spec import atmosphere as atm

G = 9.80665
GROUPS = ("pos", "vel", "att")


def chi2_band(dof: int, n: int, p: float = 0.95) -> tuple[float, float]:
    from scipy.stats import chi2
    lo, hi = chi2.ppf([(1 - p) / 2, (1 + p) / 2], dof * n) / n
    return float(lo), float(hi)


def group_nees(e: dict[str, np.ndarray], P: np.ndarray, g: int) -> np.ndarray:
    """3-dof NEES of group ``g`` (0 pos, 1 vel, 2 att) from its own 3x3 block of the covariance."""
    err = e[GROUPS[g]]
    B = P[:, 3 * g:3 * g + 3, 3 * g:3 * g + 3]
    return np.einsum("ni,ni->n", err, np.linalg.solve(B, err[..., None])[..., 0])


def run_flight(case, index: int, seeds: int, imu, gps, baro_ref: str = "pad") -> tuple[dict, dict]:
    truth = truth_run(case)
    per_seed = []
    sums = None
    for j in range(seeds):
        s = sensed_flight(truth, imu, gps, seed=j + index)
        pres = s.notes["pressure_pa"]
        p_true = float(atm.pressure_pa(geometric_to_geopotential(truth.pos[0, 2] + truth.site_asl_m)))
        # the pad reference's error (sensed_flight's mean of the pad's first 3 s) as an altitude: the offset of
        # every barometer sample
        ok = np.isfinite(s.meas.baro)
        ref_err_m = float(np.median(s.meas.baro[ok] - baro_altitude(pres[ok], p_true)))
        if baro_ref == "true":
            s.meas.baro[:] = baro_altitude(pres, p_true)
        run = reconstruct_sensed(s, truth.site_asl_m)
        E = errors(run, s, truth)
        flight = s.t >= 0.0
        rec = {"seed": j + index, "baro_ref_err_m": ref_err_m}
        cur = {}
        for k in ("f", "s"):
            e = getattr(E, k)
            P = run.Pf if k == "f" else run.Ps
            rec[f"inside_{k}"] = inside_2sigma(e, flight)
            rec[f"nees_{k}_mean"] = float(np.mean(e["nees"][flight]))
            cur[f"nees_{k}"] = e["nees"][flight]
            for g, name in enumerate(GROUPS):
                cur[f"nees3_{k}_{name}"] = group_nees(e, P, g)[flight]
                rec[f"nees3_{k}_{name}_mean"] = float(np.mean(cur[f"nees3_{k}_{name}"]))
                cur[f"in_{k}_{name}"] = np.mean(np.abs(e[name][flight]) <= 2 * e[f"sig_{name}"][flight], axis=1)
        per_seed.append(rec)
        sums = cur if sums is None else {key: sums[key] + v for key, v in cur.items()}
    avg = {key: v / seeds for key, v in sums.items()}
    t = s.t[s.t >= 0.0]
    idx = s.truth_idx[s.t >= 0.0]
    z_asl = truth.pos[idx, 2] + truth.site_asl_m
    speed = np.linalg.norm(truth.vel[idx], axis=1)
    avg["t"] = t
    avg["speed"] = speed
    avg["mach"] = speed / np.asarray(atm.speed_of_sound_mps(geometric_to_geopotential(z_asl)), dtype=np.float64)
    avg["alt"] = truth.pos[idx, 2] - truth.pos[0, 2]
    lo, hi = chi2_band(9, seeds)
    out = {"name": case.name, "index": index, "seeds": seeds, "max_mach": truth.meta["max_mach"],
           "apogee_s": truth.apogee_time_s, "per_seed": per_seed, "nees_band": [lo, hi]}
    for k in ("f", "s"):
        for g in GROUPS:
            v = np.array([r[f"inside_{k}"][g] for r in per_seed])
            out[f"inside_{k}_{g}"] = {"mean": float(v.mean()), "std": float(v.std(ddof=1)) if seeds > 1 else 0.0,
                                      "min": float(v.min()), "below_0.9": int((v < 0.9).sum())}
            out[f"nees3_{k}_{g}"] = float(np.mean(avg[f"nees3_{k}_{g}"]))
        a = avg[f"nees_{k}"]
        out[f"nees_{k}"] = {"mean": float(a.mean()), "median": float(np.median(a)),
                            "in_band": float(np.mean((a >= lo) & (a <= hi))),
                            "above": float(np.mean(a > hi)), "below": float(np.mean(a < lo))}
    return out, avg


def table(rows: list[dict]) -> str:
    seeds = rows[0]["seeds"]
    lo, hi = rows[0]["nees_band"]
    head = (f"| flight | filter inside 2σ pos / vel / att: mean ± sd over {seeds} seeds (seeds < 0.9) "
            f"| smoother, the same | NEES filter / smoother: mean (steps in [{lo:.2f}, {hi:.2f}]) |\n"
            "|---|---|---|---|\n")
    lines = []
    for r in rows:
        cells = []
        for k in ("f", "s"):
            cells.append(" / ".join(f"{r[f'inside_{k}_{g}']['mean']:.3f} ± {r[f'inside_{k}_{g}']['std']:.2f} "
                                    f"({r[f'inside_{k}_{g}']['below_0.9']})" for g in GROUPS))
        ne = " / ".join(f"{r[f'nees_{k}']['mean']:.2f} ({100 * r[f'nees_{k}']['in_band']:.0f} %)" for k in ("f", "s"))
        lines.append(f"| {r['name']} | {cells[0]} | {cells[1]} | {ne} |")
    return head + "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("build/reconstruct-seeds"))
    ap.add_argument("--suite", default="chari")
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--only", nargs="*")
    ap.add_argument("--baro-ref", choices=("pad", "true"), default="pad",
                    help="pad: the study's barometer reference (the mean pressure of the pad's first 3 s); true: "
                         "the true pad pressure (a diagnosis: the reference's error removed, the filter not told)")
    a = ap.parse_args(argv)
    imu, gps = imu_preset(a.suite, accel_range=32 * G), gps_preset("chari")   # as reconstruct_consistency.py
    rows, arrays = [], {}
    for i, c in enumerate(flight_set()):
        if a.only and c.name not in a.only:
            continue
        t0 = time.time()
        r, avg = run_flight(c, i, a.seeds, imu, gps, a.baro_ref)
        rows.append(r)
        for key, v in avg.items():
            arrays[f"{c.name}/{key}"] = v
        print(f"{c.name:32s} F " + " ".join(f"{r[f'inside_f_{g}']['mean']:.3f}" for g in GROUPS)
              + "  S " + " ".join(f"{r[f'inside_s_{g}']['mean']:.3f}" for g in GROUPS)
              + f"  NEES {r['nees_f']['mean']:.2f} / {r['nees_s']['mean']:.2f}  ({time.time() - t0:.0f} s)",
              flush=True)
    a.out.mkdir(parents=True, exist_ok=True)
    summary = {}
    for k in ("f", "s"):
        for g in GROUPS:
            m = np.array([r[f"inside_{k}_{g}"]["mean"] for r in rows])
            summary[f"inside_{k}_{g}"] = {"mean": float(m.mean()), "min_flight_mean": float(m.min()),
                                          "flights_mean_below_0.9": int((m < 0.9).sum()),
                                          "flights_mean_below_0.93": int((m < 0.93).sum())}
    tag = a.suite if a.baro_ref == "pad" else f"{a.suite}-baro-{a.baro_ref}"
    write_file(a.out / f"seeds-{tag}.json", json.dumps({"suite": a.suite, "seeds": a.seeds, "baro_ref": a.baro_ref,
                                                        "summary": summary, "flights": rows}, indent=1) + "\n")
    np.savez_compressed(a.out / f"seeds-{tag}.npz", **arrays)
    print(table(rows))
    print(json.dumps(summary, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The reference apogee on simulated flights that end in an ejection (issue 31; docs/evaluation.md, "The reference
apogee and the log's own charge").

    PYTHONPATH=$PWD python bench/reference_ejection.py [--n 120] [--seed 31] [--out build/reference-ejection]

Builds ``--n`` ejection logs (:mod:`tests.support.ejection`: 1-DOF flights, barometer on a non-standard day with white
and correlated noise, 100 samples/s until the charge and 10 or 5 after it, the charge 0-1.5 s after the true apogee with
a pressure pulse, a lifted barometer and a one-sample accelerometer shock; a state event, an rate drop and a shock, a
shock alone at 10 or 5 samples/s throughout, or a barometer alone) and for each: the charge
:func:`flights.charge.recovery_charge` finds (against the logged charge sample), the reference
(:func:`flights.apogee_reference.reference_apogee`) and its error against the true apogee, and whether the truth lies
inside the stated half-width (2 sigma) or interval. Prints the table by evidence and tail rate, and writes
``reference-ejection.json`` (every flight) when ``--out`` is given.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from firmware_model.flights.reference.apogee_reference import reference_apogee
from firmware_model.flights.reference.charge import recovery_charge
from firmware_model.runtime.errors import UserError
from firmware_model.runtime.output import write_file
from tests.support.ejection import ejection_logs


def judge(n: int, seed: int) -> list[dict]:
    rows = []
    for lg in ejection_logs(n, seed):
        row = {"name": lg.record.name, "evidence": lg.evidence, "tail_hz": lg.tail_hz, "apogee_s": lg.apogee_s,
               "charge_s": lg.charge_s, "lag_s": lg.charge_s - lg.apogee_s, "scale": lg.scale}
        ch = recovery_charge(lg.record)
        row["charge_found_s"] = None if ch is None else ch.time_s
        row["charge_evidence"] = None if ch is None else ch.evidence
        # found: between the moment it fired (less one 100/s interval: a rate drop) and the first logged sample
        row["charge_ok"] = ch is not None and lg.charge_s - 0.0101 <= ch.time_s <= lg.logged_charge_s + 1e-6
        try:
            ref = reference_apogee(lg.record)
        except UserError as exc:
            row.update(error_s=None, covered=False, failed=str(exc))
            rows.append(row)
            continue
        err = ref.time_s - lg.apogee_s
        if ref.interval_s is not None:
            covered = ref.interval_s[0] <= lg.apogee_s <= ref.interval_s[1]
        else:
            covered = abs(err) <= ref.uncertainty_s
        row.update(error_s=err, half_width_s=ref.uncertainty_s, source=ref.source, covered=bool(covered),
                   interval=ref.interval_s, after_charge="after_charge" in ref.notes, warning="warning" in ref.notes,
                   later_than_charge=ref.time_s > lg.charge_s)
        rows.append(row)
    return rows


def summary(rows: list[dict]) -> dict:
    errs = np.array([abs(r["error_s"]) for r in rows if r.get("error_s") is not None])
    return {"n": len(rows), "failed": sum(1 for r in rows if r.get("error_s") is None),
            "median_abs_s": float(np.median(errs)) if errs.size else None,
            "worst_abs_s": float(errs.max()) if errs.size else None,
            "covered": sum(1 for r in rows if r["covered"]),
            "charge_found": sum(1 for r in rows if r["charge_ok"]),
            "intervals": sum(1 for r in rows if r.get("interval") is not None),
            "median_half_width_s": float(np.median([r["half_width_s"] for r in rows if "half_width_s" in r]))
            if any("half_width_s" in r for r in rows) else None,
            "later_than_charge": sum(1 for r in rows if r.get("later_than_charge"))}


def table(rows: list[dict]) -> str:
    out = ["| flights | n | charge found | median \\|error\\| s | worst \\|error\\| s | truth inside 2σ / interval "
           "| intervals | median half-width s | later than the charge |", "|---|---|---|---|---|---|---|---|---|"]
    groups = [("all", rows)] + [(f"{e}", [r for r in rows if r["evidence"] == e])
                                for e in ("state", "rate", "shock", "pressure")]
    groups += [(f"{h:g} samples/s after the charge", [r for r in rows if r["tail_hz"] == h]) for h in (10.0, 5.0)]
    for name, rs in groups:
        if not rs:
            continue
        s = summary(rs)
        fmt = lambda x: "—" if x is None else f"{x:.3f}"
        out.append(f"| {name} | {s['n']} | {s['charge_found']} | {fmt(s['median_abs_s'])} | {fmt(s['worst_abs_s'])} "
                   f"| {s['covered']} ({100 * s['covered'] / s['n']:.0f} %) | {s['intervals']} "
                   f"| {fmt(s['median_half_width_s'])} | {s['later_than_charge']} |")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=120)
    ap.add_argument("--seed", type=int, default=31)
    ap.add_argument("--out", type=Path, default=None)
    a = ap.parse_args(argv)
    t0 = time.process_time()
    rows = judge(a.n, a.seed)
    print(table(rows))
    print(f"\n{a.n} flights, seed {a.seed}: {time.process_time() - t0:.1f} s of CPU")
    if a.out is not None:
        write_file(a.out / "reference-ejection.json", json.dumps({"seed": a.seed, "rows": rows}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The before/after table of a firmware change, from two ``fwemu evaluate`` JSON files of the same flights.

``python -m firmware_model.flights.studies.beforeafter BEFORE.json AFTER.json [--rescore]`` prints, per method and k:
median |error|, worst |error| and the most early detection before and after, the worst over usable references
after (rows whose reference carries a warning left out, docs/evaluation.md "Flagged references"), and the median
|error| on the AltosUI logs next to AltOS's own (README "Field-ready firmware").

``--rescore`` judges both files against the reference apogee of *this* tree: each real log named by its
``source`` path is read again and :func:`flights.evaluation.setup.reference_for` recomputed (simulated flights keep
their
truth), so that a "before" run made with an older reference rule is compared on the same reference as "after".
Only detection times are taken from the files. The flights of the two files must be the same (by name and k).
"""

from __future__ import annotations

import json
import statistics
import sys
from dataclasses import asdict
from pathlib import Path
from typing import Any

from firmware_model.flights.evaluation.setup import reference_for
from firmware_model.flights.readers import read_flight
from firmware_model.runtime.errors import UserError

#: Rows of the table: (method key in the JSON, label).
ROWS: tuple[tuple[str, str], ...] = (("rec_quarter", "recursive 1/4 LSB"), ("kalman_baro", "kalman_baro"),
                                     ("kalman_accel", "kalman_accel"))


def load(path: str) -> list[dict[str, Any]]:
    """The flights of an ``fwemu evaluate`` JSON file."""
    try:
        doc = json.loads(Path(path).read_text(encoding="utf-8"))
        return list(doc["flights"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise UserError(f"{path}: not an fwemu evaluate JSON file ({exc})") from None


def rescore(flights: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """``flights`` with every real log's reference recomputed by this tree (see the module docstring)."""

    cache: dict[str, Any] = {}
    out = []
    for f in flights:
        f = json.loads(json.dumps(f))
        if f["reference"]["source"] != "truth":
            src = f["source"]
            if src not in cache:
                if not Path(src).is_file():
                    raise UserError(f"{src}: the log of flight {f['name']!r} is not there to rescore")
                cache[src] = reference_for(read_flight(src))
            ref = cache[src]
            f["reference"] = asdict(ref)                  # as FlightResult.to_dict writes it
            for d in f["methods"].values():
                d["error_s"] = None if d["time_s"] is None else d["time_s"] - ref.time_s
            if f.get("altos"):
                f["altos"]["error_s"] = f["altos"]["time_s"] - ref.time_s
        out.append(f)
    return out


def _usable(f: dict[str, Any]) -> bool:
    ref = f["reference"]
    return bool(ref.get("usable", "warning" not in str(ref.get("notes", ""))))


def stats(flights: list[dict[str, Any]], method: str, k: int) -> dict[str, Any]:
    """median / worst |error|, most early, worst over usable references, misses, n/a, AltosUI-log medians."""
    errs, usable, altos_logs, altos_own, missed, na = [], [], [], [], 0, 0
    for f in flights:
        if f["k"] != k or method not in f["methods"]:
            continue
        d = f["methods"][method]
        if d.get("failed"):
            na += 1
            continue
        if d["time_s"] is None:
            missed += 1
            continue
        e = float(d["error_s"])
        errs.append(e)
        if _usable(f):
            usable.append(abs(e))
        if f.get("altos"):
            altos_logs.append(abs(e))
            altos_own.append(abs(float(f["altos"]["error_s"])))
    if not errs:
        return {"n": 0, "missed": missed, "na": na}
    a = [abs(e) for e in errs]
    return {"n": len(errs), "median": statistics.median(a), "worst": max(a), "most_early": min(errs),
            "worst_usable": max(usable) if usable else None, "missed": missed, "na": na,
            "altosui_median": statistics.median(altos_logs) if altos_logs else None,
            "altos_median": statistics.median(altos_own) if altos_own else None}


def _cell(s: dict[str, Any]) -> str:
    if not s["n"]:
        return "—"
    text = f"{s['median']:.2f} / {s['worst']:.2f} / {s['most_early']:+.2f}"
    extra = [f"{s['missed']} missed"] if s["missed"] else []
    extra += [f"{s['na']} n/a"] if s["na"] else []
    return text + (f" ({', '.join(extra)})" if extra else "")


def table(before: list[dict[str, Any]], after: list[dict[str, Any]]) -> str:
    """The Markdown before/after table."""
    kb = sorted({(f["name"], f["k"]) for f in before})
    ka = sorted({(f["name"], f["k"]) for f in after})
    if kb != ka:
        only = sorted(set(kb) ^ set(ka))[:3]
        raise UserError(f"before and after hold different flights (e.g. {only}): compare the same set")
    ks = sorted({k for _, k in ka})
    lines = ["| method | k | before: median / worst / most early (s) | after | after, worst over usable references "
             "| after, AltosUI logs median (AltOS) |", "|---|---|---|---|---|---|"]
    for m, label in ROWS:
        for k in ks:
            b, a = stats(before, m, k), stats(after, m, k)
            if not (b["n"] or a["n"]):
                continue
            wu = "—" if not a["n"] or a["worst_usable"] is None else f"{a['worst_usable']:.2f}"
            alt = "—" if not a["n"] or a["altosui_median"] is None else \
                f"{a['altosui_median']:.2f} ({a['altos_median']:.2f})"
            lines.append(f"| {label} | {k} | {_cell(b)} | {_cell(a)} | {wu} | {alt} |")
    n = {k: sum(1 for _, kk in ka if kk == k) for k in ks}
    lines.append("")
    lines.append("n = " + ", ".join(f"{n[k]} flights at k = {k}" for k in ks) + "; errors in s, detection - reference.")
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    args = [a for a in argv if a != "--rescore"]
    if len(args) != 2:
        print("usage: python -m firmware_model.flights.studies.beforeafter BEFORE.json AFTER.json [--rescore]",
              file=sys.stderr)
        return 2
    try:
        before, after = load(args[0]), load(args[1])
        if "--rescore" in argv:
            before, after = rescore(before), rescore(after)
        print(table(before, after))
    except BrokenPipeError:            # `... | head`: the reader is gone
        sys.stdout = None              # type: ignore[assignment]  # no second failure at the final flush
        return 0
    except UserError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main(sys.argv[1:]))

"""The apogee table as a person and a machine read it: per-method summaries (:func:`summarize`), the Markdown
table (:func:`render_markdown`), the complete CSV and JSON (:func:`render_csv`, :func:`render_json`) and the
files ``fwemu evaluate`` writes (:func:`table_files`). docs/evaluation.md."""

from __future__ import annotations

import csv
import io
import json
import math
import re
from dataclasses import asdict, dataclass
from typing import Any, Sequence

import numpy as np

from firmware_model.flights.evaluation.evaluate import FlightResult
from firmware_model.flights.evaluation.methods import METHODS
from firmware_model.flights.evaluation.setup import EARLY_S, FAST_MACH
from firmware_model.runtime import markdown as md


# ---------------------------------------------------------------------------------------------------- the table
@dataclass(frozen=True)
class MethodSummary:
    """Median and worst |error| of one method over the flights it was run on (detections only), and the misses."""

    method: str
    label: str
    n: int
    detected: int
    median_abs_s: float | None
    worst_abs_s: float | None
    worst_flight: str | None
    median_s: float | None
    early: int
    late: int
    most_early_s: float | None = None          # the most negative error (None: nothing fired early)
    most_early_flight: str | None = None
    worst_usable_abs_s: float | None = None    # worst |error| over flights whose reference is usable
    worst_usable_flight: str | None = None
    unusable: int = 0                          # detections on flights whose reference carries a warning
    early_1s: int = 0                          # detections > EARLY_S before the reference (usable references)
    early_1s_flagged: int = 0                  # the same on flights whose reference carries a warning
    most_early_1s_flight: str | None = None    # the flight of the most early of those
    before_burnout: int = 0                    # detections at or before burnout (truth or estimate)
    fast: int = 0                              # detections at Mach >= FAST_MACH
    burnout_known: int = 0                     # flights (that ran) whose burnout is known
    censored: int = 0                          # not fired by the log's recovery charge (error only bounded below)
    median_abs_bound_s: float | None = None    # median |error| with the censored rows at their bounds (a lower
                                               # bound of the true median); None without censored rows


def summarize(results: Sequence[FlightResult], method: str, label: str) -> MethodSummary:
    """Summary of ``method`` (``"altos"`` for AltOS) over the flights where it ran (``n``); ``detected`` of them
    fired; median/worst over the detections; flights where the build was refused are left out of ``n``."""
    if method == "altos":
        ran = [r for r in results if r.altos_s is not None]
    else:
        ran = [r for r in results if method in r.detections and not r.detections[method].failed]
    trio = [(r.error(method), r.name, r.reference.usable) for r in ran]
    trio = [t for t in trio if t[0] is not None]
    got = [(e, name) for e, name, _ in trio]
    early_usable = [r for r in ran if r.flags(method)["early_1s"] and r.reference.usable]
    danger = {"early_1s": len(early_usable),
              "early_1s_flagged": sum(1 for r in ran if r.flags(method)["early_1s"] and not r.reference.usable),
              "most_early_1s_flight": min(early_usable, key=lambda r: r.error(method)).name if early_usable else None,
              "before_burnout": sum(1 for r in ran if r.flags(method)["before_burnout"]),
              "fast": sum(1 for r in ran if r.flags(method)["fast"]),
              "burnout_known": sum(1 for r in ran if r.burnout_s is not None)}
    bounds = [r.error_bound(method) for r in ran if r.censored(method)]
    danger["censored"] = len(bounds)
    if bounds:
        danger["median_abs_bound_s"] = float(np.median([abs(e) for e, _ in got] + [max(b or 0.0, 0.0)
                                                                                    for b in bounds]))
    if not got:
        return MethodSummary(method, label, len(ran), 0, None, None, None, None, 0, 0, **danger)
    a = np.array([abs(e) for e, _ in got])
    worst = int(np.argmax(a))
    early = min(got)
    usable = [(abs(e), name) for e, name, ok in trio if ok]
    wu = max(usable) if usable else (None, None)
    return MethodSummary(method, label, len(ran), len(got), float(np.median(a)), float(a[worst]), got[worst][1],
                         float(np.median([e for e, _ in got])), sum(e < 0 for e, _ in got),
                         sum(e > 0 for e, _ in got), float(early[0]) if early[0] < 0 else None,
                         early[1] if early[0] < 0 else None, None if wu[0] is None else float(wu[0]), wu[1],
                         len(got) - len(usable), **danger)


def table_methods(results: Sequence[FlightResult]) -> list[tuple[str, str]]:
    """(name, label) of the columns: AltOS (when any flight has it), then the methods in table order."""
    present: list[str] = []
    for r in results:
        for m in r.detections:
            if m not in present:
                present.append(m)
    cols = [("altos", "own computer")] if any(r.altos_s is not None for r in results) else []
    order = [m for m in METHODS if m in present] + [m for m in present if m not in METHODS]
    return cols + [(m, METHODS[m].label if m in METHODS else m) for m in order]


def _fmt(x: float | None, digits: int = 3) -> str:
    return "—" if x is None else f"{x:.{digits}f}"


def _fmt_err(x: float | None) -> str:
    return "miss" if x is None else f"{x:+.3f}"


def _fmt_censored(r: FlightResult, method: str) -> str:
    b = r.error_bound(method)
    return "censored" if b is None else f"≥ {b:+.3f} censored"


def _danger_marks(r: FlightResult, method: str) -> str:
    f = r.flags(method)
    marks = []
    if f["early_1s"]:
        marks.append("‼")
    if f["before_burnout"]:
        marks.append("boost")
    if f["fast"]:
        marks.append(f"M{r.mach_at[method]:.2f}")
    return (" " + " ".join(marks)) if marks else ""


_LABEL_TAIL = re.compile(r"(\s*\[[^\]]*\])?(\s+k\d+)?$")


def _flight_name(r: FlightResult) -> str:
    """The flight's label without what its own columns say (the sensing in brackets, `` kN``)."""
    return _LABEL_TAIL.sub("", r.name) or r.name


def _reference_cell(r: FlightResult) -> str:
    ref = r.reference
    if ref.lower_s is not None and ref.upper_s is not None:
        when = f"[{ref.lower_s:.3f}, {ref.upper_s:.3f}]"
    else:
        when = f"{ref.time_s:.3f}" + (f" ±{ref.uncertainty_s:.3f}" if ref.uncertainty_s else "")
    return (f"{when} ({ref.source}){'' if ref.usable else ' ⚠'}{' ≠ parabola' if ref.disagree else ''}"
            + ("" if ref.charge_s is None else f"; charge {ref.charge_s:.2f}"))


def _error_cell(r: FlightResult, m: str) -> str:
    """One method's error on one flight (s, + late): the cell of the per-flight table; times are in the CSV/JSON."""
    if m == "altos":
        if r.altos_s is None:
            return ""
        if r.censored("altos"):
            return f"{r.own_computer} {_fmt_censored(r, 'altos')}"
        return f"{r.own_computer} {_fmt_err(r.error('altos'))}{_danger_marks(r, 'altos')}"
    if m not in r.detections:
        return "—"
    d = r.detections[m]
    if d.failed:
        return "n/a"
    if r.censored(m):
        return _fmt_censored(r, m)
    return "miss" if d.time_s is None else f"{_fmt_err(r.error(m))}{_danger_marks(r, m)}"


def render_markdown(results: Sequence[FlightResult], command: str | None = None) -> str:
    """The apogee table (Schultz 2002 Tables 1-2 style) and the per-method summary, as Markdown, the way a person
    reads it (issue 34): the first figure first (how many detections of each method came more than 1 s early);
    one error per cell (the detection times are in apogee.csv and apogee.json); the flight named once (its k and
    sensing have their own columns); the log's own computer as a column only when a flight has one."""
    cols = table_methods(results)
    sums = [(label, summarize(results, m, label)) for m, label in cols]
    own = [(m, label) for m, label in cols if m == "altos"]
    methods = [(m, label) for m, label in cols if m != "altos"]
    if own and not any(r.altos_s is not None for r in results):
        own = []
    head = (["flight", "k", "sensor", "reference apogee s", "alt m"] + ["log's computer" for _ in own]
            + [label for _, label in methods])
    lines = md.header(head)
    for r in results:
        cells = [_flight_name(r), str(r.k), r.sensor, _reference_cell(r), _fmt(r.reference.altitude_m, 0)]
        cells += [_error_cell(r, m) for m, _ in own + methods]
        lines.append(md.row(cells))
    headline = "; ".join(f"{label} {s.early_1s} of {s.n}" + (f" (+{s.early_1s_flagged} on flagged references)"
                                                             if s.early_1s_flagged else "") for label, s in sums)
    out = [f"**Detections more than {EARLY_S:g} s before the reference apogee**: {headline}.", "",
           "Each cell is the error in s (detection - reference; + late; the detection times are in apogee.csv and "
           f"apogee.json); miss = never fired. ‼: more than {EARLY_S:g} s early; boost: at or before burnout; M: Mach "
           f"at the detection when >= {FAST_MACH:g} (burnout and Mach: truth for simulated flights, estimated on "
           "logs). ⚠: the reference carries a warning (the fit is not a free flight near its peak, "
           "docs/flights.md); such rows are left out of the summary's first count and of its worst on usable "
           "references. ±: the reference's uncertainty; [a, b]: the reference is an interval (0 error inside it, "
           "else the distance to its nearer end). charge: the log's recovery charge (docs/evaluation.md, \"The "
           "reference apogee and the log's own charge\"); a method that had not fired by then is \"later than the "
           "log's computer\": censored, its error only bounded below (≥ b censored), left out of the medians and "
           "counted apart." + (" ≠ parabola: the smoother's and the parabola's apogees differ by more than their "
                       "uncertainties (the reference's notes in apogee.json give both)."
                       if any(r.reference.disagree for r in results) else ""), ""] + lines
    out += [""] + md.header(["method", f"> {EARLY_S:g} s early", "of them flagged", "before burnout",
                             f"above Mach {FAST_MACH:g}", "missed", "median abs error s", "worst abs error s",
                             "worst flight", "most early s", "most early flight", "flights", "detected",
                             "censored", "early / late", "median error s"])
    for (m, label), (_, s) in zip(cols, sums):
        miss = s.n - s.detected - s.censored
        burn = f"{s.before_burnout}" + (f" of {s.burnout_known} known" if s.burnout_known < s.n else "")
        med = _fmt(s.median_abs_s) + ("" if s.median_abs_bound_s is None else f" (≥ {s.median_abs_bound_s:.3f})")
        out.append(md.row([label, s.early_1s, s.early_1s_flagged, burn, s.fast, miss, med, _fmt(s.worst_abs_s),
                           s.worst_flight or "—", "—" if s.most_early_s is None else f"{s.most_early_s:+.3f}",
                           s.most_early_flight or "—", s.n, s.detected, s.censored, f"{s.early} / {s.late}",
                           _fmt(s.median_s)]))
    notes = []
    skipped = {label: sum(1 for r in results if m in r.detections and r.detections[m].failed) for m, label in cols}
    if any(skipped.values()):
        notes.append("n/a (the method cannot run on the flight, e.g. no accelerometer): "
                     + ", ".join(f"{label} {n}" for label, n in skipped.items() if n) + ".")
    usable = [(label, s) for label, s in sums if s.unusable]
    if usable:
        notes.append("Worst abs error on usable references only: " + "; ".join(
            f"{label} {_fmt(s.worst_usable_abs_s)} ({s.worst_usable_flight}; {s.unusable} on flagged references left "
            "out)" for label, s in usable) + ".")
    if any(s.median_abs_bound_s is not None for _, s in sums):
        notes.append("Median abs error (≥ b): b is the median with the censored rows at their bounds, a lower bound "
                     "of the true median.")
    out += [""] + notes if notes else []
    if command:
        out += ["", f"Regenerate: `{command}`"]
    return "\n".join(out) + "\n"


def render_csv(results: Sequence[FlightResult]) -> str:
    """One row per flight: reference, AltOS, each method's detection time and error (empty = none)."""
    cols = table_methods(results)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    head = ["flight", "source", "k", "sensor", "n_samples", "ref_time_s", "ref_altitude_m", "ref_uncertainty_s",
            "ref_source", "ref_lower_s", "ref_upper_s", "charge_s"]
    for m, _ in cols:
        head += [f"{m}_time_s", f"{m}_error_s"]
    head += ["burnout_s", "mach_source"] + [f"{m}_mach" for m, _ in cols] + [f"{m}_early_1s" for m, _ in cols]
    head += [f"{m}_censored" for m, _ in cols]
    w.writerow(head)

    def num(x: float | None) -> str:
        return "" if x is None else repr(round(float(x), 6))

    for r in results:
        row = [r.name, r.source, r.k, r.sensor, r.n_samples, num(r.reference.time_s), num(r.reference.altitude_m),
               num(r.reference.uncertainty_s), r.reference.source, num(r.reference.lower_s),
               num(r.reference.upper_s), num(r.reference.charge_s)]
        for m, _ in cols:
            t = r.altos_s if m == "altos" else (r.detections[m].time_s if m in r.detections else None)
            row += [num(t), num(r.error(m))]
        row += [num(r.burnout_s), r.mach_source] + [num(r.mach_at.get(m)) for m, _ in cols]
        row += [int(r.flags(m)["early_1s"]) for m, _ in cols]
        row += [int(r.censored(m)) for m, _ in cols]
        w.writerow(row)
    return buf.getvalue()


def render_json(results: Sequence[FlightResult], command: str | None = None) -> str:
    """Every flight's result plus the per-method summary, JSON (sorted keys, stable)."""
    cols = table_methods(results)
    doc = {"schema": "fwemu-apogee-table/1", "command": command,
           "rule": {"detection": "time of the first sample with EVENTS.APOGEE set (APFRAC prediction not added; "
                                 "reported as predicted_s)",
                    "error": "detection time - reference time, s (positive = late)",
                    "early_1s": f"error < -{EARLY_S:g} s", "before_burnout": "detection time <= burnout_s",
                    "censored": "a real log's method that had not fired by the log's recovery charge "
                                "(reference.charge_s): error None, error_lower_bound_s its bound",
                    "interval": "reference.lower_s..upper_s set: error 0 inside, else to the nearer end",
                    "fast": f"Mach at the detection >= {FAST_MACH:g}"},
           "flights": [r.to_dict() for r in results],
           "summary": {m: asdict(summarize(results, m, label)) for m, label in cols}}
    return json.dumps(_clean(doc), indent=1, sort_keys=True) + "\n"


def _clean(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        x = float(obj)
        return round(x, 6) if math.isfinite(x) else None
    return obj


def table_files(results: Sequence[FlightResult], command: str | None = None) -> dict[str, bytes]:
    """``apogee.md``, ``apogee.csv``, ``apogee.json`` contents."""
    return {"apogee.md": render_markdown(results, command).encode(),
            "apogee.csv": render_csv(results).encode(),
            "apogee.json": render_json(results, command).encode()}

"""Apogee error against the tuning ratio R/q (Schultz 2002 Figure 10) and against the sample period 2^-k, over a set
of flights (docs/evaluation.md, "Sweeps").

* :func:`ratio_sweep`: one method (default ``kalman_baro``) built at each ratio in ``ratios`` on each flight's own
  inputs (made once per flight); error = detection - reference (s, late positive), None = never fired, or the
  reason the build was refused (e.g. gains below 2^-33 at huge ratios).
* :func:`k_sweep`: every method at each k; the flight's inputs are remade at each k (resampled from the record).

Each (flight, ratio) / (flight, k) cell is independent; ``jobs`` > 1 spreads the flights over processes (results
in input order). Rendering: Markdown, CSV and JSON here, the PNGs in :mod:`firmware_model.flights.plot`.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from firmware_model.flights.evaluation.methods import METHODS, methods_named, run_method
from firmware_model.flights.evaluation.setup import FlightSpec, flight_inputs, load_record, reference_for, sensor_config
from firmware_model.flights.evaluation.tables import _clean
from firmware_model.runtime import markdown as md
from firmware_model.runtime.errors import UserError
from firmware_model.runtime.pool import ordered_map

#: Default R/q grid: 10^1 .. 10^8, four points a decade (Schultz 2002 Figure 10 spans about 10^1 .. 10^8).
DEFAULT_RATIOS: tuple[float, ...] = tuple(float(10 ** (e / 4)) for e in range(4, 33))
DEFAULT_KS: tuple[int, ...] = (4, 5, 6, 7, 8)


@dataclass
class SweepResult:
    """``errors[flight][j]``: error (s) at ``axis[j]``, None when the method never fired; ``failed[flight][j]``:
    the reason a point could not be built/run ("" when it ran). ``kind``: ``"ratio"`` or ``"k"``; for ``"k"``
    there is one such table per method (``per_method``)."""

    kind: str
    axis: list[float]
    flights: list[str]
    method: str
    errors: dict[str, list[float | None]]
    failed: dict[str, list[str]]
    reference: dict[str, dict[str, Any]] = field(default_factory=dict)
    per_method: dict[str, dict[str, list[float | None]]] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "axis": self.axis, "flights": self.flights, "method": self.method,
                "errors": self.errors, "failed": self.failed, "reference": self.reference,
                "per_method": self.per_method}


def _ratio_job(job: tuple[FlightSpec, str, tuple[float, ...], tuple[tuple[str, Any], ...]]
               ) -> tuple[str, list[float | None], list[str], dict[str, Any]]:
    spec, method_name, ratios, overrides = job
    method = METHODS[method_name]
    record = load_record(spec.source, spec.format)
    ref = reference_for(record)
    inputs = flight_inputs(record, spec)
    sensor = sensor_config(inputs)
    time_s = np.asarray(inputs.time_s, dtype=np.float64)
    errs: list[float | None] = []
    why: list[str] = []
    for ratio in ratios:
        try:
            cfg = method.config(spec.k, sensor, **dict(overrides), ratio=ratio)
            det = run_method(method, cfg, np.asarray(inputs.adc), None if inputs.acc is None
                             else np.asarray(inputs.acc), time_s)
        except UserError as exc:
            errs.append(None)
            why.append(str(exc))
            continue
        errs.append(None if det.time_s is None else det.time_s - ref.time_s)
        why.append(f"integer wrap at {det.wrap}" if det.wrap else "")
    return spec.name, errs, why, {"time_s": ref.time_s, "uncertainty_s": ref.uncertainty_s, "source": ref.source,
                                   "usable": ref.usable}


def _k_job(job: tuple[FlightSpec, tuple[str, ...], tuple[int, ...], tuple[tuple[str, Any], ...]]
           ) -> tuple[str, dict[str, list[float | None]], list[str], dict[str, Any]]:
    spec, names, ks, overrides = job
    methods = methods_named(names)
    record = load_record(spec.source, spec.format)
    ref = reference_for(record)
    per: dict[str, list[float | None]] = {m.name: [] for m in methods}
    why: list[str] = []
    for k in ks:
        sk = dataclasses.replace(spec, k=k)
        try:
            inputs = flight_inputs(record, sk)
        except UserError as exc:
            for m in methods:
                per[m.name].append(None)
            why.append(str(exc))
            continue
        sensor = sensor_config(inputs)
        time_s = np.asarray(inputs.time_s, dtype=np.float64)
        notes = []
        for m in methods:
            try:
                det = run_method(m, m.config(k, sensor, **dict(overrides)), np.asarray(inputs.adc),
                                 None if inputs.acc is None else np.asarray(inputs.acc), time_s)
            except UserError as exc:
                per[m.name].append(None)
                notes.append(f"{m.name}: {exc}")
                continue
            per[m.name].append(None if det.time_s is None else det.time_s - ref.time_s)
        why.append("; ".join(notes))
    return spec.name, per, why, {"time_s": ref.time_s, "uncertainty_s": ref.uncertainty_s, "source": ref.source,
                                   "usable": ref.usable}


def _map(fn: Callable[[Any], Any], jobs_list: list[Any], jobs: int, scheduler: str | None) -> list[Any]:
    return ordered_map(fn, jobs_list, jobs, scheduler=scheduler)


def ratio_sweep(specs: Sequence[FlightSpec], ratios: Sequence[float] = DEFAULT_RATIOS, method: str = "kalman_baro",
                overrides: dict[str, Any] | None = None, jobs: int = 1, scheduler: str | None = None) -> SweepResult:
    """Apogee error of ``method`` at each R/q in ``ratios`` on each flight (Schultz 2002 Figure 10)."""
    if method not in METHODS or METHODS[method].program not in ("kalman_baro", "kalman_accel"):
        raise UserError(f"ratio sweep: method {method!r} has no R/q (use kalman_baro, kalman_accel or ideal_kalman)")
    if not ratios or any(not (r > 0) for r in ratios):
        raise UserError(f"ratio sweep: ratios must be > 0, got {list(ratios)}")
    ov = tuple(sorted((overrides or {}).items()))
    out = _map(_ratio_job, [(s, method, tuple(float(r) for r in ratios), ov) for s in specs], jobs, scheduler)
    res = SweepResult("ratio", [float(r) for r in ratios], [o[0] for o in out], method, {}, {})
    for name, errs, why, ref in out:
        res.errors[name], res.failed[name], res.reference[name] = errs, why, ref
    return res


def k_sweep(specs: Sequence[FlightSpec], ks: Sequence[int] = DEFAULT_KS, methods: Sequence[str] | None = None,
            overrides: dict[str, Any] | None = None, jobs: int = 1, scheduler: str | None = None) -> SweepResult:
    """Apogee error of each method at each k on each flight."""
    names = tuple(m.name for m in methods_named(methods))
    ov = tuple(sorted((overrides or {}).items()))
    out = _map(_k_job, [(s, names, tuple(int(k) for k in ks), ov) for s in specs], jobs, scheduler)
    res = SweepResult("k", [float(k) for k in ks], [o[0] for o in out], ",".join(names), {}, {})
    for m in names:
        res.per_method[m] = {}
    for name, per, why, ref in out:
        res.failed[name], res.reference[name] = why, ref
        for m in names:
            res.per_method[m][name] = per[m]
    return res


# ---------------------------------------------------------------------------------------------------- rendering
def _cell(x: float | None) -> str:
    return "miss" if x is None else f"{x:+.3f}"


def _axis_label(res: SweepResult, x: float) -> str:
    return f"{x:.3g}" if res.kind == "ratio" else str(int(x))


def render_markdown(res: SweepResult, command: str | None = None) -> str:
    """The sweep as Markdown: one row per axis point, one column per flight (k sweep: one table per method, plus the
    median and worst |error| over flights per k)."""
    lines: list[str] = []
    if res.kind == "ratio":
        tables = {res.method: res.errors}
        what = f"Apogee error (s, + late) of {res.method} against R/q"
    else:
        tables = res.per_method
        what = "Apogee error (s, + late) against k (dt = 2^-k s)"
    lines += [what + "; `miss` = never fired, `n/a` = build refused.", ""]
    for method, errors in tables.items():
        if res.kind == "k":
            lines += [f"**{METHODS[method].label if method in METHODS else method}**", ""]
        usable = [f for f in res.flights if res.reference.get(f, {}).get("usable", True)]
        head = ["R/q" if res.kind == "ratio" else "k"] + res.flights + ["median abs", "worst abs",
                                                                        "most early", "worst abs, usable references"]
        lines += md.header(head)
        for j, x in enumerate(res.axis):
            cells = [_axis_label(res, x)]
            vals = []
            for f in res.flights:
                e = errors[f][j]
                failed = res.kind == "ratio" and e is None and res.failed[f][j] and "wrap" not in res.failed[f][j]
                cells.append("n/a" if failed else _cell(e))
                if e is not None:
                    vals.append(abs(e))
            missed = sum(errors[f][j] is None for f in res.flights)
            cells.append(f"{np.median(vals):.3f}" if vals else "—")
            cells.append((f"{max(vals):.3f}" if vals else "—") + (f" ({missed} miss)" if missed else ""))
            early = [errors[f][j] for f in res.flights if errors[f][j] is not None and errors[f][j] < 0]
            cells.append(f"{min(early):+.3f}" if early else "—")
            uv = [abs(errors[f][j]) for f in usable if errors[f][j] is not None]
            cells.append(f"{max(uv):.3f}" if uv else "—")
            lines.append(md.row(cells))
        lines.append("")
    notes = sorted({w for f in res.flights for w in res.failed[f] if w})
    if notes:
        lines += ["Notes:", ""] + [f"- {n}" for n in notes[:20]] + [""]
    refs = [f"- {f}: reference {r['time_s']:.3f} s ±{r['uncertainty_s']:.3f} ({r['source']})"
            + ("" if r.get("usable", True) else " ⚠ flagged: left out of the usable-references column")
            for f, r in res.reference.items()]
    lines += refs
    if command:
        lines += ["", f"Regenerate: `{command}`"]
    return "\n".join(lines) + "\n"


def render_csv(res: SweepResult) -> str:
    """Long form: method, flight, axis value, error (empty = miss), note."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["method", "flight", "ratio" if res.kind == "ratio" else "k", "error_s", "note"])
    tables = {res.method: res.errors} if res.kind == "ratio" else res.per_method
    for method, errors in tables.items():
        for f in res.flights:
            for j, x in enumerate(res.axis):
                e = errors[f][j]
                w.writerow([method, f, _axis_label(res, x) if res.kind == "k" else repr(x),
                            "" if e is None else repr(round(e, 6)), res.failed[f][j] if res.kind == "ratio" else
                            res.failed[f][j]])
    return buf.getvalue()


def render_json(res: SweepResult, command: str | None = None) -> str:
    return json.dumps(_clean({"schema": "fwemu-sweep/1", "command": command, **res.to_dict()}), indent=1,
                      sort_keys=True) + "\n"


__all__ = ["DEFAULT_RATIOS", "DEFAULT_KS", "SweepResult", "ratio_sweep", "k_sweep", "render_markdown", "render_csv",
           "render_json"]

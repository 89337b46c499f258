"""Monte Carlo rows on disk and what they say: encoding (Parquet via pyarrow, CSV without it), merging the committed
chunk files in index order, the per-(method, tuning) summary with Wilson intervals, and the two figures.

Probabilities are over every flight the method ran on (``status`` "ok"); a flight whose simulation did not end
within the record bound is reported as ``unfinished`` and left out; a build the gain design refused as
``build_failed``. Wilson score intervals (Wilson 1927) at 95 %: for x events in n flights,
``(p + z^2/2n +- z sqrt(p(1-p)/n + z^2/4n^2)) / (1 + z^2/n)``, z = 1.959964; unlike the normal approximation it
stays inside [0, 1] and is informative at x = 0 (upper bound about 3.84 / n, the "rule of three" region).
"""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np

from firmware_model.runtime.errors import UserError
from firmware_model.runtime.output import open_atomic, write_file

Z95 = 1.959963984540054
#: Events whose probability the summary reports: row column -> label.
EVENT_COLUMNS: dict[str, str] = {"early_05": "P(> 0.5 s early)", "early_1": "P(> 1 s early)",
                                 "missed": "P(missed)", "before_burnout": "P(fired before burnout)"}


def have_pyarrow() -> bool:
    try:
        import pyarrow  # noqa: F401 - only whether it imports: the optional 'montecarlo' extra
    except ImportError:
        return False
    return True


# --------------------------------------------------------------------------------------------- encoding
def _csv_cell(v: Any) -> str:
    if isinstance(v, (bool, np.bool_)):
        return "1" if v else "0"
    if isinstance(v, (float, np.floating)):
        return "" if math.isnan(v) else repr(float(v))
    return str(v)


def encode(cols: dict[str, Any], fmt: str) -> bytes:
    """One chunk's columns as a Parquet file (``fmt`` "parquet") or CSV text with a header ("csv"). Same columns,
    same bytes: the encodings are deterministic (no timestamps)."""
    names = list(cols)
    if fmt == "parquet":
        import pyarrow as pa
        import pyarrow.parquet as pq

        table = pa.table({n: pa.array(list(cols[n]) if np.asarray(cols[n]).dtype == object else np.asarray(cols[n]))
                          for n in names})
        buf = io.BytesIO()
        pq.write_table(table, buf, compression="zstd")
        return buf.getvalue()
    if fmt != "csv":
        raise UserError(f"--format {fmt!r}: parquet or csv")
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(names)
    arrays = [np.asarray(cols[n]) for n in names]
    for i in range(len(arrays[0]) if arrays else 0):
        w.writerow([_csv_cell(a[i].item() if hasattr(a[i], "item") else a[i]) for a in arrays])
    return out.getvalue().encode()


def chunk_rows(path: Path, fmt: str) -> int | None:
    """The number of rows of a chunk file, or None when it is not whole (a Parquet file whose magic bytes, footer
    or row groups do not read; a CSV without its header or with a cut last line): ``--resume`` redoes it."""
    try:
        if fmt == "parquet":
            import pyarrow.parquet as pq

            with open(path, "rb") as f:
                head = f.read(4)
                f.seek(-4, 2)
                if head != b"PAR1" or f.read(4) != b"PAR1":
                    return None
            return int(pq.read_table(path).num_rows)
        data = path.read_bytes()
        if not data.endswith(b"\n") or not data.startswith(b"flight,"):
            return None
        return data.count(b"\n") - 1
    except Exception:      # noqa: BLE001 - any failure to read it back means it is not a whole chunk
        return None


def merge(paths: Iterable[Path], dest: Path, fmt: str) -> None:
    """Concatenate chunk files (in the given order) into ``dest`` atomically (streamed: one chunk in memory)."""
    if fmt == "parquet":
        import pyarrow.parquet as pq

        with open_atomic(dest, "wb") as f:
            writer = None
            for p in paths:
                t = pq.read_table(p)
                if writer is None:
                    writer = pq.ParquetWriter(f, t.schema, compression="zstd")
                writer.write_table(t)
            if writer is not None:
                writer.close()
        return
    with open_atomic(dest, "wb") as f:
        for i, p in enumerate(paths):
            data = p.read_bytes()
            if i:
                data = data[data.index(b"\n") + 1:]
            f.write(data)


def read_rows(path: Path, columns: Iterable[str] | None = None) -> dict[str, np.ndarray]:
    """The rows file as columns (numpy arrays; strings as object arrays)."""
    cols = None if columns is None else list(columns)
    if path.suffix == ".parquet":
        import pyarrow as pa
        import pyarrow.parquet as pq

        t = pq.read_table(path, columns=cols)
        out = {}
        for name in t.column_names:
            col = t.column(name)
            if pa.types.is_string(col.type) or pa.types.is_large_string(col.type):
                # a few distinct strings (method, tuning, status, preset): one Python object each, not one per row
                d = col.combine_chunks().dictionary_encode()
                out[name] = np.array(d.dictionary.to_pylist(), dtype=object)[d.indices.to_numpy()]
            else:
                out[name] = col.to_numpy()
        return out
    with open(path, newline="") as f:
        rd = csv.reader(f)
        head = next(rd)
        data = list(rd)
    out = {}
    for j, name in enumerate(head):
        if cols is not None and name not in cols:
            continue
        vals = [r[j] for r in data]
        out[name] = _parse_column(name, vals)
    return out


_BOOL = {"fired", "early_05", "early_1", "missed", "before_burnout"}
_STR = {"method", "tuning", "status"}


def _parse_column(name: str, vals: list[str]) -> np.ndarray:
    if name in _BOOL:
        return np.array([v == "1" for v in vals])
    if name == "flight":
        return np.array([int(v) for v in vals], dtype=np.int64)
    if name in _STR:
        return np.array(vals, dtype=object)
    try:
        return np.array([float(v) if v != "" else math.nan for v in vals])
    except ValueError:
        return np.array(vals, dtype=object)


# --------------------------------------------------------------------------------------------- statistics
def wilson(x: int, n: int, z: float = Z95) -> tuple[float, float]:
    """Wilson score interval for x successes in n trials (n = 0: (0, 1))."""
    if n == 0:
        return 0.0, 1.0
    p = x / n
    den = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    # at x = 0 and x = n the bound is exactly 0 or 1 (the float sum can miss it by an ulp)
    return (0.0 if x == 0 else max(0.0, centre - half)), (1.0 if x == n else min(1.0, centre + half))


def flights_for(p: float, events: int = 1, confidence: float = 0.95) -> int:
    """Flights needed so that an event of probability ``p`` shows at least ``events`` times with probability
    ``confidence`` (Poisson approximation; events = 1: n = -ln(1 - confidence) / p, 2,996 for 1 in 1,000)."""
    from math import exp, factorial

    n = 1
    lo, hi = 1, int(1e9)
    while lo < hi:
        n = (lo + hi) // 2
        lam = n * p
        miss = sum(exp(-lam) * lam ** k / factorial(k) for k in range(events))
        if 1 - miss >= confidence:
            hi = n
        else:
            lo = n + 1
    return lo


def _spearman(x: np.ndarray, y: np.ndarray) -> float:
    if x.size < 3 or np.all(x == x[0]) or np.all(y == y[0]):
        return 0.0
    rx = np.argsort(np.argsort(x, kind="stable"), kind="stable").astype(float)
    ry = np.argsort(np.argsort(y, kind="stable"), kind="stable").astype(float)
    c = np.corrcoef(rx, ry)[0, 1]
    return 0.0 if not np.isfinite(c) else float(c)


def summarize(cols: dict[str, np.ndarray], dispersed: Sequence[str]) -> list[dict[str, Any]]:
    """One dict per (method, tuning), in the rows' order of first appearance: counts, error quantiles, each event
    of :data:`EVENT_COLUMNS` with its Wilson interval, and the dispersed parameter with the largest |Spearman
    rank correlation| with the error (over the flights that fired)."""
    method, tuning, status = cols["method"], cols["tuning"], cols["status"]
    out = []
    combos = list(dict.fromkeys(zip(method.tolist(), tuning.tolist())))
    for m, t in combos:
        sel = (method == m) & (tuning == t)
        ok = sel & (status == "ok")
        n = int(ok.sum())
        err = cols["error_s"][ok & cols["fired"]]
        row: dict[str, Any] = {"method": m, "tuning": t, "flights": n, "fired": int(err.size),
                               "unfinished": int((sel & (status == "unfinished")).sum()),
                               "build_failed": int((sel & (status == "build_failed")).sum())}
        q = (0.001, 0.01, 0.05, 0.5, 0.95, 0.99, 0.999)
        row["error_quantiles_s"] = {str(p): float(np.quantile(err, p)) for p in q} if err.size else {}
        row["error_min_s"] = float(err.min()) if err.size else None
        row["error_max_s"] = float(err.max()) if err.size else None
        for c, label in EVENT_COLUMNS.items():
            x = int((cols[c] & ok).sum())
            lo, hi = wilson(x, n)
            row[c] = {"count": x, "p": x / n if n else None, "wilson95": [lo, hi]}
        best, rho = None, 0.0
        fired_ok = ok & cols["fired"]
        for p in dispersed:
            v = cols.get(f"p_{p}")
            if v is None or v.dtype == object:
                continue
            r = _spearman(v[fired_ok].astype(float), cols["error_s"][fired_ok])
            if abs(r) > abs(rho):
                best, rho = p, r
        row["most_influential"] = {"parameter": best, "spearman": rho}
        out.append(row)
    return out


def _pct(p: dict[str, Any]) -> str:
    if p["p"] is None:
        return "—"
    lo, hi = p["wilson95"]
    return f"{p['count']} ({100 * p['p']:.2f} %, {100 * lo:.2f}–{100 * hi:.2f})"


def render_markdown(summary: list[dict[str, Any]], title: str) -> str:
    """The summary as Markdown: one row per (method, tuning)."""
    lines = [f"### {title}", "",
             "Events: count (rate, 95 % Wilson interval). Error = detection - true apogee, s (+ late).", "",
             "| method | tuning | flights | " + " | ".join(EVENT_COLUMNS.values())
             + " | error p1 / p50 / p99 s | min / max s | most influential (Spearman) |",
             "|---|---|---|" + "---|" * len(EVENT_COLUMNS) + "---|---|---|"]
    for r in summary:
        q = r["error_quantiles_s"]
        qs = "—" if not q else f"{q['0.01']:+.3f} / {q['0.5']:+.3f} / {q['0.99']:+.3f}"
        mm = "—" if r["error_min_s"] is None else f"{r['error_min_s']:+.3f} / {r['error_max_s']:+.3f}"
        mi = r["most_influential"]
        inf = "—" if mi["parameter"] is None else f"{mi['parameter']} ({mi['spearman']:+.2f})"
        extra = ""
        if r["unfinished"] or r["build_failed"]:
            extra = f" (+{r['unfinished']} unfinished, {r['build_failed']} build refused)"
        lines.append(f"| {r['method']} | {r['tuning']} | {r['flights']}{extra} | "
                     + " | ".join(_pct(r[c]) for c in EVENT_COLUMNS) + f" | {qs} | {mm} | {inf} |")
    return "\n".join(lines) + "\n"


def write_summary(folder: Path, summary: list[dict[str, Any]], meta: dict[str, Any], title: str) -> None:
    write_file(folder / "summary.md", render_markdown(summary, title))
    write_file(folder / "summary.json", json.dumps({"meta": meta, "summary": summary}, indent=1, sort_keys=True,
                                                   default=str) + "\n")


# --------------------------------------------------------------------------------------------- figures
def write_figures(folder: Path, cols: dict[str, np.ndarray], summary: list[dict[str, Any]], title: str) -> list[Path]:
    """``error_cdf.png`` (empirical CDF of the error per method and tuning; misses drawn at the right edge) and
    ``error_vs_dispersion.png`` (per method and tuning, the error against its most influential dispersion).
    Nothing (an empty list) without matplotlib."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return []
    written = []
    fig, axes = plt.subplots(1, 2, figsize=(13, 5), sharey=True)
    for ax, tun in zip(axes, ("default", "recommended")):
        for r in summary:
            if r["tuning"] != tun:
                continue
            sel = (cols["method"] == r["method"]) & (cols["tuning"] == tun) & (cols["status"] == "ok")
            e = np.sort(cols["error_s"][sel & cols["fired"]])
            n = int(sel.sum())
            if n == 0:
                continue
            ax.step(e, np.arange(1, e.size + 1) / n, where="post", label=f"{r['method']} (miss {n - e.size})")
        ax.axvline(-0.5, color="k", lw=0.6, ls="--")
        ax.axvline(-1.0, color="r", lw=0.6, ls="--")
        ax.set_xlabel("detection - true apogee (s)")
        ax.set_title(f"{title}: {tun} tuning")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    axes[0].set_ylabel("fraction of flights")
    fig.tight_layout()
    p = folder / "error_cdf.png"
    buf = io.BytesIO()
    fig.savefig(buf, dpi=90)
    plt.close(fig)
    write_file(p, buf.getvalue())
    written.append(p)
    n = len(summary)
    ncol = min(5, n)
    nrow = (n + ncol - 1) // ncol
    fig, axes = plt.subplots(nrow, ncol, figsize=(3.2 * ncol, 2.8 * nrow), squeeze=False)
    for ax, r in zip(axes.flat, summary):
        par = r["most_influential"]["parameter"]
        sel = (cols["method"] == r["method"]) & (cols["tuning"] == r["tuning"]) & (cols["status"] == "ok") \
            & cols["fired"]
        if par is not None:
            ax.plot(cols[f"p_{par}"][sel], cols["error_s"][sel], ".", ms=1.5, alpha=0.5)
            ax.set_xlabel(f"{par} (ρ {r['most_influential']['spearman']:+.2f})", fontsize=8)
        ax.set_title(f"{r['method']} / {r['tuning']}", fontsize=9)
        ax.axhline(0, color="k", lw=0.5)
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    axes[0][0].set_ylabel("error (s)")
    fig.tight_layout()
    p = folder / "error_vs_dispersion.png"
    buf = io.BytesIO()
    fig.savefig(buf, dpi=90)
    plt.close(fig)
    write_file(p, buf.getvalue())
    written.append(p)
    return written


__all__ = ["EVENT_COLUMNS", "chunk_rows", "encode", "flights_for", "have_pyarrow", "merge", "read_rows",
           "render_markdown",
           "summarize", "wilson", "write_figures", "write_summary"]

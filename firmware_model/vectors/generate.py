"""Golden vectors for microcontroller ports (docs/vectors.md).

A *vector set* is a directory::

    <out>/manifest.json        every generated file with its SHA-256 (and the set kind)
    <out>/schema.json          JSON Schema of a case JSON
    <out>/cases/<name>.json    one case: description, build config, constants, inputs, expected words
    <out>/cases/<name>.h       the same data as C99 ``const`` arrays and ``#define`` constants
    <out>/c/cases.h            the table of every case for vectors/c/harness.c
    <out>/c/cases_avr.h        (full set only) the subset that fits an ATmega2560, for ``make -C vectors/c avr``

Expected words come from the 68000 firmware run on the emulated CPU (:mod:`firmware_model.firmware.harness`) and are
cross-checked, every word of every sample, against the numpy integer model (:func:`firmware_model.model.run.run_model`)
before anything is written. ``generator="model"`` (model only) exists for bootstrapping and is marked as such in
every file. Output is deterministic to the byte: sorted keys, floats with 12 significant digits, no timestamps.
Files are written into a temporary directory first and moved into place only when everything succeeded.
"""

from __future__ import annotations

import itertools
import json
from dataclasses import dataclass
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from firmware_model.model.streams import (
    ACC_PROGRAMS,
    read_stream_csv,
)
from firmware_model.runtime import output
from firmware_model.runtime.errors import UserError
from firmware_model.runtime.hashing import sha256_bytes, sha256_file
from firmware_model.runtime.output import worker_init
from firmware_model.runtime.pool import end_pool, start_pool
from firmware_model.runtime.progress import Progress
from firmware_model.flights.evaluation.evalset import shared_dir
from firmware_model.spec.config import PROGRAMS, BuildConfig, load_config
from firmware_model.vectors.c_header import (
    _INT32_MIN,
    _c_expected,
    _c_i32,
    _c_rows,
    alt_table_files,
    case_header_parts,
    cases_table_header,
)
from firmware_model.vectors.case_json import _json_rows, _json_values, case_json_parts
from firmware_model.vectors.cases import AVR_CASES, CaseSpec, case_matrix, case_name, grid_case_specs, tail_case_specs
from firmware_model.vectors.compute import CaseResult, compute_case
from firmware_model.vectors.manifest import manifest_bytes
from firmware_model.vectors.schema import schema_bytes


def _sha256_or_none(path: Path) -> str | None:
    """The file's SHA-256, or None when it cannot be read (missing from a vector set)."""
    try:
        return sha256_file(path)
    except OSError:
        return None


def _row_texts(rows: Any) -> tuple[str, str]:
    """``(_json_rows(rows), _c_expected(rows))`` with each row's numbers converted to text once: a row of Python
    ints prints as ``str(row)`` = ``"[" + ", ".join(map(str, row)) + "]"``, the JSON row, and the same numbers
    make the C row unless one is INT32_MIN (then :func:`_c_expected`'s spelling). Rows that are not lists of
    Python ints are formatted value by value by those two functions."""
    if not (isinstance(rows, list) and all(type(r) is list for r in rows)
            and set(map(type, itertools.chain.from_iterable(rows))) <= {int}):
        return _json_rows(rows), _c_expected(rows)
    text = [str(r)[1:-1] for r in rows]
    json_rows = ",\n  ".join(["[" + t + "]" for t in text])
    c_rows = ",\n".join(["    { " + t + " }" if _INT32_MIN not in r else
                          "    { " + ", ".join(_c_i32(v) for v in r) + " }" for t, r in zip(text, rows)])
    return json_rows, c_rows


def render_case(res: CaseResult) -> tuple[bytes, bytes]:
    """``(case_json(res), case_header(res))`` encoded, with each row of expected words converted to text once for
    both files: a row of Python ints prints as ``str(row)`` = ``"[" + ", ".join(map(str, row)) + "]"``, the JSON
    row, and the same numbers make the C row unless one is INT32_MIN (then :func:`_c_expected`'s spelling). The
    number-to-text conversion is most of the rendering; the bytes equal the two functions'
    (tests/vectors/test_generate.py)."""
    json_rows, c_rows = _row_texts(res.words)
    stream = res.spec.stream
    json_b = "".join(case_json_parts(res, [_json_values(stream.adc)], [_json_values(stream.acc)], [json_rows]))
    header_b = "".join(case_header_parts(res, [_c_rows(stream.adc)], [_c_rows(stream.acc)], [c_rows]))
    return json_b.encode(), header_b.encode()


# ------------------------------------------------------------------------------------------- writing a set
def render_set(results: Sequence[CaseResult], kind: str, avr: Sequence[str] = ()) -> dict[str, bytes]:
    """All files of a vector set as {relative path: bytes}, including manifest.json (computed last)."""
    files: dict[str, bytes] = {}
    for res in results:
        json_b, header_b = res.rendered or render_case(res)
        files[f"cases/{res.spec.name}.json"] = json_b
        files[f"cases/{res.spec.name}.h"] = header_b
        if res.consts.ALT_TABLE:
            files.update(alt_table_files(res.consts))
    files["c/cases.h"] = cases_table_header(results, "FWV_CASES_H").encode()
    if avr:
        by_name = {r.spec.name: r for r in results}
        missing = [n for n in avr if n not in by_name]
        if missing:
            raise UserError(f"vectors: AVR subset names unknown cases: {', '.join(missing)}")
        files["c/cases_avr.h"] = cases_table_header([by_name[n] for n in avr], "FWV_CASES_AVR_H").encode()
    files["schema.json"] = schema_bytes()
    files["manifest.json"] = manifest_bytes(kind, [r.generator for r in results], len(results),
                                            {path: sha256_bytes(data) for path, data in sorted(files.items())})
    return files


def write_set(files: dict[str, bytes], out: str | Path, kind: str) -> None:
    """Write a rendered set into ``out`` through :func:`firmware_model.runtime.output.staged_folder`: every file goes to
    a stage folder beside ``out`` first; then, under the folder lock and with SIGINT/SIGTERM deferred, ``cases/`` is
    swapped in as a whole and each other file replaced with ``os.replace``, the manifest last. On any error or
    interrupt before the commit nothing in ``out`` changes and no temporary name remains. A user set (kind
    ``user``) refuses to overwrite a directory holding the committed set (manifest kind ``all``)."""

    owned = ("cases", "tables") if any(rel.startswith("tables/") for rel in files) else ("cases",)
    with output.staged_folder(out, owned=owned, guard=_set_guard(kind), last=("manifest.json",)) as stage:
        for rel, data in files.items():
            path = stage / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)


def _set_guard(kind: str) -> Any:
    """The commit guard of :func:`write_set`: a non-``all`` set never replaces the committed set."""

    def guard(out: Path) -> None:
        old_manifest = out / "manifest.json"
        if kind == "all" or not old_manifest.exists():
            return
        try:
            old_kind = json.loads(old_manifest.read_text()).get("kind")
        except (OSError, ValueError, AttributeError):
            old_kind = None
        if old_kind == "all":
            raise UserError(f"vectors: {out} holds the committed vector set; choose another --out for a user set")

    return guard


def _compute_job(job: tuple[Sequence[CaseSpec], str, bool]) -> list[CaseResult]:
    specs, generator, render = job
    builds: dict[Any, Any] = {}
    results = [compute_case(spec, generator, builds) for spec in specs]
    if render:  # the per-case files, in the worker: render_set in the parent is then only the tables + manifest
        for res in results:
            res.rendered = render_case(res)
    return results


def _job_batches(specs: Sequence[CaseSpec], jobs: int) -> list[list[int]]:
    """Indices of ``specs`` in batches for ``jobs`` workers: the cases of one build stay together (a worker then
    assembles or loads each build and compiles its blocks once), about ``4 * jobs`` batches of similar sample
    counts, largest first (so the last batch to finish is a short one)."""
    by_cfg: dict[Any, list[int]] = {}
    for i, spec in enumerate(specs):
        by_cfg.setdefault(spec.cfg, []).append(i)
    groups = sorted(by_cfg.values(), key=lambda g: -sum(len(specs[i].stream) for i in g))
    n_batches = min(len(groups), 4 * jobs)
    batches: list[list[int]] = [[] for _ in range(n_batches)]
    load = [0] * n_batches
    for g in groups:  # greedy: each build to the lightest batch so far
        b = load.index(min(load))
        batches[b] += g
        load[b] += sum(len(specs[i].stream) for i in g) + 2000  # + a build's fixed cost, in samples
    order = sorted(range(n_batches), key=lambda b: -load[b])
    return [sorted(batches[b]) for b in order if batches[b]]


def _worker_start() -> None:
    """Initializer of a ``--jobs`` worker: SIGINT ignored, SIGTERM quiet
    (:func:`firmware_model.runtime.output.worker_init`), the modules every case needs come with this one, imported
    while the parent is still building the case matrix."""

    worker_init()


def generate(specs: Sequence[CaseSpec], generator: str = "emulation", progress: bool | None = None,
             jobs: int = 1, pool: Any = None, render: bool = False,
             more: Callable[[], Sequence[CaseSpec]] | None = None) -> list[CaseResult]:
    """Run every case (in order); ``jobs`` > 1 runs them in that many worker processes, the cases of one build in one
    worker (:func:`_job_batches`). The results come back in the order of ``specs`` whatever the workers' timing, so the
    files written are byte-identical to ``jobs=1``. An error or interrupt terminates the workers at once. ``pool``:
    workers the caller started already (:func:`~firmware_model.runtime.pool.start_pool`; terminated here). ``render``:
    the workers also render each case's files (:attr:`CaseResult.rendered`), in parallel. ``more``: a function returning
    further cases, run after ``specs`` (their results follow in order); with workers it is called after the batches of
    ``specs`` are handed to them, so that building the further cases overlaps running the first ones (an error it raises
    ends the workers as any other)."""
    if jobs <= 1 or (len(specs) <= 1 and more is None):
        specs = list(specs) + (list(more()) if more is not None else [])
        bar = Progress(sum(len(s.stream) for s in specs), "vectors", progress, unit="samples")
        builds: dict[Any, Any] = {}
        results: list[CaseResult] = []
        try:
            for spec in specs:
                results.append(compute_case(spec, generator, builds))
                bar.step(spec.name, len(spec.stream))
        finally:
            if pool is not None:  # started by the caller, not needed
                end_pool(pool, completed=False)
            bar.close()
        return results
    bar = None
    try:
        if pool is None:
            pool = start_pool(jobs, _worker_start)
        pending: list[tuple[list[CaseSpec], Any]] = []  # (a batch's specs, its AsyncResult), in submission order

        def submit(part: Sequence[CaseSpec]) -> None:
            for b in _job_batches(part, jobs):
                batch = [part[i] for i in b]
                pending.append((batch, pool.apply_async(_compute_job, ((batch, generator, render),))))

        order = list(specs)
        submit(order)
        if more is not None:
            tail = list(more())
            submit(tail)
            order += tail
        bar = Progress(sum(len(s.stream) for s in order), "vectors", progress, unit="samples")
        done: dict[int, CaseResult] = {}
        for batch, pend in pending:
            for spec, res in zip(batch, pend.get()):
                done[id(spec)] = res
                bar.step(res.spec.name, len(res.spec.stream))
        end_pool(pool, completed=True)  # every result is in: the workers leave on their own
        pool = None
        return [done[id(s)] for s in order]
    finally:
        if pool is not None:  # an error or an interrupt: end the workers at once
            end_pool(pool, completed=False)
        if bar is not None:
            bar.close()


def generate_all(out: str | Path, generator: str = "emulation", progress: bool | None = None,
                 jobs: int = 1) -> dict[str, bytes]:
    """Regenerate the whole committed set (:func:`case_matrix`) into ``out``; returns the files written. With
    ``jobs`` > 1 the workers start first, so their start-up overlaps the building of the case matrix, and they
    run the grid cases (:func:`grid_case_specs`) while the flight and pascal cases (:func:`tail_case_specs`:
    logs read, flights simulated) are built.

    Without the shared logs (``../shared/flights`` or ``$FWEMU_SHARED_FLIGHTS`` absent) every other case is
    regenerated and the real-log cases are carried over unchanged from the set already in ``out``
    (:func:`carried_log_cases`: their files checked against its manifest, kept in their place in the case table),
    so a newcomer's ``make main`` still refreshes what it can; :data:`LAST_CARRIED` names them for the report."""
    logs = shared_dir() is not None
    pool = start_pool(jobs, _worker_start) if jobs > 1 else None
    try:
        grid = grid_case_specs()
    except BaseException:
        if pool is not None:
            pool.terminate()
            pool.join()
        raise
    results: list[Any] = generate(grid, generator, progress, jobs, pool=pool, render=True,
                                  more=lambda: tail_case_specs(require_logs=logs))
    LAST_CARRIED.clear()
    if not logs:
        carried = carried_log_cases(Path(out), [r.spec.name for r in results])
        LAST_CARRIED.extend(c.spec.name for c in carried)
        results = _in_table_order(Path(out), results, carried)
    files = render_set(results, "all", AVR_CASES)
    write_set(files, out, "all")
    return files


#: The real-log cases the last :func:`generate_all` carried over (the shared logs were absent).
LAST_CARRIED: list[str] = []


@dataclass(frozen=True)
class _CarriedSpec:
    name: str
    cfg: Any


@dataclass(frozen=True)
class _CarriedConsts:
    gains: dict[str, None]
    ALT_TABLE: tuple[int, ...]
    ALT_SHIFT: int


@dataclass(frozen=True)
class CarriedCase:
    """A committed real-log case taken over unchanged: what :func:`render_set` and the case table need (its name,
    program, pascal kind, gain names, altitude table), its generator, and its two files' bytes."""

    spec: _CarriedSpec
    consts: _CarriedConsts
    generator: str
    rendered: tuple[bytes, bytes]


def _committed_table_order(out: Path) -> list[str]:
    """The case names of the set in ``out`` in its case table's order (``c/cases.h``'s includes)."""
    try:
        text = (out / "c" / "cases.h").read_text()
    except OSError:
        return []
    return [line[len('#include "'):-len('.h"')] for line in text.splitlines()
            if line.startswith('#include "') and line.endswith('.h"') and line != '#include "fwv_case.h"']


def carried_log_cases(out: Path, generated: Sequence[str]) -> list[CarriedCase]:
    """The cases of the set in ``out`` that were not ``generated`` and come from a shared log (``input.provenance.
    source`` under ``../shared/flights/``), each file checked against ``out``'s manifest. Raises
    :class:`UserError` when ``out`` holds no committed set or a file does not match its manifest."""
    try:
        manifest = json.loads((out / "manifest.json").read_text())
    except (OSError, ValueError):
        raise UserError(f"vectors: the shared logs are absent and {out} holds no vector set to keep the real-log "
                        "cases from (../shared/flights or $FWEMU_SHARED_FLIGHTS)") from None
    hashes = manifest.get("files", {})
    done = set(generated)
    carried = []
    for name in _committed_table_order(out):
        if name in done:
            continue
        case = read_committed_case(out, name, hashes, why="and the shared logs to regenerate it are absent")
        doc = json.loads(case.rendered[0])
        source = str(doc.get("input", {}).get("provenance", {}).get("source", ""))
        if not source.startswith("../shared/flights/"):
            raise UserError(f"vectors: case {name} in {out} is not generated any more and is not a real-log case: "
                            "regenerate the set with the shared logs present")
        carried.append(case)
    return carried


def read_committed_case(out: Path, name: str, hashes: dict[str, str] | None = None,
                        why: str = "") -> CarriedCase:
    """Case ``name`` of the vector set in ``out`` read back from its files (what :func:`render_set` needs to list it
    in a case table), each file checked against ``hashes`` (the set's manifest) when given."""
    rels = (f"cases/{name}.json", f"cases/{name}.h")
    data = []
    for rel in rels:
        try:
            blob = (out / rel).read_bytes()
        except OSError:
            raise UserError(f"vectors: {out / rel}: missing{', ' + why if why else ''}") from None
        if hashes is not None and sha256_bytes(blob) != hashes.get(rel):
            raise UserError(f"vectors: {out / rel}: does not match {out / 'manifest.json'}{', ' + why if why else ''}")
        data.append(blob)
    doc = json.loads(data[0])
    table: tuple[int, ...] = ()
    shift = 0
    if doc.get("alt_table"):
        table_doc = json.loads((out / doc["alt_table"]["file"]).read_text())
        table, shift = tuple(int(v) for v in table_doc["nodes"]), int(table_doc["shift"])
    cfg = BuildConfig.from_dict(doc["build_config"], where=f"{out / rels[0]}: build_config")
    return CarriedCase(_CarriedSpec(name, cfg), _CarriedConsts({g: None for g in doc["gains"]}, table, shift),
                       str(doc["generator"]), (data[0], data[1]))


def _in_table_order(out: Path, results: Sequence[Any], carried: Sequence[CarriedCase]) -> list[Any]:
    """``results`` and ``carried`` merged in the order of ``out``'s case table (a carried case keeps its place)."""
    order = _committed_table_order(out)
    by_name = {r.spec.name: r for r in list(results) + list(carried)}
    if set(order) != set(by_name):
        new = sorted(set(by_name) - set(order))
        raise UserError(f"vectors: the case matrix changed ({len(new)} new case(s), e.g. {new[:3]}) and the shared "
                        "logs are absent: regenerate the set with ../shared/flights present")
    return [by_name[name] for name in order]


def generate_subset(names: Sequence[str], out: str | Path, generator: str = "emulation") -> dict[str, bytes]:
    """Write the cases of the committed matrix named ``names`` (in matrix order) as a set of kind ``subset``."""
    wanted = set(names)
    specs = [spec for spec in case_matrix(require_logs=False) if spec.name in wanted]
    unknown = wanted - {spec.name for spec in specs}
    if unknown:
        raise UserError(f"vectors: unknown case name(s): {', '.join(sorted(unknown))}")
    files = render_set(generate(specs, generator, progress=False), "subset")
    write_set(files, out, "subset")
    return files


def check_set(directory: str | Path) -> list[str]:
    """Problems with a vector set on disk: files listed in manifest.json that are missing or whose SHA-256 differs,
    and generated files present but not listed. Empty list = consistent."""
    directory = Path(directory)
    try:
        manifest = json.loads((directory / "manifest.json").read_text())
    except (OSError, ValueError) as exc:
        return [f"{directory / 'manifest.json'}: unreadable ({exc})"]
    problems = []
    listed = manifest.get("files", {})
    for rel, digest in sorted(listed.items()):
        path = directory / rel
        if not path.is_file():
            problems.append(f"{rel}: listed in the manifest but missing")
        elif _sha256_or_none(path) != digest:
            problems.append(f"{rel}: SHA-256 differs from the manifest")
    for sub in ("cases", "tables"):
        for path in sorted((directory / sub).glob("*")) if (directory / sub).is_dir() else []:
            rel = f"{sub}/{path.name}"
            if rel not in listed:
                problems.append(f"{rel}: not listed in the manifest")
    return problems


# ------------------------------------------------------------------------------------------- user streams
def generate_user(program: str, input_csv: str | Path, out: str | Path, config: str | Path | None = None,
                  generator: str = "emulation") -> dict[str, bytes]:
    """A one-case vector set from a user CSV stream, built with ``config`` (JSON BuildConfig; default
    :class:`BuildConfig`) and ``program`` (must agree with the config's program), computed in memory. The CLI
    uses :func:`firmware_model.vectors.stream.generate_user`, which writes the same bytes in constant memory;
    this one is its reference for short streams."""
    if program not in PROGRAMS:
        raise UserError(f"vectors: unknown firmware {program!r}; known: {', '.join(PROGRAMS)}")
    _set_guard("user")(Path(out))
    cfg = load_config(config, {"program": program}, {"program": "--firmware"})
    stream = read_stream_csv(input_csv, cfg.baro_word_bits, cfg.k, require_acc=program in ACC_PROGRAMS)
    spec = CaseSpec(case_name(program, cfg.rounding, cfg.k, cfg.baro_word_bits, stream.name), cfg, stream)
    results = generate([spec], generator, progress=False)
    files = render_set(results, "user")
    write_set(files, out, "user")
    return files

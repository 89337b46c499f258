"""Vector sets from long user streams in constant memory (``fwemu vectors --firmware P --input FILE.csv``).

The committed matrix (short cases) is computed in memory by :mod:`firmware_model.vectors.generate`; a user stream can be
hours of samples, so here nothing grows with its length:

1. The CSV is read in chunks (:func:`firmware_model.model.streams.iter_stream_csv`), validated and spooled as 16-bit
   binary into the stage folder of :func:`firmware_model.runtime.output.staged_folder` (2 + 2 bytes per sample on disk).
2. The firmware runs chunk by chunk on one emulated CPU that keeps its RAM between chunks
   (:class:`FirmwareStepper`, the same sequencing as :func:`firmware_model.firmware.harness.run_firmware`: spec §7), and
   the integer model runs chunk by chunk from the state it reached (:class:`ModelStepper`, on the model's own
   kernels); every word of every chunk is cross-checked before the chunk's rows are spooled as text.
3. The case JSON and the C header are written from the spools in pieces
   (:func:`~firmware_model.vectors.generate.case_json_parts`,
   :func:`~firmware_model.vectors.generate.case_header_parts`): byte for byte what the in-memory path writes for the
   same stream (tested).

Memory: O(chunk) (:data:`CHUNK` samples); disk: the final files plus the spools (about 20 bytes per sample per
state word), all inside the stage, removed on any exit. Progress (stderr, when a terminal) counts samples.
Limits (docs/vectors.md): a C header holds at most :data:`HEADER_MAX_SAMPLES` samples; a longer stream is refused
with a message naming the count, unless ``header=False`` (``--no-header``: JSON, manifest and schema only).
"""

from __future__ import annotations

import struct
from pathlib import Path
from typing import Any

import numpy as np

from firmware_model.firmware.assemble import (
    ACCEL_ADC,
    BARO_ADC,
    BARO_PA,
    STACK_TOP,
    build_firmware,
    source_path_text,
    source_sha256,
    write_inputs,
)
from firmware_model.firmware.harness import DEFAULT_MAX_CYCLES_PER_CALL, firmware_cpu
from firmware_model.model.run import kernels_for
from firmware_model.model.streams import ACC_PROGRAMS, CsvInfo, Stream, _identifier, iter_stream_csv
from firmware_model.model.trace import EVENT_BITS, word_names
from firmware_model.runtime import output
from firmware_model.runtime.errors import UserError
from firmware_model.runtime.hashing import sha256_file
from firmware_model.runtime.output import TEMP_PREFIX, interrupts_deferred
from firmware_model.runtime.progress import Progress
from firmware_model.spec.build_constants import build_constants
from firmware_model.spec.config import load_config
from firmware_model.vectors import c_header as vec_c_header
from firmware_model.vectors import case_json as vec_case_json
from firmware_model.vectors import cases as vec_cases
from firmware_model.vectors import compute as vec_compute
from firmware_model.vectors import generate as vectors
from firmware_model.vectors import manifest as vec_manifest
from firmware_model.vectors import schema as vec_schema
from isa.errors import CPUFault

#: Samples per chunk (a multiple of 16, the values per line of the C arrays).
CHUNK: int = 65536
#: Most samples a generated C header may hold: 2^20 (68 min at 256 Hz). Its size is about 14 + 12 x words bytes
#: per sample (kalman_accel: ~86 bytes, 90 MB at the limit): more does not fit any microcontroller's flash and
#: makes compilers crawl.
HEADER_MAX_SAMPLES: int = 1 << 20


# ------------------------------------------------------------------------------------------- resumable engines
class FirmwareStepper:
    """The firmware on one emulated 68000 (memory map of spec §2), run chunk by chunk: :meth:`init` once with
    sample 0, then :meth:`run` on consecutive chunks. Same words and cycles as
    :func:`firmware_model.firmware.harness.run_firmware` on the whole stream (tested)."""

    def __init__(self, build: Any, max_cycles_per_call: int | None = None) -> None:
        self.build = build
        self.max_cycles = max_cycles_per_call or DEFAULT_MAX_CYCLES_PER_CALL
        self.cpu = cpu = firmware_cpu(build)
        self._stack_top = STACK_TOP
        names = tuple(build.variables)
        addr_size = [build.variables[w] for w in names]
        order = sorted(range(len(addr_size)), key=lambda j: addr_size[j][0])
        base = min(a for a, _ in addr_size)
        fmt, pos = ">", base
        for j in order:
            address, size = addr_size[j]
            fmt += "x" * (address - pos) + ("i" if size == 4 else "H")
            pos = address + size
        unpack, span = struct.Struct(fmt).unpack, pos - base
        inverse = [order.index(j) for j in range(len(addr_size))]
        read_bytes = cpu.read_bytes

        def read_state() -> tuple[int, ...]:
            raw = unpack(read_bytes(base, span))
            return tuple(raw[i] for i in inverse)

        self._read_state = read_state
        self.names = names

    def _fault(self, exc: Exception, where: str) -> Exception:
        if isinstance(exc, CPUFault):
            new = type(exc).__new__(type(exc))
            Exception.__init__(new, f"firmware {self.build.program_name}: {where}: {exc}")
            new.pc, new.instruction, new.source = exc.pc, exc.instruction, exc.source
            return new
        return exc

    def init(self, adc0: int, acc0: int) -> tuple[list[int], int]:
        """Run ``init`` on sample 0; returns (init words, init clocks)."""

        cpu = self.cpu
        try:
            write_inputs(cpu, bool(self.build.consts.PASCAL), int(adc0), int(acc0))
            clocks = cpu.call(self.build.init_address, max_cycles=self.max_cycles)
        except Exception as exc:
            raise self._fault(exc, "init") from exc
        return list(self._read_state()), int(clocks)

    def run(self, adc: np.ndarray, acc: np.ndarray, start: int) -> tuple[np.ndarray, np.ndarray]:
        """``step`` on each sample of the chunk (global index ``start`` ...); returns (words (m, n_words), cycles)."""

        write, read_state = self.cpu.write, self._read_state
        baro_reg, baro_size, baro_mask = ((BARO_PA, 4, 0xFFFFFFFF) if self.build.consts.PASCAL
                                          else (BARO_ADC, 2, 0xFFFF))
        call_step = self.cpu.caller(self.build.step_address, self.max_cycles)  # call(step, max_cycles=...)
        adc_l, acc_l = adc.tolist(), (np.asarray(acc) & 0xFFFF).tolist()
        out: list[tuple[int, ...]] = [()] * len(adc_l)
        cyc = [0] * len(adc_l)
        i = 0
        try:
            for i in range(len(adc_l)):
                write(baro_reg, adc_l[i] & baro_mask, baro_size)
                write(ACCEL_ADC, acc_l[i], 2)
                cyc[i] = call_step()
                out[i] = read_state()
        except Exception as exc:
            raise self._fault(exc, f"sample {start + i}") from exc
        return np.array(out, dtype=np.int64).reshape(len(adc_l), len(self.names)), np.array(cyc, dtype=np.int64)

    @property
    def stack_bytes(self) -> int:
        return self._stack_top - int(self.cpu.min_sp)


class ModelStepper:
    """The integer model (:mod:`firmware_model.model.kernels`, compiled when numba is there) resumed chunk by
    chunk from its state array, through the kernels' own one-stream sample loops (``_stream_<program>``, the loop
    :func:`~firmware_model.model.kernels.run_streams` calls once per stream). Same words and wrap report as
    :func:`firmware_model.model.run.run_model` on the whole stream (tested)."""

    _LOOPS = {"recursive": "_stream_recursive", "recursive_seed_literal": "_stream_seed_literal",
              "kalman_baro": "_stream_kalman_baro", "kalman_accel": "_stream_kalman_accel"}

    def __init__(self, consts: Any, n_samples: int | None = None) -> None:
        # the engine run_model's "auto" picks for a call of n_samples (a short stream: the plain-Python kernels)
        kern = kernels_for("auto", n_samples)
        self.kern = kern
        self.program = consts.program
        self.prog = kern.PROGRAMS.index(consts.program)
        self.loop = getattr(kern, self._LOOPS[consts.program])
        import inspect

        # these loops are the kernels' internals: their signature has changed once (the output columns became
        # compile-time constants); pass ``cols`` only where the loop still takes it
        params = inspect.signature(getattr(self.loop, "py_func", self.loop)).parameters
        self._pass_cols = "cols" in params
        self.cols = np.array(kern.OUT_COLS[consts.program], dtype=np.int64)
        self.dtype: Any = np.int64 if kern.COMPILED else object   # object: exact Python ints, as run_model
        self.c = kern.pack_constants(consts, dtype=self.dtype)
        self.state = np.zeros(kern.N_STATE, dtype=self.dtype)
        self.first_wrap = -1
        self.wrap_word = str(kern.WRAP_NAMES[0])

    def _arr(self, values: Any) -> np.ndarray:
        a = np.ascontiguousarray(values, dtype=np.int64)
        return a if self.dtype is np.int64 else a.astype(object)

    def init(self, adc0: int, acc0: int) -> list[int]:
        adc, acc = self._arr([adc0]), self._arr([acc0])

        with interrupts_deferred():  # the first call compiles (seconds): an interrupt waits for it
            self.kern._init(self.prog, self.state, adc[0], acc[0], self.c)
        return [int(self.state[j]) for j in self.cols]

    def run(self, adc: np.ndarray, acc: np.ndarray, start: int) -> np.ndarray:
        out = np.empty((len(adc), len(self.cols)), dtype=self.dtype)
        args = (self.state, self._arr(adc), self._arr(acc), self.c) + ((self.cols,) if self._pass_cols else ())

        with interrupts_deferred():
            f, w = self.loop(*args, out)
        if f >= 0 and self.first_wrap < 0:
            self.first_wrap, self.wrap_word = start + int(f), str(self.kern.WRAP_NAMES[int(w)])
        return out if self.dtype is np.int64 else out.astype(np.int64)   # exact Python ints back to int64


# ------------------------------------------------------------------------------------------- the user set
def _spool_path(stage: Path, name: str) -> Path:
    return stage / f"{TEMP_PREFIX}spool-{name}"


class _Spooled:
    """A 1-D integer array on disk, read slice by slice (no memory map: the resident size stays O(chunk))."""

    def __init__(self, path: Path, dtype: str, n: int) -> None:
        self.path, self.dtype, self.shape = path, np.dtype(dtype), (n,)

    def __len__(self) -> int:
        return self.shape[0]

    def __getitem__(self, index: int | slice) -> Any:
        if isinstance(index, slice):
            start, stop, step = index.indices(self.shape[0])
            if step != 1:
                raise ValueError("spooled arrays are read in contiguous slices")
            return np.fromfile(self.path, dtype=self.dtype, count=max(stop - start, 0),
                               offset=start * self.dtype.itemsize).astype(np.int64)
        i = range(self.shape[0])[index]
        return int(self[i:i + 1][0])


def _chunks_of(path: Path) -> Any:
    """The text chunks of a spool file written as ``<length>\\n<text>`` records."""
    with path.open("r", encoding="ascii", newline="") as f:
        while True:
            head = f.readline()
            if not head:
                return
            yield f.read(int(head))


def _put(f: Any, text: str) -> None:
    f.write(f"{len(text)}\n")
    f.write(text)


def generate_user(program: str, input_csv: str | Path, out: str | Path, config: str | Path | None = None,
                  generator: str = "emulation", header: bool = True, progress: bool | None = None,
                  chunk: int = CHUNK) -> dict[str, int]:
    """A one-case vector set (kind ``user``) from a user CSV, in constant memory (module docstring). Returns
    {relative path: size in bytes} of the files written."""

    if chunk < 16 or chunk % 16:
        raise ValueError(f"chunk={chunk} must be a positive multiple of 16")
    if program not in vectors.PROGRAMS:
        raise UserError(f"vectors: unknown firmware {program!r}; known: {', '.join(vectors.PROGRAMS)}")
    if generator not in ("emulation", "model"):
        raise UserError(f"vectors: unknown generator {generator!r} (emulation or model)")
    guard = vectors._set_guard("user")
    guard(Path(out))
    cfg = load_config(config, {"program": program}, {"program": "--firmware"})
    path = Path(input_csv)
    info = CsvInfo(path, cfg.baro_word_bits, cfg.k)
    adc_dtype = "<i4" if cfg.pascal else "<u2"          # the barometer register: 32-bit pascal word or 16-bit ADC
    with output.staged_folder(out, owned=("cases", "tables"), guard=guard, last=("manifest.json",)) as stage:
        # 1. validate and spool the inputs
        adc_path, acc_path = _spool_path(stage, "adc"), _spool_path(stage, "acc")
        with adc_path.open("wb") as fa, acc_path.open("wb") as fb:
            for a, b in iter_stream_csv(path, cfg.baro_word_bits, cfg.k, program in ACC_PROGRAMS, chunk, info):
                a.astype(adc_dtype).tofile(fa)
                b.astype("<i2").tofile(fb)
        n = info.n
        if header and n > HEADER_MAX_SAMPLES:
            raise UserError(f"vectors: {path} has {n:,} samples; a C header holds at most {HEADER_MAX_SAMPLES:,} "
                            f"(docs/vectors.md, Limits): cut the stream, or pass --no-header for JSON only")
        adc, acc = _Spooled(adc_path, adc_dtype, n), _Spooled(acc_path, "<i2", n)
        stream = Stream(name=_identifier(path.stem), adc=adc, acc=acc, k=cfg.k, bits=cfg.baro_word_bits,
                        provenance=info.provenance())
        name = vec_cases.case_name(program, cfg.rounding, cfg.k, cfg.baro_word_bits, stream.name)
        spec = vec_cases.CaseSpec(name, cfg, stream)
        # 2. run chunk by chunk, cross-check, spool the rows
        if generator == "emulation":
            build = build_firmware(cfg)
            consts, label, source_sha = build.consts, vec_compute.GENERATOR_EMULATION, build.source_sha256
            fw: FirmwareStepper | None = FirmwareStepper(build)
        else:

            consts, label, source_sha = build_constants(cfg), vec_compute.GENERATOR_MODEL, source_sha256(program)
            fw = None
        model = ModelStepper(consts, n)
        names = list(word_names(program))
        ev_col = names.index("EVENTS") if "EVENTS" in names else None
        events_first = {ev: -1 for ev in EVENT_BITS} if ev_col is not None else {}
        cyc_min = cyc_max = cyc_arg = -1
        cyc_sum = 0
        init_cycles = None
        bar = Progress(n, "vectors", progress, unit="samples")
        json_rows, c_rows = _spool_path(stage, "json"), _spool_path(stage, "c")
        try:
            with json_rows.open("w", encoding="ascii", newline="") as fj, \
                    c_rows.open("w", encoding="ascii", newline="") as fc:
                init_m = model.init(int(adc[0]), int(acc[0]))
                if fw is not None:
                    init_w, init_cycles = fw.init(int(adc[0]), int(acc[0]))
                    if init_w != init_m:
                        j = next(j for j in range(len(names)) if init_w[j] != init_m[j])
                        raise UserError(f"vectors: case {name}: emulated firmware and model differ after init, "
                                        f"word {names[j]}: firmware {init_w} model {init_m}")
                for start in range(0, n, chunk):
                    a = np.asarray(adc[start:start + chunk], dtype=np.int64)
                    b = np.asarray(acc[start:start + chunk], dtype=np.int64)
                    words = model.run(a, b, start)
                    if fw is not None:
                        fwords, cyc = fw.run(a, b, start)
                        diff = np.argwhere(fwords != words)
                        if diff.size:
                            i, j = (int(v) for v in diff[0])
                            raise UserError(f"vectors: case {name}: emulated firmware and model differ at sample "
                                            f"{start + i} word {names[j]}: firmware {int(fwords[i, j])} model "
                                            f"{int(words[i, j])}")
                        lo, hi = int(cyc.min()), int(cyc.max())
                        if cyc_min < 0 or lo < cyc_min:
                            cyc_min = lo
                        if hi > cyc_max:
                            cyc_max, cyc_arg = hi, start + int(np.argmax(cyc))
                        cyc_sum += int(cyc.sum())
                    if ev_col is not None:
                        col = words[:, ev_col]
                        for ev, bit in EVENT_BITS.items():
                            if events_first[ev] < 0:
                                hit = np.flatnonzero(col & bit)
                                if hit.size:
                                    events_first[ev] = start + int(hit[0])
                    rows = words.tolist()
                    json_text, c_text = vectors._row_texts(rows)
                    _put(fj, json_text)
                    _put(fc, c_text)
                    bar.step(name, len(a))
        finally:
            bar.close()
        cycles = None
        if fw is not None:
            cycles = {"cpu": "MC68000, zero wait states", "step_min": cyc_min, "step_max": cyc_max,
                      "step_max_sample": cyc_arg, "step_mean": round(cyc_sum / n, 3), "init": init_cycles}
        res = vec_compute.CaseResult(spec=spec, generator=label, source=source_path_text(program),
                                 source_sha256=source_sha, consts=consts, init=init_m, words=[], cycles=cycles,
                                 first_wrap=int(model.first_wrap), wrap_word=str(model.wrap_word),
                                 events_first=events_first if ev_col is not None else None)

        # 3. the files, streamed from the spools
        sizes = _write_case_files(stage, res, adc, acc, json_rows, c_rows, chunk, header)
    return sizes


def _write_case_files(stage: Path, res: vec_compute.CaseResult, adc: _Spooled, acc: _Spooled, json_rows: Path,
                      c_rows: Path, chunk: int, header: bool) -> dict[str, int]:
    """Step 3 of :func:`generate_user`: the case's JSON (and C header, with ``header``), the shared tables, the
    schema and the manifest in ``stage``, streamed from the input spools ``adc``/``acc`` and the row spools;
    returns {relative path: size in bytes}."""
    name, n, consts, label = res.spec.name, len(adc), res.consts, res.generator

    def values(arr: _Spooled, fmt: Any) -> Any:
        for start in range(0, n, chunk):
            yield fmt(np.asarray(arr[start:start + chunk], dtype=np.int64))

    rel_files = [f"cases/{name}.json"] + ([f"cases/{name}.h", "c/cases.h"] if header else [])
    (stage / "cases").mkdir()
    if getattr(consts, "ALT_TABLE", None):       # the shared altitude table of a Kalman build
        for rel, data in vec_c_header.alt_table_files(consts).items():
            if rel.endswith(".h") and not header:
                continue
            (stage / rel).parent.mkdir(exist_ok=True)
            (stage / rel).write_bytes(data)
            rel_files.append(rel)
    with (stage / rel_files[0]).open("w", encoding="ascii", newline="") as f:
        for piece in vec_case_json.case_json_parts(res, values(adc, vec_case_json._json_values),
                                                   values(acc, vec_case_json._json_values), _chunks_of(json_rows)):
            f.write(piece)
    if header:
        with (stage / rel_files[1]).open("w", encoding="ascii", newline="") as f:
            for piece in vec_c_header.case_header_parts(res, values(adc, vec_c_header._c_rows),
                                                        values(acc, vec_c_header._c_rows), _chunks_of(c_rows)):
                f.write(piece)
        (stage / "c").mkdir()
        (stage / "c" / "cases.h").write_bytes(vec_c_header.cases_table_header([res], "FWV_CASES_H").encode())
    (stage / "schema.json").write_bytes(vec_schema.schema_bytes())
    rel_files.append("schema.json")
    hashes = {rel: sha256_file(stage / rel) for rel in sorted(rel_files)}
    (stage / "manifest.json").write_bytes(vec_manifest.manifest_bytes("user", [label], 1, hashes))
    return {rel: (stage / rel).stat().st_size for rel in rel_files + ["manifest.json"]}

"""What check-port writes and prints for a difference: a report (sample, word, expected, actual, the inputs up to
it), a Unity test, a plain C test (no framework) and a golden-vector case JSON, each reproducing it alone.

The C tests carry the stream, the build's constants and the model's words after init and after every step, call
the port through the same generated code as check-port (:func:`firmware_model.vectors.portcheck.adapter.glue_core`), and
fail at the first differing word with ``sample <i> word <W>: expected <x> got <y>``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from firmware_model.model.streams import Stream
from firmware_model.runtime.output import staged_folder, write_file
from firmware_model.vectors.case_json import case_json
from firmware_model.vectors.cases import PROGRAM_IDS, CaseSpec, case_name
from firmware_model.vectors.compute import compute_case
from firmware_model.vectors.portcheck.adapter import Adapter, const_slots, consts_vector, glue_core, includes
from firmware_model.vectors.portcheck.check import Mismatch


def runs(values: np.ndarray) -> str:
    """``values`` run-length encoded: ``26756 x12, 0, 65535 x3``."""
    out: list[str] = []
    vals = np.asarray(values).tolist()
    i = 0
    while i < len(vals):
        j = i
        while j + 1 < len(vals) and vals[j + 1] == vals[i]:
            j += 1
        out.append(f"{vals[i]}" + (f" x{j - i + 1}" if j > i else ""))
        i = j + 1
    return ", ".join(out)


def describe(mm: Mismatch) -> list[str]:
    """The lines check-port prints for a difference."""
    d, cfg = mm.diff, mm.cfg
    if mm.crash is not None:
        c = mm.crash
        done = ("before init returned" if c.samples_done < 0 else
                f"after init and {c.samples_done} step(s): last sample completed {c.samples_done - 1}"
                if c.samples_done > 0 else "after init, in the first step (sample 0)")
        return [f"CRASH: the port {c.kind}",
                f"  at: {done}",
                f"  build: program {cfg.program}, rounding {cfg.rounding}, k {cfg.k}, "
                f"{'pascal' if cfg.pascal else f'{cfg.baro_bits}-bit ADC'} barometer",
                (f"  stream: {len(mm.adc)} samples (hypothesis found one of {mm.first_len}, shrank it to "
                 f"{mm.shrunk_len}, cut after the sample it crashed on)" if mm.source == "hypothesis" else
                 f"  stream: {len(mm.adc)} samples (the given stream of {mm.first_len})"),
                f"  {'pascal' if cfg.pascal else 'adc'}: {runs(mm.adc)}",
                f"  acc: {runs(mm.acc)}"] + ([f"  the port printed: {c.output}"] if c.output else [])
    where = "after init" if d.sample < 0 else f"at sample {d.sample}"
    exp_row = mm.expected_init if d.sample < 0 else mm.expected[d.sample]
    got_row = mm.actual_init if d.sample < 0 else mm.actual[d.sample]
    lines = [f"DIFFERENCE {where}, word {d.word}: expected {d.expected} (model), actual {d.actual} (port)",
             f"  build: program {cfg.program}, rounding {cfg.rounding}, k {cfg.k}, "
             f"{'pascal' if cfg.pascal else f'{cfg.baro_bits}-bit ADC'} barometer",
             (f"  stream: {len(mm.adc)} samples (hypothesis found one of {mm.first_len}, shrank it to "
              f"{mm.shrunk_len}, cut after the first difference)" if mm.source == "hypothesis" else
              f"  stream: {len(mm.adc)} samples (the given stream of {mm.first_len}, cut after the first "
              "difference)"),
             f"  {'pascal' if cfg.pascal else 'adc'}: {runs(mm.adc)}",
             f"  acc: {runs(mm.acc)}",
             "  words " + " ".join(mm.names),
             "  model " + " ".join(str(int(v)) for v in exp_row),
             "  port  " + " ".join(str(int(v)) for v in got_row)]
    return lines


def _c_int(v: int) -> str:
    return "(-2147483647 - 1)" if v == -(1 << 31) else str(int(v))


def _c_array(ctype: str, name: str, values: Any, per_line: int = 12) -> str:
    vals = [_c_int(v) for v in np.asarray(values, dtype=np.int64).ravel().tolist()] or ["0"]
    body = ",\n".join("    " + ", ".join(vals[i:i + per_line]) for i in range(0, len(vals), per_line))
    return f"static const {ctype} {name}[{len(vals)}] = {{\n{body}\n}};"


def unit_test_sources(mm: Mismatch, adapter: Adapter, name: str) -> tuple[str, str]:
    """``(unity_test_c, plain_test_c)`` reproducing ``mm`` through ``adapter``."""
    cfg, consts = mm.cfg, mm.consts
    program = cfg.program
    n, nw = len(mm.adc), len(mm.names)
    expected = np.vstack([mm.expected_init[None, :], mm.expected]) if n else mm.expected_init[None, :]
    d = mm.diff
    slots = const_slots()
    what = (f" * The port {mm.crash.kind} on this stream (check-port ran it in a child process); run this test "
            "under a debugger or with -fsanitize=address,undefined." if mm.crash is not None else
            f" * The port differs from the bit-exact model {'after init' if d.sample < 0 else f'at sample {d.sample}'}"
            f", word {d.word}: expected {d.expected}, got {d.actual}.")
    head = [f"/* {name}: generated by fwemu check-port (docs/port-check.md); do not edit.", what,
            f" * Build: program {program}, rounding {cfg.rounding}, k {cfg.k}, "
            f"{'pascal' if cfg.pascal else f'{cfg.baro_bits}-bit ADC'} barometer; {n} samples; {adapter.source}.",
            " * Expected words: firmware_model.model.run.run_model (the integer model the golden vectors are checked "
            "against). */"]
    data = [f"#define FWPC_PROGRAM {PROGRAM_IDS[program]} /* {program} */",
            f"#define FWPC_N {n}", f"#define FWPC_NW {nw}", "",
            f"/* constants: {', '.join(slots)} */",
            _c_array("int32_t", "fwpc_consts", consts_vector(consts)),
            "/* altitude table (Q24.8 m), unused by the recursive programs */",
            _c_array("int32_t", "fwpc_alt", consts.ALT_TABLE if consts.ALT_TABLE else [0]),
            f"/* barometer words ({'pascal' if cfg.pascal else 'ADC counts'}); sample 0 is also the init sample */",
            _c_array("int32_t", "fwpc_baro", mm.adc),
            "/* accelerometer counts */",
            _c_array("int16_t", "fwpc_acc", mm.acc),
            f"/* the model's state words after init (row 0) and after each step: {' '.join(mm.names)} */",
            _c_array("int32_t", "fwpc_expected", expected, per_line=nw),
            "static const char *const fwpc_names[FWPC_NW] = {" + ", ".join(f'"{w}"' for w in mm.names) + "};",
            "static int32_t fwpc_got[(FWPC_N + 1) * FWPC_NW];", ""]
    core = glue_core(adapter, programs=(program,))
    unity = "\n".join([
        *head, "", '#include <stdio.h>', '#include "unity.h"', includes(adapter), "", core, *data,
        "void setUp(void) {}", "void tearDown(void) {}", "",
        f"static void {name}(void)", "{", "    char msg[96];", "    long i, j;",
        "    TEST_ASSERT_EQUAL_INT32_MESSAGE(FWPC_NW, fwpc_run(FWPC_PROGRAM, fwpc_consts, fwpc_alt, FWPC_N, "
        "fwpc_baro, fwpc_acc, FWPC_NW, fwpc_got), \"number of state words\");",
        "    for (i = 0; i <= FWPC_N; i++) {", "        for (j = 0; j < FWPC_NW; j++) {",
        "            if (fwpc_got[i * FWPC_NW + j] != fwpc_expected[i * FWPC_NW + j]) {",
        "                snprintf(msg, sizeof msg, \"sample %ld word %s\", i - 1, fwpc_names[j]);",
        "                TEST_ASSERT_EQUAL_INT32_MESSAGE(fwpc_expected[i * FWPC_NW + j], fwpc_got[i * FWPC_NW + j], "
        "msg);", "            }", "        }", "    }", "}", "",
        "int main(void)", "{", "    UNITY_BEGIN();", f"    RUN_TEST({name});", "    return UNITY_END();", "}",
        ""])
    plain = "\n".join([
        *head, "", "#include <stdio.h>", includes(adapter), "", core, *data,
        "int main(void)", "{", "    long i, j;",
        "    int32_t k = fwpc_run(FWPC_PROGRAM, fwpc_consts, fwpc_alt, FWPC_N, fwpc_baro, fwpc_acc, FWPC_NW, "
        "fwpc_got);",
        "    if (k != FWPC_NW) {",
        f"        printf(\"{name}: the port has %ld state words, the model %d\\n\", (long)k, FWPC_NW);",
        "        return 1;", "    }",
        "    for (i = 0; i <= FWPC_N; i++) {", "        for (j = 0; j < FWPC_NW; j++) {",
        "            if (fwpc_got[i * FWPC_NW + j] != fwpc_expected[i * FWPC_NW + j]) {",
        f"                printf(\"{name}: sample %ld word %s: expected %ld got %ld\\n\", i - 1, fwpc_names[j],",
        "                       (long)fwpc_expected[i * FWPC_NW + j], (long)fwpc_got[i * FWPC_NW + j]);",
        "                return 1;", "            }", "        }", "    }",
        f"    printf(\"{name}: PASS (%d samples)\\n\", FWPC_N);", "    return 0;", "}", ""])
    return unity, plain


def case_file(mm: Mismatch, seed: int) -> tuple[str, bytes]:
    """``(case name, case JSON bytes)``: the shrunk stream as a golden-vector case (generator "model")."""
    cfg = mm.cfg
    name = case_name(cfg.program, cfg.rounding, cfg.k, 32 if cfg.pascal else cfg.baro_bits, "portcheck")
    d = mm.diff
    stream = Stream(name="portcheck", adc=np.asarray(mm.adc, dtype=np.int64), acc=np.asarray(mm.acc, dtype=np.int64),
                    k=cfg.k, bits=32 if cfg.pascal else cfg.baro_bits,
                    provenance={"generator": "fwemu check-port (hypothesis, shrunk, cut after the first difference)",
                                "seed": seed, "first_difference": {"sample": d.sample, "word": d.word,
                                                                   "expected": d.expected, "actual": d.actual}}
                    if mm.crash is None else
                    {"generator": "fwemu check-port (hypothesis, shrunk, cut after the sample the port crashed on)",
                     "seed": seed, "crash": {"kind": mm.crash.kind, "samples_done": mm.crash.samples_done}})
    res = compute_case(CaseSpec(name, cfg, stream), generator="model")
    return name, case_json(res).encode()


def write_repro(mm: Mismatch, adapter: Adapter, out: str | Path, seed: int) -> list[Path]:
    """Write the three files into ``out`` as one set (staged, then committed together: a full disk leaves none
    of them, and the earlier contents of ``out`` intact); returns their paths."""
    out = Path(out)
    name, doc = case_file(mm, seed)
    unity, plain = unit_test_sources(mm, adapter, f"test_{name}")
    names = [f"test_{name}_unity.c", f"test_{name}.c", f"{name}.json"]
    with staged_folder(out) as stage:
        for fname, data in zip(names, (unity, plain, doc)):
            write_file(stage / fname, data)
    return [out / fname for fname in names]


__all__ = ["case_file", "describe", "runs", "unit_test_sources", "write_repro"]

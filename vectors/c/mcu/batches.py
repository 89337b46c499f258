#!/usr/bin/env python3
"""Split a golden-vector case table (vectors/c/cases.h) into batches that fit a board's flash.

    batches.py CASES_H CASE_DIR OUT_DIR BUDGET_BYTES [--only REGEX] [--max-object BYTES]

Writes OUT_DIR/batch_NN.h (each a complete case table in the format of cases.h: the per-case includes, FWV_N_CASES and
fwv_cases[]) and OUT_DIR/batches.txt (one line per batch: its file name, estimated bytes, and the names of the cases it
checks (wholly or a slice)). The cases keep the order of CASES_H. A case's size is estimated from its header's N_SAMPLES
/ N_WORDS macros (inputs at 4 bytes a sample, words at 4 bytes, plus a fixed overhead); a case larger than the budget on
its own goes into a batch of its own, and the board's linker script then reports the overflow by name rather than
dropping the case.

Splitting: a case whose expected array is larger than --max-object (avr-gcc refuses objects of 32 KiB and more) or
whose size alone exceeds the budget is split into slices by sample: slice [a, b) keeps the inputs of samples 0..b-1
(the filter must run from the first sample) and the expected rows a..b-1 only, in a header of its own
(OUT_DIR/slices/); the batch header then defines FWV_HAS_CHECK_FROM and fwv_check_from[] (the first checked sample
of each case), and the harness runs samples before a without checking or timing them. Every sample of every case
is still checked exactly once. Slice names are "<case>[a:b)".
Uses only the Python standard library (it runs before any venv exists).
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

OVERHEAD = 256  # descriptor, name string, alignment


def parse_table(text: str) -> tuple[list[str], list[str]]:
    """The case names (from the includes) and the table entries of a cases.h, in order."""
    start = text.index("fwv_cases[]")
    body = text[text.index("{", start) + 1:text.rindex("};")]
    entries = [e.rstrip().rstrip(",") for e in re.split(r"\n(?=    \{\")", "\n" + body.strip("\n")) if e.strip()]
    names = [re.match(r'\s*\{"([^"]+)"', e).group(1) for e in entries]
    return names, entries


def case_shape(header: Path) -> tuple[int, int]:
    """(samples, words) of a case header."""
    text = header.read_text()
    return (int(re.search(r"_N_SAMPLES (\d+)", text).group(1)), int(re.search(r"_N_WORDS (\d+)", text).group(1)))


def input_bytes(header: Path) -> int:
    """Bytes of input per sample: 2 (ADC word) or 4 (pascal word) + 2 (accelerometer)."""
    return 6 if re.search(r"int32_t fwv_\w+_pa\[", header.read_text()) else 4


def case_bytes(header: Path) -> int:
    n, w = case_shape(header)
    return n * input_bytes(header) + (n + 1) * w * 4 + OVERHEAD


def slice_bytes(a: int, b: int, w: int, per_input: int = 4) -> int:
    return b * per_input + (b - a + 1) * w * 4 + OVERHEAD


def _rename(text: str, name: str, tag: str) -> str:
    up = name.upper()
    text = text.replace(f"FWV_{up}_", f"FWV_{up}_{tag.upper()}_")
    return text.replace(f"fwv_{name}_", f"fwv_{name}_{tag}_")


def slice_header(text: str, name: str, tag: str, a: int, b: int) -> str:
    """The case header ``text`` cut to inputs 0..b-1 and expected rows a..b-1, its symbols renamed with ``tag``."""
    def cut_inputs(m: re.Match) -> str:
        values = [v.strip() for v in m.group(3).split(",") if v.strip()][:b]
        rows = [", ".join(values[i:i + 16]) for i in range(0, b, 16)]
        return f"{m.group(1)}[{b}]{m.group(2)}\n    " + ",\n    ".join(rows) + "\n};"

    text = re.sub(r"(static const \w+ fwv_\w+_(?:adc|acc|pa))\[\d+\]( FWV_ROM = \{)(.*?)\};", cut_inputs, text,
                  flags=re.S)

    def cut_expected(m: re.Match) -> str:
        rows = re.findall(r"\{ [^}]* \}", m.group(3))[a:b]
        return f"{m.group(1)}[{b - a}]{m.group(2)}\n    " + ",\n    ".join(rows) + "\n};"

    text = re.sub(r"(static const \w+ fwv_\w+_expected)\[\d+\](\[\d+\] FWV_ROM = \{)(.*?)\};", cut_expected, text,
                  flags=re.S)
    text = re.sub(r"(_N_SAMPLES) \d+", rf"\g<1> {b}", text)
    return _rename(text, name, tag)


def main(argv: list[str]) -> int:
    args = list(argv)
    opts: dict[str, str] = {}
    for flag in ("--only", "--max-object"):
        if flag in args:
            k = args.index(flag)
            opts[flag] = args[k + 1]
            del args[k:k + 2]
    if len(args) != 4:
        print("usage: " + __doc__.strip().splitlines()[2].strip(), file=sys.stderr)
        return 2
    cases_h, case_dir, out_dir, budget = Path(args[0]), Path(args[1]), Path(args[2]), int(args[3])
    only = re.compile(opts["--only"]) if "--only" in opts else None
    max_object = int(opts.get("--max-object", "0")) or None
    names, entries = parse_table(cases_h.read_text())
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "slices").mkdir(exist_ok=True)
    for old in [*out_dir.glob("batch_*.h"), *(out_dir / "slices").glob("*.h")]:
        old.unlink()
    # units: (include file, table entry, first checked sample, bytes, case name)
    units: list[tuple[str, str, int, int, str]] = []
    for i, name in enumerate(names):
        if only is not None and not only.search(name):
            continue
        header = case_dir / f"{name}.h"
        n, w = case_shape(header)
        too_big = (max_object is not None and n * w * 4 >= max_object) or case_bytes(header) > budget
        if not too_big:
            units.append((f"{name}.h", entries[i], 0, case_bytes(header), name))
            continue
        per_input = input_bytes(header)
        rows = (budget - OVERHEAD - n * per_input) // (w * 4) - 1
        if max_object is not None:
            rows = min(rows, (max_object - 1) // (w * 4))
        if rows < 1:
            units.append((f"{name}.h", entries[i], 0, case_bytes(header), name))  # cannot split: the build says so
            continue
        text = header.read_text()
        for s_i, a in enumerate(range(0, n, rows)):
            b = min(n, a + rows)
            tag = f"s{s_i}"
            fname = f"slices/{name}_{tag}.h"
            (out_dir / fname).write_text(slice_header(text, name, tag, a, b))
            entry = _rename(entries[i], name, tag).replace(f'{{"{name}"', f'{{"{name}[{a}:{b})"', 1)
            units.append((fname, entry, a, slice_bytes(a, b, w, per_input), name))
    batches: list[list[int]] = [[]]
    used = 0
    for u, (_, _, _, size, _) in enumerate(units):
        if batches[-1] and used + size > budget:
            batches.append([])
            used = 0
        batches[-1].append(u)
        used += size
    lines = []
    for b, idx in enumerate(batches):
        if not idx:
            continue
        fname = f"batch_{b:02d}.h"
        guard = f"FWV_BATCH_{b:02d}_H"
        parts = [f"/* Batch {b} of {cases_h.name} (generated by mcu/batches.py). */",
                 f"#ifndef {guard}", f"#define {guard}", "", '#include "fwv_case.h"', ""]
        parts += [f'#include "{units[u][0]}"' for u in idx]
        parts += ["", f"#define FWV_N_CASES {len(idx)}u", "static const fwv_case fwv_cases[] FWV_ROM = {"]
        parts.append(",\n".join(units[u][1] for u in idx))
        parts += ["};"]
        if any(units[u][2] for u in idx):
            parts += ["#define FWV_HAS_CHECK_FROM 1",
                      "static const int32_t fwv_check_from[FWV_N_CASES] = {"
                      + ", ".join(str(units[u][2]) for u in idx) + "};"]
        parts += ["", f"#endif /* {guard} */", ""]
        (out_dir / fname).write_text("\n".join(parts))
        cases = list(dict.fromkeys(units[u][4] for u in idx))
        lines.append(f"{fname} {sum(units[u][3] for u in idx)} " + " ".join(cases))
    (out_dir / "batches.txt").write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

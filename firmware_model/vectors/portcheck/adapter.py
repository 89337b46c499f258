"""How check-port calls a port: the ``vectors/c/fw.h`` API, or an adapter file that maps a team's own names and
types onto it (docs/port-check.md, "Adapter").

Either way check-port generates one small C file, the *glue*, compiled with the port into a shared library. The
glue exports three functions with plain C types, the only ones :mod:`firmware_model.vectors.portcheck.build` calls
through ctypes:

* ``int32_t fwpc_run(int32_t program, const int32_t *consts, const int32_t *alt, int32_t n, const int32_t *baro,
  const int16_t *acc, int32_t nw, int32_t *out)``: fills the port's constants from the flat vector ``consts``
  (:func:`consts_vector`: the scalars of :data:`firmware_model.vectors.cases.SCALAR_CONSTANTS`, then ``m, s`` of each
  gain of :data:`~firmware_model.vectors.cases.GAIN_NAMES`) and the altitude table ``alt``, calls init on sample 0,
  then step on samples 0..n-1, and writes the ``nw`` state words after init and after each step into ``out``
  (``(n + 1) * nw`` values); returns the number of words the port has for ``program``.
* ``int32_t fwpc_n_words(int32_t program)`` and ``const char *fwpc_word_name(int32_t program, int32_t i)``: the
  port's own word list (the fw.h API: ``fw_words`` / ``fw_word_name``; an adapter: its ``words`` keys), which
  check-port compares with the model's (:func:`firmware_model.model.trace.word_names`) before anything else.

Nothing here lists the state words or the constants: the words come from the model (and the port), the constants
from the vectors module's tables, so a new state word or constant needs no change here.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from firmware_model.model.trace import STATE_WORDS, word_names
from firmware_model.runtime.errors import UserError
from firmware_model.spec.config import PROGRAMS, read_config_file
from firmware_model.vectors.cases import GAIN_NAMES, PROGRAM_IDS, SCALAR_CONSTANTS

#: Version of the glue's ABI (``fwpc_abi()``); bumped when the three functions change.
GLUE_ABI: int = 2
#: Placeholders an adapter's C templates may use.
PLACEHOLDERS: tuple[str, ...] = ("s", "c", "baro", "acc", "program")
#: Keys of an adapter file.
ADAPTER_KEYS: tuple[str, ...] = ("include", "state_type", "consts_type", "programs", "consts", "init", "step",
                                 "words", "prelude", "comment")


def const_slots() -> tuple[str, ...]:
    """Names of the entries of the flat constants vector, in order: each scalar constant, then ``<G>.m`` and
    ``<G>.s`` for each gain (an adapter's ``consts`` keys are these names and ``ALT``)."""
    return tuple(SCALAR_CONSTANTS) + tuple(f"{g}.{part}" for g in GAIN_NAMES for part in ("m", "s"))


def consts_vector(consts: Any) -> list[int]:
    """The flat int32 constants vector of a :class:`~firmware_model.spec.build_constants.FirmwareConstants` (a gain the
    build does not have is ``m = s = 0``, as in the golden vectors' case table)."""
    out = [int(getattr(consts, name)) for name in SCALAR_CONSTANTS]
    for g in GAIN_NAMES:
        q = consts.gains.get(g)
        out += [int(q.m), int(q.s)] if q is not None else [0, 0]
    return out


@dataclass(frozen=True)
class Adapter:
    """How to call one port. ``words`` is ``None`` for the fw.h API (the port lists its words through
    ``fw_words``/``fw_word_name``), else ``{program: {word: C expression}}``. ``consts``: ``{slot: C lvalue}``
    (slots of :func:`const_slots` and ``ALT``); unmapped slots are not set (a port that does not use them).
    Templates use ``{s}`` (the state variable), ``{c}`` (the constants variable), ``{baro}`` (``int32_t``),
    ``{acc}`` (``int16_t``) and ``{program}`` (the ``programs`` entry of the program checked)."""

    include: tuple[str, ...]
    state_type: str
    consts_type: str
    programs: dict[str, str]
    consts: dict[str, str]
    init: str
    step: str
    words: dict[str, dict[str, str]] | None = None
    prelude: str = ""
    source: str = "the fw.h API"
    extra: dict[str, Any] = field(default_factory=dict, compare=False)

    def supports(self, program: str) -> bool:
        return program in self.programs

    def check_program(self, program: str) -> None:
        """UserError when the adapter cannot run ``program`` or lacks one of the model's words for it."""
        if program not in self.programs:
            raise UserError(f"{self.source}: no entry for program {program!r} in \"programs\" "
                            f"(it has: {', '.join(self.programs) or 'none'})")
        if self.words is not None:
            have = self.words.get(program, {})
            missing = [w for w in word_names(program) if w not in have]
            if missing:
                raise UserError(f"{self.source}: \"words\" of {program} has no expression for "
                                f"{', '.join(missing)} (the model's words: {' '.join(word_names(program))})")


def api_adapter(header: str = "fw.h") -> Adapter:
    """The fw.h API (vectors/c/fw.h) as an adapter: ``fw_consts`` fields named like the constants, ``fw_init`` /
    ``fw_step``, and the port's own ``fw_words`` / ``fw_word_name`` for the words."""
    consts = {name: f"{{c}}.{name}" for name in SCALAR_CONSTANTS}
    consts.update({f"{g}.{part}": f"{{c}}.{g}.{part}" for g in GAIN_NAMES for part in ("m", "s")})
    consts["ALT"] = "{c}.ALT"
    return Adapter(include=(header,), state_type="fw_state", consts_type="fw_consts",
                   programs={p: f"(fw_program){PROGRAM_IDS[p]}" for p in PROGRAMS}, consts=consts,
                   init="fw_init({program}, &{c}, &{s}, {baro}, {acc});",
                   step="fw_step({program}, &{c}, &{s}, {baro}, {acc});", words=None)


_FIELD = re.compile(r"\{([A-Za-z_]+)\}")


def _check_template(text: Any, where: str, allowed: tuple[str, ...]) -> str:
    if not isinstance(text, str) or not text.strip():
        raise UserError(f"{where}: must be a non-empty string of C")
    for m in _FIELD.finditer(text):
        if m.group(1) not in allowed:
            raise UserError(f"{where}: unknown placeholder {{{m.group(1)}}} (allowed: "
                            f"{', '.join('{' + a + '}' for a in allowed)})")
    return text


def _line_of(text: str, needle: str) -> str:
    i = text.find(json.dumps(needle))
    return f":{text.count(chr(10), 0, i) + 1}" if i >= 0 else ""


def load_adapter(path: str | Path) -> Adapter:  # noqa: C901 - one check per adapter key, each naming the file, line and key
    """Read an adapter file (JSON, docs/port-check.md "Adapter"); every problem is a :class:`UserError` naming the
    file, the line where it can, and the key."""
    path = Path(path)
    data = read_config_file(path)  # JSON object, duplicate keys / bad bytes reported with file and line
    text = path.read_text(encoding="utf-8-sig")
    where = str(path)
    unknown = sorted(set(data) - set(ADAPTER_KEYS))
    if unknown:
        raise UserError(f"{where}{_line_of(text, unknown[0])}: unknown key {unknown[0]!r}; known: "
                        f"{', '.join(ADAPTER_KEYS)}")
    for key in ("include", "state_type", "consts_type", "programs", "consts", "init", "step", "words"):
        if key not in data:
            raise UserError(f"{where}: missing key {key!r} (docs/port-check.md, Adapter)")
    include = data["include"]
    if isinstance(include, str):
        include = [include]
    if not isinstance(include, list) or not all(isinstance(h, str) and h for h in include):
        raise UserError(f"{where}{_line_of(text, 'include')}: \"include\" must be a header name or a list of them")
    for key in ("state_type", "consts_type"):
        if not isinstance(data[key], str) or not data[key].strip():
            raise UserError(f"{where}{_line_of(text, key)}: {key!r} must be a C type name")
    programs = data["programs"]
    if not isinstance(programs, dict) or not programs:
        raise UserError(f"{where}{_line_of(text, 'programs')}: \"programs\" must map program names to C "
                        "expressions")
    for p, expr in programs.items():
        if p not in PROGRAMS:
            raise UserError(f"{where}{_line_of(text, p)}: unknown program {p!r}; known: {', '.join(PROGRAMS)}")
        _check_template(expr, f"{where}{_line_of(text, p)}: programs.{p}", ())
    slots = set(const_slots()) | {"ALT"}
    consts = data["consts"]
    if not isinstance(consts, dict):
        raise UserError(f"{where}{_line_of(text, 'consts')}: \"consts\" must map constant names to C lvalues")
    for name, expr in consts.items():
        if name not in slots:
            raise UserError(f"{where}{_line_of(text, name)}: unknown constant {name!r} in \"consts\"; known: "
                            f"{', '.join(const_slots())}, ALT")
        _check_template(expr, f"{where}{_line_of(text, name)}: consts.{name}", ("c",))
    init = _check_template(data["init"], f"{where}{_line_of(text, 'init')}: init", PLACEHOLDERS)
    step = _check_template(data["step"], f"{where}{_line_of(text, 'step')}: step", PLACEHOLDERS)
    raw = data["words"]
    if not isinstance(raw, dict) or not raw:
        raise UserError(f"{where}{_line_of(text, 'words')}: \"words\" must map state-word names to C expressions "
                        "(or program names to such maps)")
    if all(isinstance(v, dict) for v in raw.values()):
        per = raw
    elif all(isinstance(v, str) for v in raw.values()):
        per = {p: raw for p in programs}
    else:
        raise UserError(f"{where}{_line_of(text, 'words')}: \"words\": either every value a C expression or every "
                        "value a map per program")
    words: dict[str, dict[str, str]] = {}
    for p, mapping in per.items():
        if p not in PROGRAMS:
            raise UserError(f"{where}{_line_of(text, p)}: \"words\": unknown program {p!r}")
        for w, expr in mapping.items():
            _check_template(expr, f"{where}{_line_of(text, w)}: words.{w}", ("s",))
        words[p] = dict(mapping)
    prelude = data.get("prelude", "")
    if not isinstance(prelude, str):
        raise UserError(f"{where}{_line_of(text, 'prelude')}: \"prelude\" must be a string of C")
    return Adapter(include=tuple(include), state_type=data["state_type"], consts_type=data["consts_type"],
                   programs=dict(programs), consts=dict(consts), init=init, step=step, words=words, prelude=prelude,
                   source=where)


def _fill(template: str, **values: str) -> str:
    return _FIELD.sub(lambda m: values[m.group(1)], template)


def _word_cast(program: str, word: str, expr: str) -> str:
    """``expr`` as the int32 the model reports: ``.w`` words zero-extended from 16 bits, ``.l`` words as int32."""
    size = dict(STATE_WORDS[program]).get(word, 4)
    return f"(int32_t)(uint16_t)({expr})" if size == 2 else f"(int32_t)({expr})"


def glue_core(adapter: Adapter, programs: tuple[str, ...] = PROGRAMS, prefix: str = "fwpc") -> str:
    """The C functions that run a stream through the port (shared by the glue library and the generated unit
    tests): ``static void <prefix>_set(...)``, ``static int32_t <prefix>_words(...)``, ``<prefix>_run``."""
    slots = const_slots()
    lines = [f"/* constants from the flat vector: {', '.join(slots)} */",
             f"static void {prefix}_set({adapter.consts_type} *fwpc_c, const int32_t *v, const int32_t *alt)", "{"]
    for i, slot in enumerate(slots):
        if slot in adapter.consts:
            lines.append(f"    {_fill(adapter.consts[slot], c='(*fwpc_c)')} = v[{i}];")
    if "ALT" in adapter.consts:
        lines.append(f"    {_fill(adapter.consts['ALT'], c='(*fwpc_c)')} = alt;")
    lines += ["    (void)v;", "    (void)alt;", "}", ""]
    lines += ["/* the state words after init / step, in the order of the model (firmware_model.model.trace) */",
              f"static int32_t {prefix}_words(int32_t program, const {adapter.state_type} *fwpc_s, int32_t nw, "
              "int32_t *out)", "{"]
    if adapter.words is None:
        lines += ["#ifdef FW_MAX_WORDS", "    int32_t tmp[FW_MAX_WORDS + 1];", "#else", "    int32_t tmp[64];",
                  "#endif", "    int32_t i, k;",
                  "    k = (int32_t)fw_words((fw_program)program, fwpc_s, tmp);",
                  "    for (i = 0; i < nw && i < k; i++) {", "        out[i] = tmp[i];", "    }", "    return k;"]
    else:
        lines += ["    (void)nw;", "    switch (program) {"]
        for p in programs:
            if p not in adapter.programs:
                continue
            names = word_names(p)
            lines.append(f"    case {PROGRAM_IDS[p]}:")
            for j, w in enumerate(names):
                expr = adapter.words.get(p, {}).get(w)
                if expr is not None:
                    lines.append(f"        out[{j}] = {_word_cast(p, w, _fill(expr, s='(*fwpc_s)'))};")
            lines.append(f"        return {len(names)};")
        lines += ["    default:", "        break;", "    }", "    return 0;"]
    lines += ["}", ""]
    lines += ["/* FWPC_PROGRESS(i): i samples stepped (-1: before init); check-port's child reads it after a crash */",
              "#ifndef FWPC_PROGRESS", "#define FWPC_PROGRESS(i) ((void)0)", "#endif", "",
              f"static int32_t {prefix}_run(int32_t program, const int32_t *v, const int32_t *alt, int32_t n, "
              "const int32_t *baro, const int16_t *acc, int32_t nw, int32_t *out)", "{",
              f"    static {adapter.consts_type} fwpc_c;", f"    static {adapter.state_type} fwpc_s;",
              "    int32_t i, k = 0;", "    memset(&fwpc_c, 0, sizeof fwpc_c);",
              "    memset(&fwpc_s, 0, sizeof fwpc_s);",
              f"    {prefix}_set(&fwpc_c, v, alt);", "    FWPC_PROGRESS(-1);", "    if (n < 1) {",
              "        return 0;", "    }",
              "    switch (program) {"]
    for p in programs:
        if p not in adapter.programs:
            continue
        call = dict(s="fwpc_s", c="fwpc_c", program=adapter.programs[p])
        lines += [f"    case {PROGRAM_IDS[p]}:",
                  "        " + _fill(adapter.init, baro="baro[0]", acc="acc[0]", **call),
                  f"        k = {prefix}_words(program, &fwpc_s, nw, out);", "        FWPC_PROGRESS(0);",
                  "        for (i = 0; i < n; i++) {",
                  "            " + _fill(adapter.step, baro="baro[i]", acc="acc[i]", **call),
                  f"            {prefix}_words(program, &fwpc_s, nw, out + (i + 1) * nw);",
                  "            FWPC_PROGRESS(i + 1);", "        }",
                  "        break;"]
    lines += ["    default:", "        return -1;", "    }", "    return k;", "}", ""]
    return "\n".join(lines)


def includes(adapter: Adapter) -> str:
    """The ``#include`` lines (standard headers, then the port's) and the adapter's prelude."""
    out = ["#include <stdint.h>", "#include <string.h>"]
    out += [f'#include "{h}"' if not h.startswith("<") else f"#include {h}" for h in adapter.include]
    if adapter.prelude:
        out += ["", adapter.prelude.rstrip()]
    return "\n".join(out)


def glue_source(adapter: Adapter) -> str:
    """The glue library's C source (module docstring)."""
    names: list[str] = []
    if adapter.words is None:
        names = ["int32_t fwpc_n_words(int32_t program)", "{",
                 f"    static {adapter.state_type} s;", "    int32_t tmp[64];", "    memset(&s, 0, sizeof s);",
                 "    return (int32_t)fw_words((fw_program)program, &s, tmp);", "}", "",
                 "const char *fwpc_word_name(int32_t program, int32_t i)", "{",
                 "    return fw_word_name((fw_program)program, (int)i);", "}"]
    else:
        names = ["int32_t fwpc_n_words(int32_t program)", "{", "    switch (program) {"]
        for p in PROGRAMS:
            if p in adapter.programs:
                names.append(f"    case {PROGRAM_IDS[p]}: return {len(word_names(p))};")
        names += ["    default: return 0;", "    }", "}", "",
                  "const char *fwpc_word_name(int32_t program, int32_t i)", "{"]
        for p in PROGRAMS:
            if p in adapter.programs:
                ws = list(word_names(p))
                arr = ", ".join(json.dumps(w) for w in ws)
                names += [f"    static const char *const w{PROGRAM_IDS[p]}[] = {{{arr}}};",
                          f"    if (program == {PROGRAM_IDS[p]} && i >= 0 && i < {len(ws)}) "
                          f"return w{PROGRAM_IDS[p]}[i];"]
        names += ["    (void)program;", "    (void)i;", '    return "?";', "}"]
    return "\n".join([
        f"/* check-port glue, generated by fwemu for {adapter.source}: do not edit. */",
        includes(adapter), "",
        "int32_t fwpc_abi(void);", "int32_t fwpc_n_words(int32_t program);",
        "const char *fwpc_word_name(int32_t program, int32_t i);",
        "int32_t fwpc_run_stream(int32_t program, const int32_t *v, const int32_t *alt, int32_t n, "
        "const int32_t *baro, const int16_t *acc, int32_t nw, int32_t *out);", "",
        f"int32_t fwpc_abi(void) {{ return {GLUE_ABI}; }}", "",
        "/* set by check-port's child process (a word of a shared file): the samples stepped so far */",
        "extern volatile int32_t *fwpc_progress_word;", "volatile int32_t *fwpc_progress_word = 0;",
        "#define FWPC_PROGRESS(i) do { if (fwpc_progress_word) { *fwpc_progress_word = (int32_t)(i); } } while (0)",
        "",
        glue_core(adapter),
        "int32_t fwpc_run_stream(int32_t program, const int32_t *v, const int32_t *alt, int32_t n, "
        "const int32_t *baro, const int16_t *acc, int32_t nw, int32_t *out)", "{",
        "    return fwpc_run(program, v, alt, n, baro, acc, nw, out);", "}", "",
        *names, ""])

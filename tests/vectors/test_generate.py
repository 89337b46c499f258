"""Golden vectors: the committed set is fresh (regenerating it changes no byte), self-consistent (manifest hashes,
schema, JSON == header), generated deterministically, and every expected word equals the integer model's
(computed here from the build config alone, independently of the generator's run)."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from firmware_model.model.streams import Stream
from firmware_model.vectors import generate as vectors
from firmware_model.vectors import c_header as vec_c_header
from firmware_model.vectors import case_json as vec_case_json
from firmware_model.vectors import cases as vec_cases
from firmware_model.vectors import compute as vec_compute
from firmware_model.vectors import schema as vec_schema
from firmware_model.spec.config import BuildConfig
from firmware_model.spec.build_constants import build_constants
from firmware_model.runtime.errors import UserError
from firmware_model.model.streams import EDGE_KINDS, FlightParams, edge_stream, synthetic_flight
from firmware_model.model.run import run_model
from firmware_model.model.trace import EVENT_BITS

ROOT = Path(__file__).resolve().parents[2]
VECTORS = ROOT / "vectors"
SHARED_ABSENT = not Path(os.environ.get("FWEMU_SHARED_FLIGHTS") or ROOT.parent / "shared" / "flights").is_dir()


def committed_cases() -> list[Path]:
    return sorted((VECTORS / "cases").glob("*.json"))


@pytest.fixture(scope="module")
def manifest() -> dict:
    return json.loads((VECTORS / "manifest.json").read_text())


@pytest.fixture(scope="module")
def docs() -> dict[str, dict]:
    return {p.stem: json.loads(p.read_text()) for p in committed_cases()}


# ----------------------------------------------------------------------------------------------- freshness
@pytest.fixture(scope="module")
def regenerated(tmp_path_factory: pytest.TempPathFactory, manifest: dict) -> Path:
    """The whole set regenerated from scratch with the generator the committed set names."""
    if SHARED_ABSENT:
        pytest.skip("the flight cases need ../shared/flights")
    gens = manifest["generators"]
    generator = "emulation" if gens == [vec_compute.GENERATOR_EMULATION] else "model"
    out = tmp_path_factory.mktemp("regen") / "vectors"
    vectors.generate_all(out, generator, progress=False)
    return out


def test_committed_set_is_the_emulated_firmware_cross_checked(manifest: dict) -> None:
    assert manifest["kind"] == "all"
    assert manifest["generators"] == [vec_compute.GENERATOR_EMULATION], \
        "the committed vectors must come from the 68000 emulation (fwemu vectors --all --out vectors)"


def test_committed_vectors_are_fresh(regenerated: Path, manifest: dict) -> None:
    new = json.loads((regenerated / "manifest.json").read_text())
    stale = sorted(p for p in set(new["files"]) | set(manifest["files"])
                   if new["files"].get(p) != manifest["files"].get(p))
    assert not stale, f"{len(stale)} stale vector file(s), e.g. {stale[:5]}: run `fwemu vectors --all --out vectors`"
    assert (regenerated / "manifest.json").read_bytes() == (VECTORS / "manifest.json").read_bytes()
    for rel in new["files"]:
        assert (regenerated / rel).read_bytes() == (VECTORS / rel).read_bytes(), rel


def test_manifest_matches_files_on_disk() -> None:
    assert vectors.check_set(VECTORS) == []


def test_checker_catches_a_corrupted_manifest_hash(tmp_path: Path) -> None:
    import shutil

    copy = tmp_path / "set"
    shutil.copytree(VECTORS, copy, ignore=shutil.ignore_patterns("build"))
    assert vectors.check_set(copy) == []
    man = json.loads((copy / "manifest.json").read_text())
    victim = sorted(man["files"])[3]
    digest = man["files"][victim]
    man["files"][victim] = ("0" if digest[0] != "0" else "1") + digest[1:]
    (copy / "manifest.json").write_text(json.dumps(man, sort_keys=True, indent=1) + "\n")
    assert vectors.check_set(copy) == [f"{victim}: SHA-256 differs from the manifest"]
    # and a file changed on disk (hash in the manifest intact) is caught too
    man["files"][victim] = digest
    (copy / "manifest.json").write_text(json.dumps(man, sort_keys=True, indent=1) + "\n")
    (copy / victim).write_bytes((copy / victim).read_bytes() + b" ")
    assert vectors.check_set(copy) == [f"{victim}: SHA-256 differs from the manifest"]
    (copy / "cases" / "extra.h").write_text("/* stray */\n")
    assert "cases/extra.h: not listed in the manifest" in vectors.check_set(copy)


SUBSET = ["recursive_floor_k4_b16_edge_ties", "kalman_baro_half_up_k5_b12_edge_step",
          "kalman_accel_floor_k4_b16_flight", "recursive_seed_literal_half_up_k6_b16_edge_ramp",
          "kalman_baro_floor_k4_b16_flight_fast"]


def test_second_generation_changes_no_byte(tmp_path: Path) -> None:
    """Two generations in separate interpreters with different hash seeds, the second over the first's output."""
    script = ("import sys; from firmware_model.vectors import generate as vectors; "
              "vectors.generate_subset(sys.argv[2:], sys.argv[1], 'model')")
    out = tmp_path / "set"
    snapshots = []
    for seed in ("1", "2"):
        env = dict(os.environ, PYTHONHASHSEED=seed)
        subprocess.run([sys.executable, "-c", script, str(out), *SUBSET], check=True, env=env, cwd=ROOT)
        snapshots.append({p.relative_to(out).as_posix(): p.read_bytes() for p in sorted(out.rglob("*"))
                          if p.is_file()})
    assert snapshots[0] == snapshots[1]
    assert len([p for p in snapshots[0] if p.endswith(".json") and p.startswith("cases/")]) == len(SUBSET)
    assert not [p for p in out.iterdir() if p.name.startswith(".")], "temporary directories left behind"


# ----------------------------------------------------------------------------------------------- contents
@pytest.mark.skipif(SHARED_ABSENT, reason="the flight cases need ../shared/flights")
def test_case_matrix_size_and_coverage(docs: dict[str, dict]) -> None:
    names = {spec.name for spec in vec_cases.case_matrix()}
    assert names == set(docs)
    total = sum(p.stat().st_size for p in VECTORS.rglob("*") if p.is_file() and "build" not in p.parts)
    assert total < 31.0e6    # 30.04 MB since issue 30's third round (+0.64 MB: HP, 4 bytes a sample of every
    #                          kalman_accel case in its JSON and header, H_STEP and threshold_sigmas in every case);
    #                          29.40 MB since issue 30's descent guard (+1.7 MB: HMAX and HT, 6 bytes a sample of
    #                          every Kalman case, in its JSON and its header, and DESC_N);
    #                          27.70 MB since issue 30 (+0.28 MB: GUARDS, DG, V_FALL, H_FLOOR in every case's JSON
    #                          and header, ~410 bytes x 680 cases);
    #                          27.12 MB since the clipped-accelerometer change (CLP, E0 words, A_DRAG, CLIP_N and the
    #                          kalman_accel sim_sup_m6400 case; generated with the model: the 68000 emulation's
    #                          cycle reports add ~0.22 MB, 25.79 -> 26.01 MB on the set before it, so ~27.34 MB);
    #                          26.0 MB since issue 20 (21.1 MB before: PHASE, CST, DLY, VB, LOCK words and the
    #                          supersonic cases, docs/vectors.md)
    programs = {d["firmware"]["program"] for d in docs.values()}
    assert programs == {"recursive", "kalman_baro", "kalman_accel", "recursive_seed_literal"}
    assert {d["rounding"] for d in docs.values()} == {"floor", "half_up"}
    assert {d["sample_period"]["k"] for d in docs.values()} == set(vec_cases.MATRIX_K)
    # every event bit occurs somewhere in the expected words (the vectors exercise every branch of the logic)
    seen = 0
    for d in docs.values():
        if "EVENTS" in d["words"]:
            col = d["words"].index("EVENTS")
            for row in d["expected"]:
                seen |= row[col]
    assert seen == sum(EVENT_BITS.values())


def test_every_case_validates_against_the_schema(docs: dict[str, dict]) -> None:
    schema = json.loads((VECTORS / "schema.json").read_text())
    assert schema == vec_schema.case_schema()
    for name, doc in docs.items():
        assert vec_schema.validate(doc, schema) == [], name
        assert len(doc["adc"]) == len(doc["acc"]) == len(doc["expected"]) == doc["input"]["n_samples"]
        assert all(len(row) == len(doc["words"]) for row in doc["expected"])


def test_schema_validator_reports_bad_documents(docs: dict[str, dict]) -> None:
    schema = vec_schema.case_schema()
    doc = json.loads(json.dumps(docs["kalman_baro_floor_k4_b16_edge_step"]))
    del doc["init"]
    doc["adc"][3] = 2**31          # the barometer word is at most a signed 32-bit word (the pascal kind)
    doc["gains"]["G11"]["s"] = "7"
    doc["surprise"] = 1
    doc["acc"][5] = -32769         # below the minimum, in an array of ints (the validator's fast path must fall back)
    doc["acc"][6] = True           # a bool is not an integer here
    doc["expected"][2][1] = "x"
    errs = vec_schema.validate(doc, schema)
    assert "$.acc[5]: -32769 < minimum -32768" in errs
    assert "$.acc[6]: expected integer, got bool" in errs
    assert "$.expected[2][1]: expected integer, got str" in errs
    assert "$: missing required key 'init'" in errs
    assert "$.adc[3]: 2147483648 > maximum 2147483647" in errs
    assert "$.gains.G11.s: expected integer, got str" in errs
    assert "$: unexpected key 'surprise'" in errs


def test_expected_words_equal_the_integer_model(docs: dict[str, dict]) -> None:
    """Independent check: rebuild the constants from each case's build config and run the integer model."""
    consts_by_cfg: dict[str, object] = {}
    for name, doc in docs.items():
        key = json.dumps(doc["build_config"], sort_keys=True)
        if key not in consts_by_cfg:
            consts_by_cfg[key] = build_constants(BuildConfig.from_dict(doc["build_config"]))
        consts = consts_by_cfg[key]
        assert doc["constants"] == {c: int(getattr(consts, c)) for c in vec_cases.SCALAR_CONSTANTS}, name
        assert {g: (v["m"], v["s"]) for g, v in doc["gains"].items()} == \
            {g: (q.m, q.s) for g, q in consts.gains.items()}, name
        model = run_model(consts, np.array(doc["adc"]), np.array(doc["acc"]))
        assert model.init_words.tolist() == doc["init"], name
        exp = np.array(doc["expected"], dtype=np.int64)
        diff = np.argwhere(model.words != exp)
        assert diff.size == 0, f"{name}: first difference at sample/word {diff[0].tolist()}"


_ARRAY = re.compile(r"static const (u?int\d+_t) fwv_(\w+?)_(adc|pa|acc|init|expected)\[[^=]*= \{(.*?)\};", re.S)


def test_headers_hold_the_same_data_as_the_json(docs: dict[str, dict]) -> None:
    for name, doc in docs.items():
        text = (VECTORS / "cases" / f"{name}.h").read_text()
        arrays = {}
        for ctype, case, what, body in _ARRAY.findall(text):
            assert case == name
            body = body.replace("(-2147483647 - 1)", "-2147483648")
            arrays[what] = [int(v) for v in re.findall(r"-?\d+", body)]
        pascal = doc["build_config"].get("baro_kind") == "pascal"
        assert arrays["pa" if pascal else "adc"] == doc["adc"], name          # pascal: int32_t fwv_<case>_pa[]
        assert ("adc" in arrays) != pascal and ("pa" in arrays) == pascal, name
        assert arrays["acc"] == doc["acc"], name
        assert arrays["init"] == doc["init"], name
        assert arrays["expected"] == [v for row in doc["expected"] for v in row], name
        up = name.upper()
        for c, v in doc["constants"].items():
            assert re.search(rf"#define FWV_{up}_{c} \({v}\)", text) or v == -(1 << 31), (name, c)
        for g, q in doc["gains"].items():
            assert f"#define FWV_{up}_{g}_M ({q['m']})" in text and f"#define FWV_{up}_{g}_S ({q['s']})" in text


def test_flight_cases_see_liftoff_and_emulation_cycles(docs: dict[str, dict]) -> None:
    for name, doc in docs.items():
        if doc["input"]["name"].startswith("flight"):
            assert doc["events_first_sample"]["LIFTOFF"] >= 0, name
            assert doc["input"]["truth"]["apogee_sample"] > doc["events_first_sample"]["LIFTOFF"], name
        if doc["generator"] == vec_compute.GENERATOR_EMULATION:
            cyc = doc["cycles_68000"]
            assert 0 < cyc["step_min"] <= cyc["step_mean"] <= cyc["step_max"], name
            assert doc["firmware"]["source_sha256"] and len(doc["firmware"]["source_sha256"]) == 64


# ----------------------------------------------------------------------------------------------- inputs
def test_streams_are_deterministic_and_in_range() -> None:
    for bits in (8, 12, 16):
        full = (1 << bits) - 1
        for kind in EDGE_KINDS:
            s = edge_stream(kind, 40, bits, 5)
            assert s.adc.min() >= 0 and s.adc.max() <= full and s.acc.min() >= -32768 and s.acc.max() <= 32767
        a = synthetic_flight(5, bits, seed=7, params=FlightParams(units_per_metre=3.5 * 2.0 ** (bits - 16)))
        b = synthetic_flight(5, bits, seed=7, params=FlightParams(units_per_metre=3.5 * 2.0 ** (bits - 16)))
        c = synthetic_flight(5, bits, seed=8, params=FlightParams(units_per_metre=3.5 * 2.0 ** (bits - 16)))
        assert np.array_equal(a.adc, b.adc) and np.array_equal(a.acc, b.acc)
        assert not np.array_equal(a.acc, c.acc)
        assert a.adc.min() >= 0 and a.adc.max() <= full
    assert edge_stream("adc_max", 8, 12, 4).adc.tolist() == [4095] * 8
    assert edge_stream("adc_min", 8, 16, 4).acc.tolist() == [-32768] * 8
    assert edge_stream("ties", 8, 16, 4).adc.tolist() == [32767, 32768, 32768, 32767] * 2
    with pytest.raises(UserError, match="unknown kind 'wobble'"):
        edge_stream("wobble", 8, 16, 4)
    with pytest.raises(UserError, match="bits=20"):
        edge_stream("step", 8, 20, 4)


def test_synthetic_flight_physics_is_plausible() -> None:
    """Noise-free flight: the barometer minimum (pressure ADC) is at the true apogee, the pad reading is 1 g, the
    altitude in counts matches units_per_metre near the pad."""
    p = FlightParams(baro_sigma=1e-9, accel_sigma=1e-9, units_per_metre=3.5)
    s = synthetic_flight(6, 16, seed=0, params=p)
    dt = 2.0 ** -6
    assert abs(int(np.argmin(s.adc)) - s.truth["apogee_s"] / dt) < 0.6 / dt   # flat top of +-0.6 s (1 count)
    assert abs(s.acc[0] - 2048) <= 1
    drop = s.adc[0] - s.adc.min()
    assert abs(drop - 3.5 * s.truth["apogee_height_m"]) < 0.05 * drop   # ISA non-linearity < 5 % below 1 km
    # the kinematic integral of (acc - pad) recovers the peak speed
    v = np.cumsum(s.acc - s.acc[0]) / p.accel_counts_per_mps2 * dt
    assert abs(v.max() - s.truth["max_speed_mps"]) < 0.03 * s.truth["max_speed_mps"]


# ----------------------------------------------------------------------------------------------- user streams
def test_user_csv_errors_name_file_and_line(tmp_path: Path) -> None:
    f = tmp_path / "log.csv"
    cases = [("", "empty file"), ("adc,acc\n", "no samples"), ("time,acc\n1,2\n", ":1: header must name"),
             ("adc,acc\n100,0\n200\n", ":3: expected 2 fields"), ("adc,acc\n100,0\nabc,1\n", ":3: adc='abc'"),
             ("adc,acc\n100,0\n100,40000\n", ":3: acc=40000 outside"), ("adc\n70000\n", ":2: adc=70000 outside")]
    for text, msg in cases:
        f.write_text(text)
        with pytest.raises(UserError) as exc:
            vectors.read_stream_csv(f, 16, 7)
        assert str(f) in str(exc.value) and msg in str(exc.value), (text, str(exc.value))
    with pytest.raises(UserError, match="no such input file"):
        vectors.read_stream_csv(tmp_path / "missing.csv", 16, 7)


def test_user_set_from_csv_runs_and_refuses_the_committed_dir(tmp_path: Path) -> None:
    f = tmp_path / "My Log.csv"
    rows = ["# a comment", "adc,acc,extra"] + [f"{40000 - 3 * i},{2048 + (i % 3)},x" for i in range(20)]
    f.write_text("\n".join(rows) + "\n")
    cfg = tmp_path / "cfg.json"
    cfg.write_text(json.dumps({"k": 5, "rounding": "half_up", "ratio": 1000.0}))
    out = tmp_path / "out"
    files = vectors.generate_user("kalman_baro", f, out, cfg, generator="model")
    name = "kalman_baro_half_up_k5_b16_my_log"
    assert f"cases/{name}.json" in files and f"cases/{name}.h" in files and "c/cases.h" in files
    doc = json.loads((out / "cases" / f"{name}.json").read_text())
    assert doc["build_config"]["ratio"] == 1000.0 and doc["input"]["provenance"]["generator"] == "user CSV"
    assert doc["adc"][:2] == [40000, 39997] and vectors.check_set(out) == []
    with pytest.raises(UserError, match="holds the committed vector set"):
        vectors.generate_user("kalman_baro", f, VECTORS, cfg, generator="model")


def test_failed_generation_writes_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "out"
    vectors.generate_subset(SUBSET[:2], out, "model")
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    calls = {"n": 0}
    real = vec_compute.compute_case

    def flaky(spec, generator="emulation", builds=None):
        calls["n"] += 1
        if calls["n"] == 3:
            raise UserError("boom")
        return real(spec, generator, builds)

    monkeypatch.setattr(vectors, "compute_case", flaky)
    with pytest.raises(UserError, match="boom"):
        vectors.generate_subset(SUBSET, out, "model")
    after = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert after == before


# ----------------------------------------------------------------------------------------------- CLI
def _cli(argv: list[str]) -> int:
    """Run ``fwemu vectors`` through the module's own ``register`` (the contract of firmware_model.cli.main)."""
    import argparse

    from firmware_model.cli import vectors as cli_vectors

    parser = argparse.ArgumentParser(prog="fwemu")
    cli_vectors.register(parser.add_subparsers())
    args = parser.parse_args(["vectors", *argv])
    return args.func(args)


def test_cli_check_and_user_set(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert _cli(["--check", str(VECTORS)]) == 0
    assert capsys.readouterr().out.strip().endswith(": OK")
    f = tmp_path / "s.csv"
    f.write_text("adc,acc\n" + "\n".join(f"{30000 + i},2048" for i in range(10)) + "\n")
    out = tmp_path / "out"
    assert _cli(["--firmware", "recursive", "--input", str(f), "--out", str(out), "--generator", "model"]) == 0
    assert "wrote 1 case(s)" in capsys.readouterr().err
    (out / "cases" / "recursive_floor_k7_b16_s.h").write_text("tampered\n")
    assert _cli(["--check", str(out)]) == 1
    assert "cases/recursive_floor_k7_b16_s.h: SHA-256 differs" in capsys.readouterr().out
    with pytest.raises(UserError, match="--firmware needs --input"):
        _cli(["--firmware", "recursive", "--out", str(out)])
    with pytest.raises(UserError, match="go with --firmware"):
        _cli(["--all", "--config", "x.json", "--out", str(out)])


def test_jobs_give_byte_identical_files_in_case_order() -> None:
    """--jobs N: worker processes, results in matrix order, the same bytes as the committed set (which --jobs 1 gives:
    test_committed_vectors_are_fresh, tests/vectors/test_reproducible_bytes.py)."""
    # 40 cases across programs, roundings, k, widths and streams (none of them a real-log case: those come last,
    # so the pick is the same with or without ../shared/flights)
    # (--jobs 1 against the committed files is test_committed_vectors_are_fresh's and the coretype tests'; here the
    # worker path alone, so the 40 cases are emulated once, not twice: issue 29)
    specs = vec_cases.case_matrix(require_logs=False)[::16]
    # as generate_all runs them: the first part handed to the workers, the rest built meanwhile (``more``)
    two = vectors.generate(specs[:25], "emulation", progress=False, jobs=2, more=lambda: specs[25:])
    assert [r.spec.name for r in two] == [s.name for s in specs]
    b = vectors.render_set(two, "subset")
    cases = [rel for rel in b if rel.startswith("cases/")]
    assert len(cases) == 2 * len(specs)
    for rel in cases:
        assert (VECTORS / rel).read_bytes() == b[rel], rel


def test_job_batches_keep_each_build_in_one_batch() -> None:
    """--jobs batches: every case exactly once, in order within a batch, all cases of a build in the same batch."""
    specs = vec_cases.case_matrix(require_logs=False)
    for jobs in (2, 3):
        batches = vectors._job_batches(specs, jobs)
        flat = [i for b in batches for i in b]
        assert sorted(flat) == list(range(len(specs)))
        assert all(b == sorted(b) for b in batches)
        where = {}
        for n, b in enumerate(batches):
            for i in b:
                assert where.setdefault(specs[i].cfg, n) == n, specs[i].name
        assert 1 < len(batches) <= 4 * jobs


def test_jobs_pool_started_early_is_ended_when_the_matrix_fails(tmp_path, monkeypatch) -> None:
    """generate_all --jobs 2 starts its workers before building the case matrix: a matrix that fails (the shared
    logs absent) raises the one-line UserError and leaves no worker process behind."""
    import multiprocessing

    monkeypatch.setenv("FWEMU_SHARED_FLIGHTS", str(tmp_path / "absent"))
    with pytest.raises(UserError, match="shared logs"):
        vectors.generate_all(tmp_path / "out", jobs=2, progress=False)
    assert not multiprocessing.active_children()
    assert not (tmp_path / "out").exists()


def test_render_case_equals_case_json_and_case_header() -> None:
    """render_case (both files from one text conversion of the rows) gives the bytes of case_json and case_header,
    also for a row holding INT32_MIN (the C spelling differs from the JSON one) and for rows that are not lists of
    Python ints (the per-value path)."""
    spec = vec_cases.case_matrix(require_logs=False)[0]
    res = vec_compute.compute_case(spec)
    words = [list(r) for r in res.words]
    words[1][0] = -(1 << 31)
    words[2][-1] = 2**31 - 1
    for rows in (res.words, words, np.asarray(words, dtype=np.int64), [tuple(r) for r in words]):
        res.words = rows
        assert vectors.render_case(res) == (vec_case_json.case_json(res).encode(),
                                            vec_c_header.case_header(res).encode())
    res.words = words
    assert b"(-2147483647 - 1)" in vectors.render_case(res)[1] and b"-2147483648" in vectors.render_case(res)[0]


def _spec_fields(spec: vec_cases.CaseSpec) -> tuple:
    st = spec.stream
    return (spec.name, spec.cfg, st.name, st.k, st.bits, st.adc.dtype, st.adc.tolist(), st.acc.dtype, st.acc.tolist(),
            json.dumps(st.provenance, sort_keys=True), json.dumps(st.truth, sort_keys=True))


def test_flight_cases_come_from_the_disk_cache_unchanged(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The flight cases are computed once per content key and stored; a second call loads them without reading a
    log (the computing function is then broken) and gives the same specs, field by field, as a computation with no
    cache at all; another key (require_logs, code digest) computes again."""
    from firmware_model.runtime import diskcache
    from firmware_model.vectors import flight_cases as vectorcases

    args = (vec_cases.case_name, vec_cases.CaseSpec, Stream)
    monkeypatch.setenv("FWEMU_CACHE_DIR", "off")
    fresh = vectorcases.flight_case_specs(*args, require_logs=False)
    monkeypatch.setenv("FWEMU_CACHE_DIR", str(tmp_path))
    first = vectorcases.flight_case_specs(*args, require_logs=False)
    stored = list((tmp_path / "cases").glob("flights-*.pickle"))
    assert len(stored) == 1
    real = vectorcases._flight_case_specs

    def broken(*a, **k):
        raise AssertionError("computed again")

    monkeypatch.setattr(vectorcases, "_flight_case_specs", broken)
    again = vectorcases.flight_case_specs(*args, require_logs=False)
    assert [_spec_fields(s) for s in again] == [_spec_fields(s) for s in first] == [_spec_fields(s) for s in fresh]
    assert len(again) > 0
    with pytest.raises(AssertionError, match="computed again"):
        vectorcases.flight_case_specs(*args, require_logs=True)
    monkeypatch.setattr(diskcache, "source_digest", lambda: "another version")
    with pytest.raises(AssertionError, match="computed again"):
        vectorcases.flight_case_specs(*args, require_logs=False)
    monkeypatch.setattr(vectorcases, "_flight_case_specs", real)
    stored[0].write_bytes(b"damaged")  # a damaged entry is a miss
    monkeypatch.undo()
    monkeypatch.setenv("FWEMU_CACHE_DIR", str(tmp_path))
    assert [_spec_fields(s) for s in vectorcases.flight_case_specs(*args, require_logs=False)] == \
        [_spec_fields(s) for s in fresh]


def test_build_constants_come_from_the_disk_cache_unchanged(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """vectors' constants: computed once per config and code, stored, then loaded (equal to a fresh derivation)
    without designing again; another config is designed."""
    cfg = BuildConfig(program="kalman_accel", k=6)
    other = BuildConfig(program="kalman_accel", k=5)
    monkeypatch.setenv("FWEMU_CACHE_DIR", str(tmp_path))
    vec_compute._constants.cache_clear()
    try:
        first = vec_compute._constants(cfg)
        assert len(list((tmp_path / "constants").glob("*.pickle"))) == 1
        vec_compute._constants.cache_clear()

        def broken(c):
            raise AssertionError("designed again")

        monkeypatch.setattr(vec_compute, "build_constants", broken)
        again = vec_compute._constants(cfg)
        assert again == first == build_constants(cfg)
        with pytest.raises(AssertionError, match="designed again"):
            vec_compute._constants(other)
    finally:
        vec_compute._constants.cache_clear()


def test_integer_arrays_render_as_before() -> None:
    """The input arrays' JSON and C texts: numpy int arrays (the fast path) read as the value-by-value spelling,
    INT32_MIN spelled as a C expression, other dtypes and plain lists through the per-value path."""
    vals = [0, 1, -1, 65535, 2**31 - 1, -(2**31), 7] * 5
    want_c = ",\n".join("    " + ", ".join("(-2147483647 - 1)" if v == -(2**31) else str(v) for v in vals[i:i + 16])
                        for i in range(0, len(vals), 16))
    for arr in (np.asarray(vals, dtype=np.int64), vals, np.asarray(vals, dtype=np.float64)):
        assert vec_c_header._c_rows(arr) == want_c
        assert vec_case_json._json_values(arr) == ", ".join(str(v) for v in vals)
    no_min = [v for v in vals if v != -(2**31)]
    assert vec_c_header._c_rows(np.asarray(no_min, dtype=np.int32)) == ",\n".join(
        "    " + ", ".join(str(v) for v in no_min[i:i + 16]) for i in range(0, len(no_min), 16))


def test_real_log_cases_are_carried_over_unchanged_without_the_logs() -> None:
    """Without ../shared/flights, `fwemu vectors --all` keeps the committed real-log cases: each one read back from
    the set renders the same case-table row and altitude-table files as the committed ones, in the same place."""
    from firmware_model.vectors.c_header import alt_table_files, cases_table_header

    docs = {p.stem: json.loads(p.read_text()) for p in committed_cases()}
    log_names = [n for n, d in docs.items()
                 if str(d["input"]["provenance"].get("source", "")).startswith("../shared/flights/")]
    assert len(log_names) >= 4
    generated = [n for n in docs if n not in log_names]
    carried = vectors.carried_log_cases(VECTORS, generated)
    assert sorted(c.spec.name for c in carried) == sorted(log_names)
    committed_h = (VECTORS / "c" / "cases.h").read_text()
    for case in carried:
        assert case.rendered == ((VECTORS / "cases" / f"{case.spec.name}.json").read_bytes(),
                                 (VECTORS / "cases" / f"{case.spec.name}.h").read_bytes())
        row = cases_table_header([case], "G").split("fwv_cases[] FWV_ROM = {\n")[1].split("\n};")[0]
        assert row in committed_h, case.spec.name
        for rel, data in (alt_table_files(case.consts).items() if case.consts.ALT_TABLE else ()):
            assert (VECTORS / rel).read_bytes() == data, rel
    order = vectors._committed_table_order(VECTORS)
    assert len(order) == len(docs) and set(order) == set(docs)


def test_carrying_over_refuses_a_tampered_or_missing_set(tmp_path: Path) -> None:
    with pytest.raises(UserError, match="holds no vector set"):
        vectors.carried_log_cases(tmp_path, [])
    copy = tmp_path / "vectors"
    (copy / "cases").mkdir(parents=True)
    (copy / "c").mkdir()
    for rel in ("manifest.json", "c/cases.h"):
        (copy / rel).write_bytes((VECTORS / rel).read_bytes())
    name = next(p.stem for p in committed_cases()
                if str(json.loads(p.read_text())["input"]["provenance"].get("source", "")).startswith("../shared/"))
    for ext in (".json", ".h"):
        (copy / "cases" / f"{name}{ext}").write_bytes((VECTORS / "cases" / f"{name}{ext}").read_bytes())
    (copy / "cases" / f"{name}.h").write_bytes(b"/* tampered */\n")
    others = [n for n in vectors._committed_table_order(VECTORS) if n != name]
    with pytest.raises(UserError, match="does not match"):
        vectors.carried_log_cases(copy, others)

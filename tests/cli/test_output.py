"""Outputs of every command (firmware_model.runtime.output, issue 8 items 7-9): atomic files and folders, folder locks
for concurrent writers, one-line errors for unwritable outputs and a full stdout, clean SIGINT/SIGTERM.

CLI cases run the real ``fwemu`` in a subprocess."""

from __future__ import annotations

import errno
import json
import multiprocessing
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from firmware_model.runtime.hashing import sha256_bytes
from firmware_model.runtime import output

from firmware_model.vectors import generate as vectors
from firmware_model.vectors import cases as vec_cases
from firmware_model.runtime.errors import UserError

ROOT = Path(__file__).resolve().parents[2]
SHARED = Path(os.environ.get("FWEMU_SHARED_FLIGHTS") or ROOT.parent / "shared" / "flights")
#: `fwemu vectors --all` includes cases made from the shared flight logs (docs/vectors.md, "Flight cases").
needs_logs = pytest.mark.skipif(not SHARED.is_dir(), reason=f"shared flight logs not at {SHARED}")
SUBSET = ["recursive_floor_k4_b16_edge_step", "kalman_baro_half_up_k5_b12_edge_ties",
          "kalman_accel_floor_k6_b16_edge_ramp"]


def fwemu(*argv: str, stdout: int | None = subprocess.PIPE, timeout: float = 300,
          cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "firmware_model.cli.main", *argv], stdout=stdout,
                          stderr=subprocess.PIPE, text=True, env=env, timeout=timeout, cwd=cwd)


def one_clean_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert "Traceback" not in err and lines[0].startswith("fwemu: "), err
    return lines[0]


def temp_names(*folders: Path) -> list[Path]:
    found = []
    for folder in folders:
        if folder.is_dir():
            found += [p for p in folder.rglob("*") if p.name.startswith(".fwemu") or p.name.startswith(".old-")
                      or p.name.startswith(".budget-")]
    return found


def wait_until_catching(pid: int, sig: int = signal.SIGTERM, timeout: float = 60.0) -> None:
    """Wait until process ``pid`` has installed a handler for ``sig`` (Linux /proc SigCgt), i.e. fwemu's main() is
    running: a signal before that (interpreter start-up, imports) would get the default action. Wait on SIGTERM
    whatever signal is sent next: Python catches SIGINT from its own start-up on (KeyboardInterrupt), so only
    SIGTERM's bit says that fwemu's handlers (installed for both at once) are in place."""
    status = Path(f"/proc/{pid}/status")
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            caught = next(int(line.split()[1], 16) for line in status.read_text().splitlines()
                          if line.startswith("SigCgt:"))
        except (OSError, StopIteration):
            caught = 0
        if caught >> (sig - 1) & 1:
            return
        time.sleep(0.02)
    raise AssertionError(f"pid {pid} never caught signal {sig}")


def snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


# ------------------------------------------------------------------------------------------ the output module
def test_write_file_is_atomic_and_leaves_no_temp(tmp_path: Path) -> None:
    target = tmp_path / "a" / "b.txt"
    output.write_file(target, "one")
    output.write_file(target, b"two")
    assert target.read_text() == "two" and sorted(p.name for p in target.parent.iterdir()) == ["b.txt"]
    with pytest.raises(RuntimeError):
        with output.open_atomic(target, "w") as f:
            f.write("half")
            raise RuntimeError("stop")
    assert target.read_text() == "two" and sorted(p.name for p in target.parent.iterdir()) == ["b.txt"]


def test_output_errors_name_the_path(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(UserError, match=r"file/x\.txt: cannot create folder .*a file"):
        output.write_file(blocker / "x.txt", "y")
    with pytest.raises(UserError, match="exists and is not a folder"):
        with output.staged_folder(blocker):
            pass
    with pytest.raises(UserError, match="is a folder"):
        output.write_file(tmp_path, "y")


def test_staged_folder_commits_all_or_nothing(tmp_path: Path) -> None:
    out = tmp_path / "set"
    (out / "cases").mkdir(parents=True)
    (out / "cases" / "stale.json").write_text("old")
    (out / "c").mkdir()
    (out / "c" / "fw.c").write_text("hand-written")
    (out / "manifest.json").write_text("old manifest")
    before = snapshot(out)
    for exc in (RuntimeError("boom"), output.Interrupted(signal.SIGTERM)):
        with pytest.raises(type(exc)):
            with output.staged_folder(out, owned=("cases",)) as stage:
                (stage / "cases").mkdir()
                (stage / "cases" / "new.json").write_text("new")
                (stage / "manifest.json").write_text("new manifest")
                raise exc
        assert snapshot(out) == before
        assert temp_names(tmp_path) == []
    with output.staged_folder(out, owned=("cases",), last=("manifest.json",)) as stage:
        (stage / "cases").mkdir()
        (stage / "cases" / "new.json").write_text("new")
        (stage / "c").mkdir()
        (stage / "c" / "cases.h").write_text("generated")
        (stage / "manifest.json").write_text("new manifest")
    assert snapshot(out) == {"c/cases.h": b"generated", "c/fw.c": b"hand-written", "cases/new.json": b"new",
                             "manifest.json": b"new manifest"}
    assert temp_names(tmp_path) == []
    with output.staged_folder(out, whole=True) as stage:
        (stage / "only.txt").write_text("x")
    assert snapshot(out) == {"only.txt": b"x"} and temp_names(tmp_path) == []


def test_staged_folder_guard_refuses_under_the_lock(tmp_path: Path) -> None:
    out = tmp_path / "o"

    def guard(target: Path) -> None:
        raise UserError(f"{target}: refused")

    with pytest.raises(UserError, match="refused"):
        with output.staged_folder(out, guard=guard) as stage:
            (stage / "x").write_text("x")
    assert not (out / "x").exists() and temp_names(tmp_path) == []


def _hold_lock(target: str, ready: multiprocessing.synchronize.Event, seconds: float) -> None:
    with output.folder_lock(target):
        ready.set()
        time.sleep(seconds)


def test_folder_lock_excludes_a_second_writer_and_times_out_clearly(tmp_path: Path) -> None:
    ctx = multiprocessing.get_context("spawn")
    ready = ctx.Event()
    holder = ctx.Process(target=_hold_lock, args=(str(tmp_path / "out"), ready, 3.0))
    holder.start()
    try:
        assert ready.wait(60)
        with pytest.raises(UserError, match=r"another fwemu \(pid \d+\) is writing it; gave up after 0.3 s"):
            with output.folder_lock(tmp_path / "out", timeout=0.3):
                pass
        t0 = time.monotonic()
        with output.folder_lock(tmp_path / "out", timeout=60):   # waits for the holder, then gets it
            assert time.monotonic() - t0 > 0.5
            assert not holder.is_alive() or holder.exitcode is None
    finally:
        holder.join(60)
    assert holder.exitcode == 0
    assert temp_names(tmp_path) == [] and list(tmp_path.iterdir()) == []   # the lock file is gone too


# ------------------------------------------------------------------------------------------ two writers (item 9)
def _writer(out: str, tag: int, rounds: int, queue: multiprocessing.Queue,  # type: ignore[type-arg]  # multiprocessing.Queue is not generic at runtime
            go: multiprocessing.synchronize.Barrier) -> None:
    """Write a small vector set ``rounds`` times, each round with content unique to (tag, round)."""
    try:
        base = vectors.render_set(vectors.generate([s for s in vec_cases.case_matrix(require_logs=False)
                                                    if s.name in SUBSET],
                                                   "model", progress=False), "subset")
        go.wait(120)   # both writers start together
        for r in range(rounds):
            files = dict(base)
            files[f"cases/writer{tag}_round{r}.json"] = json.dumps({"tag": tag, "round": r}).encode()
            files["manifest.json"] = json.dumps({"kind": "subset", "files": {
                rel: sha256_bytes(data) for rel, data in sorted(files.items()) if rel != "manifest.json"}},
                sort_keys=True).encode()
            vectors.write_set(files, out, "subset")
        queue.put((tag, "ok"))
    except BaseException as exc:  # noqa: BLE001 - report everything to the parent
        queue.put((tag, f"{type(exc).__name__}: {exc}"))


def test_write_set_from_two_processes_stays_consistent(tmp_path: Path) -> None:
    out = tmp_path / "set"
    ctx = multiprocessing.get_context("spawn")
    queue = ctx.Queue()
    rounds = 150
    go = ctx.Barrier(2)
    procs = [ctx.Process(target=_writer, args=(str(out), tag, rounds, queue, go)) for tag in (1, 2)]
    for p in procs:
        p.start()
    results = dict(queue.get(timeout=300) for _ in procs)
    for p in procs:
        p.join(60)
    assert results == {1: "ok", 2: "ok"}, results
    assert vectors.check_set(out) == []
    extra = sorted(p.name for p in (out / "cases").iterdir() if p.name.startswith("writer"))
    assert len(extra) == 1 and extra[0].endswith(f"_round{rounds - 1}.json")   # one writer's last set, whole
    assert temp_names(tmp_path) == [] and sorted(p.name for p in tmp_path.iterdir()) == ["set"]


# ------------------------------------------------------------------------------------------ CLI errors (item 7)
def test_budget_out_naming_a_file_or_a_path_below_a_file(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("keep")
    for out in (blocker, blocker / "below"):
        r = fwemu("budget", "--program", "recursive", "--k", "4", "--out", str(out))
        assert r.returncode == 2, r.stderr
        assert str(out) in one_clean_line(r.stderr)
    assert blocker.read_text() == "keep" and temp_names(tmp_path) == []


@pytest.mark.parametrize("argv", [["budget", "--seed", "-1"], ["compare", "--synthetic", "-1"],
                                  ["vectors", "--all", "--jobs", "0", "--out", "x"]])
def test_negative_seeds_are_usage_errors(argv: list[str], tmp_path: Path) -> None:
    r = fwemu(*argv, cwd=tmp_path)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert "is out of range; allowed: an integer >= " in r.stderr.splitlines()[-1]
    assert list(tmp_path.iterdir()) == []


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full")
@pytest.mark.parametrize("argv", [["design"], ["design", "--json"], ["compare", "--bias-table"],
                                  ["asm", str(ROOT / "isa" / "demo" / "demo.s")],
                                  ["vectors", "--check", str(ROOT / "vectors")], ["--help"], ["asm", "--help"]])
def test_full_stdout_is_one_line(argv: list[str]) -> None:
    with open("/dev/full", "w") as full:
        r = fwemu(*argv, stdout=full)
    assert r.returncode == 2, r.stderr
    assert one_clean_line(r.stderr) == "fwemu: error: cannot write to standard output: No space left on device"


def test_budget_to_full_stdout_still_writes_nothing_partial(tmp_path: Path) -> None:
    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full")
    with open("/dev/full", "w") as full:
        r = fwemu("budget", "--program", "recursive", "--k", "4", "--out", str(tmp_path / "b"), stdout=full)
    assert r.returncode == 2 and "standard output" in one_clean_line(r.stderr)
    assert temp_names(tmp_path) == []


@pytest.fixture
def tmpfs(tmp_path: Path):
    """Mount small tmpfs file systems (read-only, 16 KiB) when allowed (root in a container); else skip."""
    mounted: list[Path] = []

    def mount(name: str, options: str) -> Path:
        point = tmp_path / name
        point.mkdir()
        r = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "fwemu-test", str(point)],
                           capture_output=True, text=True)
        if r.returncode != 0:
            pytest.skip(f"cannot mount a tmpfs here: {r.stderr.strip()}")
        mounted.append(point)
        return point

    yield mount
    for point in mounted:
        subprocess.run(["umount", str(point)], capture_output=True)


def test_read_only_and_full_file_systems_are_one_line(tmpfs, tmp_path: Path) -> None:
    ro = tmpfs("ro", "ro,size=1m")
    full = tmpfs("full", "size=16k")
    csv = tmp_path / "s.csv"
    csv.write_text("adc,acc\n" + "\n".join(f"{30000 + i},2048" for i in range(300)) + "\n")
    for out, why in ((ro / "b", "Read-only file system"), (full / "b", "No space left on device")):
        r = fwemu("budget", "--program", "recursive", "--k", "4", "--out", str(out))
        assert r.returncode == 2 and why in one_clean_line(r.stderr) and str(out) in r.stderr
        r = fwemu("vectors", "--firmware", "recursive", "--input", str(csv), "--generator", "model",
                  "--out", str(out))
        assert r.returncode == 2 and why in one_clean_line(r.stderr), r.stderr
    assert list(full.iterdir()) == [] and list(ro.iterdir()) == []


def test_enospc_during_commit_is_one_line_in_process(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """Without mount rights: a full disk while the stage is written, through main()."""
    from firmware_model.budget import cpu68k as budget
    from firmware_model.cli.main import main

    def full_disk(*args: object, **kwargs: object) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(budget, "plot_cycles", full_disk)
    assert main(["budget", "--program", "recursive", "--k", "4", "--out", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err
    assert one_clean_line(err) == f"fwemu: error: {tmp_path / 'b'}: cannot write: No space left on device"
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------------------------------ signals (item 8)
@needs_logs
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_interrupted_vectors_run_leaves_previous_outputs_and_no_temp(sig: int, tmp_path: Path) -> None:
    out = tmp_path / "vectors"
    vectors.generate_subset(SUBSET, out, "model")
    before = snapshot(out)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    outcomes = []
    for delay in (0.5, 3.0, 6.0):
        proc = subprocess.Popen([sys.executable, "-m", "firmware_model.cli.main", "vectors", "--all", "--generator",
                                 "model", "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True, env=env)
        wait_until_catching(proc.pid)
        time.sleep(delay)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=120)
        assert temp_names(tmp_path) == [], (delay, err)
        assert sorted(p.name for p in tmp_path.iterdir()) == ["vectors"]
        committed = f"fwemu: interrupted; outputs in {out} complete"
        if proc.returncode == 0 or (proc.returncode == 128 + sig and one_clean_line(err) == committed):
            # finished before the signal, or the signal came after the new set was committed (the run then says
            # so): the new set is complete
            outcomes.append("finished")
            assert vectors.check_set(out) == [] and json.loads((out / "manifest.json").read_text())["kind"] == "all"
            break
        outcomes.append("interrupted")
        assert proc.returncode == 128 + sig, err
        assert one_clean_line(err) == f"fwemu: interrupted; previous outputs in {out} left intact"
        assert snapshot(out) == before
    assert "interrupted" in outcomes


def _group(pgid: int) -> list[str]:
    """The live (not zombie) processes of process group ``pgid``, as ``ps`` lines."""
    lines = subprocess.run(["ps", "-o", "pid=,stat=,args=", "-g", str(pgid)], capture_output=True,
                           text=True).stdout.splitlines()
    return [line for line in lines if " Z" not in f" {line.split()[1]}"]   # zombies are already dead


@needs_logs
def test_interrupted_jobs_run_terminates_its_workers(tmp_path: Path) -> None:
    """Ctrl-C to the process group of `vectors --all --jobs 2` while its workers run: one line, no output, no
    temporary file, and no worker left. The signal goes once the two workers are up plus `delay`; a run that
    finished first (warm caches make the model run short) is tried again with a shorter delay."""
    for delay in (0.5, 0.1, 0.0):
        out = tmp_path / f"v{delay}"
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        proc = subprocess.Popen([sys.executable, "-m", "firmware_model.cli.main", "vectors", "--all", "--generator",
                                 "model", "--jobs", "2", "--out", str(out)], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True, env=env, start_new_session=True)
        wait_until_catching(proc.pid)
        deadline = time.monotonic() + 60
        while len(_group(proc.pid)) < 3 and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)   # the parent and its two spawned workers
        time.sleep(delay)
        os.killpg(proc.pid, signal.SIGINT)          # Ctrl-C reaches the whole process group, workers included
        _, err = proc.communicate(timeout=120)
        if proc.returncode == 0:                    # the run was done before the signal: try again, sooner
            continue
        assert proc.returncode == 130, err
        assert one_clean_line(err) == f"fwemu: interrupted; previous outputs in {out} left intact"
        assert not out.exists() and temp_names(tmp_path) == []
        deadline = time.monotonic() + 20   # the workers get SIGTERM; multiprocessing's resource tracker follows
        while _group(proc.pid) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert _group(proc.pid) == [], f"workers still running: {_group(proc.pid)}"
        return
    raise AssertionError("every run finished before the signal: no interrupt was tested")


def test_out_is_named_before_the_parser_runs() -> None:
    """An interrupt between fwemu's handlers going in and the command parsing its arguments (a loaded machine
    can take a second there) still names --out: main() declares it from argv first."""
    from firmware_model.cli.main import _declare_out_early

    output.reset_run_state()
    _declare_out_early(["vectors", "--all", "--out", "v1", "--", "--out", "not-this"], output)
    _declare_out_early(["budget", "--out=b2"], output)
    assert output.interrupted_message() == "fwemu: interrupted; previous outputs in v1, b2 left intact"
    output.reset_run_state()
    _declare_out_early(["design", "--json"], output)
    assert output.interrupted_message() == "fwemu: interrupted; nothing written"

"""The task engine (firmware_model/runtime/engine.py): backends, a dead local worker costs its chunk only, a real Dask
LocalCluster with a worker killed mid-run gives the rows of an unkilled run."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

from firmware_model.runtime.errors import UserError
from firmware_model.runtime.engine import Backend, ChunkStore, dask_available, parse_scheduler, run_chunks


def test_parse_scheduler():
    assert parse_scheduler(None, 3) == Backend("local", 3)
    assert parse_scheduler("local:2") == Backend("dask", 2, None)
    assert parse_scheduler("10.0.0.5:8786") == Backend("dask", 1, "tcp://10.0.0.5:8786")
    assert parse_scheduler("tls://h:1") == Backend("dask", 1, "tls://h:1")
    for bad in ("local:0", "local:x", " "):
        with pytest.raises(UserError, match="--scheduler"):
            parse_scheduler(bad)
    with pytest.raises(UserError, match="--jobs"):
        parse_scheduler(None, 0)


def square_or_die(chunk):
    """Test task: (i, marker folder, die_once) -> i*i; the chunk with die_once kills its worker process on its
    first attempt (a marker file per attempt says how often each chunk ran)."""
    i, folder, die = chunk
    folder = Path(folder)
    n = len(list(folder.glob(f"ran-{i}-*")))
    (folder / f"ran-{i}-{n}").write_text("")
    if die and n == 0:
        os.kill(os.getpid(), signal.SIGKILL)
    return i * i


def test_local_worker_death_costs_its_chunk_only(tmp_path):
    chunks = [(i, str(tmp_path), i == 3) for i in range(8)]
    got = dict(run_chunks(square_or_die, chunks, Backend("local", 2)))
    assert got == {i: i * i for i in range(8)}
    runs = {i: len(list(tmp_path.glob(f"ran-{i}-*"))) for i in range(8)}
    assert runs == {i: (2 if i == 3 else 1) for i in range(8)}


def test_local_skip_and_one_worker(tmp_path):
    chunks = [(i, str(tmp_path), False) for i in range(5)]
    assert sorted(run_chunks(square_or_die, chunks, Backend("local", 1), skip={1, 4})) == [(0, 0), (2, 4), (3, 9)]


def test_chunk_store_refuses_a_different_run(tmp_path):
    s = ChunkStore(tmp_path / "c", {"a": 1}, "csv")
    s.commit(0, b"x")
    assert s.done() == {0}
    with pytest.raises(UserError, match="--resume"):
        ChunkStore(tmp_path / "c", {"a": 1}, "csv")
    with pytest.raises(UserError, match="different run"):
        ChunkStore(tmp_path / "c", {"a": 2}, "csv", resume=True)
    leftover = tmp_path / "c" / ".fwemu-tmp-chunk-000001.csv-x1y2"      # what a SIGKILL mid-write leaves
    leftover.write_bytes(b"half a chu")
    assert s.done() == {0}
    assert ChunkStore(tmp_path / "c", {"a": 1}, "csv", resume=True).done() == {0}
    assert not leftover.exists()


needs_dask = pytest.mark.skipif(not dask_available(), reason="dask.distributed not installed (the 'montecarlo' extra)")


@needs_dask
def test_dask_worker_killed_mid_run_gives_the_rows_of_an_unkilled_run(tmp_path):
    import distributed

    from firmware_model.flights.montecarlo.run import run_montecarlo
    from firmware_model.flights.montecarlo.spec import load_spec
    from tests.flights.test_montecarlo import SMALL as SMALL_SPEC

    spec = load_spec({**SMALL_SPEC, "chunk_flights": 2})
    n = 24
    run_montecarlo(spec, 9, n, tmp_path / "ref", fmt="csv", figures=False)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                  silence_logs=50) as cluster, distributed.Client(cluster) as client:
        before = client.run(os.getpid)
        killed: list[int] = []

        def kill_one(done, total, seconds):
            if done >= 4 and not killed:      # two chunks in: more are running on both workers
                pid = sorted(before.values())[0]
                os.kill(pid, signal.SIGKILL)
                killed.append(pid)

        res = run_montecarlo(spec, 9, n, tmp_path / "dask", Backend("dask", 2, cluster.scheduler_address),
                             fmt="csv", progress=kill_one, figures=False)
        assert killed
        client.wait_for_workers(2, timeout=180)
        after = client.run(os.getpid)
        assert killed[0] not in after.values()       # that worker process is gone (the nanny started another)
    assert res.flights == n
    assert (tmp_path / "dask" / "rows.csv").read_bytes() == (tmp_path / "ref" / "rows.csv").read_bytes()

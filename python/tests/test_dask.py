"""Sweeps on Dask: in-process, on a LocalCluster (worker processes) and on a scheduler and a
worker started as separate processes give the same rows to the last bit; the packing makes
tasks of at least the requested work; a missing Dask or a bad executor is a clear error."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

import ringsync
from ringsync import _dask

GRID = {"control.alpha": [0.25, 0.5], "faults.loss": [0.0, 0.02]}
KW = {"seeds": 2, "duration": "0.4s"}


@pytest.fixture(scope="module")
def local() -> ringsync.Sweep:
    return ringsync.sweep("paper-2015", GRID, **KW)


@pytest.fixture(scope="module")
def client() -> Iterator[object]:
    from dask.distributed import Client, LocalCluster

    with LocalCluster(
        n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None
    ) as cluster, Client(cluster) as c:
        yield c


def test_local_cluster_gives_identical_rows_and_means(local: ringsync.Sweep, client: object) -> None:
    # Tiny tasks (one run each after the timing) spread the runs over both workers.
    sw = ringsync.sweep("paper-2015", GRID, executor=client, task_seconds=0.0, **KW)
    assert sw.rows == local.rows
    assert sw.mean_rows == local.mean_rows
    assert sw.tasks == [1] * (len(sw.rows) - 1)  # one run was timed here, to size the tasks
    # One big task instead: the same numbers (results are keyed, not ordered by task).
    big = ringsync.sweep("paper-2015", GRID, executor=client, task_seconds=1e6, **KW)
    assert big.rows == local.rows and len(big.tasks or []) == 1
    # No timing here: every run on the cluster, tasks of >= 0.5 s at 0.1 s a run.
    given = ringsync.sweep("paper-2015", GRID, executor=client, run_seconds=0.1, task_seconds=0.5, **KW)
    assert given.rows == local.rows and sum(given.tasks or []) == len(local.rows)
    assert all(n >= 5 for n in given.tasks or [])


def test_progress_line(client: object, capsys: pytest.CaptureFixture[str]) -> None:
    ringsync.sweep("paper-2015", {"control.alpha": [0.3]}, seeds=3, duration="0.2s",
                   executor=client, run_seconds=0.1, task_seconds=0.1, progress=True)
    err = capsys.readouterr().err
    assert re.search(r"ringsync sweep: (\d+)/\1 tasks, 3/3 runs\n$", err), err


def test_an_interrupted_sweep_cancels_its_tasks(client: object, monkeypatch: pytest.MonkeyPatch) -> None:
    """Ctrl-C while the results come in (KeyboardInterrupt raised where the sweep waits):
    the cluster drops the sweep's other tasks, although the traceback (as Jupyter keeps
    it) still holds their futures."""
    import distributed

    real = distributed.as_completed

    def interrupted_after_one(futures: object) -> Iterator[object]:
        for f in real(futures):
            yield f
            raise KeyboardInterrupt

    monkeypatch.setattr(distributed, "as_completed", interrupted_after_one)
    with pytest.raises(KeyboardInterrupt) as caught:
        ringsync.sweep("paper-2015", {"control.alpha": [0.1, 0.2]}, seeds=100, duration="0.2s",
                       executor=client, run_seconds=0.1, task_seconds=0.1)
    assert caught.traceback  # held, with the sweep's frames and their futures

    def tasks() -> int:
        return client.run_on_scheduler(lambda dask_scheduler: len(dask_scheduler.tasks))  # type: ignore[attr-defined]

    deadline = time.monotonic() + 30
    while tasks() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert tasks() == 0


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_separate_scheduler_and_worker_processes(local: ringsync.Sweep, tmp_path: Path) -> None:
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    dask = [sys.executable, "-m", "dask"]
    log = open(tmp_path / "dask.log", "w")
    procs = [subprocess.Popen(
        [*dask, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
        stdout=log, stderr=subprocess.STDOUT, env=env, cwd=tmp_path,
    )]
    try:
        procs.append(subprocess.Popen(
            [*dask, "worker", address, "--nthreads", "1", "--nworkers", "1",
             "--host", "127.0.0.1", "--no-dashboard"],
            stdout=log, stderr=subprocess.STDOUT, env=env, cwd=tmp_path,
        ))
        from dask.distributed import Client

        deadline = time.monotonic() + 60
        while True:
            try:
                with Client(address, timeout="5s") as c:
                    c.wait_for_workers(1, timeout=60)
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.5)
        sw = ringsync.sweep("paper-2015", GRID, executor=address, task_seconds=0.05, **KW)
        assert sw.rows == local.rows
        assert sw.mean_rows == local.mean_rows
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in reversed(procs):
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        log.close()


def test_packing_makes_tasks_of_at_least_the_requested_work() -> None:
    cases = [([0.01] * 1000, 0.5), ([0.003, 0.2, 0.04] * 37, 0.5), ([0.07] * 9, 0.5),
             ([0.6] * 3, 0.5), ([0.001 * (i % 7 + 1) for i in range(500)], 0.25)]
    for costs, task in cases:
        for slots in (1, 2, 3):
            packs = _dask.pack(costs, task, slots)
            assert sorted(i for p in packs for i in p) == list(range(len(costs)))
            assert all(p == list(range(p[0], p[-1] + 1)) for p in packs)  # contiguous
            work = [sum(costs[i] for i in p) for p in packs]
            assert all(w >= task * (1 - 1e-9) for w in work), (task, slots, min(work))
            # Even: no pack holds much more than an equal share of the work ...
            share = sum(costs) / len(packs)
            assert max(work) <= max(share, task) + max(costs) + 1e-9
            # ... and whole rounds of the slots when there is work for them.
            if sum(costs) >= slots * (task + max(costs)):
                assert len(packs) % slots == 0, (task, slots, len(packs))
    sizes = [len(p) for p in _dask.pack([0.01] * 1000, 0.5, 2)]
    assert len(sizes) == 18 and max(sizes) - min(sizes) <= 1
    assert _dask.pack([0.3] * 5, 0.0) == [[0], [1], [2], [3], [4]]
    assert _dask.pack([0.1, 0.1], 0.5) == [[0, 1]]  # less than one task's work: one task
    assert _dask.pack([], 0.5) == []


def test_bad_executor_is_a_type_or_value_error() -> None:
    with pytest.raises(TypeError, match="executor must be None.*not int"):
        ringsync.sweep("paper-2015", GRID, executor=4, **KW)
    with pytest.raises(ValueError, match="not a scheduler address"):
        ringsync.sweep("paper-2015", GRID, executor="localhost", **KW)
    with pytest.raises(ValueError, match="task_seconds"):
        ringsync.sweep("paper-2015", GRID, executor="tcp://127.0.0.1:1", task_seconds=-1, **KW)


def test_missing_dask_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed fails
    with pytest.raises(ImportError, match=r"pip install 'ringsync\[dask\]'"):
        ringsync.sweep("paper-2015", GRID, executor="tcp://127.0.0.1:8786", **KW)

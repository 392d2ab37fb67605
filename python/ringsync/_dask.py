"""Sweeps on Dask: the cases of a sweep packed into tasks of at least ``task_seconds`` of
work each, every task a pure function of plain data (the cases' text) that calls the Rust
library on a worker, the results keyed by (value indices, seed) so that a task Dask reruns
or reorders changes nothing.

Nothing here imports dask at module level: :func:`run_pack` is what a worker runs, and it
needs only ``ringsync`` (the same package, installed where the workers run).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence
from typing import Any

from . import _ringsync as _rs

__all__ = ["run_pack", "pack", "check_executor", "distributed_results"]

#: A case's key: (the index of each swept value in the grid, the seed).
Key = tuple[tuple[int, ...], int]

#: Work at least this long [s] is measured before the cases are packed (at most
#: ``_CALIBRATION_RUNS`` cases and a tenth of them, run here, their results kept).
_CALIBRATION_S = 0.05
_CALIBRATION_RUNS = 8


def run_pack(pack: Sequence[tuple[Key, str]]) -> list[tuple[Key, dict[str, Any]]]:
    """Runs a pack of cases (each ``(key, case as JSON text)``) one after the other in this
    process, the GIL released: ``[(key, result dict), …]``. A pure function of its argument:
    what a Dask worker runs.

    Example::

        >>> from ringsync import _dask, _ringsync
        >>> cases = _ringsync.sweep_cases('duration = "100ms"\\n', "t", [], 1)
        >>> [(key, r["sync_rmse"] > 0) for key, r in
        ...  _dask.run_pack([((tuple(c[0]), c[1]), c[2]) for c in cases])]
        [(((), 1), True)]
    """
    keys = [k for k, _ in pack]
    results = _rs.run_cases([text for _, text in pack], 1)
    return list(zip(keys, results))


def pack(costs: Sequence[float], task_seconds: float, slots: int = 1) -> list[list[int]]:
    """Splits cases with estimated ``costs`` [s] (in order) into contiguous packs of at
    least ``task_seconds`` [s] each, as even as whole cases allow; the number of packs is a
    multiple of ``slots`` (the cluster's worker threads) when the work allows it, so that
    no slot idles at the end while another runs a last pack. Less work than one pack's
    size goes into one pack; ``task_seconds`` 0 makes one pack per case. Returns the
    cases' indices per pack.

    How: n packs of an equal share total/n of the work, with n the largest number (a
    multiple of the slots, if at least one round) such that share ≥ task_seconds + the
    largest cost; case i goes to the pack whose share holds the middle of its cost. A pack
    then misses at most half a case at each end: it holds at least share − largest cost ≥
    task_seconds.

    Example::

        >>> from ringsync._dask import pack
        >>> [len(p) for p in pack([0.01] * 1000, 0.5)]  # 10 s of work, tasks >= 0.5 s
        [53, 52, 53, 53, 52, 53, 52, 53, 53, 52, 53, 53, 52, 53, 52, 53, 53, 52, 53]
        >>> [len(p) for p in pack([0.01] * 1000, 0.5, slots=4)]  # 16 packs, 4 per slot
        [62, 63, 62, 63, 62, 63, 62, 63, 62, 63, 62, 63, 62, 63, 62, 63]
        >>> pack([0.1, 0.1], 0.5), pack([0.3, 0.3, 0.3], 0.5)
        ([[0, 1]], [[0, 1, 2]])
    """
    if not costs:
        return []
    if task_seconds <= 0:
        return [[i] for i in range(len(costs))]
    total = float(sum(costs))
    largest = max(costs)
    n = int(total / (task_seconds + largest) * (1 + 1e-12))
    slots = max(1, int(slots))
    if n >= slots:
        n -= n % slots
    if n <= 1:
        return [list(range(len(costs)))]
    share = total / n
    packs: list[list[int]] = [[] for _ in range(n)]
    cum = 0.0
    for i, c in enumerate(costs):
        packs[min(n - 1, int((cum + c / 2) / share))].append(i)
        cum += c
    return [p for p in packs if p]


_MISSING_DASK = (
    "sweep(executor=...) runs on Dask, which is not installed: "
    "pip install 'ringsync[dask]' (or pip install 'dask[distributed]')"
)


def check_executor(executor: Any) -> None:
    """Raises before any case runs when ``executor`` cannot work: TypeError for what is
    neither an address nor a Client, ValueError for a string that is no address,
    ImportError (naming the extra to install) when Dask is missing.

    Example::

        >>> from ringsync._dask import check_executor
        >>> check_executor(4)
        Traceback (most recent call last):
        ...
        TypeError: executor must be None (threads in this process), a dask.distributed.Client or a scheduler address such as 'tcp://127.0.0.1:8786', not int
    """
    if isinstance(executor, str):
        if ":" not in executor:
            raise ValueError(
                f"executor {executor!r} is not a scheduler address: give one such as "
                "'tcp://127.0.0.1:8786', or a dask.distributed.Client"
            )
    elif type(executor).__name__ != "Client" or not hasattr(executor, "submit"):
        raise TypeError(
            "executor must be None (threads in this process), a dask.distributed.Client or "
            f"a scheduler address such as 'tcp://127.0.0.1:8786', not {type(executor).__name__}"
        )
    try:
        import distributed  # noqa: F401
    except ImportError as e:
        raise ImportError(_MISSING_DASK) from e


def _client(executor: Any) -> tuple[Any, bool]:
    """The Dask client for ``executor`` (a ``dask.distributed.Client`` or a scheduler
    address) and whether it was made here (then it is closed after the sweep)."""
    check_executor(executor)
    import distributed

    if isinstance(executor, str):
        return distributed.Client(executor, timeout="30s"), True
    return executor, False


def distributed_results(
    cases: Sequence[tuple[list[int], int, str, float]],
    executor: Any,
    *,
    task_seconds: float,
    run_seconds: float | None,
    progress: bool,
) -> tuple[list[dict[str, Any]], list[int]]:
    """Runs the ``cases`` (as :func:`ringsync._ringsync.sweep_cases` lists them) on Dask:
    a few first here to time them (unless ``run_seconds`` [s] per run is given), the rest
    packed into tasks of at least ``task_seconds`` [s]. Returns the results in the cases'
    order, and the size of each task sent (in cases)."""
    client, own = _client(executor)
    try:
        keyed: dict[Key, dict[str, Any]] = {}
        keys: list[Key] = [(tuple(c[0]), int(c[1])) for c in cases]
        start = 0
        if run_seconds is None:
            # Time the first cases here (their results are kept): seconds per axis-cycle.
            t0 = time.perf_counter()
            units = 0.0
            # At most a tenth of the cases (at least one), so most run on the cluster.
            limit = min(_CALIBRATION_RUNS, max(1, len(cases) // 10))
            while start < len(cases) and start < limit:
                (key, result), = run_pack([(keys[start], cases[start][2])])
                keyed[key] = result
                units += cases[start][3]
                start += 1
                if time.perf_counter() - t0 >= _CALIBRATION_S:
                    break
            per_unit = (time.perf_counter() - t0) / max(units, 1.0)
            costs = [c[3] * per_unit for c in cases[start:]]
        else:
            costs = [float(run_seconds)] * (len(cases) - start)
        slots = sum(client.nthreads().values())
        packs = [[start + i for i in p] for p in pack(costs, task_seconds, slots)]
        futures: list[Any] = []
        try:
            for p in packs:
                futures.append(client.submit(run_pack, [(keys[i], cases[i][2]) for i in p], pure=True))
            if futures:
                import distributed

                done_runs = 0
                sizes = {f.key: len(p) for f, p in zip(futures, packs)}
                for n, f in enumerate(distributed.as_completed(futures), start=1):
                    for key, result in f.result():
                        keyed[key] = result
                    done_runs += sizes[f.key]
                    if progress:
                        print(
                            f"\rringsync sweep: {n}/{len(futures)} tasks, "
                            f"{done_runs + start}/{len(cases)} runs",
                            end="" if n < len(futures) else "\n",
                            file=sys.stderr,
                            flush=True,
                        )
        except BaseException:
            # Ctrl-C (or a failed task): the cluster stops the sweep's other tasks rather
            # than running them for nobody (a traceback kept in Jupyter would otherwise hold
            # the futures, and so the work, alive). A cancel that fails (the scheduler gone)
            # does not hide why.
            try:
                client.cancel(futures)
            except Exception:
                pass
            raise
        return [keyed[k] for k in keys], [len(p) for p in packs]
    finally:
        if own:
            client.close()

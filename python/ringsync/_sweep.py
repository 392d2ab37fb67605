"""Parameter sweeps: the product of a grid of scenario keys, several seeds each, run in
parallel inside Rust (the GIL released), as ``ringsync sweep`` runs them, or on Dask (a
``LocalCluster`` or a cluster by address) with the same numbers."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

from . import _ringsync as _rs
from ._ringsync import ScenarioError
from ._run import _check_axes, _pandas, _pyplot, _root_figure
from ._scenario import Scenario, ScenarioLike, load

if TYPE_CHECKING:
    import pandas
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["Sweep", "sweep"]

#: The columns of a sweep's rows after the grid's keys, with their units.
ROW_COLUMNS: dict[str, str] = {
    "seed": "",
    "track_rmse": "rad",
    "sync_rmse": "rad",
    "group_stop_s": "s",
    "group_stop_reason": "",
    "lumped_lost": "frames",
    "retries": "commands",
    "commands_lost": "commands",
    "clock_error_max_ns": "ns",
    "peak_u": "V",
    "saturated_cycles": "cycles",
    "contour_rmse": "mm",
    "contour_max": "mm",
}


class Sweep:
    """A finished sweep: one row per run (every combination of the grid's values, each
    seed), and means over the seeds per combination.

    Each row holds the grid's keys with the values given, then ``seed``, ``track_rmse``
    and ``sync_rmse`` (eq. 26-27) [rad], ``group_stop_s`` [s] and ``group_stop_reason``
    (None without a group stop; else e.g. ``"following-error"``, as summary.json names
    it), ``lumped_lost``, ``retries``, ``commands_lost``, ``clock_error_max_ns`` [ns],
    ``peak_u`` [V] (the largest command over the axes) and ``saturated_cycles`` (the most
    cycles any axis's drive was held at its limit ±u_max), and for a part program
    ``contour_rmse`` and ``contour_max`` [mm] (None for other trajectories).
    Rows come in the grid's order (the first key outermost), seeds innermost; a row has the
    same numbers as ``simulate(scenario, seed=row["seed"], **values)``.

    Example::

        >>> import ringsync
        >>> sw = ringsync.sweep("paper-2015", {"faults.loss": [0.0, 0.05]}, seeds=2,
        ...                     duration="0.5s")
        >>> len(sw.rows), sw.keys
        (4, ['faults.loss'])
        >>> [(m["faults.loss"], m["runs"]) for m in sw.mean_rows]
        [(0.0, 2), (0.05, 2)]
    """

    def __init__(
        self,
        scenario: Scenario,
        grid: dict[str, list[Any]],
        seeds: int,
        rows: list[dict[str, Any]],
        mean_rows: list[dict[str, Any]],
        jobs: int,
        tasks: list[int] | None = None,
    ) -> None:
        """Made by :func:`sweep`; not called directly."""
        self.scenario: Scenario = scenario
        """The base scenario (the grid's values set on it case by case)."""
        self.grid: dict[str, list[Any]] = grid
        """The swept keys and their values, as given."""
        self.seeds: int = seeds
        """Seeds per combination: the scenario's seed, +1, …"""
        self.rows: list[dict[str, Any]] = rows
        """One dict per run (see the class docstring)."""
        self.mean_rows: list[dict[str, Any]] = mean_rows
        """One dict per combination: the grid's keys, ``runs``, ``track_rmse``,
        ``sync_rmse`` (means over the seeds) and ``sync_rmse_std`` (the sample standard
        deviation (n − 1) of ``sync_rmse`` over the seeds; 0 for a single seed) [rad]."""
        self.jobs: int = jobs
        """Threads the runs were spread over (in-process; 1 per task on Dask)."""
        self.tasks: list[int] | None = tasks
        """On Dask: the number of runs in each task sent to the cluster (the first few
        runs, timed here to size the tasks, are not in them); None in-process."""

    @property
    def keys(self) -> list[str]:
        """The swept keys, in order."""
        return list(self.grid)

    @property
    def stopped(self) -> int:
        """How many runs ended in a group stop."""
        return sum(1 for r in self.rows if r["group_stop_s"] is not None)

    def to_pandas(self) -> pandas.DataFrame:
        """The rows as a DataFrame, one row per run: the grid's keys, ``seed``,
        ``track_rmse``, ``sync_rmse``, ``group_stop_s``, ``group_stop_reason``, the
        counters, ``peak_u`` and ``saturated_cycles``. Needs pandas.

        Example::

            >>> df = ringsync.sweep("paper-2015", {"control.law": ["pd", "sync"]}, seeds=1,
            ...                     duration="0.5s").to_pandas()
            >>> list(df.columns[:4])
            ['control.law', 'seed', 'track_rmse', 'sync_rmse']
        """
        pd = _pandas("Sweep.to_pandas()")
        return pd.DataFrame(self.rows, columns=[*self.grid, *ROW_COLUMNS])

    def means(self) -> pandas.DataFrame:
        """Means over the seeds, one row per combination of the grid's values: the keys,
        ``runs``, ``track_rmse``, ``sync_rmse`` [rad] (means) and ``sync_rmse_std`` [rad],
        the sample standard deviation (n − 1) of ``sync_rmse`` over the seeds (0 for a
        single seed), as ``df.groupby(keys)["sync_rmse"].std()`` (pandas' ``ddof=1``) gives
        it. Needs pandas (:attr:`mean_rows` has the same as dicts).

        Example::

            >>> sw = ringsync.sweep("paper-2015", {"control.law": ["pd", "sync"]}, seeds=3,
            ...                     duration="0.5s")
            >>> m = sw.means()
            >>> m.set_index("control.law")["sync_rmse"].idxmin()
            'sync'
            >>> import numpy as np
            >>> pd_seeds = [r["sync_rmse"] for r in sw.rows if r["control.law"] == "pd"]
            >>> bool(np.isclose(m["sync_rmse_std"][0], np.std(pd_seeds, ddof=1), rtol=1e-12))
            True
        """
        pd = _pandas("Sweep.means()")
        cols = [*self.grid, "runs", "track_rmse", "sync_rmse", "sync_rmse_std"]
        return pd.DataFrame(self.mean_rows, columns=cols)

    def plot(self, metric: str = "sync_rmse", *, ax: Axes | None = None) -> Figure:
        """Draws ``metric`` (a row column: ``sync_rmse``, ``track_rmse`` [rad], …) against
        the grid's first key: the mean over the seeds with ± one sample standard deviation
        (n − 1) over the seeds as error bars (none for a single seed), one line per
        combination of the other keys. With an empty grid (the scenario alone over its
        seeds) it draws each seed's value and their mean. Needs matplotlib (``pip install
        'ringsync[plot]'``); draws into ``ax`` (a matplotlib ``Axes``, else TypeError) when
        given. Returns the ``matplotlib.figure.Figure`` (``ax``'s figure when given).

        Raises ValueError naming ``metric`` when the rows have no such column or it is not
        a number (``group_stop_reason``).

        Example::

            >>> import matplotlib; matplotlib.use("Agg")
            >>> sw = ringsync.sweep("paper-2015", {"faults.loss": [0.0, 0.05]}, seeds=2,
            ...                     duration="0.3s")
            >>> fig = sw.plot("sync_rmse")
            >>> fig.axes[0].get_xlabel()
            'faults.loss'
        """
        plt = _pyplot("Sweep.plot()")
        if not self.rows or metric not in self.rows[0]:
            raise ValueError(
                f"Sweep.plot(): no column {metric!r}; the rows have {', '.join(self.rows[0]) if self.rows else 'none'}"
            )
        def number(v: Any) -> bool:
            return isinstance(v, (int, float)) and not isinstance(v, bool)

        values = [r[metric] for r in self.rows if r[metric] is not None]
        if metric == "group_stop_reason" or not values or not all(number(v) for v in values):
            numbers = [k for k in self.rows[0] if any(number(r[k]) for r in self.rows)]
            what = "is None in every row" if not values and metric != "group_stop_reason" else "is not a number"
            raise ValueError(f"Sweep.plot(): column {metric!r} {what}; plot one of {', '.join(numbers)}")
        _check_axes("Sweep.plot()", ax)
        unit = ROW_COLUMNS.get(metric, "")
        if not self.grid:
            return self._plot_seeds(plt, metric, unit, ax)
        first, others = self.keys[0], self.keys[1:]
        xs = self.grid[first]
        numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in xs)
        pos = {repr(v): (float(v) if numeric else float(i)) for i, v in enumerate(xs)}
        lines: dict[tuple[str, ...], dict[str, list[float]]] = {}
        for r in self.rows:
            label = tuple(f"{k}={r[k]}" for k in others)
            v = r[metric]
            if v is None:
                continue
            lines.setdefault(label, {}).setdefault(repr(r[first]), []).append(float(v))
        if ax is None:
            fig, ax = plt.subplots(figsize=(6.4, 4.0))
        else:
            fig = _root_figure(ax)
        for label, by_x in lines.items():
            keys = [repr(v) for v in xs if repr(v) in by_x]
            x = [pos[k] for k in keys]
            mean = [sum(by_x[k]) / len(by_x[k]) for k in keys]
            sd = [sample_sd(by_x[k], m) for k, m in zip(keys, mean)]
            ax.errorbar(x, mean, yerr=sd, marker="o", capsize=3, label=", ".join(label) or None)
        if not numeric:
            ax.set_xticks([pos[repr(v)] for v in xs], [str(v) for v in xs])
        elif _doubling([float(v) for v in xs]):
            # As the CLI's sweep.svg: values that double (ring sizes, cycles) on a log axis,
            # base 2, a tick at each.
            ax.set_xscale("log", base=2)
            ax.set_xticks([float(v) for v in xs], [str(v) for v in xs])
            ax.minorticks_off()
        ax.set_xlabel(first)
        ax.set_ylabel(f"{metric} [{unit}]" if unit else metric)
        ax.set_title(f"{self.scenario.name}: mean ± sample sd (n − 1) over {self.seeds} seed(s)")
        if others:
            ax.legend(fontsize="small")
        ax.grid(True, alpha=0.3)
        return fig

    def _plot_seeds(self, plt: Any, metric: str, unit: str, ax: Axes | None) -> Figure:
        """:meth:`plot` for an empty grid: ``metric`` of each seed, and the mean over them."""
        pts = [(r["seed"], float(r[metric])) for r in self.rows if r[metric] is not None]
        if ax is None:
            fig, ax = plt.subplots(figsize=(6.4, 4.0))
        else:
            fig = _root_figure(ax)
        ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", label=metric)
        if pts:
            mean = sum(p[1] for p in pts) / len(pts)
            ax.axhline(mean, linestyle="--", color="grey", label=f"mean {mean:.6g}")
        ax.set_xlabel("seed")
        ax.set_ylabel(f"{metric} [{unit}]" if unit else metric)
        ax.set_title(f"{self.scenario.name}: {metric} of each of {self.seeds} seed(s)")
        ax.legend(fontsize="small")
        ax.grid(True, alpha=0.3)
        return fig

    def __repr__(self) -> str:
        return (
            f"<Sweep of {self.scenario.name!r} over {', '.join(self.grid) or 'nothing'}: "
            f"{len(self.rows)} runs ({len(self.mean_rows)} combinations × {self.seeds} seeds), "
            f"{self.stopped} stopped>"
        )


def sweep(
    scenario: ScenarioLike,
    grid: Mapping[str, Sequence[Any] | Any],
    *,
    seeds: int = 8,
    jobs: int | None = None,
    executor: Any = None,
    task_seconds: float = 0.5,
    run_seconds: float | None = None,
    progress: bool = False,
    **overrides: Any,
) -> Sweep:
    """Runs every combination of ``grid``'s values (``{"faults.loss": [0, 0.01, 0.02],
    "control.law": ["pd", "sync"]}``: a dict of scenario key → list of values), ``seeds``
    seeds each (the scenario's seed, +1, …; a whole number 1 ..= 10 000, numpy
    integers too), as ``ringsync sweep SCENARIO --set KEY=V1,V2 … --seeds SEEDS``.
    ``overrides`` set keys of the base scenario first, as for :func:`ringsync.simulate`. A
    single value in the grid counts as a list of one; an empty grid runs the scenario alone
    over its seeds.

    Where the runs go:

    - ``executor=None`` (default): in parallel on ``jobs`` threads inside Rust (a whole
      number 1 ..= 4096; default: the CPUs), the GIL released. Ctrl-C (a Jupyter
      kernel's interrupt) starts no further run, ends those running at their next cycle
      and raises ``KeyboardInterrupt``. ``progress=True`` prints ``ringsync sweep:
      DONE/ALL runs`` on standard error, rewritten as runs finish.
    - ``executor=`` a ``dask.distributed.Client``, or a scheduler address such as
      ``"tcp://10.0.0.5:8786"`` (a client is made and closed): on Dask. The first few runs
      are timed here (unless ``run_seconds`` [s], the time of one run, is given), then the
      rest are packed into tasks of at least ``task_seconds`` [s] of work each (Dask spends
      milliseconds per task; one run is a few). Each task is a pure function of plain data
      (the cases' scenario text) that calls the Rust library on a worker; results are keyed
      by (values, seed), so a task Dask reruns or reorders changes nothing. The numbers are
      identical to the in-process sweep's. The workers need ``ringsync`` installed (the
      same version). ``progress=True`` prints a line on standard error as tasks finish.
      Needs ``pip install 'ringsync[dask]'``.

    Raises :class:`ringsync.ScenarioError` naming the case and its bad key or value, or the
    argument (``seeds``, ``jobs``, ``task_seconds``, ``run_seconds``) out of its range;
    TypeError for a grid that is not a dict; TypeError or ValueError for an executor that
    is neither; ImportError (naming the extra) when Dask is missing.

    Example::

        >>> sw = ringsync.sweep("paper-2015", {"control.alpha": [0.25, 0.5]}, seeds=2,
        ...                     duration="0.5s")
        >>> r = sw.rows[1]
        >>> one = ringsync.simulate("paper-2015", seed=r["seed"], duration="0.5s",
        ...                         **{"control.alpha": r["control.alpha"]})
        >>> one.metrics["sync_rmse"] == r["sync_rmse"]
        True

    On a cluster (here a local one, two worker processes)::

        >>> from dask.distributed import Client, LocalCluster
        >>> with LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
        ...                   dashboard_address=None) as cluster, Client(cluster) as client:
        ...     on_dask = ringsync.sweep("paper-2015", {"control.alpha": [0.25, 0.5]},
        ...                              seeds=2, duration="0.5s", executor=client)
        >>> on_dask.rows == sw.rows
        True
    """
    if not isinstance(grid, Mapping):
        raise TypeError(
            "sweep(): grid must be a dict of scenario key → list of values, e.g. "
            f'{{"faults.loss": [0.0, 0.01]}}, not {type(grid).__name__}'
        )
    if executor is not None:
        from ._dask import check_executor

        check_executor(executor)
        if not _seconds(task_seconds) >= 0:
            raise ScenarioError(f"task_seconds = {task_seconds!r} is out of range: allowed a number >= 0 [s]")
        if run_seconds is not None and not _seconds(run_seconds) > 0:
            raise ScenarioError(f"run_seconds = {run_seconds!r} is out of range: allowed a number > 0 [s], or None")
    s = load(scenario)
    if overrides:
        s = s.set(**overrides)
    g: dict[str, list[Any]] = {}
    for key, values in grid.items():
        if not isinstance(key, str):
            raise ScenarioError(f'{key!r} is not a scenario key: keys are strings like "control.alpha"')
        if isinstance(values, (str, bytes, Mapping)) or not isinstance(values, Iterable):
            values = [values]
        g[str(key)] = list(values)
        if not g[str(key)]:
            raise ScenarioError(f"the grid gives no values for {key}: give a list of at least one value")
    items = list(g.items())
    tasks: list[int] | None = None
    if executor is None:
        out = _rs.sweep(s.to_toml(), s.origin, items, seeds, jobs, progress)
    else:
        from ._dask import distributed_results

        cases = _rs.sweep_cases(s.to_toml(), s.origin, items, seeds)
        results, tasks = distributed_results(
            cases,
            executor,
            task_seconds=float(task_seconds),
            run_seconds=run_seconds,
            progress=progress,
        )
        out = _rs.sweep_collect(s.to_toml(), s.origin, items, seeds, results, 1)
    keys = list(g)

    def named(row: dict[str, Any]) -> dict[str, Any]:
        idx = row.pop("values")
        return {**{k: g[k][i] for k, i in zip(keys, idx)}, **row}

    rows = [named(r) for r in out["rows"]]
    means = [named(m) for m in out["means"]]
    return Sweep(s, g, int(out["seeds"]), rows, means, int(out["jobs"]), tasks)


def _doubling(xs: list[float]) -> bool:
    """Whether ``xs`` are all positive, each a power of 2 times the least, spanning a factor
    of 8 or more: the values the CLI's ``sweep.svg`` draws on a log axis."""
    if not xs or min(xs) <= 0:
        return False
    lo = min(xs)
    return max(xs) / lo >= 8 and all(abs(math.log2(x / lo) - round(math.log2(x / lo))) < 1e-9 for x in xs)


def sample_sd(values: Sequence[float], mean: float) -> float:
    """The sample standard deviation (n − 1) of ``values`` about their ``mean``:
    √(Σ (v − mean)² / (n − 1)); 0 for a single value (and for none).

    Example::

        >>> from ringsync._sweep import sample_sd
        >>> sample_sd([1.0, 2.0, 3.0], 2.0), sample_sd([5.0], 5.0)
        (1.0, 0.0)
    """
    n = len(values)
    if n < 2:
        return 0.0
    return math.sqrt(sum((v - mean) * (v - mean) for v in values) / (n - 1))


def _seconds(v: Any) -> float:
    """``v`` as a number of seconds, NaN (refused by the caller's comparison) when it is not
    a real number or is a bool."""
    if isinstance(v, bool):
        return float("nan")
    try:
        return float(v)
    except (TypeError, ValueError):
        return float("nan")

"""Simulating and checking a scenario: :func:`simulate` gives a :class:`Run` (numpy arrays,
metrics, plots, the CLI's files), :func:`check` a :class:`Check` (stability, the loop
matrix, a python-control ``StateSpace``)."""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any, TypeVar, overload

import numpy as np

from . import _ringsync as _rs
from ._ringsync import ScenarioError
from ._path import PathRun
from ._scenario import Scenario, ScenarioLike, load

if TYPE_CHECKING:
    import control
    import pandas
    import xarray
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure, FigureBase

#: A matplotlib figure or subfigure that :meth:`Run.plot` draws into and returns.
_Fig = TypeVar("_Fig", bound="FigureBase")

__all__ = ["Run", "simulate", "rt", "Check", "check"]

#: The per-cycle, per-axis columns of a run's trace, with their units.
COLUMNS: dict[str, str] = {
    "x_d": "rad",
    "x": "rad",
    "e": "rad",
    "eps": "rad",
    "u": "V",
    "sample_time": "s",
    "apply_time": "s",
    "clock_error_ns": "ns",
}


def _optional(module: str, extra: str, package: str, what: str, name: str = "") -> Any:
    """``module``, imported on first use, or ImportError saying that ``what`` needs
    ``name`` (default ``package``) and the extra (``ringsync[extra]``) or package that
    installs it."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError(
            f"{what} needs {name or package}: pip install 'ringsync[{extra}]' (or pip install {package})"
        ) from e


def _pandas(what: str) -> Any:
    """pandas, imported on first use."""
    return _optional("pandas", "pandas", "pandas", what)


def _pyplot(what: str) -> Any:
    """matplotlib.pyplot, imported on first use (the backend is the caller's choice)."""
    return _optional("matplotlib.pyplot", "plot", "matplotlib", what)


def _control(what: str) -> Any:
    """python-control, imported on first use."""
    return _optional("control", "control", "control", what, "python-control")


def _root_figure(ax: Axes) -> Figure:
    """The figure ``ax`` is drawn on (the top-level one when ``ax`` is in a subfigure)."""
    fig: Figure = ax.figure.figure  # a Figure's .figure is itself, a SubFigure's its root
    return fig


def _check_axes(what: str, ax: Any) -> None:
    """TypeError naming ``ax`` unless it is None or a matplotlib ``Axes`` (matplotlib is
    imported by then)."""
    from matplotlib.axes import Axes

    if ax is not None and not isinstance(ax, Axes):
        raise TypeError(f"{what}: ax must be a matplotlib Axes, not {type(ax).__name__}")


def _with(scenario: ScenarioLike, overrides: dict[str, Any]) -> Scenario:
    s = load(scenario)
    return s.set(**overrides) if overrides else s


class Run:
    """One simulated run: the trace as numpy arrays, the metrics, the CLI's summary.

    Arrays: one row per cycle the master computed, one column per axis (``time`` is 1-D):

    - ``time`` (cycles,): cycle start k·T_cyc [s]
    - ``x_d``, ``x`` (cycles, axes): desired and true position at the cycle start [rad]
    - ``e`` (cycles, axes): tracking error e = x_d − x [rad]
    - ``eps`` (cycles, axes): synchronisation error ε = T·e [rad]
    - ``u`` (cycles, axes): the command computed in the cycle [V]
    - ``sample_time`` (cycles, axes): when the sample the command used was taken [s]
    - ``apply_time`` (cycles, axes): when the command took effect at the slave [s]
      (NaN: it never arrived)
    - ``clock_error_ns`` (cycles, axes): slave clock minus true time at the cycle start
      [ns]

    ``metrics`` is a flat dict of the run's figures: ``track_rmse`` and ``sync_rmse``
    (eq. 26-27) [rad], ``samples``, ``cycles``, ``t_cyc_s`` [s], ``clock_error_max_ns``
    [ns], ``group_stop_s`` [s] and ``group_stop_reason`` (None without a stop), the frame
    counters, and per-axis lists ``rms_e``, ``max_e``, ``rms_eps``, ``max_eps`` [rad],
    ``rms_u``, ``peak_u`` [V], ``saturations``, ``clock_error_rms_ns``. ``summary`` is the
    dict ``ringsync sim`` writes as summary.json, to the last bit.

    The clock figures (``clock_error_max_ns``: the largest |error| of any slave clock;
    ``clock_error_rms_ns`` per axis) count the **second half** of the run only, cycles k
    with 2·k ≥ the planned cycles: the clocks once settled, as summary.json's and a
    sweep's ``clock_error_max_ns`` count them. ``clock_error_ns``, the array, holds every cycle, the start-up included,
    so ``abs(r.clock_error_ns).max()`` is over the whole run and usually larger; the
    metric is ``abs(r.clock_error_ns[(r.metrics["cycles"] + 1) // 2:]).max()``.

    Example::

        >>> import ringsync
        >>> r = ringsync.simulate("paper-2015", duration="0.5s")
        >>> r.x.shape, r.time.shape
        ((500, 4), (500,))
        >>> r.metrics["sync_rmse"] < r.metrics["track_rmse"]
        True
        >>> r.summary["controller"]
        'sync'
        >>> import numpy as np
        >>> settled = r.clock_error_ns[(r.metrics["cycles"] + 1) // 2:]   # the second half
        >>> float(np.abs(settled).max()) == r.metrics["clock_error_max_ns"]
        True
        >>> float(np.abs(r.clock_error_ns).max()) >= r.metrics["clock_error_max_ns"]
        True
    """

    time: np.ndarray
    """Cycle starts [s], shape (cycles,)."""
    x_d: np.ndarray
    """Desired positions [rad], shape (cycles, axes)."""
    x: np.ndarray
    """True positions [rad], shape (cycles, axes)."""
    e: np.ndarray
    """Tracking errors e = x_d − x [rad], shape (cycles, axes)."""
    eps: np.ndarray
    """Synchronisation errors ε [rad], shape (cycles, axes)."""
    u: np.ndarray
    """Commands [V], shape (cycles, axes)."""
    sample_time: np.ndarray
    """Sampling instant of the sample each command used [s], shape (cycles, axes)."""
    apply_time: np.ndarray
    """When each command took effect at its slave [s] (NaN if never), shape (cycles, axes)."""
    clock_error_ns: np.ndarray
    """Slave clock minus true time at each cycle start [ns], shape (cycles, axes): every
    cycle, whereas ``metrics["clock_error_max_ns"]`` counts the second half only."""

    def __init__(self, core: _rs.SimRun, scenario: Scenario) -> None:
        """Made by :func:`simulate`; not called directly."""
        self._core = core
        self.scenario: Scenario = scenario
        """The scenario as given (its ``seed`` may differ from :attr:`seed`)."""
        self.seed: int = core.seed
        """The seed the run used."""
        cols = core.columns()
        self.time = cols["time"]
        for name in COLUMNS:
            setattr(self, name, cols[name])
        self.metrics: dict[str, Any] = core.metrics()
        """The run's figures (see the class docstring); ``track_rmse``, ``sync_rmse`` [rad];
        ``clock_error_max_ns`` [ns] and ``clock_error_rms_ns`` [ns] over the second half of
        the run only (the settled clocks), unlike the array :attr:`clock_error_ns`."""
        self._summary: dict[str, Any] | None = None
        self._path: PathRun | bool | None = None

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        """Pickling (and :func:`copy.deepcopy`) of a simulated run keeps its scenario and
        seed, and unpickling simulates it again: the same numbers to the last bit with the
        same ringsync version (a warning says when the versions differ). A real-time run
        (:func:`rt`) cannot be run again: pickling it raises TypeError (save it with
        :meth:`save`).

        Example::

            >>> import pickle
            >>> r = ringsync.simulate("paper-2015", duration="0.1s")
            >>> pickle.loads(pickle.dumps(r)).metrics == r.metrics
            True
        """
        if self.realtime:
            raise TypeError(
                "a real-time run cannot be pickled: it cannot be run again to the same "
                "numbers; keep its files with Run.save(dir)"
            )
        return (_simulated_again, (self.scenario, self.seed, _rs.__version__))

    @property
    def summary(self) -> dict[str, Any]:
        """The content of the CLI's ``summary.json`` for this run (``ringsync sim
        SCENARIO --seed SEED``), parsed: the same numbers to the last bit."""
        if self._summary is None:
            self._summary = self._core.summary()
        return self._summary

    @property
    def path(self) -> PathRun | None:
        """A part program's run (``trajectory.kind = "program"``): the tool's actual and
        commanded position per machine axis [mm], the contour error, its metrics and the
        ISO 230-4 circular tests (a :class:`ringsync.PathRun`); None for other
        trajectories."""
        if self._path is None:
            d = self._core.path()
            self._path = False if d is None else PathRun(d)
        return self._path if isinstance(self._path, PathRun) else None

    @property
    def axes(self) -> int:
        """Number of axes."""
        return int(self._core.axes)

    @property
    def realtime(self) -> bool:
        """Whether the run ran in real time (:func:`rt`) rather than in the simulator."""
        return bool(self._core.realtime)

    @property
    def stopped(self) -> bool:
        """Whether the run ended in a group stop (the CLI's exit status 3)."""
        return self.metrics["group_stop_s"] is not None

    def text(self) -> str:
        """The few lines ``ringsync sim`` prints about the run.

        Example::

            >>> print(ringsync.simulate("paper-2015", duration="0.2s").text())  # doctest: +ELLIPSIS
            paper-2015: 200 cycles of 4 axes, sync controller, estimator paper
            ...
        """
        return str(self._core.text())

    def to_pandas(self, *, wide: bool = False) -> pandas.DataFrame:
        """The trace as a DataFrame. Needs pandas (``pip install 'ringsync[pandas]'``).

        - ``wide=False`` (default): long format, one row per cycle and axis, as
          ``trace.csv``: columns ``time`` [s], ``axis`` (1-based), then ``x_d``, ``x``,
          ``e``, ``eps`` [rad], ``u`` [V], ``sample_time``, ``apply_time`` [s],
          ``clock_error_ns`` [ns].
        - ``wide=True``: one row per cycle, indexed by the cycle start ``time`` [s], and
          one column per signal and axis, named ``SIGNAL[AXIS]`` (axis 1-based), signal by
          signal: ``x_d[1]`` … ``x_d[n]``, ``x[1]`` …, ``e[1]`` …, ``eps[1]`` … [rad],
          ``u[1]`` … [V], ``sample_time[1]`` …, ``apply_time[1]`` … [s],
          ``clock_error_ns[1]`` … [ns]: the long frame's signals, the same values
          (``wide.loc[t, "e[2]"]`` is the long row with that ``time`` and ``axis`` 2), and
          the labels :meth:`to_timeresponse` gives its signals.

        Example::

            >>> r = ringsync.simulate("paper-2015", duration="0.2s")
            >>> df = r.to_pandas()
            >>> list(df.columns[:4]), len(df)
            (['time', 'axis', 'x_d', 'x'], 800)
            >>> wide = r.to_pandas(wide=True)
            >>> wide.shape, wide.index.name, list(wide.columns[:5])
            ((200, 32), 'time', ['x_d[1]', 'x_d[2]', 'x_d[3]', 'x_d[4]', 'x[1]'])
            >>> float(wide["e[2]"].iloc[-1]) == float(df[df["axis"] == 2]["e"].iloc[-1])
            True
        """
        if not isinstance(wide, bool):
            raise TypeError(f"Run.to_pandas(): wide must be True or False, not {type(wide).__name__}")
        pd = _pandas("Run.to_pandas()")
        cycles, n = self.x.shape
        if wide:
            columns: dict[str, Any] = {}
            for name in COLUMNS:
                values = getattr(self, name)
                for i in range(n):
                    columns[f"{name}[{i + 1}]"] = values[:, i]
            return pd.DataFrame(columns, index=pd.Index(self.time, name="time"))
        data: dict[str, Any] = {
            "time": np.repeat(self.time, n),
            "axis": np.tile(np.arange(1, n + 1), cycles),
        }
        for name in COLUMNS:
            data[name] = getattr(self, name).reshape(-1)
        return pd.DataFrame(data)

    def to_timeresponse(self) -> control.TimeResponseData:
        """The run as python-control's time response (``control.TimeResponseData``, what
        ``control.input_output_response`` returns), the ring's axes as one MIMO system:

        - ``time``: the cycle starts [s] (:attr:`time`);
        - ``outputs``: each axis's true position x [rad] (:attr:`x`), labelled ``x[1]`` …
          ``x[n]``;
        - ``inputs``: each axis's command u [V] (:attr:`u`), labelled ``u[1]`` … ``u[n]``;
        - no states (``states`` is an empty (0, cycles) array, ``nstates`` 0: the plant's
          states stay inside the simulator); ``title`` ``"ringsync SCENARIO seed SEED"``,
          ``sysname`` the scenario's name.

        The arrays are indexed (signal, time), python-control's convention:
        ``resp.outputs[i]`` is ``r.x[:, i]`` (copies). A one-axis run is SISO, so
        ``outputs`` and ``inputs`` are squeezed to (cycles,) as python-control does
        (``resp.y`` and ``resp.u`` keep (1, cycles)). ``resp.to_pandas()`` and
        ``resp.plot()`` (``control.time_response_plot``) work on it as on any response.
        Needs python-control (``pip install 'ringsync[control]'``).

        Example::

            >>> r = ringsync.simulate("paper-2015", duration="0.2s")
            >>> resp = r.to_timeresponse()
            >>> resp.output_labels, resp.input_labels[0], resp.outputs.shape
            (['x[1]', 'x[2]', 'x[3]', 'x[4]'], 'u[1]', (4, 200))
            >>> bool((resp.outputs[2] == r.x[:, 2]).all()), resp.title
            (True, 'ringsync paper-2015 seed 1')
        """
        ct = _control("Run.to_timeresponse()")
        cycles, n = self.x.shape
        return ct.TimeResponseData(
            np.array(self.time, dtype=float),
            np.array(self.x.T, dtype=float),
            # Empty rather than None: python-control 0.10's `states` fails on None.
            states=np.empty((0, cycles)),
            inputs=np.array(self.u.T, dtype=float),
            output_labels=[f"x[{i + 1}]" for i in range(n)],
            input_labels=[f"u[{i + 1}]" for i in range(n)],
            title=f"ringsync {self.scenario.name} seed {self.seed}",
            sysname=self.scenario.name,
        )

    def to_xarray(self) -> xarray.Dataset:
        """The trace as an ``xarray.Dataset`` with dims ``time`` (cycle starts [s]) ×
        ``axis`` (1-based): variables ``x_d``, ``x``, ``e``, ``eps`` [rad], ``u`` [V],
        ``sample_time``, ``apply_time`` [s], ``clock_error_ns`` [ns], each with its unit in
        ``attrs["units"]``; the metrics' scalars in the dataset's ``attrs``. Needs xarray
        (``pip install 'ringsync[xarray]'``).

        Example::

            >>> ds = ringsync.simulate("paper-2015", duration="0.2s").to_xarray()
            >>> dict(ds.sizes), ds["e"].attrs["units"]
            ({'time': 200, 'axis': 4}, 'rad')
            >>> float(ds["e"].sel(axis=2).isel(time=-1)) == float(ds["e"][-1, 1])
            True
        """
        try:
            import xarray as xr
        except ImportError as e:  # pragma: no cover - depends on the environment
            raise ImportError(
                "Run.to_xarray() needs xarray: pip install 'ringsync[xarray]' (or pip install xarray)"
            ) from e
        n = self.x.shape[1]
        data = {
            name: (("time", "axis"), getattr(self, name), {"units": unit})
            for name, unit in COLUMNS.items()
        }
        attrs = {
            k: v
            for k, v in self.metrics.items()
            if isinstance(v, (int, float, str)) and not isinstance(v, bool)
        }
        attrs["scenario"] = self.scenario.name
        attrs["seed"] = self.seed
        return xr.Dataset(
            data,
            coords={
                "time": ("time", self.time, {"units": "s"}),
                "axis": ("axis", np.arange(1, n + 1)),
            },
            attrs=attrs,
        )

    @overload
    def plot(self, *, fig: None = None) -> Figure: ...
    @overload
    def plot(self, *, fig: _Fig) -> _Fig: ...
    def plot(self, *, fig: FigureBase | None = None) -> FigureBase:
        """Draws the run in three panels over time [s], one line per axis: tracking errors
        e [rad], synchronisation errors ε [rad], commands u [V]. Needs matplotlib
        (``pip install 'ringsync[plot]'``); draws into ``fig`` (a matplotlib ``Figure`` or
        ``SubFigure``, else TypeError) when given. Returns the figure drawn into: a new
        ``matplotlib.figure.Figure``, or ``fig`` (``fig.savefig("run.png")``; in Jupyter it
        shows itself).

        Example::

            >>> import matplotlib; matplotlib.use("Agg")
            >>> fig = ringsync.simulate("paper-2015", duration="0.5s").plot()
            >>> [a.get_ylabel() for a in fig.axes]
            ['e [rad]', 'ε [rad]', 'u [V]']
        """
        plt = _pyplot("Run.plot()")
        if fig is None:
            fig = plt.figure(figsize=(8.0, 7.0))
        else:
            from matplotlib.figure import FigureBase

            if not isinstance(fig, FigureBase):
                raise TypeError(f"Run.plot(): fig must be a matplotlib Figure, not {type(fig).__name__}")
        axs = fig.subplots(3, 1, sharex=True)
        n = self.x.shape[1]
        for what, label, ax in (
            ("e", "e [rad]", axs[0]),
            ("eps", "ε [rad]", axs[1]),
            ("u", "u [V]", axs[2]),
        ):
            values = getattr(self, what)
            for i in range(n):
                ax.plot(self.time, values[:, i], linewidth=0.8, label=f"axis {i + 1}")
            ax.set_ylabel(label)
            ax.grid(True, alpha=0.3)
        axs[0].legend(fontsize="small", ncol=min(n, 4), loc="upper right")
        axs[-1].set_xlabel("time [s]")
        m = self.metrics
        axs[0].set_title(
            f"{self.scenario.name} seed {self.seed}: Track-RMSE {m['track_rmse']:.5f} rad, "
            f"Sync-RMSE {m['sync_rmse']:.7f} rad"
        )
        return fig

    def save(self, directory: str | os.PathLike[str]) -> str:
        """Writes the CLI's files into ``directory`` (``scenario.toml``, the scenario as run,
        which ``ringsync identify`` reads; ``summary.json``, ``trace.csv``, ``path.csv`` for
        a part program, the figures ``*.svg``, ``report.html``), replacing it as a whole as
        ``ringsync sim --out`` does: it must be new, empty, or hold earlier ringsync
        results. Returns the directory.

        Raises :class:`ringsync.ScenarioError` for an empty path, a path that is a file, or a
        directory holding other files; :class:`ringsync.RunError` when writing fails.

        Example::

            >>> import tempfile, os
            >>> d = os.path.join(tempfile.mkdtemp(), "run")
            >>> _ = ringsync.simulate("paper-2015", duration="0.2s").save(d)
            >>> sorted(f for f in os.listdir(d) if f.endswith((".json", ".csv", ".toml")))
            ['scenario.toml', 'summary.json', 'trace.csv']
        """
        path = os.fspath(directory)
        self._core.save(path)
        return path

    def __repr__(self) -> str:
        m = self.metrics
        stop = f", GROUP STOP at {m['group_stop_s']:.3f} s ({m['group_stop_reason']})" if self.stopped else ""
        return (
            f"<Run {self.scenario.name!r} seed {self.seed}: {len(self.time)} cycles × {self.axes} axes, "
            f"Track-RMSE {m['track_rmse']:.6f} rad, Sync-RMSE {m['sync_rmse']:.7f} rad{stop}>"
        )


def _simulated_again(scenario: Scenario, seed: int, version: str) -> Run:
    """A pickled :class:`Run`, simulated again from its scenario and seed."""
    if version != _rs.__version__:
        import warnings

        warnings.warn(
            f"this run was pickled by ringsync {version} and is simulated again by "
            f"{_rs.__version__}: its numbers may differ",
            stacklevel=2,
        )
    return Run(_rs.simulate(scenario.to_toml(), scenario.origin, seed), scenario)


def simulate(scenario: ScenarioLike, *, seed: int | None = None, **overrides: Any) -> Run:
    """Simulates a scenario deterministically (frames on links, drifting clocks, servo
    axes) and returns the :class:`Run`: arrays, metrics, the CLI's summary.

    ``scenario`` is anything :func:`load` takes. ``seed`` replaces the scenario's seed
    (as ``ringsync sim --seed``): a whole number 0 ..= 2**63 − 1 (what a scenario's TOML
    ``seed`` holds; numpy integers too, not bools). ``overrides`` set scenario keys first, dotted keys through
    ``**``: ``simulate("paper-2015", **{"control.alpha": 0.3})``, top-level ones directly:
    ``simulate("paper-2015", duration="1s")``. Same scenario and seed, same numbers, to the
    last bit, as ``ringsync sim``. The GIL is released while it runs; Ctrl-C (a Jupyter
    kernel's interrupt) ends it at its next cycle and raises ``KeyboardInterrupt``.

    Raises :class:`ringsync.ScenarioError` for a bad scenario, key or value, or a
    ``seed`` out of range (naming it).

    Example::

        >>> pd = ringsync.simulate("paper-2015", duration="1s", **{"control.law": "pd"})
        >>> sync = ringsync.simulate("paper-2015", duration="1s")
        >>> sync.metrics["sync_rmse"] < pd.metrics["sync_rmse"]
        True
    """
    s = _with(scenario, overrides)
    return Run(_rs.simulate(s.to_toml(), s.origin, seed), s)


def rt(
    scenario: ScenarioLike = "paper-2015",
    *,
    prediction_seeds: int = 8,
    transport: str = "udp",
    stamps: str = "phy",
    **overrides: Any,
) -> Run:
    """Runs a scenario in real time, as ``ringsync rt SCENARIO --transport T --stamps S``
    does: the master and one slave per axis exchange real frames on their own threads for
    the scenario's ``duration`` of wall-clock time (plus a short calibration), the servo
    plants stepped in real time. ``transport`` is ``"udp"`` (loopback, no privileges
    needed) or ``"veth"`` (a ring of network namespaces and veth pairs, raw Ethernet; needs
    root); ``stamps`` is how the slaves stamp the lumped frames their clocks follow:
    ``"phy"`` (as a PHY would) or ``"software"`` (when their loop reads them); the CLI's
    ``"kernel"`` stamps belong to its ring of node processes (``ringsync rt --processes``)
    and are refused here. ``prediction_seeds`` is a whole number 0 ..= 10 000. Each
    mistake raises :class:`ringsync.ScenarioError` (a ``ValueError``) naming it.
    Real-time scheduling is used when allowed, and ``summary["realtime"]`` says what was
    applied. The GIL is released; Ctrl-C ends the run early (KeyboardInterrupt once it has
    stopped).

    Returns a :class:`Run` (``realtime`` True): the same arrays and metrics as a
    simulation, ``summary`` is what ``ringsync rt`` writes (the simulator's fields plus the
    timing: ``overruns``, ``lateness_us``, ``p2p_phase_us``, ``calibration`` …, and the
    simulator's predictions from ``prediction_seeds`` seeds, 0 for none:
    ``summary["sim_prediction"]`` for the scenario as run on its plan's links, and its
    ``"measured_ring"`` for the ring as the start-up phase measured it, with, under
    ``"with_the_runs_clock_bias"``, that ring again with each clock off by the run's mean
    clock error), ``text()`` its
    lines. Numbers vary from run to run: the host's timing is part of the result.
    ``overrides`` set scenario keys first, as for :func:`simulate`.

    Example::

        >>> r = ringsync.rt("paper-2015", duration="0.2s", prediction_seeds=0)
        >>> r.realtime, r.summary["transport"], r.e.shape[1]
        (True, 'udp', 4)
    """
    if transport not in ("udp", "veth"):
        raise ScenarioError(f'unknown transport {transport!r}: use "udp" or "veth"')
    if stamps not in ("phy", "software"):
        raise ScenarioError(f'unknown stamps {stamps!r}: use "phy" or "software"')
    s = _with(scenario, overrides)
    return Run(_rs.rt(s.to_toml(), s.origin, prediction_seeds, transport, stamps), s)


class Check:
    """The stability check of a scenario's loop, as ``ringsync check`` does it: the
    spectral radius of the linearised sampled closed loop with each axis's delay, and the
    paper's continuous-time conditions.

    ``verdict`` is ``"stable"`` (spectral radius < 1, every term modelled),
    ``"unstable"`` or ``"not shown"`` (a loop the check does not model: the lumped-only
    plan's slaves running their own error or disturbance observers, the coupled arm, the
    exact sign with K_N ≠ 0). ``report`` is the dict
    ``ringsync check --json`` prints. ``matrix`` is the closed-loop matrix behind the
    spectral radius, and :meth:`statespace` the same loop as a python-control system.

    Example::

        >>> c = ringsync.check("paper-2015")
        >>> c.stable, c.verdict, round(c.spectral_radius, 3) < 1
        (True, 'stable', True)
        >>> c.matrix.shape            # 9 states per axis
        (36, 36)
    """

    def __init__(
        self,
        report: dict[str, Any],
        text: str,
        stable: bool,
        matrix: np.ndarray | None = None,
        t_cyc: float = float("nan"),
    ) -> None:
        """Made by :func:`check`; not called directly."""
        self.report: dict[str, Any] = report
        """``ringsync check --json``'s object."""
        self.stable: bool = stable
        """Whether the verdict is ``"stable"``."""
        self.matrix: np.ndarray | None = matrix
        """The sampled closed loop's matrix M (z[k+1] = M·z[k], one step per cycle), states
        × states, or None when the check does not model the loop. On the proposed plan 9
        states per axis i at ``9*i … 9*i+8``: x [rad], ẋ [rad/s], the command held from the
        last cycle u[k−1] [V], the three previous error samples e[k−1], e[k−2], e[k−3]
        [rad] and error rates ė[k−1], ė[k−2], ė[k−3] [rad/s] (the history the estimators
        read); with ``control.velocity = "observer"`` two more per axis (the observer's ê
        [rad], ė̂ [rad/s]), with ``control.dob_bandwidth`` > 0 three more (u[k−2], u[k−3], d̂
        [V]). On the lumped-only plan 11: x, ẋ, u[k−1], e[k−1..k−4], ė[k−1..k−4] (each
        slave runs the law on this cycle's samples of the slaves up to it and last cycle's
        of the others). ``matrix.shape[0] // axes`` states per axis in all, named in
        ``report["discrete"]["state_names"]``. The loop
        regulates to x^d = 0 (e = −x) on the axes' linear part (no Coulomb friction, no
        saturation), with each axis's sample-to-actuation delay; its eigenvalues' largest
        modulus is :attr:`spectral_radius`."""
        self.t_cyc: float = t_cyc
        """The cycle time T_cyc [s]: the loop's sampling period."""
        self._text = text

    @property
    def verdict(self) -> str:
        """``"stable"``, ``"unstable"`` or ``"not shown"``."""
        return str(self.report["verdict"])

    @property
    def spectral_radius(self) -> float | None:
        """Spectral radius of the sampled closed loop (stable below 1); None when the
        check does not model the loop."""
        d = self.report.get("discrete")
        return None if d is None else float(d["spectral_radius"])

    @property
    def delays(self) -> list[float]:
        """Sample-to-actuation delay of each axis [s]."""
        return [ns * 1e-9 for ns in self.report["delays_ns"]]

    @property
    def conditions(self) -> dict[str, Any] | None:
        """The paper's continuous-time conditions (sync law on independent axes), else
        None."""
        c = self.report.get("conditions")
        return None if c is None else dict(c)

    def statespace(self) -> control.StateSpace:
        """The linearised sampled loop as a python-control discrete-time system,
        ``control.StateSpace(A, B, C, D, dt=T_cyc)``:

        - ``A`` = :attr:`matrix` (on the proposed plan 9 states per axis: x, ẋ, u[k−1], e[k−1..k−3],
          ė[k−1..k−3]; see :attr:`matrix`), so its poles' largest modulus is
          :attr:`spectral_radius`;
        - ``B`` = 0 with one input per axis (``d[i]``): the loop regulates to x^d = 0 and
          has no exogenous input; study it with ``control.initial_response`` from an
          offset state, or add your own B;
        - ``C`` picks each axis's position x [rad] (outputs ``x[1]`` … ``x[n]``);
        - ``D`` = 0.

        States, inputs and outputs are named (``x[1]``, ``v[1]``, ``u_prev[1]``,
        ``e1[1]`` …). Needs python-control (``pip install 'ringsync[control]'``). Raises
        ValueError when the check does not model the loop (:attr:`matrix` is None).

        Example::

            >>> import numpy as np
            >>> c = ringsync.check("paper-2015")
            >>> sys = c.statespace()
            >>> sys.dt, sys.nstates, sys.noutputs
            (0.001, 36, 4)
            >>> bool(np.isclose(max(abs(sys.poles())), c.spectral_radius, rtol=1e-9))
            True
        """
        ct = _control("Check.statespace()")
        if self.matrix is None:
            raise ValueError(
                f"the check does not model the loop of {self.report['scenario']!r} "
                f"(verdict {self.verdict!r}): no state-space system"
            )
        a = np.array(self.matrix, dtype=float)
        dim = a.shape[0]
        n = len(self.delays)
        per = dim // n
        b = np.zeros((dim, n))
        c = np.zeros((n, dim))
        for i in range(n):
            c[i, per * i] = 1.0
        d = np.zeros((n, n))
        # The check names an axis's states (with the observers', and on the lumped-only
        # plan e4 and de4 too).
        per_axis = list(self.report["discrete"]["state_names"])
        assert len(per_axis) == per, (per_axis, per)
        states = [f"{name}[{i + 1}]" for i in range(n) for name in per_axis]
        return ct.StateSpace(
            a,
            b,
            c,
            d,
            self.t_cyc,
            states=states,
            inputs=[f"d[{i + 1}]" for i in range(n)],
            outputs=[f"x[{i + 1}]" for i in range(n)],
            name=f"ringsync {self.report['scenario']}",
        )

    def text(self) -> str:
        """What ``ringsync check`` prints."""
        return self._text

    def __repr__(self) -> str:
        rho = self.spectral_radius
        radius = "not modelled" if rho is None else f"spectral radius {rho:.4f}"
        return f"<Check {self.report['scenario']!r}: {self.verdict}, {radius}>"


def check(scenario: ScenarioLike, *, points: int = 4001, **overrides: Any) -> Check:
    """Checks a scenario's stability (``ringsync check``); ``points`` instants of the
    motion evaluate the paper's conditions (a whole number 1 ..= 1 000 000, as ``ringsync
    check --points`` takes; the check's time grows with it); ``overrides`` as for
    :func:`simulate`.

    Raises:
        ringsync.ScenarioError: a bad scenario, key or value, or ``points`` not a whole
            number in 1 ..= 1 000 000 (the message names it).

    Example::

        >>> ringsync.check("paper-2015", **{"control.kp": 3000.0}).verdict
        'unstable'
        >>> ringsync.check("paper-2015", points=0)
        Traceback (most recent call last):
          ...
        ringsync.ScenarioError: points = 0 is out of range: allowed a whole number 1 ..= 1000000 (instants of the motion, as ringsync check --points)
    """
    s = _with(scenario, overrides)
    report, text, stable, matrix, t_cyc = _rs.check(s.to_toml(), s.origin, points)
    return Check(report, text, stable, matrix, t_cyc)

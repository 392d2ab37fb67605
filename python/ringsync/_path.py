"""A part program's run (docs/programs.md): :attr:`ringsync.Run.path` is a :class:`PathRun`
with the tool's actual and commanded position of every machine axis per cycle [mm], the
contour error [mm], its metrics and the ISO 230-4 circular tests, as ``path.csv`` and
``summary.json`` hold them."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    import pandas
    from matplotlib.axes import Axes

__all__ = ["PathRun", "plan_program"]


class PathRun:
    """A part program's run, one row per cycle start:

    - ``time`` (cycles,): cycle start [s]
    - ``axes``: the machine axes' letters, e.g. ``['X', 'Y']``
    - ``actual``, ``desired`` (cycles, machine axes): the tool's position from the
      encoders through the transmissions, and the commanded one [mm] (a gantry axis: the
      mean of its drives)
    - ``contour_error`` (cycles,): the distance from the actual position to the
      programmed path's geometry [mm]
    - ``metrics``: ``contour_rmse``, ``contour_max``, ``contour_mean`` [mm] over the
      cycles before any group stop, rapids (G0) left out; ``cycles``;
      ``program_duration_s``; ``complete`` (whether the run lasted to the program's end)
    - ``circles``: one dict per programmed full circle, the ISO 230-4 circular test from
      feedback: ``radius``, ``direction`` (``ccw``/``cw``), ``mean_radius``,
      ``radius_error``, ``radial_deviation_min``/``_max``, ``circular_deviation`` [mm],
      ``lsq_centre``, ``samples``, and the profile ``angle`` [rad] / ``deviation`` [mm]

    ``run.path["X"]`` is a column of ``path.csv`` (``time_s``, ``X``, ``X_d``, …,
    ``contour_error``); :meth:`to_pandas` is that file as a DataFrame.

    Example::

        >>> import ringsync
        >>> r = ringsync.simulate("circle-xy", duration="6s")
        >>> p = r.path
        >>> p.axes, p.actual.shape == (len(p.time), 2)
        (['X', 'Y'], True)
        >>> 0 < p.metrics["contour_rmse"] < 0.05      # mm
        True
        >>> list(p.to_pandas().columns)
        ['time_s', 'X', 'X_d', 'Y', 'Y_d', 'contour_error']
    """

    time: np.ndarray
    """Cycle starts [s], shape (cycles,)."""
    actual: np.ndarray
    """The tool's actual position [mm], shape (cycles, machine axes)."""
    desired: np.ndarray
    """The commanded position [mm], shape (cycles, machine axes)."""
    contour_error: np.ndarray
    """Contour error [mm], shape (cycles,)."""

    def __init__(self, d: dict[str, Any]) -> None:
        """Made by :attr:`ringsync.Run.path`; not called directly."""
        self.axes: list[str] = list(d["axes"])
        """The machine axes' letters, in column order."""
        self.time = d["time"]
        self.actual = d["actual"]
        self.desired = d["desired"]
        self.contour_error = d["contour_error"]
        self.metrics: dict[str, Any] = dict(d["metrics"])
        """Contour RMSE, largest and mean [mm]; cycles; the program's planned duration [s];
        whether the run completed it."""
        self.circles: list[dict[str, Any]] = list(d["circles"])
        """The ISO 230-4 circular test of each programmed full circle."""

    def __getitem__(self, column: str) -> np.ndarray:
        """A column of ``path.csv``: ``time_s``, an axis letter (actual), the letter with
        ``_d`` (commanded), or ``contour_error``; KeyError naming the columns otherwise."""
        if column == "time_s":
            return self.time
        if column == "contour_error":
            return self.contour_error
        name, desired = (column[:-2], True) if column.endswith("_d") else (column, False)
        if name in self.axes:
            i = self.axes.index(name)
            return (self.desired if desired else self.actual)[:, i]
        raise KeyError(f"{column!r}: the columns are {', '.join(self.columns)}")

    @property
    def columns(self) -> list[str]:
        """``path.csv``'s columns, in order."""
        cols = ["time_s"]
        for a in self.axes:
            cols += [a, f"{a}_d"]
        return cols + ["contour_error"]

    def to_pandas(self) -> pandas.DataFrame:
        """``path.csv`` as a DataFrame (its columns, every value at full precision). Needs
        pandas."""
        from ._run import _pandas

        pd = _pandas("PathRun.to_pandas()")
        return pd.DataFrame({c: self[c] for c in self.columns})

    def plot(self, *, ax: Axes | None = None) -> Axes:
        """The path in its first two machine axes, commanded and actual [mm], equal
        scales. Needs matplotlib (``pip install 'ringsync[plot]'``); draws into ``ax`` (a
        matplotlib ``Axes``) when given; returns the ``matplotlib.axes.Axes`` drawn into.
        ValueError for a path of one machine axis.

        Example::

            >>> import matplotlib; matplotlib.use("Agg")
            >>> ax = ringsync.simulate("circle-xy", duration="2s").path.plot()
            >>> ax.get_xlabel(), ax.get_ylabel()
            ('X [mm]', 'Y [mm]')
        """
        from ._run import _check_axes, _pyplot

        plt = _pyplot("PathRun.plot()")
        _check_axes("PathRun.plot()", ax)
        if len(self.axes) < 2:
            raise ValueError(f"PathRun.plot(): the path has one machine axis ({self.axes[0]})")
        if ax is None:
            ax = plt.figure(figsize=(6.0, 6.0)).add_subplot()
        ax.plot(self.desired[:, 0], self.desired[:, 1], color="0.6", linewidth=2.5, label="commanded")
        ax.plot(self.actual[:, 0], self.actual[:, 1], color="C3", linewidth=0.8, label="actual")
        ax.set_aspect("equal")
        ax.set_xlabel(f"{self.axes[0]} [mm]")
        ax.set_ylabel(f"{self.axes[1]} [mm]")
        ax.legend(fontsize="small")
        return ax

    def plot_circular(self, index: int = 0, *, ax: Axes | None = None) -> Axes:
        """Circular test ``index`` as a polar plot: the measured radius minus the
        programmed one [µm] against the angle about the programmed centre (the deviation
        on its own scale, as a ballbar plot magnifies it). Needs matplotlib (``pip install
        'ringsync[plot]'``); draws into ``ax`` (a polar Axes) when given; returns the
        (polar) ``matplotlib.axes.Axes`` drawn into. IndexError when there is no such
        circle.

        Example::

            >>> import matplotlib; matplotlib.use("Agg")
            >>> ax = ringsync.simulate("circle-xy").path.plot_circular(0)
            >>> ax.name
            'polar'
        """
        from ._run import _check_axes, _pyplot

        plt = _pyplot("PathRun.plot_circular()")
        _check_axes("PathRun.plot_circular()", ax)
        if not -len(self.circles) <= index < len(self.circles):
            raise IndexError(
                f"PathRun.plot_circular({index}): the run has {len(self.circles)} circular test(s)"
            )
        c = self.circles[index]
        if ax is None:
            ax = plt.figure(figsize=(6.0, 6.0)).add_subplot(projection="polar")
        dev_um = np.asarray(c["deviation"]) * 1e3
        ax.plot(c["angle"], dev_um, color="C0", linewidth=1.0)
        ax.set_title(
            f"R {c['radius']:g} mm {c['direction']}: mean {c['radius_error'] * 1e3:+.2f} µm, "
            f"G {c['circular_deviation'] * 1e3:.2f} µm (radius − R [µm])",
            fontsize="small",
        )
        return ax

    def __repr__(self) -> str:
        m = self.metrics
        return (
            f"<PathRun {''.join(self.axes)}: {len(self.time)} cycles, contour error RMS "
            f"{m['contour_rmse'] * 1e3:.2f} µm, max {m['contour_max'] * 1e3:.2f} µm, "
            f"{len(self.circles)} circular test(s)>"
        )


def plan_program(scenario: Any, *, points: int = 1000, **overrides: Any) -> dict[str, Any]:
    """A scenario's part program planned on its machine without a ring, as ``ringsync
    program --json`` prints it: ``duration_s``, ``length`` [mm], ``blends``, ``stops``,
    ``blocks``; ``axes`` with each machine axis's limits and the peak ``v_peak``,
    ``a_peak``, ``j_peak`` of its setpoints sampled at the cycle; ``limit_ratio`` (the
    largest share of a limit, ≤ 1); ``path_deviation`` [mm]; ``bound_by`` (what bounds the
    feed, for how long); and ``feed``, a pair of arrays (time [s], path speed [mm/s]) at
    ``points`` instants. ``scenario`` is anything :func:`ringsync.load` takes;
    ``overrides`` set keys first (``**{"machine.path_tolerance": 0.05}``).

    Raises :class:`ringsync.ScenarioError` when the scenario has no part program, or its
    program cannot be read, interpreted or planned (the message names the file, line and
    column).

    Example::

        >>> p = ringsync.plan_program("circle-xy")
        >>> round(p["duration_s"], 1), p["limit_ratio"] <= 1.001
        (19.4, True)
        >>> [a["axis"] for a in p["axes"]]
        ['X', 'Y']
    """
    from . import _ringsync as _rs
    from ._scenario import load

    s = load(scenario)
    if overrides:
        s = s.set(**overrides)
    return dict(_rs.program(s.to_toml(), s.origin, int(points)))

"""The cycle plan (eq. 1-2 of the paper): where the time of one cycle goes, as
``ringsync plan --json`` gives it, and the paper's Table 1 reproduced."""

from __future__ import annotations

import copy
from collections.abc import Iterator, Mapping
from typing import TYPE_CHECKING, Any

from . import _ringsync as _rs
from ._run import _check_axes, _pandas, _pyplot, _root_figure
from ._scenario import Scenario, ScenarioLike, load

if TYPE_CHECKING:
    import pandas
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["Plan", "plan", "Reproduction", "reproduce"]


class Plan(Mapping[str, Any]):
    """The cycle plan of a scenario's ring (eq. 1-2): every term in integer nanoseconds,
    as ``ringsync plan --json`` prints it.

    The terms of eq. 1 (the lumped phase): ``t_lmf_ns`` (the lumped frame's wire time),
    ``d_ms_ns`` (its way from the master to the last slave), ``d_snm_ns`` (from the last
    slave back to the master), ``t_rest_ns`` (the master computes), their sum ``t_syn_ns``;
    of eq. 2 (the point-to-point phase): ``t_cmf_ns`` and ``t_rmf_ns`` (command and
    response frames' wire times), ``d_c_ns`` (the master's path delay to each slave),
    ``slot_ns`` (each slave's slice), ``reserve_slices`` × ``reserve_slice_ns``; then
    ``t_idle_ns`` (what is left of the cycle) and ``min_t_cyc_ns`` (the shortest cycle the
    ring holds); ``event`` has the frame-by-frame (event-level) figures, ``lumped_only`` the
    plan of ref. [3], ``params`` the ring's figures. docs/planner.md names every key.

    A plan reads like a read-only dict of its top-level keys: ``plan["t_syn_ns"]`` reads a
    term (KeyError for a key it lacks), ``plan.get(key, default)``, ``list(plan)``,
    ``len(plan)``, ``dict(plan)``; :meth:`to_dict` gives the whole object as a deep copy;
    :meth:`plot` draws the cycle.

    Example::

        >>> import ringsync
        >>> p = ringsync.plan()                       # the reference ring: 4 axes, 1 ms
        >>> p["t_syn_ns"] == p["t_lmf_ns"] + p["d_ms_ns"] + p["d_snm_ns"] + p["t_rest_ns"]
        True
        >>> p.min_t_cyc < p.t_cyc                     # [s]
        True
        >>> "t_syn_ns" in list(p), p.get("nope", 0)
        (True, 0)
    """

    def __init__(self, data: dict[str, Any], timeline: Any, scenario: Scenario) -> None:
        """Made by :func:`plan`; not called directly."""
        self._data = data
        self.timeline: Any = timeline
        """The frame-by-frame timeline of one cycle (``ringsync plan --json --events``'s
        ``timeline``): every frame's passage at every node, times in ns from the cycle
        start."""
        self.scenario: Scenario = scenario
        """The scenario whose ring this is."""

    def __getitem__(self, key: str) -> Any:
        """The term ``key`` as ``ringsync plan --json`` gives it (e.g. ``"t_syn_ns"`` [ns]);
        KeyError when the plan has no such key."""
        return self._data[key]

    def __iter__(self) -> Iterator[str]:
        """The plan's top-level keys, in ``ringsync plan --json``'s order."""
        return iter(self._data)

    def __len__(self) -> int:
        """How many top-level keys the plan has."""
        return len(self._data)

    @property
    def t_cyc(self) -> float:
        """The cycle time T_cyc [s]."""
        return float(self._data["t_cyc_ns"]) * 1e-9

    @property
    def min_t_cyc(self) -> float:
        """The shortest cycle time this ring holds with this plan (eq. 1-2) [s]."""
        return float(self._data["min_t_cyc_ns"]) * 1e-9

    @property
    def idle(self) -> float:
        """What is left of the cycle after the lumped phase, the slices and the reserve
        [s]."""
        return float(self._data["t_idle_ns"]) * 1e-9

    def to_dict(self) -> dict[str, Any]:
        """The plan as ``ringsync plan --json`` prints it (a deep copy): integer
        nanoseconds, keys as in docs/planner.md.

        Example::

            >>> d = ringsync.plan(None, **{"ring.slaves": 8}).to_dict()
            >>> d["n"], len(d["slot_ns"]), d["plan"]
            (8, 8, 'p2p-lumped')
        """
        return copy.deepcopy(self._data)

    def segments(self) -> list[tuple[str, str, int, int]]:
        """The cycle as consecutive segments (kind, label, start [ns], length [ns]) in the
        order of eq. 1-2: the lumped frame, its way out and back, T_rest, one slice per
        slave, the reserve slices, the idle rest. What :meth:`plot` draws.

        Example::

            >>> segs = ringsync.plan().segments()
            >>> [s[1] for s in segs[:4]], segs[-1][0]
            (['T_lmf', 'D_ms', 'D_snm', 'T_rest'], 'idle')
            >>> sum(s[3] for s in segs) == ringsync.plan()["t_cyc_ns"]
            True
        """
        d = self._data
        out: list[tuple[str, str, int, int]] = []
        t = 0

        def add(kind: str, label: str, length: int) -> None:
            nonlocal t
            out.append((kind, label, t, int(length)))
            t += int(length)

        add("lumped", "T_lmf", d["t_lmf_ns"])
        add("lumped", "D_ms", d["d_ms_ns"])
        add("lumped", "D_snm", d["d_snm_ns"])
        add("rest", "T_rest", d["t_rest_ns"])
        for i, slot in enumerate(d["slot_ns"]):
            add("slice", f"slice {i + 1}", slot)
        for j in range(int(d["reserve_slices"])):
            add("reserve", f"reserve {j + 1}", d["reserve_slice_ns"])
        add("idle", "idle", d["t_idle_ns"])
        return out

    def plot(self, *, ax: Axes | None = None, zoom: bool = False) -> Figure:
        """Draws the cycle as a timeline [µs]: the lumped phase (the lumped frame T_lmf, its
        way to the last slave D_ms and back D_snm), T_rest, the point-to-point slices (one
        per slave), the reserve slices and the idle rest. ``zoom=True`` shows only the used
        part (up to the shortest cycle). Needs matplotlib (``pip install
        'ringsync[plot]'``); draws into ``ax`` (a matplotlib ``Axes``, else TypeError) when
        given. Returns the ``matplotlib.figure.Figure`` (``ax``'s figure when given).

        Example::

            >>> import matplotlib; matplotlib.use("Agg")
            >>> fig = ringsync.plan().plot()
            >>> fig.axes[0].get_xlabel()
            'time in the cycle [µs]'
        """
        plt = _pyplot("Plan.plot()")
        _check_axes("Plan.plot()", ax)
        if ax is None:
            fig, ax = plt.subplots(figsize=(9.0, 2.6))
        else:
            fig = _root_figure(ax)
        colors = {
            "lumped": "#1f77b4",
            "rest": "#aec7e8",
            "slice": "#ff7f0e",
            "reserve": "#ffbb78",
            "idle": "#dddddd",
        }
        names = {
            "lumped": "lumped phase (T_lmf, D_ms, D_snm)",
            "rest": "T_rest",
            "slice": "P2P slices",
            "reserve": "reserve slices",
            "idle": "idle",
        }
        seen: set[str] = set()
        for kind, label, start, length in self.segments():
            ax.broken_barh(
                [(start * 1e-3, length * 1e-3)],
                (0.0, 1.0),
                facecolors=colors[kind],
                edgecolors="white",
                linewidth=0.6,
                label=None if kind in seen else names[kind],
            )
            seen.add(kind)
            if kind in ("slice", "reserve") and zoom:
                ax.text((start + length / 2) * 1e-3, 0.5, label.split()[-1], ha="center", va="center", fontsize=7)
        end = self._data["min_t_cyc_ns"] * 1.05 if zoom else self._data["t_cyc_ns"]
        ax.set_xlim(0.0, end * 1e-3)
        ax.set_ylim(0.0, 1.0)
        ax.set_yticks([])
        ax.set_xlabel("time in the cycle [µs]")
        d = self._data
        ax.set_title(
            f"{self.scenario.name}: {d['n']} slaves, T_cyc {d['t_cyc_ns'] / 1e3:g} µs, "
            f"used {d['min_t_cyc_ns'] / 1e3:g} µs ({d['plan']})"
        )
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.45), ncol=5, fontsize="small", frameon=False)
        fig.tight_layout()
        return fig

    def __repr__(self) -> str:
        d = self._data
        return (
            f"<Plan {self.scenario.name!r}: {d['n']} slaves, T_cyc {d['t_cyc_ns']} ns, "
            f"T_syn {d['t_syn_ns']} ns, min T_cyc {d['min_t_cyc_ns']} ns, idle {d['t_idle_ns']} ns>"
        )


def plan(scenario: ScenarioLike | None = None, **overrides: Any) -> Plan:
    """The cycle plan (eq. 1-2) of a scenario's ring: every term in ns, as ``ringsync plan
    --json``. ``scenario`` is anything :func:`ringsync.load` takes, or None for the
    reference scenario ``paper-2015`` (the CLI's defaults); ``overrides`` set scenario
    keys first (``**{"ring.slaves": 8, "ring.cycle": "500us"}``).

    Raises :class:`ringsync.ScenarioError` when the ring cannot be planned (a figure out of
    range, or a cycle too short for the ring: the message says by how much).

    Example::

        >>> p = ringsync.plan(None, **{"ring.slaves": 8, "ring.cycle": "500us"})
        >>> p["n"], p["t_cyc_ns"]
        (8, 500000)
        >>> p["t_idle_ns"] == p["t_cyc_ns"] - p["min_t_cyc_ns"]
        True
    """
    s = load("paper-2015" if scenario is None else scenario)
    if overrides:
        s = s.set(**overrides)
    data = _rs.plan(s.to_toml(), s.origin, True)
    timeline = data.pop("timeline", None)
    return Plan(data, timeline, s)


class Reproduction:
    """The paper's Table 1 reproduced: Track-RMSE and Sync-RMSE of standard PD, the sync
    controller and the ring-coupled baseline, on the proposed plan (``p2p-lumped``) and on
    the lumped-only plan of ref. [3], for each seed.

    ``rows``: one dict per (seed, plan, controller): ``seed``, ``plan``, ``controller``,
    ``track_rmse``, ``sync_rmse`` [rad], ``group_stop`` (whether the run stopped).
    ``summary``: the same object as ``ringsync reproduce``'s summary.json
    (docs/schemas/reproduce-summary.json): the paper's claims with ours and a verdict each,
    the cases (means, the sample standard deviation (n − 1) of each, ranges), the reductions and the
    bench experiment.

    Example::

        >>> r = ringsync.reproduce(seeds=1, duration="0.3s")
        >>> len(r.rows), sorted({row["controller"] for row in r.rows})
        (6, ['pd', 'ring-coupled', 'sync'])
    """

    def __init__(self, scenario: Scenario, rows: list[dict[str, Any]], summary: dict[str, Any]) -> None:
        """Made by :func:`reproduce`; not called directly."""
        self.scenario: Scenario = scenario
        """The base scenario."""
        self.rows: list[dict[str, Any]] = rows
        """One dict per (seed, plan, controller)."""
        self.summary: dict[str, Any] = summary
        """``ringsync reproduce``'s summary.json as a dict."""

    @property
    def verdicts(self) -> dict[str, str]:
        """The verdict on each of the paper's claims by ``"claim metric"``:
        ``"reproduced"``, ``"direction-only"`` or ``"not-reproduced"``.

        Example::

            >>> r = ringsync.reproduce(seeds=2, duration="0.5s")
            >>> sorted(r.verdicts)
            ['controller Sync-RMSE', 'controller Track-RMSE', 'plan Sync-RMSE']
        """
        return {f"{c['claim']} {c['metric']}": str(c["verdict"]) for c in self.summary["claims"]}

    def to_pandas(self) -> pandas.DataFrame:
        """The rows as a DataFrame: ``seed``, ``plan``, ``controller``, ``track_rmse``,
        ``sync_rmse`` [rad], ``group_stop``. Needs pandas.

        Example::

            >>> df = ringsync.reproduce(seeds=2, duration="0.3s").to_pandas()
            >>> df.groupby(["plan", "controller"])["sync_rmse"].mean().shape
            (6,)
        """
        pd = _pandas("Reproduction.to_pandas()")
        cols = ["seed", "plan", "controller", "track_rmse", "sync_rmse", "group_stop"]
        return pd.DataFrame(self.rows, columns=cols)

    def __repr__(self) -> str:
        seeds = sorted({r["seed"] for r in self.rows})
        return f"<Reproduction of Table 1 on {self.scenario.name!r}: {len(self.rows)} rows, seeds {seeds}>"


def reproduce(scenario: ScenarioLike | None = None, *, seeds: int = 8, **overrides: Any) -> Reproduction:
    """Reproduces the paper's Table 1 on ``scenario`` (default ``paper-2015``) as
    ``ringsync reproduce`` does, for ``seeds`` seeds (the scenario's seed, +1, …; a whole
    number 1 ..= 10 000, numpy integers too, as ``ringsync reproduce --seeds``): six runs
    per seed (PD, sync, ring-coupled × the two plans), in parallel inside Rust, the GIL
    released. ``overrides`` set scenario keys first. The first seed's rows are the
    numbers ``ringsync reproduce`` prints. Ctrl-C (a Jupyter kernel's interrupt) ends
    it early and raises ``KeyboardInterrupt``.

    Raises :class:`ringsync.ScenarioError` for a bad scenario, key or value, or ``seeds``
    out of range (naming it).

    Example::

        >>> r = ringsync.reproduce(seeds=1, duration="0.5s")
        >>> rows = {(x["plan"], x["controller"]): x for x in r.rows}
        >>> rows["p2p-lumped", "sync"]["sync_rmse"] < rows["p2p-lumped", "pd"]["sync_rmse"]
        True
    """
    s = load("paper-2015" if scenario is None else scenario)
    if overrides:
        s = s.set(**overrides)
    rows, summary = _rs.reproduce(s.to_toml(), s.origin, seeds)
    return Reproduction(s, list(rows), summary)

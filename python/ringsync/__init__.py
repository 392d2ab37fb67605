"""ringsync: simulate synchronised multi-axis motion over a ring fieldbus, from Python.

A master and n servo axes on a 100 Mbit/s Ethernet ring (Huang, Lou, Luo and Qian, 2015):
one lumped frame per cycle synchronises the clocks and gathers every axis's feedback,
point-to-point time slices carry the commands, and a position-synchronisation controller
keeps the axes' errors equal. The simulator models frames on links, drifting clocks and
the servo plants, deterministically: the same scenario and seed give the same numbers, to
the last bit, as the ``ringsync`` command.

Functions (each returns an object; docs/python.md is the walk-through):

- ``scenarios()``: the built-in scenario names; ``load(x)``: a :class:`Scenario` from a
  name, a path, TOML text or a dict; ``laws()``: the control laws and their parameters
  (:class:`Law` records, each with its :class:`LawParam` list; ``laws_text()`` as
  ``ringsync scenario laws`` prints them).
- ``simulate(scenario, *, seed=None, **overrides)``: a :class:`Run` with numpy arrays
  (``time`` [s]; ``x``, ``x_d``, ``e``, ``eps`` [rad]; ``u`` [V]; cycles × axes),
  ``metrics``, ``summary``, ``plot()`` (a matplotlib ``Figure``), ``to_pandas()`` (long,
  or ``wide=True``: one row per cycle), ``to_timeresponse()`` (python-control's
  ``TimeResponseData``), ``to_xarray()``, ``save(dir)``.
- ``check(scenario)``: a :class:`Check` (spectral radius, verdict, the paper's conditions,
  the loop ``matrix``, ``statespace()``: a python-control ``StateSpace``).
- ``plan(scenario=None)``: a :class:`Plan`, every term of eq. 1-2 in ns; ``plot()`` draws
  the cycle.
- ``sweep(scenario, grid, *, seeds=8, executor=None)``: a :class:`Sweep` of every
  combination of the grid's values and seeds, run in parallel in Rust, or on Dask
  (``executor=`` a Client or a scheduler address); ``to_pandas()``, ``means()`` (means
  and the sample standard deviation (n − 1) over the seeds), ``plot()``.
- ``reproduce(seeds=8)``: the paper's Table 1 over seeds (:class:`Reproduction`).
- ``rt(scenario)``: the same scenario run in real time over UDP on loopback (a
  :class:`Run` with the timing in its ``summary``).
- Part programs (``trajectory.kind = "program"`` on a ``[machine]``, e.g. the built-in
  ``circle-xy``): ``Run.path`` is a :class:`PathRun`, the tool's actual and commanded
  position [mm], the contour error, its metrics and the ISO 230-4 circular tests;
  ``plan_program(scenario)`` plans the program without a ring (``ringsync program``).

Optional extras: ``ringsync[pandas]``, ``ringsync[plot]`` (matplotlib),
``ringsync[xarray]``, ``ringsync[control]`` (python-control), ``ringsync[dask]``; each is
imported only when a method needs it.

Errors: :class:`ScenarioError` (a ``ValueError``) for a bad scenario, key or value, with
the CLI's one-line message; :class:`RunError` (a ``RuntimeError``) when the work fails.

Units: SI throughout (s, rad, V), clock errors in ns; scenario durations are strings with
a unit (``"1ms"``).

Example::

    >>> import ringsync
    >>> r = ringsync.simulate("paper-2015", duration="1s", **{"control.alpha": 0.3})
    >>> r.e.shape
    (1000, 4)
    >>> round(r.metrics["track_rmse"], 2) > 0
    True
"""

from __future__ import annotations

from ._ringsync import RunError, ScenarioError, __version__
from ._path import PathRun, plan_program
from ._plan import Plan, Reproduction, plan, reproduce
from ._run import Check, Run, check, rt, simulate
from ._scenario import Law, LawParam, Scenario, ScenarioLike, laws, laws_text, load, scenarios
from ._sweep import Sweep, sweep

__all__ = [
    "scenarios",
    "load",
    "laws",
    "laws_text",
    "simulate",
    "check",
    "plan",
    "plan_program",
    "sweep",
    "reproduce",
    "rt",
    "Scenario",
    "ScenarioLike",
    "Run",
    "PathRun",
    "Check",
    "Plan",
    "Sweep",
    "Reproduction",
    "Law",
    "LawParam",
    "ScenarioError",
    "RunError",
    "__version__",
]

for _cls in (Scenario, Run, PathRun, Check, Plan, Sweep, Reproduction, Law, LawParam):
    _cls.__module__ = __name__
del _cls

# The exceptions come from the extension module; their examples are added here.
ScenarioError.__doc__ = (ScenarioError.__doc__ or "") + """

Example::

    >>> import ringsync
    >>> try:
    ...     ringsync.load("paper-2015").set("faults.loss", 2.0)
    ... except ringsync.ScenarioError as e:
    ...     print("faults.loss = 2 is out of range: allowed 0 ..= 1" in str(e), isinstance(e, ValueError))
    True True
    >>> ringsync.simulate("paper-2015", seed=-1)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
      ...
    ringsync.ScenarioError: seed = -1 is out of range: allowed a whole number 0 ..= 9223372036854775807 (2^63 - 1: ...)
"""
RunError.__doc__ = (RunError.__doc__ or "") + """

Example::

    >>> import ringsync
    >>> try:
    ...     ringsync.simulate("paper-2015", duration="0.1s").save("/proc/ringsync-run")
    ... except ringsync.RunError as e:
    ...     print("could not write:", type(e).__name__, isinstance(e, RuntimeError))
    could not write: RunError True
"""

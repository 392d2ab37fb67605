"""Type stubs of the extension module ``ringsync._ringsync`` (the Rust binding crate
``crates/python``). Private: use the package ``ringsync``, whose functions call these.

A scenario crosses as its TOML text and its origin (what it was loaded from, named in
error messages); every function validates it again.
"""

from typing import Any

import numpy as np
import numpy.typing as npt

__version__: str

class ScenarioError(ValueError):
    """A scenario, key or value is invalid, a scenario name or file is unknown, or an
    argument (a seed, a count, a directory) is out of its range; the message is one line
    (the CLI's for a scenario) naming the key or argument and what is allowed.

    Example::

        >>> ringsync.simulate("paper-2015", seed=-1)
        Traceback (most recent call last):
          ...
        ringsync.ScenarioError: seed = -1 is out of range: allowed a whole number 0 ..= 9223372036854775807 (...)
    """

class RunError(RuntimeError):
    """The work failed (I/O, an internal error, a Rust panic); the input was fine.

    Example::

        >>> try:
        ...     ringsync.simulate("paper-2015", duration="0.1s").save("/proc/ringsync-run")
        ... except ringsync.RunError as e:
        ...     print(type(e).__name__)
        RunError
    """

def scenarios() -> list[str]:
    """The names of the built-in scenarios."""

def load(source: str) -> tuple[str, str]:
    """A built-in scenario by name or a scenario file by path: (TOML text, origin)."""

def parse(text: str, origin: str) -> dict[str, Any]:
    """Validates scenario text: name, description, axes, seed, duration_s [s], cycle_s [s],
    law, hash (hex)."""

def from_dict(d: dict[str, Any]) -> str:
    """A dict of dotted keys and/or nested tables as TOML text (a value nested more than 32
    levels deep, or containing itself, is a ScenarioError naming its key)."""

def with_values(text: str, origin: str, items: list[tuple[str, Any]]) -> tuple[str, str]:
    """The scenario with the (dotted key, value) items set and validated, as
    ``ringsync sweep --set`` makes a case: (TOML text, origin)."""

def values(text: str) -> dict[str, Any]:
    """Every key with its value in effect (the text's, else the reference scenario's)."""

def builtin_text(name: str) -> str | None:
    """The commented TOML text of a built-in scenario."""

def laws() -> str:
    """The control laws and their parameters, as ``ringsync scenario laws`` prints them."""

def law_registry() -> list[dict[str, Any]]:
    """The control laws of the registry as data, in registry order (``ringsync.laws()``
    makes ``Law`` records of them): one dict per law with ``name`` (str), ``description``
    (str), ``min_axes`` (int) and ``params``, a list of dicts of its own parameters
    (``[control.params]``) with ``key``, ``doc``, ``unit`` (str), ``default``, ``min`` and
    ``max`` (float, in ``unit``; ``max`` is ``inf`` for no upper bound)."""

class SimRun:
    """A finished simulation (``ringsync.Run`` wraps it)."""

    @property
    def axes(self) -> int: ...
    @property
    def seed(self) -> int: ...
    @property
    def name(self) -> str: ...
    @property
    def realtime(self) -> bool: ...
    def columns(self) -> dict[str, npt.NDArray[np.float64]]:
        """``time`` (cycles,) [s]; ``x_d``, ``x``, ``e``, ``eps`` [rad], ``u`` [V],
        ``sample_time``, ``apply_time`` [s], ``clock_error_ns`` [ns], cycles × axes."""
    def path(self) -> dict[str, Any] | None:
        """A part program's run (None otherwise): ``axes`` (letters), ``time`` (cycles,)
        [s], ``actual`` and ``desired`` (cycles × machine axes) [mm], ``contour_error``
        (cycles,) [mm], ``metrics`` and ``circles`` (ISO 230-4 tests, each with its
        ``angle`` [rad] and ``deviation`` [mm] arrays)."""
    def summary_json(self) -> str:
        """summary.json's text, as ``ringsync sim`` writes it."""
    def summary(self) -> dict[str, Any]:
        """summary.json's content."""
    def metrics(self) -> dict[str, Any]:
        """The run's figures, flat, from the run itself."""
    def text(self) -> str:
        """The CLI's lines on the run."""
    def save(self, dir: str) -> None:
        """Writes the CLI's files into ``dir`` (replaced as a whole); an empty ``dir`` is a
        ScenarioError."""

def program(text: str, origin: str, points: int = 1000) -> dict[str, Any]:
    """The scenario's part program planned without a ring: ``ringsync program --json``'s
    object, with ``feed`` = (time [s], path speed [mm/s]) at ``points`` instants."""

def simulate(text: str, origin: str, seed: int | None = None) -> SimRun:
    """Simulates the scenario (its seed replaced when given: a whole number 0 ..= 2**63 - 1,
    else ScenarioError), keeping the trace."""

def rt(
    text: str, origin: str, prediction_seeds: int = 8, transport: str = "udp", stamps: str = "phy"
) -> SimRun:
    """Runs the scenario in real time (``ringsync rt``) over ``transport`` ("udp" or
    "veth") with ``stamps`` ("phy" or "software"), with ``prediction_seeds`` (0 ..= 10 000)
    seeds of the simulator's predictions; Ctrl-C ends it early (KeyboardInterrupt)."""

def check(
    text: str, origin: str, points: int = 4001
) -> tuple[dict[str, Any], str, bool, npt.NDArray[np.float64] | None, float]:
    """(``ringsync check --json``'s object, its text, whether stable, the discrete-time
    check's closed-loop matrix (states × states, 9 per axis; None when not modelled), the
    cycle time T_cyc [s]); ``points`` 1 ..= 1 000 000, as ``ringsync check --points``."""

def plan(text: str, origin: str, events: bool = False) -> dict[str, Any]:
    """``ringsync plan --json``'s object for the scenario's ring (integer ns); with
    ``events`` the frame-by-frame ``timeline`` too."""

def reproduce(text: str, origin: str, seeds: int) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """The paper's Table 1 on the scenario over ``seeds`` seeds (1 ..= 10 000): one dict per (seed, plan,
    controller) with ``seed``, ``plan``, ``controller``, ``track_rmse``, ``sync_rmse``
    [rad], ``group_stop``; and reproduce's summary.json as a dict."""

def sweep(
    text: str,
    origin: str,
    grid: list[tuple[str, list[Any]]],
    seeds: int = 1,
    jobs: int | None = None,
    progress: bool = False,
) -> dict[str, Any]:
    """``rows`` (one per run) and ``means`` (one per combination), values named by their
    index in the grid; ``seeds`` (1 ..= 1 000 000) and ``jobs`` (threads, 1 ..= 4096) as
    used. ``progress``: a line ``ringsync sweep: DONE/ALL runs`` on ``sys.stderr`` as runs
    finish. Ctrl-C raises ``KeyboardInterrupt`` once the runs under way have stopped."""

def sweep_cases(
    text: str, origin: str, grid: list[tuple[str, list[Any]]], seeds: int = 1
) -> list[tuple[list[int], int, str, float]]:
    """The sweep's cases, validated, in order: (value indices, seed, the case as JSON
    text, cost in axis-cycles)."""

def run_cases(cases: list[str], jobs: int = 1) -> list[dict[str, Any]]:
    """Runs cases given as JSON text (from :func:`sweep_cases`): one result dict per case
    (``track_rmse``, ``sync_rmse`` [rad], counters, ``clock_error_max_ns`` [ns],
    ``group_stop_s`` [s], ``group_stop_reason``, ``peak_u`` [V], ``saturated_cycles``)."""

def sweep_collect(
    text: str,
    origin: str,
    grid: list[tuple[str, list[Any]]],
    seeds: int,
    results: list[dict[str, Any]],
    jobs: int = 1,
) -> dict[str, Any]:
    """The same dict as :func:`sweep` from every case's result (in case order)."""

def _panic(message: str) -> None:
    """Panics inside Rust (for the tests: a panic becomes RunError)."""

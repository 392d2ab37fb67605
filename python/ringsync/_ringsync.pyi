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
    """A scenario, key or value is invalid, or a scenario name or file is unknown; the
    message is the CLI's one line."""

class RunError(RuntimeError):
    """The work failed (I/O, an internal error, a Rust panic); the input was fine."""

def scenarios() -> list[str]:
    """The names of the built-in scenarios."""

def load(source: str) -> tuple[str, str]:
    """A built-in scenario by name or a scenario file by path: (TOML text, origin)."""

def parse(text: str, origin: str) -> dict[str, Any]:
    """Validates scenario text: name, description, axes, seed, duration_s [s], cycle_s [s],
    law, hash (hex)."""

def from_dict(d: dict[str, Any]) -> str:
    """A dict of dotted keys and/or nested tables as TOML text."""

def with_values(text: str, origin: str, items: list[tuple[str, Any]]) -> tuple[str, str]:
    """The scenario with the (dotted key, value) items set and validated, as
    ``ringsync sweep --set`` makes a case: (TOML text, origin)."""

def values(text: str) -> dict[str, Any]:
    """Every key with its value in effect (the text's, else the reference scenario's)."""

def builtin_text(name: str) -> str | None:
    """The commented TOML text of a built-in scenario."""

def laws() -> str:
    """The control laws and their parameters, as ``ringsync scenario laws`` prints them."""

class SimRun:
    """A finished simulation (``ringsync.Run`` wraps it)."""

    @property
    def axes(self) -> int: ...
    @property
    def seed(self) -> int: ...
    @property
    def name(self) -> str: ...
    def columns(self) -> dict[str, npt.NDArray[np.float64]]:
        """``time`` (cycles,) [s]; ``x_d``, ``x``, ``e``, ``eps`` [rad], ``u`` [V],
        ``sample_time``, ``apply_time`` [s], ``clock_error_ns`` [ns], cycles × axes."""
    def summary_json(self) -> str:
        """summary.json's text, as ``ringsync sim`` writes it."""
    def summary(self) -> dict[str, Any]:
        """summary.json's content."""
    def metrics(self) -> dict[str, Any]:
        """The run's figures, flat, from the run itself."""
    def text(self) -> str:
        """The CLI's lines on the run."""
    def save(self, dir: str) -> None:
        """Writes the CLI's files into ``dir`` (replaced as a whole)."""

def simulate(text: str, origin: str, seed: int | None = None) -> SimRun:
    """Simulates the scenario (its seed replaced when given), keeping the trace."""

def check(text: str, origin: str, points: int = 4001) -> tuple[dict[str, Any], str, bool]:
    """(``ringsync check --json``'s object, its text, whether stable)."""

def sweep(
    text: str,
    origin: str,
    grid: list[tuple[str, list[Any]]],
    seeds: int = 1,
    jobs: int | None = None,
) -> dict[str, Any]:
    """``rows`` (one per run) and ``means`` (one per combination), values named by their
    index in the grid; ``jobs``: threads used."""

def _panic(message: str) -> None:
    """Panics inside Rust (for the tests: a panic becomes RunError)."""

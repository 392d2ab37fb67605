"""Scenarios: load one (a built-in name, a path, TOML text, a dict), read its values by
dotted key, change them into a new validated scenario."""

from __future__ import annotations

import math
import os
import re
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any, Union

from . import _ringsync as _rs
from ._ringsync import ScenarioError

__all__ = ["Scenario", "ScenarioLike", "load", "scenarios", "laws", "laws_text", "Law", "LawParam"]

#: What the functions of ringsync take as a scenario: a :class:`Scenario`, a built-in name,
#: a path, TOML text, or a dict of scenario keys.
ScenarioLike = Union["Scenario", str, "os.PathLike[str]", Mapping[str, Any]]

_MISSING: Any = object()
_INDEXED = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)\[(\d+)\]$")


class Scenario(Mapping[str, Any]):
    """A validated scenario: every parameter of one run.

    Tables and keys are those of the scenario files (``ringsync scenario show
    paper-2015`` prints the reference one, commented, with units): ``duration``, ``seed``,
    ``ring.*`` (slaves, cycle, bit rate, PHY and cable delays), ``clock.*`` (oscillator
    drift [ppm], offsets, sync), ``faults.*`` (loss and corruption probabilities, watchdog
    cycles, following-error limit [rad]), ``control.*`` (the law, estimator, gains
    ``kp`` [V/rad], ``kd``, ``ke`` [V·s/rad], coupling weight ``alpha``), ``trajectory.*``
    (``peak_speed`` [rad/s], ``period``), ``axis`` (one table per axis: ``u_max`` [V],
    ``rated_torque`` [N·m], ``encoder_bits``, …). Durations are strings with a unit
    (``"1ms"``, ``"250us"``, ``"4s"``).

    A scenario reads like a read-only dict keyed by dotted names, with the values in effect
    (the scenario's own, and the reference scenario's where it says nothing);
    ``s["axis[1].u_max"]`` reads axis 1's table (0-based, as error messages count).
    :meth:`set` returns a new, validated scenario; :meth:`to_toml` gives its text, which
    ``ringsync sim FILE`` runs identically.

    Example::

        >>> import ringsync
        >>> s = ringsync.load("paper-2015")
        >>> s.name, s.axes, s["control.alpha"], s["ring.cycle"]
        ('paper-2015', 4, 0.5, '1ms')
        >>> t = s.set("control.alpha", 0.3)
        >>> t["control.alpha"], s["control.alpha"]
        (0.3, 0.5)
        >>> s.set(**{"ring.slaves": 2, "duration": "0.5s"}).axes
        2
    """

    __slots__ = ("_text", "_origin", "_info", "_values")

    def __init__(self, text: str, origin: str = "<text>") -> None:
        """Validates the TOML ``text``; ``origin`` names it in error messages.

        Raises :class:`ringsync.ScenarioError` with the CLI's one-line message when the
        text is not a valid scenario. Prefer :func:`ringsync.load`, which also takes names,
        paths and dicts.

        Example::

            >>> ringsync.Scenario('duration = "1s"\\n[ring]\\nslaves = 2\\n').axes
            2
        """
        self._text: str = text
        self._origin: str = origin
        self._info: dict[str, Any] = _rs.parse(text, origin)
        self._values: dict[str, Any] | None = None

    # -- facts --------------------------------------------------------------------------

    @property
    def name(self) -> str:
        """The scenario's name (``name``), as outputs show it."""
        return str(self._info["name"])

    @property
    def description(self) -> str:
        """Its one line of description (``description``)."""
        return str(self._info["description"])

    @property
    def axes(self) -> int:
        """Number of axes n (one per slave, ``ring.slaves``)."""
        return int(self._info["axes"])

    @property
    def seed(self) -> int:
        """The seed of every random draw (``seed``)."""
        return int(self._info["seed"])

    @property
    def duration(self) -> float:
        """Simulated time [s] (``duration``)."""
        return float(self._info["duration_s"])

    @property
    def cycle(self) -> float:
        """Cycle time T_cyc [s] (``ring.cycle``)."""
        return float(self._info["cycle_s"])

    @property
    def law(self) -> str:
        """The control law's name as outputs give it (e.g. ``sync``, ``pd``)."""
        return str(self._info["law"])

    @property
    def origin(self) -> str:
        """Where it came from: a built-in name, a path, ``<text>``, ``<dict>``, plus the keys
        set since (``paper-2015 with control.alpha=0.3``)."""
        return self._origin

    @property
    def hash(self) -> str:
        """FNV-1a 64-bit hash of its text (hex), as ``summary.json`` names it."""
        return str(self._info["hash"])

    # -- the mapping --------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """Every value in effect as nested dicts (tables) and lists (``axis``): a copy.

        Example::

            >>> ringsync.load("paper-2015").to_dict()["ring"]["slaves"]
            4
        """
        import copy

        return copy.deepcopy(self._effective())

    def _effective(self) -> dict[str, Any]:
        if self._values is None:
            self._values = _rs.values(self._text)
        return self._values

    def __getitem__(self, key: str) -> Any:
        """The value in effect of the dotted ``key`` (``"control.alpha"``,
        ``"axis[1].u_max"``); KeyError for a key the scenario lacks or that is not a
        string, as a dict raises (so ``s.get(key, default)`` and ``key in s`` work).

        Example::

            >>> s = ringsync.load("paper-2015")
            >>> s["axis[1].u_max"], s.get("control.nope", "none"), s.get(1, "none")
            (10.0, 'none', 'none')
        """
        if not isinstance(key, str):
            raise KeyError(key)
        node: Any = self._effective()
        for part in key.split("."):
            m = _INDEXED.match(part)
            name, index = (m.group(1), int(m.group(2))) if m else (part, None)
            if not isinstance(node, dict) or name not in node:
                raise KeyError(key)
            node = node[name]
            if index is not None:
                if not isinstance(node, list) or index >= len(node):
                    raise KeyError(key)
                node = node[index]
        return node

    def __iter__(self) -> Iterator[str]:
        def walk(prefix: str, table: dict[str, Any]) -> Iterator[str]:
            for k, v in table.items():
                full = f"{prefix}{k}"
                if isinstance(v, dict) and v:
                    yield from walk(full + ".", v)
                else:
                    yield full

        return walk("", self._effective())

    def __len__(self) -> int:
        return sum(1 for _ in self)

    def __contains__(self, key: object) -> bool:
        if not isinstance(key, str):
            return False
        try:
            self[key]
        except KeyError:
            return False
        return True

    # -- changes ------------------------------------------------------------------------

    def set(self, key: str | None = None, value: Any = _MISSING, /, **items: Any) -> Scenario:
        """A new scenario with keys set, validated; this one is unchanged.

        ``s.set("control.alpha", 0.3)`` or ``s.set(**{"control.alpha": 0.3, "duration":
        "1s"})``. Values are numbers, strings (durations with a unit, names such as
        ``"pd"``), bools, lists (one value per axis) or dicts (tables). A key or value the
        scenario does not accept raises :class:`ringsync.ScenarioError` with the message
        ``ringsync sweep --set KEY=VALUE`` prints for it.

        Example::

            >>> s = ringsync.load("paper-2015").set("control.kp", [3.0, 3.2, 3.4, 3.6])
            >>> s["control.kp"]
            [3.0, 3.2, 3.4, 3.6]
            >>> ringsync.load("paper-2015").set("faults.loss", 2.0)
            Traceback (most recent call last):
              ...
            ringsync.ScenarioError: faults.loss = 2 is out of range: allowed 0 ..= 1 (a probability)
        """
        pairs: list[tuple[str, Any]] = []
        if key is not None and not isinstance(key, str):
            raise ScenarioError(f'{key!r} is not a scenario key: keys are strings like "control.alpha"')
        if key is not None:
            if value is _MISSING:
                raise TypeError("Scenario.set(key, value): the value is missing")
            pairs.append((key, value))
        elif value is not _MISSING:
            raise TypeError("Scenario.set(key, value): the key is missing")
        pairs.extend(items.items())
        if not pairs:
            return self
        text, origin = _rs.with_values(self._text, self._origin, pairs)
        return Scenario(text, origin)

    def to_toml(self) -> str:
        """The scenario as TOML text: the file it was loaded from as written (comments and
        all), or the text made when keys were set. ``ringsync sim`` runs it identically.

        Example::

            >>> 'alpha = 0.3' in ringsync.load("paper-2015").set("control.alpha", 0.3).to_toml()
            True
        """
        return self._text

    # -- plumbing -----------------------------------------------------------------------

    def __repr__(self) -> str:
        return (
            f"<Scenario {self.name!r} from {self._origin!r}: {self.axes} axes, "
            f"{self.law} law, {self.duration:g} s of {self.cycle * 1e3:g} ms cycles, seed {self.seed}>"
        )

    def __reduce__(self) -> tuple[Any, ...]:
        return (Scenario, (self._text, self._origin))

    def _repr_pretty_(self, p: Any, cycle: bool) -> None:  # IPython
        p.text(repr(self))


def scenarios() -> list[str]:
    """The names of the built-in scenarios, for :func:`load`.

    Example::

        >>> ringsync.scenarios()
        ['paper-2015', 'arm-2link', 'circle-xy', 'gantry-xyy']
    """
    return list(_rs.scenarios())


@dataclass(frozen=True)
class LawParam:
    """One parameter a control law declares for itself (the registry's ``ParamSpec``): a
    value per axis, set in a scenario's ``[control.params]`` table (one number for every
    axis, or a list of one per axis).

    - ``name``: its key in ``[control.params]``, e.g. ``"kx"``
    - ``default``: the value when a scenario does not set it, in ``unit``
    - ``unit``: its unit, e.g. ``"V/rad"`` (``"1"`` for a pure number)
    - ``doc``: one line, what it is, with its symbol
    - ``min``, ``max``: the allowed range, inclusive, in ``unit`` (``max`` is ``math.inf``
      for no upper bound)

    Example::

        >>> kx = next(law for law in ringsync.laws() if law.name == "adjacent").param("kx")
        >>> kx.name, kx.default, kx.unit, kx.min, kx.max
        ('kx', 1.591, 'V/rad', 0.0, inf)
    """

    name: str
    default: float
    unit: str
    doc: str
    min: float = 0.0
    max: float = math.inf

    def allows(self, value: float) -> bool:
        """Whether ``value`` (in :attr:`unit`) is finite and within [min, max], as a
        scenario's ``[control.params]`` is checked."""
        return math.isfinite(value) and self.min <= value <= self.max


@dataclass(frozen=True)
class Law:
    """A control law of the registry (``control.law`` in a scenario), as ``ringsync scenario
    laws`` lists it:

    - ``name``: the name scenarios use, e.g. ``"sync"``
    - ``description``: one line, what the law is and where it comes from
    - ``params``: its own parameters in ``[control.params]`` (a tuple of :class:`LawParam`,
      empty for most laws; the common gains are ``[control]`` keys)
    - ``min_axes``: the fewest axes it runs on (2 for a coupling)

    Example::

        >>> sync = next(law for law in ringsync.laws() if law.name == "sync")
        >>> sync.params, sync.min_axes
        ((), 2)
        >>> ringsync.load("paper-2015")["control.law"] == sync.name
        True
    """

    name: str
    description: str
    params: tuple[LawParam, ...] = ()
    min_axes: int = 1

    def param(self, name: str) -> LawParam:
        """The parameter whose key is ``name``; KeyError naming the law's parameters
        otherwise."""
        for p in self.params:
            if p.name == name:
                return p
        known = ", ".join(p.name for p in self.params) or "none"
        raise KeyError(f"law {self.name!r} has no parameter {name!r}: its [control.params] are {known}")

    @property
    def defaults(self) -> dict[str, float]:
        """Each parameter's default, by key: what ``[control.params]`` holds when a scenario
        sets none."""
        return {p.name: p.default for p in self.params}


def laws() -> list[Law]:
    """The control laws (``control.law``) with their own ``[control.params]``, in the
    registry's order, as typed records (:class:`Law`, its parameters :class:`LawParam`
    with default, unit, meaning and allowed range). :func:`laws_text` is the same as the
    text ``ringsync scenario laws`` prints.

    Example::

        >>> [law.name for law in ringsync.laws()]
        ['pd', 'sync', 'ring-coupled', 'adjacent', 'ccc']
        >>> adjacent = {law.name: law for law in ringsync.laws()}["adjacent"]
        >>> [(p.name, p.default, p.unit) for p in adjacent.params]
        [('kx', 1.591, 'V/rad'), ('kxd', 0.7955, 'V·s/rad')]
    """
    return [
        Law(
            name=str(e["name"]),
            description=str(e["description"]),
            params=tuple(
                LawParam(
                    name=str(p["key"]),
                    default=float(p["default"]),
                    unit=str(p["unit"]),
                    doc=str(p["doc"]),
                    min=float(p["min"]),
                    max=float(p["max"]),
                )
                for p in e["params"]
            ),
            min_axes=int(e["min_axes"]),
        )
        for e in _rs.law_registry()
    ]


def laws_text() -> str:
    """The control laws and their ``[control.params]`` as the text ``ringsync scenario
    laws`` prints (one law per line, its parameters indented below it); :func:`laws` has the
    same as records.

    Example::

        >>> print(ringsync.laws_text())  # doctest: +ELLIPSIS
        pd             standard PD, the paper's baseline: ...
        sync           the paper's position-synchronisation controller ...
    """
    return str(_rs.laws())


def _looks_like_toml(text: str) -> bool:
    """Whether ``text`` (no built-in name, no existing file) is TOML rather than a path: a
    single line ending in ``.toml`` is a path (``runs/alpha=0.5.toml``), even with an ``=``."""
    if "\n" not in text and text.rstrip().lower().endswith(".toml"):
        return False
    return "\n" in text or "=" in text or text.lstrip().startswith("[")


def load(source: ScenarioLike) -> Scenario:
    """A scenario from a built-in name, a path, TOML text or a dict, validated.

    - a name from :func:`scenarios` (``"paper-2015"``), or a path (``str`` or
      ``pathlib.Path``) to a scenario file;
    - TOML text (anything with ``=`` or a newline that is not an existing file, except a
      single line ending in ``.toml``, which is a path): every key is optional, the
      reference scenario fills in the rest;
    - a dict of dotted keys (``{"control.alpha": 0.3}``) and/or nested tables
      (``{"ring": {"slaves": 2}}``);
    - a :class:`Scenario`, returned as it is.

    Raises :class:`ringsync.ScenarioError` with the CLI's one-line message (an unknown name
    lists the built-in ones; a bad key or value names it).

    Example::

        >>> a = ringsync.load("paper-2015")
        >>> b = ringsync.load({"ring.slaves": 2, "control": {"alpha": 0.25}})
        >>> c = ringsync.load('[ring]\\nslaves = 2\\n[control]\\nalpha = 0.25\\n')
        >>> (a.axes, b.axes, b["control.alpha"] == c["control.alpha"])
        (4, 2, True)
    """
    if isinstance(source, Scenario):
        return source
    if isinstance(source, Mapping):
        return Scenario(_rs.from_dict(dict(source)), "<dict>")
    if isinstance(source, os.PathLike):
        text, origin = _rs.load(os.fspath(source))
        return Scenario(text, origin)
    if isinstance(source, str):
        if source in _rs.scenarios() or os.path.exists(source) or not _looks_like_toml(source):
            text, origin = _rs.load(source)
            return Scenario(text, origin)
        return Scenario(source, "<text>")
    raise TypeError(
        f"ringsync.load takes a scenario name, a path, TOML text, a dict or a Scenario, not {type(source).__name__}"
    )

"""The conventions a python-control or pandas user expects: a run as a
``control.TimeResponseData``, a wide trace frame, typed returns (matplotlib's and
python-control's classes), the control laws as records, sample standard deviations (n − 1)
over a sweep's seeds, and a README whose install line and Dask snippet match docs/python.md."""

from __future__ import annotations

import dataclasses
import math
import re
import subprocess
import sys
import tomllib
import typing
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import ringsync
from ringsync import _path, _plan, _run, _sweep

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def run() -> ringsync.Run:
    return ringsync.simulate("paper-2015", duration="0.3s")


# --- Run.to_timeresponse() -------------------------------------------------------------


def test_to_timeresponse_is_python_controls_response_of_x_and_u(run: ringsync.Run) -> None:
    control = pytest.importorskip("control")
    resp = run.to_timeresponse()
    assert isinstance(resp, control.TimeResponseData)
    n = run.axes
    np.testing.assert_array_equal(resp.time, run.time)
    assert resp.outputs.shape == (n, len(run.time)) and resp.inputs.shape == (n, len(run.time))
    np.testing.assert_array_equal(resp.outputs, run.x.T)  # outputs: positions x [rad]
    np.testing.assert_array_equal(resp.inputs, run.u.T)  # inputs: commands u [V]
    assert resp.states.shape == (0, len(run.time))  # no states, but `states` works
    assert resp.output_labels == [f"x[{i}]" for i in range(1, n + 1)]
    assert resp.input_labels == [f"u[{i}]" for i in range(1, n + 1)]
    assert "paper-2015" in resp.title and resp.sysname == "paper-2015"
    assert (resp.noutputs, resp.ninputs, resp.nstates) == (n, n, 0)
    # The run's arrays are not shared: changing the response leaves the run alone.
    resp.y[0, 0] += 1.0
    assert run.x[0, 0] != resp.y[0, 0]
    # python-control's own tools take it: its frame has the labels as columns.
    df = resp.to_pandas()
    assert list(df.columns) == ["time", *resp.input_labels, *resp.output_labels]


def test_to_timeresponse_of_one_axis_is_siso() -> None:
    pytest.importorskip("control")
    one = ringsync.simulate("paper-2015", duration="0.1s", **{"ring.slaves": 1, "control.law": "pd"})
    resp = one.to_timeresponse()
    assert resp.issiso and resp.outputs.shape == (100,)
    np.testing.assert_array_equal(resp.outputs, one.x[:, 0])
    assert resp.y.shape == (1, 100) and resp.output_labels == ["x[1]"]


def test_missing_control_names_the_extra(run: ringsync.Run, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "control", None)  # `import control` raises ImportError
    with pytest.raises(ImportError, match=r"Run\.to_timeresponse\(\) needs python-control: pip install 'ringsync\[control\]'"):
        run.to_timeresponse()
    with pytest.raises(ImportError, match=r"ringsync\[control\]"):
        ringsync.check("paper-2015").statespace()


# --- Run.to_pandas(wide=True) ------------------------------------------------------------


def test_to_pandas_wide_has_a_row_per_cycle_and_a_column_per_signal_and_axis(run: ringsync.Run) -> None:
    pd = pytest.importorskip("pandas")
    long = run.to_pandas()
    wide = run.to_pandas(wide=True)
    n, cycles = run.axes, len(run.time)
    signals = ["x_d", "x", "e", "eps", "u", "sample_time", "apply_time", "clock_error_ns"]
    assert list(long.columns) == ["time", "axis", *signals]  # the long frame as before
    assert wide.shape == (cycles, len(signals) * n)
    assert list(wide.columns) == [f"{s}[{i}]" for s in signals for i in range(1, n + 1)]
    assert wide.index.name == "time"
    np.testing.assert_array_equal(wide.index.to_numpy(), run.time)
    for s in signals:
        for i in range(n):
            np.testing.assert_array_equal(wide[f"{s}[{i + 1}]"].to_numpy(), getattr(run, s)[:, i])
    # One value, looked up in both frames.
    t = wide.index[123]
    assert wide.loc[t, "eps[3]"] == long[(long["time"] == t) & (long["axis"] == 3)]["eps"].item()
    # The long frame pivoted is the wide one.
    pivot = long.pivot(index="time", columns="axis", values="u")
    np.testing.assert_array_equal(pivot.to_numpy(), wide[[f"u[{i}]" for i in range(1, n + 1)]].to_numpy())
    assert isinstance(wide, pd.DataFrame)
    with pytest.raises(TypeError, match="wide must be True or False"):
        run.to_pandas(wide="yes")  # type: ignore[arg-type]


def test_to_pandas_wide_keeps_nan_of_lost_commands() -> None:
    pytest.importorskip("pandas")
    lossy = ringsync.simulate("paper-2015", duration="0.3s", **{"faults.loss": 0.2})
    wide = lossy.to_pandas(wide=True)
    lost = np.isnan(lossy.apply_time)
    assert lost.any()
    assert wide.filter(regex=r"^apply_time\[").isna().to_numpy().sum() == lost.sum()


# --- Precise return types --------------------------------------------------------------


def _hints(func: Any) -> dict[str, Any]:
    """``func``'s annotations resolved with the names its module imports under
    ``TYPE_CHECKING``."""
    import control
    import pandas
    import xarray
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure, FigureBase

    names = {"control": control, "pandas": pandas, "xarray": xarray, "Axes": Axes,
             "Figure": Figure, "FigureBase": FigureBase, "_Fig": _run._Fig}
    return typing.get_type_hints(func, localns=names)


def test_plots_and_python_control_returns_are_typed() -> None:
    control = pytest.importorskip("control")
    pytest.importorskip("matplotlib")
    pytest.importorskip("xarray")
    pandas = pytest.importorskip("pandas")
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    assert _hints(ringsync.Sweep.plot)["return"] is Figure
    assert _hints(ringsync.Plan.plot)["return"] is Figure
    assert _hints(ringsync.PathRun.plot)["return"] is Axes
    assert _hints(ringsync.PathRun.plot_circular)["return"] is Axes
    assert _hints(ringsync.Check.statespace)["return"] is control.StateSpace
    assert _hints(ringsync.Run.to_timeresponse)["return"] is control.TimeResponseData
    assert _hints(ringsync.Run.to_pandas)["return"] is pandas.DataFrame
    assert _hints(ringsync.Sweep.plot)["ax"] == Axes | None
    # Run.plot(): a new Figure, or the figure (or subfigure) it was given.
    if hasattr(typing, "get_overloads"):  # Python 3.11
        new, given = typing.get_overloads(ringsync.Run.plot)
        assert _hints(new)["return"] is Figure
        assert _hints(given)["return"] is _run._Fig and _hints(given)["fig"] is _run._Fig
    # No `Any` left where a class exists.
    for cls in (ringsync.Run, ringsync.Sweep, ringsync.Plan, ringsync.PathRun, ringsync.Check):
        for name in ("plot", "plot_circular", "statespace", "to_timeresponse", "to_pandas"):
            f = getattr(cls, name, None)
            if f is not None:
                assert f.__annotations__.get("return") not in ("Any", None), (cls, name)


def test_plots_return_what_they_say() -> None:
    mpl = pytest.importorskip("matplotlib")
    mpl.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    r = ringsync.simulate("circle-xy", duration="1s")
    assert type(r.plot()) is Figure
    top = plt.figure()
    sub = top.subfigures(1, 2)[0]
    assert r.plot(fig=sub) is sub  # Run.plot returns the (sub)figure it drew into
    assert isinstance(r.path.plot(), Axes) and isinstance(ringsync.plan().plot(), Figure)
    # Given an Axes in a subfigure, plot() returns the Figure it is on (savefig works).
    ax = top.subfigures(1, 2)[1].subplots()
    assert ringsync.plan().plot(ax=ax) is top
    plt.close("all")


def test_import_leaves_the_extras_unimported() -> None:
    code = (
        "import sys, ringsync\n"
        "print(sorted(m for m in ('control', 'matplotlib', 'pandas', 'xarray', 'dask') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


# --- laws() as records -------------------------------------------------------------------


def test_laws_are_typed_records_with_their_params() -> None:
    laws = ringsync.laws()
    assert isinstance(laws, list) and all(isinstance(law, ringsync.Law) for law in laws)
    by_name = {law.name: law for law in laws}
    assert list(by_name) == ["pd", "sync", "ring-coupled", "adjacent", "ccc"]
    sync = by_name["sync"]
    assert "synchronisation controller" in sync.description
    assert sync.params == () and sync.min_axes == 2 and sync.defaults == {}
    assert by_name["pd"].min_axes == 1
    adjacent = by_name["adjacent"]
    assert [p.name for p in adjacent.params] == ["kx", "kxd"]
    kx = adjacent.param("kx")
    assert kx == ringsync.LawParam(name="kx", default=1.591, unit="V/rad", doc=kx.doc, min=0.0, max=math.inf)
    assert "K_X" in kx.doc and adjacent.defaults == {"kx": 1.591, "kxd": 0.7955}
    assert kx.allows(0.0) and not kx.allows(-1.0) and not kx.allows(math.nan)
    with pytest.raises(KeyError, match="its \\[control.params\\] are kx, kxd"):
        adjacent.param("ky")
    with pytest.raises(dataclasses.FrozenInstanceError):
        sync.name = "other"  # type: ignore[misc]
    assert hash(adjacent) == hash(ringsync.laws()[3])  # frozen, so hashable and equal
    assert [p.name for p in by_name["ccc"].params] == ["kcp", "kcd"]


def test_laws_text_is_the_clis_and_matches_the_records(cli: Any) -> None:
    text = ringsync.laws_text()
    assert text == cli.run("scenario", "laws").stdout
    lines = text.splitlines()
    for law in ringsync.laws():
        head = next(i for i, line in enumerate(lines) if line.split(" ", 1)[0] == law.name)
        assert law.description in lines[head]
        assert f"runs on {law.min_axes} or more axes" in lines[head + 1]
        for p in law.params:
            assert any(line.strip().startswith(f"{p.name} = {p.default:g} {p.unit} ") and p.doc in line
                       for line in lines), p


def test_a_laws_defaults_are_what_a_scenario_runs_with() -> None:
    kx = next(law for law in ringsync.laws() if law.name == "adjacent").param("kx")
    base = {"control.law": "adjacent", "duration": "0.3s"}
    plain = ringsync.simulate("paper-2015", **base)
    explicit = ringsync.simulate("paper-2015", **base, **{"control.params.kx": kx.default})
    assert plain.metrics == explicit.metrics
    with pytest.raises(ringsync.ScenarioError, match=re.escape(f"allowed >= 0 {kx.unit}")):
        ringsync.load("paper-2015").set(**base, **{"control.params.kx": -1.0})


# --- Sample standard deviations (n − 1) over a sweep's seeds ---------------------------


@pytest.fixture(scope="module")
def sw() -> ringsync.Sweep:
    return ringsync.sweep("paper-2015", {"faults.loss": [0.0, 0.05], "control.law": ["pd", "sync"]},
                          seeds=3, duration="0.3s")


def test_mean_rows_sd_is_the_sample_sd_of_the_rows(sw: ringsync.Sweep) -> None:
    assert len(sw.mean_rows) == 4
    for m in sw.mean_rows:
        mine = [r["sync_rmse"] for r in sw.rows
                if (r["faults.loss"], r["control.law"]) == (m["faults.loss"], m["control.law"])]
        assert len(mine) == m["runs"] == 3
        sample = float(np.std(mine, ddof=1))
        assert sample > 0 and not math.isclose(sample, float(np.std(mine)), rel_tol=1e-6)
        assert math.isclose(m["sync_rmse_std"], sample, rel_tol=1e-12)


def test_means_frame_sd_is_pandas_std(sw: ringsync.Sweep) -> None:
    pytest.importorskip("pandas")
    means = sw.means()
    by_case = sw.to_pandas().groupby(["faults.loss", "control.law"], sort=False)["sync_rmse"].std()
    np.testing.assert_allclose(means["sync_rmse_std"].to_numpy(), by_case.to_numpy(), rtol=1e-12, atol=0)


def test_one_seed_has_sd_zero() -> None:
    one = ringsync.sweep("paper-2015", {"control.law": ["pd", "sync"]}, seeds=1, duration="0.1s")
    assert [m["sync_rmse_std"] for m in one.mean_rows] == [0.0, 0.0]


def test_plot_error_bars_are_the_sample_sd(sw: ringsync.Sweep) -> None:
    mpl = pytest.importorskip("matplotlib")
    mpl.use("Agg")
    import matplotlib.pyplot as plt

    fig = sw.plot("track_rmse")
    ax = fig.axes[0]
    assert len(ax.containers) == 2  # one line per law
    for container, law in zip(ax.containers, ["pd", "sync"]):
        _, _, (bars,) = container
        for seg, loss in zip(bars.get_segments(), [0.0, 0.05]):
            vals = [r["track_rmse"] for r in sw.rows if (r["control.law"], r["faults.loss"]) == (law, loss)]
            (x0, lo), (x1, hi) = seg
            assert x0 == x1 == loss
            assert math.isclose((hi - lo) / 2, float(np.std(vals, ddof=1)), rel_tol=1e-9)
            assert math.isclose((hi + lo) / 2, float(np.mean(vals)), rel_tol=1e-12)
    assert "sample sd (n − 1)" in ax.get_title()
    plt.close("all")


def test_every_sd_in_the_package_is_said_to_be_the_sample_sd() -> None:
    files = sorted((REPO / "python" / "ringsync").glob("*.py")) + [REPO / "docs" / "python.md"]
    for f in files:
        text = " ".join(f.read_text().split())  # one line, single spaces
        assert "population" not in text, f
        for m in re.finditer(r"standard deviation", text):
            around = text[max(0, m.start() - 10) : m.end() + 10]
            assert "sample standard deviation (n − 1)" in around, (f.name, around)
        for m in re.finditer(r"± (one )?(sd|std)\b", text):
            raise AssertionError(f"{f.name}: {text[m.start() - 30 : m.end() + 30]!r} says sd, not the sample sd")


# --- README and docs/python.md ---------------------------------------------------------


#: What in a docs/python.md snippet needs which extra of pyproject.toml.
NEEDS = {
    "pandas": r"\.to_pandas\(|\.means\(\)",
    "plot": r"\.plot\(|plot_circular\(|matplotlib",
    "xarray": r"\.to_xarray\(",
    "control": r"\bimport control\b|\.statespace\(|\.to_timeresponse\(",
    "dask": r"\bdask\b|executor=",
}


def _python_snippets(text: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)


def test_readme_install_line_has_every_extra_the_walkthrough_needs() -> None:
    extras = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    docs = "\n".join(_python_snippets((REPO / "docs" / "python.md").read_text()))
    needed = {extra for extra, pattern in NEEDS.items() if re.search(pattern, docs)}
    assert needed == set(NEEDS)  # the walk-through uses every extra but `test`
    assert needed <= set(extras)
    readme = (REPO / "README.md").read_text()
    lines = re.findall(r"python -m pip install '\.\[([a-z,]+)\]'", readme)
    assert len(lines) >= 2  # the opening paragraph's and "From Python"'s
    for line in lines:
        assert needed <= set(line.split(",")), line
    docs_text = (REPO / "docs" / "python.md").read_text()
    assert "python -m pip install '.[" + ",".join(NEEDS) + "]'" in docs_text


@pytest.mark.parametrize("doc", ["README.md", "docs/python.md"])
def test_dask_snippets_are_guarded(doc: str) -> None:
    snippets = [s for s in _python_snippets((REPO / doc).read_text()) if re.search(NEEDS["dask"], s)]
    assert snippets, doc
    for s in snippets:
        lines = s.splitlines()
        guard = next(i for i, line in enumerate(lines) if line.startswith('if __name__ == "__main__":'))
        # Everything that starts processes or hands work to Dask runs under the guard.
        for i, line in enumerate(lines):
            if re.search(r"LocalCluster\(|executor=", line):
                assert i > guard and line.startswith((" ", "\t")), (doc, line)

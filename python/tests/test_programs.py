"""Part programs from Python (docs/programs.md): the planner against the ``ruckig`` package
(time-optimal jerk-limited durations), ``Run.path`` against the CLI's ``path.csv``, the
circular test's plot, and programs that cannot run."""

from __future__ import annotations

import csv
import random
from pathlib import Path

import numpy as np
import pytest

import ringsync

# The oracle: the ruckig package (scripts/check installs it with the test tools).
import ruckig  # noqa: E402


def one_axis(v: float, a: float, j: float, program: str) -> ringsync.Scenario:
    return ringsync.load(
        {
            "ring": {"slaves": 1},
            "control": {"law": "pd"},
            "trajectory": {"kind": "program", "program": program},
            "machine": {"axes": {"X": {"drives": [1], "v_max": v, "a_max": a, "j_max": j}}},
        }
    )


def ruckig_duration(d: float, v: float, a: float, j: float) -> float:
    otg = ruckig.Ruckig(1)
    inp = ruckig.InputParameter(1)
    inp.current_position = [0.0]
    inp.target_position = [d]
    inp.max_velocity = [v]
    inp.max_acceleration = [a]
    inp.max_jerk = [j]
    traj = ruckig.Trajectory(1)
    result = otg.calculate(inp, traj)
    assert result in (ruckig.Result.Working, ruckig.Result.Finished), result
    return float(traj.duration)


def test_rest_to_rest_moves_take_ruckigs_time_optimal_duration(tmp_path: Path) -> None:
    """100 random single-axis moves from rest to rest (lines by G1 with a feed above the
    axis's limit, and rapids by G0; short ones that never reach v or a, long ones that
    cruise): the planned duration is the time-optimal jerk-limited one the ruckig package
    computes, to 1e-6 relative."""
    rng = random.Random(2015)
    worst = 0.0
    for k in range(100):
        d = rng.choice([-1, 1]) * 10 ** rng.uniform(-2, 2.5)  # 0.01 .. 316 mm
        v = 10 ** rng.uniform(0.5, 2.5)  # 3 .. 316 mm/s
        a = 10 ** rng.uniform(2, 4)  # 100 .. 10 000 mm/s²
        j = 10 ** rng.uniform(3, 5.5)  # 1e3 .. 3e5 mm/s³
        word = "G0" if k % 2 else f"G1 F{v * 60 * 10:.6f}"
        prog = tmp_path / f"move{k}.ngc"
        prog.write_text(f"{word} X{d:.6f}\nM2\n")
        d = float(f"{d:.6f}")
        planned = ringsync.plan_program(one_axis(v, a, j, str(prog)))["duration_s"]
        want = ruckig_duration(d, v, a, j)
        rel = abs(planned - want) / want
        worst = max(worst, rel)
        assert rel <= 1e-6, (k, d, v, a, j, planned, want)
    assert worst < 1e-6


def test_run_path_is_the_clis_path_csv(cli, tmp_path: Path) -> None:
    """``Run.path`` holds what ``ringsync sim`` writes to path.csv, and its metrics are
    summary.json's."""
    r = ringsync.simulate("circle-xy", duration="3s")
    out = tmp_path / "run"
    cli.run("sim", "circle-xy", "--set", "duration=\"3s\"", "--out", str(out))
    with open(out / "path.csv", newline="") as f:
        rows = list(csv.reader(f))
    assert rows[0] == r.path.columns == ["time_s", "X", "X_d", "Y", "Y_d", "contour_error"]
    table = np.array(rows[1:], dtype=float)
    assert table.shape == (len(r.path.time), 6)
    for i, col in enumerate(r.path.columns):
        decimals = 9 if col == "contour_error" else 6
        np.testing.assert_allclose(table[:, i], r.path[col], atol=0.6 * 10**-decimals, rtol=0)
    summary = r.summary
    assert summary["contour_rmse"] == r.path.metrics["contour_rmse"]
    assert summary["contour_max"] == r.path.metrics["contour_max"]
    assert r.metrics["track_rmse"] == summary["track_rmse"]
    with pytest.raises(KeyError, match="Z"):
        r.path["Z"]


def test_circular_test_and_its_plot() -> None:
    import matplotlib

    matplotlib.use("Agg")
    r = ringsync.simulate("circle-xy")
    assert [c["direction"] for c in r.path.circles] == ["ccw", "cw"]
    c = r.path.circles[0]
    assert c["radius"] == 50.0
    assert c["radial_deviation_min"] <= c["radius_error"] <= c["radial_deviation_max"]
    assert 0 < c["circular_deviation"] < 0.1
    ax = r.path.plot_circular(1)
    assert ax.name == "polar"
    with pytest.raises(IndexError, match="2 circular test"):
        r.path.plot_circular(2)
    assert r.path.plot().get_xlabel() == "X [mm]"
    # Not a program: no path.
    assert ringsync.simulate("paper-2015", duration="0.1s").path is None


def test_bad_programs_are_scenario_errors(tmp_path: Path) -> None:
    prog = tmp_path / "bad.ngc"
    prog.write_text("G1 X1 F100\nG2 X5 Y0 R1\n")
    with pytest.raises(ringsync.ScenarioError, match=r"bad.ngc: line 2, column 10: R1: a radius of 1.0000 mm cannot reach"):
        ringsync.load("circle-xy").set(**{"trajectory.program": str(prog)})
    with pytest.raises(ringsync.ScenarioError, match="not a part program"):
        ringsync.plan_program("paper-2015")


def test_trace_parquet_holds_the_programs_columns(cli, tmp_path: Path) -> None:
    """A program's trace.parquet adds each axis's position through its lead and the cycle's
    contour error, equal to Run.path's (exactly) and to path.csv's (to its 9 decimals)."""
    import pandas as pd
    import pyarrow.parquet as pq

    out = tmp_path / "run"
    cli.run("sim", "circle-xy", "--set", 'duration="3s"', "--out", str(out), "--outputs", "all,parquet")
    df = pd.read_parquet(out / "trace.parquet")
    assert list(df.columns[-3:]) == ["x_mm", "x_d_mm", "contour_error_mm"]
    meta = pq.read_metadata(out / "trace.parquet").metadata
    assert b"axis 1 drives X (10.000000 mm/rev)" in meta[b"ringsync.machine"]
    r = ringsync.simulate("circle-xy", duration="3s")
    x = df[df["axis"] == 1]
    y = df[df["axis"] == 2]
    n = min(len(x), len(r.path.time))
    np.testing.assert_array_equal(x["contour_error_mm"].to_numpy()[:n], r.path.contour_error[:n])
    np.testing.assert_allclose(x["x_mm"].to_numpy()[:n], r.path["X"][:n], rtol=0, atol=1e-12)
    np.testing.assert_allclose(y["x_d_mm"].to_numpy()[:n], r.path["Y_d"][:n], rtol=0, atol=1e-12)
    table = np.loadtxt(out / "path.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(x["contour_error_mm"].to_numpy()[:n], table[:n, -1], rtol=0, atol=6e-10)


def test_the_contour_law_runs_from_python_as_on_the_cli() -> None:
    """``control.law = "ccc"`` from Python: the same law, the same contour error as the CLI's
    sweep (docs/control.md, "Cross-coupled contour control"), and less than PD's."""
    import ringsync

    pd = ringsync.simulate("circle-xy", **{"control.law": "pd"})
    ccc = ringsync.simulate("circle-xy", **{"control.law": "ccc"})
    assert ccc.summary["controller"] == "ccc"
    assert ccc.path.metrics["contour_rmse"] < 0.5 * pd.path.metrics["contour_rmse"]

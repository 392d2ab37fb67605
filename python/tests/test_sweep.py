"""Sweeps: rows equal single runs, means equal the rows' means, the table as pandas."""

from __future__ import annotations

import math

import pytest

import ringsync


def test_rows_equal_single_simulate_calls() -> None:
    grid = {"faults.loss": [0.0, 0.05], "control.estimator": ["hold", "paper"]}
    sw = ringsync.sweep("paper-2015", grid, seeds=2, duration="0.5s")
    assert len(sw.rows) == 2 * 2 * 2 and len(sw.mean_rows) == 4
    assert [(r["faults.loss"], r["control.estimator"], r["seed"]) for r in sw.rows[:3]] == [
        (0.0, "hold", 1), (0.0, "hold", 2), (0.0, "paper", 1)]
    for row in sw.rows:
        one = ringsync.simulate(
            "paper-2015", seed=row["seed"], duration="0.5s",
            **{"faults.loss": row["faults.loss"], "control.estimator": row["control.estimator"]},
        )
        m = one.metrics
        assert (row["track_rmse"], row["sync_rmse"]) == (m["track_rmse"], m["sync_rmse"])
        assert row["lumped_lost"] == m["lumped_lost"] and row["retries"] == m["retries"]
        assert row["group_stop_reason"] == m["group_stop_reason"]
    for mean in sw.mean_rows:
        mine = [r["sync_rmse"] for r in sw.rows
                if (r["faults.loss"], r["control.estimator"]) == (mean["faults.loss"], mean["control.estimator"])]
        assert mean["runs"] == len(mine) == 2
        assert math.isclose(mean["sync_rmse"], sum(mine) / 2, rel_tol=1e-15)


def test_the_same_on_one_thread_or_many() -> None:
    grid = {"control.alpha": [0.25, 0.5, 0.75]}
    a = ringsync.sweep("paper-2015", grid, seeds=2, jobs=1, duration="0.3s")
    b = ringsync.sweep("paper-2015", grid, seeds=2, jobs=3, duration="0.3s")
    assert a.rows == b.rows and a.jobs == 1 and b.jobs == 3
    # The threads used, not those asked for: never more than the runs.
    c = ringsync.sweep("paper-2015", {}, seeds=2, jobs=8, duration="0.1s")
    assert c.jobs == 2


def test_stops_are_named_and_to_pandas_has_one_row_per_run() -> None:
    pd = pytest.importorskip("pandas")
    sw = ringsync.sweep(
        {"duration": "0.5s", "faults.silent_from": "200ms"},
        {"faults.silent_slave": [0, 2]}, seeds=1,
    )
    df = sw.to_pandas()
    assert isinstance(df, pd.DataFrame)
    assert list(df.columns[:4]) == ["faults.silent_slave", "seed", "track_rmse", "sync_rmse"]
    assert "group_stop_reason" in df.columns and len(df) == 2
    assert pd.isna(df["group_stop_reason"].iloc[0]) and not pd.isna(df["group_stop_reason"].iloc[1])
    assert sw.rows[0]["group_stop_reason"] is None
    assert sw.stopped == 1
    means = sw.means()
    assert list(means["faults.silent_slave"]) == [0, 2] and list(means["runs"]) == [1, 1]


def test_bad_grids_are_errors() -> None:
    with pytest.raises(ringsync.ScenarioError, match="faults.lost"):
        ringsync.sweep("paper-2015", {"faults.lost": [0.1]}, seeds=1)
    with pytest.raises(ringsync.ScenarioError, match="faults.loss = 2"):
        ringsync.sweep("paper-2015", {"faults.loss": [0.0, 2.0]}, seeds=1)
    with pytest.raises(ValueError, match="seeds"):
        ringsync.sweep("paper-2015", {"faults.loss": [0.0]}, seeds=0)
    with pytest.raises(ValueError, match="no values"):
        ringsync.sweep("paper-2015", {"faults.loss": []}, seeds=1)


def test_seeds_take_numpy_integers_and_say_their_range() -> None:
    np = pytest.importorskip("numpy")
    sw = ringsync.sweep("paper-2015", {"control.alpha": [0.25]}, seeds=np.int64(2), duration="0.1s")
    assert sw.seeds == 2 and type(sw.seeds) is int and [r["seed"] for r in sw.rows] == [1, 2]
    for bad in (0, -1, 10_001, 2**64, True, 1.0, np.bool_(True)):
        with pytest.raises(ringsync.ScenarioError, match=r"^seeds = .*allowed a whole number 1 \.\.= 10000"):
            ringsync.sweep("paper-2015", {"control.alpha": [0.25]}, seeds=bad)
    # reproduce's seeds alike, with its own cap (ringsync reproduce --seeds).
    with pytest.raises(ringsync.ScenarioError, match=r"^seeds = 10001 .*1 \.\.= 10000"):
        ringsync.reproduce(seeds=10_001)


def test_a_grid_that_is_not_a_dict_is_a_type_error_naming_the_grid() -> None:
    for grid in (None, [("control.alpha", [0.1])], "control.alpha"):
        with pytest.raises(TypeError, match="grid must be a dict of scenario key → list of values"):
            ringsync.sweep("paper-2015", grid, seeds=1)  # type: ignore[arg-type]
    with pytest.raises(ringsync.ScenarioError, match="1 is not a scenario key"):
        ringsync.sweep("paper-2015", {1: [0.1]}, seeds=1)  # type: ignore[dict-item]


def test_a_grid_that_would_mislabel_its_rows_is_refused() -> None:
    """A key and a key inside it, or ``seed`` as a key: refused before anything runs."""
    with pytest.raises(ringsync.ScenarioError, match="overlap"):
        ringsync.sweep(
            "paper-2015",
            {"control.alpha": [0.1], "control": [{"alpha": 0.2}]},
            seeds=1,
            duration="0.1s",
        )
    with pytest.raises(ringsync.ScenarioError, match="seed is not a key to sweep"):
        ringsync.sweep("paper-2015", {"seed": [5, 9]}, seeds=2, duration="0.1s")
    with pytest.raises(ringsync.ScenarioError, match="go beyond"):
        ringsync.sweep(
            ringsync.load("paper-2015").set("seed", 2**63 - 1), {}, seeds=3, duration="0.1s"
        )


def test_progress_line_in_process(capsys: pytest.CaptureFixture[str]) -> None:
    ringsync.sweep("paper-2015", {"control.alpha": [0.3, 0.4]}, seeds=3, duration="0.2s",
                   progress=True)
    err = capsys.readouterr().err
    assert err.endswith("\rringsync sweep: 6/6 runs\n"), repr(err)
    ringsync.sweep("paper-2015", {"control.alpha": [0.3]}, seeds=2, duration="0.2s")
    assert capsys.readouterr().err == ""


def test_saturated_cycles_show_where_gains_drive_the_axes_bang_bang() -> None:
    sw = ringsync.sweep("paper-2015", {"control.kp": [340.0, 1e8]}, seeds=1, duration="0.5s")
    low, high = sw.rows
    for row in sw.rows:
        one = ringsync.simulate("paper-2015", seed=row["seed"], duration="0.5s",
                                **{"control.kp": row["control.kp"]})
        assert row["saturated_cycles"] == max(one.metrics["saturations"])
        assert row["peak_u"] == max(one.metrics["peak_u"])
    assert low["saturated_cycles"] == 0 and low["peak_u"] < 10.0
    assert high["saturated_cycles"] > 400 and high["peak_u"] == 10.0

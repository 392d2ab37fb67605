"""The loop matrix and python-control's StateSpace against the check's spectral radius; the
plan against `ringsync plan --json`; Table 1 against `ringsync reproduce`; the plots
(Agg backend) and xarray."""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib
import numpy as np
import pytest

import ringsync

from conftest import Cli

matplotlib.use("Agg")


@pytest.mark.parametrize(
    "overrides",
    [{}, {"control.law": "pd"}, {"ring.slaves": 2}, {"control.kp": 3000.0}, {"control.estimator": "hold"}],
    ids=["reference", "pd", "2-axes", "unstable", "hold"],
)
def test_statespace_poles_give_the_spectral_radius(overrides: dict[str, object]) -> None:
    c = ringsync.check("paper-2015", **overrides)
    assert c.matrix is not None and c.spectral_radius is not None
    n = ringsync.load("paper-2015").set(**overrides).axes
    assert c.matrix.shape == (9 * n, 9 * n)
    # numpy's eigenvalues against the Rust check's own solver.
    rho = max(abs(np.linalg.eigvals(c.matrix)))
    assert rho == pytest.approx(c.spectral_radius, rel=1e-9)
    # And against what the state-space system does when stepped: power iteration on
    # python-control's A from a random state grows (or decays) per cycle by ρ.
    sys = c.statespace()
    assert sys.dt == c.t_cyc == 1e-3
    assert (sys.ninputs, sys.noutputs, sys.nstates) == (n, n, 9 * n)
    assert per_cycle_growth(np.asarray(sys.A)) == pytest.approx(c.spectral_radius, abs=3e-3)
    assert (per_cycle_growth(np.asarray(sys.A)) < 1) == c.stable
    assert not sys.B.any() and not sys.D.any()  # regulation to a fixed final position


def per_cycle_growth(a: np.ndarray, steps: int = 6000) -> float:
    """The mean growth of ‖Aᵏ·x₀‖ per step over the last third of ``steps`` steps from a
    random x₀: the spectral radius, found without an eigenvalue solver."""
    x = np.random.default_rng(1).standard_normal(a.shape[0])
    logs = []
    for _ in range(steps):
        x = a @ x
        s = float(np.linalg.norm(x))
        logs.append(np.log(s))
        x /= s
    return float(np.exp(np.mean(logs[-steps // 3 :])))


def test_statespace_decays_like_the_spectral_radius() -> None:
    import control

    c = ringsync.check("paper-2015")
    sys = c.statespace()
    x0 = np.zeros(sys.nstates)
    x0[0::9] = 0.05  # every axis 0.05 rad off
    r = control.initial_response(sys, T=np.arange(0, 4.0, c.t_cyc), X0=x0, return_x=True)
    states = np.asarray(r.states)
    # From 2 s on the slowest mode (the common mode every axis starts in) dominates: the
    # state shrinks by ρ per cycle, ρ^1999 over the last 1999 cycles.
    ratio = np.linalg.norm(states[:, -1]) / np.linalg.norm(states[:, 2000])
    assert ratio == pytest.approx(c.spectral_radius ** 1999, rel=0.02)


def test_a_loop_the_check_does_not_model_has_no_matrix() -> None:
    c = ringsync.check("paper-2015", **{"ring.plan": "lumped-only", "control.velocity": "observer"})
    assert c.matrix is None and c.spectral_radius is None
    with pytest.raises(ValueError, match="does not model the loop"):
        c.statespace()


def test_the_lumped_only_loop_has_its_own_states() -> None:
    c = ringsync.check("paper-2015", **{"ring.plan": "lumped-only"})
    assert c.report["plan"] == "lumped-only" and c.stable
    sys = c.statespace()
    assert sys.nstates == 4 * 11
    assert sys.state_labels[:11] == ["x[1]", "v[1]", "u_prev[1]", "e1[1]", "e2[1]", "e3[1]",
                                     "e4[1]", "de1[1]", "de2[1]", "de3[1]", "de4[1]"]
    assert per_cycle_growth(np.asarray(sys.A)) == pytest.approx(c.spectral_radius, abs=3e-3)
    # The same gains and law on the proposed plan give another loop.
    assert c.spectral_radius != ringsync.check("paper-2015").spectral_radius


@pytest.mark.parametrize(
    "args,overrides",
    [([], {}), (["--slaves", "8", "--cycle", "500us"], {"ring.slaves": 8, "ring.cycle": "500us"}),
     (["--bit-rate", "1G", "--t-rest", "20us"], {"ring.bit_rate": "1G", "ring.t_rest": "20us"})],
)
def test_plan_terms_equal_the_cli(cli: Cli, args: list[str], overrides: dict[str, object]) -> None:
    mine = ringsync.plan(None, **overrides)
    theirs = json.loads(cli.run("plan", "--json", *args).stdout)
    assert mine.to_dict() == theirs
    segs = mine.segments()
    assert sum(s[3] for s in segs) == theirs["t_cyc_ns"]
    assert sum(s[3] for s in segs if s[0] != "idle") == theirs["min_t_cyc_ns"]


def test_plan_error_names_the_problem() -> None:
    with pytest.raises(ringsync.ScenarioError, match="short by"):
        ringsync.plan(None, **{"ring.slaves": 64, "ring.cycle": "100us"})


def test_reproduce_equals_the_cli(cli: Cli, tmp_path: Path) -> None:
    cli.run("reproduce", "--seeds", "2", "--out", str(tmp_path / "r"))
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    theirs = summary["cases"]
    r = ringsync.reproduce(seeds=2)
    assert r.summary == summary, "the same object as the CLI's summary.json"
    assert r.verdicts["plan Sync-RMSE"] == summary["claims"][2]["verdict"]
    assert len(theirs) == 6
    for row in theirs:  # the CLI's rows: every seed's values beside the means
        mine = [x for x in r.rows if (x["plan"], x["controller"]) == (row["plan"], row["controller"])]
        assert [x["seed"] for x in mine] == row["seed_values"] == [1, 2]
        assert [x["track_rmse"] for x in mine] == row["track_rmse_per_seed"]
        assert [x["sync_rmse"] for x in mine] == row["sync_rmse_per_seed"]
    assert [row["seed"] for row in r.rows] == [1] * 6 + [2] * 6
    assert len(r.to_pandas()) == 12


def test_plots_return_figures() -> None:
    from matplotlib.figure import Figure

    run = ringsync.simulate("paper-2015", duration="0.3s")
    fig = run.plot()
    assert isinstance(fig, Figure) and len(fig.axes) == 3
    assert len(fig.axes[0].lines) == run.axes
    np.testing.assert_array_equal(fig.axes[1].lines[2].get_ydata(), run.eps[:, 2])
    sw = ringsync.sweep("paper-2015", {"control.law": ["pd", "sync"], "faults.loss": [0.0, 0.05]},
                        seeds=2, duration="0.3s")
    fig2 = sw.plot("track_rmse")
    assert isinstance(fig2, Figure) and len(fig2.axes[0].containers) == 2  # one line per loss
    with pytest.raises(ValueError, match="no column 'nope'"):
        sw.plot("nope")
    # An empty grid: the scenario alone over its seeds, each seed's value and the mean.
    seeds = ringsync.sweep("paper-2015", {}, seeds=3, duration="0.3s")
    fig4 = seeds.plot()
    line, mean = fig4.axes[0].lines
    assert list(line.get_xdata()) == [1, 2, 3]
    assert list(line.get_ydata()) == [r["sync_rmse"] for r in seeds.rows]
    assert mean.get_ydata()[0] == pytest.approx(seeds.mean_rows[0]["sync_rmse"])
    fig3 = ringsync.plan().plot(zoom=True)
    assert isinstance(fig3, Figure)
    import matplotlib.pyplot as plt

    plt.close("all")


def test_to_xarray() -> None:
    run = ringsync.simulate("paper-2015", duration="0.3s", **{"ring.slaves": 3})
    ds = run.to_xarray()
    assert dict(ds.sizes) == {"time": 300, "axis": 3}
    np.testing.assert_array_equal(ds["u"].values, run.u)
    np.testing.assert_array_equal(ds["time"].values, run.time)
    assert ds["clock_error_ns"].attrs["units"] == "ns"
    assert ds.attrs["track_rmse"] == run.metrics["track_rmse"]


def test_statespace_with_observers_names_their_states() -> None:
    """The error observer adds two states per axis, the disturbance observer three: the
    state-space system picks each axis's position at its own offset and names them."""
    c = ringsync.check("paper-2015", **{"control.velocity": "observer", "control.kh": 0.016,
                                        "control.dob_bandwidth": 20.0})
    sys = c.statespace()
    assert sys.nstates == 4 * 14 and c.matrix.shape == (56, 56)
    assert sys.state_labels[:14][-5:] == ["e_hat[1]", "de_hat[1]", "u_prev2[1]", "u_prev3[1]", "d_hat[1]"]
    assert sys.C[1, 14] == 1.0 and sys.C[1].sum() == 1.0
    assert np.isclose(max(abs(sys.poles())), c.spectral_radius, rtol=1e-9)


def test_check_points_are_a_bounded_whole_number() -> None:
    import time

    # 10**12 ran for ever (and ignored Ctrl-C); 0 became 1; -1 was an OverflowError.
    for bad in (10**12, 1_000_001, 0, -1, 2**64, True, 4001.0):
        t0 = time.monotonic()
        with pytest.raises(ringsync.ScenarioError, match=r"^points = .*allowed a whole number 1 \.\.= 1000000"):
            ringsync.check("paper-2015", points=bad)
        assert time.monotonic() - t0 < 5.0
    few = ringsync.check("paper-2015", points=np.int32(11))
    assert few.report == ringsync.check("paper-2015", points=11).report
    assert ringsync.check("paper-2015", points=1).stable


def test_the_clock_metric_counts_the_second_half_the_array_every_cycle() -> None:
    # With a group stop too: the half is of the cycles planned (metrics["cycles"]).
    for run in (ringsync.simulate("paper-2015", duration="1s"),
                ringsync.simulate('duration = "0.5s"\n[faults]\nsilent_slave = 3\nsilent_from = "400ms"\n')):
        m = run.metrics
        settled = run.clock_error_ns[(m["cycles"] + 1) // 2:]
        assert float(np.abs(settled).max()) == m["clock_error_max_ns"]
        rms = np.sqrt(np.mean(run.clock_error_ns[(m["cycles"] + 1) // 2:m["cycles"]] ** 2, axis=0))
        assert rms == pytest.approx(m["clock_error_rms_ns"], rel=1e-9) or run.stopped
    whole = ringsync.simulate("paper-2015", duration="1s")
    # The start-up (clocks not yet synchronised) is in the array, not in the metric.
    assert float(np.abs(whole.clock_error_ns).max()) > 10 * whole.metrics["clock_error_max_ns"]
    assert "second half" in (ringsync.Run.__doc__ or "")


def test_save_refuses_an_empty_path_and_a_foreign_directory_in_plain_words(tmp_path: Path) -> None:
    run = ringsync.simulate("paper-2015", duration="0.1s")
    with pytest.raises(ringsync.ScenarioError, match=r"^directory = '' is empty: give Run.save the path"):
        run.save("")
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep me")
    with pytest.raises(ringsync.ScenarioError) as e:
        run.save(mine)
    msg = str(e.value)
    assert msg.startswith(f"the save directory {mine} is not empty and holds no ringsync results")
    assert "the run replaces the save directory as a whole" in msg and "save:" not in msg
    assert [p.name for p in mine.iterdir()] == ["notes.txt"]
    assert run.save(tmp_path / "new") == str(tmp_path / "new")


def test_plot_arguments_are_checked() -> None:
    import matplotlib.pyplot as plt

    sw = ringsync.sweep("paper-2015", {"control.law": ["pd", "sync"]}, seeds=1, duration="0.1s")
    for column in ("group_stop_reason", "group_stop_s", "control.law"):
        with pytest.raises(ValueError, match=f"Sweep.plot\\(\\): column '{column}' is"):
            sw.plot(column)
    with pytest.raises(TypeError, match="Sweep.plot\\(\\): ax must be a matplotlib Axes, not int"):
        sw.plot(ax=5)
    with pytest.raises(TypeError, match="Plan.plot\\(\\): ax must be a matplotlib Axes, not int"):
        ringsync.plan().plot(ax=5)
    run = ringsync.simulate("paper-2015", duration="0.1s")
    with pytest.raises(TypeError, match="Run.plot\\(\\): fig must be a matplotlib Figure, not int"):
        run.plot(fig=5)
    fig, ax = plt.subplots()
    assert sw.plot("seed", ax=ax) is fig and ringsync.plan().plot(ax=ax) is fig
    assert run.plot(fig=plt.figure()) is not None
    plt.close("all")


def test_a_run_pickles_by_its_scenario_and_seed() -> None:
    """A pickled run comes back simulated again: the same arrays and figures to the bit."""
    import copy
    import pickle

    r = ringsync.simulate("paper-2015", seed=11, duration="0.2s", **{"control.alpha": 0.3})
    for back in (pickle.loads(pickle.dumps(r)), copy.deepcopy(r)):
        assert back.seed == 11 and back.metrics == r.metrics
        assert back.scenario.to_toml() == r.scenario.to_toml()
        assert np.array_equal(back.x, r.x) and np.array_equal(back.u, r.u)

"""Same scenario and seed: the same numbers as the `ringsync` command, to the last bit."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

import ringsync


def test_summary_and_metrics_equal_the_clis_summary_json(cli, tmp_path: Path) -> None:
    cli_summary = cli.sim_summary("paper-2015", tmp_path / "cli", "--seed", "3")
    r = ringsync.simulate("paper-2015", seed=3)
    assert r.seed == 3
    assert r.summary == cli_summary  # every number, bit for bit (floats compare exactly)
    m = r.metrics
    # The metrics come from the run itself, not through JSON: still the same bits.
    assert m["track_rmse"] == cli_summary["track_rmse"]
    assert m["sync_rmse"] == cli_summary["sync_rmse"]
    assert m["cycles"] == cli_summary["cycles"]
    assert m["clock_error_max_ns"] == cli_summary["clock_error_max_ns"]
    for i, axis in enumerate(cli_summary["axes"]):
        for key in ("rms_e", "max_e", "rms_eps", "max_eps", "rms_u", "peak_u", "saturations"):
            assert m[key][i] == axis[key], key
    assert m["frames_sent"] == cli_summary["frames"]["sent_by_master"]
    assert m["group_stop_s"] is None and cli_summary["faults"]["group_stop"] is None


def test_saved_files_equal_the_clis_byte_for_byte(cli, tmp_path: Path) -> None:
    cli.run("sim", "paper-2015", "--out", str(tmp_path / "cli"), "--seed", "2")
    r = ringsync.simulate("paper-2015", seed=2)
    r.save(tmp_path / "py")
    for name in ("scenario.toml", "summary.json", "trace.csv", "report.html"):
        assert (tmp_path / "py" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), name
    # What Run.save() writes is a run `ringsync identify` reads (issue 41: it wrote no
    # scenario.toml, so identify could not).
    cli.run("identify", str(tmp_path / "py"), "--out", str(tmp_path / "id.toml"))
    assert "kh" in (tmp_path / "id.toml").read_text()


def test_a_changed_scenario_runs_the_same_from_its_text(cli, tmp_path: Path) -> None:
    s = ringsync.load("paper-2015").set(
        **{"duration": "1s", "control.alpha": 0.3, "faults.loss": 0.02, "ring.jitter": "50ns"}
    )
    f = tmp_path / "changed.toml"
    f.write_text(s.to_toml())
    cli_summary = cli.sim_summary(str(f), tmp_path / "cli")
    r = ringsync.simulate(s)
    assert r.summary == cli_summary
    assert r.summary["scenario_hash"] == s.hash
    assert r.metrics["frames_lost"] > 0  # the loss took effect


def test_a_group_stop_is_reported_as_the_cli_reports_it(cli, tmp_path: Path) -> None:
    text = 'duration = "0.5s"\n[faults]\nsilent_slave = 3\nsilent_from = "200ms"\n'
    f = tmp_path / "silent.toml"
    f.write_text(text)
    p = cli.run("sim", str(f), "--out", str(tmp_path / "cli"))
    assert p.returncode == 3
    cli_summary = json.loads((tmp_path / "cli" / "summary.json").read_text())
    r = ringsync.simulate(text)
    assert r.stopped
    assert r.summary["faults"] == cli_summary["faults"]
    stop = cli_summary["faults"]["group_stop"]
    assert (r.metrics["group_stop_s"], r.metrics["group_stop_reason"]) == (stop["time_s"], stop["reason"])


def test_arrays_reproduce_the_summarys_rmses() -> None:
    """Eq. 26-27 (docs/control.md, "Metrics"): the sum over the axes inside the root, N the
    number of samples (one per cycle, at the cycle start)."""
    for scenario in ("paper-2015", "arm-2link"):
        r = ringsync.simulate(scenario)
        n = r.metrics["samples"]
        assert r.e.shape == (n, r.axes) == r.eps.shape
        track = math.sqrt(float(np.sum(r.e**2)) / n)
        sync = math.sqrt(float(np.sum(r.eps**2)) / n)
        assert math.isclose(track, r.summary["track_rmse"], rel_tol=1e-12, abs_tol=0.0)
        assert math.isclose(sync, r.summary["sync_rmse"], rel_tol=1e-12, abs_tol=0.0)
        # Per axis too, and e is x_d − x exactly.
        rms_e = np.sqrt(np.mean(r.e**2, axis=0))
        assert np.allclose(rms_e, [a["rms_e"] for a in r.summary["axes"]], rtol=1e-12, atol=0)
        assert np.array_equal(r.e, r.x_d - r.x)


def test_arrays_match_the_clis_trace_csv(cli, tmp_path: Path) -> None:
    cli.run("sim", "paper-2015", "--out", str(tmp_path / "cli"))
    csv = np.genfromtxt(tmp_path / "cli" / "trace.csv", delimiter=",", names=True)
    r = ringsync.simulate("paper-2015")
    df = r.to_pandas()
    assert len(df) == len(csv)
    assert np.array_equal(df["axis"].to_numpy(), csv["axis"])
    # trace.csv rounds: to 1e-6 s and V, 1e-9 rad.
    assert np.allclose(df["time"], csv["t_s"], atol=5e-7, rtol=0)
    assert np.allclose(df["x"], csv["x_rad"], atol=5e-10, rtol=0)
    assert np.allclose(df["eps"], csv["eps_rad"], atol=5e-10, rtol=0)
    assert np.allclose(df["u"], csv["u_v"], atol=5e-7, rtol=0)
    assert np.allclose(df["apply_time"], csv["apply_time_s"], atol=5e-10, rtol=0, equal_nan=True)


def test_the_clis_parquet_trace_holds_the_runs_exact_values(cli, tmp_path: Path) -> None:
    import pandas as pd  # the test extra; read_parquet needs pyarrow, also in it

    out = tmp_path / "cli"
    cli.run("sim", "paper-2015", "--out", str(out), "--seed", "5", "--outputs", "all,parquet")
    df = pd.read_parquet(out / "trace.parquet")
    csv = pd.read_csv(out / "trace.csv")
    assert list(df.columns) == list(csv.columns)
    assert str(df["axis"].dtype) == "int32" and len(df) == len(csv) == 16000
    # Every value is the run's own double, where the CSV rounds to 6 or 9 decimals.
    r = ringsync.simulate("paper-2015", seed=5)
    mine = r.to_pandas()
    assert np.array_equal(df["t_s"].to_numpy(), mine["time"].to_numpy())
    names = ["x_d", "x", "e", "eps", "u", "sample_time", "apply_time", "clock_error_ns"]
    for col, name in zip(df.columns[2:], names):
        assert np.array_equal(df[col].to_numpy(), mine[name].to_numpy(), equal_nan=True), col
        assert np.allclose(df[col], csv[col], rtol=0, atol=5e-7, equal_nan=True), col


def test_path_delays_the_nodes_measured_come_through_as_the_cli_writes_them(cli, tmp_path: Path) -> None:
    # clock.path_delays = "measured": the nodes' start-up phase before the run. On the
    # reference ring the measured delays are the planner's, so the run is the plan's run.
    cli_summary = cli.sim_summary(
        "paper-2015", tmp_path / "cli", "--set", 'clock.path_delays="measured"'
    )
    r = ringsync.simulate("paper-2015", **{"clock.path_delays": "measured"})
    assert r.summary == cli_summary
    start = r.summary["start_up"]
    assert start["measured_minus_planned_ns"] == [0, 0, 0, 0]
    assert start["taken_by_slaves_ns"] == start["path_delay_ns"]
    assert any("every link of the ring" in a for a in r.summary["assumptions"])
    plan = ringsync.simulate("paper-2015")
    assert "start_up" not in plan.summary
    assert r.metrics["sync_rmse"] == plan.metrics["sync_rmse"]

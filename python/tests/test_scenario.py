"""Loading scenarios every way, reading and setting keys, and the errors."""

from __future__ import annotations

import pickle
from pathlib import Path

import pytest

import ringsync

REPO = Path(__file__).resolve().parents[2]


def test_scenarios_lists_the_built_ins() -> None:
    names = ringsync.scenarios()
    assert "paper-2015" in names and "arm-2link" in names


def test_name_path_text_and_dict_agree() -> None:
    by_name = ringsync.load("paper-2015")
    path = REPO / "scenarios" / "paper-2015.toml"
    by_path = ringsync.load(path)
    by_str_path = ringsync.load(str(path))
    by_text = ringsync.load(path.read_text())
    assert by_name.to_toml() == by_path.to_toml() == by_str_path.to_toml() == by_text.to_toml()
    assert by_name.hash == by_path.hash == by_text.hash
    # A dict: dotted keys, nested tables, or both.
    text = '[ring]\nslaves = 2\n[control]\nalpha = 0.25\nlaw = "pd"\n'
    as_text = ringsync.load(text)
    dotted = ringsync.load({"ring.slaves": 2, "control.alpha": 0.25, "control.law": "pd"})
    nested = ringsync.load({"ring": {"slaves": 2}, "control": {"alpha": 0.25, "law": "pd"}})
    mixed = ringsync.load({"ring": {"slaves": 2}, "control.alpha": 0.25, "control": {"law": "pd"}})
    assert dict(as_text) == dict(dotted) == dict(nested) == dict(mixed)
    assert as_text == dotted  # a Mapping: equal values
    short = {"duration": "0.3s"}
    runs = [ringsync.simulate(s, **short) for s in (as_text, dotted, nested)]
    assert runs[0].metrics == runs[1].metrics == runs[2].metrics
    # And a set() of the same keys on the reference.
    via_set = ringsync.load("paper-2015").set(**{"ring.slaves": 2, "control.alpha": 0.25, "control.law": "pd"})
    assert dict(via_set) == dict(as_text)


def test_values_in_effect_fill_in_the_reference() -> None:
    s = ringsync.load('duration = "1s"\n')
    ref = ringsync.load("paper-2015")
    assert s["duration"] == "1s"
    assert s["control.alpha"] == ref["control.alpha"] == 0.5
    assert s["ring.cycle"] == "1ms"
    assert s["axis[2].rated_torque"] == 1.27
    assert len(s["axis"]) == 4
    assert "control.kp" in s and "control.nope" not in s
    with pytest.raises(KeyError):
        s["control.nope"]
    assert "faults.loss" in list(s)


def test_set_returns_a_new_validated_scenario() -> None:
    s = ringsync.load("paper-2015")
    t = s.set("control.alpha", 0.3)
    assert (s["control.alpha"], t["control.alpha"]) == (0.5, 0.3)
    u = t.set(**{"ring.slaves": 2, "control.estimator": "hold", "clock.sync": False})
    assert (u.axes, u["control.estimator"], u["clock.sync"]) == (2, "hold", False)
    assert u["control.alpha"] == 0.3
    assert "control.alpha=0.3" in u.origin
    assert s.set() is s
    # Lists per axis, numpy values.
    np = pytest.importorskip("numpy")
    v = s.set("control.kp", np.array([3.0, 3.1, 3.2, 3.3]))
    assert v["control.kp"] == [3.0, 3.1, 3.2, 3.3]
    assert s.set("control.alpha", np.float64(0.3))["control.alpha"] == 0.3
    assert s.set("ring.slaves", np.int64(3)).axes == 3
    # Round trip through its text and through pickle.
    assert ringsync.load(u.to_toml()) == u
    assert pickle.loads(pickle.dumps(u)) == u


def test_overrides_change_what_they_should() -> None:
    base = ringsync.simulate("paper-2015", duration="1s")
    assert base.time.shape == (1000,)
    assert ringsync.simulate("paper-2015", duration="1s", seed=1).metrics == base.metrics
    alpha = ringsync.simulate("paper-2015", duration="1s", **{"control.alpha": 0.1})
    assert alpha.metrics["sync_rmse"] != base.metrics["sync_rmse"]
    assert alpha.scenario["control.alpha"] == 0.1
    pd = ringsync.simulate("paper-2015", duration="1s", **{"control.law": "pd"})
    assert pd.summary["controller"] == "pd" and pd.metrics["sync_rmse"] > base.metrics["sync_rmse"]
    two = ringsync.simulate("paper-2015", duration="0.5s", **{"ring.slaves": 2})
    assert two.x.shape == (500, 2)
    lossy = [ringsync.simulate("paper-2015", duration="1s", seed=k, **{"faults.loss": 0.05}) for k in (1, 2)]
    assert all(r.metrics["frames_lost"] > 0 for r in lossy)
    assert lossy[0].metrics["frames_lost"] != lossy[1].metrics["frames_lost"]  # the seed counts
    assert ringsync.load("paper-2015")["control.alpha"] == 0.5  # nothing shared changed


def test_bad_key_bad_value_unknown_name_are_scenario_errors_with_the_clis_message(cli, tmp_path: Path) -> None:
    out = str(tmp_path / "out")
    cases = [
        # (what Python does, the same in the CLI)
        (lambda: ringsync.load("paper-2015").set("control.alpah", 0.3),
         ["sweep", "paper-2015", "--set", "control.alpah=0.3", "--out", out]),
        (lambda: ringsync.simulate("paper-2015", **{"faults.loss": 2}),
         ["sweep", "paper-2015", "--set", "faults.loss=2", "--out", out]),
        (lambda: ringsync.simulate("paper-2015", **{"control.law": "nope"}),
         ["sweep", "paper-2015", "--set", "control.law=nope", "--out", out]),
        (lambda: ringsync.load("paper-2015").set("ring.slaves", 0),
         ["sweep", "paper-2015", "--set", "ring.slaves=0", "--out", out]),
        (lambda: ringsync.load("no-such-scenario"),
         ["sim", "no-such-scenario", "--out", out]),
    ]
    bad_file = tmp_path / "bad.toml"
    bad_file.write_text('[ring]\nslaves = 4\ncycle = "1ms"\nbogus = 1\n')
    cases.append((lambda: ringsync.load(bad_file), ["sim", str(bad_file), "--out", out]))
    cases.append((lambda: ringsync.load(str(bad_file)), ["sim", str(bad_file), "--out", out]))
    out_of_range = tmp_path / "range.toml"
    out_of_range.write_text("[control]\nalpha = -1.0\n")
    cases.append((lambda: ringsync.simulate(out_of_range), ["sim", str(out_of_range), "--out", out]))
    for call, argv in cases:
        with pytest.raises(ringsync.ScenarioError) as e:
            call()
        assert isinstance(e.value, ValueError)
        assert str(e.value) == cli.error(*argv), argv
        assert "\n" not in str(e.value)


def test_other_mistakes_are_plain_python_errors() -> None:
    with pytest.raises(TypeError):
        ringsync.load(42)  # type: ignore[arg-type]
    with pytest.raises(ringsync.ScenarioError, match="not a scenario value"):
        ringsync.load("paper-2015").set("control.alpha", None)
    with pytest.raises(ringsync.ScenarioError, match="both as a value and as a table"):
        ringsync.load({"ring": 1, "ring.slaves": 2})


def test_a_rust_panic_is_an_exception_and_python_goes_on() -> None:
    from ringsync import _ringsync

    with pytest.raises(ringsync.RunError, match="boom"):
        _ringsync._panic("boom")
    assert isinstance(ringsync.RunError("x"), RuntimeError)
    assert ringsync.simulate("paper-2015", duration="0.1s").time.shape == (100,)


def test_a_broken_link_reshapes_the_ring_and_a_second_splits_it() -> None:
    # One break: the run goes on, the summary names the link and what it cost.
    r = ringsync.simulate("paper-2015", duration="1s", **{"faults.break_link": "2@500ms"})
    ring = r.summary["ring"]
    assert r.summary["faults"]["group_stop"] is None
    assert [(c["event"], c["broken_link"], c["cycle"]) for c in ring["changes"]] == [("broken", 2, 500)]
    assert ring["at_end"] == "link 2 broken"
    whole = ringsync.simulate("paper-2015", duration="1s")
    assert "ring" not in whole.summary
    assert abs(r.metrics["sync_rmse"] / whole.metrics["sync_rmse"] - 1) < 0.2
    # Two breaks cut slaves 2 and 3 off both of the master's ports: the group stops.
    split = ringsync.simulate("paper-2015", duration="1s", **{"faults.break_link": ["2@300ms", "4@600ms"]})
    stop = split.summary["faults"]["group_stop"]
    assert stop["reason"] == "ring-split" and stop["isolated_slaves"] == [2, 3]
    with pytest.raises(ringsync.ScenarioError, match="faults.break_link"):
        ringsync.simulate("paper-2015", **{"faults.break_link": "7@1s"})

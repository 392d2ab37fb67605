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


def _nested_list(depth: int) -> list[object]:
    x: list[object] = []
    for _ in range(depth):
        x = [x]
    return x


def _nested_dict(depth: int) -> object:
    x: object = 1
    for _ in range(depth):
        x = {"a": x}
    return x


def test_a_value_nested_too_deep_or_containing_itself_is_a_scenario_error_not_a_crash() -> None:
    import subprocess
    import sys

    # In a child first: before the depth limit, each of these ended the interpreter (SIGSEGV).
    code = (
        "import ringsync\n"
        "a = []; a.append(a)\n"
        "deep = []\n"
        "for _ in range(3000):\n"
        "    deep = [deep]\n"
        "for call in (lambda: ringsync.load({'control.kp': a}),\n"
        "             lambda: ringsync.load({'control.kp': deep})):\n"
        "    try:\n"
        "        call()\n"
        "    except ringsync.ScenarioError as e:\n"
        "        print('refused:', str(e).split(':')[0])\n"
    )
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, (p.returncode, p.stderr[-500:])
    assert p.stdout.splitlines() == ["refused: control.kp", "refused: control.kp"]
    # Every way in names the key the caller gave, in one line.
    a: list[object] = []
    a.append(a)
    d: dict[str, object] = {}
    d["x"] = d
    np = pytest.importorskip("numpy")
    obj = np.empty((), dtype=object)
    obj[()] = obj  # a numpy object array holding itself
    calls = {
        "control.kp": [
            lambda: ringsync.load({"control.kp": a}),
            lambda: ringsync.load("paper-2015").set("control.kp", a),
            lambda: ringsync.load("paper-2015").set("control.kp", _nested_list(20_000)),
            lambda: ringsync.simulate("paper-2015", **{"control.kp": a}),
            lambda: ringsync.sweep("paper-2015", {"control.kp": [a]}, seeds=1),
            lambda: ringsync.load({"control.kp": obj}),
        ],
        "control": [lambda: ringsync.load({"control": d})],
        "a": [lambda: ringsync.load(_nested_dict(3000))],  # type: ignore[arg-type]
    }
    for key, fs in calls.items():
        for f in fs:
            with pytest.raises(ringsync.ScenarioError, match="nested more than 32 levels deep") as e:
                f()
            assert str(e.value).startswith(f"{key}: ") and "\n" not in str(e.value)
    # A few levels are fine (the library then judges the value).
    assert ringsync.load({"axis": [{"u_max": 5.0}] * 4})["axis[3].u_max"] == 5.0


def test_scenario_and_plan_are_read_only_mappings() -> None:
    from collections.abc import Mapping

    s = ringsync.load("paper-2015")
    assert isinstance(s, Mapping)
    with pytest.raises(KeyError):
        s[1]  # type: ignore[index]
    assert s.get(1, "d") == "d"  # type: ignore[call-overload]
    assert s.get("control.nope", "d") == "d" and s.get("control.alpha") == 0.5
    assert 1 not in s
    p = ringsync.plan()
    assert isinstance(p, Mapping)
    keys = list(p)
    assert keys[:2] == ["ringsync_version", "schema_version"], "as plan --json"
    assert keys[2:5] == ["plan", "n", "t_cyc_ns"] and len(p) == len(keys) == len(p.to_dict())
    assert dict(p) == p.to_dict() and list(p.keys()) == keys
    assert p.get("n") == 4 and p.get("nope", 0) == 0 and p.get(1) is None  # type: ignore[call-overload]
    assert dict(p.items())["t_cyc_ns"] == 1_000_000 and "t_syn_ns" in p and "nope" not in p
    with pytest.raises(KeyError):
        p["nope"]


def test_whole_number_arguments_are_checked_and_named() -> None:
    np = pytest.importorskip("numpy")
    seed_range = r"allowed a whole number 0 \.\.= 9223372036854775807 \(2\^63 - 1"
    for bad in (-1, 2**63, 2**64, 10**400):
        with pytest.raises(ringsync.ScenarioError, match=rf"^seed = .* is out of range: {seed_range}"):
            ringsync.simulate("paper-2015", seed=bad)
    for bad in (True, np.bool_(True), 1.5, "3", 2.0):
        with pytest.raises(ringsync.ScenarioError, match=rf"^seed = .*: {seed_range}"):
            ringsync.simulate("paper-2015", seed=bad)  # type: ignore[arg-type]
    assert ringsync.simulate("paper-2015", seed=2**63 - 1, duration="10ms").seed == 2**63 - 1
    r = ringsync.simulate("paper-2015", seed=np.uint64(3), duration="0.1s")
    assert r.seed == 3 and r.metrics == ringsync.simulate("paper-2015", seed=3, duration="0.1s").metrics
    # Any other whole-number argument the same way: ScenarioError (a ValueError), never an
    # OverflowError; numpy integers taken.
    cases = [
        ("jobs", lambda v: ringsync.sweep("paper-2015", {}, seeds=1, jobs=v, duration="10ms")),
        ("seeds", lambda v: ringsync.reproduce(seeds=v, duration="10ms")),
        ("prediction_seeds", lambda v: ringsync.rt("paper-2015", prediction_seeds=v)),
    ]
    for name, call in cases:
        for bad in (-1, 2**64, True, 0.5):
            with pytest.raises(ringsync.ScenarioError, match=rf"^{name} = "):
                call(bad)
    assert ringsync.sweep("paper-2015", {}, seeds=2, jobs=np.int8(2), duration="10ms").jobs == 2
    assert len(ringsync.reproduce(seeds=np.int64(1), duration="10ms").rows) == 6


def test_a_bad_value_in_a_dict_is_named_by_its_dotted_key() -> None:
    """The error of a dict's value names the key as the caller would set it."""
    with pytest.raises(ringsync.ScenarioError, match=r"\(ring\.slaves = \"two\"\)"):
        ringsync.load({"ring.slaves": "two"})
    with pytest.raises(ringsync.ScenarioError, match=r"\(axis\[1\]\.u_max = \"x\"\)"):
        ringsync.load({"axis": [{}, {"u_max": "x"}]})
    # A partial [trajectory] is the reference cosine with what it gives.
    s = ringsync.load({"trajectory.period": "3s"})
    assert s["trajectory.period"] == "3s"
    assert s["trajectory.peak_speed"] == ringsync.load("paper-2015")["trajectory.peak_speed"]


def test_an_indexed_key_in_a_dict_says_how_to_set_it() -> None:
    """``axis[1].u_max`` belongs to ``set`` on a loaded scenario; a dict gives lists whole."""
    with pytest.raises(ringsync.ScenarioError, match=r"axis\[1\]\.u_max: an indexed key"):
        ringsync.load({"axis[1].u_max": 5})
    s = ringsync.load("paper-2015").set("axis[1].u_max", 5)
    assert s["axis[1].u_max"] == 5


def test_a_missing_file_whose_name_holds_an_equals_sign_is_named_as_a_file() -> None:
    """``runs/alpha=0.5.toml`` is a path even with its ``=``: a missing one says so."""
    with pytest.raises(ringsync.ScenarioError, match=r"runs/alpha=0\.5\.toml") as e:
        ringsync.load("runs/alpha=0.5.toml")
    assert "line 1" not in str(e.value), str(e.value)

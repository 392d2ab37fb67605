"""The JSON outputs against the schemas published in docs/schemas/ (generated from the Rust
types that write them): what the CLI writes is what the schema says."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
import pytest

import ringsync

from conftest import Cli

SCHEMAS = Path(__file__).resolve().parents[2] / "docs" / "schemas"


def schema(name: str) -> dict:
    return json.loads((SCHEMAS / name).read_text())


def test_reproduce_summary_meets_its_schema(cli: Cli, tmp_path: Path) -> None:
    cli.run("reproduce", "--seeds", "2", "--out", str(tmp_path / "r"))
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    s = schema("reproduce-summary.json")
    jsonschema.Draft202012Validator.check_schema(s)
    jsonschema.validate(summary, s, cls=jsonschema.Draft202012Validator)
    # The schema is not vacuous: a summary missing its claims, or with a verdict it does
    # not know, is refused.
    broken = {k: v for k, v in summary.items() if k != "claims"}
    with pytest.raises(jsonschema.ValidationError, match="claims"):
        jsonschema.validate(broken, s, cls=jsonschema.Draft202012Validator)
    summary["claims"][0]["verdict"] = "probably"
    with pytest.raises(jsonschema.ValidationError, match="probably"):
        jsonschema.validate(summary, s, cls=jsonschema.Draft202012Validator)


def test_python_reproduce_meets_the_same_schema() -> None:
    r = ringsync.reproduce(seeds=1, duration="0.3s")
    jsonschema.validate(r.summary, schema("reproduce-summary.json"), cls=jsonschema.Draft202012Validator)
    assert r.summary["schema_version"] == 2 and r.summary["ringsync_version"]


@pytest.mark.parametrize(
    "args",
    [
        ["paper-2015", "--set", 'duration="0.3s"'],
        # A group stop, a part program (contour keys), the monitors on.
        ["paper-2015", "--set", 'duration="0.5s"', "--set", "faults.following_error_limit=0.01"],
        ["circle-xy", "--set", 'duration="2s"'],
        [str(Path(__file__).resolve().parents[2] / "examples" / "scenarios" / "weak-axis.toml")],
    ],
    ids=["reference", "group-stop", "program", "monitor"],
)
def test_a_run_summary_meets_its_schema(cli: Cli, tmp_path: Path, args: list[str]) -> None:
    r = cli.run("sim", *args, "--outputs", "summary", "--out", str(tmp_path / "s"), check=False)
    assert r.returncode in (0, 3), r.stderr
    summary = json.loads((tmp_path / "s" / "summary.json").read_text())
    s = schema("run-summary.json")
    jsonschema.Draft202012Validator.check_schema(s)
    jsonschema.validate(summary, s, cls=jsonschema.Draft202012Validator)
    summary["axes"][0]["peak_u"] = "high"
    with pytest.raises(jsonschema.ValidationError, match="high"):
        jsonschema.validate(summary, s, cls=jsonschema.Draft202012Validator)

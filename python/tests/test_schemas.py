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

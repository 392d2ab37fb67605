"""Shared fixtures: the `ringsync` command (the CLI built by cargo) to compare against."""

from __future__ import annotations

import json
import os
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[2]


@dataclass
class Cli:
    """The `ringsync` binary: run it, read what it wrote."""

    path: Path

    def run(self, *args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
        p = subprocess.run(
            [str(self.path), *args], capture_output=True, text=True, timeout=300
        )
        if check and p.returncode not in (0, 3):
            raise AssertionError(f"ringsync {' '.join(args)} failed ({p.returncode}): {p.stderr}")
        return p

    def error(self, *args: str) -> str:
        """The one-line message of a command that fails with bad input (exit status 2),
        without the `ringsync: error: ` prefix."""
        p = self.run(*args, check=False)
        assert p.returncode == 2, (p.returncode, p.stdout, p.stderr)
        prefix = "ringsync: error: "
        assert p.stderr.startswith(prefix), p.stderr
        return p.stderr[len(prefix) :].rstrip("\n")

    def sim_summary(self, scenario: str, out: Path, *args: str) -> dict[str, Any]:
        self.run("sim", scenario, "--out", str(out), *args)
        return json.loads((out / "summary.json").read_text())


def _find_cli() -> Path | None:
    named = os.environ.get("RINGSYNC_CLI")
    if named:
        p = Path(named)
        if not p.is_file():
            raise RuntimeError(f"RINGSYNC_CLI={named} is not a file: build it with cargo build -p ringsync-cli")
        return p
    for target in (os.environ.get("CARGO_TARGET_DIR"), str(REPO / "target")):
        if not target:
            continue
        for profile in ("debug", "release"):
            p = Path(target) / profile / "ringsync"
            if p.is_file():
                return p
    return None


@pytest.fixture(scope="session")
def cli() -> Cli:
    """The CLI: RINGSYNC_CLI, else target/{debug,release}/ringsync (skipped if none)."""
    p = _find_cli()
    if p is None:
        pytest.skip("no ringsync binary: set RINGSYNC_CLI or run cargo build -p ringsync-cli")
    return Cli(p)

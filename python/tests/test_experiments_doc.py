"""docs/experiments.md gives figures with the commands that made them: three of them run
here and must print what the page says (the review found these three stale once)."""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

from conftest import Cli

DOC = (Path(__file__).resolve().parents[2] / "docs" / "experiments.md").read_text()


def test_section_1_clock_sync_table(cli: Cli, tmp_path: Path) -> None:
    cli.run("sweep", "paper-2015", "--set", "clock.sync=true,false", "--set", "control.law=pd,sync",
            "--seeds", "4", "--out", str(tmp_path / "c"))
    with open(tmp_path / "c" / "means.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        on = "on" if r["clock.sync"] == "true" else "off"
        line = (f"| {on} | {r['control.law']} | {float(r['track_rmse_mean']):.5f} | "
                f"{float(r['sync_rmse_mean']):.7f} ± {float(r['sync_rmse_std']):.7f} |")
        assert line in DOC, line


def test_section_4_the_64_axis_ring_is_unstable(cli: Cli, tmp_path: Path) -> None:
    n64 = tmp_path / "n64.toml"
    n64.write_text('[ring]\nslaves = 64\ncycle = "10ms"\n')
    p = cli.run("check", str(n64), "--json", check=False)
    assert p.returncode == 3, p.stderr
    rho = json.loads(p.stdout)["discrete"]["spectral_radius"]
    assert f"**{rho:.3f} (unstable)**" in DOC, rho


def test_section_6_the_pd_run_identify_starts_from(cli: Cli, tmp_path: Path) -> None:
    cli.run("sim", "paper-2015", "--set", "control.law=pd", "--outputs", "summary", "--out", str(tmp_path / "P"))
    s = json.loads((tmp_path / "P" / "summary.json").read_text())
    peak = max(a["peak_u"] for a in s["axes"])
    line = f"| P: standard PD | {s['track_rmse']:.6f} | {s['sync_rmse']:.7f} | {peak:.4f} | – |"
    assert line in DOC, line
    assert re.search(r"ringsync identify P --out id\.toml --dob-bandwidth 0", DOC)

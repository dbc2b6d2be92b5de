"""System test: `lit compare` as a user runs it, through the repository's `./lit` wrapper."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _lit(*args: str, timeout: float = 300.0) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, LIT_SKIP_SETUP="1", ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    return subprocess.run([str(ROOT / "lit"), *args], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=timeout, check=False)


def test_compare_runs_every_planner_on_the_same_seeds(tmp_path: Path) -> None:
    out = tmp_path / "compare.json"
    result = _lit("compare", "--scenarios", "np4", "--planners", "litstar-fixed,aitstar,rrtconnect",
                  "--runs", "2", "--time", "0.1", "--json", str(out))
    assert result.returncode == 0, result.stderr
    assert "| np4 | litstar-fixed |" in result.stdout
    assert "| np4 | aitstar |" in result.stdout
    assert "0 returned paths failed the independent re-check" in result.stdout
    summary = json.loads(out.read_text())
    seeds = {(r["planner"], r["seed"]) for r in summary["records"]}
    assert seeds == {(p, s) for p in ("litstar-fixed", "aitstar", "rrtconnect") for s in (1, 2)}
    for planner in ("litstar-fixed", "aitstar", "rrtconnect"):
        medians = summary["medians"]["np4"][planner]
        assert medians["success"] == 1.0
        assert medians["c_init"] >= medians["c_final"] >= 0.4236


def test_compare_rejects_an_unknown_planner() -> None:
    result = _lit("compare", "--planners", "litstar,nosuchplanner", "--runs", "1")
    assert result.returncode == 2
    assert "nosuchplanner" in result.stderr
    assert "Traceback" not in result.stderr



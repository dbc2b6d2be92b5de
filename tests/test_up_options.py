"""``lit up`` refuses bad options with one line and exit 2 before it starts any process."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--scenario", "foo", "--policy", "tensor"], "--scenario foo: "),
        (["--scenario", "np8/3"], "--scenario np8/3: "),  # training: family and dimension only
        (["--scenario", "zz8"], "--scenario zz8: "),
        (["--time-budget", "-1"], "--time-budget must be 0"),
        (["--time-budget", "nan"], "--time-budget must be 0"),
        (["--episodes", "-1"], "--episodes must be 0"),
        (["--run-id", "../escape"], "--run-id '../escape': use letters"),
        (["--bag", "EXISTING"], "exists already"),
    ],
)
def test_bad_options_start_nothing(tmp_path: Path, options: list[str], message: str) -> None:
    (tmp_path / "bag").mkdir()
    options = [str(tmp_path / "bag") if o == "EXISTING" else o for o in options]
    process = subprocess.run(
        [sys.executable, "-m", "lit_planner.cli", "up", "--domain-id", "1", *options],
        cwd=tmp_path,
        env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST"),
        capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert process.returncode == 2, process.stdout + process.stderr
    assert message in process.stderr and "Traceback" not in process.stderr
    assert "lit up: run" not in process.stdout  # nothing started
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"]  # no runs/ folder either

"""A query on an explicit world, planned by a ``lit up`` system and recorded to its bag, is
re-checked by ``lit replay verify`` against that world: the EpisodeSummary (version 2) carries
it. Real processes: ``lit up`` (recorder, learner, planner), ``lit call``, ``lit replay``."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from lit_planner.testing import DescendantWatch
from ros_helpers import launcher_domain

WORLD = {
    "lower": [0.0, 0.0],
    "upper": [1.0, 1.0],
    "boxes": [{"lower": [0.4, 0.1], "upper": [0.6, 0.9]}],
    "start": [0.1, 0.5],
    "goal": [0.9, 0.5],
}


def _lit(*args: str, env: dict[str, str], cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "lit_planner.cli", *args],
        cwd=cwd, env=env, capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip


def _wait_for(path: Path, text: str, process: subprocess.Popen[bytes], timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        log = path.read_text(encoding="utf-8", errors="replace")
        if text in log:
            return
        if process.poll() is not None:
            raise AssertionError(f"lit up ended ({process.returncode}):\n{log[-3000:]}")
        time.sleep(0.2)
    raise AssertionError(f"{text!r} not in the log of lit up:\n{log[-3000:]}")


def test_a_custom_world_query_is_verified_from_the_bag(tmp_path: Path) -> None:
    domain = launcher_domain()
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ROS_DOMAIN_ID=str(domain))
    bag = tmp_path / "bag"
    log = tmp_path / "up.log"
    (tmp_path / "world.json").write_text(json.dumps(WORLD), encoding="utf-8")
    with log.open("wb") as out:
        up = subprocess.Popen(
            [sys.executable, "-m", "lit_planner.cli", "up", "--policy", "fixed", "--episodes",
             "0", "--bag", str(bag), "--run-id", "world1", "--domain-id", str(domain)],
            cwd=tmp_path, env=env, stdout=out, stderr=subprocess.STDOUT, start_new_session=True,
        )  # fmt: skip
    watch = DescendantWatch(up.pid)
    try:
        # the recorder hears the planner's topics (volatile: a summary sent before is lost)
        _wait_for(log, "subscribers: 1 on every topic", up, timeout=120.0)
        answer = _lit(
            "call", "--wait", "120", "--payload-only", "plan", "--world", "world.json",
            "--time", "0.3", env=env, cwd=tmp_path,
        )  # fmt: skip
        assert answer.returncode == 0, answer.stdout + answer.stderr
        assert json.loads(answer.stdout)["solved"] is True
        up.send_signal(signal.SIGINT)
        assert up.wait(timeout=120) == 0, log.read_text(encoding="utf-8", errors="replace")
        assert len(watch.seen) >= 3 and not watch.alive(), watch.alive()  # every node stopped
    finally:
        watch.kill()  # the nodes: sessions of their own, which killpg of lit up does not reach
        if up.poll() is None:
            os.killpg(up.pid, signal.SIGKILL)
            up.wait()

    verify = _lit("replay", "verify", str(bag), env=env, cwd=tmp_path)
    assert verify.returncode == 0, verify.stdout + verify.stderr
    assert "1 paths checked: 1 valid, 0 invalid" in verify.stdout + verify.stderr

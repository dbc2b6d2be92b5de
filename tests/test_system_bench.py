"""``lit system-bench`` runs end to end on real processes and prints its three tables.

A smoke test with tiny sizes: the numbers themselves are benchmarks, not test assertions.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

from lit_planner.testing import (
    descendants,
    identify,
    kill_identified,
    read_until,
    run_watched,
    still_running,
)
from ros_helpers import launcher_domain


def test_system_bench_prints_all_three_measurements() -> None:
    domain = launcher_domain()
    process = run_watched(
        [
            sys.executable, "-m", "lit_planner.cli", "system-bench", "--episodes", "2",
            "--calls", "30", "--kills", "1", "--budget", "0.2", "--domain-id", str(domain),
        ],
        env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST"),
        timeout=600,
    )  # fmt: skip
    assert process.returncode == 0, process.stdout[-2000:] + process.stderr[-2000:]
    out = process.stdout
    assert "| decide psi_K | 30 |" in out and "| decide B | 30 |" in out
    assert "| echo (baseline) | 30 |" in out
    assert "| training | 2 |" in out and "| tensor | 2 |" in out
    assert "training / tensor wall time per episode" in out
    assert "Decide round trip inside the planner node during this training run" in out
    assert "decisions fell back (no answer within the 50 ms decision timeout)" in out
    assert "kill 1:" in out and "median" in out


def test_parts_switched_off_and_ctrl_c_stops_every_child() -> None:
    """``--episodes 0 --kills 0`` measures only the round trips (0 episodes used to wait for a
    planner that serves forever); Ctrl-C ends the run with 130 and stops every process it began."""
    rejected = run_watched(
        [sys.executable, "-m", "lit_planner.cli", "system-bench", "--episodes", "-1"],
        timeout=60,
    )  # fmt: skip
    assert rejected.returncode == 2 and "must be 0 or more, not -1" in rejected.stderr
    assert not rejected.started, rejected.started
    nothing = run_watched(
        [sys.executable, "-m", "lit_planner.cli", "system-bench", "--episodes", "0", "--calls", "0",
         "--kills", "0"],
        timeout=60,
    )  # fmt: skip
    assert nothing.returncode == 2 and "nothing to measure" in nothing.stderr
    assert not nothing.started, nothing.started
    domain = launcher_domain()
    process = subprocess.Popen(
        [
            sys.executable, "-m", "lit_planner.cli", "system-bench", "--episodes", "0",
            "--kills", "0", "--calls", "100000", "--domain-id", str(domain),
        ],
        env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST"),
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    children: set[tuple[int, int | None]] = set()
    try:
        assert process.stdout is not None
        assert len(read_until(process.stdout, "## Decide round trip")) == 1  # its first line
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:  # learner, echo and the `lit call` client all up
            children = identify(descendants(process.pid))
            if len(children) >= 3:
                break
            time.sleep(0.2)
        time.sleep(1.0)
        children = identify(descendants(process.pid))
        assert len(children) >= 3, children
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=120)
        assert process.returncode == 130, out + err
        assert "lit system-bench: interrupted" in err
        assert "Planning throughput" not in out and "dead learner" not in out
        assert not still_running(children)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
        kill_identified(children)  # by PID, and only the processes seen (a PID may be reused)


# lit system-bench whose recorder is killed (SIGKILL) 2 s after the first planner starts.
_RECORDER_KILLED = """
import sys, threading
from lit_planner import cli, up

original = up.System.start

def start(self, name, *args, **kwargs):
    child = original(self, name, *args, **kwargs)
    if name == "planner":
        threading.Timer(2.0, self.children["recorder"].process.kill).start()
    return child

up.System.start = start
sys.exit(cli.main(sys.argv[1:]))
"""


def test_a_recorder_that_died_is_named_instead_of_a_traceback() -> None:
    """A killed recorder left a bag without its metadata, and lit system-bench ended with a
    traceback from reading it; now it names the recorder's exit and stops the other nodes."""
    domain = launcher_domain()
    process = run_watched(
        [
            sys.executable, "-c", _RECORDER_KILLED, "system-bench", "--episodes", "20",
            "--calls", "0", "--kills", "0", "--budget", "0.2", "--domain-id", str(domain),
        ],
        env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST"),
        timeout=600,
    )  # fmt: skip
    assert process.returncode == 1, process.stdout[-2000:] + process.stderr[-2000:]
    assert "the training run's bag" in process.stderr, process.stderr
    assert "cannot be measured: the recorder exited with code -9" in process.stderr
    assert "Traceback" not in process.stderr, process.stderr

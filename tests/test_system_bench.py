"""``lit system-bench`` runs end to end on real processes and prints its three tables.

A smoke test with tiny sizes: the numbers themselves are benchmarks, not test assertions.
"""

from __future__ import annotations

import os
import subprocess
import sys

from ros_helpers import reserve_domain


def test_system_bench_prints_all_three_measurements() -> None:
    domain, lock = reserve_domain()
    try:
        process = subprocess.run(
            [
                sys.executable, "-m", "lit_planner.cli", "system-bench", "--episodes", "2",
                "--calls", "30", "--kills", "1", "--budget", "0.2", "--domain-id", str(domain),
            ],
            env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST"),
            capture_output=True, text=True, timeout=600, check=False,
        )  # fmt: skip
    finally:
        if lock is not None:
            lock.close()
    assert process.returncode == 0, process.stdout[-2000:] + process.stderr[-2000:]
    out = process.stdout
    assert "| decide psi_K | 30 |" in out and "| decide B | 30 |" in out
    assert "| echo (baseline) | 30 |" in out
    assert "| training | 2 |" in out and "| tensor | 2 |" in out
    assert "training / tensor wall time per episode" in out
    assert "Decide round trip inside the planner node during this training run" in out
    assert "decisions fell back (no answer within the 50 ms decision timeout)" in out
    assert "kill 1:" in out and "median" in out

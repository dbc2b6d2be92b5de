"""A non-interactive shell starts background commands with SIGINT ignored, and Python then
installs no KeyboardInterrupt handler: ``kill -INT`` would do nothing. ``lit`` restores the
handler, so a command stops on SIGINT as documented wherever it was started (a CI run launched
that way once hung in ``lit system-bench``'s Ctrl-C test). Real process: ``lit bench``."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

from lit_planner.testing import read_until


def test_sigint_stops_a_command_started_with_sigint_ignored(tmp_path: Path) -> None:
    process = subprocess.Popen(
        [sys.executable, "-m", "lit_planner.cli", "bench", "--scenarios", "np4", "--planners",
         "litstar-fit", "--runs", "100000", "--no-bag", "--out", str(tmp_path / "out")],
        env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST"),
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN),  # noqa: PLW1509
    )  # fmt: skip
    try:
        assert process.stderr is not None
        # Running: past start-up, where the handler is set.
        read_until(process.stderr, "lit bench: writing to")
        process.send_signal(signal.SIGINT)
        _, err = process.communicate(timeout=120)
        assert process.returncode == 130, err
        assert "lit bench: interrupted" in err and "Traceback" not in err
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()

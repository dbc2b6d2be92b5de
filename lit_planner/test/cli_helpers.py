"""What the ``lit`` command-line tests share."""

from __future__ import annotations

import os
import subprocess
import sys


def lit(*args: str) -> subprocess.CompletedProcess[str]:
    """Run the ``lit`` entry point in this interpreter (the checkout's .venv), with discovery on
    this host whatever the caller's environment says."""
    return subprocess.run(
        [sys.executable, "-m", "lit_planner.cli", *args],
        env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST"),
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )

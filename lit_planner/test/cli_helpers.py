"""What the ``lit`` command-line tests share."""

from __future__ import annotations

import subprocess
import sys


def lit(*args: str) -> subprocess.CompletedProcess[str]:
    """Run the ``lit`` entry point in this interpreter (the checkout's .venv)."""
    return subprocess.run(
        [sys.executable, "-m", "lit_planner.cli", *args],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )

"""``tools/bootstrap.sh``: the interpreter checks that run before anything is installed."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_an_interpreter_without_venv_or_headers_is_refused_in_one_line(tmp_path: Path) -> None:
    """An interpreter other than Debian's python3.11 that lacks ensurepip or ``Python.h`` is not
    one apt-get can fix: set-up stops in one line naming it, before any package or environment
    (here, a stand-in whose every check fails)."""
    interpreter = tmp_path / "bin" / "python3.11"
    interpreter.parent.mkdir()
    interpreter.write_text("#!/bin/sh\nexit 1\n")
    interpreter.chmod(0o755)
    cache = tmp_path / "cache"
    result = subprocess.run(
        ["bash", str(ROOT / "tools" / "bootstrap.sh")],
        env=dict(os.environ, LIT_PYTHON=str(interpreter), LIT_ENV_CACHE=str(cache)),
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert result.returncode == 1, result.stderr
    expected = (
        f"[lit setup] ERROR: {interpreter} has no venv module (ensurepip) or no C headers "
        "(Python.h); install them for that interpreter, or set LIT_PYTHON to one that has both"
    )
    assert result.stderr.splitlines() == [expected]
    # Only the checkout's set-up lock is there: no environment was begun.
    assert [path.name for path in cache.iterdir() if not path.name.startswith("checkout-")] == []

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


def test_missing_packages_without_root_or_sudo_stop_with_the_command_to_run(
    tmp_path: Path,
) -> None:
    """A user who is not root, on a machine without sudo, got "sudo: command not found" twice
    (around a misleading "running apt-get update and retrying once") and exit 127. Set-up now
    stops in one line naming the packages and the command to run as root, before any
    environment (a PATH of stand-ins: ``id -u`` says 1000, dpkg-query finds nothing installed)."""
    import shutil
    import sys

    tools = tmp_path / "bin"
    tools.mkdir()
    for name in ("bash", "dirname", "sha256sum", "cut", "mkdir", "flock", "grep", "readlink"):
        found = shutil.which(name)
        assert found is not None, name
        (tools / name).symlink_to(found)
    (tools / "python3.11").symlink_to(sys.executable)  # has venv and headers: not the refusal
    for name, script in (("id", "echo 1000"), ("dpkg-query", "exit 1")):
        (tools / name).write_text(f"#!{shutil.which('bash')}\n{script}\n")
        (tools / name).chmod(0o755)
    cache = tmp_path / "cache"
    result = subprocess.run(
        [str(tools / "bash"), str(ROOT / "tools" / "bootstrap.sh")],
        env={"PATH": str(tools), "HOME": str(tmp_path), "LIT_ENV_CACHE": str(cache)},
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert result.returncode == 1, result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1, lines
    assert lines[0].startswith(
        "[lit setup] ERROR: set-up needs these Debian packages, and installing them needs root "
        "(no sudo here): run as root: apt-get install g++ cmake ninja-build libompl-dev"
    ), lines
    assert [path.name for path in cache.iterdir() if not path.name.startswith("checkout-")] == []

"""Where and with what a benchmark ran: machine, software versions, checkout.

Every probe is best effort: a fact that cannot be found is None, never a guess.
"""

from __future__ import annotations

import importlib.metadata
import os
import platform
import socket
import subprocess
from pathlib import Path
from typing import Any

OMPL_PACKAGES = ("libompl-dev", "libompl1.5")
"""Debian packages whose version is OMPL's (the first one installed counts)."""


def machine() -> dict[str, Any]:
    """Hostname, CPU model, cores, memory and operating system."""
    return {
        "hostname": socket.gethostname(),
        "cpu_model": _cpu_model(),
        "cores": os.cpu_count(),
        "memory_bytes": _memory_bytes(),
        "os": _os_name(),
        "kernel": platform.release(),
        "architecture": platform.machine(),
    }


def versions(root: Path) -> dict[str, Any]:
    """Python, the numeric packages, the C++ core, OMPL and the checkout's git commit."""
    import matplotlib
    import numpy
    import scipy

    return {
        "python": platform.python_version(),
        "numpy": numpy.__version__,
        "scipy": scipy.__version__,
        "matplotlib": matplotlib.__version__,
        "lit_core": _lit_core(),
        "ompl": _ompl_version(),
        "git": git_state(root),
    }


def _cpu_model() -> str | None:
    try:
        for line in Path("/proc/cpuinfo").read_text(encoding="utf-8").splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or None


def _memory_bytes() -> int | None:
    try:
        for line in Path("/proc/meminfo").read_text(encoding="utf-8").splitlines():
            if line.startswith("MemTotal:"):
                return int(line.split()[1]) * 1024  # the kernel writes kB (KiB)
    except (OSError, ValueError, IndexError):
        pass
    return None


def _os_name() -> str:
    try:
        for line in Path("/etc/os-release").read_text(encoding="utf-8").splitlines():
            if line.startswith("PRETTY_NAME="):
                return line.split("=", 1)[1].strip().strip('"')
    except OSError:
        pass
    return platform.platform()


def _lit_core() -> dict[str, Any]:
    info: dict[str, Any] = {"version": None, "module": None, "built": None, "build_type": None}
    try:
        info["version"] = importlib.metadata.version("lit-core")
    except importlib.metadata.PackageNotFoundError:
        pass
    try:
        import lit_core

        module = Path(lit_core.__file__)
        info["module"] = str(module)
        info["built"] = _iso_mtime(module)
    except (ImportError, OSError):
        return info
    cache = module.resolve().parent
    # An editable scikit-build install leaves the build tree beside the package sources.
    for candidate in Path(__file__).resolve().parents[2].glob("core/build/*/CMakeCache.txt"):
        cache = candidate
        break
    if cache.is_file():
        for line in cache.read_text(encoding="utf-8", errors="replace").splitlines():
            if line.startswith("CMAKE_BUILD_TYPE:"):
                info["build_type"] = line.split("=", 1)[1].strip() or None
    return info


def _ompl_version() -> str | None:
    for package in OMPL_PACKAGES:
        try:
            answer = subprocess.run(
                ["dpkg-query", "-W", "-f=${Version}", package],
                capture_output=True,
                text=True,
                timeout=10,
                check=False,
            )
        except (OSError, subprocess.TimeoutExpired):
            return None
        if answer.returncode == 0 and answer.stdout.strip():
            return f"{answer.stdout.strip()} ({package})"
    return None


def git_state(root: Path) -> dict[str, Any] | None:
    """``{"commit", "dirty"}`` of the git checkout at ``root`` (dirty: tracked files modified;
    None if git could not tell); None outside git. Read-only: ``git status`` takes no lock and
    writes no refreshed index (``--no-optional-locks``), so it cannot make the user's own git
    command fail on ``index.lock``, nor leave one behind when it is killed."""

    def git(*args: str) -> str | None:
        try:
            answer = subprocess.run(
                ["git", "--no-optional-locks", "-C", str(root), *args],
                capture_output=True,
                text=True,
                timeout=10,
                check=False,
            )
        except (OSError, subprocess.TimeoutExpired):
            return None
        return answer.stdout.strip() if answer.returncode == 0 else None

    commit = git("rev-parse", "HEAD")
    if commit is None:
        return None
    status = git("status", "--porcelain", "--untracked-files=no")
    return {"commit": commit, "dirty": bool(status) if status is not None else None}


def commit_label(root: Path) -> str | None:
    """The checkout's commit as provenance names it, ``-dirty`` appended when tracked files are
    modified; None outside git."""
    state = git_state(root)
    if state is None:
        return None
    return state["commit"] + ("-dirty" if state["dirty"] else "")


def _iso_mtime(path: Path) -> str:
    from datetime import UTC, datetime

    return datetime.fromtimestamp(path.stat().st_mtime, UTC).isoformat(timespec="seconds")

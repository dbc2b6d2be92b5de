"""Fixtures and session hooks shared by the system tests."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from ros_helpers import RosSystem

# Discovery stays on this host for every process the system tests start, also under a plain
# pytest run whose environment says otherwise (lit test exports it too).
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.pop("ROS_LOCALHOST_ONLY", None)

SHM_CLEAN_TIMEOUT = 60.0
"""Seconds Fast DDS's shared-memory cleaner may take."""


@pytest.fixture
def ros(tmp_path: Path) -> Iterator[RosSystem]:
    """The processes of one test, in a domain of their own, stopped by PID at the end."""
    system = RosSystem(tmp_path)
    try:
        yield system
    finally:
        system.close()


def clean_fast_dds_shared_memory() -> str:
    """Run Fast DDS's own cleaner, ``fastdds shm clean``: it removes the shared-memory files in
    ``/dev/shm`` whose owner is gone (their lock file is not held), such as those of children a
    test killed; the files of running processes stay. Returns its report in one line."""
    found = shutil.which("fastdds") or str(Path(sys.executable).parent / "fastdds")
    # The wrapper finds its Python tool relative to itself: call it where it really lives, not
    # through the environment's symbolic link.
    tool = os.path.realpath(found)
    try:
        done = subprocess.run(
            [tool, "shm", "clean"],
            capture_output=True,
            text=True,
            timeout=SHM_CLEAN_TIMEOUT,
            check=False,
        )
    except (OSError, subprocess.TimeoutExpired) as error:
        return f"not run ({error})"
    report = " ".join((done.stdout or done.stderr).split())
    return report if done.returncode == 0 else f"exit {done.returncode}: {report}"


def _report(session: pytest.Session, when: str) -> None:
    # Left-over files of killed processes make Fast DDS print "open_and_lock_file failed" and
    # can cost a new process its shared-memory port; clean before the first and after the last
    # test's processes.
    line = f"Fast DDS shared memory {when}: {clean_fast_dds_shared_memory()}"
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    if reporter is not None:
        if when.startswith("after"):
            reporter.write("\n")  # the progress line is still open
        reporter.write_line(line)


def pytest_sessionstart(session: pytest.Session) -> None:
    _report(session, "before the tests")


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    _report(session, "after the tests")

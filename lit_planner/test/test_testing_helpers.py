"""``lit_planner.testing.read_until``, which the process tests use to wait for a child's line
without blocking the run when the line never comes (real child processes)."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest
from lit_planner.testing import (
    ProcessIdentity,
    kill_identified,
    read_until,
    run_watched,
    start_time,
    still_running,
)

PRINTS_THEN_HANGS = (
    "import time\nprint('one', flush=True)\nprint('two', flush=True)\ntime.sleep(600)"
)


def _child(code: str) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)


def test_returns_the_lines_up_to_the_match_and_reads_no_further() -> None:
    process = _child("print('one')\nprint('two')\nprint('three')")
    try:
        assert process.stdout is not None
        assert read_until(process.stdout, "tw") == ["one\n", "two\n"]
        assert process.stdout.readline() == "three\n"
    finally:
        process.kill()
        process.wait()


def test_a_line_that_never_comes_fails_after_the_timeout() -> None:
    process = _child(PRINTS_THEN_HANGS)
    try:
        assert process.stdout is not None
        # (a read that blocked would see the stream end only when the child does, 600 s on)
        with pytest.raises(AssertionError, match=r"'three' not seen within 1 s; lines: one\ntwo"):
            read_until(process.stdout, "three", timeout=1.0)
    finally:
        process.kill()
        process.wait()


def test_a_stream_that_ends_first_fails_at_once() -> None:
    process = _child("print('one')")
    try:
        assert process.stdout is not None
        with pytest.raises(
            AssertionError, match="'two' not seen before the stream ended; lines: one"
        ):
            read_until(process.stdout, "two", timeout=600.0)
    finally:
        process.kill()
        process.wait()


GRANDCHILD = """
import os, subprocess, sys, time
child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"],
                         start_new_session=True)
print(child.pid, flush=True)
time.sleep(1.0)  # long enough for the watch to see its grandchild
"""


def test_run_watched_ends_what_the_command_left_behind() -> None:
    """A command that starts a process in a session of its own and exits: ``run_watched`` returns
    its output and code, names the process it started, and has ended it (by PID, start time
    checked); one that outlives its timeout raises TimeoutExpired with its output, its process
    ended as well."""

    def ended(identities: set[ProcessIdentity]) -> bool:
        deadline = time.monotonic() + 30.0  # SIGKILLed: gone once the kernel has ended it
        while still_running(identities) and time.monotonic() < deadline:
            time.sleep(0.05)
        return still_running(identities) == []

    result = run_watched([sys.executable, "-c", GRANDCHILD], timeout=60)
    try:
        assert result.returncode == 0, result.stderr
        left = int(result.stdout.split()[0])
        assert left in {pid for pid, _ in result.started}, (left, result.started)
        assert ended(result.started)
    finally:
        kill_identified(result.started)
    hung = [sys.executable, "-c", GRANDCHILD.replace("time.sleep(1.0)", "time.sleep(600)")]
    with pytest.raises(subprocess.TimeoutExpired) as raised:
        run_watched(hung, timeout=3)
    left = int(raised.value.output.split()[0])  # printed before the timeout
    deadline = time.monotonic() + 30.0
    while Path(f"/proc/{left}").exists() and start_time(left) is not None:
        assert time.monotonic() < deadline, f"{left} still runs"
        time.sleep(0.05)

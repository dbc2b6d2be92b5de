"""The benchmark's path-check workers end with the process that started them, even when it is
SIGKILLed (it runs no clean-up then)."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from lit_planner.testing import ProcessIdentity, kill_identified, still_running

SCRIPT = """
import multiprocessing, os, signal, sys
from concurrent.futures import ProcessPoolExecutor
from lit_planner.bench.runner import end_with_parent
from lit_planner.testing import start_time

if __name__ == "__main__":
    pool = ProcessPoolExecutor(
        2,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=end_with_parent if sys.argv[1] == "end" else None,
        initargs=(os.getpid(),) if sys.argv[1] == "end" else (),
    )
    pids = {pool.submit(os.getpid).result() for _ in range(4)}
    with open(sys.argv[2], "w") as out:  # with their start times, read while they surely run
        out.write(" ".join(f"{pid}:{start_time(pid)}" for pid in sorted(pids)))
    os.kill(os.getpid(), signal.SIGKILL)
"""


def _workers_after_sigkill(mode: str, tmp_path: Path) -> set[ProcessIdentity]:
    """Start the script, which SIGKILLs itself with its pool's workers idle; the workers'
    identities (PID and start time: a PID reused later is not taken for a worker)."""
    script, pid_file, log = tmp_path / "pool.py", tmp_path / "pids", tmp_path / "log"
    script.write_text(SCRIPT)
    with log.open("wb") as output:  # a file: orphaned workers would hold a pipe open
        code = subprocess.run(
            [sys.executable, str(script), mode, str(pid_file)],
            check=False,
            stdout=output,
            stderr=subprocess.STDOUT,
            timeout=120,
        ).returncode
    pairs = (
        [entry.split(":") for entry in pid_file.read_text().split()] if pid_file.exists() else []
    )
    workers = {(int(pid), int(start)) for pid, start in pairs}
    pids = sorted(pid for pid, _ in workers)
    if code != -signal.SIGKILL or not pids:
        kill_identified(workers)  # the workers it did start do not outlive the failure
        raise AssertionError(f"exit {code}, workers {pids}:\n{log.read_text()}")
    return workers


def _wait_gone(workers: set[ProcessIdentity], timeout: float) -> list[int]:
    deadline = time.monotonic() + timeout
    while True:
        alive = still_running(workers)
        if not alive or time.monotonic() > deadline:
            return alive
        time.sleep(0.05)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
def test_workers_end_with_a_sigkilled_parent(tmp_path: Path) -> None:
    workers = _workers_after_sigkill("end", tmp_path)
    try:
        assert _wait_gone(workers, timeout=30.0) == []
    finally:
        kill_identified(workers)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
def test_without_the_initializer_workers_stay_behind(tmp_path: Path) -> None:
    """What the initializer is for: the same pool without it leaves its workers running."""
    workers = _workers_after_sigkill("plain", tmp_path)
    try:
        assert _wait_gone(workers, timeout=2.0) == sorted(pid for pid, _ in workers)
    finally:
        kill_identified(workers)

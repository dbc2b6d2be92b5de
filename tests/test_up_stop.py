"""``System.stop`` (``lit up``, ``lit demo``, ``lit system-bench``) under Ctrl-C: a first interrupt
while a child is stopping keeps waiting for it and says why; a second one kills every child still
running. Real processes: a launcher script and a child that takes its time over SIGTERM."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

LAUNCHER = textwrap.dedent(
    """
    import sys
    from pathlib import Path
    from lit_planner.up import System

    child = '''
    import signal, sys, time
    def slow(*_):
        print("child: stopping slowly", flush=True)
        time.sleep(600)
    signal.signal(signal.SIGTERM, slow)
    print("ready: child", flush=True)
    while True:
        time.sleep(1)
    '''
    system = System(0, Path.cwd(), echo=lambda line: print(line, flush=True))
    process = system.start("learner", [sys.executable, "-c", child]).process
    system.wait_ready("learner")
    print(f"child pid {process.pid}", flush=True)
    print("codes", system.stop(), flush=True)
    """
)


def _read_until(stream: object, text: str, timeout: float = 60.0) -> list[str]:
    lines: list[str] = []
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        line = stream.readline()  # type: ignore[attr-defined]
        if not line:
            break
        lines.append(line.rstrip("\n"))
        if text in line:
            return lines
    raise AssertionError(f"{text!r} not seen: {lines}")


def _gone(pid: int, timeout: float = 30.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.05)
    return False


def test_interrupts_during_stop_wait_then_kill(tmp_path: Path) -> None:
    launcher = subprocess.Popen(
        [sys.executable, "-c", LAUNCHER],
        cwd=tmp_path,
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        start_new_session=True,
    )  # fmt: skip
    child_pid = None
    try:
        lines = _read_until(launcher.stdout, "child pid")
        child_pid = int(lines[-1].split()[-1])
        _read_until(launcher.stdout, "child: stopping slowly")  # stop() sent SIGTERM
        launcher.send_signal(signal.SIGINT)
        lines = _read_until(launcher.stdout, "still stopping")
        why = "it saves its checkpoint and exports its tensors; at most"
        assert f"waiting for the learner to finish ({why}" in lines[-1]
        assert "interrupt again to kill every process now" in lines[-1]
        os.kill(child_pid, 0)  # not left behind: still running, still waited for
        assert launcher.poll() is None

        launcher.send_signal(signal.SIGINT)
        lines = _read_until(launcher.stdout, "codes")
        assert any("killed the processes still running" in line for line in lines)
        assert lines[-1] == f"codes {{'learner': {-signal.SIGKILL}}}"
        assert launcher.wait(timeout=60) == 0
        assert _gone(child_pid)
        child_pid = None
    finally:
        if launcher.poll() is None:
            launcher.kill()
        launcher.wait(timeout=60)
        if child_pid is not None and not _gone(child_pid, timeout=0.0):
            os.kill(child_pid, signal.SIGKILL)  # the launcher left it behind

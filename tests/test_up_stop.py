"""``System.stop`` (``lit up``, ``lit demo``, ``lit system-bench``) under Ctrl-C: a first interrupt
while a child is stopping keeps waiting for it and says why; a second one kills every child still
running. Real processes: a launcher script and a child that takes its time over SIGTERM."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path
from typing import IO

from lit_planner.testing import ProcessIdentity, identify, kill_identified, read_until

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


def _read_until(stream: IO[str] | None, text: str, timeout: float = 60.0) -> list[str]:
    assert stream is not None
    return [line.rstrip("\n") for line in read_until(stream, text, timeout)]


def _gone(pid: int, timeout: float = 30.0) -> bool:
    deadline = time.monotonic() + timeout
    while True:  # checked at least once, also with timeout 0
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.05)


class _Launcher:
    """The launcher script, started; ``child_pid`` once its child is up and being stopped."""

    def __init__(self, cwd: Path) -> None:
        self.process = subprocess.Popen(
            [sys.executable, "-c", LAUNCHER],
            cwd=cwd,
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
            start_new_session=True,
        )  # fmt: skip
        self.child_pid: int | None = None
        self.child: set[ProcessIdentity] = set()

    def stopping(self) -> None:
        lines = _read_until(self.process.stdout, "child pid")
        # The launcher's print and System's echo thread (the child's "ready: child") share stdout,
        # and a print writes its text and its newline separately: a CI run once read the line
        # "child pid 1234" followed on the same line by the echoed child output.
        found = re.search(r"child pid (\d+)", lines[-1])
        assert found, lines
        self.child_pid = int(found.group(1))
        self.child = identify([self.child_pid])  # running now: its start time tells it apart
        _read_until(self.process.stdout, "child: stopping slowly")  # stop() sent SIGTERM

    def killed_everything(self) -> list[str]:
        lines = _read_until(self.process.stdout, "codes")
        assert lines[-1] == f"codes {{'learner': {-signal.SIGKILL}}}"
        assert not any("Traceback" in line for line in lines)
        assert self.process.wait(timeout=60) == 0
        assert self.child_pid is not None and _gone(self.child_pid)
        self.child_pid = None
        return lines

    def clean_up(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
        self.process.wait(timeout=60)
        kill_identified(self.child)  # if the launcher left it behind (and no other took its PID)


def test_interrupts_during_stop_wait_then_kill(tmp_path: Path) -> None:
    launcher = _Launcher(tmp_path)
    try:
        launcher.stopping()
        launcher.process.send_signal(signal.SIGINT)
        lines = _read_until(launcher.process.stdout, "still stopping")
        why = "it saves its checkpoint and exports its tensors; at most"
        assert f"waiting for the learner to finish ({why}" in lines[-1]
        assert "interrupt again to kill every process now" in lines[-1]
        assert launcher.child_pid is not None
        os.kill(launcher.child_pid, 0)  # not left behind: still running, still waited for
        assert launcher.process.poll() is None

        launcher.process.send_signal(signal.SIGINT)
        lines = launcher.killed_everything()
        assert any("killed the processes still running" in line for line in lines)
    finally:
        launcher.clean_up()


def test_two_quick_interrupts_kill_without_a_traceback(tmp_path: Path) -> None:
    """A double Ctrl-C: wherever the launcher is when the second one comes (printing the first
    one's message, say), it kills its children and ends normally. (Two signals that arrive
    before the first is handled count once, as the kernel delivers them; the grace then ends
    the wait.)"""
    launcher = _Launcher(tmp_path)
    try:
        launcher.stopping()
        launcher.process.send_signal(signal.SIGINT)
        time.sleep(0.05)
        launcher.process.send_signal(signal.SIGINT)
        launcher.killed_everything()
    finally:
        launcher.clean_up()


# lit up whose recorder is replaced by the program argv[1] (the launcher's own options follow).
_UP_WITH_FAKE_RECORDER = textwrap.dedent(
    """
    import sys
    from lit_planner import cli, up

    fake, original = sys.argv.pop(1), up.System.start

    def start(self, name, executable, *args, **kwargs):
        if name == "recorder":
            executable = [sys.executable, "-c", fake]
        return original(self, name, executable, *args, **kwargs)

    up.System.start = start
    sys.exit(cli.main(sys.argv[1:]))
    """
)


def _lit_up(tmp_path: Path, fake_recorder: str) -> subprocess.Popen[str]:
    from ros_helpers import launcher_domain

    return subprocess.Popen(
        [sys.executable, "-c", _UP_WITH_FAKE_RECORDER, fake_recorder, "up", "--domain-id",
         str(launcher_domain()), "--bag", str(tmp_path / "bag"), "--run-id", "up-test"],
        cwd=tmp_path,
        env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST"),
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True,
    )  # fmt: skip


def test_a_stop_before_the_recorder_is_ready_starts_nothing_more(tmp_path: Path) -> None:
    """Ctrl-C while lit up waited for its recorder: the wait went on (up to 60 s, then a
    traceback), and the learner and planner were started before the stop."""
    process = _lit_up(tmp_path, "import time\nprint('starting', flush=True)\ntime.sleep(600)")
    try:
        _read_until(process.stdout, "[recorder] starting")
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=40)  # the wait for "ready:" alone took 60 s
        assert "lit up: stopped recorder (exit -15)" in out, out + err
        assert "[learner]" not in out and "[planner]" not in out, out
        assert "Traceback" not in err, err
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()


def test_a_recorder_that_exits_before_it_is_ready_is_named(tmp_path: Path) -> None:
    """It ended lit up with a traceback; now one line says so, and exit 1."""
    process = _lit_up(tmp_path, "import sys\nprint('no bag for me', flush=True)\nsys.exit(3)")
    try:
        out, err = process.communicate(timeout=60)
        assert process.returncode == 1, out + err
        assert "lit up: recorder exited with code 3 before it was ready:" in err, err
        assert "no bag for me" in err and "Traceback" not in err, err
        assert "lit up: stopped recorder (exit 3)" in out, out
        assert "[learner]" not in out and "[planner]" not in out, out
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()

"""Process management for the ROS 2 system tests (``tests/test_ros_system.py``).

Every node, recorder and ``lit call`` runs as a separate process, exactly as a user would start it:

- each :class:`RosSystem` has its own ``ROS_DOMAIN_ID`` (:func:`reserve_domain`) and keeps DDS
  discovery on loopback (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``);
- every child starts in a new session (``start_new_session=True``), runs in the test's working
  directory, writes its output into a log file there, and is tracked by PID;
- :meth:`RosSystem.close` (called from a fixture finalizer, so also when a test fails) sends
  SIGTERM to every child still running, then SIGKILL after a grace period, by PID only.

Run as a script, this module is the topic recorder::

    python tests/ros_helpers.py record OUT.jsonl /lit/episode /lit/learner/stats

It subscribes (reliable, keep-all, like the publishers) to the given ``std_msgs/String`` topics,
prints ``ready:`` once subscribed and ``publishers: TOPIC N`` whenever the number of publishers it
has discovered on a topic changes, and appends one JSON line ``{"topic": ..., "message": ...}`` per
message to ``OUT.jsonl`` (flushed at once) until SIGTERM or SIGINT. The topics are volatile: a test
waits for the publishers before anything it must see is published.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import os
import re
import signal
import subprocess
import sys
import time
import warnings
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from lit_planner.testing import reserve_ros_domain
from lit_planner.up import DomainClaim

ROOT = Path(__file__).resolve().parents[1]
"""The repository."""
BIN = Path(sys.executable).parent
"""The virtual environment's scripts (``lit``, ``lit_planner_node``, ``lit_learner_node``)."""
PLANNER_NODE = str(BIN / "lit_planner_node")
LEARNER_NODE = str(BIN / "lit_learner_node")
RECORDER_NODE = str(BIN / "lit_recorder_node")
LIT = str(BIN / "lit")

DOMAIN_RANGE = (101, 232)
"""Domain ids these tests use: above ``lit test``'s (1-100), within Fast DDS's port range."""
GRACE = 20.0
"""Seconds a child gets between SIGTERM and SIGKILL in :meth:`RosSystem.close`."""

_domains = itertools.count()


def run_node_script(script: str, *args: str) -> tuple[subprocess.CompletedProcess[str], Any]:
    """Run ``script`` (Python that drives a node's class with rclpy, and prints ``RESULT <json>``
    last) in a child process of its own, so rclpy's global state stays out of pytest's, in a ROS
    domain of its own with localhost discovery; the process and the decoded RESULT. Fails the
    test when the script fails or prints no RESULT."""
    domain, lock = reserve_domain()
    try:
        env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ROS_DOMAIN_ID=str(domain))
        process = subprocess.run(
            [sys.executable, "-c", script, *args],
            env=env, capture_output=True, text=True, timeout=300, check=False,
        )  # fmt: skip
    finally:
        if lock is not None:
            lock.close()
    assert process.returncode == 0, process.stdout[-2000:] + process.stderr[-3000:]
    line = next((x for x in process.stdout.splitlines() if x.startswith("RESULT ")), None)
    assert line is not None, process.stdout[-2000:] + process.stderr[-3000:]
    return process, json.loads(line.removeprefix("RESULT "))


def reserve_domain() -> tuple[int, DomainClaim]:
    """A ``ROS_DOMAIN_ID`` for one test from :data:`DOMAIN_RANGE`, and the claim reserving it
    (``lit test``'s own reservation, searched from the PID and a per-process counter). The test
    fails when every one is taken (it used to share one)."""
    low, high = DOMAIN_RANGE
    domain, claim = reserve_ros_domain(range(low, high + 1), os.getpid() * 37 + next(_domains))
    if claim is None:  # a test's processes must not share a domain with another test's
        import pytest  # here: this module also runs as the recorder script

        pytest.fail(f"no free ROS_DOMAIN_ID in {low}-{high}: every one is claimed on this host")
    return domain, claim


def launcher_domain() -> int:
    """A free ``ROS_DOMAIN_ID`` for a launcher the test starts (``lit up``, ``lit demo``,
    ``lit system-bench``), which claims the domain itself: found free, then released to it."""
    domain, claim = reserve_domain()
    if claim is not None:
        claim.close()
    return domain


@dataclass
class Child:
    """One child process: its command, its log file (stdout and stderr) and its exit code."""

    name: str
    argv: list[str]
    popen: subprocess.Popen[bytes]
    log: Path
    stdout: Path | None = None
    """Where standard output went when kept apart from the log (``lit call``)."""
    started: float = field(default_factory=time.monotonic)

    @property
    def pid(self) -> int:
        """The process id (also its session and process-group id)."""
        return self.popen.pid

    def text(self) -> str:
        """Everything the child logged so far."""
        try:
            return self.log.read_text(encoding="utf-8", errors="replace")
        except FileNotFoundError:
            return ""

    def output(self) -> str:
        """Standard output, when it was kept apart from the log."""
        if self.stdout is None:
            return self.text()
        return self.stdout.read_text(encoding="utf-8", errors="replace")

    def running(self) -> bool:
        """Whether the process has not exited yet."""
        return self.popen.poll() is None

    def wait_for_log(self, pattern: str, timeout: float = 60.0, start: int = 0) -> re.Match[str]:
        """Poll the log until the regular expression ``pattern`` matches (after offset ``start``).

        Raises:
            AssertionError: the child exited or ``timeout`` passed first (with the log's tail).
        """
        deadline = time.monotonic() + timeout
        compiled = re.compile(pattern)
        while True:
            match = compiled.search(self.text(), start)
            if match is not None:
                return match
            if not self.running():
                # One more look: the line may have been written just before the exit.
                match = compiled.search(self.text(), start)
                if match is not None:
                    return match
                raise AssertionError(
                    f"{self.name} exited ({self.popen.returncode}) before logging {pattern!r}:\n"
                    f"{self.tail()}"
                )
            if time.monotonic() > deadline:
                raise AssertionError(
                    f"{self.name} did not log {pattern!r} within {timeout:g} s:\n{self.tail()}"
                )
            time.sleep(0.05)

    def wait(self, timeout: float) -> int:
        """The exit code, waiting up to ``timeout`` s.

        Raises:
            AssertionError: still running after ``timeout`` (with the log's tail).
        """
        try:
            return self.popen.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            raise AssertionError(
                f"{self.name} still running after {timeout:g} s:\n{self.tail()}"
            ) from None

    def tail(self, lines: int = 40) -> str:
        """The last lines of the log, for failure messages."""
        return "\n".join(self.text().splitlines()[-lines:])


class RosSystem:
    """The processes of one test, all in one ROS domain, all stopped by :meth:`close`."""

    def __init__(self, workdir: Path) -> None:
        self.workdir = workdir
        self._locks: list[IO[str]] = []
        self.domain = self.other_domain()
        """This system's ``ROS_DOMAIN_ID``."""
        self.children: list[Child] = []
        self._names = itertools.count()
        (workdir / "ros_log").mkdir(parents=True, exist_ok=True)

    def other_domain(self) -> int:
        """Reserve one more domain (free of other tests) until :meth:`close`."""
        domain, lock = reserve_domain()
        if lock is not None:
            self._locks.append(lock)
        return domain

    def environment(self, domain: int | None = None) -> dict[str, str]:
        """The environment of every child: this domain, loopback discovery, unbuffered logs."""
        env = dict(os.environ)
        env.update(
            ROS_DOMAIN_ID=str(self.domain if domain is None else domain),
            ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
            ROS_LOG_DIR=str(self.workdir / "ros_log"),
            RCUTILS_LOGGING_BUFFERED_STREAM="0",
            RCUTILS_COLORIZED_OUTPUT="0",
            PYTHONUNBUFFERED="1",
            LIT_SKIP_SETUP="1",
        )
        env.pop("ROS_LOCALHOST_ONLY", None)  # deprecated; would fight the discovery range
        return env

    def start(
        self,
        name: str,
        argv: Sequence[str],
        *,
        domain: int | None = None,
        stdin: bytes | None = None,
        separate_stdout: bool = False,
    ) -> Child:
        """Start ``argv`` in a new session in the working directory; output goes to ``name.log``.

        Args:
            name: a label for logs and failure messages.
            argv: the command.
            domain: another ``ROS_DOMAIN_ID`` than this system's.
            stdin: bytes written to standard input (closed afterwards); None: no input.
            separate_stdout: keep standard output in ``name.out`` apart from the log.
        """
        label = f"{next(self._names):02d}-{name}"
        log = self.workdir / f"{label}.log"
        out = self.workdir / f"{label}.out" if separate_stdout else None
        with open(log, "wb") as log_file, open(out or os.devnull, "wb") as out_file:
            popen = subprocess.Popen(
                list(argv),
                cwd=self.workdir,
                env=self.environment(domain),
                stdin=subprocess.PIPE if stdin is not None else subprocess.DEVNULL,
                stdout=out_file if separate_stdout else log_file,
                stderr=log_file,
                start_new_session=True,
            )
        child = Child(name, list(argv), popen, log, out)
        self.children.append(child)
        if stdin is not None:
            assert popen.stdin is not None
            try:
                popen.stdin.write(stdin)
                popen.stdin.close()
            except BrokenPipeError:
                pass
        return child

    def planner(
        self, name: str = "planner", namespace: str | None = None, **params: object
    ) -> Child:
        """Start ``lit_planner_node`` with ROS parameters (and a namespace)."""
        return self.start(name, [PLANNER_NODE, *ros_arguments(params, namespace)])

    def learner(
        self, name: str = "learner", *, ros_namespace: str | None = None, **params: object
    ) -> Child:
        """Start ``lit_learner_node`` (in the namespace ``ros_namespace``, when given); checkpoint and export go
        into the working directory."""
        params.setdefault("checkpoint", str(self.workdir / "learner" / "checkpoint.pt"))
        params.setdefault("export_dir", str(self.workdir / "learner" / "tensors"))
        return self.start(name, [LEARNER_NODE, *ros_arguments(params, ros_namespace)])

    def recorder(self, topics: Iterable[str], name: str = "recorder") -> Recording:
        """Start the topic recorder (this module as a script) and wait until it is subscribed."""
        path = self.workdir / f"{name}.jsonl"
        child = self.start(
            name, [sys.executable, str(Path(__file__).resolve()), "record", str(path), *topics]
        )
        child.wait_for_log(r"ready:", timeout=60.0)
        return Recording(child, path)

    def call_start(
        self, *args: str, domain: int | None = None, stdin: bytes | None = None
    ) -> Child:
        """Start ``lit call ARGS`` without waiting (its JSON answer goes to a ``.out`` file)."""
        return self.start(
            "call", [LIT, "call", *args], domain=domain, stdin=stdin, separate_stdout=True
        )

    def call(
        self,
        *args: str,
        domain: int | None = None,
        stdin: bytes | None = None,
        timeout: float = 120.0,
    ) -> CallResult:
        """Run ``lit call ARGS`` to its end."""
        return finish_call(self.call_start(*args, domain=domain, stdin=stdin), timeout)

    def stop(self, child: Child, sig: int = signal.SIGTERM, timeout: float = 60.0) -> int:
        """Send ``sig`` to ``child`` (by PID) and return its exit code."""
        if child.running():
            _signal(child.pid, sig)
        return child.wait(timeout)

    def close(self) -> None:
        """SIGTERM every child still running, SIGKILL those left after :data:`GRACE` s."""
        for child in self.children:
            if child.running():
                _signal(child.pid, signal.SIGTERM)
        deadline = time.monotonic() + GRACE
        for child in self.children:
            try:
                child.popen.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                _signal(child.pid, signal.SIGKILL)
                child.popen.wait(timeout=10.0)
        # Children of children: every process still in one of our sessions.
        for child in self.children:
            for pid in session_members(child.pid):
                _signal(pid, signal.SIGKILL)
        for lock in self._locks:
            lock.close()
        self._locks.clear()


@dataclass
class CallResult:
    """The end of one ``lit call``."""

    returncode: int
    stdout: str
    stderr: str

    def json(self) -> Any:
        """Standard output parsed as JSON.

        Raises:
            AssertionError: not JSON (with both streams).
        """
        try:
            return json.loads(self.stdout)
        except ValueError:
            raise AssertionError(
                f"lit call printed no JSON (exit {self.returncode}):\n"
                f"stdout: {self.stdout[:2000]}\nstderr: {self.stderr[-2000:]}"
            ) from None

    def __str__(self) -> str:
        return (
            f"exit {self.returncode}\nstdout: {self.stdout[:2000]}\nstderr: {self.stderr[-2000:]}"
        )


def finish_call(child: Child, timeout: float = 120.0) -> CallResult:
    """Wait for a ``lit call`` started by :meth:`RosSystem.call_start`. A teardown that its
    watchdog had to end is a warning in the test report (seen, not hidden by the right exit
    code), with where it hung."""
    code = child.wait(timeout)
    result = CallResult(code, child.output(), child.text())
    if "the ROS teardown did not end" in result.stderr or "Timeout (0:00:" in result.stderr:
        warnings.warn(f"lit call's teardown hung:\n{result.stderr[-4000:]}", stacklevel=2)
    return result


class Recording:
    """What the recorder process received, read from its JSON-lines file."""

    def __init__(self, child: Child, path: Path) -> None:
        self.child = child
        self.path = path

    def messages(self, topic: str | None = None) -> list[dict[str, Any]]:
        """Envelopes received so far (on ``topic``, or on all topics), oldest first."""
        try:
            lines = self.path.read_text(encoding="utf-8").splitlines()
        except FileNotFoundError:
            return []
        found = []
        for line in lines:
            try:
                record = json.loads(line)
            except ValueError:
                continue  # a line still being written
            if topic is None or record["topic"] == topic:
                found.append(record["message"])
        return found

    def wait_for_publishers(self, topic: str, count: int = 1, timeout: float = 60.0) -> None:
        """Wait until the recorder has discovered ``count`` publishers on ``topic``.

        Raises:
            AssertionError: the recorder exited or ``timeout`` passed first.
        """
        pattern = re.compile(rf"^publishers: {re.escape(topic)} (\d+)$", re.MULTILINE)
        deadline = time.monotonic() + timeout
        while True:
            counts = [int(n) for n in pattern.findall(self.child.text())]
            if counts and counts[-1] >= count:
                return
            if not self.child.running() or time.monotonic() > deadline:
                raise AssertionError(
                    f"the recorder did not discover {count} publishers on {topic} within "
                    f"{timeout:g} s (counts: {counts}):\n{self.child.tail()}"
                )
            time.sleep(0.05)

    def payloads(self, topic: str) -> list[dict[str, Any]]:
        """The payloads received on ``topic``, oldest first."""
        return [message["payload"] for message in self.messages(topic)]

    def wait_until(
        self,
        topic: str,
        condition: Callable[[list[dict[str, Any]]], bool],
        timeout: float,
        what: str,
        watch: Sequence[Child] = (),
    ) -> list[dict[str, Any]]:
        """Poll until ``condition(payloads on topic)`` holds; the payloads then.

        Raises:
            AssertionError: ``timeout`` passed first, or one of ``watch`` exited (with its log).
        """
        deadline = time.monotonic() + timeout
        while True:
            payloads = self.payloads(topic)
            if condition(payloads):
                return payloads
            for child in watch:
                if not child.running():
                    raise AssertionError(
                        f"{child.name} exited ({child.popen.returncode}) while waiting for "
                        f"{what}:\n{child.tail()}"
                    )
            if time.monotonic() > deadline:
                raise AssertionError(
                    f"no {what} on {topic} within {timeout:g} s; got {len(payloads)} messages, "
                    f"last: {payloads[-1:]}\n"
                    + "\n".join(f"--- {c.name}:\n{c.tail(15)}" for c in watch)
                )
            time.sleep(0.1)


def ros_arguments(params: Mapping[str, object], namespace: str | None) -> list[str]:
    """``--ros-args -p name:=value ...`` (floats keep a decimal point: ROS checks the type)."""
    argv = ["--ros-args"]
    for name, value in params.items():
        if isinstance(value, bool):
            text = "true" if value else "false"
        elif isinstance(value, float):
            text = repr(value)
        else:
            text = str(value)
        argv += ["-p", f"{name}:={text}"]
    if namespace:
        argv += ["-r", f"__ns:={namespace}"]
    return argv


def _signal(pid: int, sig: int) -> None:
    """Send ``sig`` to ``pid``, which may have exited meanwhile."""
    with contextlib.suppress(ProcessLookupError):
        os.kill(pid, sig)


_FILE_SIZE_LIMIT = (
    "import os, resource, signal, sys\n"
    "signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # the write fails instead of killing\n"
    "limit = int(sys.argv[1])\n"
    "resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))\n"
    "os.execv(sys.argv[2], sys.argv[2:])\n"
)


def file_size_limited(limit: int, program: str) -> list[str]:
    """The start of a command line that runs ``program`` (an absolute path; its arguments follow)
    with every write beyond ``limit`` bytes of a file failing (EFBIG): a full disk for that
    process alone, without root. Pipes are not files: its output still reaches the test."""
    return [sys.executable, "-c", _FILE_SIZE_LIMIT, str(limit), program]


def session_members(session: int) -> list[int]:
    """PIDs of the live processes in session ``session`` (from ``/proc``)."""
    return [pid for pid, (_, sid) in _process_table().items() if sid == session]


def children_of(parent: int) -> list[int]:
    """PIDs of the live processes whose parent is ``parent`` (from ``/proc``)."""
    return [pid for pid, (ppid, _) in _process_table().items() if ppid == parent]


def live_pids() -> set[int]:
    """PIDs of every live (not zombie) process (from ``/proc``)."""
    return set(_process_table())


def _process_table() -> dict[int, tuple[int, int]]:
    """``pid -> (ppid, session)`` of every live (not zombie) process."""
    table = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue  # exited meanwhile
        # The command name (field 2) may hold spaces and parentheses: split after the last ')'.
        fields = stat[stat.rfind(")") + 2 :].split()
        state, ppid, _pgrp, session = fields[0], int(fields[1]), fields[2], int(fields[3])
        if state != "Z":
            table[int(entry.name)] = (ppid, session)
    return table


# ---------------------------------------------------------------------- the recorder


def _stoppable_node(prefix: str) -> tuple[Any, Callable[[], bool]]:
    """rclpy started without its own signal handlers, a node ``<prefix>_<pid>``, and whether a
    SIGTERM or SIGINT has come since (the caller's loop ends then and shuts down in order)."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    flag = [False]

    def stop(*_: object) -> None:
        flag[0] = True

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    return rclpy.create_node(f"{prefix}_{os.getpid()}"), lambda: flag[0]


def record(path: Path, topics: Sequence[str]) -> int:
    """Append every message on ``topics`` to ``path`` as JSON lines until SIGTERM/SIGINT."""
    import rclpy
    from lit_planner.rosutil import json_qos
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import String

    node, stopped = _stoppable_node("lit_test_recorder")
    with open(path, "a", encoding="utf-8") as out:

        def subscriber(topic: str) -> Callable[[Any], None]:
            def receive(message: Any) -> None:
                try:
                    document = json.loads(message.data)
                except ValueError:
                    document = {"unparsed": message.data}
                out.write(json.dumps({"topic": topic, "message": document}) + "\n")
                out.flush()

            return receive

        def trajectory_subscriber(topic: str) -> Callable[[Any], None]:
            def receive(message: Any) -> None:
                points = [list(point.positions) for point in message.points]
                document = {"payload": {"frame_id": message.header.frame_id, "points": points}}
                out.write(json.dumps({"topic": topic, "message": document}) + "\n")
                out.flush()

            return receive

        for topic in topics:
            if topic.endswith("/lit/path"):  # trajectory_msgs/JointTrajectory, not JSON
                from trajectory_msgs.msg import JointTrajectory

                node.create_subscription(
                    JointTrajectory, topic, trajectory_subscriber(topic), json_qos()
                )
            else:
                node.create_subscription(String, topic, subscriber(topic), json_qos())
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        print(f"ready: recording {', '.join(topics)} into {path}", flush=True)
        publishers = dict.fromkeys(topics, 0)
        while not stopped():
            executor.spin_once(timeout_sec=0.05)
            for topic, known in publishers.items():
                count = node.count_publishers(topic)
                if count != known:
                    publishers[topic] = count
                    print(f"publishers: {topic} {count}", flush=True)
        executor.shutdown(timeout_sec=1.0)
    node.destroy_node()
    rclpy.shutdown()
    return 0


def publish_burst(topic: str, count: int) -> int:
    """Publish ``count`` JSON strings on ``topic`` with the contract's QoS once a subscriber is
    matched, print ``acked`` when every subscriber has acknowledged all of them, then wait for
    SIGTERM (a publisher that leaves at once could take undelivered samples with it)."""
    import rclpy
    from lit_planner.rosutil import json_qos
    from rclpy.duration import Duration
    from std_msgs.msg import String

    node, stopped = _stoppable_node("lit_test_burst")
    publisher = node.create_publisher(String, topic, json_qos())
    deadline = time.monotonic() + 60.0
    while publisher.get_subscription_count() == 0 and time.monotonic() < deadline:
        time.sleep(0.05)
    for index in range(count):
        publisher.publish(String(data=json.dumps({"burst": index})))
    acked = publisher.wait_for_all_acked(Duration(seconds=60.0))
    print("acked" if acked else "not acked", flush=True)
    while not stopped():
        time.sleep(0.05)
    node.destroy_node()
    rclpy.shutdown()
    return 0


def main(argv: Sequence[str]) -> int:
    """``ros_helpers.py record OUT TOPIC...`` or ``ros_helpers.py publish TOPIC COUNT`` (ROS
    arguments after ``--ros-args``, which ``lit_planner.up.System`` appends, are ignored)."""
    argv = list(argv)
    if "--ros-args" in argv:
        argv = argv[: argv.index("--ros-args")]
    if len(argv) == 3 and argv[0] == "publish":
        return publish_burst(argv[1], int(argv[2]))
    if len(argv) < 3 or argv[0] != "record":
        print(
            "usage: ros_helpers.py record OUT.jsonl TOPIC... | publish TOPIC COUNT", file=sys.stderr
        )
        return 2
    return record(Path(argv[1]), argv[2:])


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

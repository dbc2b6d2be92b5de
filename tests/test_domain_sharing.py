"""Two runs on one ROS domain: the launchers (``lit up``, ``lit demo``, ``lit system-bench``)
refuse a domain another launcher of this host holds, before they start anything; and a node
notices another server of its service (nodes started without a launcher)."""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import pytest
from lit_planner.testing import run_watched
from lit_planner.up import DomainBusy, claim_domain
from ros_helpers import launcher_domain, reserve_domain

from lit_planner import rosutil


@pytest.mark.parametrize(
    "command",
    [
        ["up", "--no-record"],
        ["demo"],
        ["system-bench", "--calls", "1", "--episodes", "0", "--kills", "0"],
    ],
    ids=["up", "demo", "system-bench"],
)
def test_launchers_refuse_a_domain_another_launcher_holds(
    tmp_path: Path, command: list[str]
) -> None:
    domain, claim = reserve_domain()  # held as lit test holds its domains, as a launcher would
    assert claim is not None, "no free test domain"
    try:
        process = run_watched(
            [sys.executable, "-m", "lit_planner.cli", *command, "--domain-id", str(domain)],
            cwd=tmp_path,
            env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST"),
            timeout=120,
        )  # fmt: skip
        assert process.returncode == 2, process.stdout + process.stderr
        assert not process.started, process.started
        holder = f"in use on this host by lit test (pid {os.getpid()}, since "
        assert f"lit {command[0]}: ROS_DOMAIN_ID={domain} is {holder}" in process.stderr
        assert "--domain-id" in process.stderr and "Traceback" not in process.stderr
        assert not list(tmp_path.iterdir())  # no run folder, no bag: nothing started
    finally:
        claim.close()


def _held(domain: int) -> bool:
    """Whether someone holds ``domain`` (found by trying to claim it)."""
    try:
        claim_domain(domain, "probe").close()
    except DomainBusy:
        return True
    return False


def test_a_claim_lasts_as_long_as_its_file() -> None:
    domain = launcher_domain()
    claim = claim_domain(domain, "first")
    assert _held(domain)
    with pytest.raises(DomainBusy, match=r"by first \(pid"):
        claim_domain(domain, "second")
    claim.close()
    assert not _held(domain)
    with claim_domain(domain, "third"):  # released with the file
        assert _held(domain)
    assert not _held(domain)


def test_lit_test_does_not_pick_a_domain_a_launcher_holds() -> None:
    from lit_planner.testing import reserve_ros_domain

    domain = launcher_domain()  # free for reserve_ros_domain, but held by a launcher:
    with claim_domain(domain, "a launcher"):
        free = launcher_domain()  # found free just now (not the held one)
        chosen, chosen_lock = reserve_ros_domain([domain, free], start=0)
        try:
            if chosen_lock is None:  # legitimate only when another run took `free` meanwhile
                try:
                    probe = claim_domain(free, "probe", warn=False)
                except DomainBusy:
                    probe = None
                held_elsewhere = probe is None or not probe.held
                if probe is not None:
                    probe.close()
                assert chosen == domain and held_elsewhere, (chosen, free)
            else:
                assert chosen == free, (chosen, free)
        finally:
            if chosen_lock is not None:
                chosen_lock.close()


def _until(predicate: object, timeout: float = 30.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():  # type: ignore[operator]
            return True
        time.sleep(0.05)
    return False


def test_duplicate_server_watch_reports_a_second_server_that_stays(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import rclpy
    from diagnostic_msgs.srv import AddDiagnostics
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions

    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")  # read by rclpy.init
    domain, lock = reserve_domain()
    context = Context()
    rclpy.init(context=context, domain_id=domain, signal_handler_options=SignalHandlerOptions.NO)
    nodes = []
    try:
        for name in ("watch_first", "watch_second"):
            nodes.append(
                rclpy.create_node(
                    name, context=context, start_parameter_services=False, enable_rosout=False
                )
            )
        first, second = nodes
        first.create_service(AddDiagnostics, "/watch/service", lambda _req, res: res)
        watch = rosutil.DuplicateServerWatch(first, "/watch/service")
        assert _until(lambda: watch.check() == 1)
        assert watch.since is None and not watch.reported

        other = second.create_service(AddDiagnostics, "/watch/service", lambda _req, res: res)
        assert _until(lambda: watch.check() == 2)
        # Not yet: a server killed with SIGKILL stays in the graph until its lease runs out.
        assert watch.since is not None and not watch.reported
        monkeypatch.setattr(rosutil, "DEAD_SERVER_SECONDS", 0.0)
        assert watch.check() == 2 and watch.reported

        second.destroy_service(other)
        assert _until(lambda: watch.check() == 1)
        assert watch.since is None and not watch.reported
    finally:
        for node in nodes:
            node.destroy_node()
        context.try_shutdown()
        if lock is not None:
            lock.close()

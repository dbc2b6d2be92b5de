"""The decide path's transport (``lit_planner.rosutil``) across two real processes: a
:class:`DirectService` server and the private, wait-set :class:`ServiceCaller` client, in a ROS
domain of their own. The server's callback fails on one request; the server must answer it with
the empty response and keep serving, stale answers must not be mistaken for fresh ones, a request
sent again after a lost answer must be answered once more without being served twice, work the
callback defers must run after its answer is sent and before the next request, and both ends must
shut down cleanly."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import textwrap

import pytest
from ros_helpers import RosSystem, reserve_domain

SERVER = textwrap.dedent(
    """
    import signal, sys, threading, time
    import rclpy
    from rclpy.signals import SignalHandlerOptions
    from diagnostic_msgs.srv import AddDiagnostics
    from lit_planner import signals
    from lit_planner.rosutil import DirectService

    import os
    events = []

    def after(text):
        if text.startswith("defer-wait:"):
            # Blocks until the client has the answer: an answer sent after this work would never
            # arrive, and the client's call would time out.
            path = text.removeprefix("defer-wait:")
            for _ in range(3000):
                if os.path.exists(path):
                    break
                time.sleep(0.01)
        if text == "defer-boom":
            raise RuntimeError("deferred work failed on purpose")
        events.append("after:" + text)

    def serve(request, response):
        text = request.load_namespace
        events.append("call:" + text)
        if text == "boom":
            raise RuntimeError("the callback failed on purpose")
        if text.startswith("slow"):
            time.sleep(0.5)
        if text.startswith("defer"):
            holder[0].defer(lambda: after(text))
        response.success = True
        response.message = ",".join(events) if text == "order" else "echo:" + text
        return response

    holder = []

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    stop = signals.Flag()  # a handler takes no lock (an Event's set() could wait for good)
    signal.signal(signal.SIGTERM, stop.set)
    node = rclpy.create_node("direct_test_server")
    service = DirectService(
        node,
        "direct_test_service",
        AddDiagnostics,
        "/direct/echo",
        serve,
        repeat_key=lambda request: ("the one client", request.load_namespace),
    )
    holder.append(service)
    # Fast DDS losing an answer, silently: the first answer to each "lost:" request is not sent.
    send, lost = service._service.send_response, set()

    def lossy(response, header):
        if response.message.startswith("echo:lost:") and response.message not in lost:
            lost.add(response.message)
            return
        if response.message.startswith("echo:mute:"):  # no answer to it or its copies
            return
        send(response, header)

    service._service.send_response = lossy
    print("ready", flush=True)
    while not stop.wait(1.0):
        pass
    service.shutdown()
    print("repeats", service.repeats, flush=True)
    print("thread alive after shutdown:", service._thread.is_alive(), flush=True)
    node.destroy_node()
    rclpy.shutdown()
    print("clean exit", flush=True)
    """
)

CLIENT = textwrap.dedent(
    """
    import sys
    import time
    import rclpy
    from lit_planner.rosutil import ServiceCaller

    rclpy.init()
    node = rclpy.create_node("direct_test_client")
    caller = ServiceCaller(node, "/direct/echo", private=True)
    assert caller.wait(60.0), "no server"
    print("first", caller.call("hello", 10.0))
    print("boom", caller.call("boom", 10.0))
    print("after", caller.call("again", 10.0))
    print("late", caller.call("slow-1", 0.05))
    print("fresh", caller.call("next", 10.0))
    print("many", all(caller.call(str(i), 10.0) == (True, "echo:" + str(i)) for i in range(200)))
    print("lost once", caller.call("lost:a", 0.5), caller.resent)
    print("sent again", caller.call("lost:b", 20.0, 0.05), caller.resent > 0)
    print("after loss", caller.call("next-2", 10.0, 0.05))
    # A slow answer (0.5 s) to a call sent again twice: late, through whichever copy comes
    # first; the call counts as answered late once, and no copy's answer is taken for the next.
    before = caller.resent
    print("slow copies", caller.call("slow-2", 0.3, 0.02), caller.resent - before)
    call = caller.last_overdue
    for _ in range(500):
        if caller.answered_late(call):
            break
        time.sleep(0.01)
    print("answered late", caller.answered_late(call), call in caller._overdue.values())
    print("after slow copies", caller.call("next-3", 10.0))
    # A limit on copies: 2 sent (after 20 and 60 ms), none more in the 3 s without an answer
    # (copies would go at 140 ms, 300 ms, 620 ms, ... without it).
    before = caller.resent
    print("limited copies", caller.call("mute:1", 3.0, 0.02, max_resends=2), caller.resent - before)
    before = caller.resent
    print("unlimited copies", caller.call("mute:2", 1.0, 0.02), caller.resent - before > 2)
    flag = sys.argv[1]
    print("defer-wait", caller.call("defer-wait:" + flag, 20.0))
    open(flag, "w").close()
    print("defer-boom", caller.call("defer-boom", 20.0))
    print("defer-1", caller.call("defer-1", 20.0))
    order = caller.call("order", 20.0)[1].split(",")
    print("order", order[order.index("call:defer-wait:" + flag):])
    print("lost:b served", order.count("call:lost:b"))
    print("slow-2 served", order.count("call:slow-2"))
    caller.destroy()
    try:
        caller.call("x", 0.1)
    except RuntimeError as exc:
        print("destroyed:", exc)
    node.destroy_node()
    rclpy.shutdown()
    """
)


def test_direct_service_and_wait_set_client_across_processes(ros: RosSystem, tmp_path) -> None:
    flag = str(tmp_path / "answer-received")
    server = ros.start("server", [sys.executable, "-c", SERVER])
    server.wait_for_log(r"^ready", timeout=60.0)
    client = ros.start("client", [sys.executable, "-c", CLIENT, flag])
    assert client.wait(120.0) == 0, client.tail()
    out = client.text()
    assert "first (True, 'echo:hello')" in out
    assert "boom (False, '')" in out  # answered, not dropped
    assert "after (True, 'echo:again')" in out  # and still serving
    assert "late None" in out  # the deadline passed
    assert "fresh (True, 'echo:next')" in out  # the late answer to slow-1 was not taken for it
    assert "many True" in out
    # A lost answer: without sending again the call times out; sent again (after 50 ms, 100 ms,
    # ...) the server answers the copy from its cache, without running the callback again.
    assert "lost once None 0" in out
    assert "sent again (True, 'echo:lost:b') True" in out
    assert "after loss (True, 'echo:next-2')" in out
    assert "lost:b served 1" in out
    # Copies after 20, 60 and 140 ms (each wait twice the last) until the 300 ms deadline.
    assert re.search(r"^slow copies None [123]$", out, re.MULTILINE), out
    assert "answered late True False" in out
    assert "limited copies None 2" in out
    assert "unlimited copies None True" in out
    assert "after slow copies (True, 'echo:next-3')" in out
    assert "slow-2 served 1" in out
    # Deferred work: after the answer (the client got it while the work was still waiting for
    # the client), before the next request; failing work is logged and serving goes on.
    assert f"defer-wait (True, 'echo:defer-wait:{flag}')" in out
    assert "defer-boom (True, 'echo:defer-boom')" in out
    assert "defer-1 (True, 'echo:defer-1')" in out
    expected = [
        f"call:defer-wait:{flag}",
        f"after:defer-wait:{flag}",
        "call:defer-boom",
        "call:defer-1",
        "after:defer-1",
        "call:order",
    ]
    assert f"order {expected}" in out
    assert "deferred work failed" in server.text()
    assert "destroyed: the client of /direct/echo was destroyed" in out
    assert "callback failed" in server.text()
    assert ros.stop(server) == 0, server.tail()
    assert re.search(r"^repeats [1-9]", server.text(), re.MULTILINE), server.tail()
    assert "thread alive after shutdown: False" in server.text()
    assert "clean exit" in server.text()


CROWD = textwrap.dedent(
    """
    import time
    import rclpy
    from diagnostic_msgs.srv import AddDiagnostics
    from lit_planner.rosutil import ServiceCaller

    rclpy.init()
    node = rclpy.create_node("direct_crowd_client")
    a = ServiceCaller(node, "/direct/echo", private=True, suffix="a")
    b = ServiceCaller(node, "/direct/echo", private=True, suffix="b")
    assert a.wait(60.0) and b.wait(60.0), "no server"
    # A sends a request and is not scheduled while the server answers it and then 50 calls of
    # B: every client of a service receives every answer, and with ROS's default history of 10
    # A's reader dropped its own answer before A took it (silently).
    request = AddDiagnostics.Request()
    request.load_namespace = "held"
    with a._owner.context.handle, a.client.handle:
        held = a.client.handle.send_request(request)
    time.sleep(0.3)
    print("others", all(b.call(f"other-{i}", 10.0) == (True, f"echo:other-{i}") for i in range(50)))
    response, deadline = None, time.monotonic() + 5.0
    with a._lock, a._owner.context.handle, a.client.handle:
        while response is None and time.monotonic() < deadline:
            _, response, _ = a._take(a.client.handle, a._wait_set, 0.1, [held])
    print("held", None if response is None else response.message)
    a.destroy()
    b.destroy()
    node.destroy_node()
    rclpy.shutdown()
    """
)


def test_a_clients_answer_outlasts_many_answers_to_other_clients(ros: RosSystem) -> None:
    """A client's answer waits in its reader while other clients' calls are answered (a planner
    not scheduled while the learner serves other planners): the service QoS's history
    (rosutil.service_qos) keeps it; ROS's default of 10 lost it every time."""
    server = ros.start("server", [sys.executable, "-c", SERVER])
    server.wait_for_log(r"^ready", timeout=60.0)
    client = ros.start("crowd", [sys.executable, "-c", CROWD])
    assert client.wait(120.0) == 0, client.tail()
    out = client.text()
    assert "others True" in out, client.tail()
    assert "held echo:held" in out, client.tail()
    assert ros.stop(server) == 0, server.tail()


def test_send_response_retries_an_answer_fast_dds_dropped() -> None:
    """rclpy only warns when Fast DDS drops an answer; send_response tries again, logs when it
    gives up, and turns no other warning into an error (nor leaves its filter behind)."""
    import warnings

    from lit_planner import rosutil

    class Log:
        def __init__(self) -> None:
            self.lines: list[str] = []

        def warning(self, text: str) -> None:
            self.lines.append(text)

    sent: list[object] = []

    def flaky(drops: int):  # type: ignore[no-untyped-def]
        def send(response: object, header: object) -> None:
            if len(sent) < drops:
                sent.append(None)
                warnings.warn("failed to send response (timeout): x", RuntimeWarning, stacklevel=1)
                return
            warnings.warn("an unrelated warning", RuntimeWarning, stacklevel=1)
            sent.append(response)

        return send

    log = Log()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert rosutil.send_response(flaky(2), "answer", None, "/svc", log)
        assert sent == [None, None, "answer"] and not log.lines
        assert [str(w.message) for w in caught] == ["an unrelated warning"]
    sent.clear()
    assert not rosutil.send_response(flaky(10**6), "answer", None, "/svc", log)
    assert len(sent) == rosutil.SEND_ATTEMPTS
    assert log.lines == ["/svc: answer not delivered: failed to send response (timeout): x"]
    assert not rosutil.send_response(flaky(10**6), "a", None, "/svc", log, stopping=lambda: True)
    sent.clear()
    assert not rosutil.send_response(flaky(10**6), "a", None, "/svc", log, attempts=7)
    assert len(sent) == 7
    assert not any(f[0] == "error" for f in warnings.filters)

    class Service:  # what retry_lost_answers wraps: an rclpy Service's send_response
        srv_name = "/slow"

        def __init__(self) -> None:
            self.send_response = flaky(10**6)

    sent.clear()
    service = rosutil.retry_lost_answers(Service(), log)
    service.send_response("answer", None)
    assert len(sent) == rosutil.SEND_ATTEMPTS
    sent.clear()
    service = rosutil.retry_lost_answers(Service(), log, attempts=rosutil.PLAN_SEND_ATTEMPTS)
    service.send_response("answer", None)
    assert len(sent) == rosutil.PLAN_SEND_ATTEMPTS > rosutil.SEND_ATTEMPTS


def _run_script(script) -> subprocess.CompletedProcess[str]:
    """Run a Python script in a ROS domain of its own, to the end."""
    domain, lock = reserve_domain()
    try:
        env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ROS_DOMAIN_ID=str(domain))
        return subprocess.run(
            [sys.executable, str(script)], env=env, capture_output=True, text=True, timeout=120,
            check=False,
        )  # fmt: skip
    finally:
        if lock is not None:
            lock.close()


def test_a_node_run_by_spin_node_has_its_startup_objects_frozen(tmp_path) -> None:
    """A full garbage collection over the ~200 000 objects of a node with rclpy and torch
    loaded holds the GIL for 80 ms (every thread stops); spin_node freezes what the node built
    at startup, so later collections skip it."""
    script = tmp_path / "owner.py"
    script.write_text(
        textwrap.dedent(
            """
            import gc, sys
            import rclpy.node
            from lit_planner.rosutil import spin_node

            class Owner:
                finished = True

                def __init__(self):
                    self.node = rclpy.node.Node("lit_freeze_probe")
                    self.kept = [[i] for i in range(5000)]  # startup objects

                def shutdown(self):
                    print("frozen", gc.get_freeze_count(), flush=True)

            sys.exit(spin_node(Owner, sys.argv, threads=1))
            """
        )
    )
    process = _run_script(script)
    assert process.returncode == 0, process.stderr[-2000:]
    frozen = int(process.stdout.split("frozen", 1)[1].split()[0])
    assert frozen > 5000


def test_an_answer_that_cannot_be_sent_does_not_end_the_executor_thread() -> None:
    """A send that raises (rclpy's compiled send_response once raised a SystemError when the
    dropped-answer warning was an error, and the exception ended the planner's executor thread)
    is logged by send_response, which the executor's wrapper and DirectService both use, and
    counts as not delivered; nothing is raised into the serving thread."""
    from lit_planner import rosutil

    class Log:
        def __init__(self) -> None:
            self.errors: list[str] = []

        def warning(self, text: str) -> None:
            raise AssertionError(text)

        def error(self, text: str) -> None:
            self.errors.append(text)

    class Service:
        srv_name = "/broken"

        @staticmethod
        def send_response(response: object, header: object) -> None:
            raise SystemError("returned a result with an exception set")

    log = Log()
    assert not rosutil.send_response(Service.send_response, "answer", None, "/broken", log)
    sent: list[int] = []
    service = rosutil.retry_lost_answers(Service(), log, on_sent=lambda: sent.append(1))
    service.send_response("answer", None)  # does not raise
    assert (
        log.errors
        == ["/broken: answer not sent: SystemError('returned a result with an exception set')"] * 2
    )
    # The planner's shutdown counts the answers still being sent: a failed one counts as done.
    assert sent == [1]


def test_the_learner_keys_repeated_requests_by_planner_and_text() -> None:
    """The learner's decide service keeps one answer per planner (the envelope's source and
    run): a copy is the same text; the planner's next request (next seq) is a new one; a text
    the service rejects is never taken for a copy (it is served, and rejected, each time). The
    key's decoding is the one the service uses: each text is decoded once."""
    from types import SimpleNamespace

    import pytest
    from lit_learner.node import _DecodeOnce

    from lit_msgs_json import MessageError, Publisher

    publisher = Publisher("/robot1/lit_planner", "run-1")
    payload = {"episode_id": "e", "planning_time": 0.0, "time_budget": 1.0, "cost": None,
               "minimum_cost": 1.0, "improvements": 0, "path_states": 0, "truncated": True,
               "fallback_decisions": 0}  # fmt: skip
    first = publisher.encode("EpisodeEnd", payload)
    second = publisher.encode("EpisodeEnd", payload)
    decoder = _DecodeOnce()

    def key(text: str):  # type: ignore[no-untyped-def]
        return decoder.repeat_key(SimpleNamespace(load_namespace=text))

    assert key(first) == key(first)
    assert key(first)[0] == key(second)[0] == ("/robot1/lit_planner", "run-1")
    assert key(first)[1] != key(second)[1]
    other = Publisher("/robot2/lit_planner", "run-1").encode("EpisodeEnd", payload)
    assert key(other)[0] != key(first)[0]
    stale = {**json.loads(first), "version": 99}
    for text in ("not json", "[1, 2]", '{"source": ["a"], "run_id": "r"}', "{}", json.dumps(stale)):
        assert key(text) is None
        with pytest.raises(MessageError):
            decoder.decode(text)  # the service's answer: rejected
    key(second)
    message = decoder.decode(second)
    assert decoder.decode(second) is message  # not decoded again
    assert message.payload["episode_id"] == "e" and message.source == "/robot1/lit_planner"
    assert decoder.decode(first) is not message


_DIES = {
    # An rcl error in DirectService's serving thread: its service handle destroyed under it.
    "serving thread": """
        service = DirectService(self.node, "lit_dies_direct", AddDiagnostics, "/dies", None)
        service._owner.destroy_service(service._service)  # deferred while the wait holds it
        service._stop.trigger()  # the wait ends; the next one finds the handle gone
    """,
    "worker thread": """
        def work():
            raise RuntimeError("the worker failed on purpose")

        essential("worker", work).start()
    """,
}


@pytest.mark.parametrize("case", sorted(_DIES))
def test_a_node_whose_thread_dies_shuts_down_and_exits_1(tmp_path, case: str) -> None:
    """A thread the node needs (DirectService's serving thread, a worker started with
    ``essential``) that ends on an error made the node serve nothing while it looked alive (exit
    0 at its eventual stop): spin_node now shuts it down in order and exits 1, saying why."""
    script = tmp_path / "owner.py"
    script.write_text(
        textwrap.dedent(
            """
            import sys
            import rclpy.node
            from diagnostic_msgs.srv import AddDiagnostics
            from lit_planner.rosutil import DirectService, essential, spin_node

            class Owner:
                def __init__(self):
                    self.node = rclpy.node.Node("lit_dies_probe")
            {}
                def shutdown(self):
                    print("shutdown ran", flush=True)

            sys.exit(spin_node(Owner, sys.argv, threads=1))
            """
        ).format(textwrap.indent(textwrap.dedent(_DIES[case]), " " * 8))
    )
    process = _run_script(script)
    assert process.returncode == 1, process.stderr[-2000:]
    assert "shutdown ran" in process.stdout
    assert "; the node shuts down (exit 1)" in process.stderr
    if case == "serving thread":
        assert "/dies: serving stopped" in process.stderr and "/dies is no longer served" in (
            process.stderr
        )
    else:
        assert "thread 'worker' ended: RuntimeError: the worker failed on purpose" in (
            process.stderr
        )
        assert "Traceback" in process.stderr

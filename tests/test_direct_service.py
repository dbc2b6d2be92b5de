"""The decide path's transport (``lit_planner.rosutil``) across two real processes: a
:class:`DirectService` server and the private, wait-set :class:`ServiceCaller` client, in a ROS
domain of their own. The server's callback fails on one request; the server must answer it with
the empty response and keep serving, stale answers must not be mistaken for fresh ones, and both
ends must shut down cleanly."""

from __future__ import annotations

import sys
import textwrap

from ros_helpers import RosSystem

SERVER = textwrap.dedent(
    """
    import signal, sys, threading, time
    import rclpy
    from rclpy.signals import SignalHandlerOptions
    from diagnostic_msgs.srv import AddDiagnostics
    from lit_planner.rosutil import DirectService

    def serve(request, response):
        text = request.load_namespace
        if text == "boom":
            raise RuntimeError("the callback failed on purpose")
        if text.startswith("slow"):
            time.sleep(0.5)
        response.success = True
        response.message = "echo:" + text
        return response

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    node = rclpy.create_node("direct_test_server")
    service = DirectService(node, "direct_test_service", AddDiagnostics, "/direct/echo", serve)
    print("ready", flush=True)
    stop.wait()
    service.shutdown()
    print("thread alive after shutdown:", service._thread.is_alive(), flush=True)
    node.destroy_node()
    rclpy.shutdown()
    print("clean exit", flush=True)
    """
)

CLIENT = textwrap.dedent(
    """
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
    caller.destroy()
    try:
        caller.call("x", 0.1)
    except RuntimeError as exc:
        print("destroyed:", exc)
    node.destroy_node()
    rclpy.shutdown()
    """
)


def test_direct_service_and_wait_set_client_across_processes(ros: RosSystem) -> None:
    server = ros.start("server", [sys.executable, "-c", SERVER])
    server.wait_for_log(r"^ready", timeout=60.0)
    client = ros.start("client", [sys.executable, "-c", CLIENT])
    assert client.wait(120.0) == 0, client.tail()
    out = client.text()
    assert "first (True, 'echo:hello')" in out
    assert "boom (False, '')" in out  # answered, not dropped
    assert "after (True, 'echo:again')" in out  # and still serving
    assert "late None" in out  # the deadline passed
    assert "fresh (True, 'echo:next')" in out  # the late answer to slow-1 was not taken for it
    assert "many True" in out
    assert "destroyed: the client of /direct/echo was destroyed" in out
    assert "callback failed" in server.text()
    assert ros.stop(server) == 0, server.tail()
    assert "thread alive after shutdown: False" in server.text()
    assert "clean exit" in server.text()

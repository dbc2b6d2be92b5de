"""Small ROS 2 helpers shared by the planner node, the learner node, ``lit up`` and ``lit call``.

Everything here follows ``PLATFORM_FACTS.md``: discovery stays on this host unless the user says
otherwise, service calls wait on a future with a deadline (never ``spin_until_future_complete`` in a
loop), and shutdown tolerates the race between SIGTERM and a spinning executor.
"""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

LOCALHOST_ENV = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
"""Environment every entry point sets unless the user already chose: DDS discovery on loopback."""
DEFAULT_DOMAIN_ID = 42
"""``ROS_DOMAIN_ID`` of ``lit up`` / ``lit demo`` / ``lit call`` when the user has not set one."""
DECIDE_SERVICE = "/lit/learner/decide"
"""The learner's decision service (absolute: one learner serves planners in any namespace)."""
EXPORT_SERVICE = "/lit/learner/export"
"""The learner's export service (``std_srvs/srv/Trigger``)."""
PLAN_SERVICE = "lit/planner/plan"
"""The planner's plan service, relative to the planner node's namespace."""
TOPICS = {
    "observation": "lit/observation",
    "decision": "lit/decision",
    "solution": "lit/solution",
    "episode": "lit/episode",
    "path": "lit/path",
}
"""The planner node's topics, relative to its namespace."""
STATS_TOPIC = "/lit/learner/stats"
"""The learner's training-progress topic."""


def localhost_environment() -> None:
    """Keep DDS discovery on this host unless the user set a range; set a domain id if unset."""
    for key, value in LOCALHOST_ENV.items():
        os.environ.setdefault(key, value)
    os.environ.setdefault("ROS_DOMAIN_ID", str(DEFAULT_DOMAIN_ID))


def json_qos() -> Any:
    """QoS of the JSON topics: reliable, keep-all, volatile (keep-last drops in bursts)."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(
        history=HistoryPolicy.KEEP_ALL,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.VOLATILE,
    )


def flush_publishers(publishers: Sequence[Any], timeout: float = 5.0) -> bool:
    """Wait until every matched reliable subscriber has acknowledged everything published, at
    most ``timeout`` s per publisher. Call before a node exits: the last messages still queued in
    DDS would otherwise die with the process (``seq`` accounting cannot see a lost tail).

    Returns:
        True when everything was acknowledged.
    """
    from rclpy.duration import Duration

    return all(
        publisher.wait_for_all_acked(Duration(nanoseconds=int(timeout * 1e9)))
        for publisher in publishers
    )


class ServiceCaller:
    """Calls one service with a deadline (``diagnostic_msgs/srv/AddDiagnostics`` unless
    ``srv_type`` says otherwise).

    Two ways to wait for the answer:

    - shared (default): the client lives on ``node``, which an executor spins in another thread;
      a call blocks the calling thread only.
    - ``private=True``: the client lives on a small node of its own (``<node>_<suffix>``, no
      parameter services, no rosout) with its own single-threaded executor, which the *calling*
      thread spins until the answer or the deadline. The response then takes no detour through
      another thread's executor: this halves the round trip (``PLATFORM_FACTS.md``: 0.29 ms
      median spinning in the caller, about 0.5 ms through an executor thread). Calls must come
      from one thread at a time (a lock enforces it).
    """

    def __init__(
        self,
        node: Any,
        name: str,
        callback_group: Any = None,
        srv_type: Any = None,
        *,
        private: bool = False,
        suffix: str = "client",
    ) -> None:
        if srv_type is None:
            from diagnostic_msgs.srv import AddDiagnostics

            srv_type = AddDiagnostics
        self.srv_type = srv_type
        self.name = name
        self._executor: Any = None
        self._owner: Any = None
        self._lock = threading.Lock()
        if private:
            import rclpy
            from rclpy.executors import SingleThreadedExecutor

            self._owner = rclpy.create_node(
                f"{node.get_name()}_{suffix}",
                namespace=node.get_namespace(),
                context=node.context,
                start_parameter_services=False,
                enable_rosout=False,
                use_global_arguments=False,  # a process-wide __node:= remap is the main node's
            )
            self._executor = SingleThreadedExecutor(context=node.context)
            self._executor.add_node(self._owner)
            node = self._owner
        self.client = node.create_client(srv_type, name, callback_group=callback_group)

    def wait(self, timeout: float) -> bool:
        """Whether the service appeared within ``timeout`` seconds (DDS discovery)."""
        return bool(self.client.wait_for_service(timeout_sec=timeout))

    def request(self, request: Any, timeout: float) -> Any:
        """Send ``request``; the response, or None after ``timeout``."""
        if self._owner is not None:
            return self._request_spinning(request, timeout)
        done = threading.Event()
        future = self.client.call_async(request)
        future.add_done_callback(lambda _: done.set())
        if not done.wait(timeout):
            self.client.remove_pending_request(future)
            return None
        return future.result()

    def _request_spinning(self, request: Any, timeout: float) -> Any:
        with self._lock:
            if self._executor is None:
                raise RuntimeError(f"the client of {self.name} was destroyed")
            deadline = time.monotonic() + timeout
            future = self.client.call_async(request)
            while not future.done():
                remaining = deadline - time.monotonic()
                if remaining <= 0.0:
                    self.client.remove_pending_request(future)
                    return None
                self._executor.spin_once(timeout_sec=remaining)
            return future.result()

    def call(self, text: str, timeout: float) -> tuple[bool, str] | None:
        """Send ``text`` as ``load_namespace``; ``(success, message)``, or None after ``timeout``."""
        request = self.srv_type.Request()
        request.load_namespace = text
        response = self.request(request, timeout)
        if response is None:
            return None
        return bool(response.success), str(response.message)

    def destroy(self) -> None:
        """Release the private node and executor (nothing to do for a shared client)."""
        if self._executor is not None:
            with self._lock:
                self._executor.shutdown(timeout_sec=1.0)
                self._owner.destroy_node()
                self._executor = None


def spin_node(
    make_owner: Callable[[], Any],
    args: Sequence[str] | None = None,
    threads: int = 4,
) -> int:
    """Run a node until SIGINT/SIGTERM (or until its owner sets ``finished``), then shut down.

    Args:
        make_owner: builds the object that owns the node (called after ``rclpy.init``); it has a
            ``node`` attribute, optionally a ``finished`` flag and a ``shutdown()`` method, which
            runs after the signal and before the executor stops.
        args: command line (ROS arguments after ``--ros-args``).
        threads: executor threads.

    Returns:
        0 after a clean shutdown.
    """
    localhost_environment()
    import rclpy
    from rclpy.executors import (
        ExternalShutdownException,
        MultiThreadedExecutor,
        SingleThreadedExecutor,
    )
    from rclpy.signals import SignalHandlerOptions

    # Our own handlers: finish the current work and shut down in order (rclpy's would raise
    # inside whatever thread happens to run).
    rclpy.init(
        args=list(args) if args is not None else None,
        signal_handler_options=SignalHandlerOptions.NO,
    )
    stop = threading.Event()

    def request_stop(*_: object) -> None:
        stop.set()

    signal.signal(signal.SIGTERM, request_stop)
    signal.signal(signal.SIGINT, request_stop)
    owner = make_owner()
    node = owner.node
    # One thread: rclpy's single-threaded executor has a much shorter callback path (a service
    # round trip of about 0.3 ms against several ms with the thread pool).
    executor = SingleThreadedExecutor() if threads == 1 else MultiThreadedExecutor(threads)
    executor.add_node(node)
    spinner = threading.Thread(target=_spin, args=(executor, stop), name="executor", daemon=True)
    spinner.start()
    try:
        while not stop.wait(0.2):
            if getattr(owner, "finished", False):
                break
    finally:
        if hasattr(owner, "shutdown"):
            try:
                owner.shutdown()
            except Exception as exc:  # noqa: BLE001 - must not hide the clean exit
                node.get_logger().error(f"shutdown: {exc}")
        executor.shutdown(timeout_sec=2.0)
        spinner.join(timeout=2.0)
        try:
            node.destroy_node()
        except Exception:  # noqa: BLE001, S110 - a node half torn down by the signal race
            pass
        if rclpy.ok():
            try:
                rclpy.shutdown()
            except (ExternalShutdownException, RuntimeError):
                pass
    return 0


def _spin(executor: Any, stop: threading.Event) -> None:
    from rclpy.executors import ExternalShutdownException

    try:
        executor.spin()
    except (ExternalShutdownException, KeyboardInterrupt):
        pass
    except Exception as exc:  # RCLError when shutdown races the spin (PLATFORM_FACTS)
        import rclpy

        if rclpy.ok():
            raise
        del exc
    finally:
        stop.set()

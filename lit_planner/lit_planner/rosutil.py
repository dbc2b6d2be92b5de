"""Small ROS 2 helpers shared by the planner node, the learner node, ``lit up`` and ``lit call``.

Everything here follows ``PLATFORM_FACTS.md``: discovery stays on this host unless the user says
otherwise, service calls wait on a future with a deadline (never ``spin_until_future_complete`` in a
loop), and shutdown tolerates the race between SIGTERM and a spinning executor.
"""

from __future__ import annotations

import argparse
import collections
import gc
import os
import signal
import sys
import threading
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from lit_planner import signals
from lit_planner.guarded_stdout import GuardedStdout

LOCALHOST_ENV = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
"""Environment every entry point sets unless the user already chose: DDS discovery on loopback."""
DEFAULT_DOMAIN_ID = 42
"""``ROS_DOMAIN_ID`` of ``lit up``, ``lit call`` and the nodes when the user has not set one
(``lit demo``'s is its own, 91)."""
DECIDE_SERVICE = "/lit/learner/decide"
"""The learner's decision service (absolute: one learner serves planners in any namespace)."""
EXPORT_SERVICE = "/lit/learner/export"
"""The learner's export service (``std_srvs/srv/Trigger``)."""
MAX_EPISODE_BUDGET = 3600.0
"""Most seconds of a training episode's time budget: the maximum of ``time_budget`` in the
DecideRequest and EpisodeEnd schemas."""
MIN_EPISODE_BUDGET = 1e-6
"""Fewest seconds of a training episode's time budget: the minimum of ``time_budget`` in the
DecideRequest and EpisodeEnd schemas (the learner refuses less)."""
MAX_INFERENCE_BUDGET = 86400.0
"""Most seconds of another policy's episode: the maximum ``planning_time`` of an Observation."""
MAX_REQUEST_TIME = 600.0
"""Planning time of a plan request that gives an iteration or batch limit and no ``time``: the
longest ``time`` PlanRequest allows (its schema's maximum, which a test holds this to)."""
PLAN_SERVICE = "lit/planner/plan"
"""The planner's plan service, relative to the planner node's namespace."""
CANCEL_SERVICE = "lit/planner/cancel"
"""The planner's cancel service (a CancelRequest names a plan request's ``request_id``),
relative to the planner node's namespace."""
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


def episode_budget_limit(policy: str) -> float:
    """The longest time budget the planner node's episodes of ``policy`` can have."""
    return MAX_EPISODE_BUDGET if policy == "training" else MAX_INFERENCE_BUDGET


def declare_parameters(node: Any, defaults: Mapping[str, Any], program: str) -> dict[str, Any]:
    """Declare ``defaults`` on ``node``; their values. A value of another type than its default
    (``-p time_budget:=1`` for a float) ends the program with one line (SystemExit) instead of
    rclpy's InvalidParameterTypeException traceback."""
    from rclpy.exceptions import InvalidParameterTypeException

    values = {}
    for name, default in defaults.items():
        try:
            node.declare_parameter(name, default)
        except InvalidParameterTypeException as exc:
            kind = {bool: "true or false", int: "a whole number", float: "a number with a "
                    "decimal point", str: "text"}.get(type(default), type(default).__name__)  # fmt: skip
            raise SystemExit(
                f"{program}: parameter {name} takes {kind}, as its default {default!r} does ({exc})"
            ) from None
        values[name] = node.get_parameter(name).value
    return values


def localhost_environment() -> None:
    """Keep DDS discovery on this host unless the user set a range; set a domain id if unset. A
    variable set but empty counts as unset (rcl would take its own default: domain 0, where
    ``lit up`` and ``lit call`` resolve an empty one to 42)."""
    defaults = {**LOCALHOST_ENV, "ROS_DOMAIN_ID": str(DEFAULT_DOMAIN_ID)}
    for key, value in defaults.items():
        if not os.environ.get(key, "").strip():
            os.environ[key] = value


DUPLICATE_CHECK_PERIOD = 5.0
"""Seconds between a node's checks for another server of its service (see
:class:`DuplicateServerWatch`)."""
DEAD_SERVER_SECONDS = 25.0
"""How long a second server must stay in the graph before it counts as alive: a process killed
with SIGKILL stays in it until its DDS lease (20 s) runs out, as the learner does when it is
killed and restarted (PLATFORM_FACTS.md)."""


class DuplicateServerWatch:
    """Checks whether more than one server offers ``service`` on the domain, and logs an error
    once that has lasted :data:`DEAD_SERVER_SECONDS` (an info line when it ends): each request
    then goes to either server (two learners each see part of every episode; two planners answer
    each other's plan calls). Launchers refuse a second run on their domain (``lit up``'s domain
    claim); this catches nodes started by other means. :meth:`start` checks every
    :data:`DUPLICATE_CHECK_PERIOD` s on the node's executor."""

    def __init__(self, node: Any, service: str) -> None:
        self.node = node
        self.name = node.resolve_service_name(service)
        self.since: float | None = None
        """When a second server was first seen (None: one server or none)."""
        self.reported = False

    def start(self) -> Any:
        """Check periodically; returns the timer."""
        return self.node.create_timer(DUPLICATE_CHECK_PERIOD, self.check)

    def check(self) -> int:
        """One check; returns the number of servers the graph shows."""
        servers = int(self.node.count_services(self.name))
        now = time.monotonic()
        if servers <= 1:
            if self.reported:
                self.node.get_logger().info(f"{self.name}: the only server again")
            self.since, self.reported = None, False
            return servers
        if self.since is None:
            self.since = now
        if not self.reported and now - self.since >= DEAD_SERVER_SECONDS:
            self.reported = True
            domain = self.node.context.get_domain_id()
            self.node.get_logger().error(
                f"{servers} servers of {self.name} on ROS_DOMAIN_ID={domain} for "
                f"{now - self.since:.0f} s: another node serves it too, and each request goes "
                "to either of them. Stop the other one, or run this one on another domain or in "
                "another namespace"
            )
        return servers


def json_qos() -> Any:
    """QoS of the JSON topics: reliable, keep-all, volatile (keep-last drops in bursts)."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(
        history=HistoryPolicy.KEEP_ALL,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.VOLATILE,
    )


SERVICE_DEPTH = 1000
"""History depth of every service and client the project creates (:func:`service_qos`)."""


def service_qos() -> Any:
    """QoS of the project's services and clients: ROS's service default (reliable, volatile)
    with a history of :data:`SERVICE_DEPTH` instead of 10.

    Every client of a service receives every answer of its server, each client's own and the
    others', and takes out its own; a keep-last history of 10 drops the oldest unread answers
    when more come in. A planner whose call was answered while it was not scheduled lost that
    answer, without an error on either side, once the learner had answered ten calls of other
    planners meanwhile (a one-off script: the default history lost a client's answer in 20 of 20
    tries with 15 answers to another client before it took its own, none with 100). The service's
    request history drops requests the same way when more than 10 wait while the server is busy.
    Depth does not take part in QoS matching, so clients and servers with ROS's default still
    talk to these."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=SERVICE_DEPTH,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.VOLATILE,
    )


def flush_publishers(publishers: Sequence[Any], timeout: float = 5.0) -> bool:
    """Wait until every matched reliable subscriber has acknowledged everything published, at
    most ``timeout`` s for all the publishers together (it was per publisher: five slow ones
    could take longer than ``lit up`` gives a node to stop). Call before a node exits: the last
    messages still queued in DDS would otherwise die with the process (``seq`` accounting cannot
    see a lost tail).

    Returns:
        True when everything was acknowledged.
    """
    from rclpy.duration import Duration

    deadline = time.monotonic() + timeout
    for publisher in publishers:
        left = max(0.0, deadline - time.monotonic())
        if not publisher.wait_for_all_acked(Duration(nanoseconds=int(left * 1e9))):
            return False
    return True


def freeze_startup_objects() -> None:
    """Exempt every object alive now from later garbage collections (``gc.freeze``).

    Call it once a long-running process has imported and built what it keeps for its whole life.
    A process with rclpy, numpy and torch loaded holds about 200 000 objects that the cyclic
    collector would otherwise traverse in every full collection: 80 ms in the learner node here
    (10-20 ms in the planner and recorder nodes), with the GIL held, so every thread of the
    process, the one answering decide requests included, stops for as long. After the freeze a
    full collection only visits objects created since. Cycles created later are still collected.
    """
    gc.collect()
    gc.freeze()


def private_node(node: Any, name: str) -> Any:
    """A small node beside ``node`` (same context and namespace) for one latency-critical
    endpoint: no parameter services, no rosout, and immune to a process-wide ``__node:=`` remap
    (that one is the main node's)."""
    import rclpy

    return rclpy.create_node(
        name,
        namespace=node.get_namespace(),
        context=node.context,
        start_parameter_services=False,
        enable_rosout=False,
        use_global_arguments=False,
    )


INTERRUPT_POLL = 0.1
"""Seconds between two looks at a :class:`ServiceCaller` call's ``interrupted``."""


class CallInterrupted(RuntimeError):
    """A :class:`ServiceCaller` call stopped waiting because its ``interrupted`` became true."""


class ServerGone(CallInterrupted):
    """A :class:`ServiceCaller` call stopped waiting because the graph showed no server of its
    service for its ``server_gone`` seconds: the node stopped (or crashed) before it answered."""


SETTLE_SECONDS = 0.1
"""Pause of :meth:`ServiceCaller.wait` after the service appeared (endpoint matching)."""


OVERDUE_KEPT = 64
"""Overdue requests, and answered ones, a private :class:`ServiceCaller` remembers (the
latest)."""


class ServiceCaller:
    """Calls one service with a deadline (``diagnostic_msgs/srv/AddDiagnostics`` unless
    ``srv_type`` says otherwise).

    Two ways to wait for the answer:

    - shared (default): the client lives on ``node``, which an executor spins in another thread;
      a call blocks the calling thread only.
    - ``private=True``: the client lives on a small node of its own (``<node>_<suffix>``, no
      parameter services, no rosout) that no executor spins: the *calling* thread sends the
      request and waits on an rcl wait set holding just this client until the answer or the
      deadline. Neither another thread nor rclpy's executor machinery (which rebuilds its wait
      set and dispatches through generators on every spin) sits on the path; that machinery was
      most of the round trip (``lit system-bench`` measures it against a bare echo). Answers to
      requests that already timed out are taken and dropped by sequence number, and noted
      (:meth:`answered_late`: the server is alive, it was slow once). Calls must come
      from one thread at a time (a lock enforces it). A call may send its request again while
      it waits (``resend_after``): a request or an answer can be lost with no error on either
      side (the server took the request, sent its answer, and the answer never came, not even
      late: with ROS's default history answers to other clients could push it out, see
      :func:`service_qos`); the server must then take a repeated request as the same one
      (:class:`DirectService` with ``repeat_key``).
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
        self._owner: Any = None
        self._wait_set: Any = None
        self._lock = threading.Lock()
        self._overdue: dict[int, int] = {}
        """Sequence numbers of requests whose deadline passed, not answered yet, each mapped to
        its call (the sequence number of the call's first request; private mode)."""
        self._answered_late: set[int] = set()
        """Overdue calls whose answer has been taken since (private mode)."""
        self.last_overdue: int | None = None
        """The latest call whose deadline passed: its first request's sequence number (private
        mode)."""
        self.resent = 0
        """Requests sent again so far (``resend_after``, private mode)."""
        self.answered_by_copy = 0
        """Calls whose answer came to a copy sent again, not to the first request (private
        mode): the first request or its answer was lost, or the answer was slower than the
        copy's."""
        if private:
            self._owner = node = private_node(node, f"{node.get_name()}_{suffix}")
        self.client = node.create_client(
            srv_type, name, qos_profile=service_qos(), callback_group=callback_group
        )
        if private:
            from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

            with node.context.handle:
                self._wait_set = _rclpy.WaitSet(0, 0, 0, 1, 0, 0, node.context.handle)

    def wait(self, timeout: float, interrupted: Callable[[], bool] | None = None) -> bool:
        """Whether the service appeared within ``timeout`` seconds (DDS discovery). The graph
        shows the server before the server's response writer has matched this client's reader;
        a short settle time keeps the first answers from going nowhere. ``interrupted``: looked
        at every :data:`INTERRUPT_POLL` s; once true the wait raises :class:`CallInterrupted`."""
        if interrupted is None:
            found = self.client.wait_for_service(timeout_sec=timeout)
        else:
            deadline, found = time.monotonic() + timeout, False
            while not found:
                if interrupted():
                    raise CallInterrupted(f"the wait for {self.name} was interrupted")
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                found = self.client.wait_for_service(timeout_sec=min(left, INTERRUPT_POLL))
        if not found:
            return False
        time.sleep(SETTLE_SECONDS)
        return True

    def request(
        self,
        request: Any,
        timeout: float,
        resend_after: float | None = None,
        interrupted: Callable[[], bool] | None = None,
        server_gone: float | None = None,
        max_resends: int | None = None,
    ) -> Any:
        """Send ``request``; the response, or None after ``timeout``. ``resend_after`` (private
        mode only; ignored otherwise): without an answer after that many seconds send the same
        request again, then after twice as long, and so on until the deadline (or until
        ``max_resends`` copies are sent), and take the first answer to any of them (the others
        are dropped when they come). ``interrupted``:
        looked at every :data:`INTERRUPT_POLL` s while waiting; once true the call raises
        :class:`CallInterrupted` (a signal handler that shut the context down does not wake the
        wait set, which would wait out the whole timeout; a server process that died will not
        answer). ``server_gone``: once the graph has shown no server of the service for that
        many seconds in a row while waiting, the call raises :class:`ServerGone` (a node that
        stops removes its service at once; one killed outright, after Fast DDS's lease of
        about 20 s), rather than wait out ``timeout`` for an answer nobody will send."""
        if server_gone is not None:
            interrupted = self._unless_gone(interrupted, server_gone)
        if self._owner is not None:
            return self._request_waiting(request, timeout, resend_after, interrupted, max_resends)
        done = threading.Event()
        future = self.client.call_async(request)
        future.add_done_callback(lambda _: done.set())
        deadline = time.monotonic() + timeout
        while not done.wait(max(0.0, min(deadline - time.monotonic(), INTERRUPT_POLL))):
            try:
                gave_up = interrupted is not None and interrupted()
            except ServerGone:
                self.client.remove_pending_request(future)
                raise
            if gave_up or time.monotonic() >= deadline:
                self.client.remove_pending_request(future)
                if gave_up:
                    raise CallInterrupted(f"the call of {self.name} was interrupted")
                return None
        return future.result()

    def _unless_gone(
        self, interrupted: Callable[[], bool] | None, grace: float
    ) -> Callable[[], bool]:
        """``interrupted``, which also raises :class:`ServerGone` once no server of the service
        has been seen for ``grace`` seconds in a row."""
        missing_since: float | None = None

        def check() -> bool:
            nonlocal missing_since
            if interrupted is not None and interrupted():
                return True
            now = time.monotonic()
            if self.client.service_is_ready():
                missing_since = None
            elif missing_since is None:
                missing_since = now
            elif now - missing_since >= grace:
                raise ServerGone(
                    f"{self.name} went away before it answered (no server for {grace:g} s: "
                    "its node stopped)"
                )
            return False

        return check

    def _request_waiting(
        self,
        request: Any,
        timeout: float,
        resend_after: float | None,
        interrupted: Callable[[], bool] | None = None,
        max_resends: int | None = None,
    ) -> Any:
        with self._lock:
            if self._wait_set is None:
                raise RuntimeError(f"the client of {self.name} was destroyed")
            deadline = time.monotonic() + timeout
            interval = resend_after if resend_after is not None and resend_after > 0 else None
            handle = self.client.handle
            wait_set = self._wait_set
            with self._owner.context.handle, handle:
                sent = [handle.send_request(request)]
                resend = deadline if interval is None else time.monotonic() + interval
                while True:
                    if interrupted is not None and interrupted():
                        raise CallInterrupted(f"the call of {self.name} was interrupted")
                    now = time.monotonic()
                    if now >= deadline:
                        call = sent[0]
                        self.last_overdue = call
                        self._overdue.update(dict.fromkeys(sent, call))
                        while len(self._overdue) > OVERDUE_KEPT:  # a server that never answers
                            del self._overdue[min(self._overdue)]
                        return None
                    if interval is not None and now >= resend:
                        sent.append(handle.send_request(request))
                        self.resent += 1
                        interval *= 2.0
                        resend = now + interval
                        if max_resends is not None and len(sent) > max_resends:
                            resend = deadline  # no more copies
                        continue
                    until = min(deadline, resend)
                    if interrupted is not None:
                        until = min(until, now + INTERRUPT_POLL)
                    _, response, answered = self._take(handle, wait_set, until - now, sent)
                    if response is not None:
                        if answered != sent[0]:
                            self.answered_by_copy += 1
                        return response

    def _take(
        self, handle: Any, wait_set: Any, timeout: float, sequences: Sequence[int]
    ) -> tuple[bool, Any, int | None]:
        """Wait up to ``timeout`` s for one answer and take it: ``(whether one was taken, the
        response if it answers one of ``sequences`` else None, the sequence number it
        answers)``. An answer to an overdue
        request is noted (:meth:`answered_late`) and dropped, as are answers to requests of a
        call already answered. Caller holds the lock and the handles."""
        wait_set.clear_entities()
        wait_set.add_client(handle)
        wait_set.wait(int(timeout * 1e9))
        if handle.pointer not in wait_set.get_ready_entities("client"):
            return False, None, None
        header, response = handle.take_response(self.srv_type.Response)
        if header is None:
            return False, None, None
        answered = header.request_id.sequence_number
        if answered in sequences:
            return True, response, answered
        call = self._overdue.pop(answered, None)
        if call is not None:
            for sequence in [s for s, c in self._overdue.items() if c == call]:
                del self._overdue[sequence]
            self._answered_late.add(call)
            if len(self._answered_late) > OVERDUE_KEPT:
                self._answered_late.discard(min(self._answered_late))
        return True, None, answered

    def answered_late(self, sequence: int | None) -> bool:
        """Whether the overdue request ``sequence`` (:attr:`last_overdue` of its call) has been
        answered since, taking the answers that have arrived without waiting (private mode; a
        shared client's late answers are dropped by its executor: False). An overdue request
        that is answered shows a server that is alive but was slow once."""
        if self._owner is None or sequence is None:
            return False
        with self._lock:
            if self._wait_set is not None:
                handle = self.client.handle
                with self._owner.context.handle, handle:
                    while (
                        sequence in self._overdue.values()
                        and self._take(handle, self._wait_set, 0.0, ())[0]
                    ):
                        pass
            return sequence in self._answered_late

    def call(
        self,
        text: str,
        timeout: float,
        resend_after: float | None = None,
        interrupted: Callable[[], bool] | None = None,
        server_gone: float | None = None,
        max_resends: int | None = None,
    ) -> tuple[bool, str] | None:
        """Send ``text`` as ``load_namespace``; ``(success, message)``, or None after ``timeout``
        (``resend_after``, ``interrupted``, ``server_gone``, ``max_resends``: see
        :meth:`request`)."""
        request = self.srv_type.Request()
        request.load_namespace = text
        response = self.request(
            request, timeout, resend_after, interrupted, server_gone, max_resends
        )
        if response is None:
            return None
        return bool(response.success), str(response.message)

    def destroy(self) -> None:
        """Release the private node (nothing to do for a shared client)."""
        if self._owner is not None:
            with self._lock:
                if self._wait_set is not None:
                    self._wait_set = None
                    self._owner.destroy_node()


PLAN_RESENDS = 3
"""Copies of a plan request ``lit call`` sends at most (after 1, 3 and 7 s without an answer: a
request lost while a new client is matched is lost in its first seconds, and a long query's
answer is not); the planner node keeps an executor thread for each."""

SEND_ATTEMPTS = 20
"""Tries of :func:`send_response` (each waits up to 100 ms for the client's reader): about 2 s,
the most the decide service's one serving thread (and any send waiting for the send lock
meanwhile) may spend on a client that went away."""

_DROPPED = "failed to send response"
"""rclpy's warning when Fast DDS dropped a service's answer."""

_SEND_LOCK = threading.Lock()
"""Serialises :func:`send_response`'s warning filter: ``warnings.catch_warnings`` saves and
restores the process's filter list, and two threads interleaving it would leave the filter on."""


def send_response(
    send: Callable[[Any, Any], None],
    response: Any,
    header: Any,
    name: str,
    log: Any,
    stopping: Callable[[], bool] = lambda: False,
    attempts: int = SEND_ATTEMPTS,
) -> bool:
    """Send a service's answer with ``send`` (a ``Service.send_response``). Fast DDS drops an
    answer (rclpy then warns "failed to send response", after waiting 100 ms) when the client's
    response reader is not matched yet, which happens to a client that calls right after
    discovering the service, more often under load; then try again, ``attempts`` times in all
    (about 0.1 s each). Whether it went out.

    The warning is recorded, not turned into an error: raised from inside rclpy's compiled
    ``send_response`` an error comes out as a ``SystemError`` (a result with an exception set),
    which once escaped and ended the planner node's executor thread. Other warnings caught
    meanwhile (the filter is process-wide) are issued again afterwards. A send that raises is
    logged as an error and counts as not delivered: the thread that serves goes on."""
    for attempt in range(attempts):
        with _SEND_LOCK, warnings.catch_warnings(record=True) as caught:
            # "always": the default action would show (and record) it once per code location.
            warnings.filterwarnings("always", message=_DROPPED, category=RuntimeWarning)
            try:
                send(response, header)
            except Exception as exc:  # noqa: BLE001 - raised into an executor it would end it
                log.error(f"{name}: answer not sent: {exc!r}")
                return False
        dropped = None
        for w in caught:
            if issubclass(w.category, RuntimeWarning) and _DROPPED in str(w.message):
                dropped = w.message
            else:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        if dropped is None:
            return True
        if stopping() or attempt == attempts - 1:
            log.warning(f"{name}: answer not delivered: {dropped}")
            return False
    return False


PLAN_SEND_ATTEMPTS = 100
"""Tries of the planner's plan answers: about 10 s. A plan takes long anyway, the executor has
other threads, and a client that discovered the service while many processes were starting may
stay unmatched for more than 2 s. Only where nothing latency-critical shares the process:
every try holds the process's send lock for up to 100 ms (the learner's export keeps
:data:`SEND_ATTEMPTS`, since its decide service sends through the same lock)."""


def retry_lost_answers(
    service: Any,
    log: Any,
    attempts: int = SEND_ATTEMPTS,
    on_sent: Callable[[], None] | None = None,
) -> Any:
    """Make the executor's answers of ``service`` (an rclpy ``Service``) go through
    :func:`send_response` (``attempts`` tries); returns ``service``. ``on_sent``: called after
    each answer went out (or could not), e.g. to let a shutdown wait for answers still being
    sent before it destroys the node."""
    send = service.send_response
    name = service.srv_name

    def retrying(response: Any, header: Any) -> None:
        try:
            send_response(send, response, header, name, log, attempts=attempts)
        finally:
            if on_sent is not None:
                on_sent()

    service.send_response = retrying  # the executor calls srv.send_response(response, header)
    return service


REPEAT_CLIENTS = 4096
"""Clients whose latest answer a :class:`DirectService` with ``repeat_key`` keeps (the ones
heard from last)."""


class DirectService:
    """Serves one service from a thread of its own on a small node of its own (``name`` of the
    node, no parameter services, no rosout) that no executor spins: the thread waits on an rcl
    wait set holding the service and a stop guard, takes each request, runs ``callback(request,
    response)`` and sends its answer. For a latency-critical service (the learner's decide): no
    executor machinery on the path, and nothing else of the process's node (timers, parameter
    services, other services) can delay it. A callback that raises is logged and answered with
    the empty response, and the thread keeps serving.

    Work the answer does not need can wait until it is sent: the callback hands it to
    :meth:`defer`, and the thread runs it right after sending, before it takes the next request
    (so deferred work and requests keep their order).

    ``repeat_key(request)``: ``(client, identity)`` of a request, or None (not cached). A
    request whose identity equals that of the client's latest answered request is the client's
    copy sent again (``ServiceCaller.call(resend_after=...)``, after a lost request or answer;
    a client has one call in flight, and its copies come in order): it gets the same answer
    again, once tried (a copy to a client not matched yet must not hold the thread for
    seconds), and the callback does not run (:attr:`repeats` counts them). One answer is kept
    per client, for the latest :data:`REPEAT_CLIENTS` clients.
    """

    def __init__(
        self,
        node: Any,
        node_name: str,
        srv_type: Any,
        service: str,
        callback: Callable,
        repeat_key: Callable[[Any], Any] | None = None,
        attempts: int | None = None,
    ) -> None:
        from rclpy.guard_condition import GuardCondition
        from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

        self._log = node.get_logger()
        self._srv_type = srv_type
        self._callback = callback
        self._owner = private_node(node, node_name)
        self._service = self._owner.create_service(
            srv_type, service, callback, qos_profile=service_qos()
        )
        self._stop = GuardCondition(None, None, context=node.context)
        self._stopping = False
        self._busy = threading.Lock()
        """Held by the serving thread from taking a request until its deferred work is done."""
        self._deferred: list[Callable[[], object]] = []
        self._repeat_key = repeat_key
        self._attempts = SEND_ATTEMPTS if attempts is None else attempts
        """Tries of :func:`send_response` for a new answer (default :data:`SEND_ATTEMPTS`)."""
        self._answers: collections.OrderedDict[Any, tuple[Any, Any]] = collections.OrderedDict()
        """Each client's latest request identity and answer, by client (serving thread)."""
        self.repeats = 0
        """Requests answered again from :attr:`_answers` (serving thread)."""
        context = node.context
        with context.handle:
            self._wait_set = _rclpy.WaitSet(0, 1, 0, 0, 1, 0, context.handle)
        self._thread = threading.Thread(target=self._serve, name=f"{node_name}", daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        from rclpy.executors import ExternalShutdownException

        service, stop, wait_set = self._service, self._stop, self._wait_set
        context = self._owner.context
        try:
            while not self._stopping:
                with context.handle, service.handle, stop.handle:
                    wait_set.clear_entities()
                    wait_set.add_service(service.handle)
                    wait_set.add_guard_condition(stop.handle)
                    wait_set.wait(-1)
                    if self._stopping or not context.ok():
                        return
                    if service.handle.pointer not in wait_set.get_ready_entities("service"):
                        continue
                    taken = service.handle.service_take_request(self._srv_type.Request)
                if taken is None or taken[1] is None:
                    continue
                with self._busy:
                    self._answer(*taken)
        except ExternalShutdownException:
            return
        except Exception as exc:  # noqa: BLE001 - RCLError when the context shuts down under the wait
            if context.ok() and not self._stopping:
                self._log.error(f"{service.srv_name}: serving stopped: {exc!r}")
                fail_process(f"{service.srv_name} is no longer served")

    def _answer(self, request: Any, header: Any) -> None:
        """Run the callback (or take a copy's cached answer), send, run the deferred work."""
        service = self._service
        key, response = self._repeated(request, service.srv_name)
        attempts = self._attempts
        if response is not None:  # a copy: the same answer, once tried
            self.repeats += 1
            attempts = 1
        else:
            try:
                response = self._callback(request, self._srv_type.Response())
            except Exception as exc:  # noqa: BLE001 - keep serving
                self._log.error(f"{service.srv_name}: callback failed: {exc!r}")
                response = self._srv_type.Response()
            if key is not None:
                client, identity = key
                self._answers[client] = (identity, response)
                self._answers.move_to_end(client)
                if len(self._answers) > REPEAT_CLIENTS:
                    self._answers.popitem(last=False)
        try:
            send_response(
                service.send_response,
                response,
                header,
                service.srv_name,
                self._log,
                lambda: self._stopping,
                attempts,
            )
        finally:  # the answer is out (or cannot go out): its work is still owed
            self._run_deferred(service.srv_name)

    def _repeated(self, request: Any, name: str) -> tuple[Any, Any]:
        """``(repeat key, the cached answer if the request is a copy else None)``; a key
        function that raises is logged and the request served as new."""
        if self._repeat_key is None:
            return None, None
        try:
            key = self._repeat_key(request)
            if key is None:
                return None, None
            client, identity = key
            cached = self._answers.get(client)
        except Exception as exc:  # noqa: BLE001 - keep serving
            self._log.error(f"{name}: repeat key failed: {exc!r}")
            return None, None
        if cached is not None and cached[0] == identity:
            return key, cached[1]
        return key, None

    def defer(self, work: Callable[[], object]) -> None:
        """Run ``work`` on the serving thread once the current answer is sent (call it from the
        callback only). Work that raises is logged; the thread keeps serving."""
        self._deferred.append(work)

    def _run_deferred(self, name: str) -> None:
        while self._deferred:
            work = self._deferred.pop(0)
            try:
                work()
            except Exception as exc:  # noqa: BLE001 - keep serving
                self._log.error(f"{name}: deferred work failed: {exc!r}")

    def refuse(self, callback: Callable) -> None:
        """Answer every request from now on with ``callback(request, response)`` (e.g. an
        ``unavailable`` Error while the owner shuts down), and return once a request being
        served the old way is answered and its deferred work done."""
        self._callback = callback
        with self._busy:
            pass

    def shutdown(self, timeout: float = 2.0) -> None:
        """Stop the thread and destroy the node."""
        if self._stopping:
            return
        self._stopping = True
        try:
            self._stop.trigger()
        except Exception:  # noqa: BLE001, S110 - the context is already gone: the wait ended
            pass
        self._thread.join(timeout=timeout)
        try:
            self._owner.destroy_node()
        except Exception:  # noqa: BLE001, S110 - a node half torn down by the signal race
            pass


_FAILED = threading.Event()
"""Set by :func:`fail_process`: :func:`spin_node` shuts the node down and exits 1."""


def fail_process(reason: str) -> None:
    """A thread the node cannot do without has ended (a service's serving thread, the executor,
    a planner's or learner's worker): say so on stderr and make :func:`spin_node` shut the node
    down in order and exit 1. Without it the process lived on, serving nothing, and whatever
    supervised it (``lit up``) saw nothing wrong."""
    print(f"error: {reason}; the node shuts down (exit 1)", file=sys.stderr, flush=True)
    _FAILED.set()


def essential(name: str, target: Callable[..., object], *args: object) -> threading.Thread:
    """A daemon thread named ``name`` running ``target(*args)``; an exception that ends it is
    printed with its traceback and ends the process through :func:`fail_process` (a normal
    return does not: the thread's work is over)."""

    def run() -> None:
        try:
            target(*args)
        except BaseException as exc:  # noqa: BLE001 - reported, and the process stops
            import traceback

            traceback.print_exc(file=sys.stderr)
            fail_process(f"thread {name!r} ended: {type(exc).__name__}: {exc}")

    return threading.Thread(target=run, name=name, daemon=True)


def spin_node(
    make_owner: Callable[[], Any],
    args: Sequence[str] | None = None,
    threads: int = 4,
) -> int:
    """Run a node until SIGINT/SIGTERM (or until its owner sets ``finished``), then shut down.

    Args:
        make_owner: builds the object that owns the node (called after ``rclpy.init``); it has a
            ``node`` attribute, optionally a ``finished`` flag (with an ``exit_code``), a
            ``threads`` count (instead of ``threads``) and a ``shutdown()`` method, which runs
            after the signal and before the executor stops.
        args: command line (ROS arguments after ``--ros-args``).
        threads: executor threads.

    Returns:
        0 after a clean shutdown; 1 when the owner's ``shutdown()`` raised (a checkpoint or
        export that could not be written: logged, and the exit code says so), or when a thread
        the node needs ended (:func:`fail_process`); else the owner's ``exit_code`` once it
        ``finished``.
    """
    localhost_environment()
    import rclpy
    from rclpy._rclpy_pybind11 import RCLError
    from rclpy.executors import (
        ExternalShutdownException,
        MultiThreadedExecutor,
        SingleThreadedExecutor,
    )
    from rclpy.signals import SignalHandlerOptions

    # Our own handlers: finish the current work and shut down in order (rclpy's would raise
    # inside whatever thread happens to run).
    try:
        rclpy.init(
            args=list(args) if args is not None else None,
            signal_handler_options=SignalHandlerOptions.NO,
        )
    except RCLError as exc:  # ROS arguments rcl cannot parse (`--ros-args -p` and no rule)
        program = os.path.basename(sys.argv[0])
        raise SystemExit(f"{program}: error: {exc}") from None
    stop = signals.Flag()  # set by a signal, or when the executor's spin ends
    signal.signal(signal.SIGTERM, stop.set)
    signal.signal(signal.SIGINT, stop.set)
    owner = make_owner()
    node = owner.node
    freeze_startup_objects()
    # One thread: rclpy's single-threaded executor has a much shorter callback path (a service
    # round trip of about 0.3 ms against several ms with the thread pool).
    threads = int(getattr(owner, "threads", threads))
    executor = SingleThreadedExecutor() if threads == 1 else MultiThreadedExecutor(threads)
    executor.add_node(node)
    stopping = threading.Event()
    spinner = essential("executor", _spin, executor, stop, stopping)
    spinner.start()
    code = 0
    try:
        while not stop.wait(0.2):
            if getattr(owner, "finished", False):
                code = int(getattr(owner, "exit_code", 0))
                break
            if _FAILED.is_set():
                break
    finally:
        if hasattr(owner, "shutdown"):
            try:
                owner.shutdown()
            except Exception as exc:  # noqa: BLE001 - stop the executor and the node all the same
                node.get_logger().error(f"shutdown failed: {type(exc).__name__}: {exc}")
                code = 1
        stopping.set()
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
    return 1 if _FAILED.is_set() else code


MAX_DOMAIN_ID = 232
"""Largest ROS domain id Fast DDS can use on Linux (it computes its ports from the id; above
this it fails at start-up with "Calculated port number is too high")."""


def service_name_problem(label: str, name: str) -> str | None:
    """Why ``name`` cannot be a ROS service name (rcl's own rules, relative names and ``~``
    included), in words; None when it can. A node given such a name failed at start with
    rclpy's traceback."""
    from rclpy.exceptions import InvalidServiceNameException
    from rclpy.expand_topic_name import expand_topic_name
    from rclpy.validate_full_topic_name import validate_full_topic_name
    from rclpy.validate_topic_name import validate_topic_name

    try:
        validate_topic_name(name, is_service=True)
        # Some rules hold only for the expanded name, which rcl checks when the node creates
        # the service or client (a repeated '/' was a traceback at start). Expanded as in a
        # namespace other than the root ({ns}/x is //x in the root, /robot/x in /robot).
        validate_full_topic_name(expand_topic_name(name, "node", "/ns"), is_service=True)
    except (InvalidServiceNameException, ValueError) as error:
        reason = str(error).splitlines()[0].rstrip(": ").split(", at /")[0]
        return f"{label} {name!r} is not a ROS service name: {reason}"
    return None


def run_id_problem(label: str, run_id: str) -> str | None:
    """Why ``run_id`` cannot be a message envelope's ``run_id``, in words; None when it can (an
    empty one: the node makes one up)."""
    from lit_msgs_json.codec import shown
    from lit_msgs_json.envelope import MessageError, Publisher

    if not run_id:
        return None
    try:
        Publisher("lit", run_id)
    except MessageError as error:
        reason = str(error)
        for quoted in (repr(run_id), shown(run_id)):  # the message quotes it, long ones short
            reason = reason.replace(quoted, "it")
        return f"{label} {run_id[:40]!r}{'...' if len(run_id) > 40 else ''}: {reason}"
    return None


def domain_id(text: str) -> int:
    """An argparse ``type``: a ROS domain id, 0..:data:`MAX_DOMAIN_ID`."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if not 0 <= value <= MAX_DOMAIN_ID:
        raise argparse.ArgumentTypeError(
            f"{value} is not a ROS domain id Fast DDS can use (0-{MAX_DOMAIN_ID})"
        )
    return value


def add_domain_option(parser: argparse.ArgumentParser, default: int) -> None:
    """``--domain-id N``; :func:`resolve_domain_id` turns its value into the domain to use."""
    parser.add_argument(
        "--domain-id",
        type=domain_id,
        default=None,
        metavar="N",
        help=f"ROS domain of the run, 0-{MAX_DOMAIN_ID} (default: $ROS_DOMAIN_ID when set, "
        f"else {default})",
    )


def resolve_domain_id(value: int | None, default: int) -> int:
    """The domain of ``--domain-id`` (``value``), else of ``$ROS_DOMAIN_ID``, else ``default``.

    Raises:
        ValueError: ``$ROS_DOMAIN_ID`` is set to something that is not a usable domain id.
    """
    if value is not None:
        return value
    text = os.environ.get("ROS_DOMAIN_ID", "").strip()
    if not text:
        return default
    try:
        return domain_id(text)
    except argparse.ArgumentTypeError as error:
        raise ValueError(f"$ROS_DOMAIN_ID: {error}; set it right or give --domain-id") from None


def set_domain_id(args: argparse.Namespace, default: int) -> str | None:
    """Resolve a launcher's ``args.domain_id`` (:func:`resolve_domain_id`) in place; the problem
    with ``$ROS_DOMAIN_ID`` if it cannot be used, else None."""
    try:
        args.domain_id = resolve_domain_id(args.domain_id, default)
    except ValueError as error:
        return str(error)
    return None


def spin_quietly(executor: Any, stopping: Callable[[], bool]) -> None:
    """Spin until the executor is shut down.

    While the shutdown has begun (``stopping()`` true, or the context no longer ok), the two
    races it is known to cause are expected and not shown: the signal's race with the context
    (``RCLError``, PLATFORM_FACTS), and rclpy 7.1's own race in ``Executor.shutdown``, which
    destroys its guard condition while a callback that became ready just before (a timer's) is
    still to run (``InvalidHandle`` from ``GuardCondition.trigger``). Any other error raised by a
    callback while stopping is reported on stderr (one line, with its type) rather than lost; the
    stop goes on. Outside a shutdown every error propagates.
    """
    from rclpy.executors import ExternalShutdownException

    try:
        executor.spin()
    except (ExternalShutdownException, KeyboardInterrupt):
        pass
    except Exception as exc:
        import rclpy

        if rclpy.ok() and not stopping():
            raise
        if not _is_shutdown_race(exc):
            print(
                f"warning: while stopping, the executor raised {type(exc).__name__}: {exc}",
                file=sys.stderr,
                flush=True,
            )


def _is_shutdown_race(exc: BaseException) -> bool:
    """Whether ``exc`` is one of the errors a spin racing its shutdown raises (see above)."""
    try:
        from rclpy._rclpy_pybind11 import InvalidHandle, RCLError
    except ImportError:  # pragma: no cover - rclpy without its extension cannot spin at all
        return False
    return isinstance(exc, (InvalidHandle, RCLError))


def _spin(executor: Any, stop: signals.Flag, stopping: threading.Event) -> None:
    """:func:`spin_quietly`; ``stop`` is set when the spin ends (for any reason)."""
    try:
        spin_quietly(executor, stopping.is_set)
    finally:
        stop.set()


def native_output_to_stderr() -> None:
    """Send what native code writes to file descriptor 1 to standard error, for the rest of the
    process, and keep ``sys.stdout`` on the original standard output.

    Fast DDS and rcl log to descriptor 1 (for example Fast DDS's "Failed init_port ...:
    open_and_lock_file failed" when a shared-memory port's lock is stale, after which it carries
    on), while a command's standard output is for its answer (``lit call``'s is parsed as JSON)
    or its report (``lit demo``). Not undone at the end: a native logging thread may still flush
    after the answer.
    """
    sys.stdout.flush()
    answers = os.fdopen(
        os.dup(sys.stdout.fileno()), "w", encoding=sys.stdout.encoding or "utf-8", buffering=1
    )
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())
    # Guarded as lit's own standard output: an answer that cannot be written is one line.
    sys.stdout = GuardedStdout(answers)

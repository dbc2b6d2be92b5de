"""The planner node's answer texts, without a ROS graph."""

from __future__ import annotations

import typing

from lit_msgs_json.envelope import MAX_MESSAGE_BYTES, Publisher, decode
from lit_planner.node import plan_answer_text

from lit_msgs_json import codec


class _Log:
    def __init__(self) -> None:
        self.errors: list[str] = []

    def error(self, text: str) -> None:
        self.errors.append(text)


def _payload(states: int) -> dict:
    return {
        "request_id": "big",
        "status": "exact_solution",
        "solved": True,
        "message": "",
        "scenario": "np16",
        "dimension": 16,
        "planner": "litstar",
        "policy": "fixed",
        "seed": 1,
        "cost": 1.5,
        "t_init": 0.1,
        "c_init": 2.0,
        "time": 1.0,
        "improvements": [[0.1, 2.0], [0.5, 1.5]],
        "path": [[0.123456789012345] * 16 for _ in range(states)],
        "counters": {"iterations": 10},
        "path_valid": True,
    }


def test_an_answer_over_the_message_limit_becomes_an_error_that_says_why() -> None:
    # Before, the encoder's oversize error left the service callback and stopped the executor,
    # so the node ended and the client never had an answer.
    reply, log = Publisher("planner", "run-1"), _Log()
    states = MAX_MESSAGE_BYTES // (16 * 17) + 100
    success, text = plan_answer_text(reply, _payload(states), 7, log)
    assert not success
    error = decode(text, accept="Error").payload
    assert error["code"] == "oversize"
    assert error["request_schema"] == "PlanRequest" and error["request_seq"] == 7
    assert f"{states} path states" in error["message"] and "cost 1.5" in error["message"]
    assert len(log.errors) == 1 and "'big'" in log.errors[0]
    plan_answer_text(reply, {**_payload(states), "request_id": None}, 8, log, "req-1a2b")
    assert "plan request 'req-1a2b'" in log.errors[1]  # the id a request without one has here


def test_an_answer_within_the_limit_is_the_plan_response() -> None:
    reply, log = Publisher("planner", "run-1"), _Log()
    success, text = plan_answer_text(reply, _payload(20), 3, log)
    assert success and not log.errors
    message = decode(text, accept="PlanResponse")
    assert message.payload["request_id"] == "big" and len(message.payload["path"]) == 20


def test_a_cancel_copy_is_keyed_by_its_text_and_the_plans_queued_with_its_id() -> None:
    from types import SimpleNamespace

    from lit_planner.node import _cancel_repeat_key

    publisher = Publisher("my_client", "run-1")
    text = publisher.encode("CancelRequest", {"request_id": "a"})
    request = SimpleNamespace(load_namespace=text)
    generations = {"a": 1, "b": 5}
    client, identity = _cancel_repeat_key(request, generations)
    assert client == ("my_client", "run-1")
    assert _cancel_repeat_key(request, dict(generations)) == (client, identity)
    generations["b"] += 1  # another id's plan: still the same cancel
    assert _cancel_repeat_key(request, generations) == (client, identity)
    generations["a"] += 1  # a new plan with its id: a new cancel
    assert _cancel_repeat_key(request, generations)[1] != identity
    other = SimpleNamespace(load_namespace=publisher.encode("CancelRequest", {"request_id": "a"}))
    assert _cancel_repeat_key(other, generations)[1] != _cancel_repeat_key(request, generations)[1]
    assert _cancel_repeat_key(SimpleNamespace(load_namespace="not json"), generations) is None


def test_a_count_limited_request_without_time_becomes_a_job_with_the_longest_time() -> None:
    """A plan request with max_iterations or max_batches and no `time` gets the schema's longest
    time (it had no limit: a large count kept the worker busy for good); one with a `time` keeps
    it, and one with neither gets the scenario's budget. The request-to-job rule alone, without a
    running node (planning 600 s to see the limit would not fit in a test)."""
    from types import SimpleNamespace

    from lit_planner import node

    fake: typing.Any = SimpleNamespace(params={"policy": "fixed", "seed": 7})
    fake._problem_from_request = lambda payload: node.PlannerNode._problem_from_request(
        fake, payload
    )
    make = node.PlannerNode._job_from_request
    for limit in ({"max_iterations": 10**9}, {"max_batches": 10**6}):
        job = make(fake, {"scenario": "np4", **limit})
        assert job.time == node.MAX_REQUEST_TIME == 600.0
    assert (
        node.MAX_REQUEST_TIME == codec.load_schema("PlanRequest")["properties"]["time"]["maximum"]
    )
    assert make(fake, {"scenario": "np4", "max_iterations": 5, "time": 2.5}).time == 2.5
    assert make(fake, {"scenario": "np4"}).time is None  # the scenario's budget
    assert make(fake, {"scenario": "np4"}).seed == 7


def test_the_nodes_logger_logs_text_that_is_not_unicode() -> None:
    """rclpy's logger raises for a lone surrogate; in the planner node's worker thread that ended
    the thread. The nodes' SafeLogger logs it escaped and passes other text through as is."""
    from lit_planner.safe_logger import SafeLogger

    class StrictLogger:  # as rclpy's: the message must encode to UTF-8
        def __init__(self) -> None:
            self.lines: list[tuple[str, str]] = []
            self.name = "strict"

        def _log(self, level: str, message: str) -> bool:
            message.encode("utf-8")
            self.lines.append((level, message))
            return True

        def info(self, message: str) -> bool:
            return self._log("info", message)

        def warning(self, message: str) -> bool:
            return self._log("warning", message)

        def error(self, message: str) -> bool:
            return self._log("error", message)

    strict = StrictLogger()
    log = SafeLogger(strict)
    log.info("plan request \ud800 started")
    log.warning("ψ_K é")
    log.error(ValueError("x\udfff"))
    # A client's text with a newline, a carriage return, an ANSI colour and a NUL forged log
    # lines or cut them short: one line, escaped (a tab stays).
    log.info("plan request a\x00b\nforged\r\x1b[31mred\tend")
    log.info("C1 \x85\x9b, separators \u2028\u2029, an override \u202e: ψ é")
    assert strict.lines == [
        ("info", "plan request \\ud800 started"),
        ("warning", "ψ_K é"),
        ("error", "x\\udfff"),
        ("info", "plan request a\\x00b\\x0aforged\\x0d\\x1b[31mred\tend"),
        ("info", "C1 \\x85\\x9b, separators \\u2028\\u2029, an override \\u202e: ψ é"),
    ]
    assert log.name == "strict"


def test_the_duplicate_server_watch_logs_both_ends_of_a_duplicate(monkeypatch: typing.Any) -> None:
    """The node that outlived a duplicate server died ("Logger severity cannot be changed
    between calls"): with SafeLogger's file counted as rclpy's own, rclpy credited the watch's
    error and its later info line to one call site, the line that ran the check."""
    import rclpy
    from lit_planner.safe_logger import SafeLogger
    from lit_planner.testing import reserve_ros_domain

    from lit_planner import rosutil

    # Its own domain on this host alone, also under a plain pytest (lit test exports both).
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")  # read by rclpy.init
    domain, claim = reserve_ros_domain()
    context = rclpy.Context()
    rclpy.init(args=[], context=context, domain_id=domain)
    try:
        node = rclpy.create_node("duplicate_watch_test", context=context)
        SafeLogger(node.get_logger())  # as the nodes make theirs

        class Graph:  # the real node's logger and context, a graph of our choosing
            servers = 2
            context = node.context

            def resolve_service_name(self, name: str) -> str:
                return name

            def count_services(self, name: str) -> int:
                return self.servers

            def get_logger(self) -> typing.Any:
                return node.get_logger()

        monkeypatch.setattr(rosutil, "DEAD_SERVER_SECONDS", 0.0)
        graph = Graph()
        watch = rosutil.DuplicateServerWatch(graph, "/lit/planner/plan")
        for servers in (2, 1, 2, 1):  # an error, then an info line, from this one line
            graph.servers = servers
            assert watch.check() == servers
        assert not watch.reported
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)
        if claim is not None:
            claim.close()


def test_the_ready_line_names_where_the_episodes_come_from() -> None:
    """It said "scenario np8" in training mode, whose episodes are drawn from the training mix."""
    from lit_planner.node import PARAMETERS, _episodes_shown

    training = PARAMETERS | {"policy": "training", "episodes": 5}
    assert _episodes_shown(training) == f"5 episodes drawn from {PARAMETERS['training_scenarios']}"
    on_scenario = training | {"episodes_from": "scenario", "scenario": "rrd4"}
    assert _episodes_shown(on_scenario) == "5 episodes on rrd4"
    inference = PARAMETERS | {"policy": "tensor", "episodes": 2}
    assert _episodes_shown(inference) == f"2 episodes on {PARAMETERS['scenario']}"
    assert _episodes_shown(inference | {"episodes_from": "training"}).startswith("2 episodes drawn")
    assert _episodes_shown(PARAMETERS | {"episodes": 0}) == "no episodes of its own"


def test_a_copy_queued_while_its_original_is_read_is_answered_with_one_plan() -> None:
    """A resent plan request can arrive while the first one is still being read into a job (its
    scenario built, outside the queue's lock). Both used to find no job under their text and
    both were planned. The copy check is made again under the lock the job is queued under: the
    one read second waits for the other's job. Two service threads, without a ROS graph."""
    import collections
    import queue
    import threading
    from types import SimpleNamespace

    from lit_planner import node

    fake: typing.Any = SimpleNamespace(
        envelopes={"reply": Publisher("planner", "run-p")},
        params={"policy": "fixed", "seed": 1, "queue_limit": 4},
        log=SimpleNamespace(info=lambda text: None, warning=lambda text: None, error=print),
        _queue_lock=threading.Lock(),
        _plan_copies=collections.OrderedDict(),
        _stopping=threading.Event(),
        _cancelled_early={},
        _queued=0,
        _requests=[],
        _id_generations=collections.OrderedDict(),
        _jobs=queue.Queue(),
    )
    first_reading, go_on = threading.Event(), threading.Event()

    def job_from_request(payload: dict, seq: int | None = None) -> node.Job:
        if not first_reading.is_set():  # the first read is slow: the copy is read and queued
            first_reading.set()
            assert go_on.wait(30)
        return node.PlannerNode._job_from_request(fake, payload, seq)

    fake._job_from_request = job_from_request
    fake._problem_from_request = lambda p: node.PlannerNode._problem_from_request(fake, p)
    fake._queue_plan = lambda *args: node.PlannerNode._queue_plan(fake, *args)
    fake._plan_response = lambda job: _payload(2)
    text = Publisher("my_client", "run-c").encode("PlanRequest", {"scenario": "np4"})
    answers: list[typing.Any] = []

    def serve() -> None:
        response = SimpleNamespace(success=None, message="")
        request = SimpleNamespace(load_namespace=text)
        answers.append(node.PlannerNode._plan_answer(fake, request, response))

    threads = [threading.Thread(target=serve, daemon=True) for _ in range(2)]
    threads[0].start()
    assert first_reading.wait(30)
    threads[1].start()  # the copy: read at once, queued
    job = fake._jobs.get(timeout=30)
    go_on.set()  # the first one now finds the copy's job
    for _ in range(300):
        with fake._queue_lock:
            if job.copies == 1:
                break
        threading.Event().wait(0.1)
    assert job.copies == 1 and fake._queued == 1 and fake._jobs.empty()
    job.result = {}
    job.done.set()
    for thread in threads:
        thread.join(30)
    assert len(answers) == 2 and all(answer.success for answer in answers)
    assert fake._jobs.empty() and list(fake._plan_copies.values()) == [job]


def test_the_shortest_episode_budget_is_one_number_everywhere() -> None:
    """The schemas' minimum of an episode's time_budget, the learner's check, the planner node's
    parameter check and the scale factors' floor (lit bench, lit train) say the same."""
    from lit_learner.messages import MIN_TIME_BUDGET

    from lit_planner import planning, rosutil

    for name in ("DecideRequest", "EpisodeEnd"):
        minimum = codec.load_schema(name)["properties"]["time_budget"]["minimum"]
        assert minimum == rosutil.MIN_EPISODE_BUDGET == MIN_TIME_BUDGET == planning.MIN_TIME


def test_learner_resends_are_reported_in_one_line_a_minute_and_at_shutdown() -> None:
    from lit_planner.node import RESEND_REPORT_EVERY, ResendTally

    tally = ResendTally(now=100.0)
    assert tally.flush(100.0) is None  # nothing sent again: no line
    first = tally.add(3, 1, now=100.0)  # the first episode that sent any is reported at once
    assert first is not None and first.startswith("1 training episode sent 3 learner requests")
    assert "1 calls answered through a copy" in first
    # Under load: every episode sends some again; they are summed, not a line each.
    assert [tally.add(2, 0, now=100.0 + i) for i in range(1, 11)] == [None] * 10
    due = tally.add(1, 2, now=100.0 + RESEND_REPORT_EVERY)
    assert due is not None and due.startswith("11 training episodes sent 21 learner requests")
    assert "2 calls answered through a copy" in due
    assert tally.add(4, 0, now=101.0 + RESEND_REPORT_EVERY) is None
    last = tally.flush(102.0 + RESEND_REPORT_EVERY)  # at shutdown: what was not reported yet
    assert last is not None and last.startswith("1 training episode sent 4 learner requests")
    assert tally.flush(103.0 + RESEND_REPORT_EVERY) is None

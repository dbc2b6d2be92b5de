"""``lit_planner_node``: the LIT* planner as a ROS 2 node.

- Serves ``lit/planner/plan`` (``diagnostic_msgs/srv/AddDiagnostics`` carrying a PlanRequest
  envelope in ``load_namespace``; the PlanResponse or an Error in ``message``). Planning runs on one
  worker thread, off the executor, so the node keeps answering while it plans; requests that arrive
  while it is busy wait in a queue of ``queue_limit`` places, and beyond that are refused with a
  ``busy`` Error (never dropped silently).
- Serves ``lit/planner/cancel`` (same carrier; a CancelRequest naming a ``request_id``, or the
  ``req-<hex>`` the node logged for a plan request without one): the running plan request that
  carries it stops within an iteration and is answered with what it found, queued ones are
  answered without planning (status ``cancelled`` for both).
- On shutdown (SIGTERM, Ctrl-C) the running plan request stops within an iteration: answered
  with the best path found until then (status ``shutdown``; nothing of it is published), or,
  without one, with an ``unavailable`` Error, as the queued requests are.
- Publishes ``lit/solution`` live, and after every query ``lit/observation`` and ``lit/decision``
  (one per decision point, from the planner's own record, so publishing never runs inside the timed
  loop), ``lit/episode`` (EpisodeSummary) and ``lit/path`` (``trajectory_msgs/JointTrajectory``).
- ``policy: training``: a loop of ``episodes`` training queries over the training distribution;
  each decision calls the learner's ``/lit/learner/decide`` with a deadline of
  ``decision_timeout`` s; a call without an answer after ``learner_resend`` s or an eighth of
  its deadline, whichever is longer (then twice as long, and so on), sends its request again,
  since a request or an answer can be lost silently (``rosutil.service_qos`` removed one cause;
  the learner answers a repeated request again without taking it twice; 0: never). A late or
  absent learner: that decision falls back to the tensor policy
  (``fixed`` without tensors), the episode is marked, a warning is logged (again when a second
  miss in a row starts the window), and for ``learner_retry`` s no decision call is tried
  (episode ends are still sent); then training resumes with the learner. Calls resume sooner
  when the learner answers the missed call late (a busy machine delayed one answer: the learner
  is alive), unless two calls in a row missed
  (a late answer does not reset that count: a learner whose every answer is late gets the
  window). An episode end waits ``max(1 s, 20 * decision_timeout)``, and ``decision_timeout``
  after two calls in a row missed. The first call waits up to ``first_decision_timeout`` s
  instead (or ``decision_timeout`` if longer; that call only: a learner that never answers
  costs each later call ``decision_timeout``): Fast DDS
  drops a server's first answers to a client it has not matched yet and the server sends again
  about 100 ms later (``rosutil.send_response``), so a first call under load took 60-250 ms and
  fell back, and with it every decision of the next ``learner_retry`` s (whole `lit demo`
  episodes). The planner's clock is paused meanwhile, as for every call.
- Other policies with ``episodes > 0``: that many inference queries on ``scenario`` (seeds
  ``seed``, ``seed + 1``, ...), then the node keeps serving.
- ``episodes_from``: ``training`` draws the episodes from the training distribution
  (``training_scenarios``, ``training_seed``; a node in a namespace draws its own problems for
  the seed) whatever the policy, ``scenario`` plans ``scenario``;
  empty: the distribution in training mode, the scenario otherwise. The same draws with two
  policies are the same problems (``lit system-bench`` compares them).
- ``decision_interval``: expansions per psi_K decision; 0 (default): 1 in training, and for the
  tensor policy the interval its psi_K tensor was trained with (else 1).
- ``wait_for_subscribers: N`` holds the episodes back until every topic has N matched
  subscriptions (``lit up`` and ``lit demo`` set it for their recorder), so a recording starts
  with the first message.

The C++ planner's clock is paused while the learner answers, so training and inference see the
same planning time.
"""

from __future__ import annotations

import collections
import math
import os
import queue
import sys
import threading
import time
import uuid
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from lit_msgs_json.envelope import MessageError, decode

from lit_planner.episode_messages import (
    DecisionSources,
    EventLog,
    decision_payloads,
    encode_summary,
    finite,
    path_timing,
    summary_payload,
    unit,
)
from lit_planner.errors import PlannerError, ScenarioError, TensorFileError
from lit_planner.rosutil import (
    CANCEL_SERVICE,
    DECIDE_SERVICE,
    MAX_REQUEST_TIME,
    MIN_EPISODE_BUDGET,
    PLAN_RESENDS,
    PLAN_SEND_ATTEMPTS,
    PLAN_SERVICE,
    TOPICS,
    CallInterrupted,
    DirectService,
    DuplicateServerWatch,
    ServiceCaller,
    declare_parameters,
    episode_budget_limit,
    essential,
    flush_publishers,
    json_qos,
    retry_lost_answers,
    run_id_problem,
    service_name_problem,
    service_qos,
    spin_node,
)
from lit_planner.safe_logger import SafeLogger

NODE_NAME = "lit_planner"
MODES = ("tensor", "fit", "fixed", "training")
"""Values of the ``policy`` parameter."""
FIXED_BATCH, FIXED_FACTOR = 100.0, math.e
"""The fixed policy's values (the fallback when no tensors are available)."""
PARAMETERS: dict[str, Any] = {
    "scenario": "np8",
    "policy": "tensor",
    "time_budget": 0.0,
    "seed": 1,
    "episodes": 0,
    "learner_service": DECIDE_SERVICE,
    "decision_timeout": 0.05,
    "first_decision_timeout": 1.0,
    "decision_interval": 0,
    "learner_retry": 1.0,
    "learner_resend": 0.01,
    "learner_wait": 10.0,
    "tensors_dir": "",
    "training_scenarios": "np4,np8,wg4,wg8,rrd4,rrd8",
    "training_seed": 7,
    "queue_limit": 4,
    "run_id": "",
    "explore": True,
    "exit_when_done": False,
    "wait_for_subscribers": 0,
    "episodes_from": "",
}
"""The node's ROS parameters and their defaults."""

MIN_RESEND = 0.001
"""The shortest ``learner_resend`` (s) taken: shorter sends many copies to no purpose."""

CANCEL_EARLY = 10.0
"""Seconds a CancelRequest naming no known plan request is remembered: a plan request with that
request_id arriving meanwhile is answered as cancelled, once."""
ID_GENERATIONS = 4096
"""request_ids whose count of queued plan requests the node keeps (``_cancel_repeat_key``)."""
PLAN_COPIES_KEPT = 32
"""Answered plan requests, the latest, whose copies (the same text from the same client: a
request sent again because its answer was slow to come) are answered with their result instead
of being planned again (``PlannerNode._plan_copies``; those queued or running are all kept; one
answered ``unavailable`` for its tensor files is not: its copies are planned again)."""
EXECUTOR_THREADS = 8
"""The planner node's executor threads at least; more for a long queue (``PlannerNode.threads``)."""
SPARE_THREADS = 3
"""Executor threads kept free of plan requests (the running one and ``queue_limit`` waiting)."""
INVALID_TERMINAL = {"invalid_start": "start", "invalid_goal": "goal"}
"""Core statuses that mean the request gave an unusable start or goal."""


def _cancel_repeat_key(
    request: Any, generations: Mapping[str, int]
) -> tuple[tuple[str, str], tuple[int, int]] | None:
    """A cancel request's client (the envelope's source and run) and identity (its text, and how
    many plan requests with its ``request_id`` the node has queued so far): a client's copy
    sent again is the same text, answered again without cancelling twice (a second cancel of a
    request just dropped would be remembered, and cancel a new request of that id). The same
    text after a new plan request with that id is a new cancel (a client that reuses its
    envelope and its ids got the first answer again, and the new plan ran on). None for a text
    the service rejects (served, and rejected, as new)."""
    from lit_msgs_json.envelope import MessageError, decode

    text = request.load_namespace
    try:
        message = decode(text, accept="CancelRequest")
    except MessageError:
        return None
    generation = generations.get(message.payload["request_id"], 0)
    return (message.source, message.run_id), (hash(text), generation)


def max_episode_id() -> int:
    """Longest ``episode_id`` the messages take (``maxLength`` in their schemas)."""
    from lit_msgs_json.codec import load_schema

    return int(load_schema("DecideRequest")["properties"]["episode_id"]["maxLength"])


def episode_id(run_id: str, index: int) -> str:
    """The id of the node's own episode ``index`` (``episodes``) in run ``run_id``."""
    return f"{run_id}/{index}"


def parameter_problem(p: Mapping[str, Any]) -> str | None:
    """What is wrong with the node's parameter values (``p`` holds every parameter), None when
    they are usable. The node exits with it at start; ``lit up`` asks before it starts anything."""
    from lit_planner import scenarios
    from lit_planner.errors import LitPlannerError
    from lit_planner.planning import MAX_DECISION_INTERVAL, MAX_SEED

    if p["policy"] not in MODES:
        return f"policy must be one of {MODES}, got {p['policy']!r}"
    if not 0 <= p["decision_interval"] <= MAX_DECISION_INTERVAL:  # beyond: every query refused
        return (
            "decision_interval must be 0 (training: 1; the tensor policy: the psi_K tensor's "
            f"training interval) up to {MAX_DECISION_INTERVAL}, got {p['decision_interval']}"
        )
    if p["episodes_from"] not in ("", "training", "scenario"):
        return f"episodes_from must be training, scenario or empty, got {p['episodes_from']!r}"
    for name in ("time_budget", "episodes", "queue_limit", "wait_for_subscribers"):
        if not p[name] >= 0:  # also NaN
            return f"{name} must be 0 or more, got {p[name]}"
    if p["policy"] == "training" and 0 < p["time_budget"] < MIN_EPISODE_BUDGET:
        return (
            f"time_budget must be 0 (the scenario's) or at least {MIN_EPISODE_BUDGET:g} s with "
            f"policy training (the learner refuses less), got {p['time_budget']}"
        )
    limit = episode_budget_limit(p["policy"])
    if not p["time_budget"] <= limit:
        # Beyond 3600 s every training decision and episode end failed their schemas (the
        # learner learned nothing), beyond 86400 s every observation, beyond 1e9 every query.
        return (
            f"time_budget must be 0 (the scenario's) or at most {limit:g} s with policy "
            f"{p['policy']}, got {p['time_budget']}"
        )
    for name in ("learner_retry", "learner_wait", "learner_resend"):
        if not (math.isfinite(p[name]) and p[name] >= 0):
            return f"{name} must be 0 or more seconds, got {p[name]}"
    if 0 < p["learner_resend"] < MIN_RESEND:
        return (
            f"learner_resend must be 0 (never send again) or at least {MIN_RESEND:g} s, got "
            f"{p['learner_resend']}"
        )
    for name in ("decision_timeout", "first_decision_timeout"):
        if not (math.isfinite(p[name]) and p[name] > 0):
            return f"{name} must be a finite positive number of seconds, got {p[name]}"
    for name in ("seed", "training_seed"):
        if not 0 <= p[name] <= MAX_SEED:
            return f"{name} must be between 0 and {MAX_SEED}, got {p[name]}"
    problem = service_name_problem("learner_service", p["learner_service"]) or run_id_problem(
        "run_id", p["run_id"]
    )
    if problem:
        return problem
    if p["episodes"] > 0:  # the only use of scenario and training_scenarios
        last, longest = episode_id(p["run_id"], p["episodes"] - 1), max_episode_id()
        if len(last) > longest:  # each such episode's messages were refused
            return (
                f"run_id of {len(p['run_id'])} characters: with {p['episodes']} episodes the "
                f"last one's id has {len(last)}, more than the {longest} the messages allow"
            )
        from lit_learner.train import TrainingDistribution, TrainingError

        drawn = _episodes_drawn(p)
        name = "training_scenarios" if drawn else "scenario"
        try:
            if drawn:
                TrainingDistribution(scenarios.split_names(p[name]), None)
            else:
                scenarios.get(p[name])
        except (LitPlannerError, TrainingError) as error:
            return f"{name} {p[name]!r}: {error}"
        if not drawn and p["seed"] + p["episodes"] - 1 > MAX_SEED:  # episode i plans seed + i
            return (
                f"seed {p['seed']} with {p['episodes']} episodes: their seeds seed + i pass "
                f"{MAX_SEED}"
            )
    return None


def _episodes_drawn(p: Mapping[str, Any]) -> bool:
    """Whether the node's own episodes come from the training distribution (else ``scenario``)."""
    training = p["policy"] == "training"
    return p["episodes_from"] == "training" or (training and p["episodes_from"] != "scenario")


def _episodes_shown(p: Mapping[str, Any]) -> str:
    """The node's own episodes in words, for its ready line."""
    if p["episodes"] <= 0:
        return "no episodes of its own"
    if _episodes_drawn(p):
        return f"{p['episodes']} episodes drawn from {p['training_scenarios']}"
    return f"{p['episodes']} episodes on {p['scenario']}"


RESEND_REPORT_EVERY = 60.0
"""Seconds between the planner node's lines on learner requests sent again (and one at shutdown)."""


class ResendTally:
    """Counts learner requests sent again over the training episodes and words one line for them
    at most every :data:`RESEND_REPORT_EVERY` s: the first episode that sent any is reported at
    once, later ones are summed until the interval has passed (``flush`` reports what is left)."""

    def __init__(self, now: float) -> None:
        self._lock = threading.Lock()
        self._last_report = now - RESEND_REPORT_EVERY
        self._episodes = self._resent = self._by_copy = 0

    def add(self, resent: int, by_copy: int, now: float) -> str | None:
        """Adds one episode's counts; the line to log if one is due, else None."""
        with self._lock:
            self._episodes += 1
            self._resent += resent
            self._by_copy += by_copy
            if now - self._last_report < RESEND_REPORT_EVERY:
                return None
            return self._report(now)

    def flush(self, now: float) -> str | None:
        """The line for what was not reported yet, or None."""
        with self._lock:
            return self._report(now) if self._episodes else None

    def _report(self, now: float) -> str:
        episodes = (
            "1 training episode" if self._episodes == 1 else f"{self._episodes} training episodes"
        )
        line = (
            f"{episodes} sent {self._resent} learner requests again (no answer within "
            f"learner_resend or an eighth of the deadline, then twice as long, ...); "
            f"{self._by_copy} calls answered through a copy"
        )
        self._last_report = now
        self._episodes = self._resent = self._by_copy = 0
        return line


@dataclass
class Job:
    """One query for the worker: a plan request (service) or an episode (training/inference)."""

    kind: str
    """``service``, ``training`` or ``inference``."""
    scenario: Any
    """The :class:`lit_planner.scenarios.Scenario`."""
    policy: str
    planner: str = "litstar"
    time: float | None = None
    seed: int = 1
    max_iterations: int = 0
    max_batches: int = 0
    request_id: str | None = None
    request_seq: int | None = None
    """The plan request's envelope seq (for an Error that answers it)."""
    episode_id: str = ""
    fell_back: set[str] = field(default_factory=set)
    """Training: agents that executed a fallback value since their last answered learner call
    (the learner drops their pending steps: its action was not the one executed)."""
    done: threading.Event = field(default_factory=threading.Event)
    result: dict[str, Any] | None = None
    error: BaseException | None = None
    cancelled: threading.Event = field(default_factory=threading.Event)
    """Set by a CancelRequest naming the job's ``episode_id`` (its ``request_id``, else the
    node's ``req-<hex>``; plan requests only)."""
    stop: Any = None
    """The running query's ``lit_core.CancelFlag``: set by a CancelRequest or by shutdown()."""
    cut_short: bool = False
    """The query was cut short by shutdown() (an episode so ended is not done)."""
    copies: int = 0
    """Copies of its plan request waiting for its result (plan requests only)."""


class PlannerNode:
    """Builds the ROS node; the planning itself lives in :mod:`lit_planner.planning`."""

    def __init__(self) -> None:
        from lit_msgs_json.envelope import Publisher
        from rclpy.callback_groups import ReentrantCallbackGroup
        from rclpy.node import Node
        from std_msgs.msg import String
        from trajectory_msgs.msg import JointTrajectory

        from lit_msgs_json import MESSAGE_VERSIONS, prepare

        self.node = node = Node(NODE_NAME)
        self.log = SafeLogger(node.get_logger())
        p = self._declare(**PARAMETERS)
        self.params = p
        problem = parameter_problem(p)
        if problem is not None:
            raise SystemExit(f"lit_planner_node: {problem}")
        self.run_id = p["run_id"] or f"{time.strftime('%Y%m%d-%H%M%S')}-{uuid.uuid4().hex[:6]}"
        self.source = node.get_fully_qualified_name()
        self.finished = False
        self.exit_code = 0
        """The process's exit code once ``finished`` (``exit_when_done``): 1 when an episode
        failed."""
        self.threads = max(
            EXECUTOR_THREADS, (int(p["queue_limit"]) + 1) * (1 + PLAN_RESENDS) + SPARE_THREADS
        )
        """Executor threads (spin_node): each plan request in progress or waiting holds one, as
        does each copy of it that ``lit call`` sends, and busy answers, cancels, parameter
        services and timers need their own (with 8 threads a queue_limit of 8 left none:
        requests beyond it waited unanswered instead of busy)."""
        qos = json_qos()
        self._string = String
        self._trajectory = JointTrajectory
        self.publishers = {
            name: node.create_publisher(String, TOPICS[name], qos)
            for name in ("observation", "decision", "solution", "episode")
        }
        self.path_publisher = node.create_publisher(JointTrajectory, TOPICS["path"], qos)
        self.envelopes = {
            name: Publisher(self.source, self.run_id)
            for name in ("observation", "decision", "solution", "episode", "decide", "reply")
        }
        self._publish_lock = threading.Lock()
        self._learner_answered = False
        """Whether a learner answer has reached the planner: one in time, or a missed call's
        late answer seen by :meth:`_learner_caught_up` (until then, and while no call missed,
        calls wait ``first_decision_timeout``)."""
        # The validators of every message the node reads or writes, built now rather than in
        # the first query (about 10 ms each, inside a learner call's deadline or a plan).
        prepare(MESSAGE_VERSIONS)
        self._fallback = self._fallback_values()
        from lit_planner.planning import TensorPolicyCache

        self._tensor_policies = TensorPolicyCache()
        if p["policy"] == "tensor":
            # Read now, so that the first query does not pay for it just before its search.
            try:
                self._tensor_policies.get(p["tensors_dir"] or None)
            except Exception as exc:  # noqa: BLE001 - each tensor query answers with it
                self.log.error(f"tensor policy unusable for now: {exc}")
        # Only the planning thread calls the learner: it spins the client's own node while it
        # waits, so answers do not queue behind the plan service on the shared executor.
        self.learner = ServiceCaller(node, p["learner_service"], private=True, suffix="learner")
        self._learner_down_until = 0.0
        self._missed_in_a_row = 0
        """Learner calls (decisions and episode ends) that missed their deadline since one was
        answered in time."""
        self._missed_call: int | None = None
        """The request sequence of the latest call that missed (``ServiceCaller.last_overdue``)."""
        self._resends = ResendTally(time.monotonic())
        """Learner requests sent again, reported in one line at most every ``RESEND_REPORT_EVERY``
        s (under load most episodes send some again: a line each drowned the log)."""
        self._jobs: queue.Queue[Job | None] = queue.Queue()
        self._queued = 0
        self._queue_lock = threading.Lock()
        self._stopping = threading.Event()
        self._unanswered = 0
        """Plan requests taken whose answer is not sent yet (a send may retry for seconds for a
        client that matches late): the shutdown waits for them before the node is destroyed."""
        self._answers_sent = threading.Condition()
        self._running: Job | None = None
        """The query the worker runs; shutdown() sets its ``stop`` flag (a 600 s request held
        the node past lit up's grace, which then killed it), and queued ones are not started."""
        self._requests: list[Job] = []
        """Plan requests queued or running, which a CancelRequest may name (under the lock)."""
        self._id_generations: collections.OrderedDict[str, int] = collections.OrderedDict()
        """Plan requests queued so far by request_id, for the latest ID_GENERATIONS ids (read
        by the cancel service's repeat key; written under the lock)."""
        self._plan_copies: collections.OrderedDict[tuple[str, str, int], Job] = (
            collections.OrderedDict()
        )
        """Plan requests queued or running, and the latest PLAN_COPIES_KEPT answered, by client
        (source, run) and text: a copy of one is answered with its result, not planned again
        (under the lock)."""
        self._cancelled_early: dict[str, float] = {}
        """request_ids a CancelRequest named before any plan request carried them, with when
        (time.monotonic()): a plan request that arrives within CANCEL_EARLY s is answered as
        cancelled (a client that gave up just after sending; under the lock)."""
        self._worker = essential("planner", self._work)
        self._worker.start()
        from diagnostic_msgs.srv import AddDiagnostics

        retry_lost_answers(
            node.create_service(
                AddDiagnostics,
                PLAN_SERVICE,
                self._serve_plan,
                qos_profile=service_qos(),
                callback_group=ReentrantCallbackGroup(),
            ),
            self.log,
            attempts=PLAN_SEND_ATTEMPTS,
            on_sent=self._answer_sent,
        )
        # A thread of its own: plan callbacks hold executor threads while their queries run or
        # wait, and a cancel must not wait for one of them to end.
        self._cancel_service = DirectService(
            node,
            f"{NODE_NAME}_cancel",
            AddDiagnostics,
            CANCEL_SERVICE,
            self._serve_cancel,
            # a copy sent again gets the same answer
            repeat_key=lambda request: _cancel_repeat_key(request, self._id_generations),
            attempts=PLAN_SEND_ATTEMPTS,  # a new `lit call cancel` may match late, as for plans
        )
        DuplicateServerWatch(node, PLAN_SERVICE).start()
        self._driver = essential("episodes", self._drive)
        self._driver.start()
        self.log.info(
            f"ready: policy {p['policy']}, {_episodes_shown(p)}, run_id {self.run_id}, "
            f"service {node.resolve_service_name(PLAN_SERVICE)}, "
            f"cancel {node.resolve_service_name(CANCEL_SERVICE)}"
        )

    # ------------------------------------------------------------------ parameters

    def _declare(self, **defaults: Any) -> dict[str, Any]:
        return declare_parameters(self.node, defaults, "lit_planner_node")

    def _fallback_values(self) -> dict[str, Any]:
        """Lookups answering decisions the learner could not, each in the mode its sidecar
        names, as the tensor policy looks up (None entries: fixed values)."""
        from lit_planner import planning, tensor_files

        folder = self.params["tensors_dir"] or str(planning.default_tensors_dir())
        lookups: dict[str, Any] = {}
        for output, file_name in planning.TENSOR_FILES.items():
            path = os.path.join(folder, file_name)
            present = os.path.exists(path) or tensor_files.sidecar_path(path).exists()
            lookups[output] = None
            if not present:
                continue
            try:  # a sidecar without its data is a defect, named below (as the tensor policy does)
                tensor = planning.load_tensor(path, output)
                mode = tensor_files.read_sidecar(path).interpolation
            except Exception as exc:  # noqa: BLE001 - defective tensor: fixed values instead
                self.log.error(f"fallback tensor {path} unusable ({exc}); using fixed values")
                continue
            lookups[output] = tensor.nearest if mode == "nearest" else tensor.trilinear
        return lookups

    # ------------------------------------------------------------------ service

    def _answer_sent(self) -> None:
        with self._answers_sent:
            self._unanswered -= 1
            self._answers_sent.notify_all()

    def _serve_plan(self, request: Any, response: Any) -> Any:
        with self._answers_sent:  # every call's response is sent (and counted) after it returns
            self._unanswered += 1
        try:
            return self._plan_answer(request, response)
        except BaseException:  # no response, so no send to count it
            self._answer_sent()
            raise

    def _plan_answer(self, request: Any, response: Any) -> Any:
        reply = self.envelopes["reply"]
        try:
            message = decode(request.load_namespace, accept="PlanRequest")
            copy_key = (message.source, message.run_id, hash(request.load_namespace))
            with self._queue_lock:
                original = self._plan_copies.get(copy_key)
            job = (
                original
                if original is not None
                else self._job_from_request(message.payload, message.seq)
            )
        except MessageError as exc:
            response.success, response.message = False, reply.error(exc)
            self.log.warning(f"plan request rejected: {exc}")
            return response
        except (ValueError, OverflowError) as exc:
            # ScenarioError, PlannerError: the request names bad things; an OverflowError from a
            # number a world cannot hold ended the executor, and with it the node (exit 1).
            response.success = False
            response.message = reply.error(
                MessageError(
                    "invalid-request",
                    str(exc),
                    request_schema="PlanRequest",
                    request_seq=message.seq,
                )
            )
            self.log.warning(f"plan request rejected: {exc}")
            return response
        if original is None:
            answered = self._queue_plan(job, message, copy_key, response)
            if isinstance(answered, Job):  # a copy, queued while this one was being read
                original = job = answered
            elif answered is not None:
                return answered
        if original is not None:
            # A client's copy sent again (lit call resends a plan request that no answer has
            # come to in its first seconds: one can be lost while a new client is matched).
            with self._queue_lock:
                waiting = not job.done.is_set() and job.copies >= PLAN_RESENDS
                job.copies += 0 if waiting else 1
            if waiting:  # each holds an executor thread until the query ends
                response.success = False
                response.message = reply.error(
                    MessageError(
                        "busy",
                        f"plan request {job.episode_id}: {PLAN_RESENDS} copies of it wait for "
                        "its result already; no more are taken while it runs",
                        request_schema="PlanRequest",
                        request_seq=message.seq,
                    )
                )
                return response
            self.log.info(
                f"plan request {job.episode_id}: a copy came again (seq {message.seq} of "
                f"{message.source}); answered with the request's result, not planned twice"
            )
        job.done.wait()
        if job.error is not None:
            response.success = False
            if isinstance(job.error, TensorFileError):  # the tensors' fault, not the node's
                response.message = reply.error(
                    job.error,
                    code="unavailable",
                    message=(
                        f"the tensor policy is unavailable: {str(job.error)[:3000]} (the files "
                        "are read again at the next query)"
                    ),
                    request_schema="PlanRequest",
                    request_seq=message.seq,
                )
            elif isinstance(job.error, (PlannerError, ScenarioError)):  # the request's options
                response.message = reply.error(
                    job.error,
                    code="invalid-request",
                    message=str(job.error)[:3000],
                    request_schema="PlanRequest",
                    request_seq=message.seq,
                )
            else:
                response.message = reply.error(job.error)
            return response
        assert job.result is not None
        response.success, response.message = plan_answer_text(
            reply, self._plan_response(job), message.seq, self.log, job.episode_id
        )
        return response

    def _queue_plan(
        self, job: Job, message: Any, copy_key: tuple[str, str, int], response: Any
    ) -> Any:
        """Queue a new plan request's job (its copies are answered with its result from now on);
        the response when it is answered at once (refused: the node is stopping or busy;
        cancelled before it arrived), the job of a copy of it that was queued while this one was
        read (checked under the lock the copy was queued under: it is not planned twice), else
        None."""
        reply = self.envelopes["reply"]
        with self._queue_lock:
            queued_copy = self._plan_copies.get(copy_key)
            if queued_copy is not None:
                return queued_copy
            if self._stopping.is_set():  # after shutdown() began: nothing would take the job
                response.success = False
                response.message = reply.error(_stopping_error(message.seq))
                return response
            early = self._cancelled_early.pop(job.request_id, None) if job.request_id else None
            cancelled_early = early is not None and time.monotonic() - early <= CANCEL_EARLY
            if not cancelled_early:
                # One query runs, up to queue_limit wait: refuse only when the waiting places
                # are full.
                if self._queued > self.params["queue_limit"]:
                    response.success = False
                    response.message = reply.error(
                        MessageError(
                            "busy",
                            f"planner busy: {self._queued} queries queued or running "
                            f"(queue_limit {self.params['queue_limit']}); retry later",
                            request_schema="PlanRequest",
                            request_seq=message.seq,
                        )
                    )
                    return response
                if self._queued:
                    self.log.info(f"plan request {job.episode_id} waits behind {self._queued}")
                self._queued += 1
                # Cancels name a request by its episode id: the request_id, or for a request
                # without one the node's req-<hex>, which the log line below and its /lit/solution
                # messages show (a 600 s request of a client that crashed could not be stopped).
                self._requests.append(job)
                generations = self._id_generations
                generations[job.episode_id] = generations.get(job.episode_id, 0) + 1
                generations.move_to_end(job.episode_id)
                if len(generations) > ID_GENERATIONS:
                    generations.popitem(last=False)
                self._jobs.put(job)  # under the lock: shutdown() cannot slip between check and put
            copies = self._plan_copies
            copies[copy_key] = job
            copies.move_to_end(copy_key)
            answered = [key for key, kept in copies.items() if kept.done.is_set()]
            for key in answered[: max(0, len(answered) - PLAN_COPIES_KEPT)]:
                del copies[key]  # the oldest answered ones: queued or running ones stay
            if job.request_id is None:
                self.log.info(
                    f"plan request seq {message.seq} of {message.source} has no request_id: it "
                    f"is {job.episode_id} here (a CancelRequest naming {job.episode_id} stops it)"
                )
        if cancelled_early:
            self.log.info(f"plan request {job.episode_id} was cancelled before it arrived")
            job.result = _not_started(job)
            job.done.set()  # for its copies
            response.success, response.message = plan_answer_text(
                reply, self._plan_response(job), message.seq, self.log, job.episode_id
            )
            return response
        return None

    def _serve_cancel(self, request: Any, response: Any) -> Any:
        """A CancelRequest: stop the running plan request and drop the queued ones that carry
        its ``request_id``; each is still answered by the plan service (status ``cancelled``)."""
        reply = self.envelopes["reply"]
        try:
            message = decode(request.load_namespace, accept="CancelRequest")
        except MessageError as exc:
            response.success, response.message = False, reply.error(exc)
            self.log.warning(f"cancel request rejected: {exc}")
            return response
        request_id = message.payload["request_id"]
        running = queued = 0
        with self._queue_lock:
            stopping = self._stopping.is_set()  # queued ones are answered unavailable then
            for job in list(self._requests):
                if job.episode_id != request_id:
                    continue
                job.cancelled.set()
                if job is self._running:
                    job.stop.set()
                    running += 1
                elif (
                    not stopping
                ):  # answered now, not when the worker reaches it; its place is free
                    job.result = _not_started(job)
                    self._requests.remove(job)
                    self._queued -= 1
                    job.done.set()
                    queued += 1
            if not (running or queued or stopping):
                now = time.monotonic()
                self._cancelled_early = {
                    key: when
                    for key, when in self._cancelled_early.items()
                    if now - when <= CANCEL_EARLY
                }
                self._cancelled_early[request_id] = now
        if running or queued:
            parts = [f"{n} {what}" for n, what in ((running, "running"), (queued, "queued")) if n]
            text = f"cancelled the plan request {request_id!r}: {' and '.join(parts)}"
            self.log.info(text)
        else:
            text = (
                f"no plan request {request_id!r} is running or queued here (already answered, "
                "sent to another planner node, or not arrived yet: one that arrives within "
                f"{CANCEL_EARLY:g} s is answered as cancelled)"
                if not stopping
                else f"the planner node is stopping; plan request {request_id!r} is not running"
            )
        response.success = True
        response.message = reply.encode(
            "CancelResponse",
            {"request_id": request_id, "running": running, "queued": queued, "message": text},
        )
        return response

    def _problem_from_request(self, payload: dict[str, Any]) -> Any:
        """The scenario a plan request names or gives (its start and goal swapped in)."""
        from lit_planner import scenarios

        if "world" in payload:
            problem = scenarios.from_world(
                payload["world"],
                payload["start"],
                payload["goal"],
                time_budget=float(payload.get("time", 1.0)),
            )
        else:
            problem = scenarios.get(payload["scenario"])
            if "start" in payload or "goal" in payload:
                problem = scenarios.custom(
                    problem.lower,
                    problem.upper,
                    [(box[0], box[1]) for box in problem.boxes],
                    payload.get("start", problem.start),
                    payload.get("goal", problem.goal),
                    time_budget=problem.time_budget,
                    resolution=problem.resolution,
                )
        return problem

    def _job_from_request(self, payload: dict[str, Any], seq: int | None = None) -> Job:
        from lit_planner.errors import ScenarioError
        from lit_planner.planning import check_seed_in_node

        try:
            problem = self._problem_from_request(payload)
        except ScenarioError as exc:  # the part at fault, else what the problem came from
            where = exc.part or ("world" if "world" in payload else "scenario")
            raise MessageError(
                "invalid-request", str(exc), field=f"$.payload.{where}", rule=where,
                request_schema="PlanRequest", request_seq=seq,
            ) from exc  # fmt: skip
        planner = payload.get("planner", "litstar")
        if planner != "litstar" and "policy" in payload:
            raise MessageError(
                "invalid-request",
                f"policy {payload['policy']!r} is LIT*'s; {planner} takes no policy",
                field="$.payload.policy",
                rule="litstar-only",
                request_schema="PlanRequest",
                request_seq=seq,
            )
        for key in ("max_iterations", "max_batches"):
            if planner != "litstar" and payload.get(key):
                raise MessageError(
                    "invalid-request",
                    f"{planner} stops on time only: {key} is LIT*'s",
                    field=f"$.payload.{key}",
                    rule="litstar-only",
                    request_schema="PlanRequest",
                    request_seq=seq,
                )
        try:
            check_seed_in_node(planner, "seed" in payload)
        except PlannerError as exc:
            raise MessageError(
                "invalid-request",
                str(exc),
                field="$.payload.seed",
                rule="litstar-only",
                request_schema="PlanRequest",
                request_seq=seq,
            ) from None
        time_limit = payload.get("time")
        if time_limit is None and (payload.get("max_iterations") or payload.get("max_batches")):
            # A count limit alone plans without a time limit in the Python API; a request keeps
            # the schema's longest time as well (the worker was busy for good otherwise).
            time_limit = MAX_REQUEST_TIME
        policy = payload.get(
            "policy", "tensor" if self.params["policy"] == "training" else self.params["policy"]
        )
        return Job(
            kind="service",
            scenario=problem,
            policy=policy if planner == "litstar" else "",
            planner=planner,
            time=time_limit,
            seed=int(payload.get("seed", self.params["seed"])),
            max_iterations=int(payload.get("max_iterations", 0)),
            max_batches=int(payload.get("max_batches", 0)),
            request_id=payload.get("request_id"),
            request_seq=seq,
            episode_id=payload.get("request_id") or f"req-{uuid.uuid4().hex[:12]}",
        )

    def _plan_response(self, job: Job) -> dict[str, Any]:
        result = job.result
        assert result is not None
        check = result.get("path_check")
        return {
            "request_id": job.request_id,
            "status": result["status"],
            "solved": bool(result["solved"]),
            "message": result["message"],
            "scenario": job.scenario.key,
            "dimension": job.scenario.dim,
            "planner": result["planner"],
            "policy": result.get("policy"),
            "seed": job.seed,
            "cost": finite(result["cost"]),
            "t_init": finite(result["t_init"]),
            "c_init": finite(result["c_init"]),
            "time": float(result["time"]),
            "checks_init": result.get("checks_init"),
            "iteration_init": result.get("iteration_init"),
            "improvements": [[float(t), float(c)] for t, c in result["improvements"]],
            "path": [list(map(float, state)) for state in result["path"]],
            "counters": {k: int(v) for k, v in result["counters"].items()},
            "path_valid": None if check is None else bool(check["ok"]),
        }

    # ------------------------------------------------------------------ episodes

    def _drive(self) -> None:
        """Training or inference episodes from the parameters, queued like service requests."""
        p = self.params
        if p["episodes"] <= 0:
            # Serving only: say when the recorder (wait_for_subscribers) hears every topic, so a
            # caller that records can wait for it before its first request.
            if p["wait_for_subscribers"] > 0:
                if self._wait_for_subscribers(p["wait_for_subscribers"], p["learner_wait"]):
                    self.log.info(f"subscribers: {p['wait_for_subscribers']} on every topic")
                else:
                    self.log.warning(
                        f"fewer than {p['wait_for_subscribers']} subscribers on every topic after "
                        f"{p['learner_wait']} s"
                    )
            return
        from lit_planner import scenarios

        training = p["policy"] == "training"
        if training:
            try:
                # Interrupted by a shutdown, which then destroys the client: a wait still
                # polling it raised InvalidHandle, and the node exited 1 with a traceback.
                found = self.learner.wait(p["learner_wait"], interrupted=self._stopping.is_set)
            except CallInterrupted:
                return
            if found:
                self.log.info(f"learner service {p['learner_service']} found")
            else:
                self.log.warning(
                    f"learner service {p['learner_service']} not found within "
                    f"{p['learner_wait']} s; training starts with fallback decisions"
                )
        if not self._wait_for_subscribers(p["wait_for_subscribers"], p["learner_wait"]):
            self.log.warning(
                f"fewer than {p['wait_for_subscribers']} subscribers on every topic after "
                f"{p['learner_wait']} s; starting the episodes anyway"
            )

        drawn = _episodes_drawn(p)
        if drawn:
            from lit_learner.train import TrainingDistribution, draw_generator

            names = scenarios.split_names(p["training_scenarios"])
            # Not default_rng(seed): that would repeat a learner agent's numbers for equal seeds.
            # Planners in other namespaces draw other problems for the same seed.
            generator = draw_generator(p["training_seed"], self.node.get_namespace())
            distribution = TrainingDistribution(names, generator)
        mode = "training" if training else "inference"
        failed = 0
        for index in range(p["episodes"]):
            if self._stopping.is_set():
                return
            if drawn:
                spec = distribution.draw(index)
                problem, seed = scenarios.get(spec.scenario, spec.instance), spec.seed
            else:
                problem, seed = scenarios.get(p["scenario"]), p["seed"] + index
            job = Job(mode, problem, p["policy"], seed=seed)
            job.time = p["time_budget"] or None
            job.episode_id = episode_id(self.run_id, index)
            with self._queue_lock:
                if self._stopping.is_set():  # shutdown() began: its None is queued already
                    return
                self._queued += 1
                self._jobs.put(job)
            job.done.wait()
            if job.cut_short or (job.error is not None and self._stopping.is_set()):
                # Ctrl-C or SIGTERM: not a failure, and the episodes are not done (an episode
                # cut short says so itself; it was counted among the episodes done).
                if job.error is not None:
                    self.log.info(f"episode {job.episode_id} not finished: {job.error}")
                return
            if job.error is not None:
                failed += 1
                self.log.error(f"episode {job.episode_id} failed: {job.error}")
        done = f"{p['episodes']} {p['policy']} episodes done" + (
            f" ({failed} of them failed)" if failed else ""
        )
        if p["exit_when_done"]:
            self.log.info(done)
            self.exit_code = 1 if failed else 0
            self.finished = True
        else:
            self.log.info(f"{done}; still serving plan requests until stopped (Ctrl-C or SIGTERM)")

    def _wait_for_subscribers(self, count: int, timeout: float) -> bool:
        """Until each topic has ``count`` matched subscriptions (a recorder, a client): topics are
        volatile, so episodes published before they match would not reach them."""
        publishers = [*self.publishers.values(), self.path_publisher]
        deadline = time.monotonic() + timeout
        while not self._stopping.is_set():  # asked first: shutdown() then lets the node go
            if min(p.get_subscription_count() for p in publishers) >= count:
                return True
            if time.monotonic() > deadline:
                return False
            time.sleep(0.05)
        return False

    def _work(self) -> None:
        import lit_core

        while True:
            job = self._jobs.get()
            if job is None:
                return
            with self._queue_lock:  # shutdown() and _serve_cancel() see it running or not
                if job.done.is_set():  # cancelled while queued: answered and counted out already
                    continue
                stopping = self._stopping.is_set()
                if not stopping:
                    job.stop = lit_core.CancelFlag()
                    self._running = job
            try:
                if stopping:
                    job.error = _stopping_error(job.request_seq, service=job.kind == "service")
                else:
                    self._run(job)
            except BaseException as exc:  # noqa: BLE001 - reported; the node keeps serving
                # BaseException too: a SystemExit from a policy callback now leaves plan(), and
                # would have ended this worker with the queue unserved.
                job.error = exc if isinstance(exc, Exception) else RuntimeError(repr(exc))
                self.log.error(f"{job.kind} query {job.episode_id} failed: {exc!r}")
            finally:
                with self._queue_lock:
                    self._queued -= 1
                    self._running = None
                    if job in self._requests:
                        self._requests.remove(job)
                    if isinstance(job.error, TensorFileError):
                        # "unavailable": try again later. A copy sent once the files were
                        # repaired got this answer again, and the same text never planned.
                        # (Copies waiting now still get it: they came while it was the answer.)
                        for key in [k for k, kept in self._plan_copies.items() if kept is job]:
                            del self._plan_copies[key]
                job.done.set()

    def _run(self, job: Job) -> None:
        import lit_core

        from lit_planner import planning

        listener = EventLog(
            job.episode_id, lambda payload: self.publish("solution", "SolutionUpdate", payload)
        )
        episode = DecisionSources(
            resent_before=self.learner.resent,
            answered_by_copy_before=self.learner.answered_by_copy,
        )
        params: dict[str, object] = {}
        if job.planner == "litstar" and self.params["decision_interval"] > 0:
            # 0: the planner's default (1; the learner decides psi_K at every expansion) or, with
            # the tensor policy, the interval its psi_K tensor was trained with (planning.plan).
            params["decision_interval"] = self.params["decision_interval"]
        if job.policy == "training":
            budget = job.time or job.scenario.time_budget
            policy: Any = lit_core.ExternalPolicy(
                lambda context: self._decide(job, episode, budget, context),
                decides_neighbour_factor=True,
            )
        else:
            policy = job.policy or None
            if job.planner == "litstar" and policy == "tensor":
                # Read once and again only when the files change, not before every query.
                policy = self._tensor_policies.get(self.params["tensors_dir"] or None)
        planning.quiet_ompl(job.planner)
        if job.kind == "service":
            self.log.info(f"plan request {job.episode_id} started")
        result = planning.plan(
            job.scenario,
            planner=job.planner,
            policy=policy,
            time=job.time,
            seed=job.seed,
            max_iterations=job.max_iterations,
            max_batches=job.max_batches,
            params=params,
            listener=listener if job.planner == "litstar" else None,  # OMPL planners call none
            cancel=job.stop,
        )
        with self._queue_lock:  # from now on a CancelRequest finds it no more
            self._running = None
            if job in self._requests:
                self._requests.remove(job)
            cancelled = job.cancelled.is_set()
        cut_short = job.stop.is_set() and self._stopping.is_set()  # shutdown()
        job.cut_short = cut_short
        if cancelled and not cut_short and result["status"] not in INVALID_TERMINAL:
            self._stopped_early(job, result, "cancelled", "cancelled by a CancelRequest")
        if cut_short and job.kind == "service":
            if result["solved"] and result["status"] not in INVALID_TERMINAL:
                # As a cancel does: the best path found until then (a 600 s anytime query cut
                # short after a solution came threw it away with an unavailable Error).
                self._stopped_early(
                    job, result, "shutdown", "cut short by the planner node's shutdown"
                )
                job.result = result
            else:
                job.error = _stopping_error(
                    job.request_seq,
                    f"the query was cut short after {result['time']:.3g} s of planning, before "
                    "any path was found",
                )
            return
        if result["status"] in INVALID_TERMINAL:
            # The core's own start/goal check (bounds, obstacles): the request's fault.
            label = INVALID_TERMINAL[result["status"]]
            job.error = MessageError(
                "invalid-request",
                result["message"],
                field=f"$.payload.{label}" if job.kind == "service" else None,
                rule="valid-state",
                request_schema="PlanRequest" if job.kind == "service" else None,
                request_seq=job.request_seq,
            )
            return
        job.result = result
        taken = job.policy == "training" and self._end_episode(
            job, episode, result, cut_short=cut_short
        )
        if cut_short:
            # Its summary would read as a finished episode (lit replay tensors would learn a
            # terminal state from it): none is published.
            if job.policy != "training":
                told = ""
            elif taken:
                told = "; the learner took its end as truncated"
            else:
                told = "; its end was sent to the learner as truncated, without an answer"
            self.log.info(f"{job.kind} episode {job.episode_id} cut short by the shutdown{told}")
            return
        self._publish_episode(job, episode, listener, result)

    def _stopped_early(self, job: Job, result: dict[str, Any], status: str, why: str) -> None:
        """Relabel ``result`` of a query stopped before its limits (by a cancel or the shutdown)
        with ``status``; its message keeps the planner's own status and says what was found."""
        found = "the best path found until then" if result["solved"] else "no path found"
        result["message"] = (
            f"{why} after {result['time']:.3g} s of planning (status then: {result['status']}); "
            f"{found}"
        )
        result["status"] = status
        self.log.info(f"plan request {job.episode_id}: {result['message']}")

    # ------------------------------------------------------------------ learner calls

    def _decide(self, job: Job, episode: DecisionSources, budget: float, context: Any) -> float:
        kind = context.kind
        window_starts = False
        if time.monotonic() < self._learner_down_until and self._learner_caught_up(job, episode):
            self._learner_down_until = 0.0
        if time.monotonic() >= self._learner_down_until:
            payload = {
                "agent": kind,
                "episode_id": job.episode_id,
                "rho_global": unit(context.rho_global),
                "rho_local": unit(context.rho_local),
                "measure": unit(context.measure),
                "planning_time": max(0.0, float(context.planning_time)),
                "time_budget": float(budget),
                "cost": float(context.cost) if context.has_solution else None,
                "minimum_cost": float(context.minimum_cost),
                "improvements": int(context.improvements),
                "path_states": int(context.path_states),
                "explore": bool(self.params["explore"]),
                "dimension": int(context.dimension),
            }
            if kind in job.fell_back:
                payload["after_fallback"] = True
            started = time.perf_counter()
            episode.learner_calls += 1
            # The long first deadline is for a learner being matched, once: after a miss with
            # no late answer it would cost every call that much while the learner stays silent.
            deadline = self.params["decision_timeout"]
            if not self._learner_answered and self._missed_in_a_row == 0:
                deadline = max(deadline, self.params["first_decision_timeout"])
            answer = self.learner.call(
                self.envelopes["decide"].encode("DecideRequest", payload),
                deadline,
                self._resend_after(deadline),
            )
            if answer is not None:
                # Answered in time (an error too): the learner is there and its answers arrive.
                self._missed_in_a_row = 0
                success, text = answer
                try:
                    reply = decode(text, accept=("DecideResponse", "Error"))
                except MessageError as exc:
                    self._heard_from_learner("(an unreadable answer)")
                    reason = f"unreadable learner answer ({exc})"
                else:
                    # From encoding the request to the decoded, validated answer.
                    latency = (time.perf_counter() - started) * 1e3
                    self._heard_from_learner(f"in {latency:.1f} ms")
                    answers = (reply.payload.get("agent"), reply.payload.get("episode_id"))
                    if (
                        success
                        and reply.name == "DecideResponse"
                        and answers == (kind, job.episode_id)
                    ):
                        episode.add("learner", latency)
                        job.fell_back.discard(kind)
                        return float(reply.payload["value"])
                    if success and reply.name == "DecideResponse":  # it was executed as is
                        reason = (
                            f"the learner answered for agent {answers[0]!r} of episode "
                            f"{answers[1]!r}, not for {kind!r} of this episode"
                        )
                    else:
                        reason = f"learner error: {reply.payload.get('message', '?')}"
            else:
                reason = f"learner did not answer within {deadline * 1e3:.0f} ms"
                self._missed(self.learner.last_overdue)
                if self._missed_in_a_row == 1:
                    reason += (
                        "; this decision and those until the learner answers it late (at most "
                        f"{self.params['learner_retry']:g} s) use the fallback policy"
                    )
                else:
                    window_starts = self._missed_in_a_row == 2
                    reason += (
                        f" ({self._missed_in_a_row} calls in a row); this decision and those "
                        f"in the next {self.params['learner_retry']:g} s use the fallback policy"
                    )
            # One warning a query, and one more when a second miss in a row starts the
            # learner_retry window: after a late answer's "calls resume" the query's fallbacks
            # would otherwise read as calls that went on.
            if not episode.warned or window_starts:
                episode.warned = True
                self.log.warning(f"episode {job.episode_id}: {reason}")
        episode.fallbacks += 1
        job.fell_back.add(kind)
        lookup = self._fallback.get(kind)
        if lookup is None:
            episode.add("fallback-fixed")
            return FIXED_BATCH if kind == "B" else FIXED_FACTOR
        episode.add("fallback-tensor")
        # The core rounds B half away from zero and clamps both, as for any external answer.
        return float(lookup(context.rho_global, context.rho_local, context.measure))

    def _resend_after(self, deadline: float) -> float | None:
        """When a learner call without an answer sends its request again: after
        ``learner_resend`` or an eighth of its deadline, whichever is longer (then twice as
        long, ...); None with ``learner_resend: 0``."""
        resend = self.params["learner_resend"]
        return max(resend, deadline / 8.0) if resend > 0 else None

    def _learner_caught_up(self, job: Job, episode: DecisionSources) -> bool:
        """Whether the learner answered, late, the one call that missed its deadline: it is
        alive, it was slow once (a machine busy with other work), and
        training goes back to it at once rather than after ``learner_retry`` s. After two
        misses in a row the fallback window runs its course."""
        if self._missed_in_a_row != 1 or not self.learner.answered_late(self._missed_call):
            return False
        self._heard_from_learner("late")
        if not episode.resumed:
            episode.resumed = True
            self.log.info(
                f"episode {job.episode_id}: the learner answered the missed call late; calls resume"
            )
        return True

    def _heard_from_learner(self, how: str) -> None:
        """The learner answered a call (in time or late): its answers reach the planner, and
        calls no longer wait ``first_decision_timeout``. Logged once (``lit system-bench`` waits
        for the line)."""
        if not self._learner_answered:
            self._learner_answered = True
            self.log.info(f"learner answered its first call {how}")

    def _missed(self, sequence: int | None) -> None:
        """A learner call (request ``sequence``) missed its deadline: no call for
        ``learner_retry`` s, unless its late answer comes first (:meth:`_learner_caught_up`)."""
        self._learner_down_until = time.monotonic() + self.params["learner_retry"]
        self._missed_in_a_row += 1
        self._missed_call = sequence

    def _end_episode(
        self, job: Job, episode: DecisionSources, result: dict[str, Any], *, cut_short: bool = False
    ) -> bool:
        """Send the episode's end to the learner; whether it answered that it took it (without
        an answer it may still have: it stores the end when the message arrives)."""
        from lit_learner.train import BUDGET_TOLERANCE, final_features, minimum_cost

        problem = job.scenario
        budget = job.time or problem.time_budget
        payload = {
            "episode_id": job.episode_id,
            "planning_time": float(result["time"]),
            "time_budget": float(budget),
            "cost": finite(result["cost"]) if result["solved"] else None,
            "minimum_cost": minimum_cost(problem),
            "improvements": len(result["improvements"]),
            "path_states": len(result["path"]),
            # Cut short by the shutdown: truncated (bootstrapped), not a terminal state.
            "truncated": cut_short or bool(result["time"] >= budget * (1.0 - BUDGET_TOLERANCE)),
            "fallback_decisions": episode.fallbacks,
        }
        if job.fell_back:
            payload["fallback_agents"] = sorted(job.fell_back)
        final = final_features(result)
        if final is not None:
            payload["final_features"] = {agent: list(values) for agent, values in final.items()}
        # The learner stores the episode when the message arrives, whether or not the planner
        # waits for the answer: after two calls in a row missed (a learner that is gone, not
        # slow once) wait no longer than for a decision.
        if self._missed_in_a_row >= 2:
            deadline = self.params["decision_timeout"]
        else:
            deadline = max(1.0, 20 * self.params["decision_timeout"])
        answer = self.learner.call(
            self.envelopes["decide"].encode("EpisodeEnd", payload),
            deadline,
            self._resend_after(deadline),
        )
        resent = self.learner.resent - episode.resent_before
        if resent:
            by_copy = self.learner.answered_by_copy - episode.answered_by_copy_before
            self.log.debug(
                f"episode {job.episode_id}: {resent} learner requests sent again; {by_copy} "
                f"calls answered through a copy"
            )
            report = self._resends.add(resent, by_copy, time.monotonic())
            if report:
                self.log.info(report)
        if answer is None:
            self.log.warning(
                f"episode {job.episode_id}: the learner did not take the episode end within "
                f"{deadline * 1e3:.0f} ms"
            )
            self._missed(self.learner.last_overdue)
            return False
        # Answered in time: the learner is back (a late decision answer may have come meanwhile).
        self._missed_in_a_row = 0
        self._heard_from_learner("(an episode end)")
        if time.monotonic() < self._learner_down_until:
            self._learner_down_until = 0.0
            self.log.info(
                f"episode {job.episode_id}: the learner took the episode end; calls resume"
            )
        try:
            reply = decode(answer[1], accept=("EpisodeEndResponse", "Error"))
        except MessageError as exc:
            self.log.warning(f"episode {job.episode_id}: unreadable episode-end answer: {exc}")
            return False
        if reply.name == "Error":
            self.log.warning(f"episode {job.episode_id}: learner: {reply.payload['message']}")
            return False
        return True

    # ------------------------------------------------------------------ publishing

    def publish(self, topic: str, schema: str, payload: dict[str, Any]) -> None:
        """Encode and publish one JSON message (thread-safe; seq rises by one per topic)."""
        message = self._string()
        with self._publish_lock:
            message.data = self.envelopes[topic].encode(schema, payload)
            self.publishers[topic].publish(message)

    def _publish_episode(
        self, job: Job, episode: DecisionSources, listener: EventLog, result: dict[str, Any]
    ) -> None:
        from builtin_interfaces.msg import Duration
        from trajectory_msgs.msg import JointTrajectoryPoint

        sources = episode if job.policy == "training" else None
        for observation, decision in decision_payloads(
            job.episode_id, result, listener, job.policy, sources
        ):
            self.publish("observation", "Observation", observation)
            self.publish("decision", "Decision", decision)
        summary = summary_payload(
            job.episode_id, job.kind, job.scenario, job.seed, job.policy, result, episode
        )
        message = self._string()
        with self._publish_lock:
            message.data, dropped = encode_summary(self.envelopes["episode"], summary)
            self.publishers["episode"].publish(message)
        if dropped is not None:
            self.log.warning(
                f"episode {job.episode_id}: its world is too large for the EpisodeSummary "
                f"({dropped}); published without it, so lit replay verify cannot re-check its path"
            )
        if summary.get("path_valid") is False:
            # A controller listening on lit/path would execute it: the answer and the
            # EpisodeSummary say path_valid false; the trajectory topic carries only paths that
            # passed the re-check (or were not re-checked).
            self.log.warning(
                f"episode {job.episode_id}: its path failed the independent re-check "
                "(path_valid false); not published on lit/path"
            )
            return
        if not result.get("path"):
            # No path (unsolved): nothing to publish. An empty JointTrajectory went out, which a
            # joint_trajectory_controller takes as "stop the current motion".
            return
        timing = path_timing(result["path"])
        if not timing[-1] < 2**31 - 1:
            # builtin_interfaces/Duration's sec is an int32: the message could not be built (the
            # plan request was then answered with an internal error) or wrapped silently.
            self.log.warning(
                f"episode {job.episode_id}: its path takes {timing[-1]:.3g} s at unit speed, more "
                "than a JointTrajectory's time can say; not published on lit/path"
            )
            return
        trajectory = self._trajectory()
        trajectory.header.stamp = self.node.get_clock().now().to_msg()
        trajectory.header.frame_id = job.episode_id
        trajectory.joint_names = [f"q{i}" for i in range(job.scenario.dim)]
        for state, elapsed in zip(result["path"], timing, strict=True):
            point = JointTrajectoryPoint()
            point.positions = [float(x) for x in state]
            seconds = int(elapsed)
            point.time_from_start = Duration(sec=seconds, nanosec=int((elapsed - seconds) * 1e9))
            trajectory.points.append(point)
        with self._publish_lock:
            self.path_publisher.publish(trajectory)

    def shutdown(self) -> None:
        """Stop queuing episodes, end the running query early and answer the queued ones with
        ``unavailable``."""
        with self._queue_lock:  # no request is queued after this (see _serve_plan)
            self._stopping.set()
            if self._running is not None:
                self._running.stop.set()
            self._jobs.put(None)
        self._cancel_service.shutdown(timeout=5.0)
        self._worker.join(timeout=30.0)
        report = self._resends.flush(time.monotonic())
        if report:
            self.log.info(report)
        # The answers (unavailable, for the queued ones) go out from the executor's threads; a
        # node destroyed under a send still retrying lost it ("answer not sent: InvalidHandle").
        with self._answers_sent:
            # At most a few seconds: a client that went away never matches, and lit up allows
            # each node 20 s to stop.
            if not self._answers_sent.wait_for(
                lambda: self._unanswered <= 0, timeout=SHUTDOWN_SEND_WAIT
            ):
                self.log.warning(f"{self._unanswered} plan answers still unsent at shutdown")
        # The episodes thread ends at once now (its waits look at _stopping, its queued episode
        # was answered): it may still be using the learner client and the publishers.
        self._driver.join(timeout=DRIVER_JOIN)
        if not self._worker.is_alive() and not self._driver.is_alive():
            self.learner.destroy()
        if not flush_publishers([*self.publishers.values(), self.path_publisher]):
            self.log.warning("some subscribers did not acknowledge the last messages")


DRIVER_JOIN = 5.0
"""Seconds the shutdown waits for the episodes thread (it ends within one poll of its waits)."""
SHUTDOWN_SEND_WAIT = 3.0
"""Seconds the shutdown waits for plan answers still being sent (to a client matching late)."""


def plan_answer_text(
    reply: Any, payload: dict[str, Any], seq: int, log: Any, episode_id: str | None = None
) -> tuple[bool, str]:
    """``(success, text)`` of a plan request's answer: the PlanResponse, or an Error when it
    cannot be encoded (longer than the message limit: a very long path or improvement list).
    An encoding error raised out of the service callback would stop the node's executor."""
    try:
        return True, reply.encode("PlanResponse", payload)
    except MessageError as exc:
        text = (
            f"the plan's answer cannot be sent: {exc} ({len(payload['path'])} path states, "
            f"{len(payload['improvements'])} improvements; status {payload['status']}, "
            f"cost {payload['cost']})"
        )
        log.error(f"plan request {episode_id or payload['request_id']!r}: {text}")
        return False, reply.error(
            exc, message=text[:3000], request_schema="PlanRequest", request_seq=seq
        )


def _not_started(job: Job) -> dict[str, Any]:
    """The result of a plan request cancelled while it waited: nothing planned."""
    from lit_planner.planning import resolve_planner

    planner, policy = resolve_planner(job.planner, job.policy or None)
    return {
        "status": "cancelled",
        "solved": False,
        "message": "cancelled by a CancelRequest before it started; nothing was planned",
        "planner": planner,
        "policy": policy,
        "cost": math.inf,
        "t_init": math.inf,
        "c_init": math.inf,
        "time": 0.0,
        "improvements": [],
        "path": [],
        "counters": {},
        "path_check": None,
    }


def _stopping_error(
    seq: int | None, what: str = "the query was not started", *, service: bool = True
) -> MessageError:
    """The ``unavailable`` answer of a node that is shutting down."""
    return MessageError(
        "unavailable",
        f"the planner node is stopping; {what}",
        request_schema="PlanRequest" if service else None,
        request_seq=seq,
    )


def main(args: Sequence[str] | None = None) -> int:
    """Console script ``lit_planner_node`` (ROS arguments: ``--ros-args -p policy:=training``)."""
    return spin_node(PlannerNode, sys.argv if args is None else args, threads=EXECUTOR_THREADS)


if __name__ == "__main__":
    sys.exit(main())

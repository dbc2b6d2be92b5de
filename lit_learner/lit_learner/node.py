"""``lit_learner_node``: the Fuzzy-DDPG learner as a ROS 2 node.

- Serves ``/lit/learner/decide`` (``diagnostic_msgs/srv/AddDiagnostics``; the request's
  ``load_namespace`` holds a DecideRequest or EpisodeEnd envelope, the response's ``message`` the
  DecideResponse / EpisodeEndResponse, or an Error with ``success = false``).
- Episodes of several planners are kept apart: the learner core sees the episode as
  ``<source>|<run_id>|<episode_id>`` (source = the planner node's fully qualified name; a ``|``
  or ``\\`` within a part is escaped with a backslash: ``messages.episode_key``).
- Answers a decision from the actor snapshots published after the last gradient step, without
  any lock, and pairs and stores it after the answer is sent: at once when the core's lock is
  free, else (a checkpoint is copying the state) as soon as it is, in order; an episode end
  records its episode's waiting decisions first, and time order is checked against them too.
- Trains at episode ends: the episode's transitions are stored at once and the gradient steps they
  call for run on a background thread, one at a time. A step holds the networks' lock throughout
  (checkpoints and exports take it too) and the core's lock only for its bookkeeping and the
  replay's sample and priority update, so neither decisions nor episode ends wait for a step.
- Publishes ``/lit/learner/stats`` (LearnerStats) every ``stats_period`` s; with
  ``wait_for_subscribers: N`` from the first tick at which the topic has N matched subscriptions
  (a recorder: the topic is volatile, and a tick published before a recorder matched it was
  counted as missing from the bag). Ticks before that are not published and take no ``seq``.
- An episode without a decision for ``episode_timeout`` s, or twice its time budget if that is
  longer (its planner died, or lost its end), is abandoned, as when its planner starts another: its open steps are dropped, its stored
  transitions' gradient steps become due, and it no longer stays in memory and checkpoints.
- Checkpoints every ``checkpoint_every`` episodes and ``checkpoint_period`` s (0: off), and on shutdown;
  resumes from ``checkpoint`` when the file exists (``fresh: true`` starts over).
- Exports the lookup tensors of the agents that made a gradient update (with a checkpoint copy)
  to ``export_dir`` on ``/lit/learner/export`` (``std_srvs/srv/Trigger``), after
  ``max_episodes`` episodes (the end of training), and on shutdown when it trained since the last
  export.
"""

from __future__ import annotations

import collections
import contextlib
import json
import math
import os
import sys
import threading
import time
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

from lit_msgs_json.envelope import Message, MessageError, decode
from lit_planner.rosutil import (
    DECIDE_SERVICE,
    EXPORT_SERVICE,
    STATS_TOPIC,
    DirectService,
    DuplicateServerWatch,
    declare_parameters,
    essential,
    flush_publishers,
    json_qos,
    retry_lost_answers,
    run_id_problem,
    service_name_problem,
    service_qos,
    spin_node,
    spin_quietly,
)
from lit_planner.safe_logger import SafeLogger

from lit_learner.config import MAX_SEED
from lit_learner.errors import ExportError, PairingError, ReplayError
from lit_learner.errors import MessageError as CoreMessageError
from lit_learner.messages import DecisionRequest, EpisodeEnd, episode_key
from lit_learner.pairing import check_order

NODE_NAME = "lit_learner"
TRAINER_NICE = 10
"""Nice value of the trainer thread (never below the process's). Gradient steps run as long as the
scheduler gives them a core; decisions and the DDS threads that carry them must not queue behind
them. The README gives the measurement (`lit call decide --repeat 3000` against
``trainer_nice:=0`` and ``:=10``)."""
TRAINER_RETRY = 5.0
"""Seconds the trainer waits after a failed step or checkpoint before it tries again."""

PARAMETERS: dict[str, Any] = {
    "checkpoint": "runs/learner/checkpoint.pt",
    "fresh": False,
    "seed": 0,
    "train": "both",
    "checkpoint_every": 50,
    "checkpoint_period": 30.0,
    "export_dir": "runs/learner/tensors",
    "max_episodes": 0,
    "stats_period": 1.0,
    "wait_for_subscribers": 0,
    "episode_timeout": 3600.0,
    "max_open_episodes": 256,
    "max_sources": 64,
    "run_id": "",
    "service": DECIDE_SERVICE,
    "trainer_nice": TRAINER_NICE,
}
"""The node's ROS parameters and their defaults."""


MESSAGE_SCHEMAS = (
    "DecideRequest",
    "DecideResponse",
    "EpisodeEnd",
    "EpisodeEndResponse",
    "Error",
    "LearnerStats",
)
"""The messages the learner node reads and writes (their validators are built at start-up)."""


def parameter_problem(p: Mapping[str, Any]) -> str | None:
    """What is wrong with the node's parameter values (``p`` holds every parameter), None when
    they are usable. The node exits with it at start; ``lit up`` asks before it starts anything."""
    if p["train"] not in ("both", "B", "psi_K"):
        return f"train must be both, B or psi_K, not {p['train']!r}"
    for name in ("checkpoint_every", "max_episodes", "seed", "wait_for_subscribers"):
        if p[name] < 0:
            return f"{name} must be 0 or more, got {p[name]}"
    if p["seed"] > MAX_SEED:  # the learner's own bound; beyond it the node stopped with a traceback
        return f"seed must be at most 2^63 - 2, got {p['seed']}"
    for name in ("max_open_episodes", "max_sources"):
        if p[name] < 1:
            return f"{name} must be 1 or more, got {p[name]}"
    if not p["checkpoint_period"] >= 0:  # also NaN
        return f"checkpoint_period must be 0 or more seconds, got {p['checkpoint_period']}"
    if not (math.isfinite(p["episode_timeout"]) and p["episode_timeout"] >= 0):
        return f"episode_timeout must be 0 (never) or more seconds, got {p['episode_timeout']}"
    if not (math.isfinite(p["stats_period"]) and p["stats_period"] > 0):
        return f"stats_period must be a finite positive number of seconds, got {p['stats_period']}"
    if not p["checkpoint"]:
        return "checkpoint must name a file"
    foreign = foreign_tensor_files(Path(p["export_dir"]))
    if foreign:
        return foreign_problem(Path(p["export_dir"]), foreign)
    return service_name_problem("service", p["service"]) or run_id_problem("run_id", p["run_id"])


NODE_EXPORTER = "lit_learner_node"
"""``provenance.exported_by`` of the node's exports."""


REPLACED = "its planner started another one"
"""Why an episode whose planner began another one was abandoned (its end never came)."""


def foreign_tensor_files(folder: Path) -> list[str]:
    """The tensor files (``.npy`` or sidecar) in ``folder`` that are not a learner node's export
    (whose sidecar's provenance says ``exported_by: lit_learner_node``). The node's export
    replaces and removes the tensor files there: it must not take the shipped tensors, or those
    of ``lit train``, with them."""
    # Not lit_learner.export's: it imports torch, whose import starts `ldconfig -p`, and lit up
    # checks this before it starts anything (a refusal test caught that child).
    from lit_planner.errors import TensorFileError
    from lit_planner.tensor_files import TENSOR_FILES, read_sidecar_bytes, sidecar_path

    found = []
    for name in TENSOR_FILES.values():
        tensor, sidecar = folder / name, sidecar_path(folder / name)
        if not (tensor.exists() or sidecar.exists()):
            continue
        try:
            # Not read_bytes(): a named pipe there held the node's start for good.
            exporter = json.loads(read_sidecar_bytes(sidecar))["provenance"]["exported_by"]
        except (TensorFileError, ValueError, KeyError, TypeError, RecursionError):
            exporter = None
        if exporter != NODE_EXPORTER:
            found.append(tensor.name if tensor.exists() else sidecar.name)
    return found


def foreign_problem(folder: Path, files: Sequence[str]) -> str:
    """What is wrong with an ``export_dir`` that holds the tensor ``files`` of something else."""
    return (
        f"export_dir {folder} holds {', '.join(files)}, not a learner node's export (an export "
        "replaces and removes the tensor files there); choose another folder, or move them"
    )


DECIDE_ACCEPT = ("DecideRequest", "EpisodeEnd")
"""The messages the decide service takes."""


class _DecodeOnce:
    """Decodes each decide request once for the two that read it, from the serving thread: the
    repeat key (:class:`DirectService` asks it first) and :meth:`LearnerNode._serve`. It keeps
    the latest text's result, a message or the error."""

    def __init__(self) -> None:
        self._text: str | None = None
        self._result: Message | MessageError | None = None

    def decode(self, text: str) -> Message:
        """``decode(text)`` for the decide service, reused for the same text as last time.

        Raises:
            MessageError: the text is rejected.
        """
        if text != self._text:
            try:
                result: Message | MessageError = decode(text, accept=DECIDE_ACCEPT)
            except MessageError as exc:
                result = exc
            self._text, self._result = text, result
        if isinstance(self._result, MessageError):
            raise self._result
        assert self._result is not None
        return self._result

    def repeat_key(self, request: Any) -> tuple[tuple[str, str], int] | None:
        """A decide request's client (the envelope's source and run) and identity (its text,
        hashed): a planner's copy of a request it sent again is the same text. None for a text
        the service rejects (served, and rejected, as new)."""
        text = request.load_namespace
        try:
            message = self.decode(text)
        except MessageError:
            return None
        return (message.source, message.run_id), hash(text)


class LearnerNode:
    """Owns the ROS node and the :class:`~lit_learner.core.LearnerCore`."""

    def __init__(self) -> None:
        from diagnostic_msgs.srv import AddDiagnostics
        from lit_msgs_json.envelope import Publisher
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        from std_msgs.msg import String
        from std_srvs.srv import Trigger

        self.node = node = Node(NODE_NAME)
        self.log = SafeLogger(node.get_logger())
        p = declare_parameters(node, PARAMETERS, "lit_learner_node")
        problem = parameter_problem(p)
        if problem is not None:
            raise SystemExit(f"lit_learner_node: {problem}")
        self.params = p
        self.run_id = p["run_id"] or time.strftime("learner-%Y%m%d-%H%M%S")
        self.source = node.get_fully_qualified_name()
        self._checkpoint_done: str | None = None
        """The checkpoint file last loaded or written (LearnerStats' ``checkpoint``)."""
        self.core = self._load_core()
        self.core.publish()  # the actor snapshots that decisions read without the lock
        self._warm_up()
        self._lock = threading.Lock()
        """The core's bookkeeping: pairing, replay buffer, counters (held briefly)."""
        self._networks = threading.Lock()
        """The networks: held by the trainer for a whole gradient step, and by checkpoints and
        exports (always taken before ``_lock``). Decisions take neither lock."""
        self._checkpoint_lock = threading.Lock()
        """One checkpoint or export at a time (taken after ``_export_lock``, before the others)."""
        self._work = threading.Condition(self._lock)
        self._export_lock = threading.Lock()
        self._stopping = False
        self._export_stopping = False
        self._export_busy = threading.Lock()
        """The export service stops last: until then it answers that the learner stops."""
        self._decisions = 0
        self._probes = 0
        """Probe requests answered (``probe``: nothing recorded), counted in the stats' decisions."""
        self._unapplied: collections.deque[
            tuple[Any, float | None, str | None, tuple[str, str] | None]
        ] = collections.deque()
        """Answered decisions not recorded yet (the lock was taken), each with the episode it
        abandons first and why; the idle sweep queues abandonments alone (no decision). Applied
        in order."""
        self._queue_lock = threading.Lock()
        """Guards ``_unapplied`` (held for an append or a pop only), and the open episodes'
        bookkeeping that the idle sweep changes (``_latest_time``, ``_last_seen``,
        ``_open_episode``). Taken after ``_lock`` where both are held."""
        self._latest_time: dict[str, tuple[float, int, float | None]] = {}
        """Planning time, improvements and cost of each open episode's latest answered decision
        (serving thread)."""
        self._last_seen: dict[str, tuple[float, float, str]] = {}
        """Each open episode's latest decision: monotonic time, the episode's time budget and
        its planner (written by the serving thread, swept by the stats timer, both under
        ``_queue_lock``: ``episode_timeout``)."""
        self._crowded_out = 0
        """Open episodes abandoned because ``max_open_episodes`` were open (serving thread)."""
        self._replaced = 0
        """Episodes abandoned because their planner started another one (under ``_lock``)."""
        self._sources_full = False
        """Whether a planner beyond ``max_sources`` was left out of the provenance (warned once)."""
        self._open_episode: dict[str, str] = {}
        """Each planner's (source's) episode in progress (serving thread). A planner plans one
        episode at a time: its first request of another episode abandons an older one whose end
        never came (see ``LearnerCore.abandon_episode``)."""
        self._at_checkpoint = self._progress()
        """:meth:`_progress` when the last checkpoint was copied (or at start)."""
        self._at_export = self._progress()
        """:meth:`_progress` when the last export was made (or at start: a finished run started
        again does not export again until it trains)."""
        self._last_checkpoint = time.monotonic()
        self._started = time.monotonic()
        self._last_metrics: dict[str, float] = {}
        self._trainer_errors = 0
        self._retry_at = 0.0
        """Monotonic time before which a failed checkpoint or export is not tried again."""
        self._exported_at_end = False
        self.reply = Publisher(self.source, self.run_id)
        self.stats = Publisher(self.source, self.run_id)
        self._string = String
        self.stats_publisher = node.create_publisher(String, STATS_TOPIC, json_qos())
        # The export service lives on a helper node with its own executor thread: an export takes
        # seconds, and the decision service must keep answering meanwhile.
        self._export_node = Node(
            f"{NODE_NAME}_export",
            namespace=node.get_namespace(),
            start_parameter_services=False,
            use_global_arguments=False,  # a process-wide __node:= remap is the main node's
        )
        retry_lost_answers(
            self._export_node.create_service(
                Trigger, EXPORT_SERVICE, self._serve_export, qos_profile=service_qos()
            ),
            self.log,
        )
        self._export_executor = SingleThreadedExecutor()
        self._export_executor.add_node(self._export_node)
        self._export_thread = essential(
            "export", spin_quietly, self._export_executor, lambda: self._export_stopping
        )
        self._export_thread.start()
        node.create_timer(p["stats_period"], self._on_stats_timer)
        DuplicateServerWatch(node, p["service"]).start()
        self._trainer = essential("trainer", self._train)
        self._trainer.start()
        # Decisions are served from a thread and node of their own, outside the executor: the
        # round trip is on the planner's critical path (see DirectService). The service is made
        # last, so that a planner that sees it finds everything else in place.
        # A planner sends a request again when its answer is slow to come (a request or an
        # answer lost: rosutil.service_qos for one cause): the same envelope text, answered
        # again from the cache.
        self._decoder = _DecodeOnce()
        self._decide = DirectService(
            node,
            f"{NODE_NAME}_decide",
            AddDiagnostics,
            p["service"],
            self._serve,
            repeat_key=self._decoder.repeat_key,
        )
        self._repeats_logged = 0
        self._stats_final = False
        """Set by the final stats at shutdown: no tick publishes after them."""
        self._stats_lock = threading.Lock()
        """Held while stats are published (the executor's timer, and the final ones from
        :meth:`shutdown`)."""
        self._stats_heard = p["wait_for_subscribers"] == 0
        """Whether stats ticks are published: from the first with ``wait_for_subscribers`` matched
        subscriptions on (timer thread)."""
        self.log.info(
            f"ready: {p['service']}, {self.core.episodes} episodes and policy version "
            f"{self.core.policy_version} so far, checkpoint {p['checkpoint']}"
        )

    def _warm_up(self) -> None:
        """Do once, before serving, the work that a first decision would otherwise pay for: the
        message validators (about 10 ms each) and a noise-free action of each agent (torch's
        first forward pass), so that the planner's first call meets its deadline (50 ms by
        default) as the later ones do. Nothing is recorded and no random number is drawn."""
        from lit_learner.messages import DecisionRequest
        from lit_msgs_json import prepare

        prepare(MESSAGE_SCHEMAS)
        for agent in self.core.agents:
            request = DecisionRequest(
                agent=agent,
                episode_id="warm-up",
                rho_global=0.5,
                rho_local=0.5,
                measure=1.0,
                planning_time=0.0,
                time_budget=1.0,
                cost=None,
                minimum_cost=1.0,
                improvements=0,
                path_states=0,
                explore=False,
            )
            self.core.choose(request, published=True)

    def _load_core(self) -> Any:
        from lit_learner.config import LearnerConfig
        from lit_learner.core import LearnerCore

        p = self.params
        path = Path(p["checkpoint"])
        if path.exists() and not p["fresh"]:
            core = LearnerCore.load_checkpoint(path)
            self._checkpoint_done = str(path)
            config = core.config
            trains = {(True, True): "both", (True, False): "B", (False, True): "psi_K"}.get(
                (config.train_b, config.train_k), "neither"
            )
            unused = [
                f"{name}:={value}"
                for name, value, kept in (
                    ("train", p["train"], trains),
                    ("seed", p["seed"], config.seed),
                )
                if value != kept
            ]
            self.log.info(
                f"resumed from {path}: {core.episodes} episodes, train {trains} and seed "
                f"{config.seed} as the checkpoint says"
                + (
                    f" (the parameters {', '.join(unused)} are for a fresh start only)"
                    if unused
                    else ""
                )
            )
            warning = core.load_warning()
            if warning:
                self.log.warning(f"{path}: {warning}")
            # Episodes open when the checkpoint was written: their planners fell back while this
            # learner was down (those steps are not the agents'), and their gradient steps are
            # due; an episode that goes on starts a new pairing here.
            abandoned = sorted(core.open_episodes())
            for episode in abandoned:
                core.abandon_episode(episode)
            if abandoned:
                self.log.info(f"{len(abandoned)} episodes open in the checkpoint abandoned")
            return core
        train = p["train"]
        config = LearnerConfig(
            seed=int(p["seed"]), train_b=train in ("both", "B"), train_k=train in ("both", "psi_K")
        )
        return LearnerCore(config)

    # ------------------------------------------------------------------ service

    def _serve(self, request: Any, response: Any) -> Any:
        # Module-level imports: an import statement here would cost microseconds per decision.
        try:
            message = self._decoder.decode(request.load_namespace)  # decoded by the repeat key
        except MessageError as exc:
            response.success, response.message = False, self.reply.error(exc)
            self.log.warning(f"rejected: {exc}")
            return response
        payload = message.payload
        episode = episode_key(message.source, message.run_id, payload["episode_id"])
        try:
            if message.name == "DecideRequest":
                decision = DecisionRequest(
                    agent=payload["agent"],
                    episode_id=episode,
                    rho_global=payload["rho_global"],
                    rho_local=payload["rho_local"],
                    measure=payload["measure"],
                    planning_time=payload["planning_time"],
                    time_budget=payload["time_budget"],
                    cost=payload["cost"],
                    minimum_cost=payload["minimum_cost"],
                    improvements=int(payload["improvements"]),  # 2.0 is valid JSON for 2
                    path_states=int(payload["path_states"]),
                    explore=payload.get("explore", True),
                    after_fallback=payload.get("after_fallback", False),
                )
                probe = payload.get("probe", False)
                # Without the lock: a gradient step in progress does not hold the decision up
                # (the actor snapshot is the one published after the last step).
                if not probe:
                    self._check_order(decision)
                value, a_norm, version = self.core.choose(decision, published=True)
                response.success = True
                response.message = self.reply.encode(
                    "DecideResponse",
                    {
                        "agent": payload["agent"],
                        "episode_id": payload["episode_id"],
                        "value": float(value),
                        "policy_version": int(version),
                        "explore": bool(decision.explore),
                    },
                )
                if probe:  # answered only: no step, no episode, no transition
                    with self._queue_lock:
                        self._probes += 1
                    return response
                with self._queue_lock:  # the idle sweep sees all three or none
                    before = self._latest_time.get(episode)
                    self._latest_time[episode] = (
                        decision.planning_time,
                        decision.improvements,
                        # the lowest so far (a higher one was refused, but for a rounding)
                        decision.cost
                        if before is None or before[2] is None or decision.cost is None
                        else min(before[2], decision.cost),
                    )
                    self._last_seen.pop(episode, None)  # in order of their latest decisions
                    self._last_seen[episode] = (
                        time.monotonic(),
                        decision.time_budget,
                        message.source,
                    )
                    if len(self._last_seen) > self.params["max_open_episodes"]:
                        self._crowded_out += 1  # said for the 1st, 10th, 100th, ...: a flood
                        said = math.log10(self._crowded_out).is_integer()  # logs no line each
                        self._abandon_locked(
                            next(iter(self._last_seen)),  # the one idle the longest
                            f"more than max_open_episodes {self.params['max_open_episodes']} "
                            f"episodes are open; {self._crowded_out} crowded out so far"
                            if said
                            else "",
                        )
                    abandoned = self._open_episode.get(message.source)
                    if abandoned == episode:
                        abandoned = None
                    else:
                        self._open_episode[message.source] = episode
                        if abandoned is not None:
                            self._latest_time.pop(abandoned, None)
                            self._last_seen.pop(abandoned, None)
                # The pairing and the replay insert happen after the answer is on its way.
                self._decide.defer(
                    lambda: self._queue_commit(decision, a_norm, message.source, abandoned)
                )
                return response
            final = payload.get("final_features")
            end = EpisodeEnd(
                episode_id=episode,
                planning_time=payload["planning_time"],
                time_budget=payload["time_budget"],
                cost=payload["cost"],
                minimum_cost=payload["minimum_cost"],
                improvements=int(payload["improvements"]),  # 2.0 is valid JSON for 2
                path_states=int(payload["path_states"]),
                truncated=payload["truncated"],
                final_features={k: tuple(v) for k, v in final.items()} if final else None,
                fallback_agents=tuple(payload.get("fallback_agents", ())),
            )
            with self._lock:
                self._apply_commits_locked()  # the episode's decisions, in order, first
                before = sum(agent.transitions for agent in self.core.agents.values())
                known = self.core.is_open(episode)
                metrics = self.core.close_episode(end, count_unknown=False)
                # Closed: forgotten only now (an end refused above leaves the episode open, to be
                # abandoned by the planner's next episode or the idle sweep).
                with self._queue_lock:  # the idle sweep's bookkeeping too
                    self._latest_time.pop(episode, None)
                    self._last_seen.pop(episode, None)
                    if self._open_episode.get(message.source) == episode:
                        del self._open_episode[message.source]
                stored = sum(agent.transitions for agent in self.core.agents.values()) - before
                self._last_metrics.update(metrics)
                self._note_source(message.source)
                body = {
                    "episode_id": payload["episode_id"],
                    "transitions_stored": int(stored),
                    "pending_updates": int(self.core.pending_updates),
                    "policy_version": int(self.core.policy_version),
                    "episodes": int(self.core.episodes),
                }
                self._work.notify_all()
            if not known:
                self.log.info(
                    f"end of episode {episode}, which this learner has no open steps of (never "
                    "seen, already ended or abandoned, or begun before a restart): nothing stored "
                    "or counted"
                )
            if payload.get("fallback_decisions"):
                self.log.info(
                    f"episode {episode} ended with {payload['fallback_decisions']} fallback "
                    "decisions (the planner could not reach the learner for those)"
                )
            response.success = True
            response.message = self.reply.encode("EpisodeEndResponse", body)
            return response
        except (CoreMessageError, PairingError, ReplayError, ValueError, OverflowError) as exc:
            response.success = False
            response.message = self.reply.error(
                MessageError(
                    "invalid-request",
                    str(exc),
                    field=_payload_field(exc),
                    # The episode's messages go back (in time, improvements or cost): rule null
                    # said nothing of which rule it broke.
                    rule="order" if isinstance(exc, PairingError) else None,
                    request_schema=message.name,
                    request_seq=message.seq,
                )
            )
            self.log.warning(f"rejected: {exc}")
            return response

    def _check_order(self, decision: DecisionRequest) -> None:
        """The pairing's order checks (time, improvements, cost) against this episode's latest
        decision, including decisions whose commit has not been applied yet (the core's own
        check sees only the applied ones: a later decision with fewer improvements was answered,
        then dropped when its commit failed)."""
        latest = self._latest_time.get(decision.episode_id)
        if latest is not None:
            check_order(
                decision.episode_id,
                latest,
                decision.planning_time,
                decision.improvements,
                decision.cost,
            )

    def _queue_commit(
        self, decision: Any, a_norm: float | None, source: str, abandoned: str | None = None
    ) -> None:
        """Record a decision that has been answered: now if the core's lock is free, else as
        soon as it is (the trainer applies what is waiting when it lets the lock go, and so does
        the next request or episode end). A checkpoint copies the state under the lock for tens
        of ms; the serving thread used to wait for it before taking the next request, and the
        planner's 50 ms decision deadline ran out. ``abandoned``: the same planner's previous
        episode, whose end never came, is abandoned first."""
        first = None if abandoned is None else (abandoned, REPLACED)
        with self._queue_lock:
            self._unapplied.append((decision, a_norm, source, first))
        self.apply_commits(block=False)

    def apply_commits(self, block: bool = True) -> None:
        """Apply the queued commits, in order (``block=False``: only if the lock is free)."""
        if not self._unapplied or not self._lock.acquire(blocking=block):
            return
        try:
            self._apply_commits_locked()
        finally:
            self._lock.release()

    def _apply_commits_locked(self) -> None:
        while True:
            with self._queue_lock:
                if not self._unapplied:
                    return
                decision, a_norm, source, abandoned = self._unapplied.popleft()
            if abandoned is not None and self.core.abandon_episode(abandoned[0]):
                self._work.notify_all()  # its stored transitions' gradient steps are due
                episode, why = abandoned
                if why == REPLACED:
                    # Said for the 1st, 10th, 100th, ... (a client starting episodes it never
                    # ends gave a warning for every request).
                    self._replaced += 1
                    why = (
                        f"{REPLACED}; {self._replaced} so far"
                        if math.log10(self._replaced).is_integer()
                        else ""
                    )
                if why:  # not said again for every crowded-out episode (see _serve)
                    self.log.warning(
                        f"episode {episode} never ended ({why}): its open steps are dropped, the "
                        "gradient steps of its stored transitions are due"
                    )
            if decision is None:  # an abandonment alone (_sweep_idle_episodes)
                continue
            try:
                self.core.commit(decision, a_norm)
            except Exception as exc:  # noqa: BLE001 - the others still count
                self.log.error(f"commit of a decision of {decision.episode_id} failed: {exc!r}")
                continue
            self._decisions += 1
            self._note_source(source)

    def _serve_export(self, request: Any, response: Any) -> Any:
        del request
        with self._export_busy:  # the shutdown waits for an export in progress
            if self._stopping:
                response.success = False
                response.message = (
                    "the learner is shutting down: it exports on its way out when it trained "
                    f"since its last export (into {self.params['export_dir']})"
                )
                return response
            try:
                paths, left_out = self.export("request")
            except Exception as exc:  # noqa: BLE001 - report, keep serving
                response.success, response.message = False, f"export failed: {exc}"
                return response
        response.success = True
        answer: dict[str, Any] = {k: str(v) for k, v in paths.items()}
        if left_out:
            answer["left_out"] = left_out
        response.message = json.dumps(answer)
        return response

    # ------------------------------------------------------------------ training

    def _train(self) -> None:
        """Run owed gradient steps one by one; checkpoint and export when due."""
        nice = int(self.params["trainer_nice"])
        if nice:
            try:  # Linux: a thread's own nice value (raising it needs no privilege)
                thread = threading.get_native_id()
                current = os.getpriority(os.PRIO_PROCESS, thread)  # never above the process's
                os.setpriority(os.PRIO_PROCESS, thread, max(nice, current))
            except (OSError, AttributeError) as exc:
                self.log.warning(f"trainer_nice {nice} not applied: {exc}")
        while True:
            with self._work:
                while (
                    not self._stopping
                    and self.core.pending_updates == 0
                    and not self._due()
                    and not self._unapplied  # queued commits: applied below within a second
                ):
                    self._work.wait(timeout=1.0)
                if self._stopping:
                    return
            try:
                with self._networks:
                    step = self.core.update_step(lock=self._lock)
                if step is not None:
                    name, record = step
                    with self._lock:  # per agent, as lit train's (the two overwrote each other)
                        losses = {f"losses/{k}_{name}": float(v) for k, v in record.items()}
                        self._last_metrics.update(losses)
                # Between steps too: a backlog of owed steps held checkpoints off until it ended.
                if step is None or self._due():
                    self._maintain()
            except Exception as exc:  # noqa: BLE001 - the thread must outlive a full disk
                # A checkpoint that cannot be written (full disk, a folder gone) or a failed
                # step: counted in the stats, logged, tried again after a pause. The thread used
                # to end for good while the node kept answering as if it trained.
                # (A failed gradient step is dropped: its batch was drawn and counted.)
                with self._lock:
                    self._trainer_errors += 1
                    self._last_metrics["trainer/errors"] = float(self._trainer_errors)
                self._retry_at = time.monotonic() + TRAINER_RETRY
                self.log.error(
                    f"training step or checkpoint failed ({self._trainer_errors} so far): "
                    f"{type(exc).__name__}: {exc}; a checkpoint or export is tried again in "
                    f"{TRAINER_RETRY:g} s"
                )
            self.apply_commits()  # decisions answered while this thread held the lock

    def _progress(self) -> tuple[int, int]:
        """(episodes, policy version): what a checkpoint or export saves. The version also moves
        without new episodes (the gradient steps of abandoned ones)."""
        return self.core.episodes, self.core.policy_version

    def _due(self) -> bool:
        """Whether a checkpoint or the end-of-training export is owed (caller holds the lock);
        not until ``TRAINER_RETRY`` s after one failed (episode ends wake the trainer, and each
        retry copies the whole state under both locks)."""
        if time.monotonic() < self._retry_at:
            return False
        progress = self._progress()
        return self._checkpoint_due(progress) or self._export_due(progress)

    def _checkpoint_due(self, progress: tuple[int, int]) -> bool:
        """``checkpoint_every`` episodes ended, or ``checkpoint_period`` s passed with progress,
        since the last checkpoint; either at 0 is off (as ``lit train --checkpoint-every 0``;
        0 meant every episode, or every trainer wake-up)."""
        every, period = self.params["checkpoint_every"], self.params["checkpoint_period"]
        new = progress[0] - self._at_checkpoint[0]
        return (every > 0 and new >= every) or (
            period > 0
            and progress != self._at_checkpoint
            and time.monotonic() - self._last_checkpoint >= period
        )

    def _export_due(self, progress: tuple[int, int]) -> bool:
        """The end-of-training export is owed: ``max_episodes`` episodes ended and their owed
        gradient steps ran (an agent whose warm-up ended with the last episodes had no step
        yet, and was left out)."""
        limit = self.params["max_episodes"]
        return (
            bool(limit)
            and progress[0] >= limit
            and not self._exported_at_end
            and progress != self._at_export
            and self.core.pending_updates == 0
        )

    def _maintain(self) -> None:
        if time.monotonic() < self._retry_at:
            return
        with self._lock:
            progress = self._progress()
        if self._checkpoint_due(progress):
            self.checkpoint()
        if self._export_due(progress):
            self.export("end of training")  # a failure raises: tried again after the pause
            self._exported_at_end = True

    def checkpoint(self) -> None:
        """Write the checkpoint atomically: a consistent copy of the state under both locks, the
        file after they are released (decisions' commits and episode ends wait for the copy
        only)."""
        with self._checkpoint_lock:  # one checkpoint at a time: files written in copy order
            with self._networks, self._lock:
                state = self.core.checkpoint_state()
                progress = self._progress()
            self.core.write_checkpoint(state, self.params["checkpoint"])
            self._at_checkpoint = progress
            self._checkpoint_done = str(self.params["checkpoint"])
        self._last_checkpoint = time.monotonic()
        self.log.info(f"checkpoint {self.params['checkpoint']} ({progress[0]} episodes)")

    def export(self, why: str) -> tuple[dict[str, Path], dict[str, str]]:
        """Write the lookup tensors of the agents that made a gradient update (as ``lit train``
        does) and a checkpoint copy into ``export_dir``, and remove the other agent's tensor
        files from it (an earlier export's: the folder holds one export).

        Returns:
            The written files' paths and, for each agent left out, what the export says of it
            (:meth:`~lit_learner.core.LearnerCore.export_trained`).

        Raises:
            ExportError: ``export_dir`` holds tensor files that are not a learner node's export
                (:func:`foreign_tensor_files`), or a file could not be written.
        """
        folder = Path(self.params["export_dir"])
        # One export at a time, decisions going on meanwhile; and not beside a checkpoint (the
        # export writes a checkpoint copy, perhaps to the same file).
        with self._export_lock, self._checkpoint_lock:
            foreign = foreign_tensor_files(folder)
            if foreign:
                raise ExportError(foreign_problem(folder, foreign))
            record: dict[str, Any] = {
                "exported_by": NODE_EXPORTER,
                "reason": why,
                "run_id": self.run_id,
                "time": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            }
            at_export: list[tuple[int, int]] = []

            @contextlib.contextmanager
            def frozen_with_progress() -> Iterator[None]:
                # The planners and progress of the state copied under the same locks: read
                # before them, a gradient step or an episode end between the two made the
                # sidecars lag the checkpoint they name.
                with self._frozen():
                    progress = self._progress()
                    record["planners"] = sorted(self.core.sources)
                    record["episodes"] = progress[0]
                    at_export.append(progress)
                    yield

            paths, left_out = self.core.export_trained(
                folder, record, lock=frozen_with_progress(), remove_others=True
            )
            self._at_export = at_export[0]
        tensors = [path.name for name, path in paths.items() if name != "checkpoint"]
        self.log.info(
            f"exported to {folder} ({why}): "
            + (", ".join(tensors) + " and a checkpoint copy" if tensors else "a checkpoint copy")
            + "".join(f"; {name}: {note}" for name, note in left_out.items())
        )
        return paths, left_out

    @contextlib.contextmanager
    def _frozen(self) -> Iterator[None]:
        """Both locks: nothing in the core changes meanwhile."""
        with self._networks, self._lock:
            yield

    def _on_stats_timer(self) -> None:
        self._sweep_idle_episodes()
        self._publish_stats()

    def _sweep_idle_episodes(self) -> None:
        """Queue the abandonment of every episode without a decision for ``episode_timeout`` s,
        or twice its time budget if that is longer (applied in order with the decisions, under
        the core's lock). Quiet once the node is stopping: the final checkpoint keeps what is
        open then, and the next start abandons it."""
        timeout = self.params["episode_timeout"]
        if timeout <= 0 or self._stopping:
            return
        try:
            now = time.monotonic()
            idle = []
            with self._queue_lock:  # no decision of these lands between the look and the pop
                for episode, (seen, budget, _) in list(self._last_seen.items()):
                    limit = max(timeout, 2.0 * budget)
                    if now - seen > limit:
                        self._abandon_locked(episode, f"no decision for {limit:g} s")
                        idle.append(episode)
            if idle:
                self.apply_commits(block=False)
        except Exception as exc:  # noqa: BLE001 - the timer's error would stop the node
            self.log.error(f"idle episode sweep failed: {exc!r}")

    def _abandon_locked(self, episode: str, why: str) -> None:
        """Forget an open episode's bookkeeping and queue its abandonment (applied in order with
        the decisions); ``_queue_lock`` held. Should it go on, its next decision starts it anew."""
        _, _, source = self._last_seen.pop(episode)
        self._latest_time.pop(episode, None)
        if self._open_episode.get(source) == episode:
            del self._open_episode[source]
        self._unapplied.append((None, None, None, (episode, why)))

    def _note_source(self, source: str) -> None:
        """Name ``source`` in the provenance (``LearnerCore.sources``, kept in checkpoints): at
        most ``max_sources`` of them (a client sending under ever new names grew the checkpoint
        and every export's sidecar without bound); ``_lock`` held."""
        sources = self.core.sources
        if source in sources:
            return
        if len(sources) < self.params["max_sources"]:
            sources.add(source)
        elif not self._sources_full:
            self._sources_full = True
            self.log.warning(
                f"more than max_sources {self.params['max_sources']} planners sent experience: "
                "the provenance names the first ones only"
            )

    def _publish_stats(self, final: bool = False) -> None:
        """Publish the stats now: a timer tick (held back until ``wait_for_subscribers`` matched),
        or the ``final`` ones at shutdown (always)."""
        repeats = self._decide.repeats
        if repeats > self._repeats_logged:
            self.log.info(
                f"{repeats - self._repeats_logged} repeated requests answered again "
                f"({repeats} so far; a planner sent them again when an answer was slow or lost)"
            )
            self._repeats_logged = repeats
        with self._stats_lock:  # a tick and the final stats: one after the other, in order
            self._publish_stats_locked(final)

    def _publish_stats_locked(self, final: bool) -> None:
        if self._stats_final:
            return  # a tick after the final stats (the executor spins until the node is gone)
        if not (self._stats_heard or final):
            wanted = self.params["wait_for_subscribers"]
            if self.stats_publisher.get_subscription_count() < wanted:
                return  # no seq taken: the first published tick is seq 0 for the recorder too
            self._stats_heard = True
            self.log.info(f"stats: {wanted} subscribers on {STATS_TOPIC}; publishing")
        self._stats_final = final
        with self._lock:
            payload = {
                "episodes": int(self.core.episodes),
                "policy_version": int(self.core.policy_version),
                "transitions": {
                    name: int(agent.transitions) for name, agent in self.core.agents.items()
                },
                "pending_updates": int(self.core.pending_updates),
                "decisions": self._decisions + self._probes,
                "planners": sorted(self.core.sources)[:1024],
                "metrics": {
                    k: float(v) for k, v in self._last_metrics.items() if _finite_number(v)
                },
                # Null until a checkpoint is written or loaded (the parameter alone named a file
                # that did not exist yet, or an old one that `fresh` did not load).
                "checkpoint": self._checkpoint_done,
                "uptime": time.monotonic() - self._started,
            }
        message = self._string()
        message.data = self.stats.encode("LearnerStats", payload)
        self.stats_publisher.publish(message)

    def shutdown(self) -> None:
        """Stop taking decisions and training, then checkpoint (and export if trained since the
        last export). Until it is done, requests are answered ``unavailable`` (they went
        unanswered, and their clients waited out their timeouts)."""
        self._decide.refuse(self._refuse)  # returns once a request being served is done
        with self._work:
            self._stopping = True
            self._work.notify_all()
        self._trainer.join(timeout=30.0)
        self.apply_commits()  # every answered decision is in the last checkpoint
        with self._export_busy:  # an export request in progress is done; later ones refused
            pass
        # Each step is tried even when one before it failed (a checkpoint that cannot be written
        # must not cost the export, the final stats or the services' shutdown); the first
        # failure is raised at the end, so the process exits 1.
        failures: list[Exception] = []
        for step in (self.checkpoint, self._export_at_shutdown):
            try:
                step()
            except Exception as exc:  # noqa: BLE001 - collected, raised below
                self.log.error(f"shutdown: {type(exc).__name__}: {exc}")
                failures.append(exc)
        self._publish_stats(final=True)  # the final state, then wait until the recorder has it
        flush_publishers([self.stats_publisher])
        self._export_stopping = True
        self._export_executor.shutdown(timeout_sec=2.0)
        self._export_thread.join(timeout=30.0)
        self._export_node.destroy_node()
        self._decide.shutdown(timeout=5.0)
        if failures:
            raise failures[0]

    def _export_at_shutdown(self) -> None:
        if self._progress() != self._at_export:
            self.export("shutdown")

    def _refuse(self, request: Any, response: Any) -> Any:
        """The decide service's answer while the learner shuts down."""
        try:
            message = self._decoder.decode(request.load_namespace)
            about = {"request_schema": message.name, "request_seq": message.seq}
        except MessageError:
            about = {}
        error = MessageError(
            "unavailable",
            "the learner is shutting down (checkpoint and export); it takes requests again when "
            "it is started again",
            **about,
        )
        response.success, response.message = False, self.reply.error(error)
        return response


def _payload_field(error: BaseException) -> str | None:
    """The Error's ``field`` for a learner error about a payload field (``$.payload.cost``)."""
    field = getattr(error, "field", None)
    return f"$.payload.{field}" if isinstance(field, str) and field else None


def _finite_number(value: object) -> bool:
    import math

    return isinstance(value, (int, float)) and math.isfinite(value)


def main(args: Sequence[str] | None = None) -> int:
    """Console script ``lit_learner_node`` (ROS arguments: ``--ros-args -p checkpoint:=...``)."""
    # The trainer thread runs Python between torch calls; a decision that arrives then waits for
    # the GIL up to the switch interval (5 ms by default), which showed in the round trip's p99.
    sys.setswitchinterval(0.0005)
    from lit_learner.errors import CheckpointError

    try:
        return spin_node(LearnerNode, sys.argv if args is None else args, threads=1)
    except CheckpointError as exc:  # a damaged checkpoint: one line, not two tracebacks
        print(
            f"lit_learner_node: error: {exc}; restore the file, or start anew with "
            "-p fresh:=true (the file is then overwritten at the first checkpoint)",
            file=sys.stderr,
        )
        return 2


if __name__ == "__main__":
    sys.exit(main())

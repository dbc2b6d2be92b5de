"""``lit replay tensors``: train Fuzzy-DDPG offline on the transitions recorded in bags.

A recorded training episode (an EpisodeSummary with mode ``training``) is rebuilt from what the
planner published: its Observation and Decision messages (the n-th of each belong together; both
are published in the planner's decision order) give each decision's features, planner time and
executed value; its SolutionUpdate messages give the improvements and path states up to that time;
the summary gives the budget, the final state and the scenario (for c_min). Each decision is fed to
:meth:`~lit_learner.core.LearnerCore.record` (the executed value, not a new action: DDPG learns
off-policy, so fallback decisions count too, but for values outside the agent's range: the fixed
fallback psi_K = e opens no step), each episode is closed with
:meth:`~lit_learner.core.LearnerCore.end_episode` (which runs the gradient steps), and the result is
exported as lookup tensors.

Episodes are taken in the order their summaries were recorded, bag after bag, and everything random
comes from ``--seed``: the same bags and seed give identical tensors.
"""

from __future__ import annotations

import argparse
import bisect
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from lit_planner.replay import (
    BagReader,
    Envelope,
    ReplayError,
    Skipped,
    decode,
    payload_ok,
    read_before,
)

from lit_learner.config import AGENT_NAMES
from lit_learner.errors import ExportError
from lit_planner import argtypes

MAX_INTERVAL = 2**32 - 1
"""Largest psi_K decision interval (the planner's unsigned parameter)."""

OBSERVATION, DECISION = "lit_msgs_json/Observation", "lit_msgs_json/Decision"
SOLUTION, SUMMARY = "lit_msgs_json/SolutionUpdate", "lit_msgs_json/EpisodeSummary"


@dataclass
class RecordedEpisode:
    """What the bags hold of one planner episode."""

    key: tuple[str, str, str]
    """(source, run id, episode id)."""
    observations: list[dict[str, Any]] = field(default_factory=list)
    decisions: list[dict[str, Any]] = field(default_factory=list)
    solutions: list[dict[str, Any]] = field(default_factory=list)
    summary: dict[str, Any] | None = None
    summary_stamp_ns: int = -1
    """Its summary's stamp (the publisher's)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``lit replay tensors``."""
    parser.add_argument("bags", type=argtypes.path, nargs="+", metavar="BAG")
    parser.add_argument(
        "--out", type=argtypes.path, required=True, metavar="DIR", help="tensor folder"
    )
    parser.add_argument("--seed", type=int, default=0, help="learner seed (default 0)")
    parser.add_argument(
        "--train",
        choices=("both", "B", "psi_K"),
        default="both",
        help="agents that learn and are exported (the other keeps its fixed value)",
    )
    parser.add_argument(
        "--warmup",
        type=int,
        default=None,
        metavar="N",
        help="transitions before updates start, both agents (default: the learner's, 500 / 10000)",
    )
    parser.add_argument(
        "--batch-size", type=int, default=None, metavar="N",
        help="transitions per gradient step, both agents (default: the learner's, 64 / 256)",
    )  # fmt: skip
    parser.add_argument(
        "--decision-interval", type=int, default=None, metavar="N",
        help="expansions per psi_K decision in the recorded episodes, recorded with the tensors "
        "so that the tensor policy applies it; must agree with bags that name one (lit train's "
        "do) (default: the bags' own, else 1, the planner node's default in training)",
    )  # fmt: skip


def run(args: argparse.Namespace) -> int:
    """Read, train, export; print what was used."""
    from lit_learner.errors import ConfigError

    try:  # refused before the bags are read (seconds each), not after
        config = offline_config(args.seed, args.train, args.warmup, args.batch_size)
    except ConfigError as error:
        raise ReplayError(
            f"the learner refuses these options: {error} (--warmup and --batch-size apply to "
            "both agents; the learner's own are warm-up 500 / 10000, batches of 64 / 256)"
        ) from None
    interval = recorded_decision_interval(args.bags, args.decision_interval)
    # Progress bars on a terminal: the shipped training bag takes minutes (was silent).
    episodes, skipped = read_episodes(args.bags, progress=None)
    if not episodes:
        raise ReplayError("no complete training episode in the given bags")
    core = train_offline(episodes, config, progress=None)
    provenance = {
        "exported_by": "lit replay tensors",
        "bags": [str(Path(path).resolve()) for path in args.bags],
        "seed": args.seed,
        "train": args.train,
        "warmup": args.warmup,
        "batch_size": args.batch_size,
        "episodes": len(episodes),
        "decisions": sum(len(e.decisions) for e in episodes),
        "decision_interval": interval.value,
    }
    # Only an agent that made a gradient update is exported (as by lit train and the node).
    if not core.export_plan()[0]:
        raise ReplayError(
            "no agent made a gradient update, so there is no tensor to export ("
            + "; ".join(f"{name}: {core.untrained_reason(name)}" for name in AGENT_NAMES)
            + "): give more bags or a lower --warmup; nothing was written"
        )
    try:
        paths, left_out = core.export_trained(
            args.out,
            provenance,
            extra={"provenance.json": json.dumps(provenance, indent=2).encode() + b"\n"},
        )
    except ExportError as error:
        raise ReplayError(str(error)) from None
    print(
        f"lit replay tensors: {len(episodes)} episodes, {provenance['decisions']} decisions, "
        f"{sum(a.transitions for a in core.agents.values())} transitions, "
        f"policy version {core.policy_version}"
    )
    episodes_left_out = {
        reason: skipped.counts.pop(reason) for reason in (RECORDED_AGAIN, INCOMPLETE, NO_SUMMARY)
        if skipped.counts.get(reason)
    }  # fmt: skip
    if episodes_left_out:
        print("  episodes left out: " + "; ".join(
            f"{reason}: {count}" for reason, count in episodes_left_out.items()))  # fmt: skip
    print(f"  messages: {skipped.line()}")
    print(f"  psi_K decision interval {interval.value} ({interval.source})")
    for name, text in (paths | left_out).items():
        print(f"  {name}: {text}")
    return 0


@dataclass(frozen=True)
class RecordedInterval:
    """The psi_K decision interval that ``lit replay tensors`` records with its tensors."""

    value: int
    """Expansions per psi_K decision."""
    source: str
    """Where it came from, for the user."""


def bag_decision_interval(path: Path) -> int | None:
    """The psi_K decision interval that bag ``path`` names: ``lit train`` writes it into the
    metadata (``lit.decision_interval``); for older ``lit train`` bags it is the
    ``--decision-interval`` of the recorded command (default 1) unless that run was resumed (a
    resumed run keeps its checkpoint's interval). None when the bag does not say (recorder and
    bench bags, a bare ``.mcap`` without its ``metadata.yaml``, a bag salvaged without either
    ``metadata.yaml`` or the writer's ``lit-unfinished.json``).

    Raises:
        ReplayError: the bag's metadata names an interval that is not a whole number of at
            least 1.
    """
    import shlex

    from lit_learner.train import (
        DECISION_INTERVAL_KEY,
        DEFAULT_DECISION_INTERVAL,
        add_arguments,
    )

    custom = _bag_custom_data(path)
    if DECISION_INTERVAL_KEY in custom:
        text = str(custom[DECISION_INTERVAL_KEY])
        if not text.isdigit() or not 1 <= int(text) <= MAX_INTERVAL:
            raise ReplayError(
                f"{path}: metadata {DECISION_INTERVAL_KEY} is {text!r}, not a whole number "
                f"between 1 and {MAX_INTERVAL}"
            )
        return int(text)
    if custom.get("lit.source") != TRAIN_SOURCE:
        return None
    words = shlex.split(str(custom.get("lit.command", "")))
    if "train" not in words:
        return None
    parser = argparse.ArgumentParser(add_help=False, exit_on_error=False)
    add_arguments(parser)
    try:
        known, _ = parser.parse_known_args(words[words.index("train") + 1 :])
    except (argparse.ArgumentError, SystemExit):
        return None
    if known.resume is not None:
        return None
    if known.decision_interval is None:  # not given: lit train's default
        known.decision_interval = DEFAULT_DECISION_INTERVAL
    if not 1 <= known.decision_interval <= MAX_INTERVAL:
        return None
    return int(known.decision_interval)


def recorded_decision_interval(paths: list[Path], given: int | None = None) -> RecordedInterval:
    """The psi_K decision interval of the bags' training episodes (:func:`bag_decision_interval`
    of each bag that holds any; bench bags hold none and are not asked). ``given`` (the
    ``--decision-interval`` option) must agree with every bag that names one and stands for
    those that do not; without it, bags that do not name one count as 1, the planner node's
    interval in training by default.

    Raises:
        ReplayError: ``given`` is not between 1 and :data:`MAX_INTERVAL`, two bags name different
            intervals, or ``given`` contradicts a bag.
    """
    from lit_planner.bag import BENCH_SOURCE

    if given is not None and not 1 <= given <= MAX_INTERVAL:
        raise ReplayError(f"--decision-interval must be between 1 and {MAX_INTERVAL}, got {given}")
    named: dict[int, list[str]] = {}
    silent: list[str] = []
    for path in paths:
        if _bag_source(path) == BENCH_SOURCE:
            continue
        value = bag_decision_interval(path)
        if value is None:
            silent.append(str(path))
        else:
            named.setdefault(value, []).append(str(path))
    listed = "; ".join(f"{value}: {', '.join(bags)}" for value, bags in sorted(named.items()))
    if len(named) > 1:
        raise ReplayError(
            f"the bags were recorded with different psi_K decision intervals ({listed}); "
            "replay the bags of one interval at a time"
        )
    if given is not None:
        if named and given not in named:
            raise ReplayError(
                f"--decision-interval {given} contradicts the bags, which name {listed}"
            )
        return RecordedInterval(given, "--decision-interval")
    if named:
        ((value, bags),) = named.items()
        if silent:
            return RecordedInterval(
                value,
                f"named by {', '.join(bags)}; {', '.join(silent)} name none (taken to be the "
                "same; give --decision-interval to state it)",
            )
        return RecordedInterval(value, "named by the bags")
    return RecordedInterval(
        1,
        "the bags name none: taken to be 1, the planner node's interval in training by default; "
        "give --decision-interval if they were recorded at another",
    )


def _bag_source(path: Path) -> str | None:
    source = _bag_custom_data(path).get("lit.source")
    return None if source is None else str(source)


def _bag_custom_data(path: Path) -> dict[str, Any]:
    """The ``custom_data`` of the bag's ``metadata.yaml`` (beside a ``.mcap`` file given
    instead of the folder); empty without one (a salvaged or bare ``.mcap``).

    Raises:
        ReplayError: the metadata file is not rosbag2's.
    """
    from lit_planner.replay import load_metadata

    metadata = (path if path.is_dir() else path.parent) / "metadata.yaml"
    if not metadata.is_file():
        return {}
    custom = load_metadata(metadata).get("custom_data") or {}
    return dict(custom) if isinstance(custom, dict) else {}


TRAIN_SOURCE = "lit_train"
"""Envelope ``source`` (and bag ``lit.source``) of ``lit train``'s recordings."""
RECORDED_AGAIN = "training episode recorded again (the later recording is used)"
"""Why an episode's earlier recording is left out: a ``lit train`` run resumed from an earlier
checkpoint (``--rollback``, or after a second Ctrl-C) ran it again under the same id. (A planner
node restarted under the same run id numbers its episodes from 0 again too, but its learner,
which went on, trained on both: those are episodes of their own.)"""
INCOMPLETE = "incomplete training episode"
NO_SUMMARY = "episode without its summary (cut off, or the summary lost)"
"""Why an episode whose decisions are there and whose EpisodeSummary is not is left out: its
mode, scenario and end are unknown (a bag cut off in its last episode, a lost chunk)."""


class _Sessions:
    """Which publishing session of a publisher and run a message belongs to. A resumed ``lit
    train`` run publishes under the same run id with every topic's seq from 0 again: a topic's
    seq that does not rise starts the next session, which the publisher's other topics then
    join as their seq restarts."""

    def __init__(self) -> None:
        self._current: dict[tuple[str, str], int] = {}
        self._topics: dict[tuple[str, str, str], tuple[int, int]] = {}

    def of(self, item: Envelope) -> int:
        publisher = (item.source, item.run_id)
        session = self._current.get(publisher, 0)
        last = self._topics.get((item.topic, *publisher))
        if last is not None and item.seq <= last[0] and last[1] == session:
            session = self._current[publisher] = session + 1
        self._topics[(item.topic, *publisher)] = (item.seq, session)
        return session


def _identity(key: tuple[str, str, str, int]) -> tuple[Any, ...]:
    """Which recordings (``key``: source, run id, episode id, publishing session) are one episode:
    a ``lit train`` run's of one id in any session (a resumed run ran it again); a planner node's
    of one id in one session (a restarted node numbers its episodes from 0 again)."""
    return key[:3] if key[0] == TRAIN_SOURCE else key


def read_episodes(
    paths: list[Path], progress: bool | None = False
) -> tuple[list[RecordedEpisode], Skipped]:
    """Complete training episodes (summary, and as many observations and decisions as the
    summary counts decisions), in the order their summaries were recorded. A message read twice
    (a bag given with its compacted or salvaged copy: the same topic, publisher, run and seq)
    counts once; it was paired twice, and the pairing failed on the second copy's earlier
    times. An episode recorded again by a resumed ``lit train`` run (same run and episode id, a
    later publishing session) takes the place of its first recording with the content of its
    latest one (the latest summary stamp): the episodes the resumed learner trained on. A planner
    node's later session (the node restarted under the same run id, its episode numbers from 0
    again) holds episodes of their own: the learner node trained on both. ``progress``: a
    progress bar per bag on standard error (None: only on a terminal)."""
    from tqdm import tqdm

    skipped = Skipped()
    found: dict[tuple[str, str, str, int], RecordedEpisode] = {}
    order: list[tuple[str, str, str, int]] = []
    seen: dict[tuple[str, str, str, int, int], bytes] = {}
    sessions = _Sessions()
    for path in paths:
        with BagReader(path) as reader:
            for message in tqdm(
                reader.messages(), total=reader.facts.messages, unit="msg", unit_scale=True,
                desc=f"reading {Path(path).name}", disable=_no_bar(progress), leave=False,
                dynamic_ncols=True,
            ):  # fmt: skip
                item = decode(message, skipped)
                if not isinstance(item, Envelope) or not isinstance(item.payload, dict):
                    continue
                if item.schema in (OBSERVATION, DECISION, SOLUTION, SUMMARY) and not payload_ok(
                    item, skipped
                ):
                    continue
                again = read_before(seen, item, message.data)
                if again is not None:
                    skipped.counts[again] += 1
                    continue
                session = sessions.of(item)
                episode_id = item.payload.get("episode_id")
                if episode_id is None:
                    continue
                key = (item.source, item.run_id, str(episode_id), session)
                episode = found.setdefault(key, RecordedEpisode(key[:3]))
                if item.schema == OBSERVATION:
                    episode.observations.append(item.payload)
                elif item.schema == DECISION:
                    episode.decisions.append(item.payload)
                elif item.schema == SOLUTION:
                    episode.solutions.append(item.payload)
                elif item.schema == SUMMARY:
                    episode.summary = item.payload
                    episode.summary_stamp_ns = item.stamp_ns
                    order.append(key)
    # Counted, not dropped without a word (the replay's "messages" line showed nothing of them).
    summarized = {_identity(k) for k, e in found.items() if e.summary is not None}  # run again
    cut_off = sum(
        1
        for k, e in found.items()
        if e.summary is None and e.decisions and _identity(k) not in summarized
    )
    if cut_off:
        skipped.counts[NO_SUMMARY] += cut_off
    # Each episode once, at its first recording's place, as its latest recording holds it.
    latest: dict[tuple[Any, ...], RecordedEpisode] = {}
    for key in order:
        episode = found[key]
        if episode.summary is None or episode.summary.get("mode") != "training":
            continue
        identity = _identity(key)
        kept = latest.setdefault(identity, episode)
        if kept is not episode:
            skipped.counts[RECORDED_AGAIN] += 1
            if episode.summary_stamp_ns > kept.summary_stamp_ns:
                latest[identity] = episode
    complete = []
    for episode in latest.values():
        summary = episode.summary
        assert summary is not None
        # Its summary counts the decisions made: a lost observation and decision pair (a gap
        # in the recording) left an episode that looked complete by the pairing alone.
        made = summary.get("decisions")
        counted = (
            sum(made.values())
            if isinstance(made, dict)
            and all(isinstance(n, int) and not isinstance(n, bool) for n in made.values())
            else None
        )
        if (
            len(episode.observations) != len(episode.decisions)
            or not episode.decisions
            or len(episode.decisions) != counted
            or not _every_solution(episode)
        ):
            skipped.counts[INCOMPLETE] += 1
            continue
        complete.append(episode)
    return complete, skipped


def _every_solution(episode: RecordedEpisode) -> bool:
    """Whether the episode's SolutionUpdates are its summary's improvements 1, 2, ..., n in
    time order: a lost one (a gap in the recording) would give every later decision one
    improvement too few, and its B step the reward of a step without one."""
    assert episode.summary is not None
    solutions = sorted(episode.solutions, key=lambda s: (s["planning_time"], s["improvement"]))
    expected = episode.summary.get("improvements")
    return isinstance(expected, int) and [s["improvement"] for s in solutions] == list(
        range(1, expected + 1)
    )


def _no_bar(progress: bool | None) -> bool | None:
    """tqdm's ``disable`` for ``progress`` (None: tqdm's own choice, a bar on a terminal only)."""
    return None if progress is None else not progress


def offline_config(
    seed: int, train: str, warmup: int | None = None, batch_size: int | None = None
) -> Any:
    """The learner's configuration for ``lit replay tensors``: its defaults, with ``warmup`` and
    ``batch_size`` (when given) for both agents.

    Raises:
        ConfigError: a combination the learner refuses (a warm-up below the batch size, say).
    """
    from lit_learner.config import AgentConfig, LearnerConfig

    overrides = {
        key: value
        for key, value in (("warmup", warmup), ("batch_size", batch_size))
        if value is not None
    }
    return LearnerConfig(
        b=AgentConfig.batch_size_agent(**overrides),
        k=AgentConfig.neighbour_agent(**overrides),
        seed=seed,
        train_b=train in ("both", "B"),
        train_k=train in ("both", "psi_K"),
    )


def train_offline(
    episodes: list[RecordedEpisode], config: Any, progress: bool | None = False
) -> Any:
    """A :class:`~lit_learner.core.LearnerCore` of ``config`` (:func:`offline_config`) trained
    on ``episodes``; ``progress``: a progress bar on standard error (None: only on a
    terminal)."""
    from tqdm import tqdm

    from lit_learner.core import LearnerCore

    core = LearnerCore(config)
    for episode in tqdm(
        episodes, unit="ep", desc="training", disable=_no_bar(progress), dynamic_ncols=True,
    ):  # fmt: skip
        _replay_episode(core, episode)
    return core


def _replay_episode(core: Any, episode: RecordedEpisode) -> None:
    from lit_learner.messages import DecisionRequest, EpisodeEnd, episode_key
    from lit_learner.train import BUDGET_TOLERANCE, minimum_cost
    from lit_planner import scenarios

    summary = episode.summary
    assert summary is not None
    problem = scenarios.get(summary["scenario"])
    budget = float(summary["time_budget"] or problem.time_budget)
    c_min = minimum_cost(problem)
    solutions = sorted(episode.solutions, key=lambda s: (s["planning_time"], s["improvement"]))
    times = [s["planning_time"] for s in solutions]
    episode_id = episode_key(*episode.key)
    for observation, decision in zip(episode.observations, episode.decisions, strict=True):
        kind = decision["kind"]
        at = observation["planning_time"]
        improved = bisect.bisect_right(times, at)
        core.record(
            DecisionRequest(
                agent=kind,
                episode_id=episode_id,
                rho_global=observation["rho_global"],
                rho_local=observation["rho_local_b" if kind == "B" else "rho_local_k"],
                measure=observation["measure"],
                planning_time=at,
                time_budget=budget,
                cost=observation["cost"],
                minimum_cost=c_min,
                improvements=improved,
                path_states=solutions[improved - 1]["path_states"] if improved else 0,
            ),
            float(decision["value"]),
        )
    time = float(summary["time"])
    core.end_episode(
        EpisodeEnd(
            episode_id=episode_id,
            planning_time=time,
            time_budget=budget,
            cost=summary["cost"] if summary["solved"] else None,
            minimum_cost=c_min,
            improvements=int(summary["improvements"]),
            path_states=int(summary["path_states"]),
            truncated=time >= budget * (1.0 - BUDGET_TOLERANCE),
            # Version 3 summaries carry them (as the live EpisodeEnd did); older ones close each
            # agent's last step with its last request's features.
            final_features={
                agent: tuple(values) for agent, values in summary["final_features"].items()
            }
            if summary.get("final_features")
            else None,
        )
    )

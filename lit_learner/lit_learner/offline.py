"""``lit replay tensors``: train Fuzzy-DDPG offline on the transitions recorded in bags.

A recorded training episode (an EpisodeSummary with mode ``training``) is rebuilt from what the
planner published: its Observation and Decision messages (the n-th of each belong together; both
are published in the planner's decision order) give each decision's features, planner time and
executed value; its SolutionUpdate messages give the improvements and path states up to that time;
the summary gives the budget, the final state and the scenario (for c_min). Each decision is fed to
:meth:`~lit_learner.core.LearnerCore.record` (the executed value, not a new action: DDPG learns
off-policy, so fallback decisions count too), each episode is closed with
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

from lit_planner.replay import BagReader, Envelope, ReplayError, Skipped, decode

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


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``lit replay tensors``."""
    parser.add_argument("bags", type=Path, nargs="+", metavar="BAG")
    parser.add_argument("--out", type=Path, required=True, metavar="DIR", help="tensor folder")
    parser.add_argument("--seed", type=int, default=0, help="learner seed (default 0)")
    parser.add_argument(
        "--train", choices=("both", "B", "psi_K"), default="both", help="agents that learn"
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
        "so that the tensor policy applies it (default: from the bags: lit train records it; "
        "1, the planner node's in training, for bags that do not name one)",
    )  # fmt: skip


def run(args: argparse.Namespace) -> int:
    """Read, train, export; print what was used."""
    episodes, skipped = read_episodes(args.bags)
    if not episodes:
        raise ReplayError("no complete training episode in the given bags")
    interval = args.decision_interval
    if interval is None:
        interval = recorded_decision_interval(args.bags)
    elif interval < 1:
        raise ReplayError(f"--decision-interval must be at least 1, got {interval}")
    core = train_offline(episodes, args.seed, args.train, args.warmup, args.batch_size)
    provenance = {
        "exported_by": "lit replay tensors",
        "bags": [str(path) for path in args.bags],
        "seed": args.seed,
        "train": args.train,
        "warmup": args.warmup,
        "batch_size": args.batch_size,
        "episodes": len(episodes),
        "decisions": sum(len(e.decisions) for e in episodes),
        "decision_interval": interval,
    }
    paths = core.export_tensors(args.out, provenance)
    (Path(args.out) / "provenance.json").write_text(json.dumps(provenance, indent=2) + "\n")
    print(
        f"lit replay tensors: {len(episodes)} episodes, {provenance['decisions']} decisions, "
        f"{sum(a.transitions for a in core.agents.values())} transitions, "
        f"policy version {core.policy_version}; skipped {sum(skipped.counts.values())} messages"
    )
    for name, path in paths.items():
        print(f"  {name}: {path}")
    return 0


def recorded_decision_interval(paths: list[Path]) -> int:
    """The expansions per psi_K decision of the bags' episodes: the ``lit.decision_interval``
    that ``lit train`` records, else the ``--decision-interval`` of a ``lit train`` command in
    ``lit.command`` (a fresh run's; a resumed run's command does not name it), else 1 (the
    planner node's interval in training, and ``lit train``'s default).

    Raises:
        ReplayError: the bags name different intervals, or a resumed ``lit train`` run's bag
            names none (give ``--decision-interval``).
    """
    import shlex

    from lit_learner.train import DECISION_INTERVAL_KEY, DEFAULT_DECISION_INTERVAL

    found: dict[int, list[str]] = {}
    for path in paths:
        with BagReader(path) as reader:
            custom = reader.facts.custom_data
        value: int | None = None
        if DECISION_INTERVAL_KEY in custom:
            value = int(custom[DECISION_INTERVAL_KEY])
        elif custom.get("lit.source") == "lit_train":
            words = shlex.split(custom.get("lit.command", ""))
            for index, word in enumerate(words):
                if word == "--decision-interval" and index + 1 < len(words):
                    value = int(words[index + 1])
                elif word.startswith("--decision-interval="):
                    value = int(word.split("=", 1)[1])
            if value is None and "--resume" in words:
                raise ReplayError(
                    f"{path}: a resumed lit train run's bag does not say its decision interval; "
                    "give --decision-interval (the first bag of the run names it)"
                )
        found.setdefault(DEFAULT_DECISION_INTERVAL if value is None else value, []).append(
            str(path)
        )
    if len(found) > 1:
        named = "; ".join(f"{value}: {', '.join(bags)}" for value, bags in sorted(found.items()))
        raise ReplayError(
            f"the bags were recorded with different decision intervals ({named}); replay one "
            "interval at a time or give --decision-interval"
        )
    return next(iter(found))


def read_episodes(paths: list[Path]) -> tuple[list[RecordedEpisode], Skipped]:
    """Complete training episodes (summary, and as many observations as decisions), in the
    order their summaries were recorded."""
    skipped = Skipped()
    found: dict[tuple[str, str, str], RecordedEpisode] = {}
    order: list[tuple[str, str, str]] = []
    for path in paths:
        with BagReader(path) as reader:
            for message in reader.messages():
                item = decode(message, skipped)
                if not isinstance(item, Envelope) or not isinstance(item.payload, dict):
                    continue
                episode_id = item.payload.get("episode_id")
                if episode_id is None:
                    continue
                key = (item.source, item.run_id, str(episode_id))
                episode = found.setdefault(key, RecordedEpisode(key))
                if item.schema == OBSERVATION:
                    episode.observations.append(item.payload)
                elif item.schema == DECISION:
                    episode.decisions.append(item.payload)
                elif item.schema == SOLUTION:
                    episode.solutions.append(item.payload)
                elif item.schema == SUMMARY:
                    episode.summary = item.payload
                    order.append(key)
    complete = []
    for key in order:
        episode = found[key]
        summary = episode.summary
        if summary is None or summary.get("mode") != "training":
            continue
        if len(episode.observations) != len(episode.decisions) or not episode.decisions:
            skipped.counts["incomplete training episode"] += 1
            continue
        complete.append(episode)
    return complete, skipped


def train_offline(
    episodes: list[RecordedEpisode],
    seed: int,
    train: str,
    warmup: int | None = None,
    batch_size: int | None = None,
) -> Any:
    """A :class:`~lit_learner.core.LearnerCore` trained on ``episodes``."""
    from lit_learner.config import AgentConfig, LearnerConfig
    from lit_learner.core import LearnerCore

    overrides = {
        key: value
        for key, value in (("warmup", warmup), ("batch_size", batch_size))
        if value is not None
    }
    config = LearnerConfig(
        b=AgentConfig.batch_size_agent(**overrides),
        k=AgentConfig.neighbour_agent(**overrides),
        seed=seed,
        train_b=train in ("both", "B"),
        train_k=train in ("both", "psi_K"),
    )
    core = LearnerCore(config)
    for episode in episodes:
        _replay_episode(core, episode)
    return core


def _replay_episode(core: Any, episode: RecordedEpisode) -> None:
    from lit_learner.messages import DecisionRequest, EpisodeEnd
    from lit_learner.train import BUDGET_TOLERANCE, minimum_cost
    from lit_planner import scenarios

    summary = episode.summary
    assert summary is not None
    problem = scenarios.get(summary["scenario"])
    budget = float(summary["time_budget"] or problem.time_budget)
    c_min = minimum_cost(problem)
    solutions = sorted(episode.solutions, key=lambda s: s["planning_time"])
    times = [s["planning_time"] for s in solutions]
    episode_id = "|".join(episode.key)
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
        )
    )

"""The contract's messages about one planning query, built from the core's result (no ROS).

The planner node publishes them; ``lit train`` writes them straight into its bag. Both therefore
record the same Observation, Decision, SolutionUpdate and EpisodeSummary payloads, and
``lit replay tensors`` / ``verify`` read either.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any


@dataclass
class EventLog:
    """A listener for ``lit_core.solve``: keeps batch counters (for observations) and hands each
    solution improvement to ``on_solution_payload`` as a SolutionUpdate payload at once."""

    episode_id: str
    on_solution_payload: Any = None
    """Callable taking the payload, or None."""
    batches: list[tuple[float, int, int, int]] = field(default_factory=list)
    """(time, batch, valid samples, invalid samples) per batch."""
    solutions: list[dict[str, Any]] = field(default_factory=list)
    """SolutionUpdate payloads so far."""

    def on_solution(self, event: Any) -> None:
        payload = {
            "episode_id": self.episode_id,
            "planning_time": max(0.0, float(event.time)),
            "cost": float(event.cost),
            "path_states": int(event.path_states),
            "improvement": max(1, int(event.improvement)),
            "iteration": int(event.iteration),
        }
        self.solutions.append(payload)
        if self.on_solution_payload is not None:
            self.on_solution_payload(payload)

    def on_batch(self, event: Any) -> None:
        self.batches.append(
            (
                float(event.time),
                int(event.batch),
                int(event.valid_samples),
                int(event.invalid_samples),
            )
        )


@dataclass
class DecisionSources:
    """Where each decision of a query came from, in decision order (training mode)."""

    sources: list[str] = field(default_factory=list)
    latencies: list[float | None] = field(default_factory=list)
    fallbacks: int = 0
    learner_calls: int = 0
    warned: bool = False
    """The query's one warning about an unreachable learner was logged."""
    resumed: bool = False
    """The query's one note that a late learner answered and calls resume was logged."""
    resent_before: int = 0
    """The learner client's count of requests sent again when the query started."""
    answered_by_copy_before: int = 0
    """The learner client's count of calls answered through a copy when the query started."""

    def add(self, source: str, latency_ms: float | None = None) -> None:
        self.sources.append(source)
        self.latencies.append(latency_ms)


def decision_payloads(
    episode_id: str,
    result: dict[str, Any],
    log: EventLog,
    policy: str,
    sources: DecisionSources | None = None,
) -> Iterator[tuple[dict[str, Any], dict[str, Any]]]:
    """(Observation, Decision) payload pairs, one per decision the core recorded."""
    solutions = result["improvements"]
    solution_times = [float(t) for t, _ in solutions]
    batch_times = [event[0] for event in log.batches]
    for index, decision in enumerate(result.get("decisions", [])):
        at = float(decision["time"])
        solved = bisect.bisect_right(solution_times, at)
        batch = bisect.bisect_right(batch_times, at) - 1
        _, batches, valid, invalid = log.batches[batch] if batch >= 0 else (0, 0, 0, 0)
        observation = {
            "episode_id": episode_id,
            "kind": decision["kind"],
            "rho_global": unit(decision["rho_global"]),
            "rho_local_b": unit(decision["rho_local_b"]),
            "rho_local_k": unit(decision["rho_local_k"]),
            "measure": unit(decision["measure"]),
            "planning_time": max(0.0, at),
            "iteration": int(decision["iteration"]),
            "batches": int(batches),
            "valid_samples": int(valid),
            "invalid_samples": int(invalid),
            "has_solution": solved > 0,
            "cost": float(solutions[solved - 1][1]) if solved else None,
        }
        known = sources is not None and index < len(sources.sources)
        chosen = {
            "episode_id": episode_id,
            "kind": decision["kind"],
            "value": float(decision["value"]),
            "neighbours": int(decision["neighbours"]),
            "policy": policy,
            "source": sources.sources[index] if known else _policy_source(policy),
            "planning_time": max(0.0, at),
        }
        if known and sources.latencies[index] is not None:
            chosen["latency_ms"] = float(sources.latencies[index])
        yield observation, chosen


def summary_payload(
    episode_id: str,
    mode: str,
    scenario: Any,
    seed: int,
    policy: str,
    result: dict[str, Any],
    sources: DecisionSources | None = None,
) -> dict[str, Any]:
    """The EpisodeSummary payload of one query."""
    counts = {"B": 0, "psi_K": 0}
    for decision in result.get("decisions", []):
        counts[decision["kind"]] = counts.get(decision["kind"], 0) + 1
    check = result.get("path_check")
    payload = {
        "episode_id": episode_id,
        "mode": mode,
        "scenario": scenario.key,
        "instance": int(scenario.instance),
        "dimension": int(scenario.dim),
        "planner": result["planner"],
        "policy": policy or "none",
        "seed": int(seed),
        "status": result["status"],
        "solved": bool(result["solved"]),
        "cost": finite(result["cost"]),
        "t_init": finite(result["t_init"]),
        "c_init": finite(result["c_init"]),
        "optimal_cost": scenario.optimal_cost,
        "time": float(result["time"]),
        "time_budget": result.get("time_budget"),
        "improvements": len(result["improvements"]),
        "decisions": counts,
        "fallback_decisions": sources.fallbacks if sources else 0,
        "learner_calls": sources.learner_calls if sources else 0,
        "path_states": len(result["path"]),
        "path_valid": None if check is None else bool(check["ok"]),
        "counters": {k: int(v) for k, v in result["counters"].items()},
    }
    world = world_payload(scenario)
    if world is not None:
        payload["world"] = world
    final = result.get("final_features")
    if mode == "training" and final:  # the s' of each agent's last step, for lit replay tensors
        payload["final_features"] = {
            agent: [unit(value) for value in values] for agent, values in final.items()
        }
    return payload


def encode_summary(publisher: Any, summary: dict[str, Any]) -> tuple[str, str | None]:
    """``summary`` encoded by ``publisher`` (a ``lit_msgs_json`` Publisher), and None; or, when
    its ``world`` makes it larger than a message may be (thousands of boxes fit a PlanRequest
    but, with everything else, not a summary), the summary without the world and the reason,
    for a warning: an answered plan must not fail on its summary, whose path then cannot be
    re-checked from a bag.

    Raises:
        MessageError: the summary is invalid for another reason.
    """
    from lit_msgs_json.envelope import MessageError

    try:
        return publisher.encode("EpisodeSummary", summary), None
    except MessageError as error:
        if error.code != "oversize" or "world" not in summary:
            raise
        trimmed = {key: value for key, value in summary.items() if key != "world"}
        return publisher.encode("EpisodeSummary", trimmed), str(error)


def world_payload(scenario: Any) -> dict[str, Any] | None:
    """The EpisodeSummary's ``world`` of a custom scenario (what a replay needs to re-check its
    path: bounds, boxes, resolution, start, goal); None for a registry scenario, which its name
    and instance identify."""
    from lit_planner.scenarios import CUSTOM_FAMILY

    if scenario.family != CUSTOM_FAMILY:
        return None
    return {
        "lower": [float(x) for x in scenario.lower],
        "upper": [float(x) for x in scenario.upper],
        "boxes": [{"lower": box[0].tolist(), "upper": box[1].tolist()} for box in scenario.boxes],
        "resolution": float(scenario.resolution),
        "start": [float(x) for x in scenario.start],
        "goal": [float(x) for x in scenario.goal],
    }


def path_timing(path: Sequence[Sequence[float]]) -> list[float]:
    """Seconds from the start of each path state at unit speed along the path."""
    elapsed, previous, times = 0.0, None, []
    for state in path:
        if previous is not None:
            elapsed += math.dist(previous, state)
        previous = state
        times.append(elapsed)
    return times


def _policy_source(policy: str) -> str:
    if policy in ("tensor", "fixed", "fit"):
        return policy
    return "learner" if policy == "training" else "fixed"


def finite(value: float | None) -> float | None:
    """``value`` as a float, None when missing or not finite (JSON has no infinity)."""
    return float(value) if value is not None and math.isfinite(value) else None


def unit(value: float) -> float:
    """A feature clamped into [0, 1] (guards against round-off just outside)."""
    return min(1.0, max(0.0, float(value))) if math.isfinite(value) else 0.0

"""Message -> transition pairing (LEARNER.md "Episodes, steps, transitions").

Per (episode, agent) the previous request is pending. A new request of the same agent in the same
episode closes it as (s, a, r, s', terminated=False, truncated=False) with s' the new request's
features; an episode end closes every pending step of that episode (truncated per its flag,
terminated otherwise). Episodes are kept apart by ``episode_id``, so several planners may feed one
learner. The rewards follow from the progress information of the closing message.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from lit_learner.config import AGENT_NAMES, RewardConfig
from lit_learner.errors import PairingError
from lit_learner.messages import COST_TOLERANCE, DecisionRequest, EpisodeEnd, Features
from lit_learner.rewards import RewardTerms, batch_size_reward, neighbour_reward


@dataclass(frozen=True)
class Transition:
    """One agent step of one episode."""

    agent: str
    episode_id: str
    state: Features
    """Raw features at the decision."""
    action: float
    """Executed action, normalised to [0, 1]."""
    reward: RewardTerms
    next_state: Features
    terminated: bool
    truncated: bool


@dataclass
class PendingStep:
    """A decision whose outcome is not known yet."""

    state: Features
    action: float
    improvements: int
    """Improvements when the decision was taken."""
    time: float = 0.0
    """Planner time when the decision was taken."""


def check_order(
    episode_id: str,
    before: tuple[float, int, float | None],
    planning_time: float,
    improvements: int,
    cost: float | None,
) -> None:
    """Raise PairingError when a message of an episode whose earlier messages reached
    ``before`` (latest planning time, most improvements, lowest cost or None) goes back:
    ``planning_time`` before the latest, ``improvements`` below the most (improvements only add
    up), or ``cost`` above the lowest or None after it (a best cost only falls: a rising one was
    taken, and R_B / R_K rewarded it as the path's new quality)."""
    last_time, seen, best_cost = before
    if planning_time < last_time:
        raise PairingError(
            f"episode {episode_id!r}: planning_time {planning_time} is before the previous "
            f"message's {last_time}",
            field="planning_time",
        )
    if improvements < seen:
        raise PairingError(
            f"episode {episode_id!r}: improvements {improvements} is below the {seen} an "
            "earlier message reported",
            field="improvements",
        )
    # The end's cost is the path's length summed again: an ulp above on a machine whose OMPL
    # fuses multiply-adds (arm64).
    if best_cost is not None and (cost is None or cost > best_cost * (1.0 + COST_TOLERANCE)):
        raise PairingError(
            f"episode {episode_id!r}: "
            + ("no cost (no solution)" if cost is None else f"cost {cost} is above")
            + f" after the cost {best_cost} an earlier message reported (a best cost only falls)",
            field="cost",
        )


@dataclass
class EpisodeProgress:
    """What the pairing remembers of one episode."""

    improvement_times: dict[int, float] = field(default_factory=lambda: {0: 0.0})
    """Planner time at which each improvement count was first seen (0 improvements at t = 0)."""
    last_time: float = 0.0
    pending: dict[str, PendingStep] = field(default_factory=dict)
    returns: dict[str, float] = field(default_factory=dict)
    """Undiscounted return per agent so far."""
    best_cost: float | None = None
    """The lowest cost a message reported, None before a solution."""

    def check(
        self, episode_id: str, planning_time: float, improvements: int, cost: float | None
    ) -> None:
        """:func:`check_order` against this episode's messages so far."""
        check_order(
            episode_id,
            (self.last_time, max(self.improvement_times), self.best_cost),
            planning_time,
            improvements,
            cost,
        )

    def observe(
        self, episode_id: str, planning_time: float, improvements: int, cost: float | None
    ) -> None:
        self.check(episode_id, planning_time, improvements, cost)
        self.last_time = planning_time
        if cost is not None:  # the lowest (one within the tolerance above it moves nothing)
            self.best_cost = cost if self.best_cost is None else min(self.best_cost, cost)
        if improvements not in self.improvement_times and improvements > max(
            self.improvement_times
        ):
            self.improvement_times[improvements] = planning_time

    def step_time(self, improvements: int) -> float:
        """Planner time from the improvement before ``improvements`` to it (or from the start)."""
        previous = max(n for n in self.improvement_times if n < improvements)
        return self.improvement_times[improvements] - self.improvement_times[previous]


class Pairing:
    """Turns the message stream of any number of episodes into transitions."""

    def __init__(self, reward: RewardConfig) -> None:
        self.reward = reward
        self.episodes: dict[str, EpisodeProgress] = {}

    def abandon(self, episode_id: str) -> bool:
        """Forget an episode whose end will not come (its pending steps have no s'); whether it
        was open."""
        return self.episodes.pop(episode_id, None) is not None

    def check(self, request: DecisionRequest) -> None:
        """Raise the :class:`PairingError` that :meth:`step` would raise for ``request``, without
        changing anything."""
        episode = self.episodes.get(request.episode_id)
        if episode is not None:
            episode.check(
                request.episode_id, request.planning_time, request.improvements, request.cost
            )

    def step(self, request: DecisionRequest, action: float | None) -> Transition | None:
        """Close the agent's pending step in this episode (if any) and open a new one. After a
        fallback (``request.after_fallback``) the pending step is dropped instead: the planner
        did not execute its action, or executed others within it.

        Args:
            request: the decision request.
            action: the executed a_norm; None records nothing new (the agent is not trained).

        Returns:
            The closed transition, or None when nothing was pending.
        """
        episode = self.episodes.setdefault(request.episode_id, EpisodeProgress())
        episode.observe(
            request.episode_id, request.planning_time, request.improvements, request.cost
        )
        closed = None
        pending = episode.pending.pop(request.agent, None)
        if pending is not None and not request.after_fallback:
            closed = self._close(
                request.agent,
                request.episode_id,
                episode,
                pending,
                request.features,
                request,
                terminated=False,
                truncated=False,
            )
        if action is not None:
            episode.pending[request.agent] = PendingStep(
                request.features, float(action), request.improvements, request.planning_time
            )
        return closed

    def progress(self, request: DecisionRequest) -> None:
        """Note an episode's progress (time, improvements) from a decision that no step is
        made of: ``lit train``'s psi_K phase takes B from a tensor, and without its decisions,
        which come at every improvement, an improvement's time was the time of the next psi_K
        request (up to 47 % of the budget later on development queries)."""
        episode = self.episodes.setdefault(request.episode_id, EpisodeProgress())
        episode.observe(
            request.episode_id, request.planning_time, request.improvements, request.cost
        )

    def end(self, end: EpisodeEnd) -> tuple[list[Transition], dict[str, float]]:
        """Close every pending step of the episode and forget it.

        Returns:
            The closed transitions (B first) and each agent's undiscounted episode return
            (agents that took no step are absent).
        """
        episode = self.episodes.get(end.episode_id)
        if episode is None:
            return [], {}
        # An end out of time order is refused with the episode still open (it can be abandoned).
        episode.observe(end.episode_id, end.planning_time, end.improvements, end.cost)
        del self.episodes[end.episode_id]
        closed = []
        for agent in AGENT_NAMES:
            pending = episode.pending.pop(agent, None)
            if pending is None or agent in end.fallback_agents:
                continue  # a fallback value was executed last: the step is not the agent's
            final = (end.final_features or {}).get(agent, pending.state)
            closed.append(
                self._close(
                    agent,
                    end.episode_id,
                    episode,
                    pending,
                    tuple(final),
                    end,
                    terminated=not end.truncated,
                    truncated=end.truncated,
                )
            )
        return closed, dict(episode.returns)

    def _close(
        self,
        agent: str,
        episode_id: str,
        episode: EpisodeProgress,
        pending: PendingStep,
        next_state: Features,
        info: DecisionRequest | EpisodeEnd,
        *,
        terminated: bool,
        truncated: bool,
    ) -> Transition:
        improved = info.improvements > pending.improvements
        step_time = episode.step_time(info.improvements) if improved else 0.0
        if agent == "B":
            reward = batch_size_reward(
                improved,
                info.improvements,
                step_time,
                info.time_budget,
                info.cost,
                info.minimum_cost,
                self.reward,
            )
        else:
            # A step that began without a solution searched from its decision to its end, or to
            # the first solution if that came in the step (the time the pairing saw it: a B
            # decision comes at it): the search costs of an episode add up to ln(t_init / ...).
            searching = None
            if pending.improvements == 0:
                end = info.planning_time
                firsts = [t for n, t in episode.improvement_times.items() if n >= 1]
                if improved and firsts:  # the first count seen may be above 1 (calls missed)
                    end = min(end, min(firsts))
                searching = (pending.time, end)
            reward = neighbour_reward(
                improved,
                step_time,
                info.time_budget,
                info.cost,
                info.minimum_cost,
                info.path_states,
                self.reward,
                search=searching,
            )
        episode.returns[agent] = episode.returns.get(agent, 0.0) + reward.total
        return Transition(
            agent,
            episode_id,
            pending.state,
            pending.action,
            reward,
            next_state,
            terminated,
            truncated,
        )

    def state_dict(self) -> dict[str, Any]:
        return {
            episode_id: {
                "improvement_times": dict(e.improvement_times),
                "last_time": e.last_time,
                "pending": {
                    a: (p.state, p.action, p.improvements, p.time) for a, p in e.pending.items()
                },
                "returns": dict(e.returns),
                "best_cost": e.best_cost,
            }
            for episode_id, e in self.episodes.items()
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.episodes = {
            episode_id: EpisodeProgress(
                improvement_times=dict(e["improvement_times"]),
                last_time=e["last_time"],
                pending={a: PendingStep(tuple(p[0]), *p[1:]) for a, p in e["pending"].items()},
                returns=dict(e["returns"]),
                best_cost=e.get("best_cost"),  # absent from checkpoints before 2026-12-07
            )
            for episode_id, e in state.items()
        }

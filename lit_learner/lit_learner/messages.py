"""Plain messages between a planner (or its ROS node, or ``lit train``) and the learner core."""

from __future__ import annotations

import math
from dataclasses import dataclass

from lit_learner.config import AGENT_NAMES
from lit_learner.errors import MessageError

Features = tuple[float, float, float]
"""Raw features (rho_global, rho_local, measure), each in [0, 1]."""


def episode_key(source: str, run_id: str, episode_id: str) -> str:
    """The learner core's episode id of a client's episode: ``source|run_id|episode_id``, each
    part's backslashes and bars escaped with a backslash. Joined as they were, ("pl|X", "r", "e")
    and ("pl", "X|r", "e") were one episode: two planners' steps paired into one transition."""

    def escaped(part: str) -> str:
        return part.replace("\\", "\\\\").replace("|", "\\|")

    return "|".join(escaped(part) for part in (source, run_id, episode_id))


@dataclass(frozen=True)
class DecisionRequest:
    """The planner asks agent ``agent`` for a value; also carries the reward information."""

    agent: str
    """``B`` or ``psi_K``."""
    episode_id: str
    """The planning query this belongs to; several planners may feed one learner."""
    rho_global: float
    """Raw feature in [0, 1]."""
    rho_local: float
    """Raw feature in [0, 1]: rho_local,B for B, rho_local,K for psi_K."""
    measure: float
    """Raw feature m in [0, 1]."""
    planning_time: float
    """Planner clock since the episode (query) started, s."""
    time_budget: float
    """The episode's time budget T_budget, s."""
    cost: float | None
    """Current best cost, None without a solution."""
    minimum_cost: float
    """Start-goal straight-line distance c_min."""
    improvements: int
    """Solution improvements so far (1 at the first solution)."""
    path_states: int
    """States on the current best path (0 without one)."""
    explore: bool = True
    """False: noise-free action (evaluation)."""
    after_fallback: bool = False
    """True: since this agent's previous request in the episode the planner executed fallback
    values, not the learner's answer (it came too late, or the learner was not asked): the
    agent's pending step is dropped instead of closed (its stored action was not executed)."""

    @property
    def features(self) -> Features:
        """(rho_global, rho_local, measure)."""
        return (self.rho_global, self.rho_local, self.measure)

    def validate(self) -> None:
        """Raises MessageError naming the bad field."""
        if self.agent not in AGENT_NAMES:
            raise MessageError(
                f"episode {self.episode_id!r}: unknown agent {self.agent!r}; "
                f"expected one of {AGENT_NAMES}",
                field="agent",
            )
        _validate_features(f"episode {self.episode_id!r}, agent {self.agent}", self.features, "")
        _validate_progress(
            self.episode_id,
            self.planning_time,
            self.time_budget,
            self.cost,
            self.minimum_cost,
            self.improvements,
            self.path_states,
        )


@dataclass(frozen=True)
class EpisodeEnd:
    """The planner closes an episode (time budget reached or query terminated)."""

    episode_id: str
    """The planning query that ends."""
    planning_time: float
    """Planner clock at the end, s."""
    time_budget: float
    """The episode's time budget, s."""
    cost: float | None
    """Final best cost, None without a solution."""
    minimum_cost: float
    """Start-goal straight-line distance c_min."""
    improvements: int
    """Solution improvements in the episode."""
    path_states: int
    """States on the final best path (0 without one)."""
    truncated: bool = True
    """True: time-budget end (the last steps bootstrap); False: termination (no bootstrap)."""
    final_features: dict[str, Features] | None = None
    """Optional raw features at the end per agent (``B``/``psi_K``), the s' of each agent's last
    step; an agent without an entry uses its last request's features (features move slowly)."""
    fallback_agents: tuple[str, ...] = ()
    """Agents whose last decisions were fallback values: their pending steps are dropped."""

    def validate(self) -> None:
        """Raises MessageError naming the bad field."""
        unknown = set(self.fallback_agents) - set(AGENT_NAMES)
        if unknown:
            raise MessageError(
                f"episode {self.episode_id!r}: unknown fallback agents {sorted(unknown)}; "
                f"expected some of {AGENT_NAMES}",
                field="fallback_agents",
            )
        # Each is an agent's last s' in the replay buffer: a NaN there reached the networks.
        for agent, features in (self.final_features or {}).items():
            where = f"episode {self.episode_id!r}, final_features"
            if agent not in AGENT_NAMES:
                raise MessageError(
                    f"{where}: unknown agent {agent!r}; expected {AGENT_NAMES}",
                    field="final_features",
                )
            try:
                values = tuple(float(value) for value in features)
            except (TypeError, ValueError):
                raise MessageError(
                    f"{where}[{agent}]: {features!r} is not 3 numbers",
                    field=f"final_features.{agent}",
                ) from None
            if len(values) != 3:
                raise MessageError(
                    f"{where}[{agent}]: {len(values)} values, not 3",
                    field=f"final_features.{agent}",
                )
            _validate_features(f"{where}[{agent}]", values, f"final_features.{agent}")  # type: ignore[arg-type]
        _validate_progress(
            self.episode_id,
            self.planning_time,
            self.time_budget,
            self.cost,
            self.minimum_cost,
            self.improvements,
            self.path_states,
        )


def _validate_features(where: str, features: Features, field: str) -> None:
    """``field``: where the three features are in the payload ("" for its top level)."""
    for index, (name, value) in enumerate(
        zip(("rho_global", "rho_local", "measure"), features, strict=True)
    ):
        if not (math.isfinite(value) and 0.0 <= value <= 1.0):  # as DecideRequest's schema
            raise MessageError(
                f"{where}: {name} = {value} is not a number in [0, 1]",
                field=f"{field}[{index}]" if field else name,
            )


COST_TOLERANCE = 1e-9
"""Relative rounding a solution cost may fall below ``minimum_cost`` by (the planners compute the
two through different code)."""
MIN_TIME_BUDGET = 1e-6
"""Seconds: the shortest episode budget taken (the schemas' DecideRequest / EpisodeEnd minimum);
a budget below a microsecond is no query, and the search cost's floor underflowed for it."""


def _validate_progress(
    episode_id: str,
    planning_time: float,
    time_budget: float,
    cost: float | None,
    minimum_cost: float,
    improvements: int,
    path_states: int,
) -> None:
    where = f"episode {episode_id!r}"
    if not (math.isfinite(planning_time) and planning_time >= 0.0):
        raise MessageError(
            f"{where}: planning_time {planning_time} must be finite and >= 0", field="planning_time"
        )
    if not (math.isfinite(time_budget) and time_budget >= MIN_TIME_BUDGET):
        # 5e-324 passed "> 0", and the search cost's floor (search_floor * T) underflowed to 0:
        # a ZeroDivisionError lost the transition (1e-300 gave a reward of about -700).
        raise MessageError(
            f"{where}: time_budget {time_budget} must be finite and at least {MIN_TIME_BUDGET:g} s",
            field="time_budget",
        )
    if cost is not None and not cost > 0.0:
        raise MessageError(f"{where}: cost {cost} must be > 0 or None", field="cost")
    if not (math.isfinite(minimum_cost) and minimum_cost >= 0.0):
        raise MessageError(
            f"{where}: minimum_cost {minimum_cost} must be finite and >= 0", field="minimum_cost"
        )
    if cost is not None and cost < minimum_cost * (1.0 - COST_TOLERANCE):
        # No path is shorter than the straight line: such a cost made c_min / c as large as 1e300,
        # and its reward failed every gradient step that sampled it.
        raise MessageError(
            f"{where}: cost {cost} is below minimum_cost {minimum_cost}, the straight line's "
            "length: no path is that short",
            field="cost",
        )
    if improvements < 0 or path_states < 0:
        raise MessageError(
            f"{where}: improvements {improvements} and path_states {path_states} must be >= 0",
            field="improvements" if improvements < 0 else "path_states",
        )

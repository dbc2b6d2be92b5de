"""Rewards R_B and R_K from raw planner information (LEARNER.md "Rewards").

t_hat = max(t / T_budget, 0.01) with t the planner time since the previous solution improvement
(or since the start); c_ratio = c_min / c (0 without a solution);
kappa(n) = nu_min if 6.8 - n <= 0 else max(nu_min, nu * log2(6.8 - n)).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from lit_learner.config import RewardConfig


@dataclass(frozen=True)
class RewardTerms:
    """One step's reward, term by term; ``total`` is their sum."""

    time: float
    """Speed term: w_t * kappa(n) / t_hat (B) or w_t / t_hat (K), 0 without an improvement."""
    cost: float
    """Cost term: w_c * kappa(n) * c_ratio (B) or w_c * c_ratio (K); 0 without an improvement."""
    penalty: float
    """Penalty (<= 0): -w_u * n (B) or -w_s * path_states / 50 (K, only with an improvement)."""
    search: float = 0.0
    """Search cost (<= 0, K only): minus :func:`search_cost` of the step's planner time before
    the first solution (the project's addition to R_K, logged as a term of its own)."""

    @property
    def total(self) -> float:
        """time + cost + penalty + search."""
        return self.time + self.cost + self.penalty + self.search


def kappa(n: int, config: RewardConfig) -> float:
    """Improvement weight kappa(n): large for early improvements, floored at nu_min."""
    headroom = config.kappa_offset - n
    if headroom <= 0.0:
        return config.nu_min
    return max(config.nu_min, config.nu * math.log2(headroom))


def t_hat(step_time: float, time_budget: float, config: RewardConfig) -> float:
    """Normalised time since the previous improvement, floored at ``t_hat_min``."""
    return max(step_time / time_budget, config.t_hat_min)


def cost_ratio(cost: float | None, minimum_cost: float) -> float:
    """c_min / c in [0, 1]; 0 without a (finite) solution. A cost below c_min (rounding; the
    messages refuse more) counts as c_min."""
    if cost is None or not math.isfinite(cost) or cost <= 0.0:
        return 0.0
    return min(1.0, minimum_cost / cost)


def batch_size_reward(
    improved: bool,
    improvements: int,
    step_time: float,
    time_budget: float,
    cost: float | None,
    minimum_cost: float,
    config: RewardConfig,
) -> RewardTerms:
    """R_B of a B step; ``improvements`` = n at the step's end."""
    penalty = -config.w_u * improvements
    if not improved:
        return RewardTerms(0.0, 0.0, penalty)
    k = kappa(improvements, config)
    return RewardTerms(
        time=config.w_t * k / t_hat(step_time, time_budget, config),
        cost=config.w_c * k * cost_ratio(cost, minimum_cost),
        penalty=penalty,
    )


def search_cost(start: float, end: float, time_budget: float, config: RewardConfig) -> float:
    """What a K step pays for planner time spent before the first solution, from ``start`` to
    ``end``: w_search * ln(max(end, f) / max(start, f)) with the floor f = search_floor * T. The
    costs of consecutive steps add up to w_search * ln(t_init / f) (times below f are free), so
    the same relative speed-up of the first solution is worth the same in every scenario:
    a first solution in 4 ms of a 0.4 s budget and one in 40 ms of 0.3 s both matter."""
    floor = config.search_floor * time_budget
    return config.w_search * math.log(max(end, floor) / max(start, floor))


def neighbour_reward(
    improved: bool,
    step_time: float,
    time_budget: float,
    cost: float | None,
    minimum_cost: float,
    path_states: int,
    config: RewardConfig,
    search: tuple[float, float] | None = None,
) -> RewardTerms:
    """R_K of a K step: an improvement earns the paper's terms; a step taken before the first
    solution also pays :func:`search_cost` for its planner time ``search`` = (start, end)."""
    paid = -search_cost(search[0], search[1], time_budget, config) if search else 0.0
    if not improved:
        return RewardTerms(0.0, 0.0, 0.0, search=paid)
    return RewardTerms(
        time=config.w_t / t_hat(step_time, time_budget, config),
        cost=config.w_c * cost_ratio(cost, minimum_cost),
        penalty=-config.w_s * path_states / config.path_states_scale,
        search=paid,
    )

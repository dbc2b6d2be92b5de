"""Rewards: kappa table, t_hat floor, cost ratio, R_B and R_K term by term."""

from __future__ import annotations

import itertools
import math

import pytest
from lit_learner.config import RewardConfig
from lit_learner.rewards import (
    batch_size_reward,
    cost_ratio,
    kappa,
    neighbour_reward,
    search_cost,
    t_hat,
)

CONFIG = RewardConfig()


def test_kappa_table_has_no_nan_and_is_floored() -> None:
    table = {n: kappa(n, CONFIG) for n in range(1, 11)}
    assert all(math.isfinite(v) for v in table.values())
    assert table[1] == pytest.approx(math.log2(5.8))
    assert table[5] == pytest.approx(math.log2(1.8))
    assert table[6] == 0.1  # log2(0.8) < 0: the floor
    assert all(table[n] == 0.1 for n in range(7, 11))  # 6.8 - n <= 0
    assert all(table[n] >= table[n + 1] for n in range(1, 10))


def test_t_hat_and_cost_ratio() -> None:
    assert t_hat(2.0, 10.0, CONFIG) == 0.2
    assert t_hat(0.0, 10.0, CONFIG) == 0.01
    assert cost_ratio(None, 3.0) == 0.0
    assert cost_ratio(math.inf, 3.0) == 0.0
    assert cost_ratio(4.0, 3.0) == 0.75
    assert cost_ratio(3.0 - 1e-12, 3.0) == 1.0  # rounding below c_min: at most 1


def test_batch_size_reward_with_and_without_improvement() -> None:
    r = batch_size_reward(True, 2, 1.0, 10.0, 4.0, 3.0, CONFIG)
    k = math.log2(4.8)
    assert r.time == pytest.approx(0.01 * k / 0.1)
    assert r.cost == pytest.approx(1.0 * k * 0.75)
    assert r.penalty == pytest.approx(-0.1)
    assert r.total == pytest.approx(r.time + r.cost + r.penalty)
    none = batch_size_reward(False, 3, 1.0, 10.0, 4.0, 3.0, CONFIG)
    assert (none.time, none.cost, none.penalty) == (0.0, 0.0, pytest.approx(-0.15))


def test_neighbour_reward_with_and_without_improvement() -> None:
    r = neighbour_reward(True, 0.5, 10.0, 4.0, 3.0, 100, CONFIG)
    assert r.time == pytest.approx(0.01 / 0.05)
    assert r.cost == pytest.approx(0.75)
    assert r.penalty == pytest.approx(-0.1 * 2.0)  # fewer path states is better
    assert neighbour_reward(False, 0.5, 10.0, 4.0, 3.0, 100, CONFIG).total == 0.0


def test_neighbour_reward_charges_search_time_before_the_first_solution() -> None:
    # From 4 ms to 8 ms of a 0.4 s budget: w_search * ln 2, whether or not the step improved.
    quiet = neighbour_reward(False, 0.0, 0.4, None, 3.0, 0, CONFIG, search=(0.004, 0.008))
    assert quiet.search == pytest.approx(-CONFIG.w_search * math.log(2.0))
    assert quiet.time == 0.0 and quiet.total == pytest.approx(quiet.search)
    found = neighbour_reward(True, 0.1, 0.4, 4.0, 3.0, 50, CONFIG, search=(0.004, 0.008))
    assert found.time == pytest.approx(0.01 / 0.25)  # each term logged on its own
    assert found.search == pytest.approx(-CONFIG.w_search * math.log(2.0))
    assert found.cost == pytest.approx(0.75)
    assert found.total == pytest.approx(found.time + found.cost + found.penalty + found.search)
    assert neighbour_reward(False, 0.0, 0.4, None, 3.0, 0, CONFIG).total == 0.0


def test_search_costs_add_up_to_the_log_of_the_first_solution_time() -> None:
    floor = CONFIG.search_floor * 0.3
    times = [0.0, floor / 2, 0.002, 0.005, 0.0301]
    total = sum(search_cost(a, b, 0.3, CONFIG) for a, b in itertools.pairwise(times))
    assert total == pytest.approx(CONFIG.w_search * math.log(0.0301 / floor))
    # Twice as fast is worth the same at any scale.
    assert search_cost(0.0, 0.008, 0.4, CONFIG) - search_cost(0.0, 0.004, 0.4, CONFIG) == (
        pytest.approx(search_cost(0.0, 0.2, 0.3, CONFIG) - search_cost(0.0, 0.1, 0.3, CONFIG))
    )

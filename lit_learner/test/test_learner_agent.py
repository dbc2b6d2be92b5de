"""DDPG agent: executed actions, warm-up, and a one-step bandit it must solve."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from lit_learner.agent import DDPGAgent, round_half_away_from_zero
from lit_learner.config import AgentConfig

# What LearnerCore does: one thread is fastest for these batches and keeps the numbers fixed.
torch.set_num_threads(1)


def test_round_half_away_from_zero() -> None:
    assert [round_half_away_from_zero(v) for v in (2.5, 3.5, -2.5, 2.49, 0.0)] == [
        3.0,
        4.0,
        -3.0,
        2.0,
        0.0,
    ]


def test_executed_values_are_rounded_and_clamped() -> None:
    b = DDPGAgent(AgentConfig.batch_size_agent(), seed=0)
    assert b.executed(0.0) == 20.0 and b.executed(1.0) == 200.0
    assert b.executed(0.5 / 180) == 21.0  # 20.5 -> 21
    assert b.executed(1.2) == 200.0 and b.executed(-0.1) == 20.0
    k = DDPGAgent(AgentConfig.neighbour_agent(), seed=0)
    assert k.executed(0.5) == 9.0 and k.executed(1.5) == 15.0


def test_warm_up_actions_are_uniform_then_near_the_policy() -> None:
    agent = DDPGAgent(AgentConfig.neighbour_agent(warmup=300, batch_size=32), seed=0)
    warm = [agent.act((0.5, 0.5, 0.5), explore=True)[1] for _ in range(2000)]
    assert min(warm) < 0.05 and max(warm) > 0.95
    for _ in range(300):
        agent.remember((0.5, 0.5, 0.5), 0.5, 0.0, (0.5, 0.5, 0.5), True)
    assert not agent.warming_up
    noisy = np.array([agent.act((0.5, 0.5, 0.5), explore=True)[1] for _ in range(2000)])
    greedy = agent.normalise(agent.policy((0.5, 0.5, 0.5)))
    assert abs(noisy.mean() - greedy) < 0.01 and noisy.std() == pytest.approx(0.05, rel=0.1)
    value, a_norm = agent.act((0.5, 0.5, 0.5), explore=False)
    assert a_norm == greedy and value == agent.executed(greedy)


@pytest.mark.parametrize("seed", [3, 7])
def test_ddpg_solves_a_one_step_bandit(seed: int) -> None:
    """Reward peaks at a_norm = 0.8 for every state; terminated one-step episodes.

    The actor learns ten times slower than the critic so it does not run into the softmax's
    saturated corners on an early, rough critic (from there its gradient is tiny). Seeds 3 and 7
    ended in the a_norm = 1 corner before the actor's logit penalty (``logit_penalty``) existed.
    """
    target = 0.8
    config = AgentConfig.neighbour_agent(
        batch_size=32,
        buffer_size=5000,
        warmup=500,
        lr_actor=1e-4,
        lr_critic=1e-3,
        noise_std=0.1,
        beta_steps=1000,
    )
    agent = DDPGAgent(config, seed=seed)
    rng = np.random.default_rng(seed)
    start = agent.normalise(agent.policy((0.5, 0.5, 0.5)))
    assert abs(start - 0.5) < 0.01  # mid-range at the start
    for _ in range(1500):
        features = tuple(float(v) for v in rng.uniform(0.0, 1.0, 3))
        _, a_norm = agent.act(features, explore=True)
        reward = 1.0 - 4.0 * (a_norm - target) ** 2
        agent.remember(features, a_norm, reward, features, terminated=True)
        if not agent.warming_up:
            metrics = agent.update()
    assert agent.updates == 1001
    assert set(metrics) == {"critic", "actor", "mean_q", "td_abs", "beta"}
    for features in [(0.0, 0.0, 0.0), (0.5, 0.2, 0.9), (1.0, 1.0, 1.0), (0.3, 0.7, 0.1)]:
        assert agent.normalise(agent.policy(features)) == pytest.approx(target, abs=0.08)

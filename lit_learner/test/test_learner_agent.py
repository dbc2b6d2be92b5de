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
    assert a_norm == greedy and value == agent.value_of(agent.policy((0.5, 0.5, 0.5)))


def test_a_half_is_rounded_away_from_zero_whatever_its_way_through_a_norm() -> None:
    """B's z* = 112.5 taken through a_norm and back was 112.4999... and gave 112, not 113."""
    b = DDPGAgent(AgentConfig.batch_size_agent(), seed=0)
    for half in (112.5, 123.5, 20.5, 199.5):
        assert b.value_of(half) == half + 0.5
    assert b.executed(b.normalise(112.5)) == 112.0  # the round trip this no longer takes
    b.policy = lambda features, snapshot=None: 112.5  # type: ignore[method-assign]
    assert b.act((0.5, 0.5, 0.5), explore=False) == (113.0, b.normalise(113.0))


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


def test_one_update_step_is_the_specified_one() -> None:
    """One gradient step recomputed by hand from a copy of the agent: the TD target
    r + gamma (1 - terminated) Q'(s', mu'(s')) on the *target* networks, the critic loss weighted
    by the importance weights, the priorities written back as (|y - Q| + eps)^alpha, the actor
    loss on the updated critic, and the Polyak step of both targets. The targets and priorities
    are made to differ from the online networks and from each other first, so that the online
    networks in the target, a missing mask or missing weights each change the numbers."""
    import copy

    from lit_learner.replay import beta_at

    torch.manual_seed(0)
    config = AgentConfig.neighbour_agent(batch_size=16, buffer_size=64, warmup=16, gamma=0.9)
    agent = DDPGAgent(config, seed=0)
    rng = np.random.default_rng(1)
    for i in range(40):
        state, next_state = tuple(rng.uniform(0, 1, 3)), tuple(rng.uniform(0, 1, 3))
        agent.remember(state, float(rng.uniform()), float(rng.normal()), next_state, i % 3 == 0)
    with torch.no_grad():
        for target in (agent.actor_target, agent.critic_target):
            for parameter in target.parameters():
                parameter.add_(0.05 * torch.randn_like(parameter))
    stored = np.arange(len(agent.replay))
    agent.replay.update_priorities(stored, rng.uniform(0.0, 2.0, stored.size))
    before = copy.deepcopy(agent)

    result = agent.update()

    batch = before.replay.sample(config.batch_size, before.beta, before.rng)
    assert 0 < batch.terminated.sum() < len(batch.terminated)  # both kinds in the batch
    assert batch.weight.min() < 0.99  # the weights matter
    state = before.state(torch.from_numpy(batch.state))
    next_state = before.state(torch.from_numpy(batch.next_state))
    with torch.no_grad():
        next_q = before.critic_target(next_state, before.actor_target.normalised(next_state))
        y = (
            torch.from_numpy(batch.reward)
            + 0.9 * (1.0 - torch.from_numpy(batch.terminated)) * next_q
        )
        q = before.critic(state, torch.from_numpy(batch.action))
        loss = (torch.from_numpy(batch.weight) * (q - y) ** 2).mean()
    assert result["critic"] == pytest.approx(float(loss), rel=1e-5)
    assert result["beta"] == before.beta

    expected = (np.abs((y - q).double().numpy()) + config.priority_eps) ** config.alpha
    last = {int(i): k for k, i in enumerate(batch.index)}  # a repeated index keeps its last value
    index = np.array(sorted(last))
    assert np.allclose(agent.replay.tree.get(index), expected[[last[i] for i in index]], rtol=1e-6)

    with torch.no_grad():  # the actor's loss on the critic after its step, at the old actor
        logits = before.actor.logits(state)
        actor_q = agent.critic(state, before.actor.normalised_from_logits(logits))
        actor_loss = -actor_q.mean() + config.logit_penalty * (logits * logits).mean()
    assert result["actor"] == pytest.approx(float(actor_loss), rel=1e-4)

    for target, old, online in (
        (agent.critic_target, before.critic_target, agent.critic),
        (agent.actor_target, before.actor_target, agent.actor),
    ):
        for new, previous, source in zip(
            target.parameters(), old.parameters(), online.parameters(), strict=True
        ):
            expected_target = (1 - config.tau) * previous + config.tau * source
            assert torch.allclose(new, expected_target, atol=1e-7)
    assert agent.updates == 1
    for _ in range(4):
        agent.update()
    assert agent.beta == beta_at(5, config.beta_start, config.beta_end, config.beta_steps)
    assert agent.beta > before.beta


def test_an_update_with_a_loss_that_is_not_finite_changes_nothing() -> None:
    from lit_learner.errors import LearnerError

    torch.manual_seed(0)
    config = AgentConfig.neighbour_agent(batch_size=8, buffer_size=32, warmup=8)
    agent = DDPGAgent(config, seed=0)
    rng = np.random.default_rng(2)
    for _ in range(16):
        state, next_state = tuple(rng.uniform(0, 1, 3)), tuple(rng.uniform(0, 1, 3))
        agent.remember(state, float(rng.uniform()), float(rng.normal()), next_state, False)
    with torch.no_grad():
        next(agent.critic_target.parameters()).fill_(float("nan"))  # a poisoned target
    before = [p.detach().clone() for p in (*agent.actor.parameters(), *agent.critic.parameters())]
    priorities = agent.replay.tree.total
    with pytest.raises(LearnerError, match="critic loss is nan"):
        agent.update()
    after = [*agent.actor.parameters(), *agent.critic.parameters()]
    assert all(torch.equal(a, b) for a, b in zip(before, after, strict=True))
    assert agent.replay.tree.total == priorities and agent.updates == 0

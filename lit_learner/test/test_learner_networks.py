"""Actor and critic shapes, TSK range and gradient, initial mid-range output, Polyak updates."""

from __future__ import annotations

import pytest
import torch
from lit_learner.fuzzy import fuzzify
from lit_learner.networks import Actor, Critic, Trunk, polyak_update

B_CONSEQUENTS = (20.0, 110.0, 200.0)


def states(n: int, seed: int = 0) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    return fuzzify(torch.rand(n, 3, generator=g))


def test_trunk_gives_81_features() -> None:
    assert Trunk()(states(5)).shape == (5, 81)


def test_critic_maps_state_and_action_to_one_value() -> None:
    critic = Critic()
    assert critic.head[0].in_features == 82
    assert critic(states(7), torch.rand(7)).shape == (7,)


def test_actor_starts_mid_range() -> None:
    torch.manual_seed(0)
    z = Actor(B_CONSEQUENTS)(states(100))
    assert torch.allclose(z, torch.full_like(z, 110.0), atol=1.0)


def test_tsk_output_stays_inside_the_consequents_with_nonzero_gradient() -> None:
    torch.manual_seed(1)
    actor = Actor(B_CONSEQUENTS)
    last = actor.head[-1]
    with torch.no_grad():  # large random logits: near one-hot firing strengths
        last.weight.normal_(0.0, 100.0)
        last.bias.normal_(0.0, 100.0)
    s = states(500, seed=2)
    with torch.no_grad():
        z = actor(s)
        assert float(z.min()) >= 20.0 and float(z.max()) <= 200.0
        assert torch.allclose(actor.normalised(s), (z - 20.0) / 180.0, atol=1e-5)
        for rule, extreme in ((0, 20.0), (2, 200.0)):  # one rule fires alone: its consequent
            last.weight.zero_()
            last.bias.zero_()
            last.bias[rule] = 60.0
            z = actor(s)
            assert float(z.min()) >= 20.0 and float(z.max()) <= 200.0
            assert torch.allclose(z, torch.full_like(z, extreme), atol=1e-3)

    torch.manual_seed(1)
    fresh = Actor(B_CONSEQUENTS)
    fresh(states(64)).sum().backward()
    grads = [p.grad for p in fresh.parameters()]
    assert all(g is not None for g in grads)
    assert all(float(g.abs().sum()) > 0.0 for g in grads if g is not None)


@pytest.mark.parametrize("tau", [1.0, 0.25])
def test_polyak_update(tau: float) -> None:
    torch.manual_seed(3)
    source, target = Critic(), Critic()
    before = [p.detach().clone() for p in target.parameters()]
    polyak_update(target, source, tau)
    for t, s, b in zip(target.parameters(), source.parameters(), before, strict=True):
        if tau == 1.0:
            assert torch.equal(t, s)
        else:
            assert torch.allclose(t, tau * s + (1 - tau) * b)

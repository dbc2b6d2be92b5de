"""Actor and critic shapes, TSK range and gradient, initial mid-range output, Polyak updates."""

from __future__ import annotations

import numpy as np
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


@pytest.mark.parametrize("kernels", [(3, 5, 7), (1, 3)])
def test_snapshot_computes_what_the_actor_computes(kernels: tuple[int, ...]) -> None:
    from lit_learner.networks import ActorSnapshot

    torch.manual_seed(3)
    actor = Actor(B_CONSEQUENTS, kernels=kernels, last_init=1.0)  # far from uniform firing
    for layer in actor.head:  # larger weights, so a wrong index or order would show
        if isinstance(layer, torch.nn.Linear):
            torch.nn.init.normal_(layer.weight, std=0.2)
    snapshot = ActorSnapshot(actor, (0.0, 0.5, 1.0), 0.2123)
    raw = torch.cat([torch.rand(200, 3, generator=torch.Generator().manual_seed(1)),
                     torch.tensor([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [0.0, 1.0, 0.5]])])  # fmt: skip
    with torch.no_grad():
        expected = actor(fuzzify(raw))
    got = torch.tensor([snapshot(tuple(row.tolist())) for row in raw], dtype=torch.float64)
    assert torch.allclose(got, expected.double(), rtol=0, atol=1e-4)
    assert got.std() > 0.1  # the outputs really vary over the states
    # The compiled pass (the C++ core is built here) is the numpy reference (double) to the
    # rounding of its single-precision affine maps (torch's precision).
    assert snapshot.compiled is not None
    reference = [snapshot.numpy_call(tuple(row.tolist())) for row in raw]
    assert got.tolist() == pytest.approx(reference, rel=1e-6, abs=0)


def test_compiled_actor_rejects_shapes_that_do_not_chain() -> None:
    import lit_core

    trunk = (np.zeros((4, 9)), np.zeros(4))
    last = (np.zeros((3, 4)), np.zeros(3))
    actor = lit_core.TskActor((0.0, 0.5, 1.0), 0.2, trunk, [last], np.array([1.0, 2.0, 3.0]))
    assert actor(0.1, 0.2, 0.3) == pytest.approx(2.0)  # equal logits: the consequents' mean
    with pytest.raises(ValueError, match="layer 0: weight has 5 columns, expected 4 inputs"):
        lit_core.TskActor((0, 0.5, 1), 0.2, trunk, [(np.zeros((3, 5)), np.zeros(3))], np.ones(3))
    with pytest.raises(ValueError, match="trunk: bias has 3 entries, expected 4"):
        lit_core.TskActor((0, 0.5, 1), 0.2, (np.zeros((4, 9)), np.zeros(3)), [last], np.ones(3))
    with pytest.raises(ValueError, match="consequents: 2 entries"):
        lit_core.TskActor((0, 0.5, 1), 0.2, trunk, [last], np.ones(2))
    with pytest.raises(ValueError, match="sigma must be finite and positive"):
        lit_core.TskActor((0, 0.5, 1), 0.0, trunk, [last], np.ones(3))


def test_agent_policy_follows_every_weight_change() -> None:
    from lit_learner.agent import DDPGAgent
    from lit_learner.config import LearnerConfig

    agent = DDPGAgent(LearnerConfig().b, seed=0)
    features = (0.2, 0.7, 0.4)

    def torch_policy() -> float:
        with torch.no_grad():
            return float(agent.actor(agent.state(torch.tensor([features])))[0])

    before = agent.policy(features)
    assert before == pytest.approx(torch_policy(), abs=1e-4)
    with torch.no_grad():
        agent.actor.head[-1].bias.add_(torch.tensor([2.0, 0.0, -2.0]))  # in place, like Adam
    after = agent.policy(features)
    assert after != pytest.approx(before, abs=1.0)
    assert after == pytest.approx(torch_policy(), abs=1e-4)
    agent.actor.load_state_dict(DDPGAgent(LearnerConfig().b, seed=0).actor.state_dict())
    assert agent.policy(features) == pytest.approx(before, abs=1e-6)

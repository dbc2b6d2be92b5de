"""One DDPG agent with prioritized replay (LEARNER.md "Action" and "Update").

The action outside the actor is the crisp scalar a_norm in [0, 1]: (B - 20) / 180 or
(psi - 3) / 12; the executed value (B rounded half away from zero, both clamped) is what gets
stored. Exploration: a_norm + N(0, noise_std), clipped; uniform actions until warm-up is reached.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Iterable
from contextlib import AbstractContextManager, nullcontext
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F

from lit_learner.config import AgentConfig
from lit_learner.errors import LearnerError, NonFiniteWeights
from lit_learner.fuzzy import fuzzify
from lit_learner.messages import Features
from lit_learner.networks import Actor, ActorSnapshot, Critic, polyak_update
from lit_learner.replay import PrioritizedReplay, beta_at


def round_half_away_from_zero(value: float) -> float:
    """2.5 -> 3, -2.5 -> -3 (Python's round() would give 2)."""
    return math.copysign(math.floor(abs(value) + 0.5), value)


class DDPGAgent:
    """Actor, critic, their targets and optimisers, a replay buffer and a random generator."""

    def __init__(self, config: AgentConfig, seed: int) -> None:
        self.config = config
        self.rng = np.random.default_rng(seed)
        """Exploration noise, warm-up actions and replay sampling."""
        with torch.random.fork_rng(devices=[]):  # seeded init without touching the global RNG
            torch.manual_seed(seed)
            self.actor = Actor(
                config.consequents,
                config.conv_kernels,
                config.conv_channels,
                config.hidden,
                config.actor_last_init,
            )
            self.critic = Critic(config.conv_kernels, config.conv_channels, config.hidden)
        self.actor_target = copy.deepcopy(self.actor)
        self.critic_target = copy.deepcopy(self.critic)
        for net in (self.actor_target, self.critic_target):
            net.requires_grad_(False)
        self.actor_optimizer = torch.optim.Adam(
            self.actor.parameters(), lr=config.lr_actor, foreach=True
        )
        self.critic_optimizer = torch.optim.Adam(
            self.critic.parameters(), lr=config.lr_critic, foreach=True
        )
        self.replay = PrioritizedReplay(config.buffer_size, config.alpha, config.priority_eps)
        self.updates = 0
        """Gradient steps taken."""
        self.transitions = 0
        """Transitions ever stored."""
        self._snapshot: ActorSnapshot | None = None
        self._snapshot_key: tuple[int, ...] = ()
        self._snapshot_params: tuple[Actor, tuple[torch.Tensor, ...]] | None = None

    # ------------------------------------------------------------------ actions

    def state(self, features: torch.Tensor) -> torch.Tensor:
        """Fuzzy 9-vectors of raw (..., 3) features."""
        return fuzzify(features, self.config.fuzzy_centres, self.config.fuzzy_sigma)

    def policy(self, features: Features, snapshot: ActorSnapshot | None = None) -> float:
        """Noise-free z*(features) in action units, before rounding.

        Evaluated by an :class:`ActorSnapshot` of the current actor weights (rebuilt whenever a
        parameter has changed: an optimiser step, a loaded checkpoint), not by torch: a single
        decision is on the planner's critical path. ``snapshot``: evaluate that one instead (a
        thread that decides while another one trains must not look at the parameters, which are
        half-updated during a step; see :meth:`LearnerCore.choose`).
        """
        return (snapshot if snapshot is not None else self.snapshot())(features)

    def snapshot(self) -> ActorSnapshot:
        """The snapshot of the actor as it is now (cached until its parameters change)."""
        # Every in-place change of a tensor (optimiser steps, load_state_dict) bumps its _version.
        if self._snapshot_params is None or self._snapshot_params[0] is not self.actor:
            self._snapshot_params = (self.actor, tuple(self.actor.parameters()))
        key = tuple([p._version for p in self._snapshot_params[1]])
        if self._snapshot is None or self._snapshot_key != key:
            self._snapshot = ActorSnapshot(
                self.actor, self.config.fuzzy_centres, self.config.fuzzy_sigma
            )
            self._snapshot_key = key
        return self._snapshot

    @property
    def warming_up(self) -> bool:
        """True until ``warmup`` transitions are stored: actions are uniform then."""
        return self.transitions < self.config.warmup

    def normalise(self, value: float) -> float:
        """a_norm of an action value."""
        lo, hi = self.config.action_min, self.config.action_max
        return (value - lo) / (hi - lo)

    def executed(self, a_norm: float) -> float:
        """The value the planner executes for a_norm: :meth:`value_of` its action value."""
        lo, hi = self.config.action_min, self.config.action_max
        return self.value_of(lo + a_norm * (hi - lo))

    def value_of(self, value: float) -> float:
        """The value the planner executes for an action value (z*): rounded (B) and clamped to
        the range. (A z* taken through a_norm and back first could land an ulp below a .5: B =
        112.5 became 112.4999... and was rounded down.)"""
        lo, hi = self.config.action_min, self.config.action_max
        if self.config.rounding == "half_away_from_zero":
            value = round_half_away_from_zero(value)
        return min(max(value, lo), hi)

    def act(
        self, features: Features, explore: bool, snapshot: ActorSnapshot | None = None
    ) -> tuple[float, float]:
        """(executed value, its a_norm) for one decision; ``snapshot`` as for :meth:`policy`."""
        if explore and self.warming_up:
            value = self.executed(float(self.rng.uniform(0.0, 1.0)))
        else:
            value = self.policy(features, snapshot)
            if explore:
                a_norm = self.normalise(value) + float(self.rng.normal(0.0, self.config.noise_std))
                value = self.executed(min(max(a_norm, 0.0), 1.0))
            else:
                value = self.value_of(value)
        return value, self.normalise(value)

    # ------------------------------------------------------------------ learning

    def remember(
        self,
        state: Features,
        action: float,
        reward: float,
        next_state: Features,
        terminated: bool,
    ) -> None:
        """Store one transition (a truncated one bootstraps, so only ``terminated`` matters)."""
        self.replay.add(state, action, reward, next_state, terminated)
        self.transitions += 1

    @property
    def beta(self) -> float:
        """Importance-weight exponent of the next gradient step."""
        c = self.config
        return beta_at(self.updates, c.beta_start, c.beta_end, c.beta_steps)

    def update(self, replay_lock: AbstractContextManager[Any] | None = None) -> dict[str, float]:
        """One gradient step on the critic and the actor, then Polyak updates of both targets.

        ``replay_lock`` is held while the replay buffer is sampled and its priorities updated
        (another thread may add transitions meanwhile)."""
        c = self.config
        beta = self.beta
        guard = replay_lock if replay_lock is not None else nullcontext()
        with guard:
            batch = self.replay.sample(c.batch_size, beta, self.rng)
        state = self.state(torch.from_numpy(batch.state))
        next_state = self.state(torch.from_numpy(batch.next_state))
        action = torch.from_numpy(batch.action)
        reward = torch.from_numpy(batch.reward)
        terminated = torch.from_numpy(batch.terminated)
        weight = torch.from_numpy(batch.weight)

        with torch.no_grad():
            next_q = self.critic_target(next_state, self.actor_target.normalised(next_state))
            target = reward + c.gamma * (1.0 - terminated) * next_q
        q = self.critic(state, action)
        critic_loss = (weight * (q - target) ** 2).mean()
        if not torch.isfinite(critic_loss):  # no step: one would spread it into every weight
            raise LearnerError(
                f"the critic loss is {critic_loss.item()} (a network or the replay buffer "
                "holds a value that is not finite); no update made"
            )
        self.critic_optimizer.zero_grad()
        critic_loss.backward()
        self.critic_optimizer.step()
        td = (target - q).detach().double().numpy()
        with guard:
            self.replay.update_priorities(batch.index, td, sampled_at=batch.adds)

        logits = self.actor.logits(state)
        actor_loss = -self.critic(state, self.actor.normalised_from_logits(logits)).mean()
        if c.logit_penalty:
            # Keeps the softmax out of its saturated corners, where dz*/dlogits vanishes and an
            # actor pushed there by an early, rough critic could never come back.
            actor_loss = actor_loss + c.logit_penalty * (logits * logits).mean()
        self.actor_optimizer.zero_grad()
        actor_loss.backward()
        self.actor_optimizer.step()

        polyak_update(self.critic_target, self.critic, c.tau)
        polyak_update(self.actor_target, self.actor, c.tau)
        self.updates += 1
        return {
            "critic": critic_loss.item(),
            "actor": actor_loss.item(),
            "mean_q": float(q.detach().mean()),
            "td_abs": float(F.l1_loss(q.detach(), target)),
            "beta": beta,
        }

    # ------------------------------------------------------------------ checkpoints

    def state_dict(self) -> dict[str, Any]:
        return {
            "actor": self.actor.state_dict(),
            "critic": self.critic.state_dict(),
            "actor_target": self.actor_target.state_dict(),
            "critic_target": self.critic_target.state_dict(),
            "actor_optimizer": self.actor_optimizer.state_dict(),
            "critic_optimizer": self.critic_optimizer.state_dict(),
            "replay": self.replay.state_dict(),
            "rng": self.rng.bit_generator.state,
            "updates": self.updates,
            "transitions": self.transitions,
        }

    def load_state_dict(self, state: dict[str, Any]) -> int:
        """The state :meth:`state_dict` saved; how many replay transitions were left out (see
        :meth:`PrioritizedReplay.load_state_dict`).

        Raises:
            NonFiniteWeights: a network holds a weight, or an optimiser a moment, that is not
                finite (it would answer NaN, or make the weights NaN at its first step).
        """
        networks = ("actor", "critic", "actor_target", "critic_target")
        for name in networks:
            getattr(self, name).load_state_dict(state[name])
            _refuse_non_finite(name, "weights", getattr(self, name).state_dict().items())
        for name in ("actor_optimizer", "critic_optimizer"):
            optimizer = getattr(self, name)
            optimizer.load_state_dict(state[name])
            slots = optimizer.state_dict()["state"].items()  # its first step would make NaN
            _refuse_non_finite(
                name, "moments", ((f"{i}.{k}", v) for i, d in slots for k, v in d.items())
            )
        dropped = self.replay.load_state_dict(state["replay"])
        self.rng.bit_generator.state = state["rng"]
        self.updates = state["updates"]
        self.transitions = state["transitions"]
        return dropped


def _refuse_non_finite(owner: str, what: str, tensors: Iterable[tuple[str, Any]]) -> None:
    """Raise :class:`NonFiniteWeights` naming the tensors of ``owner`` that are not finite."""
    bad = [
        name
        for name, value in tensors
        if isinstance(value, torch.Tensor) and not torch.isfinite(value).all()
    ]
    if bad:
        raise NonFiniteWeights(f"the {owner} holds {what} that are not finite: {', '.join(bad)}")

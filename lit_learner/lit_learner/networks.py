"""Actor and critic of one agent (LEARNER.md "Networks").

Trunk: fuzzy 9-vector as 1 channel x 9 -> parallel Conv1d(1 -> 3), kernels 3/5/7, same padding ->
9 channels x 9 -> ReLU -> flatten (81). Actor: trunk -> MLP 64-128-128-64-32 -> 3 logits ->
softmax = rule firing strengths w -> z* = sum w_i f_i (zero-order TSK). Critic: [trunk(s), a_norm]
-> the same MLP -> Q.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import torch
from torch import nn

from lit_learner.fuzzy import STATE_SIZE


class Trunk(nn.Module):
    """Parallel 1-D convolutions over the fuzzy state, concatenated and flattened."""

    def __init__(self, kernels: Sequence[int] = (3, 5, 7), channels: int = 3) -> None:
        super().__init__()
        self.convs = nn.ModuleList(nn.Conv1d(1, channels, k, padding="same") for k in kernels)
        self.out_features = channels * len(kernels) * STATE_SIZE

    def forward(self, state: torch.Tensor) -> torch.Tensor:
        x = state.unsqueeze(1)  # (batch, 1 channel, 9)
        x = torch.cat([conv(x) for conv in self.convs], dim=1)  # (batch, 9 channels, 9)
        return torch.relu(x).flatten(1)


def mlp(inputs: int, hidden: Sequence[int], outputs: int) -> nn.Sequential:
    """Linear-ReLU stack with a linear output layer."""
    layers: list[nn.Module] = []
    for width in hidden:
        layers += [nn.Linear(inputs, width), nn.ReLU()]
        inputs = width
    layers.append(nn.Linear(inputs, outputs))
    return nn.Sequential(*layers)


class Actor(nn.Module):
    """Fuzzy state -> rule firing strengths -> TSK output z* inside [min f, max f]."""

    def __init__(
        self,
        consequents: Sequence[float],
        kernels: Sequence[int] = (3, 5, 7),
        channels: int = 3,
        hidden: Sequence[int] = (64, 128, 128, 64, 32),
        last_init: float = 3e-3,
    ) -> None:
        super().__init__()
        self.trunk = Trunk(kernels, channels)
        self.head = mlp(self.trunk.out_features, hidden, len(consequents))
        last = self.head[-1]
        assert isinstance(last, nn.Linear)
        # Near-zero logits: uniform firing strengths, so z* starts at the mean consequent.
        nn.init.uniform_(last.weight, -last_init, last_init)
        nn.init.uniform_(last.bias, -last_init, last_init)
        f = torch.as_tensor(consequents, dtype=torch.float32)
        self.register_buffer("consequents", f)
        self.register_buffer("consequents_norm", (f - f.min()) / (f.max() - f.min()))

    def logits(self, state: torch.Tensor) -> torch.Tensor:
        """Rule logits before the softmax, shape (batch, 3)."""
        return self.head(self.trunk(state))  # type: ignore[no-any-return]

    def firing_strengths(self, state: torch.Tensor) -> torch.Tensor:
        """Normalised rule firing strengths w, shape (batch, 3)."""
        return torch.softmax(self.logits(state), dim=-1)

    def forward(self, state: torch.Tensor) -> torch.Tensor:
        """z* = sum w_i f_i, shape (batch,)."""
        return self.firing_strengths(state) @ self.consequents

    def normalised(self, state: torch.Tensor) -> torch.Tensor:
        """a_norm = (z* - min f) / (max f - min f), shape (batch,); the same TSK on normalised f."""
        return self.normalised_from_logits(self.logits(state))

    def normalised_from_logits(self, logits: torch.Tensor) -> torch.Tensor:
        """a_norm of given rule logits (for a loss that also needs the logits)."""
        return torch.softmax(logits, dim=-1) @ self.consequents_norm


class ActorSnapshot:
    """The actor's noise-free output for one state, from a copy of its weights.

    One decision through torch costs about 0.3 ms of per-operator overhead for a network this
    small, the same arithmetic in numpy about 35 µs, and compiled (``lit_core.TskActor``, what a
    call uses when the C++ core is built) about 4 µs: a decision service answering across
    processes needs the last. The parallel same-padded convolutions of the trunk are one linear
    map of the 9-vector, so the snapshot folds them into a single (81 x 9) matrix.
    :meth:`numpy_call` is the same computation in numpy, in float64 (the reference the compiled
    one is tested against; the compiled affine maps run in float32, as torch's do).
    """

    def __init__(self, actor: Actor, centres: Sequence[float], sigma: float) -> None:
        with torch.no_grad():
            self.centres = np.asarray(centres, dtype=np.float64)
            self.scale = -1.0 / (2.0 * sigma * sigma)
            weights, biases = [], []
            position = np.arange(STATE_SIZE)
            for conv in actor.trunk.convs:
                assert isinstance(conv, nn.Conv1d) and conv.bias is not None
                weight = conv.weight.detach().double().numpy()[:, 0, :]  # (channels, k)
                k = weight.shape[-1]
                # Output position i reads input i + j - (k - 1) / 2 (padding="same", odd k).
                out, tap = np.meshgrid(position, np.arange(k), indexing="ij")
                source = out + tap - (k - 1) // 2
                inside = (source >= 0) & (source < STATE_SIZE)
                folded = np.zeros((weight.shape[0], STATE_SIZE, STATE_SIZE))
                folded[:, out[inside], source[inside]] = weight[:, tap[inside]]
                weights.append(folded.reshape(-1, STATE_SIZE))  # rows: channel-major, as torch
                biases.append(np.repeat(conv.bias.detach().double().numpy(), STATE_SIZE))
            self.trunk_weight = np.concatenate(weights)  # (channels * kernels * 9, 9)
            self.trunk_bias = np.concatenate(biases)
            self.layers = [
                (layer.weight.detach().double().numpy(), layer.bias.detach().double().numpy())
                for layer in actor.head
                if isinstance(layer, nn.Linear)
            ]
            self.consequents = actor.consequents.detach().double().numpy()
        self.compiled = _compiled_actor(
            tuple(float(c) for c in centres),
            float(sigma),
            (self.trunk_weight, self.trunk_bias),
            self.layers,
            self.consequents,
        )
        """The compiled forward pass, or None when ``lit_core`` is not importable."""

    def __call__(self, features: Sequence[float]) -> float:
        """z*(features) for one raw (rho_global, rho_local, m)."""
        if self.compiled is not None:
            g, l, m = features
            return self.compiled(float(g), float(l), float(m))  # type: ignore[no-any-return]
        return self.numpy_call(features)

    def numpy_call(self, features: Sequence[float]) -> float:
        """:meth:`__call__` in numpy."""
        diff = np.asarray(features, dtype=np.float64)[:, None] - self.centres
        x = np.exp(diff * diff * self.scale).ravel()
        x = np.maximum(self.trunk_weight @ x + self.trunk_bias, 0.0)
        last = len(self.layers) - 1
        for index, (weight, bias) in enumerate(self.layers):
            x = weight @ x + bias
            if index < last:
                x = np.maximum(x, 0.0)
        w = np.exp(x - x.max())
        return float(w @ self.consequents / w.sum())


def _compiled_actor(
    centres: tuple[float, ...],
    sigma: float,
    trunk: tuple[np.ndarray, np.ndarray],
    layers: list[tuple[np.ndarray, np.ndarray]],
    consequents: np.ndarray,
) -> Any:
    """``lit_core.TskActor`` of these weights; None without the C++ core (a learner installed
    alone still works, in numpy)."""
    try:
        import lit_core
    except ImportError:
        return None
    compiled = getattr(lit_core, "TskActor", None)  # None: a core built before it existed
    return None if compiled is None else compiled(centres, sigma, trunk, layers, consequents)


class Critic(nn.Module):
    """Q(s, a_norm) from [trunk(s), a_norm]."""

    def __init__(
        self,
        kernels: Sequence[int] = (3, 5, 7),
        channels: int = 3,
        hidden: Sequence[int] = (64, 128, 128, 64, 32),
    ) -> None:
        super().__init__()
        self.trunk = Trunk(kernels, channels)
        self.head = mlp(self.trunk.out_features + 1, hidden, 1)

    def forward(self, state: torch.Tensor, action_norm: torch.Tensor) -> torch.Tensor:
        """Q values, shape (batch,)."""
        x = torch.cat([self.trunk(state), action_norm.unsqueeze(-1)], dim=-1)
        return self.head(x).squeeze(-1)


@torch.no_grad()
def polyak_update(target: nn.Module, source: nn.Module, tau: float) -> None:
    """target <- tau * source + (1 - tau) * target, parameter by parameter (tau = 1 copies)."""
    targets, sources = list(target.parameters()), list(source.parameters())
    if len(targets) != len(sources):
        raise ValueError(f"Polyak update between {len(targets)} and {len(sources)} parameters")
    if tau == 1.0:
        torch._foreach_copy_(targets, sources)
    else:
        torch._foreach_lerp_(targets, sources, tau)

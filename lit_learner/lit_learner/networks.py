"""Actor and critic of one agent (LEARNER.md "Networks").

Trunk: fuzzy 9-vector as 1 channel x 9 -> parallel Conv1d(1 -> 3), kernels 3/5/7, same padding ->
9 channels x 9 -> ReLU -> flatten (81). Actor: trunk -> MLP 64-128-128-64-32 -> 3 logits ->
softmax = rule firing strengths w -> z* = sum w_i f_i (zero-order TSK). Critic: [trunk(s), a_norm]
-> the same MLP -> Q.
"""

from __future__ import annotations

from collections.abc import Sequence

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

    def firing_strengths(self, state: torch.Tensor) -> torch.Tensor:
        """Normalised rule firing strengths w, shape (batch, 3)."""
        return torch.softmax(self.head(self.trunk(state)), dim=-1)

    def forward(self, state: torch.Tensor) -> torch.Tensor:
        """z* = sum w_i f_i, shape (batch,)."""
        return self.firing_strengths(state) @ self.consequents

    def normalised(self, state: torch.Tensor) -> torch.Tensor:
        """a_norm = (z* - min f) / (max f - min f), shape (batch,); the same TSK on normalised f."""
        return self.firing_strengths(state) @ self.consequents_norm


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

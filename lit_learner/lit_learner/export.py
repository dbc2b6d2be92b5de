"""Lookup-tensor export (LEARNER.md "Lookup-tensor export").

value[i, j, k] = noise-free z*(i / 100, j / 100, k / 100) over the node-centred 101^3 grid, axes
(rho_global, rho_local, measure) in C order, float32, before rounding; written with
:func:`lit_planner.tensor_files.write_tensor`, which validates the sidecar schema.
"""

from __future__ import annotations

import numpy as np
import torch
from lit_planner.tensor_files import GRID_SIZE, TENSOR_SHAPE
from numpy.typing import NDArray

from lit_learner.config import AgentConfig
from lit_learner.fuzzy import fuzzify
from lit_learner.networks import Actor
from lit_planner import tensor_files

EXPORT_CHUNK = 1 << 16
"""Grid points per actor forward pass during export."""
TENSOR_FILES = tensor_files.TENSOR_FILES
"""File name of each agent's tensor (the planner's ``tensor`` policy looks for these)."""
CHECKPOINT_FILE = "checkpoint.pt"
"""Name of the checkpoint saved next to the tensors and hashed into their sidecars."""


def grid_features() -> NDArray[np.float32]:
    """(101^3, 3) grid points (i / 100, j / 100, k / 100) in C order, float32."""
    axis = np.arange(GRID_SIZE, dtype=np.float64) / (GRID_SIZE - 1)
    mesh = np.meshgrid(axis, axis, axis, indexing="ij")
    return np.stack([m.ravel() for m in mesh], axis=-1).astype(np.float32)


@torch.no_grad()
def policy_grid(actor: Actor, config: AgentConfig) -> NDArray[np.float32]:
    """The actor's noise-free z* on the grid, shape (101, 101, 101), clipped to [min f, max f]
    (softmax arithmetic can overshoot an extreme consequent by an ulp)."""
    points = torch.from_numpy(grid_features())
    values = torch.cat(
        [
            actor(fuzzify(chunk, config.fuzzy_centres, config.fuzzy_sigma))
            for chunk in torch.split(points, EXPORT_CHUNK)
        ]
    )
    out = values.numpy().astype(np.float32).reshape(TENSOR_SHAPE)
    return np.clip(out, config.action_min, config.action_max)

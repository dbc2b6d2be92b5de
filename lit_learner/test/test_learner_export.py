"""Tensor export round trip: Python reader, direct actor evaluation, sidecar, C++ reader."""

from __future__ import annotations

import contextlib
import hashlib
import resource
from collections.abc import Iterator
from pathlib import Path

import lit_core
import numpy as np
import pytest
import torch
from lit_learner.config import AgentConfig, LearnerConfig
from lit_learner.core import LearnerCore
from lit_learner.errors import ExportError
from lit_learner.export import grid_features

from lit_planner import tensor_files as tf


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> tuple[LearnerCore, dict[str, Path]]:
    config = LearnerConfig(
        b=AgentConfig.batch_size_agent(buffer_size=64, warmup=64),
        k=AgentConfig.neighbour_agent(buffer_size=256, warmup=256),
        seed=11,
    )
    core = LearnerCore(config)
    generator = torch.Generator().manual_seed(0)
    for agent in core.agents.values():  # a policy that varies over the grid, as a trained one
        actor = agent.actor
        with torch.no_grad():
            for layer in [*actor.trunk.convs, *actor.head[:-1]]:
                if isinstance(layer, (torch.nn.Conv1d, torch.nn.Linear)):
                    layer.weight.mul_(2.0)
            last = actor.head[-1]
            last.weight.copy_(torch.randn(last.weight.shape, generator=generator) * 5.0)
    directory = tmp_path_factory.mktemp("tensors")
    return core, core.export_tensors(directory, {"command": "pytest", "episodes": 0})


def test_grid_is_c_ordered() -> None:
    grid = grid_features().reshape(tf.TENSOR_SHAPE + (3,))
    assert grid.dtype == np.float32
    assert tuple(grid[3, 50, 100]) == (np.float32(0.03), np.float32(0.5), np.float32(1.0))


@pytest.mark.parametrize("name", ["B", "psi_K"])
def test_export_round_trip(exported: tuple[LearnerCore, dict[str, Path]], name: str) -> None:
    core, paths = exported
    agent = core.agents[name]
    assert paths[name].name == {"B": "b_tensor.npy", "psi_K": "k_tensor.npy"}[name]
    values, sidecar = tf.read_tensor(paths[name])
    assert values.shape == (101, 101, 101) and values.dtype == np.float32
    span = agent.config.action_max - agent.config.action_min
    assert float(values.max() - values.min()) > 0.05 * span  # the policy is not constant

    rng = np.random.default_rng(4)
    for i, j, k in rng.integers(0, 101, (40, 3)).tolist() + [[0, 0, 0], [100, 100, 100]]:
        direct = agent.policy((i / 100, j / 100, k / 100))
        assert values[i, j, k] == pytest.approx(direct, abs=1e-4), (i, j, k)

    assert sidecar.output == name
    assert sidecar.tsk_consequents == agent.config.consequents
    assert sidecar.fuzzy_centres == agent.config.fuzzy_centres
    assert sidecar.fuzzy_sigma == agent.config.fuzzy_sigma
    assert sidecar.policy_version == core.policy_version
    assert sidecar.reward == core.config.reward.to_dict()
    assert sidecar.training["agent"] == agent.config.to_dict()
    assert sidecar.training["seed"] == 11
    assert sidecar.provenance == {"command": "pytest", "episodes": 0}
    checkpoint = paths["checkpoint"].read_bytes()
    assert sidecar.checkpoint_sha256 == hashlib.sha256(checkpoint).hexdigest()
    assert LearnerCore.load_checkpoint(paths["checkpoint"]).agents[name].policy(
        (0.2, 0.4, 0.6)
    ) == agent.policy((0.2, 0.4, 0.6))

    cpp = lit_core.LookupTensor.load(str(paths[name]), list(sidecar.shape), *sidecar.value_range)
    points = np.vstack([rng.uniform(0.0, 1.0, (30, 3)), [[0.0, 0.0, 0.0], [1.0, 0.5, 0.25]]])
    for mode in tf.INTERPOLATIONS:
        expected = tf.lookup(values, points, mode)
        got = [getattr(cpp, mode)(*map(float, p)) for p in points]
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-4, err_msg=mode)


@contextlib.contextmanager
def _files_limited_to(size: int) -> Iterator[None]:
    """Writes beyond ``size`` bytes per file fail with EFBIG (Python ignores SIGXFSZ): as a full
    disk makes an export fail partway."""
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (size, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))


def test_an_export_that_fails_partway_leaves_nothing_of_itself(
    exported: tuple[LearnerCore, dict[str, Path]], tmp_path: Path
) -> None:
    """A full disk left a truncated b_tensor.npy and a checkpoint without sidecars, raised a bare
    OSError (a traceback from lit train), and the folder then blocked the retry ("exists and is
    not empty")."""
    core, before = exported
    new = tmp_path / "new"
    with _files_limited_to(3_000_000), pytest.raises(ExportError) as failed:  # a tensor: 4.1 MB
        core.export_tensors(new, {"command": "pytest"}, extra={"provenance.json": b"{}\n"})
    assert str(failed.value).startswith(f"export to {new} failed (")
    assert str(failed.value).endswith("nothing of it was written there")
    assert not new.exists()  # the folder it created is gone too
    # Over an earlier export: its files stay as they were, and nothing is added.
    old = before["B"].parent
    files = {path.name: path.read_bytes() for path in old.iterdir()}
    with _files_limited_to(3_000_000), pytest.raises(ExportError, match="nothing of it"):
        core.export_tensors(old, {"command": "pytest", "episodes": 1})
    assert {path.name: path.read_bytes() for path in old.iterdir()} == files
    written = core.export_tensors(new, {"command": "pytest"}, extra={"provenance.json": b"{}\n"})
    assert sorted(path.name for path in new.iterdir()) == sorted(
        [*(path.name for path in written.values()), "b_tensor.json", "k_tensor.json",
         "provenance.json"]
    )  # fmt: skip
    tf.read_tensor(written["B"])


def test_export_trained_writes_the_agents_that_made_a_gradient_update(tmp_path: Path) -> None:
    """The exporters (lit train, lit replay tensors, the learner node) write no tensor of an
    agent whose actor holds its initial weights (the tensor policy played it: psi_K about 9
    where its fixed value is e); each left out is said why, in words that fit where its
    training stands, and ``remove_others`` takes an earlier export's tensor of it away."""
    core = LearnerCore(LearnerConfig(train_b=False, seed=3))
    assert core.export_plan() == (
        (),
        {
            "B": "no tensor (this run does not train it); the tensor policy keeps its fixed value "
            "(B = 100)",
            "psi_K": "no tensor (no gradient update yet: 0 of the 10000 transitions its updates "
            "wait for); the tensor policy keeps its fixed value (psi_K = e)",
        },
    )
    core.agents["psi_K"].transitions = 10_000  # warm-up over, its first steps not run yet
    assert core.untrained_reason("psi_K") == (
        "no gradient update yet: its 10000 transitions passed the warm-up (10000); its first "
        "steps are still owed"
    )
    core.agents["psi_K"].updates = 1
    assert core.export_plan() == (("psi_K",), {"B": core.export_plan()[1]["B"]})

    folder = tmp_path / "export"
    core.export_tensors(folder, {"command": "pytest"})  # both, as an earlier export
    paths, left_out = core.export_trained(folder, {"command": "pytest"}, remove_others=True)
    assert set(paths) == {"checkpoint", "psi_K"} and set(left_out) == {"B"}
    assert sorted(path.name for path in folder.iterdir()) == [
        "checkpoint.pt", "k_tensor.json", "k_tensor.npy"
    ]  # fmt: skip
    assert tf.read_tensor(paths["psi_K"])[1].training["updates"] == 1

"""When the learner node checkpoints (``LearnerNode._checkpoint_due``) and makes its
end-of-training export (``LearnerNode._export_due``), on a stand-in holding only what the rules
read: no ROS needed. The ROS tests (tests/test_ros_system.py) run the node."""

from __future__ import annotations

import time
from pathlib import Path
from types import SimpleNamespace

import pytest
from lit_learner.node import PARAMETERS, LearnerNode


def _due(progress: tuple[int, int], since: float, **params: float) -> bool:
    node = SimpleNamespace(
        params={**PARAMETERS, **params},
        _at_checkpoint=(10, 4),  # (episodes, policy version) at the last checkpoint
        _last_checkpoint=time.monotonic() - since,
    )
    return LearnerNode._checkpoint_due(node, progress)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("progress", "since", "params", "due"),
    [
        ((60, 9), 1.0, {}, True),  # 50 episodes ended
        ((59, 9), 1.0, {}, False),
        ((11, 5), 31.0, {}, True),  # 30 s with progress
        ((10, 4), 31.0, {}, False),  # 30 s, nothing new
        ((11, 5), 1.0, {"checkpoint_every": 0}, False),  # 0 is off, not every episode
        ((10_000, 9), 1.0, {"checkpoint_every": 0}, False),
        ((11, 5), 1e6, {"checkpoint_period": 0.0}, False),  # 0 is off, not every wake-up
        ((60, 9), 1.0, {"checkpoint_period": 0.0}, True),  # the other rule still holds
        ((11, 5), 1.0, {"checkpoint_every": 1}, True),
    ],
)
def test_a_checkpoint_is_due_by_episodes_or_time_and_zero_turns_a_rule_off(
    progress: tuple[int, int], since: float, params: dict[str, float], due: bool
) -> None:
    assert _due(progress, since, **params) is due


@pytest.mark.parametrize(
    ("progress", "pending", "exported", "at_export", "due"),
    [
        ((100, 7), 0, False, (0, 0), True),  # max_episodes ended, no gradient step owed
        ((100, 7), 3, False, (0, 0), False),  # steps owed: an agent may not have trained yet
        ((99, 7), 0, False, (0, 0), False),  # not all episodes ended
        ((100, 7), 0, True, (0, 0), False),  # made once
        ((100, 7), 0, False, (100, 7), False),  # nothing new since the last export
        ((130, 9), 0, False, (0, 0), True),  # later episodes (resumed past the limit)
    ],
)
def test_the_end_of_training_export_waits_for_the_owed_gradient_steps(
    progress: tuple[int, int],
    pending: int,
    exported: bool,
    at_export: tuple[int, int],
    due: bool,
) -> None:
    """After ``max_episodes`` episodes the export waited for nothing: an agent whose warm-up
    ended with the last episode had made no gradient step yet, and was left out of the export
    for good (it is made once)."""
    node = SimpleNamespace(
        params={**PARAMETERS, "max_episodes": 100},
        core=SimpleNamespace(pending_updates=pending),
        _exported_at_end=exported,
        _at_export=at_export,
    )
    assert LearnerNode._export_due(node, progress) is due  # type: ignore[arg-type]
    off = SimpleNamespace(**{**vars(node), "params": {**PARAMETERS, "max_episodes": 0}})
    assert LearnerNode._export_due(off, progress) is False  # type: ignore[arg-type]


def test_an_export_folder_with_a_pipe_for_a_sidecar_is_foreign_without_waiting(
    tmp_path: Path,
) -> None:
    """The node's start reads the sidecars in its export_dir (whose files are not its own?): a
    named pipe there held it in open() for good. Read without blocking, the pipe is a file of
    something else, which the node refuses to replace."""
    import os
    import threading

    from lit_learner.node import foreign_tensor_files

    os.mkfifo(tmp_path / "b_tensor.json")
    found: list[list[str]] = []
    reader = threading.Thread(target=lambda: found.append(foreign_tensor_files(tmp_path)))
    reader.daemon = True  # a hung open() cannot be joined
    reader.start()
    reader.join(60)
    hung = reader.is_alive()
    if hung:
        with open(tmp_path / "b_tensor.json", "wb"):  # the other end: the reader goes on
            pass
        reader.join(10)
    assert not hung, "the sidecar's read did not end"
    assert found == [["b_tensor.json"]]


def test_a_seed_beyond_the_learners_bound_is_a_parameter_problem(tmp_path: Path) -> None:
    """A seed of 2^63 - 1 passed the node's check and then stopped it with a traceback (the
    learner's config refuses it: its psi_K agent's seed, one more, would overflow)."""
    from lit_learner.node import parameter_problem

    params = {**PARAMETERS, "export_dir": str(tmp_path)}
    assert parameter_problem({**params, "seed": 2**63 - 2}) is None
    assert parameter_problem({**params, "seed": 2**63 - 1}) == (
        "seed must be at most 2^63 - 2, got 9223372036854775807"
    )

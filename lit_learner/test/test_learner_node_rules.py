"""When the learner node checkpoints (``LearnerNode._checkpoint_due``), on a stand-in holding
only what the rule reads: no ROS needed. The ROS tests (tests/test_ros_system.py) run the node."""

from __future__ import annotations

import time
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

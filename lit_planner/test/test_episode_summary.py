"""The EpisodeSummary of a query (``episode_messages``): the world of a custom scenario rides
along (version 2) so that a replay can re-check its path, and a world too large for a message
is left out rather than failing the answered plan."""

from __future__ import annotations

import json

import numpy as np
import pytest
from lit_msgs_json.envelope import MessageError
from lit_planner.episode_messages import encode_summary, summary_payload, world_payload

from lit_msgs_json import MAX_MESSAGE_BYTES, Publisher, decode
from lit_planner import planning, scenarios


def _summary(problem: scenarios.Scenario) -> dict:
    result = planning.plan(problem, "litstar", "fixed", max_iterations=200, seed=1)
    return summary_payload("e-1", "inference", problem, 1, "fixed", result)


def _custom(boxes: int, dim: int = 16) -> scenarios.Scenario:
    rng = np.random.default_rng(0)
    corners = rng.uniform(0.2, 0.8, size=(boxes, dim))
    return scenarios.custom(
        [0.0] * dim,
        [1.0] * dim,
        [(list(c), list(c + 0.001)) for c in corners],
        [0.05] * dim,
        [0.95] * dim,
        time_budget=0.5,
    )


def test_a_registry_scenario_has_no_world_and_a_custom_one_carries_it() -> None:
    assert "world" not in _summary(scenarios.get("np4"))
    problem = scenarios.custom([0, 0], [1, 1], [([0.4, 0.1], [0.6, 0.9])], [0.1, 0.5], [0.9, 0.5])
    summary = _summary(problem)
    assert summary["world"] == world_payload(problem)
    assert summary["world"]["boxes"] == [{"lower": [0.4, 0.1], "upper": [0.6, 0.9]}]
    text, dropped = encode_summary(Publisher("p", "r"), summary)
    assert dropped is None
    assert decode(text).payload["world"]["start"] == [0.1, 0.5]


def test_a_world_too_large_for_a_message_is_left_out_with_the_reason() -> None:
    problem = _custom(boxes=3000)  # about 1.4 MB of world in the summary
    summary = _summary(problem)
    assert len(json.dumps(summary["world"])) > MAX_MESSAGE_BYTES
    text, dropped = encode_summary(Publisher("p", "r"), summary)
    assert dropped is not None and "more than the limit" in dropped
    decoded = decode(text).payload
    assert "world" not in decoded and decoded["episode_id"] == "e-1"


def test_other_defects_of_a_summary_still_raise() -> None:
    summary = _summary(scenarios.get("np4")) | {"solved": "yes"}
    with pytest.raises(MessageError, match="payload"):
        encode_summary(Publisher("p", "r"), summary)

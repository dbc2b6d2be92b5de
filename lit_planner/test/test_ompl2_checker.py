"""The cross-check's numpy box-world checker against the C++ core's checker, in this process.

The checker itself is plain numpy (no PyPI ompl), so it can be compared with ``lit_core`` here;
only the code that imports ``ompl`` must run in a separate process.
"""

from __future__ import annotations

import numpy as np
import pytest
from lit_planner.ompl2.checker import BoxWorldChecker

from lit_planner import planning, scenarios

SCENARIOS = ("np4", "np8", "wg4", "rrd4", "rrd8")


def checker_for(name: str) -> BoxWorldChecker:
    return BoxWorldChecker.from_definition(scenarios.get(name).to_dict())


def sample_points(name: str, count: int, rng: np.random.Generator) -> np.ndarray:
    """Uniform points, points a little outside the bounds, and points exactly on box faces."""
    scenario = scenarios.get(name)
    uniform = rng.uniform(-0.5, 0.5, (count, scenario.dim))
    outside = rng.uniform(-0.55, 0.55, (count // 4, scenario.dim))
    faces = rng.uniform(-0.5, 0.5, (count // 4, scenario.dim))
    for point in faces:  # put one coordinate on a face of a random box (closed boxes collide)
        box = scenario.boxes[rng.integers(len(scenario.boxes))]
        axis = rng.integers(scenario.dim)
        point[:] = np.clip(point, box[0], box[1])
        point[axis] = box[rng.integers(2), axis]
    return np.vstack([uniform, outside, faces])


@pytest.mark.parametrize("name", SCENARIOS)
def test_points_agree_with_lit_core(name: str) -> None:
    rng = np.random.default_rng(12345)
    points = sample_points(name, 1200, rng)
    query = planning.query_for(scenarios.get(name))
    expected = np.array([query.is_valid(point.tolist()) for point in points])
    got = checker_for(name).is_valid(points)
    assert got.tolist() == expected.tolist()
    assert 0 < expected.sum() < len(points)  # both verdicts occur
    single = [checker_for(name).is_state_valid(point) for point in points[:200]]
    assert single == expected[:200].tolist()


def test_face_points_and_nan_are_invalid() -> None:
    checker = checker_for("np4")
    assert not checker.is_state_valid([0.1, 0.05, 0.0, 0.0])  # corner of the lower block
    assert checker.is_state_valid([0.1, 0.0500001, 0.0, 0.0])  # inside the slab
    assert not checker.is_state_valid([0.6, 0.0, 0.0, 0.0])  # outside the bounds
    assert not checker.is_valid([[np.nan, 0.1, 0.0, 0.0]])[0]


@pytest.mark.parametrize("name", ("np4", "rrd4", "rrd8"))
def test_exact_motion_check_matches_enumerating_ompl_states(name: str) -> None:
    """The slab-interval decision equals testing OMPL's discrete states one by one."""
    checker = checker_for(name)
    rng = np.random.default_rng(7)
    valid_starts = [p for p in rng.uniform(-0.5, 0.5, (400, checker.dim))
                    if checker.is_state_valid(p)]  # fmt: skip
    verdicts = []
    for a in valid_starts[:60]:
        # short segments (a few thousand states) keep the enumeration quick
        b = np.clip(a + rng.normal(0.0, 0.03, checker.dim), -0.5, 0.5)
        exact, enumerated = checker.motion_valid(a, b), checker.motion_states_valid(a, b)
        assert exact == enumerated, (a.tolist(), b.tolist())
        verdicts.append(exact)
    assert any(verdicts) and not all(verdicts)  # both verdicts occur


def test_motion_check_grazing_a_corner_between_states() -> None:
    """A segment that clips a box between two discrete states is valid at the resolution."""
    checker = BoxWorldChecker.from_definition({
        "lower": [0.0, 0.0], "upper": [1.0, 1.0], "resolution": 0.1,
        "boxes": [[[0.5, 0.5], [0.52, 0.52]]],
    })  # fmt: skip
    # longest valid segment: 0.1 * sqrt(2); the segment crosses the tiny box between states
    a, b = [0.5 - 0.05, 0.51], [0.5 + 0.1, 0.51]
    assert checker.segment_count(a, b) == 2
    assert checker.motion_valid(a, b) and checker.motion_states_valid(a, b)
    assert not checker.check_path([a, b], refinement=4)["valid"]  # the dense check finds it


def test_dense_path_check() -> None:
    scenario = scenarios.get("np4")
    checker = checker_for("np4")
    straight = [scenario.start, scenario.goal]
    report = checker.check_path(straight, scenario.start, scenario.goal)
    assert not report["valid"] and report["first_invalid_segment"] == 0
    through_slab = [scenario.start, (-0.1, 0.1, 0, 0), (0.1, 0.1, 0, 0), scenario.goal]
    report = checker.check_path(through_slab, scenario.start, scenario.goal)
    assert report["valid"] and report["starts_at_start"] and report["ends_at_goal"]
    assert report["length"] == pytest.approx(0.2 + 2 * np.hypot(0.1, 0.1))
    assert report["spacing"] == pytest.approx(scenario.resolution * scenario.max_extent / 4)

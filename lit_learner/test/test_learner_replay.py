"""Prioritized replay: sum-tree totals, sampling frequencies, importance weights, beta."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from lit_learner.errors import ReplayError
from lit_learner.replay import PrioritizedReplay, SumTree, beta_at


def test_sum_tree_totals_follow_every_update() -> None:
    rng = np.random.default_rng(0)
    tree = SumTree(1000)  # not a power of two
    values = np.zeros(1000)
    for _ in range(50):
        index = rng.integers(0, 1000, 37)
        new = rng.uniform(0.0, 5.0, 37)
        tree.set(index, new)
        values[index] = new  # a repeated index keeps its last value, like numpy
        assert tree.total == pytest.approx(values.sum(), rel=1e-12)
        np.testing.assert_array_equal(tree.get(np.arange(1000)), values)
    assert tree.nodes.dtype == np.float64


def test_sum_tree_find_walks_the_cumulative_sums() -> None:
    tree = SumTree(4)
    tree.set(np.arange(4), np.array([1.0, 0.0, 2.0, 3.0]))
    found = tree.find(np.array([0.0, 0.999, 1.0, 2.5, 3.0, 5.999]))
    np.testing.assert_array_equal(found, [0, 0, 2, 2, 3, 3])  # the zero leaf is never found


def test_sum_tree_rejects_bad_indices() -> None:
    with pytest.raises(ReplayError, match=r"outside \[0, 3\)"):
        SumTree(3).set(3, 1.0)


@pytest.mark.parametrize("items", [0, 1, 700, 1000, 1500])
def test_a_saved_sum_tree_keeps_its_leaves_and_rebuilds_its_sums_bit_for_bit(items: int) -> None:
    """Only the filled leaves are saved; every inner node is rebuilt from them with the same
    float64 additions, through sampling updates and wrap-around (1500 adds to 1000 slots)."""
    rng = np.random.default_rng(3)
    replay = PrioritizedReplay(1000, alpha=0.6, priority_eps=1e-6)  # 1024 leaves
    for i in range(items):
        replay.add((0.1, 0.2, 0.3), 0.5, float(i), (0.1, 0.2, 0.4), False)
        if i % 50 == 49:
            index = rng.integers(0, replay.size, 64)
            replay.update_priorities(index, rng.normal(size=64), sampled_at=replay.adds)
    state = replay.state_dict()
    assert state["tree"]["leaves"].shape == (replay.size,)  # not the 2048 nodes
    loaded = PrioritizedReplay(1000, alpha=0.6, priority_eps=1e-6)
    loaded.load_state_dict(state)
    np.testing.assert_array_equal(loaded.tree.nodes, replay.tree.nodes)  # bitwise
    assert loaded.tree.total == replay.tree.total


def test_a_sum_tree_saved_with_all_its_nodes_still_loads() -> None:
    """Checkpoints written before the leaves-only layout hold every node."""
    tree = SumTree(5)
    tree.set(np.arange(5), np.array([1.0, 0.5, 2.0, 0.25, 3.0]))
    old = SumTree(5)
    old.load_state_dict({"capacity": 5, "nodes": tree.nodes.copy()})
    np.testing.assert_array_equal(old.nodes, tree.nodes)
    with pytest.raises(ReplayError, match="do not fit"):
        SumTree(5).load_state_dict({"capacity": 5, "leaves": np.ones(6)})
    with pytest.raises(ReplayError, match="filled leaves outside"):
        tree.state_dict(6)


def filled(priorities: list[float], alpha: float) -> PrioritizedReplay:
    replay = PrioritizedReplay(len(priorities), alpha, priority_eps=1e-6)
    for i in range(len(priorities)):
        replay.add((0.0, 0.0, float(i)), 0.5, float(i), (0.0, 0.0, 0.0), False)
    replay.update_priorities(np.arange(len(priorities)), np.array(priorities) - 1e-6)
    return replay


def test_sampling_frequencies_follow_p_to_the_alpha() -> None:
    priorities = [0.5, 1.0, 2.0, 4.0, 8.0]
    alpha = 0.6
    replay = filled(priorities, alpha)
    rng = np.random.default_rng(12345)
    draws = 200_000
    counts = np.zeros(len(priorities))
    for _ in range(draws // 1000):
        batch = replay.sample(1000, 0.4, rng)
        np.add.at(counts, batch.index, 1)
    expected = np.array(priorities) ** alpha
    expected = draws * expected / expected.sum()
    chi_square = float(((counts - expected) ** 2 / expected).sum())
    assert chi_square < 20.0  # 4 degrees of freedom: p < 0.001 at 18.5
    # The stored reward identifies the item: the batch carries the sampled rows.
    batch = replay.sample(16, 0.4, rng)
    np.testing.assert_array_equal(batch.reward, batch.index.astype(np.float32))


def test_importance_weights_are_at_most_one_and_one_for_the_rarest() -> None:
    replay = filled([0.5, 1.0, 2.0, 4.0, 8.0], alpha=0.6)
    rng = np.random.default_rng(1)
    for beta in (0.4, 0.7, 1.0):
        batch = replay.sample(500, beta, rng)
        assert np.all(batch.weight <= 1.0) and np.all(batch.weight > 0.0)
        assert np.all(batch.weight[batch.index == 0] == pytest.approx(1.0))
        p = np.array([0.5, 1.0, 2.0, 4.0, 8.0]) ** 0.6
        expected = (p[batch.index] / p.min()) ** (-beta)
        np.testing.assert_allclose(batch.weight, expected, rtol=1e-6)


def test_the_smallest_stored_priority_ignores_the_empty_leaves() -> None:
    tree = SumTree(8)
    tree.set(np.arange(3), np.array([2.0, 0.5, 3.0]))
    assert tree.stored_min(3) == 0.5  # leaves 3..7 are empty (zero) and not stored
    assert tree.stored_min(1) == 2.0
    for filled in (0, 9):
        with pytest.raises(ReplayError):
            tree.stored_min(filled)


def test_new_items_enter_at_the_largest_priority_so_far() -> None:
    replay = PrioritizedReplay(8, alpha=0.5, priority_eps=1e-6)
    replay.add((0, 0, 0), 0.0, 0.0, (0, 0, 0), False)
    assert replay.tree.get(np.array([0]))[0] == pytest.approx(1.0)
    replay.update_priorities(np.array([0]), np.array([9.0 - 1e-6]))
    replay.add((0, 0, 0), 0.0, 0.0, (0, 0, 0), True)
    assert replay.tree.get(np.array([1]))[0] == pytest.approx(3.0)  # 9 ** 0.5
    assert replay.terminated[1] == 1.0


def test_ring_buffer_overwrites_the_oldest() -> None:
    replay = PrioritizedReplay(3, alpha=0.6, priority_eps=1e-6)
    for i in range(5):
        replay.add((float(i), 0, 0), 0.0, float(i), (0, 0, 0), False)
    assert len(replay) == 3 and replay.position == 2
    assert sorted(replay.reward.tolist()) == [2.0, 3.0, 4.0]


def test_priorities_of_items_overwritten_since_the_sample_are_kept() -> None:
    """A gradient step samples, another thread adds (wrapping the ring), then the step writes
    its errors: only items still holding what was sampled take them."""
    replay = PrioritizedReplay(4, alpha=1.0, priority_eps=0.0)
    for _ in range(4):
        replay.add((0, 0, 0), 0.0, 0.0, (0, 0, 0), False)  # priority 1 each, position back at 0
    batch = replay.sample(64, 0.4, np.random.default_rng(0))
    assert set(batch.index.tolist()) == {0, 1, 2, 3}
    replay.update_priorities(np.array([1]), np.array([5.0]))  # max priority 5 for new items
    for _ in range(2):  # slots 0 and 1 now hold new transitions at priority 5
        replay.add((1, 1, 1), 1.0, 1.0, (1, 1, 1), False)
    replay.update_priorities(batch.index, np.full(batch.index.shape, 0.5), sampled_at=batch.adds)
    assert replay.tree.get(np.arange(4)).tolist() == pytest.approx([5.0, 5.0, 0.5, 0.5])
    # Without the add count (one thread) every sampled item takes its error.
    replay.update_priorities(np.array([0, 1]), np.array([0.25, 0.25]))
    assert replay.tree.get(np.arange(2)).tolist() == pytest.approx([0.25, 0.25])
    # A whole ring of adds since the sample: nothing sampled is left.
    batch = replay.sample(16, 0.4, np.random.default_rng(1))
    for _ in range(5):
        replay.add((2, 2, 2), 2.0, 2.0, (2, 2, 2), False)
    before = replay.tree.get(np.arange(4)).tolist()
    replay.update_priorities(batch.index, np.full(batch.index.shape, 9.0), sampled_at=batch.adds)
    assert replay.tree.get(np.arange(4)).tolist() == before


def test_sampling_an_empty_buffer_fails() -> None:
    with pytest.raises(ReplayError, match="empty replay buffer"):
        PrioritizedReplay(4, 0.6, 1e-6).sample(2, 0.4, np.random.default_rng(0))


@pytest.mark.parametrize("field", ["state", "action", "reward", "next_state"])
def test_a_transition_with_a_value_that_is_not_finite_is_not_stored(field: str) -> None:
    replay = PrioritizedReplay(4, 0.6, 1e-6)
    values = {"state": (0.1, 0.2, 0.3), "action": 0.5, "reward": 1.0,
              "next_state": (0.1, 0.2, 0.3)}  # fmt: skip
    values[field] = (0.1, float("nan"), 0.3) if "state" in field else float("inf")
    with pytest.raises(ReplayError, match="not finite"):
        replay.add(values["state"], values["action"], values["reward"], values["next_state"],
                   terminated=False)  # fmt: skip
    values[field] = (0.1, 1e300, 0.3) if "state" in field else -1e300  # inf in float32
    with pytest.raises(ReplayError, match="not finite in float32"):
        replay.add(values["state"], values["action"], values["reward"], values["next_state"],
                   terminated=False)  # fmt: skip
    assert len(replay) == 0 and replay.tree.total == 0.0


def test_beta_rises_linearly_and_stops_at_the_end() -> None:
    assert beta_at(0, 0.4, 1.0, 100) == 0.4
    assert beta_at(50, 0.4, 1.0, 100) == pytest.approx(0.7)
    assert beta_at(100, 0.4, 1.0, 100) == 1.0
    assert beta_at(10_000, 0.4, 1.0, 100) == 1.0


def test_single_leaf_updates_equal_vectorised_ones_bit_for_bit() -> None:
    rng = np.random.default_rng(1)
    one, many = SumTree(777), SumTree(777)
    for _ in range(300):
        index, value = int(rng.integers(0, 777)), float(rng.uniform(0.0, 3.0))
        one.set(index, value)  # the scalar path
        many.set(np.array([index]), np.array([value]))  # the array path
    np.testing.assert_array_equal(one.nodes, many.nodes)
    with pytest.raises(ReplayError, match=r"outside \[0, 777\)"):
        one.set(-1, 1.0)


def test_a_full_ring_loaded_without_its_bad_items_keeps_their_age_order() -> None:
    """Items left out at load (a value that is not finite) close up oldest first, so that once
    the buffer is full again the oldest item is the next one overwritten."""
    replay = PrioritizedReplay(capacity=5, alpha=0.6, priority_eps=1e-3)
    for i in range(7):  # slots hold 5, 6, 2, 3, 4; the oldest (2) is at position 2
        replay.add((0.1, 0.2, 0.3), 0.5, float(i), (0.2, 0.3, 0.4), False)
    assert replay.position == 2
    state = copy.deepcopy(replay.state_dict())
    state["reward"][3] = np.nan  # the item of reward 3
    loaded = PrioritizedReplay(capacity=5, alpha=0.6, priority_eps=1e-3)
    assert loaded.load_state_dict(state) == 1
    assert (loaded.size, loaded.position) == (4, 4)
    assert list(loaded.reward[:4]) == [2.0, 4.0, 5.0, 6.0]
    loaded.add((0.1, 0.2, 0.3), 0.5, 7.0, (0.2, 0.3, 0.4), False)
    loaded.add((0.1, 0.2, 0.3), 0.5, 8.0, (0.2, 0.3, 0.4), False)  # overwrites the oldest, 2
    assert list(loaded.reward) == [8.0, 4.0, 5.0, 6.0, 7.0]
    assert loaded.tree.total == pytest.approx(float(loaded.tree.get(np.arange(5)).sum()))


def test_a_buffer_with_alpha_zero_loads_a_priority_that_is_not_finite() -> None:
    """alpha = 0 stores every leaf as 1: the maximum priority cannot be recovered from them (it
    divided by zero), and 1 is what a fresh buffer starts with."""
    replay = PrioritizedReplay(capacity=8, alpha=0.0, priority_eps=1e-3)
    for i in range(4):
        replay.add((0.1, 0.2, 0.3), 0.5, float(i), (0.2, 0.3, 0.4), False)
    state = copy.deepcopy(replay.state_dict())
    state["max_priority"] = float("inf")
    loaded = PrioritizedReplay(capacity=8, alpha=0.0, priority_eps=1e-3)
    assert loaded.load_state_dict(state) == 0
    assert loaded.max_priority == 1.0 and loaded.size == 4

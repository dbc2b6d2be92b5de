"""Prioritized experience replay with a float64 sum tree (LEARNER.md "Update").

Sampling probability P(i) = p_i^alpha / sum_k p_k^alpha; importance weights
w_i = (P(i) / P_min)^(-beta) <= 1 (P_min over the stored items); new items enter at the largest raw
priority set so far (1 at the start), so each is sampled at least about as often as the best.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lit_learner.errors import ReplayError

FLOAT32_MAX = float(np.finfo(np.float32).max)
"""The largest value the buffer's float32 arrays hold."""


class SumTree:
    """Binary tree of float64 sums over ``capacity`` leaves, vectorised update and search."""

    def __init__(self, capacity: int) -> None:
        if capacity < 1:
            raise ReplayError(f"sum tree capacity {capacity} must be >= 1")
        self.capacity = capacity
        self.leaves = 1 << max(0, (capacity - 1).bit_length())  # power of two >= capacity
        self.nodes = np.zeros(2 * self.leaves, dtype=np.float64)  # node 1 is the root

    @property
    def total(self) -> float:
        """Sum of all leaves."""
        return float(self.nodes[1])

    def get(self, index: NDArray[np.intp]) -> NDArray[np.float64]:
        """Leaf values at ``index``."""
        return self.nodes[self.leaves + np.asarray(index)]

    def stored_min(self, filled: int) -> float:
        """Smallest of the leaves ``[0, filled)``: one pass over a view of them (a gather of
        those leaves by index copied 8 MB per gradient step of the psi_K agent's 10^6 items)."""
        if not 1 <= filled <= self.capacity:
            raise ReplayError(
                f"sum tree: minimum over {filled} leaves outside [1, {self.capacity}]"
            )
        return float(self.nodes[self.leaves : self.leaves + filled].min())

    def set(self, index: NDArray[np.intp] | int, value: NDArray[np.float64] | float) -> None:
        """Set leaves (a repeated index keeps its last value) and recompute their ancestors."""
        if isinstance(index, (int, np.integer)) and np.ndim(value) == 0:
            self._set_one(int(index), float(value))
            return
        index = np.atleast_1d(np.asarray(index, dtype=np.intp))
        if index.size == 0:
            return
        if index.min() < 0 or index.max() >= self.capacity:
            raise ReplayError(f"sum tree index outside [0, {self.capacity})")
        node = self.leaves + index
        self.nodes[node] = np.broadcast_to(np.asarray(value, dtype=np.float64), node.shape)
        node = np.unique(node // 2)
        while node[0] >= 1:
            self.nodes[node] = self.nodes[2 * node] + self.nodes[2 * node + 1]
            node = np.unique(node // 2)
            if node[0] == 0:
                break

    def _set_one(self, index: int, value: float) -> None:
        """One leaf: the same float64 additions as :meth:`set`, without its array overhead (a
        replay insert happens inside every decision the learner answers)."""
        if not 0 <= index < self.capacity:
            raise ReplayError(f"sum tree index outside [0, {self.capacity})")
        nodes = self.nodes
        node = self.leaves + index
        nodes[node] = value
        node //= 2
        while node >= 1:
            nodes[node] = nodes[2 * node] + nodes[2 * node + 1]
            node //= 2

    def find(self, value: NDArray[np.float64]) -> NDArray[np.intp]:
        """Leaf indices whose cumulative range [prefix, prefix + leaf) holds each ``value``."""
        node = np.ones(value.shape, dtype=np.intp)
        remaining = value.astype(np.float64, copy=True)
        while node[0] < self.leaves:
            left = 2 * node
            left_sum = self.nodes[left]
            go_right = remaining >= left_sum
            remaining = np.where(go_right, remaining - left_sum, remaining)
            node = np.where(go_right, left + 1, left)
        return node - self.leaves

    def state_dict(self, filled: int | None = None) -> dict[str, Any]:
        """The leaves ``[0, filled)`` (all by default); the caller vouches that the others are
        zero. Inner nodes are not saved: each is always the float64 sum of its two children
        (:meth:`set` keeps it so), so :meth:`load_state_dict` rebuilds them bit for bit. For the
        psi_K buffer (10^6 items, 2^21 nodes) the tree alone was 16.8 MB in every checkpoint."""
        filled = self.capacity if filled is None else filled
        if not 0 <= filled <= self.capacity:
            raise ReplayError(f"sum tree: {filled} filled leaves outside [0, {self.capacity}]")
        # A view, like the buffer's arrays: LearnerCore.checkpoint_state copies the whole state.
        return {"capacity": self.capacity, "leaves": self.nodes[self.leaves : self.leaves + filled]}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Leaves as :meth:`state_dict` saved them (or all nodes, as checkpoints before the
        leaves-only layout held them)."""
        if state["capacity"] != self.capacity:
            raise ReplayError(
                f"sum tree of capacity {state['capacity']} loaded into one of {self.capacity}"
            )
        if "nodes" in state:
            self.nodes[:] = state["nodes"]
            return
        leaves = np.asarray(state["leaves"], dtype=np.float64)
        if leaves.ndim != 1 or leaves.size > self.capacity:
            raise ReplayError(
                f"sum tree: {leaves.shape} leaves do not fit a capacity of {self.capacity}"
            )
        self.nodes[:] = 0.0
        self.nodes[self.leaves : self.leaves + leaves.size] = leaves
        width = self.leaves // 2
        while width >= 1:  # each level from the one below: the additions of set()
            below = self.nodes[2 * width : 4 * width]
            self.nodes[width : 2 * width] = below[0::2] + below[1::2]
            width //= 2


@dataclass
class Batch:
    """Sampled transitions (numpy) with their buffer indices and importance weights."""

    index: NDArray[np.intp]
    state: NDArray[np.float32]
    """(m, 3) raw features."""
    action: NDArray[np.float32]
    """(m,) executed a_norm."""
    reward: NDArray[np.float32]
    next_state: NDArray[np.float32]
    terminated: NDArray[np.float32]
    weight: NDArray[np.float32]
    """(m,) importance weights (P_i / P_min)^(-beta), each <= 1."""
    adds: int = 0
    """The buffer's add count when it was sampled (to spot items overwritten since)."""


class PrioritizedReplay:
    """Ring buffer of transitions (raw features, a_norm, r, raw features', terminated)."""

    def __init__(self, capacity: int, alpha: float, priority_eps: float) -> None:
        self.capacity = capacity
        self.alpha = alpha
        self.priority_eps = priority_eps
        self.tree = SumTree(capacity)
        self.state = np.zeros((capacity, 3), dtype=np.float32)
        self.action = np.zeros(capacity, dtype=np.float32)
        self.reward = np.zeros(capacity, dtype=np.float32)
        self.next_state = np.zeros((capacity, 3), dtype=np.float32)
        self.terminated = np.zeros(capacity, dtype=np.float32)
        self.size = 0
        self.position = 0
        self.max_priority = 1.0
        """Largest raw priority set so far: the priority of new items."""
        self.adds = 0
        """Items added since this buffer was made or loaded (not saved)."""

    def __len__(self) -> int:
        return self.size

    def add(
        self,
        state: tuple[float, float, float],
        action: float,
        reward: float,
        next_state: tuple[float, float, float],
        terminated: bool,
    ) -> int:
        """Store one transition at the current maximum priority; returns its index.

        Raises:
            ReplayError: a value is NaN or infinite (it would reach every network through the
                targets and priorities); nothing is stored.
        """
        values = (*state, action, reward, *next_state)
        # Checked as stored (float32): a reward of 1e300 is finite here and inf there, and it failed
        # every gradient step whose batch held it, for as long as it stayed in the buffer.
        if not all(math.isfinite(value) and abs(value) <= FLOAT32_MAX for value in values):
            raise ReplayError(
                f"transition not stored: state {state}, action {action}, reward {reward}, "
                f"next state {next_state} holds a value that is not finite in float32"
            )
        i = self.position
        self.state[i] = state
        self.action[i] = action
        self.reward[i] = reward
        self.next_state[i] = next_state
        self.terminated[i] = float(terminated)
        self.tree.set(i, self.max_priority**self.alpha)
        self.position = (i + 1) % self.capacity
        self.size = min(self.size + 1, self.capacity)
        self.adds += 1
        return i

    def sample(self, batch_size: int, beta: float, rng: np.random.Generator) -> Batch:
        """Draw ``batch_size`` items with probability p^alpha / sum p^alpha (with replacement)."""
        if self.size == 0:
            raise ReplayError("cannot sample from an empty replay buffer")
        total = self.tree.total
        index = self.tree.find(rng.uniform(0.0, total, batch_size))
        # Rounding can walk past the last stored leaf into the empty (zero) ones.
        index = np.minimum(index, self.size - 1)
        probability = self.tree.get(index) / total
        p_min = self.tree.stored_min(self.size) / total
        weight = (probability / p_min) ** (-beta)
        return Batch(
            index=index,
            state=self.state[index],
            action=self.action[index],
            reward=self.reward[index],
            next_state=self.next_state[index],
            terminated=self.terminated[index],
            weight=weight.astype(np.float32),
            adds=self.adds,
        )

    def update_priorities(
        self,
        index: NDArray[np.intp],
        td_error: NDArray[np.float64],
        sampled_at: int | None = None,
    ) -> None:
        """Raw priority |y - Q| + eps for the sampled items.

        ``sampled_at``: the batch's ``adds``. Items that were overwritten by adds since then (a
        learner thread that stores transitions while another takes a gradient step) keep the
        priority they were stored with: the error belongs to the item they replaced.
        """
        priority = np.abs(np.asarray(td_error, dtype=np.float64)) + self.priority_eps
        index = np.asarray(index)
        if sampled_at is not None and self.adds != sampled_at:
            since = self.adds - sampled_at
            # Adds since the sample wrote the `since` slots before the current position.
            first = (self.position - min(since, self.capacity)) % self.capacity
            keep = (index - first) % self.capacity >= since
            index, priority = index[keep], priority[keep]
            if index.size == 0:
                return
        self.tree.set(index, priority**self.alpha)
        self.max_priority = max(self.max_priority, float(priority.max()))

    def state_dict(self) -> dict[str, Any]:
        """Views of the filled part, as ``nn.Module.state_dict`` returns references: copy it
        (:meth:`LearnerCore.checkpoint_state` deep-copies the core's state once) before the
        buffer changes."""
        return {
            "tree": self.tree.state_dict(self.size),  # leaves past size were never set
            "state": self.state[: self.size],
            "action": self.action[: self.size],
            "reward": self.reward[: self.size],
            "next_state": self.next_state[: self.size],
            "terminated": self.terminated[: self.size],
            "size": self.size,
            "position": self.position,
            "max_priority": self.max_priority,
        }

    def load_state_dict(self, state: dict[str, Any]) -> int:
        """The buffer :meth:`state_dict` saved, without the transitions that hold a value that is
        not finite, or a priority that is not positive and finite (learners before :meth:`add`
        checked its values stored them, and each one failed every gradient step whose batch held
        it). The rest keep their priorities and their order of age.

        Returns:
            How many transitions were left out.
        """
        n, position = state["size"], state["position"]
        for name, value in (("size", n), ("position", position)):
            if not isinstance(value, (int, np.integer)) or isinstance(value, bool):
                raise ReplayError(f"replay {name} {value!r} is not a whole number")
        # A ring that is not full was filled from 0 and writes next at its size; a full one
        # writes next over its oldest item. Anything else leaves items inside the filled part
        # that were never written (priority 0: every importance weight 0) or writes outside it.
        if not 0 <= n <= self.capacity:
            raise ReplayError(f"replay size {n} is outside 0..{self.capacity} (its capacity)")
        if n < self.capacity and position != n:
            raise ReplayError(f"replay position {position} of a ring of {n} not full is not {n}")
        if not 0 <= position < self.capacity:
            raise ReplayError(f"replay position {position} is outside 0..{self.capacity - 1}")
        self.tree.load_state_dict(state["tree"])
        for name in ("state", "action", "reward", "next_state", "terminated"):
            getattr(self, name)[:n] = state[name]
        self.size = n
        self.position = position
        self.max_priority = state["max_priority"]
        leaves = self.tree.get(np.arange(n))
        good = (
            np.isfinite(self.state[:n]).all(axis=1)
            & np.isfinite(self.next_state[:n]).all(axis=1)
            & np.isfinite(self.action[:n])
            & np.isfinite(self.reward[:n])
            & np.isfinite(self.terminated[:n])
            & np.isfinite(leaves)
            & (leaves > 0.0)
        )
        dropped = int(n - np.count_nonzero(good))
        if dropped:
            # Oldest first: a full ring's oldest item is at ``position``; the new ring is not
            # full, and fills and then overwrites from the oldest on, as before.
            age = np.arange(n) if n < self.capacity else (self.position + np.arange(n)) % n
            kept = age[good[age]]
            for name in ("state", "action", "reward", "next_state", "terminated"):
                array = getattr(self, name)
                array[: kept.size] = array[kept]
                array[kept.size : n] = 0.0
            self.tree.load_state_dict({"capacity": self.capacity, "leaves": leaves[kept]})
            self.size = int(kept.size)
            self.position = self.size % self.capacity
        if not (math.isfinite(self.max_priority) and self.max_priority > 0.0):
            # Raw priority from the stored p^alpha; 1.0 (the fresh buffer's) when none is left,
            # or when alpha = 0 made every stored leaf 1.
            stored = self.tree.get(np.arange(self.size))
            if self.size and self.alpha > 0.0:
                self.max_priority = float(stored.max() ** (1.0 / self.alpha))
            else:
                self.max_priority = 1.0
        return dropped


def beta_at(update: int, start: float, end: float, steps: int) -> float:
    """Importance exponent after ``update`` gradient steps: linear from start to end."""
    return start + (end - start) * min(1.0, update / steps)

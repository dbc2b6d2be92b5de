"""An independent validity checker for box worlds, in plain numpy.

Written from the scenario definition alone (bounds, closed axis-aligned boxes, the collision-checking
resolution as a fraction of the space's maximum extent); it shares no code with the C++ core's
``BoxWorld`` nor with :func:`lit_planner.scenarios.is_valid`, so a bug in either shows up as a
disagreement. The cross-check (:mod:`lit_planner.ompl2.crosscheck`) wraps it in OMPL 2.0.1's
``StateValidityChecker`` and ``MotionValidator`` interfaces; it imports nothing of OMPL itself, so
the parent process can test it against ``lit_core``.

Semantics:

- A point is valid iff it lies inside the closed bounds and outside every closed box (a point on a
  box face collides). NaN coordinates are invalid.
- A motion ``a -> b`` is valid under OMPL's discrete rule (``DiscreteMotionValidator``): with
  ``nd = ceil(|b - a| / (resolution * max_extent))`` the states ``a + (j / nd)(b - a)`` for
  ``j = 1 .. nd`` are valid (``a`` itself is assumed valid, as OMPL does). :meth:`motion_valid`
  decides this exactly without enumerating the states: the parameters where the segment is inside a
  box form one closed interval per box (the slab method), and the motion collides iff some ``j / nd``
  falls into one of them.
- :meth:`check_path` is the dense check: every segment sampled ``refinement`` times finer than the
  resolution, both endpoints included, every sample tested.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

DENSE_REFINEMENT = 4
""":meth:`BoxWorldChecker.check_path` samples this many times finer than the resolution."""
ENDPOINT_TOLERANCE = 1e-9
"""Distance within which a path counts as starting at the start and ending at the goal."""
_CHUNK_POINTS = 1 << 15  # samples generated at once by the dense check


@dataclass(frozen=True)
class BoxWorldChecker:
    """Validity of points, motions and paths in a box world (see the module docstring)."""

    lower: FloatArray
    """Lower bounds of the space, shape (n,)."""
    upper: FloatArray
    """Upper bounds of the space, shape (n,)."""
    box_lower: FloatArray
    """Lower corners of the closed boxes, shape (m, n)."""
    box_upper: FloatArray
    """Upper corners of the closed boxes, shape (m, n)."""
    resolution: float
    """Collision-checking resolution as a fraction of :attr:`max_extent` (OMPL's convention)."""

    @classmethod
    def from_definition(cls, definition: Mapping[str, Any]) -> BoxWorldChecker:
        """Build from a scenario's ``to_dict()`` (keys ``lower``, ``upper``, ``boxes``, ``resolution``).

        ``boxes`` is an (m, 2, n) nested list: ``[:, 0]`` lower and ``[:, 1]`` upper corners.
        """
        lower = np.asarray(definition["lower"], dtype=np.float64)
        upper = np.asarray(definition["upper"], dtype=np.float64)
        boxes = np.asarray(definition["boxes"], dtype=np.float64).reshape(-1, 2, len(lower))
        resolution = float(definition["resolution"])
        if lower.shape != upper.shape or lower.ndim != 1 or not np.all(lower < upper):
            raise ValueError(f"bounds {lower.tolist()} .. {upper.tolist()} are not a box")
        if not (math.isfinite(resolution) and 0.0 < resolution < 1.0):
            raise ValueError(f"resolution {resolution!r} is not a fraction in (0, 1)")
        return cls(lower, upper, boxes[:, 0, :].copy(), boxes[:, 1, :].copy(), resolution)

    @property
    def dim(self) -> int:
        """Dimension n of the space."""
        return len(self.lower)

    @property
    def max_extent(self) -> float:
        """OMPL's ``getMaximumExtent`` of a real vector space: the length of its diagonal."""
        return float(np.linalg.norm(self.upper - self.lower))

    @property
    def longest_valid_segment(self) -> float:
        """Length of the longest segment OMPL leaves unchecked inside: resolution x max extent."""
        return self.resolution * self.max_extent

    def is_valid(self, points: ArrayLike) -> BoolArray:
        """Validity of each point of an array of shape (..., n)."""
        pts = np.asarray(points, dtype=np.float64)
        if pts.ndim == 0 or pts.shape[-1] != self.dim:
            raise ValueError(f"points of shape {pts.shape} do not have {self.dim} coordinates")
        flat = pts.reshape(-1, self.dim)
        inside = np.all((flat >= self.lower) & (flat <= self.upper), axis=1)  # NaN -> False
        q = flat[:, None, :]
        in_box = np.all((q >= self.box_lower) & (q <= self.box_upper), axis=2)
        return (inside & ~np.any(in_box, axis=1)).reshape(pts.shape[:-1])

    def is_state_valid(self, x: Sequence[float]) -> bool:
        """Validity of one point (the hot path of the planners' sample checks)."""
        p = np.asarray(x, dtype=np.float64)
        if not bool(np.all((p >= self.lower) & (p <= self.upper))):
            return False
        return not bool(np.any(np.all((p >= self.box_lower) & (p <= self.box_upper), axis=1)))

    def segment_count(self, a: ArrayLike, b: ArrayLike) -> int:
        """OMPL's ``validSegmentCount``: ``ceil(|b - a| / longest_valid_segment)``."""
        distance = float(np.linalg.norm(np.asarray(b, float) - np.asarray(a, float)))
        return math.ceil(distance / self.longest_valid_segment)

    def box_intervals(self, a: ArrayLike, b: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """For each box, the closed interval [t_lo, t_hi] of t in [0, 1] with a + t(b - a) in it.

        An empty intersection has ``t_lo > t_hi``.
        """
        a = np.asarray(a, dtype=np.float64)
        d = np.asarray(b, dtype=np.float64) - a
        moving = d != 0.0
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = (self.box_lower - a) / d
            t2 = (self.box_upper - a) / d
        entry = np.where(moving, np.minimum(t1, t2), -np.inf)
        leave = np.where(moving, np.maximum(t1, t2), np.inf)
        # An axis without motion: the whole segment is inside the slab or none of it is.
        outside_slab = ~moving & ((a < self.box_lower) | (a > self.box_upper))
        t_lo = np.maximum(entry.max(axis=1, initial=-np.inf), 0.0)
        t_hi = np.minimum(leave.min(axis=1, initial=np.inf), 1.0)
        t_hi = np.where(outside_slab.any(axis=1), -np.inf, t_hi)
        return t_lo, t_hi

    def motion_valid(self, a: ArrayLike, b: ArrayLike) -> bool:
        """OMPL's discrete motion check of ``a -> b`` at the resolution, decided exactly.

        ``b`` must be valid; then no state ``a + (j / nd)(b - a)``, j = 1 .. nd - 1, may lie in a
        box. Bounds need no check in between: the space is convex and both ends lie in it
        (``a`` by OMPL's assumption, ``b`` by the first test).
        """
        if not self.is_state_valid(b):
            return False
        nd = self.segment_count(a, b)
        if nd < 2 or len(self.box_lower) == 0:
            return True
        t_lo, t_hi = self.box_intervals(a, b)
        j_first = np.maximum(np.ceil(t_lo * nd), 1.0)
        j_last = np.minimum(np.floor(t_hi * nd), nd - 1.0)
        return not bool(np.any(j_first <= j_last))

    def motion_states_valid(self, a: ArrayLike, b: ArrayLike) -> bool:
        """The same decision as :meth:`motion_valid`, by enumerating OMPL's test states (slow)."""
        a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
        nd = self.segment_count(a, b)
        if not self.is_state_valid(b):
            return False
        for begin in range(1, nd, _CHUNK_POINTS):
            j = np.arange(begin, min(begin + _CHUNK_POINTS, nd))
            if not self.is_valid(a + (j / nd)[:, None] * (b - a)).all():
                return False
        return True

    def check_path(
        self,
        path: ArrayLike,
        start: ArrayLike | None = None,
        goal: ArrayLike | None = None,
        refinement: int = DENSE_REFINEMENT,
    ) -> dict[str, Any]:
        """Dense check of a path: every segment sampled ``refinement`` times finer than the resolution.

        Returns a JSON-able dict: ``valid`` (every sample valid), ``starts_at_start`` and
        ``ends_at_goal`` (None when not asked), ``first_invalid_segment``,
        ``first_invalid_point``, ``points_checked``, ``length`` (sum of segment lengths) and
        ``spacing``.
        """
        waypoints = np.asarray(path, dtype=np.float64)
        if waypoints.ndim != 2 or waypoints.shape[1] != self.dim or len(waypoints) == 0:
            raise ValueError(f"path of shape {waypoints.shape} is not (k >= 1, {self.dim})")
        spacing = self.longest_valid_segment / refinement
        lengths = np.linalg.norm(np.diff(waypoints, axis=0), axis=1)
        report: dict[str, Any] = {
            "valid": True,
            "starts_at_start": None
            if start is None
            else bool(np.linalg.norm(waypoints[0] - np.asarray(start)) <= ENDPOINT_TOLERANCE),
            "ends_at_goal": None
            if goal is None
            else bool(np.linalg.norm(waypoints[-1] - np.asarray(goal)) <= ENDPOINT_TOLERANCE),
            "first_invalid_segment": None,
            "first_invalid_point": None,
            "points_checked": 1,
            "length": float(lengths.sum()),
            "spacing": spacing,
        }
        if not self.is_state_valid(waypoints[0]):
            report.update(valid=False, first_invalid_segment=0,
                          first_invalid_point=waypoints[0].tolist())  # fmt: skip
            return report
        for index, (a, b, length) in enumerate(zip(waypoints[:-1], waypoints[1:], lengths)):
            steps = max(1, math.ceil(length / spacing))
            for begin in range(1, steps + 1, _CHUNK_POINTS):
                j = np.arange(begin, min(begin + _CHUNK_POINTS, steps + 1))
                samples = a + (j / steps)[:, None] * (b - a)
                samples[j == steps] = b
                valid = self.is_valid(samples)
                # Up to and including the first invalid sample, as scenarios.check_path counts.
                report["points_checked"] += (
                    len(samples) if valid.all() else int(np.argmin(valid)) + 1
                )
                if not valid.all():
                    report.update(valid=False, first_invalid_segment=index,
                                  first_invalid_point=samples[np.argmin(valid)].tolist())  # fmt: skip
                    return report
        return report

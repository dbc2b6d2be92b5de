"""Scenario registry: the single source of truth for every planning problem of the project.

Scenarios follow the Planner Developer Tools (PDT) conventions: the state space is the unit cube
[-0.5, 0.5]^n, the objective is path length, and obstacles are axis-aligned CLOSED boxes (a point
is in collision iff ``lo <= x <= hi`` on every axis). The families and their constants are data in
:data:`FAMILIES`; everything else (boxes, optima, budgets, descriptions) is derived from that table.

Names are ``<family><dim>`` (``np8``, ``wg4``, ``rr16``, ``rrd8``) with an optional instance suffix
(``rrd8/3``). Decisions beyond the design brief, each documented where it is made:

- **Seeds** of the random families: ``zlib.crc32(SEED_FORMAT.format(family, dim, instance))``, fed
  to ``np.random.Generator(np.random.PCG64(seed))``. Never Python's ``hash()`` (salted per process).
- **Box draws**: per box, the side lengths (one per axis) and then the centre (one per axis) are
  drawn; the whole box is redrawn while it contains the start or the goal.
- **RRD side ranges** for a dimension the brief does not list: those of the nearest listed
  dimension (4, 8 or 16), ties going to the smaller one.
- **Time budgets**: the paper's values at n = 4, 8, 16, piecewise-linear in n between them and flat
  beyond the ends. WG uses NP's budgets.
- **Optima** of the wall families are exact infima of the path length (the free passages are open
  sets, so the optimal route touches obstacle boundaries); random families have no known optimum.

Random instances may be unsolvable (start and goal in disconnected free space), most often for the
dense family in low dimensions. Start and goal are always valid.
"""

from __future__ import annotations

import math
import re
import sys
import zlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any, Literal, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lit_planner.errors import ScenarioError

Family = Literal["np", "wg", "rr", "rrd"]
FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

SPACE_LOWER = -0.5
"""Lower bound of every axis."""
SPACE_UPPER = 0.5
"""Upper bound of every axis."""
MIN_DIM = 2
"""Smallest supported dimension."""
MAX_DIM = 32
"""Largest supported dimension."""
LISTED_DIMS = range(2, 17)
"""Dimensions that :func:`names` lists."""
PDT_RESOLUTION = 5e-6
"""PDT's collision-checking resolution, a fraction of the space's maximum extent."""
ENDPOINT_TOLERANCE = 1e-9
"""Euclidean distance within which a path counts as starting at the start / ending at the goal."""
CHECK_REFINEMENT = 4
""":func:`check_path` samples edges this many times finer than the scenario's resolution."""
MAX_CHECK_STEPS = 1 << 40
"""Most samples :func:`check_path` takes on one segment (its exact search relies on fewer than
about 2^50: beyond that a rounded sample could pass the segment's end)."""
MAX_REDRAWS = 10_000
"""Draws per box before giving up (guards against a family that cannot avoid start and goal)."""
SEED_FORMAT = "lit_planner.scenarios/{family}/{dim}/{instance}"
"""String whose ``zlib.crc32`` is the seed of a random instance."""
DEFAULT_SCENARIO = "np8"
"""The scenario that the main job and examples run when none is given."""

PAPER_NP_BUDGETS: tuple[tuple[int, float], ...] = ((4, 0.12), (8, 0.4), (16, 0.6))
"""The paper's time budgets (dimension, seconds) for narrow passages."""
PAPER_RR_BUDGETS: tuple[tuple[int, float], ...] = ((4, 0.15), (8, 0.3), (16, 2.0))
"""The paper's time budgets (dimension, seconds) for random rectangles."""

_CHUNK_ELEMENTS = 1 << 22  # bounds the temporaries of is_valid to a few MiB
_CHUNK_POINTS = 1 << 16  # interpolated points generated at once by check_path
_NAME_PATTERN = re.compile(r"(?P<family>[a-z]+)(?P<dim>[1-9]\d*)(?:/(?P<instance>0|[1-9]\d*))?")
"""A scenario name; numbers without leading zeros (np04 was np4 under another name: past the
duplicate checks, twice in a training distribution). Instance 0 has a second name, ``np8/0``;
training distributions and ``lit bench`` take no ``/instance``, so it cannot come in twice there."""


@dataclass(frozen=True)
class WallLayout:
    """A wall across ``x0`` spanning every axis but ``x1``, solid over the closed ``x1`` blocks."""

    x0: tuple[float, float]
    """Closed interval of ``x0`` that the wall occupies."""
    x1_blocks: tuple[tuple[float, float], ...]
    """Closed ``x1`` intervals where the wall is solid; the rest of ``x1`` is free."""

    def boxes(self, dim: int) -> FloatArray:
        """One box per block, spanning the whole space along every axis but ``x0`` and ``x1``."""
        boxes = np.empty((len(self.x1_blocks), 2, dim))
        boxes[:, 0, :], boxes[:, 1, :] = SPACE_LOWER, SPACE_UPPER
        boxes[:, 0, 0], boxes[:, 1, 0] = self.x0
        boxes[:, :, 1] = self.x1_blocks
        return boxes

    def free_x1_intervals(self) -> list[tuple[float, float]]:
        """The open ``x1`` intervals through which a path can cross the wall."""
        free, edge = [], SPACE_LOWER
        for lo, hi in sorted(self.x1_blocks):
            if lo > edge:
                free.append((edge, lo))
            edge = max(edge, hi)
        if edge < SPACE_UPPER:
            free.append((edge, SPACE_UPPER))
        return free

    def describe(self, dim: int) -> str:
        """The layout in words."""
        blocks = " and ".join(f"[{lo:g}, {hi:g}]" for lo, hi in self.x1_blocks)
        return f"wall x0 in [{self.x0[0]:g}, {self.x0[1]:g}] solid over x1 in {blocks}"


@dataclass(frozen=True)
class RandomBoxes:
    """Axis-aligned boxes with uniform centres and uniform side lengths per axis."""

    count: int
    """Number of boxes."""
    side_ranges: tuple[tuple[int, float, float], ...]
    """(reference dimension, smallest side, largest side); a dimension uses its nearest entry."""

    def side_range(self, dim: int) -> tuple[float, float]:
        """Side range in ``dim`` dimensions: the nearest listed dimension's, ties to the smaller."""
        _, lo, hi = min(self.side_ranges, key=lambda entry: (abs(entry[0] - dim), entry[0]))
        return lo, hi

    def boxes(self, dim: int, seed: int, start: FloatArray, goal: FloatArray) -> FloatArray:
        """Draw the boxes reproducibly from ``seed``, redrawing any box containing start or goal."""
        rng = np.random.Generator(np.random.PCG64(seed))
        side_lo, side_hi = self.side_range(dim)
        boxes = np.empty((self.count, 2, dim))
        for index in range(self.count):
            for _ in range(MAX_REDRAWS):
                sides = rng.uniform(side_lo, side_hi, dim)
                centre = rng.uniform(SPACE_LOWER, SPACE_UPPER, dim)
                lo, hi = centre - sides / 2, centre + sides / 2
                if not any(np.all((lo <= p) & (p <= hi)) for p in (start, goal)):
                    boxes[index] = lo, hi
                    break
            else:
                raise ScenarioError(
                    f"box {index} of seed {seed} still contains start or goal "
                    f"after {MAX_REDRAWS} draws"
                )
        return boxes

    def describe(self, dim: int) -> str:
        """The layout in words."""
        lo, hi = self.side_range(dim)
        return f"{self.count} random boxes with sides U({lo:g}, {hi:g})"


@dataclass(frozen=True)
class FamilySpec:
    """Everything that defines a scenario family; :func:`get` derives instances from it."""

    family: Family
    """Short name, the prefix of scenario names."""
    title: str
    """Human-readable name."""
    start: tuple[float, float]
    """Start as (x0, every other coordinate)."""
    goal: tuple[float, float]
    """Goal as (x0, every other coordinate)."""
    obstacles: WallLayout | RandomBoxes
    """Obstacle layout."""
    time_budgets: tuple[tuple[int, float], ...]
    """(dimension, seconds) support points of the time budget."""
    resolution: float = PDT_RESOLUTION
    """Collision-checking resolution as a fraction of the space's maximum extent."""

    @property
    def randomised(self) -> bool:
        """Whether instances are random draws (several instances) or fixed (instance 0 only)."""
        return isinstance(self.obstacles, RandomBoxes)

    def time_budget(self, dim: int) -> float:
        """Budget in seconds: piecewise-linear in ``dim`` between support points, flat beyond."""
        dims, seconds = zip(*self.time_budgets, strict=True)
        return float(np.interp(dim, dims, seconds))

    def point(self, coordinates: tuple[float, float], dim: int) -> tuple[float, ...]:
        """Expand (x0, every other coordinate) to a ``dim``-dimensional point."""
        return (coordinates[0],) + (coordinates[1],) * (dim - 1)


FAMILIES: dict[str, FamilySpec] = {
    "np": FamilySpec(
        family="np",
        title="Narrow passage",
        start=(-0.2, 0.0),
        goal=(0.2, 0.0),
        obstacles=WallLayout(x0=(-0.1, 0.1), x1_blocks=((SPACE_LOWER, 0.05), (0.15, SPACE_UPPER))),
        time_budgets=PAPER_NP_BUDGETS,
    ),
    "wg": FamilySpec(
        family="wg",
        title="Wall gap",
        start=(-0.3, 0.0),
        goal=(0.3, 0.0),
        obstacles=WallLayout(x0=(-0.1, 0.1), x1_blocks=((SPACE_LOWER, 0.08), (0.12, 0.30))),
        time_budgets=PAPER_NP_BUDGETS,
    ),
    "rr": FamilySpec(
        family="rr",
        title="Random rectangles",
        start=(-0.1, -0.1),
        goal=(0.4, 0.4),
        obstacles=RandomBoxes(count=35, side_ranges=((4, 0.1, 0.2),)),
        time_budgets=PAPER_RR_BUDGETS,
    ),
    "rrd": FamilySpec(
        family="rrd",
        title="Dense random rectangles",
        start=(-0.1, -0.1),
        goal=(0.4, 0.4),
        obstacles=RandomBoxes(count=30, side_ranges=((4, 0.1, 1.0), (8, 0.1, 2.0), (16, 0.5, 1.5))),
        time_budgets=PAPER_RR_BUDGETS,
    ),
}
"""The family table: the only place where scenario constants are written down."""


@dataclass(frozen=True, eq=False)
class Scenario:
    """One planning problem: bounds, start, goal, closed obstacle boxes and benchmark settings.

    Compares by identity (it holds an array); compare :meth:`to_dict` results for equality.
    """

    name: str
    """Canonical ``<family><dim>`` name, e.g. ``rrd8``."""
    family: Family
    """Family short name, a key of :data:`FAMILIES`."""
    dim: int
    """Dimension n of the state space."""
    lower: tuple[float, ...]
    """Lower bounds of the state space."""
    upper: tuple[float, ...]
    """Upper bounds of the state space."""
    start: tuple[float, ...]
    """Start state."""
    goal: tuple[float, ...]
    """Goal state."""
    boxes: FloatArray = field(repr=False)
    """Read-only (m, 2, dim) array of closed boxes: ``[:, 0]`` lower, ``[:, 1]`` upper corners."""
    time_budget: float
    """Planning time budget in seconds."""
    resolution: float
    """Collision-checking resolution as a fraction of :attr:`max_extent` (OMPL's convention)."""
    optimal_cost: float | None
    """Infimum of the path length, or None where unknown."""
    instance: int
    """Instance number (always 0 for the fixed families)."""
    seed: int | None
    """Seed of the box draw, or None for the fixed families."""
    description: str
    """One line in words."""

    @property
    def key(self) -> str:
        """Name that :func:`get` maps back to this scenario: ``np8`` or ``rrd8/3``."""
        if self.family == CUSTOM_FAMILY:
            return self.name
        return f"{self.name}/{self.instance}" if self.family_spec.randomised else self.name

    @property
    def family_spec(self) -> FamilySpec:
        """The family table entry this scenario was derived from."""
        return FAMILIES[self.family]

    @property
    def max_extent(self) -> float:
        """OMPL's ``getMaximumExtent`` of the space: the length of its diagonal."""
        return math.dist(self.lower, self.upper)

    def to_dict(self) -> dict[str, object]:
        """JSON-able dictionary of every field (boxes as nested lists) plus :attr:`key`."""
        return {
            "name": self.name,
            "key": self.key,
            "family": self.family,
            "dim": self.dim,
            "instance": self.instance,
            "seed": self.seed,
            "lower": list(self.lower),
            "upper": list(self.upper),
            "start": list(self.start),
            "goal": list(self.goal),
            "boxes": self.boxes.tolist(),
            "time_budget": self.time_budget,
            "resolution": self.resolution,
            "optimal_cost": self.optimal_cost,
            "description": self.description,
        }


@dataclass(frozen=True)
class PathCheck:
    """Result of :func:`check_path`."""

    ok: bool
    """Valid, starts at the start and ends at the goal."""
    valid: bool
    """Every checked point lies inside the bounds and outside every box (in a registry scenario
    but for a corner clip between the planners' own check points, see :func:`check_path`), and
    no segment passes through a box from one face to the opposite one (an exact test, which finds
    a box thinner than the spacing)."""
    starts_at_start: bool
    """The first waypoint is within :data:`ENDPOINT_TOLERANCE` of the start."""
    ends_at_goal: bool
    """The last waypoint is within :data:`ENDPOINT_TOLERANCE` of the goal."""
    first_invalid_index: int | None
    """Index i of the segment ``path[i] -> path[i + 1]`` holding the first invalid point."""
    first_invalid_point: tuple[float, ...] | None
    """The first invalid point along the path."""
    points_checked: int
    """Number of points tested: every sample of a valid path; up to and including the first
    invalid one otherwise."""
    cost: float
    """Path length: the sum of the Euclidean segment lengths."""
    spacing: float
    """Largest distance between consecutive checked points on a segment."""


CUSTOM_FAMILY = "custom"
"""Family of worlds given explicitly (:func:`custom`), not drawn from :data:`FAMILIES`."""
DEFAULT_CUSTOM_RESOLUTION = 0.001
"""Collision-checking resolution of a custom world that does not give one (fraction of the
maximum extent)."""


def from_world(
    world: Mapping[str, Any],
    start: Sequence[float],
    goal: Sequence[float],
    *,
    time_budget: float = 1.0,
) -> Scenario:
    """:func:`custom` from a world as the messages write it (a PlanRequest's ``world``, an
    EpisodeSummary's): ``lower``, ``upper``, ``boxes`` as ``{"lower", "upper"}`` objects and an
    optional ``resolution``.

    Raises:
        ScenarioError: as :func:`custom`.
    """
    return custom(
        world["lower"],
        world["upper"],
        [(box["lower"], box["upper"]) for box in world["boxes"]],
        start,
        goal,
        time_budget=time_budget,
        resolution=world.get("resolution"),
    )


def refuse_duplicates(label: str, names: Sequence[str]) -> None:
    """Raise :class:`ScenarioError` naming the ``label`` names (scenario keys, planners) given
    more than once: a benchmark would run them twice and pool both runs."""
    duplicates = sorted({name for name in names if list(names).count(name) > 1})
    if duplicates:
        raise ScenarioError(f"{label} given twice: {', '.join(duplicates)}")


def custom(
    lower: Sequence[float],
    upper: Sequence[float],
    boxes: Sequence[tuple[Sequence[float], Sequence[float]]],
    start: Sequence[float],
    goal: Sequence[float],
    *,
    time_budget: float = 1.0,
    resolution: float | None = None,
) -> Scenario:
    """A scenario from an explicit world: bounds, closed axis-aligned boxes (lower, upper
    corners), start and goal. Named ``custom<n>``; no known optimum.

    Raises:
        ScenarioError: inconsistent dimensions, a lower bound not below its upper bound, a box
            with a lower corner above its upper one, a non-finite bound or box corner, a
            dimension outside ``MIN_DIM..MAX_DIM``, a time budget that is not a finite positive
            number, a resolution that does not fit the world's extent, start and goal within
            ``ENDPOINT_TOLERANCE`` of each other. (A start or goal outside the
            bounds, inside a box or with a non-finite coordinate is not refused here: planning
            it ends with ``invalid_start`` / ``invalid_goal`` and a message, as for any planner.)
    """
    lower, upper = _numbers("lower", lower), _numbers("upper", upper)
    start, goal = _numbers("start", start, part="start"), _numbers("goal", goal, part="goal")
    time_budget = _number("time budget", time_budget, part="time")
    dim = len(lower)
    if not MIN_DIM <= dim <= MAX_DIM:
        raise ScenarioError(f"world dimension {dim} outside {MIN_DIM}..{MAX_DIM}")
    for label, vector in (("upper", upper), ("start", start), ("goal", goal)):
        if len(vector) != dim:
            raise ScenarioError(
                f"{label} has {len(vector)} coordinates; the world has {dim} dimensions (its "
                f"lower bound's length)",
                part=None if label == "upper" else label,
            )
    corners = _box_corners(boxes, dim)
    values = np.concatenate([np.asarray(lower, float), np.asarray(upper, float), corners.ravel()])
    if not np.all(np.isfinite(values)):
        raise ScenarioError("the world has a non-finite coordinate")
    if np.any(np.asarray(lower, float) >= np.asarray(upper, float)):
        raise ScenarioError("every lower bound must be below its upper bound")
    bad = np.flatnonzero(np.any(corners[:, 0] > corners[:, 1], axis=1))
    if len(bad):
        raise ScenarioError(f"box {bad[0]} has a lower corner above its upper corner")
    if not (math.isfinite(time_budget) and time_budget > 0):
        raise ScenarioError(
            f"time budget must be a finite positive number of seconds, got {time_budget}",
            part="time",
        )
    resolution = (
        DEFAULT_CUSTOM_RESOLUTION if resolution is None else _number("resolution", resolution)
    )
    _check_extent(np.asarray(lower, float), np.asarray(upper, float), resolution)
    with np.errstate(under="ignore", over="ignore"):
        separation = float(np.linalg.norm(np.asarray(goal, float) - np.asarray(start, float)))
        size = float(np.max(np.asarray(upper, float) - np.asarray(lower, float)))
    # ENDPOINT_TOLERANCE counts as reaching a point; in a world smaller than a metre, that share
    # of its size (a world 1e-10 across is not all one point).
    tolerance = min(ENDPOINT_TOLERANCE, ENDPOINT_TOLERANCE * size)
    if separation <= tolerance:  # OMPL's AIT* aborts the process on a zero distance
        raise ScenarioError(
            f"start and goal are the same state ({separation:.3g} apart, within the "
            f"{tolerance:g} that counts as reaching a point): there is nothing to plan",
            part="goal",
        )
    corners.setflags(write=False)
    return Scenario(
        name=f"{CUSTOM_FAMILY}{dim}",
        family=CUSTOM_FAMILY,
        dim=dim,
        lower=tuple(float(x) for x in lower),
        upper=tuple(float(x) for x in upper),
        start=tuple(float(x) for x in start),
        goal=tuple(float(x) for x in goal),
        boxes=corners,
        time_budget=float(time_budget),
        resolution=resolution,
        optimal_cost=None,
        instance=0,
        seed=None,
        description=f"explicit world in R^{dim} with {len(boxes)} boxes",
    )


def _shown(value: Any) -> str:
    """``lit_msgs_json.codec.shown``, imported only for an error (this module is numpy only:
    the OMPL 2.0.1 worker imports it)."""
    from lit_msgs_json.codec import shown

    return shown(value)


def _number(label: str, value: Any, *, part: str | None = None) -> float:
    """``value`` as a float, or a ScenarioError naming ``label`` (float() said only "could not
    convert string to float: 'abc'", without saying which argument)."""
    if isinstance(value, (str, bytes)):  # float("1e3") would take text
        raise ScenarioError(f"{label} must be a number, got {_shown(value)}", part=part)
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ScenarioError(f"{label} must be a number, got {_shown(value)}", part=part) from None


def _sequence(label: str, value: Any, *, part: str | None = None) -> Sequence[Any]:
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__"):
        raise ScenarioError(f"{label} must be a sequence, got {_shown(value)}", part=part)
    return value


def _numbers(label: str, value: Any, *, part: str | None = None) -> list[float]:
    """``value`` as a list of floats, or a ScenarioError naming ``label`` and the entry."""
    entries = _sequence(label, value, part=part)
    array = _numeric_array(entries)
    if array is not None and array.ndim == 1:
        return array.tolist()
    return [_number(f"{label}[{i}]", x, part=part) for i, x in enumerate(entries)]


def _numeric_array(entries: Sequence[Any]) -> NDArray[np.float64] | None:
    """``entries`` as a new float array when they are all numbers (no text: numpy would convert
    "1e3"), else None."""
    try:
        array = np.asarray(entries)
    except (TypeError, ValueError):  # ragged
        return None
    return array.astype(float) if array.dtype.kind in "biuf" else None


def _box_corners(boxes: Any, dim: int) -> NDArray[np.float64]:
    """The boxes as an array (box, lower/upper, axis); a ScenarioError names the first box that
    is not a pair of ``dim`` numbers each."""
    entries = _sequence("boxes", boxes)
    corners = _numeric_array(entries) if len(entries) else np.zeros((0, 2, dim))
    if corners is not None and corners.shape == (len(entries), 2, dim):
        return corners
    for i, box in enumerate(entries):  # the first box at fault, with what is wrong with it
        if isinstance(box, (str, bytes)) or not hasattr(box, "__len__") or len(box) != 2:
            raise ScenarioError(
                f"box {i} must be a (lower corner, upper corner) pair, got {_shown(box)}"
            )
        for corner, side in zip(box, ("lower", "upper")):
            if len(_numbers(f"box {i}'s {side} corner", corner)) != dim:
                raise ScenarioError(f"box {i} does not have {dim} coordinates per corner")
    raise ScenarioError(f"the boxes must be pairs of corners with {dim} coordinates each")


MIN_RESOLUTION = 1e-6
"""The finest collision-checking resolution a custom world may ask for (PDT's default is 5e-6): an
edge's full check holds one interval per check, and a world with 1e-10 ran the planner node out of
memory on a single edge."""


def _check_extent(lower: np.ndarray, upper: np.ndarray, resolution: float) -> None:
    """The space's sizes must keep the planner's arithmetic finite: its diagonal, its measure
    (the informed-set ratios divide by it) and the collision-check spacing (resolution x the
    largest size, which LIT* steps by, must be positive; resolution x the diagonal, OMPL's
    longest valid segment, at least the machine epsilon)."""
    with np.errstate(over="ignore", under="ignore"):
        extent = upper - lower
        diagonal = float(np.sqrt(np.sum(np.square(extent))))
        measure = float(np.prod(extent))
    if not (np.all(np.isfinite(extent)) and math.isfinite(diagonal) and math.isfinite(measure)):
        raise ScenarioError(
            f"the world is too large: its size ({float(np.max(extent)):.3g} along its longest "
            "axis) makes the diagonal or the volume overflow double precision"
        )
    if not (math.isfinite(resolution) and MIN_RESOLUTION <= resolution < 1):
        raise ScenarioError(  # 1 itself passed here and failed in the core with a bare ValueError
            f"resolution must be in [{MIN_RESOLUTION:g}, 1), got {resolution} (a finer one makes "
            "one edge check take seconds and gigabytes)"
        )
    if measure <= 0 or not resolution * float(np.max(extent)) > 0:
        raise ScenarioError(
            f"the world is too small: its volume or its collision-check spacing underflows "
            f"(smallest size {float(np.min(extent)):.3g})"
        )
    if resolution * diagonal < sys.float_info.epsilon:
        # OMPL's set-up refuses it ("The longest valid segment ... must be positive"): every
        # planner failed with that RuntimeError, which the planner node answered as internal.
        raise ScenarioError(
            f"the world is too small: its collision-check spacing (resolution x diagonal, "
            f"{resolution * diagonal:.3g}) is below OMPL's smallest, the machine epsilon "
            f"{sys.float_info.epsilon:.3g}"
        )


def seed_for(family: str, dim: int, instance: int) -> int:
    """Seed of a random instance: CRC-32 of :data:`SEED_FORMAT` filled in (stable across runs)."""
    text = SEED_FORMAT.format(family=family, dim=dim, instance=instance)
    return zlib.crc32(text.encode("ascii"))


def split_names(text: str) -> list[str]:
    """The names of a comma-separated option (``"np4, rrd8,"`` -> ``["np4", "rrd8"]``)."""
    return [name.strip() for name in text.split(",") if name.strip()]


def names() -> list[str]:
    """Canonical names of every family in every dimension of :data:`LISTED_DIMS`."""
    return [f"{family}{dim}" for family in FAMILIES for dim in LISTED_DIMS]


def get(name: str, instance: int | None = None, *, suffix: bool = True) -> Scenario:
    """The scenario called ``name`` (``np8``, ``rrd8``, ``rrd8/3``); instance defaults to 0.
    ``suffix=False``: for a caller that takes the instance separately (``lit bench``), whose
    error for an unknown name then gives no ``rrd8/3`` example.

    Raises:
        ScenarioError: unknown family, malformed name, dimension outside ``MIN_DIM..MAX_DIM``, an
            instance other than 0 for a fixed family, or a suffix contradicting ``instance``.
    """
    if not isinstance(name, str):  # re's TypeError named no input
        raise ScenarioError(
            f"a scenario is a name such as {DEFAULT_SCENARIO!r} or a Scenario, not "
            f"{type(name).__name__} {name!r}"
        )
    match = _NAME_PATTERN.fullmatch(name)
    if match is None or match["family"] not in FAMILIES:
        raise ScenarioError(
            f"unknown scenario {name!r}: expected <family><dim>{'[/<instance>]' if suffix else ''} "
            "with family one of "
            f"{sorted(FAMILIES)} and numbers without leading zeros, e.g. {DEFAULT_SCENARIO!r} or "
            + ("'rrd8/3'" if suffix else "'rrd8'")
        )
    family, dim = match["family"], int(match["dim"])
    if not MIN_DIM <= dim <= MAX_DIM:
        raise ScenarioError(f"scenario {name!r}: dimension {dim} outside {MIN_DIM}..{MAX_DIM}")
    suffix = None if match["instance"] is None else int(match["instance"])
    if suffix is not None and instance is not None and suffix != instance:
        raise ScenarioError(
            f"scenario {name!r} names instance {suffix} but instance={instance} was given"
        )
    chosen = next((i for i in (suffix, instance) if i is not None), 0)
    if chosen < 0:
        raise ScenarioError(f"scenario {name!r}: instance {chosen} is negative")
    if chosen != 0 and not FAMILIES[family].randomised:
        raise ScenarioError(
            f"scenario {name!r}: family {family!r} has only instance 0, not {chosen}"
        )
    return _build(family, dim, chosen)


@lru_cache(maxsize=256)
def _build(family: str, dim: int, instance: int) -> Scenario:
    spec = FAMILIES[family]
    start, goal = spec.point(spec.start, dim), spec.point(spec.goal, dim)
    layout = spec.obstacles
    seed: int | None = None
    optimal_cost: float | None = None
    if isinstance(layout, RandomBoxes):
        seed = seed_for(family, dim, instance)
        boxes = layout.boxes(dim, seed, np.array(start), np.array(goal))
        label = f"{spec.title} ({family}) in R^{dim}, instance {instance} (seed {seed})"
    else:
        boxes = layout.boxes(dim)
        optimal_cost = min(_polyline_length(route) for route in _wall_routes(spec, dim))
        label = f"{spec.title} ({family}) in R^{dim}"
    boxes.flags.writeable = False
    return Scenario(
        name=f"{family}{dim}",
        family=cast(Family, family),
        dim=dim,
        lower=(SPACE_LOWER,) * dim,
        upper=(SPACE_UPPER,) * dim,
        start=start,
        goal=goal,
        boxes=boxes,
        time_budget=spec.time_budget(dim),
        resolution=spec.resolution,
        optimal_cost=optimal_cost,
        instance=instance,
        seed=seed,
        description=f"{label}: {layout.describe(dim)}; start {_short(spec.start)}, "
        f"goal {_short(spec.goal)}"
        + ("" if optimal_cost is None else f"; optimal cost {optimal_cost:.4f}"),
    )


def _wall_routes(spec: FamilySpec, dim: int) -> list[FloatArray]:
    """The shortest route through each free x1 interval (start and goal differ only in x0).

    Each route bends at the wall's two x0 faces at the x1 closest to the start's; any path through
    that interval is at least as long, so the shortest route gives the optimum (an infimum: it
    touches the closed blocks).
    """
    layout = cast(WallLayout, spec.obstacles)
    start, goal = np.array(spec.point(spec.start, dim)), np.array(spec.point(spec.goal, dim))
    routes = []
    for lo, hi in layout.free_x1_intervals():
        corners = np.array([start, goal])
        corners[:, 0] = layout.x0
        corners[:, 1] = min(max(start[1], lo), hi)
        routes.append(np.vstack([start, corners, goal]))
    return routes


def _short(coordinates: tuple[float, float]) -> str:
    return f"({coordinates[0]:g}, {coordinates[1]:g}, ...)"


def _polyline_length(path: FloatArray) -> float:
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())


def is_valid(scenario: Scenario, points: ArrayLike) -> BoolArray:
    """Which points lie inside the (closed) bounds and outside every (closed) box.

    Args:
        scenario: the scenario to check against.
        points: array of shape (..., dim); NaN coordinates count as invalid.

    Returns:
        Boolean array of shape ``points.shape[:-1]``.

    Raises:
        ScenarioError: the last axis of ``points`` is not ``scenario.dim`` long.
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim == 0 or pts.shape[-1] != scenario.dim:
        raise ScenarioError(
            f"points of shape {pts.shape} do not fit scenario {scenario.key!r}: "
            f"the last axis must have length {scenario.dim}"
        )
    flat = pts.reshape(-1, scenario.dim)
    lower, upper = np.array(scenario.lower), np.array(scenario.upper)
    box_lo, box_hi = scenario.boxes[None, :, 0, :], scenario.boxes[None, :, 1, :]
    chunk = max(1, _CHUNK_ELEMENTS // (max(1, len(scenario.boxes)) * scenario.dim))
    result = np.empty(len(flat), dtype=bool)
    for begin in range(0, len(flat), chunk):
        p = flat[begin : begin + chunk]
        inside = np.all((lower <= p) & (p <= upper), axis=1)
        q = p[:, None, :]
        hit = np.any(np.all((box_lo <= q) & (q <= box_hi), axis=2), axis=1)
        result[begin : begin + chunk] = inside & ~hit
    return result.reshape(pts.shape[:-1])


def check_path(scenario: Scenario, path: ArrayLike, resolution: float | None = None) -> PathCheck:
    """Independent dense re-check of a path, in numpy only.

    Every segment is sampled at ``resolution * max_extent / CHECK_REFINEMENT`` or finer, both
    endpoints included, and each sample is tested with :func:`is_valid`. The check stops at the
    first invalid sample, with one exception in the registry's scenarios, whose edges every
    planner checks at ``ceil(length / (resolution * max_extent))`` equal steps: a segment that
    meets boxes only where it clips an edge or corner (in across one axis, out across another),
    between two of those check points, passes (:func:`_only_clips_between_checks`; a path refined
    for long hugs the obstacles' corners, and such a clip passes the planners' own checks). A path
    whose samples are all valid is then tested segment by segment
    against every box exactly for a segment that passes through a box (a wall thinner than the
    spacing slips between samples; :func:`_first_box_crossing`); such a crossing gives the segment
    and the middle of its stretch inside the box as the first invalid one.

    Args:
        scenario: the scenario the path claims to solve.
        path: waypoints, shape (k, dim) with k >= 1.
        resolution: fraction of the maximum extent; the scenario's own resolution when None.

    Raises:
        ScenarioError: malformed path (shape, non-finite waypoint) or resolution.
    """
    waypoints = np.asarray(path, dtype=np.float64)
    if waypoints.ndim != 2 or waypoints.shape[1] != scenario.dim or len(waypoints) == 0:
        raise ScenarioError(
            f"path of shape {waypoints.shape} does not fit scenario {scenario.key!r}: "
            f"expected (k >= 1, {scenario.dim})"
        )
    non_finite = np.flatnonzero(~np.all(np.isfinite(waypoints), axis=1))
    if len(non_finite):
        raise ScenarioError(
            f"path waypoint {non_finite[0]} is not finite: {waypoints[non_finite[0]]}"
        )
    fraction = scenario.resolution if resolution is None else resolution
    if not (math.isfinite(fraction) and fraction > 0):
        raise ScenarioError(f"resolution must be a positive finite fraction, got {fraction!r}")
    spacing = fraction * scenario.max_extent / CHECK_REFINEMENT
    # The planners check a registry scenario's edges at points at most this far apart (a custom
    # world's exactly: no clip passes there).
    check_spacing = 0.0 if scenario.family == CUSTOM_FAMILY else fraction * scenario.max_extent
    lengths = np.linalg.norm(np.diff(waypoints, axis=0), axis=1)
    starts = bool(np.linalg.norm(waypoints[0] - scenario.start) <= ENDPOINT_TOLERANCE)
    ends = bool(np.linalg.norm(waypoints[-1] - scenario.goal) <= ENDPOINT_TOLERANCE)

    def result(
        checked: int, index: int | None = None, point: FloatArray | None = None
    ) -> PathCheck:
        valid = index is None
        return PathCheck(
            ok=valid and starts and ends,
            valid=valid,
            starts_at_start=starts,
            ends_at_goal=ends,
            first_invalid_index=index,
            first_invalid_point=None if point is None else tuple(float(x) for x in point),
            points_checked=checked,
            cost=float(lengths.sum()),
            spacing=spacing,
        )

    if not is_valid(scenario, waypoints[0]):
        return result(1, 0, waypoints[0])
    lower, upper = np.array(scenario.lower), np.array(scenario.upper)
    checked = 1
    for index, (a, b, length) in enumerate(
        zip(waypoints[:-1], waypoints[1:], lengths, strict=True)
    ):
        steps = max(1, math.ceil(length / spacing))
        if steps > MAX_CHECK_STEPS:
            raise ScenarioError(
                f"segment {index} of length {length:g} would take {steps} samples at spacing "
                f"{spacing:g}, more than {MAX_CHECK_STEPS}: the resolution is too fine"
            )
        if np.all((lower <= b) & (b <= upper)):  # a is in bounds too: so is every sample
            first = _first_sample_in_a_box(scenario, a, b, steps)
        else:  # leaves the bounds: sample by sample (it is invalid anyway)
            first = _first_invalid_sample(scenario, a, b, steps)
        if first is not None and not (
            check_spacing > 0.0 and _only_clips_between_checks(scenario, a, b, check_spacing)
        ):
            return result(checked + first, index, _samples(a, b, steps, np.array([first]))[0])
        checked += steps
    # Samples miss a box thinner than their spacing (a custom world's coarse resolution, a box of
    # zero thickness): every segment is also tested against every box exactly.
    crossing = _first_box_crossing(scenario, waypoints)
    if crossing is not None:
        return result(checked, *crossing)
    return result(checked)


def _first_box_crossing(scenario: Scenario, waypoints: FloatArray) -> tuple[int, FloatArray] | None:
    """The first segment ``waypoints[i] -> waypoints[i + 1]`` that passes through a (closed)
    box, exactly, with the middle of its stretch inside; None when none does.

    Slab test: the parameter interval in which each coordinate lies within the box's, intersected
    over the axes and with [0, 1]. *Through* means the stretch begins and ends on the same axis's
    bounds: the segment crosses the box from one face to the opposite one (a wall thinner than the
    samples' spacing, or of zero thickness). One that clips an edge or corner between samples
    (in across one axis, out across another) is not reported: every planner checks a registry
    scenario's edges at its resolution and clips corners by up to it (a custom world's edges are
    checked exactly, so its paths clip nothing)."""
    if len(waypoints) < 2 or len(scenario.boxes) == 0:
        return None
    chunk = max(1, _CHUNK_ELEMENTS // (len(scenario.boxes) * scenario.dim))
    for begin in range(0, len(waypoints) - 1, chunk):
        a = waypoints[begin : begin + chunk + 1][:-1][:, None, :]
        d = np.diff(waypoints[begin : begin + chunk + 1], axis=0)[:, None, :]
        first, last, through = _box_stretches(scenario, a, d)
        hits = np.argwhere((first <= last) & through)
        if len(hits):
            segment, box = hits[0]  # argwhere is row-major: the first segment's first box
            middle = (first[segment, box] + last[segment, box]) / 2.0
            point = a[segment, 0] + middle * d[segment, 0]
            return begin + int(segment), point
    return None


def _box_stretches(
    scenario: Scenario, a: FloatArray, d: FloatArray
) -> tuple[FloatArray, FloatArray, NDArray[np.bool_]]:
    """For segments ``a -> a + d`` (shape (m, 1, dim)) and every box: the parameters ``first``
    and ``last`` (shape (m, boxes)) of the stretch inside the closed box (none where
    first > last), and whether it goes *through* (in and out across the same axis: opposite faces,
    or the one face of a box of zero thickness); a stretch that enters across one axis and leaves
    across another clips an edge or corner. Slab test: the parameter interval in which each
    coordinate lies within the box's, intersected over the axes and with [0, 1]."""
    box_lo, box_hi = scenario.boxes[None, :, 0, :], scenario.boxes[None, :, 1, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        t_lo, t_hi = (box_lo - a) / d, (box_hi - a) / d
    enter, leave = np.minimum(t_lo, t_hi), np.maximum(t_lo, t_hi)
    # An axis the segment does not move along: inside the box's slab for every t, or never.
    still = np.broadcast_to(d == 0.0, enter.shape)
    within = (box_lo <= a) & (a <= box_hi)
    enter = np.where(still, np.where(within, -np.inf, np.inf), enter)
    leave = np.where(still, np.where(within, np.inf, -np.inf), leave)
    first = np.maximum(enter.max(axis=2), 0.0)
    last = np.minimum(leave.min(axis=2), 1.0)
    return first, last, enter.argmax(axis=2) == leave.argmin(axis=2)


def _only_clips_between_checks(
    scenario: Scenario, a: FloatArray, b: FloatArray, spacing: float
) -> bool:
    """Whether the segment a→b meets boxes only in edge or corner clips (in across one axis, out
    across another) that no point of the planners' own check of it falls in: they check the
    points ``j / n`` (j = 1 … n - 1) of the segment, ``n = ceil(|b - a| / spacing)`` (OMPL's
    ``DiscreteMotionValidator``, LIT*'s ``segmentCount``), and its ends as states. False when
    it meets no box (exactly: a sample found inside one says otherwise), when an end is invalid,
    or when it goes through a box."""
    if len(scenario.boxes) == 0 or not is_valid(scenario, np.stack([a, b])).all():
        return False
    first, last, through = _box_stretches(scenario, a[None, None, :], (b - a)[None, None, :])
    meets = first[0] <= last[0]
    if not meets.any() or through[0][meets].any():
        return False
    n = max(1, math.ceil(float(np.linalg.norm(b - a)) / spacing))
    # The points' indices within each stretch, with a slack of 1e-9 of a step (about 1e-14 of a
    # length unit here) for the rounding of the planners' interpolation and of the slab test.
    lowest = np.maximum(np.ceil(first[0][meets] * n + 1e-9), 1)
    highest = np.minimum(np.floor(last[0][meets] * n - 1e-9), n - 1)
    return bool(np.all(lowest > highest))


def _samples(a: FloatArray, b: FloatArray, steps: int, j: NDArray[np.int64]) -> FloatArray:
    """Samples ``j`` (1..steps) of the segment a→b cut into ``steps``: the points check_path
    tests (sample 0 is ``a``, the previous segment's end; sample ``steps`` is ``b`` exactly, not
    a rounded interpolation)."""
    samples = a + (j / steps)[:, None] * (b - a)
    samples[j == steps] = b
    return samples


def _first_invalid_sample(
    scenario: Scenario, a: FloatArray, b: FloatArray, steps: int
) -> int | None:
    """The first of samples 1..steps that :func:`is_valid` rejects, by testing them all."""
    for begin in range(1, steps + 1, _CHUNK_POINTS):
        j = np.arange(begin, min(begin + _CHUNK_POINTS, steps + 1))
        valid = is_valid(scenario, _samples(a, b, steps, j))
        if not valid.all():
            return int(j[np.argmin(valid)])
    return None


def _first_sample_in_a_box(
    scenario: Scenario, a: FloatArray, b: FloatArray, steps: int
) -> int | None:
    """The first of samples 1..steps inside a box, for a segment whose ends are in bounds (so
    are all its samples), found without generating the samples: exactly the answer of testing
    each with :func:`is_valid`.

    Each coordinate of ``a + (j / steps) * (b - a)`` is monotone in j (floating-point rounding
    is monotone, and with at most :data:`MAX_CHECK_STEPS` steps no sample passes ``b``), so the
    samples with a coordinate inside a box's closed slab form one run of j, found by bisection on
    the sample formula itself; a box holds the samples in the intersection of its slabs' runs.
    """
    if len(scenario.boxes) == 0:
        return None
    lo, hi = scenario.boxes[:, 0, :], scenario.boxes[:, 1, :]
    # A sample lies between the segment's ends in every coordinate: other boxes hold none.
    near = np.all((lo <= np.maximum(a, b)) & (hi >= np.minimum(a, b)), axis=1)
    if not near.any():
        return None
    lo, hi = lo[near], hi[near]
    delta = b - a
    rising = np.broadcast_to(delta > 0, lo.shape)
    falling = np.broadcast_to(delta < 0, lo.shape)

    def coordinate(j: NDArray[np.int64]) -> FloatArray:
        x = a + (j / steps) * delta
        return np.where(j >= steps, b, x)

    def first(enters: Callable[[FloatArray], NDArray[np.bool_]]) -> NDArray[np.int64]:
        """Per box and axis, the first j in 1..steps where ``enters`` holds (it holds from there
        on), steps + 1 where it never does."""
        low = np.ones(lo.shape, dtype=np.int64)
        high = np.full(lo.shape, steps + 1, dtype=np.int64)
        active = low < high
        while active.any():
            mid = (low + high) // 2  # <= steps while low < high
            hit = enters(coordinate(mid))
            high = np.where(active & hit, mid, high)
            low = np.where(active & ~hit, mid + 1, low)
            active = low < high
        return low

    # First sample inside the slab, and first sample past it (rising: above hi; falling: below lo).
    start = first(lambda x: np.where(rising, x >= lo, np.where(falling, x <= hi, True)))
    past = first(lambda x: np.where(rising, x > hi, np.where(falling, x < lo, False)))
    constant_inside = (lo <= a) & (a <= hi)  # axes the segment does not move along
    start = np.where(rising | falling, start, np.where(constant_inside, 1, steps + 1))
    past = np.where(rising | falling, past, steps + 1)
    enter, leave = start.max(axis=1), past.min(axis=1)  # samples enter..leave-1 are in the box
    inside = enter < leave
    return int(enter[inside].min()) if inside.any() else None

"""Benchmark statistics in the conventions of the Planner Developer Tools (PDT).

Pure functions of run results; nothing here plans, plots or writes files.

**Failures are infinite.** A run without an exact solution has ``t_init = c_init = c_final = inf``
and an infinite cost at every time, so it enters every median and order statistic as the largest
value. A median is therefore infinite once half the runs or more failed, and an interval bound is
infinite when its order statistic falls among the failures.

**The median's confidence interval** comes from binomial order statistics (nonparametric; it holds
for any continuous distribution). With the sample sorted, ``x_(1) <= ... <= x_(n)`` (1-based
ranks), the number of samples below the population median is Binomial(n, 1/2), so

    P(x_(l) <= median <= x_(u)) = F(u - 1) - F(l - 1),   F = CDF of Binomial(n, 1/2)

(:func:`interval_coverage`, computed with ``scipy.stats.binom``). :func:`median_interval_ranks`
picks, among all pairs ``1 <= l < u <= n`` with coverage at least the confidence (99 %), the
narrowest (smallest ``u - l``); among equally narrow pairs the one with the highest coverage; and
of two mirror-image pairs with equal coverage, ``(l, u)`` and ``(n + 1 - u, n + 1 - l)``, the
upper one: n = 10 -> ranks (1, 10), n = 50 -> (16, 35), n = 100 -> (38, 64), n = 200 -> (82, 119).
PDT's published table (``parameters/statistics/percentiles/<n>.json`` in robotic-esp/pdt,
zero-based indices) has pairs of the same width one rank lower: n = 50 -> ranks (15, 34),
coverage 0.9910 against our 0.9934; n = 100 -> (37, 63), the mirror image of ours, both 0.9907;
n = 200 -> (81, 118), 0.9906 against 0.9913; n = 300 -> (127, 172), 0.9903 against 0.9907.

**Too few runs.** The widest pair, ``(1, n)``, covers ``1 - 2 * 0.5**n``, which reaches 99 % only
from n = 8 on (:data:`MIN_RUNS_FOR_INTERVAL`). Below that no interval exists: the interval is
reported as None, and :class:`MedianEstimate` still carries the sample's full range (min, max),
which the reports show instead, marked as such.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.stats import binom

FloatArray = NDArray[np.float64]

CONFIDENCE = 0.99
"""Confidence level of every interval of the median."""
GRID_POINTS = 120
"""Points of the logarithmic time grid on which cost and success over time are evaluated."""
GRID_SPAN = 1e-3
"""The time grid starts no earlier than this fraction of the time budget."""


@dataclass(frozen=True)
class IntervalRanks:
    """Order statistics bounding the median: 1-based ranks into the sorted sample."""

    lower_rank: int
    """Rank l of the lower bound, ``x_(l)``."""
    upper_rank: int
    """Rank u of the upper bound, ``x_(u)``."""
    coverage: float
    """``P(x_(l) <= median <= x_(u))``, at least the confidence asked for."""


@dataclass(frozen=True)
class MedianEstimate:
    """A sample median with its confidence interval (None when the sample is too small)."""

    median: float
    """Sample median (mean of the two middle values for even n); inf when half or more are."""
    lower: float | None
    """``x_(l)``, or None when no interval exists."""
    upper: float | None
    """``x_(u)``, or None when no interval exists."""
    ranks: IntervalRanks | None
    """Which order statistics bound the interval, or None when no interval exists."""
    minimum: float
    """Smallest value of the sample (nan for an empty sample)."""
    maximum: float
    """Largest value of the sample (inf when any run failed; nan for an empty sample)."""
    n: int
    """Sample size."""


def interval_coverage(n: int, lower_rank: int, upper_rank: int) -> float:
    """``P(x_(l) <= median <= x_(u)) = F(u - 1) - F(l - 1)`` for a sample of ``n``."""
    if not 1 <= lower_rank <= upper_rank <= n:
        raise ValueError(
            f"ranks must satisfy 1 <= l <= u <= n, got l={lower_rank}, u={upper_rank}, n={n}"
        )
    return float(binom.cdf(upper_rank - 1, n, 0.5) - binom.cdf(lower_rank - 1, n, 0.5))


def _check_confidence(confidence: float) -> None:
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must be between 0 and 1, got {confidence}")


def min_runs_for_interval(confidence: float = CONFIDENCE) -> int:
    """Smallest n for which ``(1, n)`` covers the median with ``confidence``."""
    _check_confidence(confidence)
    return math.ceil(math.log2(2 / (1 - confidence)))


MIN_RUNS_FOR_INTERVAL = min_runs_for_interval()
"""Smallest number of runs with a 99 % interval of the median (8)."""


@lru_cache(maxsize=256)
def median_interval_ranks(n: int, confidence: float = CONFIDENCE) -> IntervalRanks | None:
    """The order statistics of the median's interval for ``n`` samples (rule: module docstring).

    Returns:
        The ranks and their coverage, or None when even ``(1, n)`` covers less than
        ``confidence`` (n below :func:`min_runs_for_interval`).
    """
    _check_confidence(confidence)
    if n < 1:
        raise ValueError(f"need at least one sample, got n={n}")
    # cdf[k + 1] = F(k) for k = -1 .. n, so F(u - 1) - F(l - 1) = cdf[u] - cdf[l].
    cdf = np.concatenate(([0.0], binom.cdf(np.arange(n + 1), n, 0.5)))
    for width in range(1, n):
        lower = np.arange(1, n - width + 1)
        coverage = cdf[lower + width] - cdf[lower]
        best = coverage.max()
        if best >= confidence:
            # Mirror-image pairs tie exactly in theory; compare with a tolerance for rounding.
            candidates = np.flatnonzero(coverage >= best - 1e-12)
            lower_rank = int(lower[candidates[-1]])
            return IntervalRanks(lower_rank, lower_rank + width, float(coverage[candidates[-1]]))
    return None


def median_with_interval(values: ArrayLike, confidence: float = CONFIDENCE) -> MedianEstimate:
    """Median of ``values`` (inf allowed, NaN not) with its nonparametric interval."""
    sample = np.sort(np.asarray(values, dtype=float).ravel())
    if np.isnan(sample).any():
        raise ValueError("values must not contain NaN (count failures as inf)")
    n = sample.size
    if n == 0:
        return MedianEstimate(math.inf, None, None, None, math.nan, math.nan, 0)
    middle = (sample[(n - 1) // 2] + sample[n // 2]) / 2  # inf + x = inf: failures dominate
    ranks = median_interval_ranks(n, confidence)
    lower = float(sample[ranks.lower_rank - 1]) if ranks else None
    upper = float(sample[ranks.upper_rank - 1]) if ranks else None
    return MedianEstimate(
        float(middle), lower, upper, ranks, float(sample[0]), float(sample[-1]), n
    )


def costs_at(improvements: Sequence[Sequence[float]], times: ArrayLike) -> FloatArray:
    """The cost of one run at each of ``times``: the last improvement at or before that time.

    ``improvements`` is the run's ``[(time, cost), ...]`` in time order; before the first one
    (and for a run without any) the cost is inf.
    """
    grid = np.asarray(times, dtype=float)
    if len(improvements) == 0:
        return np.full(grid.shape, math.inf)
    stamps = np.array([t for t, _ in improvements], dtype=float)
    costs = np.array([c for _, c in improvements], dtype=float)
    if np.any(np.diff(stamps) < 0):
        raise ValueError("improvements must be in time order")
    # Defensive: a curve that went up would be a reporting bug; the best so far is what counts.
    costs = np.minimum.accumulate(costs)
    index = np.searchsorted(stamps, grid, side="right") - 1
    return np.where(index >= 0, costs[np.clip(index, 0, None)], math.inf)


@dataclass(frozen=True)
class CostCurve:
    """Median cost over time across runs, with its interval, and the success rate over time."""

    times: FloatArray
    """The time grid in seconds."""
    median: FloatArray
    """Median cost at each time (inf while half the runs or more have no solution)."""
    lower: FloatArray | None
    """Lower interval bound at each time, or None when no interval exists (too few runs)."""
    upper: FloatArray | None
    """Upper interval bound at each time (inf where it falls among unsolved runs), or None."""
    success: FloatArray
    """Fraction of runs with a solution at each time."""
    minimum: FloatArray
    """Lowest cost of any run at each time (the range shown when no interval exists)."""
    maximum: FloatArray
    """Highest cost of any run at each time (inf while any run has no solution)."""
    ranks: IntervalRanks | None
    """The order statistics used for the bounds (the same at every time)."""


def cost_curve(
    runs: Sequence[Sequence[Sequence[float]]], times: ArrayLike, confidence: float = CONFIDENCE
) -> CostCurve:
    """Median cost over ``times`` of ``runs`` (each a list of improvements) with its interval."""
    grid = np.asarray(times, dtype=float)
    if not runs:
        raise ValueError("need at least one run for a cost curve")
    table = np.sort(np.vstack([costs_at(run, grid) for run in runs]), axis=0)
    n = table.shape[0]
    median = (table[(n - 1) // 2] + table[n // 2]) / 2
    ranks = median_interval_ranks(n, confidence)
    lower = table[ranks.lower_rank - 1] if ranks else None
    upper = table[ranks.upper_rank - 1] if ranks else None
    success = np.isfinite(table).mean(axis=0)
    return CostCurve(grid, median, lower, upper, success, table[0], table[-1], ranks)


def time_grid(
    budget: float, earliest: float | None = None, points: int = GRID_POINTS
) -> FloatArray:
    """Logarithmic grid from just before ``earliest`` (a first solution time) up to ``budget``.

    The grid never starts before ``GRID_SPAN * budget``, so one freak early solution does not
    stretch the axis over decades of nothing.
    """
    if not (math.isfinite(budget) and budget > 0):
        raise ValueError(f"budget must be a finite positive number of seconds, got {budget}")
    start = GRID_SPAN * budget
    if earliest is not None and math.isfinite(earliest) and earliest > 0:
        start = min(max(start, 0.9 * earliest), budget)
    if start >= budget:
        return np.array([budget])
    return np.geomspace(start, budget, points)


def success_rate(solved: Iterable[bool]) -> float:
    """Fraction of runs that solved (0 for no runs)."""
    flags = list(solved)
    return sum(bool(flag) for flag in flags) / len(flags) if flags else 0.0


def improvement_percent(reference: float, candidate: float) -> float | None:
    """``(reference - candidate) / reference * 100``: how much lower ``candidate`` is, in %.

    Positive means ``candidate`` is better (faster or cheaper). None when undefined: either value
    infinite (a median among failures) or the reference zero.
    """
    if not (math.isfinite(reference) and math.isfinite(candidate)) or reference == 0:
        return None
    return (reference - candidate) / reference * 100.0


def best_by_final_cost(medians: dict[str, tuple[float, float, float]]) -> str | None:
    """The planner with the lowest median final cost, ties broken by median t_init, then by the
    higher success rate (the medians of planners that solved fewer than half their runs are all
    infinite: the success rate then decides).

    Args:
        medians: ``planner -> (median c_final, median t_init, success rate)``; a remaining tie
            goes to the planner listed first.
    """
    if not medians:
        return None
    return min(medians, key=lambda name: (medians[name][0], medians[name][1], -medians[name][2]))

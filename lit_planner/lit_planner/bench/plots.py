"""Per-scenario figures like the LIT* paper's Fig. 5: cost over time and success over time.

Top panel: median cost against time (log time axis), one line per planner, the 99% interval of
the median as a band where the median is finite (the full range when the runs are too few for an
interval; an infinite upper bound is drawn to the top of the axes), the median
initial solution as a marker with its interval as error bars in time and cost, and the known
optimum as a dashed line. Bottom panel: the fraction of runs solved against time.
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only: no display, no GUI toolkit

import matplotlib.pyplot as plt  # after choosing the backend
import numpy as np
from matplotlib.ticker import FuncFormatter, NullFormatter

from lit_planner.bench import stats
from lit_planner.bench.report import label

FORMATS = ("png", "pdf")
"""File formats of every figure."""
DPI = 150
"""Resolution of the PNG files."""
HEADROOM = 1.08
"""Cost axis top as a multiple of the largest finite value drawn."""
FOOTROOM = 0.95
"""Cost axis bottom as a multiple of the smallest value drawn (or the optimum)."""


NO_MEDIAN_NOTE = "no median cost to draw: no planner solved more than half of its runs"
"""Said in the cost panel when no curve has a finite median (the panel was empty)."""


def cost_limits(
    tops: list[float], bottoms: list[float], optimum: float | None
) -> tuple[float, float]:
    """The cost axis (top, bottom) around the finite values drawn and the optimum; (1, 0) when
    there is neither (nothing solved on a scenario without a known optimum: the axis spanned
    1e-9 around nothing)."""
    known = tops + ([optimum] if optimum else [])
    if not known:
        return 1.0, 0.0
    top = HEADROOM * max(known)
    return top, FOOTROOM * min(bottoms + ([optimum] if optimum else []) + [top])


def plot_scenario(
    name: str,
    scenario: dict,
    curves: dict[str, stats.CostCurve],
    out_dir: Path,
) -> list[Path]:
    """Draw ``name``'s figure into ``out_dir`` as ``<name>.png`` and ``<name>.pdf``."""
    figure, (cost_axes, success_axes) = plt.subplots(
        2, 1, figsize=(7.0, 6.5), sharex=True, gridspec_kw={"height_ratios": [2.2, 1.0]}
    )
    colours = plt.get_cmap("tab10")
    finite_tops, finite_bottoms = [], []
    for curve in curves.values():
        lows = curve.lower if curve.ranks else curve.minimum
        if np.isfinite(lows).any():
            finite_bottoms.append(float(lows[np.isfinite(lows)].min()))
        for values in (curve.upper, curve.median, None if curve.ranks else curve.maximum):
            if values is not None and np.isfinite(values).any():
                finite_tops.append(float(np.nanmax(np.where(np.isfinite(values), values, np.nan))))
    optimum = scenario.get("optimal_cost")
    top, bottom = cost_limits(finite_tops, finite_bottoms, optimum)
    any_range = False
    for index, (planner, curve) in enumerate(curves.items()):
        colour = colours(index % 10)
        entry = scenario["planners"][planner]
        times = curve.times
        if curve.ranks is not None:
            lower, upper = curve.lower, curve.upper
        else:
            any_range = True
            lower, upper = curve.minimum, curve.maximum
        # PDT draws no interval while the median is infinite (half the runs or more unsolved).
        drawable = np.isfinite(curve.median) & np.isfinite(lower)
        cost_axes.fill_between(
            times,
            np.where(drawable, lower, np.nan),
            np.where(drawable, np.minimum(upper, top), np.nan),
            color=colour,
            alpha=0.18,
            linewidth=0,
            step="post",
        )
        median = np.where(np.isfinite(curve.median), curve.median, np.nan)
        cost_axes.step(times, median, where="post", color=colour, label=label(planner), lw=1.6)
        _initial_solution_marker(cost_axes, entry, colour, top)
        success_axes.step(times, curve.success * 100, where="post", color=colour, lw=1.6)
    if optimum:
        cost_axes.axhline(optimum, color="black", ls="--", lw=1.0, label=f"optimum {optimum:.4f}")
    if not any(np.isfinite(curve.median).any() for curve in curves.values()):
        cost_axes.text(
            0.5, 0.5, NO_MEDIAN_NOTE, transform=cost_axes.transAxes, ha="center", va="center"
        )
    cost_axes.set_xscale("log")
    cost_axes.set_ylim(bottom, top)
    cost_axes.set_ylabel("cost (path length)")
    band = "full range (too few runs for a 99% interval)" if any_range else "99% interval"
    cost_axes.set_title(
        f"{name}: median cost, band = {band}; budget {scenario['time_budget']:g} s", fontsize=10
    )
    cost_axes.grid(True, which="both", alpha=0.3)
    cost_axes.legend(fontsize=8, loc="upper right")
    success_axes.set_ylim(-2, 102)
    success_axes.set_ylabel("success (%)")
    success_axes.set_xlabel("time (s)")
    success_axes.grid(True, which="both", alpha=0.3)
    _time_labels(success_axes)
    figure.tight_layout()
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for extension in FORMATS:
        path = out_dir / f"{name}.{extension}"
        figure.savefig(path, dpi=DPI)
        paths.append(path)
    plt.close(figure)
    return paths


def _time_labels(axes: plt.Axes) -> None:
    """Plain numbers (0.01, 0.2) on the log time axis, which the two panels share. Over less
    than two decades matplotlib labels every minor tick in scientific notation, and the labels
    run into each other: there only the 2s and 5s of each decade are labelled, or, when fewer
    than two labels would show (a range within one decade), about five of the minor ticks."""
    axes.xaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
    low, high = axes.get_xlim()
    if not 0 < low < high or high / low >= 100.0:
        axes.xaxis.set_minor_formatter(NullFormatter())
        return
    seen = [v for v in axes.xaxis.get_minorticklocs() if low <= v <= high]
    labelled = [v for v in seen if _leading_digit(v) in (2, 5)]
    majors = [v for v in axes.xaxis.get_majorticklocs() if low <= v <= high]
    if len(labelled) + len(majors) < 2:
        labelled = seen[:: max(1, math.ceil(len(seen) / 5))]

    def minor(value: float, _position: int) -> str:
        return f"{value:g}" if any(math.isclose(value, v, rel_tol=1e-9) for v in labelled) else ""

    axes.xaxis.set_minor_formatter(FuncFormatter(minor))


def _leading_digit(value: float) -> int | None:
    """The leading digit of a tick value when it is one digit times a power of ten, else None."""
    mantissa = value / 10.0 ** math.floor(math.log10(value) + 1e-9)
    digit = round(mantissa)
    return digit if math.isclose(mantissa, digit, rel_tol=1e-6) else None


def _initial_solution_marker(axes: plt.Axes, entry: dict, colour: object, top: float) -> None:
    """The median initial solution with its intervals (or ranges) as error bars."""
    t, c = entry["t_init"], entry["c_init"]
    t_median, c_median = float(t["median"]), float(c["median"])
    if not (math.isfinite(t_median) and math.isfinite(c_median)):
        return

    def bounds(item: dict) -> tuple[float, float]:
        low, high = (
            (item["ci"]["lower"], item["ci"]["upper"])
            if item["ci"] is not None
            else (item["min"], item["max"])
        )
        return float(low), float(high)

    t_low, t_high = bounds(t)
    c_low, c_high = bounds(c)
    t_high = t_high if math.isfinite(t_high) else axes.get_xlim()[1]
    c_high = min(c_high, top)
    axes.errorbar(
        [t_median],
        [c_median],
        xerr=[[t_median - t_low], [max(t_high - t_median, 0.0)]],
        yerr=[[c_median - c_low], [max(c_high - c_median, 0.0)]],
        fmt="o",
        ms=4,
        color=colour,
        capsize=2,
        lw=1.0,
    )

"""Tests of the benchmark statistics (lit_planner.bench.stats) and of the summary they feed.

The reference intervals are computed here independently of scipy: exact binomial probabilities
from ``math.comb`` in rational arithmetic and a brute-force search over every pair of ranks; and
PDT's published table (robotic-esp/pdt, ``parameters/statistics/percentiles/<n>.json``,
zero-based indices) where it has the n: the same widths, one rank lower than ours.
"""

from __future__ import annotations

import copy
import math
from fractions import Fraction
from typing import Any

import numpy as np
import pytest
from lit_msgs_json.errors import SchemaError
from lit_planner.bench import report, stats
from lit_planner.bench.runner import RUN_SCHEMA, RUN_SCHEMA_VERSION, run_order

from lit_msgs_json import codec

INF = math.inf


def exact_coverage(n: int, lower: int, upper: int) -> Fraction:
    """P(x_(l) <= median <= x_(u)) = P(l <= B <= u - 1), B ~ Binomial(n, 1/2), exactly."""
    return Fraction(sum(math.comb(n, k) for k in range(lower, upper)), 2**n)


def brute_force_ranks(n: int, confidence: Fraction) -> tuple[int, int, Fraction] | None:
    """Narrowest pair with coverage >= confidence; then highest coverage; then the upper one."""
    pairs = [
        (upper - lower, -exact_coverage(n, lower, upper), -lower, lower, upper)
        for lower in range(1, n + 1)
        for upper in range(lower + 1, n + 1)
        if exact_coverage(n, lower, upper) >= confidence
    ]
    if not pairs:
        return None
    *_, lower, upper = min(pairs)
    return lower, upper, exact_coverage(n, lower, upper)


NINETY_NINE = Fraction(99, 100)


@pytest.mark.parametrize("n", [10, 20, 100])
def test_interval_ranks_match_an_independent_exact_computation(n: int) -> None:
    expected = brute_force_ranks(n, NINETY_NINE)
    ranks = stats.median_interval_ranks(n)
    assert expected is not None and ranks is not None
    assert (ranks.lower_rank, ranks.upper_rank) == expected[:2]
    assert ranks.coverage == pytest.approx(float(expected[2]), abs=1e-12)
    assert ranks.coverage >= 0.99


def test_interval_ranks_by_hand() -> None:
    # n = 10: only (1, 10) reaches 99%: 1 - 2/1024. (1, 9) covers 1 - 1/1024 - 11/1024 < 0.99.
    ranks = stats.median_interval_ranks(10)
    assert (ranks.lower_rank, ranks.upper_rank) == (1, 10)
    assert ranks.coverage == pytest.approx(1 - 2 / 1024)
    assert exact_coverage(10, 1, 9) == 1 - Fraction(12, 1024) < NINETY_NINE
    # n = 20: width 12 is the narrowest; (4, 16) and (5, 17) mirror each other at
    # 1 - F(3) - F(4) = 1 - (1351 + 6196) / 2^20; the upper one is taken.
    ranks = stats.median_interval_ranks(20)
    assert (ranks.lower_rank, ranks.upper_rank) == (5, 17)
    assert ranks.coverage == pytest.approx(1 - (1351 + 6196) / 2**20)
    assert exact_coverage(20, 5, 16) < NINETY_NINE  # width 11 is not enough
    # n = 100: ranks (38, 64), coverage 0.9907 (PDT's table: the mirror pair (37, 63)).
    ranks = stats.median_interval_ranks(100)
    assert (ranks.lower_rank, ranks.upper_rank) == (38, 64)
    assert ranks.coverage == pytest.approx(0.9907, abs=1e-4)


@pytest.mark.parametrize(
    ("n", "pdt_zero_based", "pdt_coverage"),
    [(50, (14, 33), 0.9910), (100, (36, 62), 0.9907), (200, (80, 117), 0.9906),
     (300, (126, 171), 0.9903)],
)  # fmt: skip
def test_interval_ranks_against_pdt_table(
    n: int, pdt_zero_based: tuple[int, int], pdt_coverage: float
) -> None:
    """PDT's table: pairs of our width one rank lower, whose coverage it states; ours cover as
    much or more (and the stated coverage is that of its pair, read as zero-based indices)."""
    lower, upper = pdt_zero_based[0] + 1, pdt_zero_based[1] + 1
    assert float(exact_coverage(n, lower, upper)) == pytest.approx(pdt_coverage, abs=1e-4)
    ranks = stats.median_interval_ranks(n)
    assert (ranks.lower_rank, ranks.upper_rank) == (lower + 1, upper + 1)
    assert ranks.coverage >= pdt_coverage - 1e-4


def test_no_interval_below_eight_runs() -> None:
    assert stats.MIN_RUNS_FOR_INTERVAL == 8
    for n in range(1, 8):
        # The widest pair (1, n) covers 1 - 2^(1-n) < 0.99 (n = 1 has no pair at all).
        assert brute_force_ranks(n, NINETY_NINE) is None
        assert stats.median_interval_ranks(n) is None
    assert exact_coverage(8, 1, 8) == 1 - Fraction(2, 256) >= NINETY_NINE
    assert stats.median_interval_ranks(8) is not None
    estimate = stats.median_with_interval([3.0, 1.0, 2.0, 5.0, 4.0])
    assert estimate.median == 3.0
    assert estimate.ranks is None and estimate.lower is None and estimate.upper is None
    assert (estimate.minimum, estimate.maximum) == (1.0, 5.0)


def test_median_with_interval_picks_the_order_statistics() -> None:
    values = np.arange(20, 0, -1, dtype=float)  # 20 .. 1, unsorted on purpose
    estimate = stats.median_with_interval(values)
    assert estimate.median == 10.5
    assert (estimate.lower, estimate.upper) == (5.0, 17.0)  # ranks (5, 17) of 1..20


def test_failures_count_as_infinite() -> None:
    # 4 of 10 failed: the median is finite, the upper bound x_(10) is a failure.
    values = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0] + [INF] * 4
    estimate = stats.median_with_interval(values)
    assert estimate.median == 5.5
    assert estimate.lower == 1.0 and estimate.upper == INF
    # 5 of 10 failed: the two middle values are 5.0 and inf, so the median is infinite.
    estimate = stats.median_with_interval([1.0, 2.0, 3.0, 4.0, 5.0] + [INF] * 5)
    assert estimate.median == INF
    with pytest.raises(ValueError, match="NaN"):
        stats.median_with_interval([1.0, math.nan])


def test_an_all_failed_planner() -> None:
    estimate = stats.median_with_interval([INF] * 10)
    assert estimate.median == INF and estimate.lower == INF and estimate.upper == INF
    curve = stats.cost_curve([[]] * 10, [0.1, 0.2])
    assert np.all(np.isinf(curve.median)) and np.all(curve.success == 0)
    records = [_record(run, solved=False) for run in range(10)]
    summary = report.planner_statistics(records)
    assert summary["success_rate"] == 0 and summary["solved"] == 0
    assert summary["c_final"]["median"] == "inf"
    assert summary["t_init"]["ci"]["lower"] == "inf"


def test_cost_at_is_the_last_improvement_at_or_before_each_time() -> None:
    improvements = [(0.1, 5.0), (0.3, 4.0), (0.7, 2.5)]
    times = [0.05, 0.1, 0.2, 0.3, 0.69, 0.7, 1.0]
    assert stats.costs_at(improvements, times).tolist() == [INF, 5.0, 5.0, 4.0, 4.0, 2.5, 2.5]
    assert stats.costs_at([], times).tolist() == [INF] * len(times)
    with pytest.raises(ValueError, match="time order"):
        stats.costs_at([(0.2, 3.0), (0.1, 2.0)], times)


def test_cost_curve_median_and_success_over_time() -> None:
    runs = [[(0.1, 3.0), (0.5, 1.0)], [(0.2, 4.0)], []]
    curve = stats.cost_curve(runs, [0.05, 0.15, 0.3, 0.6])
    # At 0.6 the costs are 1, 4 and inf: median 4. At 0.15 they are 3, inf, inf: median inf.
    assert curve.median.tolist() == [INF, INF, 4.0, 4.0]
    assert curve.success.tolist() == pytest.approx([0, 1 / 3, 2 / 3, 2 / 3])
    assert curve.lower is None and curve.ranks is None  # 3 runs: no 99% interval
    assert curve.minimum.tolist() == [INF, 3.0, 3.0, 1.0]


def test_cost_curve_interval_with_enough_runs() -> None:
    runs = [[(0.1 * (i + 1), float(10 - i))] for i in range(10)]  # run i: cost 10 - i from 0.1(i+1)
    curve = stats.cost_curve(runs, [1.05])
    assert curve.ranks is not None and (curve.ranks.lower_rank, curve.ranks.upper_rank) == (1, 10)
    assert (curve.lower[0], curve.median[0], curve.upper[0]) == (1.0, 5.5, 10.0)


def test_time_grid_is_logarithmic_and_ends_at_the_budget() -> None:
    grid = stats.time_grid(0.4, earliest=0.002)
    assert grid[-1] == pytest.approx(0.4) and grid[0] == pytest.approx(0.0018)
    assert np.allclose(np.diff(np.log(grid)), np.log(grid[1] / grid[0]))
    assert stats.time_grid(0.4, earliest=1e-9)[0] == pytest.approx(0.4 * stats.GRID_SPAN)
    with pytest.raises(ValueError, match="budget"):
        stats.time_grid(0.0)


def test_improvement_and_best_planner() -> None:
    assert stats.improvement_percent(0.0626, 0.0597) == pytest.approx(
        4.63, abs=0.01
    )  # paper, RR-R4
    assert stats.improvement_percent(2.0, 2.5) == pytest.approx(-25.0)
    assert stats.improvement_percent(INF, 1.0) is None
    medians = {
        "aitstar": (1.0, 0.2, 1.0),
        "bitstar": (1.0, 0.1, 1.0),
        "rrtconnect": (INF, 0.01, 1.0),
    }
    assert stats.best_by_final_cost(medians) == "bitstar"  # tie on cost, faster first solution
    # Neither solved half its runs: the one that solved more (it was the first listed: AIT* with
    # 0 of 10 over RRT-Connect with 2 of 10).
    failing = {"aitstar": (INF, INF, 0.0), "rrtconnect": (INF, INF, 0.2)}
    assert stats.best_by_final_cost(failing) == "rrtconnect"
    assert stats.best_by_final_cost({}) is None


def test_run_order_is_a_reproducible_shuffle() -> None:
    planners = ["a", "b", "c", "d", "e"]
    orders = {tuple(run_order(planners, "np4", 0, run, run + 1)) for run in range(20)}
    assert all(sorted(order) == planners for order in orders)
    assert len(orders) > 1
    # The same in every process (a hash() of the key would differ with PYTHONHASHSEED): a rerun
    # of a benchmark, or its replay, plans in the recorded order.
    assert run_order(planners, "np4", 0, 3, 4) == ["d", "a", "b", "e", "c"]
    assert run_order(planners, "rrd8", 7, 11, 4) == ["d", "b", "a", "c", "e"]


# --- summary schema -------------------------------------------------------------------------


CHECKS_BASE = {"litstar-fixed": 100, "litstar-fit": 200}
"""Run i's validity checks up to its first solution are base + 10 i in the records below."""


def _record(run: int, planner: str = "litstar-fixed", solved: bool = True) -> dict[str, Any]:
    cost = 1.0 + run / 10
    return {
        "schema": RUN_SCHEMA,
        "version": RUN_SCHEMA_VERSION,
        "scenario": "np4",
        "scenario_key": "np4",
        "instance": 0,
        "dimension": 4,
        "run": run,
        "seed": run + 1,
        "order": 0,
        "planner": planner,
        "core_planner": "litstar" if planner.startswith("litstar") else planner,
        "policy": "fixed" if planner.startswith("litstar") else None,
        "params": {},
        "time_budget": 0.12,
        "status": "exact_solution" if solved else "timeout",
        "message": "",
        "solved": solved,
        "t_init": 0.01 if solved else None,
        "c_init": cost + 1 if solved else None,
        "c_final": cost if solved else None,
        "checks_init": CHECKS_BASE.get(planner, 300) + 10 * run if solved else None,
        "improvements": [[0.01, cost + 1], [0.05, cost]] if solved else [],
        "time": 0.12,
        "wall_time": 0.125,
        "path_valid": True if solved else None,
        "path_check": None,
        "path_states": 3 if solved else 0,
        "counters": {"validity_checks": 100},
        "optimal_cost": 0.4236,
    }


def _summary() -> dict[str, Any]:
    from lit_planner.bench import cli, runner

    planners = ("litstar-fixed", "litstar-fit", "aitstar", "rrtconnect")
    records = [
        _record(run, planner, solved=planner != "rrtconnect")  # an all-failed planner too
        for planner in planners
        for run in range(8)
    ]
    config = runner.BenchConfig(scenarios=("np4",), planners=planners, runs=8)
    return {"records": records, "config": config, "cli": cli}


def _write_summary(folder: Any, parts: dict[str, Any]) -> dict[str, Any]:
    from datetime import UTC, datetime

    now = datetime.now(UTC)
    return parts["cli"].write_outputs(
        folder,
        parts["records"],
        parts["config"],
        preset=None,
        requested=list(parts["config"].planners),
        started=now,
        finished=now,
        duration=1.0,
        estimate=(0.0, "test"),
        argv=["lit", "bench", "--test"],
    )


def test_summary_reports_the_checks_up_to_the_first_solution(tmp_path: Any) -> None:
    summary = _write_summary(tmp_path, _summary())
    planners = summary["scenarios"]["np4"]["planners"]
    # Runs 0..7: medians of 100..170 and 200..270; the unsolved planner's is infinite.
    assert planners["litstar-fixed"]["checks_init"]["median"] == 135.0
    assert planners["litstar-fit"]["checks_init"]["median"] == 235.0
    assert planners["rrtconnect"]["checks_init"]["median"] == "inf"
    row = summary["comparisons"]["fit"]["rows"]["np4"]
    assert row["reference_medians"]["checks_init"] == 235.0
    assert row["litstar_medians"]["checks_init"] == 135.0
    assert row["improvement_percent"]["checks_init"] == pytest.approx(100 * 100 / 235)
    text = (tmp_path / "summary.md").read_text()
    assert "| np4 | 235 | 135 | +42.55 |" in text
    assert "| LIT* (fixed) | 8/8 | 10.000 [10.000, 10.000] " in text  # ms
    assert "| 135 [100, 170] | 0 |" in text
    assert (report.fmt(103.5, None), report.fmt(104.0, None), report.fmt("inf", None)) == (
        "103.5",
        "104",
        "∞",
    )


def test_records_without_checks_still_summarise(tmp_path: Any) -> None:
    """Bags written before the checks were recorded: their summary says null, not 0."""
    parts = _summary()
    for record in parts["records"]:
        del record["checks_init"]
        codec.validate("BenchRun", record)
    summary = _write_summary(tmp_path, parts)
    for planner in ("litstar-fit", "rrtconnect"):  # solved every run / none
        assert summary["scenarios"]["np4"]["planners"][planner]["checks_init"] is None
    row = summary["comparisons"]["fit"]["rows"]["np4"]
    assert row["litstar_medians"]["checks_init"] is None
    assert row["improvement_percent"]["checks_init"] is None
    text = (tmp_path / "summary.md").read_text()
    assert "Validity checks up to the first solution" not in text
    assert "| — | 0 |" in text


def test_the_best_ompl_planner_of_a_scenario_none_solved_is_not_named_like_a_winner(
    tmp_path: Any,
) -> None:
    """No OMPL planner solved a run: the first listed was shown as the best OMPL planner."""
    parts = _summary()
    parts["records"] = [
        _record(record["run"], record["planner"], solved=False)
        if record["planner"] == "aitstar"
        else record
        for record in parts["records"]
    ]
    summary = _write_summary(tmp_path, parts)
    assert summary["comparisons"]["best_ompl"]["rows"]["np4"]["reference"] == "aitstar"
    text = (tmp_path / "summary.md").read_text()
    assert "| np4 | none solved a run (AIT*, listed first) | ∞ |" in text, text
    # One that solved is named as before.
    solved = tmp_path / "solved"
    solved.mkdir()
    _write_summary(solved, _summary())
    assert "| np4 | AIT* | " in (solved / "summary.md").read_text()


def test_summary_validates_and_a_broken_one_is_rejected_naming_the_field(tmp_path: Any) -> None:
    summary = _write_summary(tmp_path, _summary())
    codec.validate("BenchSummary", summary)  # write_outputs validated it already; again, explicitly
    assert (tmp_path / "summary.json").is_file() and (tmp_path / "summary.md").is_file()
    stats_np4 = summary["scenarios"]["np4"]["planners"]["litstar-fixed"]
    assert stats_np4["c_final"]["ci"]["lower_rank"] == 1 and stats_np4["success_rate"] == 1.0
    assert summary["comparisons"]["fit"]["rows"]["np4"]["improvement_percent"]["c_final"] == 0.0
    assert summary["comparisons"]["best_ompl"]["rows"]["np4"]["reference"] == "aitstar"
    failed = summary["scenarios"]["np4"]["planners"]["rrtconnect"]
    assert failed["success_rate"] == 0 and failed["c_final"]["median"] == "inf"
    assert set(summary["scenarios"]["np4"]["curves"]["rrtconnect"]["median"]) == {"inf"}
    assert (tmp_path / "plots" / "np4.png").is_file() and (tmp_path / "plots" / "np4.pdf").is_file()
    assert "| RRT-Connect | 0/8 | ∞ [∞, ∞]" in (tmp_path / "summary.md").read_text()

    broken = copy.deepcopy(summary)
    broken["scenarios"]["np4"]["planners"]["aitstar"]["success_rate"] = 1.5
    with pytest.raises(SchemaError, match=r"success_rate"):
        codec.validate("BenchSummary", broken)
    broken = copy.deepcopy(summary)
    broken["runs"][3]["c_final"] = "cheap"
    with pytest.raises(SchemaError, match=r"runs\[3\]\.c_final"):
        codec.validate("BenchSummary", broken)
    broken = copy.deepcopy(summary)
    del broken["machine"]["cpu_model"]
    with pytest.raises(SchemaError, match=r"cpu_model"):
        codec.validate("BenchSummary", broken)


def test_run_record_schema_ties_solved_to_its_numbers() -> None:
    codec.validate("BenchRun", _record(0))
    codec.validate("BenchRun", _record(0, solved=False))
    unsolved_with_cost = dict(_record(0, solved=False), c_final=1.0)
    with pytest.raises(SchemaError, match="c_final"):
        codec.validate("BenchRun", unsolved_with_cost)
    unsolved_with_checks = dict(_record(0, solved=False), checks_init=12)
    with pytest.raises(SchemaError, match="checks_init"):
        codec.validate("BenchRun", unsolved_with_checks)
    # --t-init-repeats: only on solved LIT* records, with at least two times.
    codec.validate("BenchRun", dict(_record(0), t_init_runs=[0.012, 0.01]))
    for record in (
        dict(_record(0, solved=False), t_init_runs=[0.012, 0.01]),
        dict(_record(0, "aitstar"), t_init_runs=[0.012, 0.01]),
        dict(_record(0), t_init_runs=[0.01]),
    ):
        with pytest.raises(SchemaError, match="t_init_runs"):
            codec.validate("BenchRun", record)


def test_bench_config_repeats_first_solutions_of_lit_star_only() -> None:
    """The check lives in BenchConfig, so a benchmark set up through the API is held to it too."""
    from lit_planner.bench import runner

    config = runner.BenchConfig(("np4",), ("litstar-fit", "litstar-tensor"), 2, t_init_repeats=3)
    assert config.t_init_repeats == 3
    with pytest.raises(ValueError, match="single times of aitstar: benchmark those without it"):
        runner.BenchConfig(("np4",), ("litstar-fit", "aitstar"), 2, t_init_repeats=2)
    with pytest.raises(ValueError, match="must be at least 1, got 0"):
        runner.BenchConfig(("np4",), ("litstar-fit",), 2, t_init_repeats=0)
    assert runner.BenchConfig(("np4",), ("aitstar",), 2).t_init_repeats == 1


def test_paired_ratios_follow_the_rule_for_failures() -> None:
    """Per seed LIT* / reference; unsolved = infinite: only LIT* failed -> inf, only the reference
    failed -> 0, both failed -> no pair."""

    def record(seed: int, planner: str, t: float | None) -> dict[str, Any]:
        base = _record(seed, planner, solved=t is not None)
        if t is not None:
            base["t_init"], base["c_init"] = t, 2 * t
        return base

    ours = [record(0, "litstar-tensor", 1.0), record(1, "litstar-tensor", 3.0)]
    ours += [record(2, "litstar-tensor", None), record(3, "litstar-tensor", 1.0)]
    ours += [record(4, "litstar-tensor", None)]
    theirs = [record(0, "litstar-fit", 2.0), record(1, "litstar-fit", 2.0)]
    theirs += [record(2, "litstar-fit", 1.0), record(3, "litstar-fit", None)]
    theirs += [record(4, "litstar-fit", None)]
    result = report.paired(ours, theirs)
    assert result["pairs"] == 4  # seed 4: both failed
    # Ratios 0.5, 1.5, inf, 0 -> sorted 0, 0.5, 1.5, inf: median 1.0, no interval (n < 8).
    t = result["t_init"]
    assert t["ratio"]["median"] == 1.0 and t["ratio"]["ci"] is None
    assert (t["ratio"]["min"], t["ratio"]["max"]) == (0.0, "inf")
    assert t["improvement_percent"] == 0.0
    assert result["c_init"]["ratio"]["median"] == 1.0  # c_init = 2 t: the same ratios
    # Pairing by seed, not by order: shuffled records give the same result.
    assert report.paired(ours[::-1], theirs) == result
    # Mostly LIT* failures: an infinite median ratio has no improvement.
    worse = report.paired([record(s, "litstar-tensor", None) for s in range(3)], theirs[:3])
    assert worse["t_init"]["ratio"]["median"] == "inf"
    assert worse["t_init"]["improvement_percent"] is None


def test_a_paired_median_of_failures_ratios_says_no_improvement() -> None:
    """A failure's ratio (0 when only the reference failed) stands for an order, not a size.
    Averaged with a finite ratio in the middle of an even sample it gave a median no pair had
    (5 equal queries and 5 the reference failed: 0.5, "50 % better"), and as the median it put
    "+100 % cheaper" against runs without a cost (LIT* dearer in every query both solved)."""

    def record(seed: int, planner: str, t: float | None, cost: float = 1.0) -> dict[str, Any]:
        base = _record(seed, planner, solved=t is not None)
        if t is not None:
            base["t_init"], base["c_init"] = t, cost
        return base

    ours = [record(seed, "litstar-tensor", 1.0) for seed in range(10)]
    theirs = [record(seed, "litstar-fit", 1.0 if seed < 5 else None) for seed in range(10)]
    even = report.paired(ours, theirs)
    assert (even["pairs"], even["only_litstar_solved"], even["only_reference_solved"]) == (10, 5, 0)
    for metric in ("t_init", "c_init"):
        assert even[metric]["ratio"]["median"] == 0.0
        assert even[metric]["improvement_percent"] is None
        assert even[metric]["ratio"]["ci"] is not None  # the interval is the ranks': still valid
    dearer = [record(seed, "litstar-tensor", 1.0, cost=1.2) for seed in range(10)]
    few = [record(seed, "litstar-fit", 1.0 if seed < 4 else None) for seed in range(10)]
    odd = report.paired(dearer, few)
    assert odd["c_init"]["ratio"]["median"] == 0.0 and odd["c_init"]["improvement_percent"] is None
    # Both kinds in the middle: inf, as a median with half its runs failed is.
    both = report.paired(
        [record(0, "litstar-tensor", None), record(1, "litstar-tensor", 1.0)],
        [record(0, "litstar-fit", 1.0), record(1, "litstar-fit", None)],
    )
    assert (both["only_litstar_solved"], both["only_reference_solved"]) == (1, 1)
    assert both["t_init"]["ratio"]["median"] == "inf"
    assert both["t_init"]["improvement_percent"] is None
    # The verdict from the medians names a scenario whose FIT* median is a failure's (it was
    # counted as not in the range without a word, though LIT* solved more than half).
    medians = {
        "improvement_percent": {"t_init": None, "c_init": None},
        "reference_medians": {"t_init": "inf", "c_init": "inf"},
        "litstar_medians": {"t_init": 0.01, "c_init": 1.2},
    }
    (verdict, _) = report._paper_range({"rrd8": medians})
    assert "point estimates, without an interval) none (0 of 1), no percentage on rrd8 (FIT*" in (
        verdict
    )
    rows = {"np4": {"paired": even}, "np8": {"paired": both}}
    table = "\n".join(report._paired_table(rows))
    assert "| np4 | 10 (5 only LIT* solved) | 0.000 " in table
    assert "| np8 | 2 (1 only LIT*, 1 only FIT* solved) | ∞ " in table
    assert "a median that is such a ratio has no ⇑." in table
    assert "such a ratio" not in "\n".join(report._paired_table({"np4": {"paired": dict(
        even, only_litstar_solved=0)}}))  # fmt: skip


def test_summary_compares_the_same_queries_pairwise(tmp_path: Any) -> None:
    parts = _summary()
    for record in parts["records"]:
        if record["planner"] == "litstar-fit" and record["solved"]:
            record["t_init"] = 0.01 * (1.25 + record["run"] / 100)  # LIT* 20..25 % faster
    summary = _write_summary(tmp_path, parts)  # validates against the schema
    pair = summary["comparisons"]["fit"]["rows"]["np4"]["paired"]
    assert pair["pairs"] == 8 and pair["t_init"]["ratio"]["ci"] is not None
    expected = np.median([1 / (1.25 + run / 100) for run in range(8)])
    assert pair["t_init"]["ratio"]["median"] == pytest.approx(expected)
    assert pair["t_init"]["improvement_percent"] == pytest.approx((1 - expected) * 100)
    assert pair["c_init"]["improvement_percent"] == pytest.approx(0.0)
    text = (tmp_path / "summary.md").read_text()
    assert "| scenario | queries | t_init ratio | t_init ⇑ (%) | c_init ratio |" in text
    assert f"| np4 | 8 | {report.fmt(expected, 3)} [" in text
    assert (
        "initial cost not worse): from the medians (point estimates, without an interval) np4 "
        "(1 of 1); query by query at 99 %"
    ) in text
    assert "so jointly at least 98 %, per scenario) np4 (1 of 1)." in text
    # With too few queries for an interval the verdict says so: it said "none (0 of 1), not
    # testable on np4", which read as a negative finding.
    few = {"ratio": {"ci": None}}
    rows = {"np4": {"improvement_percent": {"t_init": 5.0, "c_init": 1.0},
                    "paired": {"t_init": few, "c_init": few}}}  # fmt: skip
    (verdict, _) = report._paper_range(rows)
    assert verdict.endswith(
        "; query by query at 99 % not testable on any scenario (fewer than 8 queries that "
        "either policy solved, which a 99 % interval needs, or a query recorded twice)."
    ), verdict
    # A scenario without a pair (neither policy solved a query) is not testable either, and has
    # its row in the table (it was left out of both, and counted as tested).
    rows["np4"]["paired"] = pair
    rows["rrd8"] = {"improvement_percent": {"t_init": None, "c_init": None}}
    (verdict, _) = report._paper_range(rows)
    assert verdict.endswith(
        "per scenario) np4 (1 of 1), not testable on rrd8 (fewer than 8 queries that either "
        "policy solved, which a 99 % interval needs, or a query recorded twice)."
    ), verdict
    assert "| rrd8 | 0 | — | — | — | — |" in report._paired_table(rows)
    # Decided on the unrounded values: a gain printed as +4.60 but short of 4.6 %, or a cost
    # printed as -0.00 but worse, and bounds printed as 0.954 and 1.000 above them, are not in
    # the range (they were: decided on the values as printed).
    for gain, cost_gain, upper, cost_upper, reliably in (
        (4.5999, 0.0, 0.954, 1.0, True),
        (4.6, -0.001, 0.954, 1.0, True),
        (4.6, 0.0, 0.95449, 1.0, False),
        (4.6, 0.0, 0.954, 1.0004, False),
        (4.6, 0.0, 0.954, 1.0, True),
        (stats.improvement_percent(3.0, 2.862), 0.0, 0.954, 1.0, True),  # 4.599999999999996
    ):
        rows = {"np4": {"improvement_percent": {"t_init": gain, "c_init": cost_gain}}}
        rows["np4"]["paired"] = {
            "t_init": {"ratio": {"ci": {"lower": 0.9, "upper": upper}}},
            "c_init": {"ratio": {"ci": {"lower": 0.9, "upper": cost_upper}}},
        }
        verdict = report._paper_range(rows)[0]
        from_medians = round(gain, 9) >= 4.6 and cost_gain >= 0.0
        assert ("without an interval) np4 (1 of 1)" in verdict) == from_medians, verdict
        assert ("per scenario) np4 (1 of 1)." in verdict) == reliably, verdict
    # Not against the best OMPL planner (AIT* here): its seed does not fix its run.
    assert "paired" not in summary["comparisons"]["best_ompl"]["rows"]["np4"]
    # Records of other queries (another first seed for FIT*): no pairing, no table.
    parts = _summary()
    for record in parts["records"]:
        if record["planner"] == "litstar-fit":
            record["seed"] += 100
    summary = _write_summary(tmp_path / "other", parts)
    assert "paired" not in summary["comparisons"]["fit"]["rows"]["np4"]
    other = (tmp_path / "other" / "summary.md").read_text()
    assert "| scenario | queries |" not in other
    # Equal times (the fixture's 0.01 s): outside the paper's range; no paired part of the line.
    assert "from the medians (point estimates, without an interval) none (0 of 1)." in other


def test_pairing_takes_the_common_queries_and_refuses_ambiguity(tmp_path: Any) -> None:
    ours = [_record(run, "litstar-tensor") for run in range(8)]
    theirs = [_record(run, "litstar-fit") for run in range(1, 9)]  # seeds 2..9 against 1..8
    assert report.paired(ours, theirs)["pairs"] == 7  # type: ignore[index]
    # Two records of one query on a side (two runs' bags replayed together): not paired.
    assert report.paired(ours + ours[:1], theirs) is None
    assert report.paired(ours, theirs + theirs[:1]) is None
    # No pair where both failed every query; the summary is still written and valid.
    parts = _summary()
    for record in parts["records"]:
        if record["planner"] in ("litstar-fixed", "litstar-fit"):
            record.update(_record(record["run"], record["planner"], solved=False))
    summary = _write_summary(tmp_path, parts)
    assert "paired" not in summary["comparisons"]["fit"]["rows"]["np4"]
    assert report._ratio(0.0, 0.0) == 1.0 and report._ratio(1.0, 0.0) == math.inf


def test_c_final_is_the_cost_at_the_time_budget() -> None:
    """As the cost curves have it: the record's cost counted improvements that an OMPL planner
    reported after the budget (its wall clock runs on while it stops; 3 of 78 runs of one
    --quick benchmark, by up to 12 %)."""
    record = {
        "solved": True, "t_init": 0.05, "c_init": 2.0, "c_final": 1.5, "time_budget": 0.12,
        "improvements": [[0.05, 2.0], [0.11, 1.8], [0.13, 1.5]],
    }  # fmt: skip
    assert report.record_value(record, "c_final") == 1.8
    assert report.record_value(record, "c_init") == 2.0
    late = record | {"t_init": 0.125, "improvements": [[0.125, 2.0]]}
    assert report.record_value(late, "c_final") == math.inf  # no cost at the budget
    assert report.record_value(record | {"solved": False}, "c_final") == math.inf


def test_a_first_solution_after_the_budget_is_no_solution(tmp_path: Any) -> None:
    """Every table, curve and comparison counts such a run as unsolved, as its cost at the budget
    does: a first solution just after the budget counted as solved, so a summary could show a
    median t_init above the budget next to an infinite median c_final. The run's own first time
    decides, not a smaller rerun timing."""
    late = {"solved": True, "t_init": 0.11, "c_init": 2.0, "c_final": 2.0, "time_budget": 0.12,
            "improvements": [[0.125, 2.0]]}  # fmt: skip
    assert not report.solved_in_budget(late)
    assert report.solved_in_budget(late | {"improvements": [[0.12, 2.0]]})
    assert not report.solved_in_budget(late | {"solved": False})
    assert report.solved_in_budget(late | {"improvements": []})  # no curve: the record decides
    for metric in ("t_init", "c_init", "c_final"):
        assert report.record_value(late, metric) == math.inf
    parts = _summary()
    fixed = [r for r in parts["records"] if r["planner"] == "litstar-fixed"]
    for record in fixed[:5]:  # 5 of 8 runs: the median is infinite
        record["improvements"] = [[0.125, record["c_init"]]]
    summary = _write_summary(tmp_path, parts)
    entry = summary["scenarios"]["np4"]["planners"]["litstar-fixed"]
    assert entry["solved"] == 3 and entry["success_rate"] == 3 / 8
    assert entry["t_init"]["median"] == entry["c_init"]["median"] == "inf"
    assert entry["checks_init"]["median"] == "inf"
    assert summary["scenarios"]["np4"]["curves"]["litstar-fixed"]["success"][-1] == 3 / 8
    assert summary["comparisons"]["fit"]["rows"]["np4"]["paired"]["pairs"] == 8
    assert "3/8" in (tmp_path / "summary.md").read_text(encoding="utf-8")
    assert summary["statistics"]["paired_rule"] == report.PAIRED_RULE


@pytest.mark.parametrize(
    ("low", "high", "expected"),
    [
        (0.0117, 0.0152, ["0.012", "0.013", "0.014", "0.015"]),  # within a decade: 4 of 7 ticks
        (0.0032, 0.0167, ["0.005", "0.01"]),  # the 2s and 5s, and the decade
        (0.012, 0.3, ["0.02", "0.05", "0.1", "0.2"]),
        (0.0011, 2.0, ["0.01", "0.1", "1"]),  # three decades: the decades only
    ],
)
def test_time_axis_labels_are_few_and_plain(low: float, high: float, expected: list[str]) -> None:
    """A plot over less than two decades labelled every minor tick in scientific notation, and
    the labels ran into each other (a 15 ms budget's plot)."""
    import matplotlib.pyplot as plt
    from lit_planner.bench import plots

    figure, axes = plt.subplots()
    try:
        axes.step([low, high], [0.0, 1.0])
        axes.set_xscale("log")
        axes.set_xlim(low, high)
        plots._time_labels(axes)
        figure.canvas.draw()
        labels = [
            tick.label1.get_text()
            for tick in (*axes.xaxis.get_major_ticks(), *axes.xaxis.get_minor_ticks())
            if low <= tick.get_loc() <= high and tick.label1.get_text()
        ]
    finally:
        plt.close(figure)
    assert sorted(labels, key=float) == expected


def test_a_plot_where_nothing_solved_says_so(monkeypatch, tmp_path) -> None:
    """No planner solved a scenario without a known optimum (rrd4 at a tiny --time-scale): the
    cost panel was empty, its axis spanning 1.03e-9 to 1.08e-9."""
    import matplotlib.pyplot as plt
    from lit_planner.bench import plots

    assert plots.cost_limits([], [], None) == (1.0, 0.0)
    assert plots.cost_limits([], [], 0.5) == (plots.HEADROOM * 0.5, plots.FOOTROOM * 0.5)
    top, bottom = plots.cost_limits([2.0], [1.0], None)
    assert (top, bottom) == (plots.HEADROOM * 2.0, plots.FOOTROOM * 1.0)
    notes: list[str] = []
    original = plt.Axes.text

    def text(self, x, y, s, *args, **kwargs):
        notes.append(s)
        return original(self, x, y, s, *args, **kwargs)

    monkeypatch.setattr(plt.Axes, "text", text)
    times = np.array([0.01, 0.1])
    unsolved = stats.CostCurve(
        times=times, median=np.full(2, np.inf), lower=None, upper=None,
        minimum=np.full(2, np.inf), maximum=np.full(2, np.inf), success=np.zeros(2), ranks=None,
    )  # fmt: skip
    entry = {"t_init": {"median": math.inf}, "c_init": {"median": math.inf}}
    scenario = {"planners": {"aitstar": entry}, "optimal_cost": None, "time_budget": 0.1}
    paths = plots.plot_scenario("rrd4", scenario, {"aitstar": unsolved}, tmp_path)
    assert [path.name for path in paths] == ["rrd4.png", "rrd4.pdf"]
    assert notes == [plots.NO_MEDIAN_NOTE]


def test_the_note_says_what_made_the_tensors_it_played(tmp_path) -> None:
    """The summary called every tensor folder "trained lookup tensors", the constant baselines
    of `lit tensors constant` too, and named no folder."""
    import subprocess
    import sys

    from lit_planner.bench.runner import planner_setup

    folder = tmp_path / "constant"
    subprocess.run(
        [sys.executable, "-m", "lit_planner.cli", "tensors", "constant", "--b", "120",
         "--psi-k", "4.5", "--out", str(folder)],
        check=True, capture_output=True, timeout=120,
    )  # fmt: skip
    tensors = planner_setup("litstar-tensor", folder).to_dict()["tensors"]
    assert tensors["origins"] == {"B": "constant 120", "psi_K": "constant 4.5"}
    assert report.tensors_note(tensors) == (
        f"constant lookup tensors in `{folder}`: B constant 120; ψ_K constant 4.5"
    )
    # A learner's export: trained once its agent made gradient updates, UNTRAINED before (an
    # export of a run stopped in the B phase called its psi_K tensor trained).
    from lit_planner.bench.runner import tensor_origin

    from lit_planner import tensor_files

    values = np.full(tensor_files.TENSOR_SHAPE, 5.0, dtype=np.float32)
    for updates, origin in ((0, "UNTRAINED (initial weights), policy version 58"),
                            (12, "trained, policy version 58")):  # fmt: skip
        path = tmp_path / f"updates-{updates}" / "k_tensor.npy"
        path.parent.mkdir()
        tensor_files.write_tensor(
            path, values, "psi_K", training={"updates": updates}, policy_version=58
        )
        assert tensor_origin(path) == origin
    trained = {**tensors, "psi_K": None, "origins": {"B": "trained, policy version 7"}}
    assert (
        report.tensors_note(trained, str(tmp_path))
        == "lookup tensors in `constant`: B trained, policy version 7"
    )
    # Recorded before the setups named the origin: the folder alone.
    assert report.tensors_note({"folder": "/x", "B": "ab", "psi_K": None}) == (
        "the lookup tensors in `/x`"
    )

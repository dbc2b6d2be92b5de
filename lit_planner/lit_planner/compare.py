"""``lit compare``: LIT* against OMPL's planners on the same instances and seeds, with medians and ratios.

Every planner sees the same scenario instance and seed in each run; the planner order is shuffled per
run; each run starts from a fresh planner. Unsolved runs count as infinite time and cost, so a median
is infinite when half the runs or more failed. This is the quick comparison of the planning-core issue;
``lit bench`` (its own issue) adds confidence intervals, plots and Planner Arena export.
"""

from __future__ import annotations

import argparse
import json
import math
import random
import statistics
import sys
from collections.abc import Sequence
from typing import Any

from tqdm import tqdm

from lit_planner import planning, scenarios
from lit_planner.errors import LitPlannerError

DEFAULT_SCENARIOS = ("np8", "rrd8")
DEFAULT_PLANNERS = ("litstar-fixed", "aitstar")
METRICS = ("t_init", "c_init", "c_final")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scenarios", default=",".join(DEFAULT_SCENARIOS),
                        help="comma-separated scenario names (default: %(default)s)")
    parser.add_argument("--planners", default=",".join(DEFAULT_PLANNERS),
                        help="comma-separated planners; the first is compared with the others "
                             "(default: %(default)s)")
    parser.add_argument("--runs", type=int, default=20, help="runs (seeds) per planner (default: 20)")
    parser.add_argument("--seed", type=int, default=1, help="seed of the first run (default: 1)")
    parser.add_argument("--time", type=float, default=None,
                        help="time budget per run in seconds (default: each scenario's budget)")
    parser.add_argument("--json", metavar="FILE", help="also write every run and the medians as JSON")


def _median(values: Sequence[float]) -> float:
    return statistics.median(values) if values else math.inf


def run_comparison(scenario_names: Sequence[str], planners: Sequence[str], runs: int, first_seed: int,
                   time: float | None) -> dict[str, Any]:
    """Run every planner ``runs`` times on every scenario; return records and medians."""
    planning.quiet_ompl("aitstar")
    records: list[dict[str, Any]] = []
    total = len(scenario_names) * runs * len(planners)
    with tqdm(total=total, unit="run", file=sys.stderr, dynamic_ncols=True) as progress:
        for name in scenario_names:
            scenario = scenarios.get(name)
            for run in range(runs):
                seed = first_seed + run
                order = list(planners)
                random.Random(seed).shuffle(order)
                for planner in order:
                    progress.set_description(f"{name} {planner} run {run + 1}/{runs}")
                    result = planning.plan(scenario, planner, time=time, seed=seed)
                    solved = bool(result["solved"])
                    records.append({
                        "scenario": name, "planner": planner, "seed": seed, "solved": solved,
                        "t_init": result["t_init"] if solved else math.inf,
                        "c_init": result["c_init"] if solved else math.inf,
                        "c_final": result["cost"] if solved else math.inf,
                        "path_valid": bool(result["path_check"] and result["path_check"]["ok"]) if solved else None,
                    })
                    progress.update()
    medians: dict[str, dict[str, dict[str, float]]] = {}
    for name in scenario_names:
        medians[name] = {}
        for planner in planners:
            rows = [r for r in records if r["scenario"] == name and r["planner"] == planner]
            medians[name][planner] = {m: _median([r[m] for r in rows]) for m in METRICS}
            medians[name][planner]["success"] = sum(r["solved"] for r in rows) / max(len(rows), 1)
    return {"runs": runs, "first_seed": first_seed, "time": time, "records": records, "medians": medians}


def format_table(summary: dict[str, Any], planners: Sequence[str]) -> str:
    reference = planners[0]
    header = (f"| scenario | planner | success | median t_init (s) | median c_init | median c_final | "
              f"t_init {reference} / planner | c_init {reference} / planner |")
    lines = [header, "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for name, per_planner in summary["medians"].items():
        ref = per_planner[reference]
        for planner in planners:
            m = per_planner[planner]
            t_ratio = ref["t_init"] / m["t_init"] if m["t_init"] not in (0.0, math.inf) else math.nan
            c_ratio = ref["c_init"] / m["c_init"] if m["c_init"] not in (0.0, math.inf) else math.nan
            lines.append(f"| {name} | {planner} | {m['success']:.0%} | {m['t_init']:.4f} | {m['c_init']:.4f} | "
                         f"{m['c_final']:.4f} | {t_ratio:.2f} | {c_ratio:.2f} |")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    scenario_names = [s.strip() for s in args.scenarios.split(",") if s.strip()]
    planners = [p.strip() for p in args.planners.split(",") if p.strip()]
    if args.runs < 1 or not scenario_names or len(planners) < 1:
        print("lit compare: need at least one scenario, one planner and one run", file=sys.stderr)
        return 2
    try:
        for planner in planners:
            planning.resolve_planner(planner)
        for name in scenario_names:
            scenarios.get(name)
        summary = run_comparison(scenario_names, planners, args.runs, args.seed, args.time)
    except LitPlannerError as error:
        print(f"lit compare: {error}", file=sys.stderr)
        return 2
    print(format_table(summary, planners))
    invalid = [r for r in summary["records"] if r["solved"] and not r["path_valid"]]
    print(f"\n{len(summary['records'])} runs; {len(invalid)} returned paths failed the independent re-check. "
          f"Ratios > 1 mean {planners[0]} is slower / costlier.")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as handle:
            json.dump(planning.json_safe(summary), handle, indent=1)
    return 1 if invalid else 0

"""``lit crosscheck``: LIT* against an independent implementation of everything around it.

On each scenario, LIT* (Debian OMPL 1.5.2 building blocks, our C++ box-world checker) plans
``--runs`` times in this process, one seed per run. Then a separate process
(:mod:`lit_planner.ompl2.crosscheck`; PyPI ``ompl`` must not share a process with ``lit_core``)
takes the scenario as plain data and, with OMPL 2.0.1 and a numpy validity checker written from the
scenario definition (:mod:`lit_planner.ompl2.checker`):

1. re-validates every path LIT* returned: OMPL 2.0.1's own ``checkMotion`` on every segment at the
   scenario's resolution, a dense numpy check four times finer, the endpoints, and the reported cost
   against the path length OMPL 2.0.1 computes;
2. solves the same problem ``--runs`` times with OMPL 2.0.1's ``BITstar`` and ``InformedRRTstar``
   (path-length objective, the same resolution), re-validating their paths the same way.

Verdict. Every path must be valid, and no cost may lie below a scenario's known optimum (that
would need a path through an obstacle). The best costs must agree: for each OMPL 2.0.1 planner,
``|c_LIT* - c_OMPL| <= tolerance x min(c_LIT*, c_OMPL)``, with c the best final cost over the
runs. The default tolerance is 10 %: both planners are asymptotically optimal anytime planners
converging to the same optimum, so after long runs their best costs should be within a few per
cent of it and of each other; 10 % leaves room for the remaining convergence in a few seconds
(OMPL 2.0.1's planners also pay for a Python validity checker) while a wrong collision model, a
mis-reported cost or a planner stuck far from the optimum shows up as a larger gap.

The defaults are the R^4 instances. In R^8 (``--scenarios np8,rrd8``) the best costs do not agree
within seconds, and the table shows it: LIT* and the batch planners with a k-nearest graph (OMPL
2.0.1's BIT*, OMPL 1.5.2's BIT* and AIT*) stop improving within the first second on np8 (LIT*
0.611, BIT* 0.73), while Informed RRT* keeps improving (0.447 after 10 s). A brute-force Dijkstra
over LIT*'s own graph with exactly checked edges found no better path, so LIT* returns its graph's
optimum; what stalls is the k-nearest graph in the narrow passage, not the search. Exit status 0
when everything is valid and agrees, 1 otherwise, 2 on bad input or a failed worker.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time as clock
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from lit_planner import argtypes, ompl2, scenarios
from lit_planner.errors import LitPlannerError, PlannerError

DEFAULT_SCENARIOS = ("np4", "rrd4")
"""Scenarios of ``lit crosscheck`` without ``--scenarios``."""
OMPL2_PLANNERS = ("bitstar", "irrtstar")
"""OMPL 2.0.1 planners of the cross-check (PyPI ompl's BITstar and InformedRRTstar)."""
OMPL2_LABELS = {"bitstar": "OMPL 2.0.1 BIT*", "irrtstar": "OMPL 2.0.1 Informed RRT*"}
DEFAULT_LITSTAR = "litstar-fixed"
"""LIT* variant checked without ``--litstar``."""
DEFAULT_RUNS = 3
DEFAULT_TIME = 5.0
"""Seconds per run: long against the scenarios' budgets (0.12-0.4 s), so costs have converged."""
DEFAULT_TOLERANCE = 0.10
"""Relative tolerance on the best costs (see the module docstring for why 10 %)."""
OPTIMUM_SLACK = 1e-9
"""A cost below ``optimum x (1 - OPTIMUM_SLACK)`` is impossible for a valid path."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``lit crosscheck``."""
    parser.add_argument(
        "--scenarios",
        default=",".join(DEFAULT_SCENARIOS),
        help="comma-separated scenario names (default: %(default)s)",
    )
    parser.add_argument(
        "--runs",
        type=int,
        default=DEFAULT_RUNS,
        help="runs per planner and scenario; LIT* uses seeds SEED.. (default: %(default)s)",
    )
    parser.add_argument(
        "--time",
        type=float,
        default=DEFAULT_TIME,
        help="seconds per run, for every planner (default: %(default)s)",
    )
    parser.add_argument(
        "--seed",
        type=int,
        default=1,
        help="LIT*'s first seed; also seeds OMPL 2.0.1's generator (default: 1)",
    )
    parser.add_argument(
        "--litstar",
        default=DEFAULT_LITSTAR,
        choices=("litstar", "litstar-fixed", "litstar-fit", "litstar-tensor"),
        help="LIT* variant to check (default: %(default)s)",
    )
    parser.add_argument(
        "--tensors",
        metavar="DIR",
        type=argtypes.path,
        help="the tensors of --litstar litstar-tensor (default: $LIT_TENSORS, else the shipped "
        "tensors/)",
    )
    parser.add_argument(
        "--planners",
        default=",".join(OMPL2_PLANNERS),
        help="OMPL 2.0.1 planners, comma-separated, of bitstar and irrtstar (default: %(default)s)",
    )
    parser.add_argument(
        "--tolerance",
        type=float,
        default=DEFAULT_TOLERANCE,
        help="relative tolerance on the best costs (default: %(default)s)",
    )
    parser.add_argument(
        "--json",
        metavar="FILE",
        type=argtypes.path,
        help="also write every run and the verdict as JSON",
    )


def run(args: argparse.Namespace) -> int:
    """``lit crosscheck``: 0 all valid and agreeing, 1 otherwise, 2 bad input or worker failure."""
    from lit_planner.bag import write_problem

    if args.json:
        json_path = Path(args.json)
        problem = "a folder" if json_path.is_dir() else write_problem(json_path.parent)
        if problem is None and json_path.exists() and not _is_report(json_path):
            # It was written over (a walkthrough's world file, given by mistake).
            problem = "there, and not a lit crosscheck report (which is replaced); choose another"
        if problem is not None:  # asked now, not after the runs
            print(f"lit crosscheck: --json {args.json}: {problem}", file=sys.stderr)
            return 2
    try:
        names = scenarios.split_names(args.scenarios)
        planners = scenarios.split_names(args.planners)
        report = crosscheck(names, runs=args.runs, time=args.time, first_seed=args.seed,
                            litstar=args.litstar, planners=planners,
                            tolerance=args.tolerance, tensors_dir=args.tensors)  # fmt: skip
    except (LitPlannerError, ValueError) as error:
        print(f"lit crosscheck: {error}", file=sys.stderr)
        return 2
    print(format_table(report))
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)  # checked as creatable above
        Path(args.json).write_text(json.dumps(_json_safe(report), indent=1, allow_nan=False))
    return 0 if report["ok"] else 1


def _is_report(path: Path) -> bool:
    """Whether ``path`` holds a report of ``lit crosscheck --json`` (which a new one replaces)."""
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):
        return False
    return isinstance(document, dict) and {"ok", "rows", "scenarios"} <= document.keys()


def crosscheck(
    scenario_names: Sequence[str],
    *,
    runs: int = DEFAULT_RUNS,
    time: float = DEFAULT_TIME,
    first_seed: int = 1,
    litstar: str = DEFAULT_LITSTAR,
    planners: Sequence[str] = OMPL2_PLANNERS,
    tolerance: float = DEFAULT_TOLERANCE,
    tensors_dir: Path | None = None,
) -> dict[str, Any]:
    """Run the cross-check; the report behind the table (rows, verdicts, raw runs, processes).

    Raises:
        ScenarioError, PlannerError: unknown scenario or planner, bad numbers.
        MissingTensorsError, TensorFileError: ``litstar-tensor`` without usable tensors.
        lit_planner.ompl2.Ompl2Error: the OMPL 2.0.1 worker failed.
    """
    from lit_planner import planning  # imports lit_core: this process never imports PyPI ompl

    if runs < 1:
        raise ValueError(f"--runs must be at least 1, got {runs}")
    if not (math.isfinite(time) and time > 0):
        raise ValueError(f"--time must be a finite positive number of seconds, got {time}")
    if time > planning.MAX_TIME:  # refused by the first plan, after the run's first line
        raise ValueError(f"--time must be at most {planning.MAX_TIME:g} s, got {time:g}")
    if not (math.isfinite(tolerance) and tolerance >= 0):
        raise ValueError(f"--tolerance must be a non-negative fraction, got {tolerance}")
    unknown = [name for name in planners if name not in OMPL2_PLANNERS]
    if unknown or not planners:
        raise ValueError(f"OMPL 2.0.1 planners must be among {', '.join(OMPL2_PLANNERS)}, "
                         f"got {', '.join(planners) or 'none'}")  # fmt: skip
    problems = [scenarios.get(name) for name in scenario_names]
    if not problems:
        raise ValueError("no scenarios given")
    # A name given twice ran twice and pooled both runs in rows printed twice (as lit bench).
    scenarios.refuse_duplicates("scenario", [problem.key for problem in problems])  # np4 = np4/0
    scenarios.refuse_duplicates("planner", planners)
    # The first and the last seed (a seed per run: one check each took minutes for a huge --runs).
    planning.check_seed(first_seed)
    try:
        planning.check_seed(first_seed + runs - 1)
    except PlannerError:
        raise PlannerError(
            f"--runs {runs} from seed {first_seed} reaches seed {first_seed + runs - 1}, beyond "
            f"the largest, {planning.MAX_SEED}"
        ) from None
    planning.quiet_ompl(litstar)
    # The tensor policy's files are read (and checked) once, before the first run.
    _, policy_name = planning.resolve_planner(litstar)
    if tensors_dir is not None and policy_name != "tensor":
        raise ValueError(f"--tensors is for --litstar litstar-tensor, not {litstar}")
    policy = planning.make_policy("tensor", tensors_dir) if policy_name == "tensor" else None

    rows: list[dict[str, Any]] = []
    details: list[dict[str, Any]] = []
    for scenario in problems:
        began = clock.perf_counter()
        lit_runs = []
        for seed in range(first_seed, first_seed + runs):
            print(f"lit crosscheck: {scenario.key} {litstar} seed {seed}", file=sys.stderr,
                  flush=True)  # fmt: skip
            result = planning.plan_interruptibly(scenario, litstar, policy, time=time, seed=seed)
            lit_runs.append({
                "planner": litstar, "seed": seed, "solved": bool(result["solved"]),
                "status": result["status"], "t_init": result["t_init"],
                "c_init": result["c_init"], "c_final": result["cost"],
                "improvements": result["improvements"], "path": result["path"],
            })  # fmt: skip
        response = ompl2.run_worker("crosscheck", {
            "scenario": scenario.to_dict(),
            "paths": [{"label": f"{litstar} seed {r['seed']}", "path": r["path"],
                       "cost": r["c_final"]} for r in lit_runs if r["solved"]],
            "planners": list(planners), "runs": runs, "time": time, "seed": first_seed,
        })  # fmt: skip
        if response["process"].get("lit_core_loaded"):
            raise ompl2.Ompl2Error(
                "the OMPL 2.0.1 worker reports lit_core loaded; refusing its results"
            )
        validations = iter(response["validations"])
        for lit_run in lit_runs:
            lit_run["validation"] = next(validations) if lit_run["solved"] else None
            lit_run.pop("path")
        scenario_rows = _rows(scenario, litstar, lit_runs, response["runs"], planners, tolerance)
        rows += scenario_rows
        details.append({
            "scenario": scenario.key, "optimal_cost": scenario.optimal_cost,
            "litstar_runs": lit_runs, "ompl2_runs": response["runs"],
            "ompl2_process": response["process"], "ompl_version": response.get("ompl_version"),
            "seconds": clock.perf_counter() - began,
        })  # fmt: skip
    return {
        "ok": all(row["ok"] for row in rows),
        "tolerance": tolerance,
        "time": time,
        "runs": runs,
        "first_seed": first_seed,
        "litstar": litstar,
        "rows": rows,
        "scenarios": details,
    }


def agree(cost_a: float | None, cost_b: float | None, tolerance: float) -> bool:
    """Whether two best costs agree: both finite and ``|a - b| <= tolerance x min(a, b)``."""
    if cost_a is None or cost_b is None or not (math.isfinite(cost_a) and math.isfinite(cost_b)):
        return False
    return abs(cost_a - cost_b) <= tolerance * min(cost_a, cost_b)


def _rows(
    scenario: scenarios.Scenario,
    litstar: str,
    lit_runs: Sequence[Mapping[str, Any]],
    ompl_runs: Sequence[Mapping[str, Any]],
    planners: Sequence[str],
    tolerance: float,
) -> list[dict[str, Any]]:
    """One row per planner: runs, solved, valid paths, best and median final cost, agreement."""
    lit_row = _row(scenario, litstar, litstar, lit_runs)
    rows = [lit_row]
    for name in planners:
        row = _row(
            scenario, name, OMPL2_LABELS[name], [r for r in ompl_runs if r["planner"] == name]
        )
        row["difference"] = _difference(lit_row["best_cost"], row["best_cost"])
        row["agrees"] = agree(lit_row["best_cost"], row["best_cost"], tolerance)
        row["ok"] = row["ok"] and row["agrees"]
        rows.append(row)
    lit_row["agrees"] = all(row["agrees"] for row in rows[1:])
    lit_row["ok"] = lit_row["ok"] and lit_row["agrees"]
    return rows


def _row(
    scenario: scenarios.Scenario, planner: str, label: str, runs: Sequence[Mapping[str, Any]]
) -> dict[str, Any]:
    solved = [r for r in runs if r["solved"]]
    valid = [r for r in solved if r.get("validation") and r["validation"]["valid"]]
    finals = [float(r["c_final"]) for r in solved]
    costs = finals if len(solved) == len(runs) else finals + [math.inf] * (len(runs) - len(solved))
    best = min(finals) if finals else None
    optimum = scenario.optimal_cost
    below_optimum = (
        optimum is not None and best is not None and best < optimum * (1 - OPTIMUM_SLACK)
    )
    return {
        "scenario": scenario.key,
        "planner": planner,
        "label": label,
        "runs": len(runs),
        "solved": len(solved),
        "paths_valid": len(valid),
        "best_cost": best,
        "median_final_cost": statistics.median(costs) if costs else None,
        "optimal_cost": optimum,
        "gap_to_optimum": None if optimum is None or best is None else best / optimum - 1,
        "below_optimum": below_optimum,
        "difference": None,
        "agrees": None,
        "ok": len(valid) == len(solved) and not below_optimum,
    }


def _difference(reference: float | None, other: float | None) -> float | None:
    """Relative difference ``(other - reference) / min(reference, other)``."""
    if reference is None or other is None:
        return None
    return (other - reference) / min(reference, other)


def format_table(report: Mapping[str, Any]) -> str:
    """The cross-check table in Markdown, with the verdict below it."""
    tolerance = report["tolerance"]
    lines = [
        (
            f"lit crosscheck: {report['runs']} run(s) of {report['time']:g} s per planner; LIT* = "
            f"{report['litstar']} (lit_core, this process), OMPL 2.0.1 planners and the "
            "independent numpy checker in a separate process"
        ),
        "",
        (
            "| scenario | planner | runs | solved | paths valid (independent) | best cost | "
            "median final cost | gap to optimum | vs LIT* | agreement |"
        ),
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for row in report["rows"]:
        is_lit = row["difference"] is None and row["planner"] == report["litstar"]
        agreement = ("reference" if row["agrees"] else "no") if is_lit else (
            "yes" if row["agrees"] else "no")  # fmt: skip
        if is_lit and row["agrees"]:
            agreement = "reference (all agree)"
        lines.append(
            f"| {row['scenario']} | {row['label']} | {row['runs']} | {row['solved']} | "
            f"{row['paths_valid']}/{row['solved']} | {_cost(row['best_cost'])} | "
            f"{_cost(row['median_final_cost'])} | {_percent(row['gap_to_optimum'])}"
            f"{' (BELOW OPTIMUM)' if row['below_optimum'] else ''} | "
            f"{'' if is_lit else _percent(row['difference'])} | {agreement} |"
        )
    optima = {row["scenario"]: row["optimal_cost"] for row in report["rows"] if row["optimal_cost"]}
    lines.append("")
    if optima:
        families = {scenarios.get(row["scenario"]).family for row in report["rows"]}
        notes = [note for family, note in (("np", "NP's is the infimum through the slab"),
                                           ("wg", "WG's the infimum through the gap"))
                 if family in families]  # fmt: skip
        if families - {"np", "wg"}:
            notes.append("random scenarios have none")
        lines.append("Known optima: " + ", ".join(f"{name} {cost:.4f}" for name, cost in optima.items())
                     + f" ({'; '.join(notes)}).")  # fmt: skip
    lines.append(
        f"Agreement: |c_LIT* - c_OMPL| <= {tolerance:.0%} x min(c_LIT*, c_OMPL) on the best final "
        "costs over the runs; vs LIT* = (c_OMPL - c_LIT*) / min(...)."
    )
    invalid = sum(row["solved"] - row["paths_valid"] for row in report["rows"])
    disagreements = [f"{row['scenario']} {row['label']}" for row in report["rows"]
                     if row["agrees"] is False and row["difference"] is not None]  # fmt: skip
    below = [f"{row['scenario']} {row['label']}" for row in report["rows"] if row["below_optimum"]]
    if report["ok"]:
        lines.append("lit crosscheck: OK: every path valid under the independent checker, "
                     "best costs agree")  # fmt: skip
    else:
        problems = []
        if invalid:
            problems.append(f"{invalid} invalid path(s)")
        if below:
            problems.append(f"cost below the known optimum: {', '.join(below)}")
        if disagreements:
            problems.append(f"best costs disagree: {', '.join(disagreements)}")
        uncompared = [f"{row['scenario']} {row['label']}" for row in report["rows"]
                      if row["agrees"] is False and row["difference"] is None
                      and row["planner"] != report["litstar"]]  # fmt: skip
        if uncompared:  # the line used to end empty ("FAILED: ")
            problems.append(
                "no best costs to compare (no solution in LIT*'s runs, the planner's, or both): "
                + ", ".join(uncompared)
            )
        lines.append("lit crosscheck: FAILED: " + ("; ".join(problems) or "see the table above"))
    return "\n".join(lines)


def _cost(value: float | None) -> str:
    if value is None or not math.isfinite(value):
        return "—"
    return f"{value:.4f}"


def _percent(value: float | None) -> str:
    if value is None or not math.isfinite(value):
        return "—"
    return f"{value:+.1%}"


def _json_safe(value: Any) -> Any:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, Mapping):
        return {str(key): _json_safe(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(item) for item in value]
    return value

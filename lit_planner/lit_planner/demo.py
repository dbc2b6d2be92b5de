"""``lit demo``: the main job. For now: plan the default scenario (narrow passage in R^8) with LIT*
and print what happened: times, costs against the known optimum, counts, and the independent
re-check of the path.

Later issues extend the job (planner and learner nodes, a recorded bag, a summary table); each
step is one small function called from :func:`run`.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

import lit_core

from lit_planner import plan_cli, planning, scenarios
from lit_planner.errors import LitPlannerError
from lit_planner.scenarios import Scenario

DEMO_PLANNER = planning.LITSTAR
"""The planner the demo runs."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``lit demo``."""
    parser.add_argument(
        "--scenario",
        default=scenarios.DEFAULT_SCENARIO,
        help="scenario name (default: %(default)s, the narrow passage in R^8)",
    )
    parser.add_argument(
        "--policy",
        default=planning.DEFAULT_POLICY,
        choices=planning.NAMED_POLICIES,
        help="LIT*'s parameter policy (default: %(default)s)",
    )
    parser.add_argument("--seed", type=int, default=1, help="seed (default: %(default)s)")
    parser.add_argument(
        "--time", type=float, metavar="SECONDS", help="time budget (default: the scenario's)"
    )


def run(args: argparse.Namespace) -> int:
    """Run the demo; 0 when the plan is solved and its path passes the re-check."""
    try:
        scenario = scenarios.get(args.scenario)
        result = plan_scenario(scenario, args.policy, args.seed, args.time)
    except LitPlannerError as error:
        print(f"lit demo: {error}", file=sys.stderr)
        return plan_cli.EXIT_BAD_INPUT
    print_summary(result, scenario)
    check = result["path_check"]
    return 0 if result["solved"] and check is not None and check["ok"] else 1


def plan_scenario(scenario: Scenario, policy: str, seed: int, time: float | None) -> dict[str, Any]:
    """Plan ``scenario`` with LIT* and ``policy`` on the scenario's budget unless ``time`` is set."""
    planning.check_seed(seed)
    planning.quiet_ompl(DEMO_PLANNER)
    lit_core.set_global_seed(seed)
    return planning.plan(scenario, DEMO_PLANNER, policy, time=time, seed=seed)


def print_summary(result: dict[str, Any], scenario: Scenario) -> None:
    """The plan in a few lines."""
    print(f"LIT* demo: {result['planner']} on {scenario.key}")
    print("\n".join(plan_cli.summary_lines(result, scenario)))

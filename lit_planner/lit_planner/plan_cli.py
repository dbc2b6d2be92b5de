"""``lit plan``: plan one scenario with one planner and print the result.

::

    lit plan --scenario np8 --planner litstar --policy fixed --time 1.0 --seed 7 --json

With ``--json`` the output is exactly one JSON object on one line: everything
:func:`lit_planner.planning.plan` returns, with ``null`` for every infinite float (an unsolved
run's ``cost``, ``t_init`` and ``c_init``). Without it, a readable summary.

Exit status: 0 solved, 1 planned but no exact solution, 2 bad input (unknown scenario, planner or
policy, missing or defective tensors; lit's main adds an answer that could not be written), 3
solved with a path that failed the independent re-check, 130 interrupted; errors are one line on
stderr.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Mapping
from typing import Any

import lit_core

from lit_planner import argtypes, planning, scenarios
from lit_planner.errors import LitPlannerError, PlannerError
from lit_planner.scenarios import Scenario

EXIT_SOLVED = 0
"""The planner found an exact solution."""
EXIT_UNSOLVED = 1
"""The planner ran but found no exact solution (see ``status`` and ``message``)."""
EXIT_BAD_INPUT = 2
"""The query could not be set up; nothing was planned."""
EXIT_PATH_INVALID = 3
"""The planner found a solution whose path failed the independent re-check (``path_check.ok``
false, as ``lit call``'s ``path_valid``)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``lit plan``."""
    parser.add_argument(
        "--scenario",
        default=scenarios.DEFAULT_SCENARIO,
        help="scenario name such as np8, wg4, rr16, rrd8 or rrd8/3 (default: %(default)s)",
    )
    parser.add_argument(
        "--instance", type=int, help="instance of a random family (rr, rrd); default 0"
    )
    parser.add_argument(
        "--planner",
        default=planning.LITSTAR,
        metavar="NAME",
        help=f"one of {', '.join(planning.PLANNER_CHOICES)} (default: %(default)s)",
    )
    parser.add_argument(
        "--policy",
        metavar="NAME",
        help=f"LIT*'s parameter policy: {', '.join(planning.NAMED_POLICIES)} "
        f"(default: {planning.DEFAULT_POLICY})",
    )
    parser.add_argument(
        "--time",
        type=float,
        metavar="SECONDS",
        help="time budget (default: the scenario's; LIT* with --iterations or --batches: none)",
    )
    parser.add_argument("--seed", type=int, default=1, help="seed (default: %(default)s)")
    parser.add_argument(
        "--iterations",
        type=int,
        default=0,
        metavar="N",
        help="LIT*: stop after N iterations (default: 0, no limit)",
    )
    parser.add_argument(
        "--batches",
        type=int,
        default=0,
        metavar="N",
        help="LIT*: stop after N batches (default: 0, no limit)",
    )
    parser.add_argument(
        "--tensors",
        type=argtypes.path,
        metavar="DIR",
        help="tensor policy: folder with b_tensor.npy / k_tensor.npy "
        f"(default: ${planning.TENSORS_ENV} or the checkout's tensors/)",
    )
    parser.add_argument(
        "--interpolation",
        choices=tuple(planning.INTERPOLATIONS),
        default=None,
        help="tensor policy lookup (default: the one the sidecars name; trilinear for lit train exports)",
    )
    parser.add_argument(
        "--json", action="store_true", help="print one JSON object (null for infinite values)"
    )


def run(args: argparse.Namespace) -> int:
    """Plan as ``args`` say; the exit status of ``lit plan``."""
    try:
        scenario = scenarios.get(args.scenario, args.instance)
        _check_policy_name(args.policy)
        planner, policy = planning.resolve_planner(args.planner, args.policy)
        planning.check_seed(args.seed)
        planning.check_count(args.iterations, "--iterations")
        planning.check_count(args.batches, "--batches")
        if policy != "tensor" and (args.tensors is not None or args.interpolation is not None):
            raise PlannerError(
                f"--tensors and --interpolation are for the tensor policy, not for "
                f"{policy or planner}"
            )
        if args.seed == 0 and planner != planning.LITSTAR:
            # OMPL's generator takes 0 as 1 (with a warning the baselines' log level hides):
            # --seed 0 was silently the run of --seed 1.
            raise PlannerError(
                f"{planner} is seeded through OMPL's generator, which cannot take seed 0 (it "
                "would plan the run of --seed 1); give a seed from 1"
            )
        planning.quiet_ompl(planner)
        # LIT* plans with its own seed, 0 included; OMPL's global generator (which LIT* does not
        # draw from) would warn about 0 and use 1.
        lit_core.set_global_seed(planning.ompl_global_seed(args.seed))
        result = planning.plan_interruptibly(
            scenario,
            planner,
            policy,
            time=args.time,
            seed=args.seed,
            max_iterations=args.iterations,
            max_batches=args.batches,
            tensors_dir=args.tensors,
            interpolation=args.interpolation,
        )
    except LitPlannerError as error:
        print(f"lit plan: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if policy == "tensor":
        _warn_of_untrained_tensors(args.tensors)
    if args.json:
        print(json.dumps(planning.json_safe(result), allow_nan=False))
    else:
        print("\n".join(summary_lines(result, scenario)))
    if not result["solved"]:
        return EXIT_UNSOLVED
    check = result.get("path_check")
    # ok, as the summary's verdict and the planner node's path_valid: also a path that does not
    # start at the start or end at the goal (valid covers collisions only).
    return EXIT_PATH_INVALID if check is not None and not check["ok"] else EXIT_SOLVED


def _warn_of_untrained_tensors(tensors: Any) -> None:
    """Say on stderr which tensor of the folder is a learner's export of an agent that made no
    gradient update (the learner node's export early in its training, or an older ``lit train``
    export of a run stopped before that agent trained): the policy plays its initial actor (psi_K
    about 9, not the fixed e that a folder without the file gives)."""
    from pathlib import Path

    from lit_planner.bench.runner import tensor_origin

    folder = Path(tensors) if tensors is not None else planning.default_tensors_dir()
    for name in planning.TENSOR_FILES.values():
        path = folder / name
        origin = tensor_origin(path) if path.exists() else None
        if origin is not None and origin.startswith("UNTRAINED"):
            print(
                f"lit plan: warning: {path} is {origin}: its agent made no gradient update, so it "
                "decides as an untrained actor (without the file its fixed value applies)",
                file=sys.stderr,
            )


def _check_policy_name(policy: str | None) -> None:
    """Refuse a policy the command line cannot configure, naming only those it can.

    :func:`lit_planner.planning.resolve_planner` knows ``external`` too, which needs a callable.
    """
    if policy == "external":
        raise PlannerError(
            "the external policy needs a callable and is not available on the command line"
        )
    if policy is not None and policy not in planning.NAMED_POLICIES:
        raise PlannerError(
            f"unknown policy {policy!r}; expected one of {', '.join(planning.NAMED_POLICIES)}"
        )


def summary_lines(result: Mapping[str, Any], scenario: Scenario) -> list[str]:
    """A readable summary of a :func:`lit_planner.planning.plan` result."""
    counters = result["counters"]
    policy = f" (policy {result['policy']})" if result.get("policy") else ""
    budget = result.get("time_budget")
    status = result["status"]
    if status == "timeout" and (not budget or result["time"] < budget):
        # OMPL's name for any stop: here a count limit (or a cancel) before the time budget
        status = "stopped before the time budget (iteration or batch limit)"
    lines = [
        f"scenario   {scenario.key}: {scenario.description}",
        f"planner    {result['planner']}{policy}, seed {result['seed']}, "
        + (f"budget {_duration(budget)}" if budget else "no time limit"),
        f"status     {status}: {'solved' if result['solved'] else 'not solved'}"
        + (f" ({result['message']})" if result.get("message") else ""),
    ]
    if result["improvements"]:
        lines.append(
            f"first      t_init {_duration(result['t_init'])}, c_init {result['c_init']:.4f}"
        )
    if result["solved"]:
        cost, optimum = result["cost"], result.get("optimal_cost")
        versus = f" (optimum {optimum:.4f}, ratio {cost / optimum:.3f})" if optimum else ""
        better = len(result["improvements"]) - 1  # the list starts with the first solution
        lines.append(
            f"final      cost {cost:.4f}{versus}, "
            + (f"the first solution improved {better} time(s)" if better else "the first solution")
        )
    lines.append(f"time       {_duration(result['time'])} planning")
    if "batches" in counters:
        samples = (
            f"{counters['valid_samples']} valid, {counters['invalid_samples']} invalid, "
            f"{counters['pruned_samples']} pruned, in {counters['batches']} batches"
        )
        edges = (
            f"{counters['edges_evaluated']} fully checked by the forward search, "
            f"{counters.get('edges_sparsely_checked', 0)} sparsely by the reverse search, "
            f"{counters['edges_invalid']} found invalid"
        )
        lines += [f"samples    {samples}", f"edges      {edges}"]
    checks = f"checks     {counters['validity_checks']} collision checks"
    if result.get("checks_init") is not None:
        checks += f", {result['checks_init']} up to the first solution"
    lines.append(checks)
    check = result.get("path_check")
    if check is not None:
        verdict = "passed" if check["ok"] else "FAILED"
        lines.append(
            f"path       {len(result['path'])} states; independent re-check {verdict} "
            f"({check['points_checked']} points, length {check['cost']:.4f})"
        )
    return lines


def _duration(seconds: float) -> str:
    if not math.isfinite(seconds):
        return "-"
    if 0.0 < seconds < 5e-5:  # "0.0 ms" for a budget of 1e-9 s
        return f"{seconds * 1e6:.3g} µs"
    return f"{seconds * 1e3:.1f} ms" if seconds < 1.0 else f"{seconds:.3f} s"

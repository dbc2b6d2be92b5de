"""``lit demo``: the main job, as the distributed system a user would run.

1. The bag recorder, the learner and a planner start as three ROS 2 processes (:mod:`lit_up`'s
   :class:`~lit_planner.up.System`; localhost discovery, their own domain id).
2. The planner runs a few training episodes over ROS: each B / psi_K decision is a call to the
   learner's ``/lit/learner/decide``; the learner trains at episode ends.
3. This process then calls ``/lit/planner/plan`` as any robot program would: inference plans on the
   default scenario (narrow passage in R^8) with the shipped tensors, and re-checks each returned
   path itself.
4. Everything is stopped in order; the bag under ``bags/<run>/`` is summarised with
   ``lit replay info`` and the results are printed as a table.

``--local`` runs the single-process version instead (plan once with the C++ core, no ROS).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import sys
import threading
import time
from pathlib import Path
from typing import Any, Self

from lit_planner import argtypes, plan_cli, planning, scenarios
from lit_planner.errors import LitPlannerError
from lit_planner.rosutil import MAX_EPISODE_BUDGET, add_domain_option, resolve_domain_id
from lit_planner.scenarios import Scenario

DEMO_PLANNER = planning.LITSTAR
"""The planner the demo runs."""
DEMO_DOMAIN_ID = 91
"""Default ROS domain of the demo (its own, so it does not meet a running ``lit up``)."""
DISTRIBUTED_DEFAULTS = {"training_episodes": 4, "training_budget": 0.3, "plans": 3}
"""Defaults of the options of the ROS demo alone (``--local`` refuses them)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``lit demo``."""
    parser.add_argument(
        "--scenario",
        default=scenarios.DEFAULT_SCENARIO,
        help="scenario of the inference plans (default: %(default)s, the narrow passage in R^8)",
    )
    parser.add_argument(
        "--policy",
        default="tensor",
        choices=planning.NAMED_POLICIES,
        help="LIT*'s policy for the inference plans (default: %(default)s)",
    )
    parser.add_argument("--seed", type=int, default=1, help="first seed (default: %(default)s)")
    parser.add_argument(
        "--time", type=float, metavar="SECONDS", help="inference time budget (default: scenario's)"
    )
    parser.add_argument(
        "--training-episodes",
        type=int,
        metavar="N",
        help="training episodes over ROS before the plans (default: 4; 0: none)",
    )
    parser.add_argument(
        "--training-budget",
        type=float,
        metavar="SECONDS",
        help="planner time of each training episode (default: 0.3)",
    )
    parser.add_argument("--plans", type=int, help="inference plans (default: 3)")
    add_domain_option(parser, DEMO_DOMAIN_ID)
    parser.add_argument(
        "--out",
        type=argtypes.path,
        default=None,
        help="folder for the bag and the learner's files (default: <run> in the repository's "
        "bags/ and runs/<run> under the current folder)",
    )
    parser.add_argument("--local", action="store_true", help="one process, no ROS: plan once")


def run(args: argparse.Namespace) -> int:
    """Run the demo; 0 when every inference plan is solved and its path passes the re-check."""
    try:
        given = [
            "--" + name.replace("_", "-")
            for name in (*DISTRIBUTED_DEFAULTS, "out", "domain_id")
            if getattr(args, name) is not None
        ]
        if args.local and given:  # they were ignored
            raise LitPlannerError(
                f"--local plans once in this process, without ROS: {', '.join(given)} "
                f"{'applies' if len(given) == 1 else 'apply'} to the ROS demo only"
            )
        for name, default in DISTRIBUTED_DEFAULTS.items():
            if getattr(args, name) is None:
                setattr(args, name, default)
        scenario = scenarios.get(args.scenario)
        planning.check_seed(args.seed)
        if args.time is not None and not (math.isfinite(args.time) and args.time > 0):
            raise LitPlannerError(
                f"--time must be a finite positive number of seconds, got {args.time}"
            )
        if not args.local and (args.plans < 1 or args.training_episodes < 0):
            raise LitPlannerError(
                f"--plans must be 1 or more and --training-episodes 0 or more, got {args.plans} "
                f"and {args.training_episodes}"
            )
        if not args.local and args.seed + args.plans - 1 > planning.MAX_SEED:
            # Checked here, not by the planner node after the training (a traceback, exit 1).
            raise LitPlannerError(
                f"--seed {args.seed} with --plans {args.plans} plans seeds up to "
                f"{args.seed + args.plans - 1}; the largest seed is {planning.MAX_SEED}"
            )
        budget = args.training_budget
        if not args.local and not (math.isfinite(budget) and 0 < budget <= MAX_EPISODE_BUDGET):
            raise LitPlannerError(
                f"--training-budget must be a finite positive number of seconds up to "
                f"{MAX_EPISODE_BUDGET:g}, got {budget}"
            )
        if not args.local:
            try:
                args.domain_id = resolve_domain_id(args.domain_id, DEMO_DOMAIN_ID)
            except ValueError as error:
                raise LitPlannerError(str(error)) from None
            from lit_planner.bag import write_problem

            problem = None if args.out is None else write_problem(args.out)
            if problem is not None:  # the recorder found it after the start, in a traceback
                raise LitPlannerError(f"--out {args.out}: {problem}")
    except LitPlannerError as error:
        print(f"lit demo: {error}", file=sys.stderr)
        return plan_cli.EXIT_BAD_INPUT
    if args.local:
        result = plan_scenario(scenario, args.policy, args.seed, args.time)
        print_summary(result, scenario)
        check = result["path_check"]
        return 0 if result["solved"] and check is not None and check["ok"] else 1
    return run_distributed(args, scenario)


def plan_scenario(scenario: Scenario, policy: str, seed: int, time: float | None) -> dict[str, Any]:
    """Plan ``scenario`` with LIT* and ``policy`` on the scenario's budget unless ``time`` is set."""
    import lit_core

    planning.quiet_ompl(DEMO_PLANNER)
    lit_core.set_global_seed(planning.ompl_global_seed(seed))
    return planning.plan(scenario, DEMO_PLANNER, policy, time=time, seed=seed)


def print_summary(result: dict[str, Any], scenario: Scenario) -> None:
    """The plan in a few lines."""
    print(f"LIT* demo: {result['planner']} on {scenario.key}")
    print("\n".join(plan_cli.summary_lines(result, scenario)))


# ---------------------------------------------------------------------------- distributed


def run_distributed(args: argparse.Namespace, scenario: Scenario) -> int:
    """Steps 1-4 of the module docstring."""
    from lit_planner.bag import default_bag_root
    from lit_planner.rosutil import native_output_to_stderr
    from lit_planner.up import DomainBusy, System, claim_domain, stop_on_sigterm

    run_id = time.strftime("demo-%Y%m%d-%H%M%S")
    try:
        claim = claim_domain(args.domain_id, f"lit demo (run {run_id})")
    except DomainBusy as error:
        print(f"lit demo: {error}", file=sys.stderr)
        return 2
    # Fast DDS writes its own errors (a stale shared-memory lock, after which it carries on) to
    # descriptor 1, in the middle of the demo's report: they go to standard error.
    native_output_to_stderr()
    runs = (args.out or Path("runs")) / run_id
    bag = (args.out or default_bag_root()) / (f"{run_id}-bag" if args.out else run_id)
    system = System(args.domain_id, Path.cwd(), echo=_quiet_echo)
    print(f"lit demo: run {run_id}, ROS_DOMAIN_ID={args.domain_id} (localhost discovery)")
    print("  starting recorder, planner and learner as three processes ...", flush=True)
    training: list[dict[str, Any]] = []
    plans: list[tuple[int, dict[str, Any] | None, str]] = []
    started = time.monotonic()
    stop_on_sigterm()
    stopped: dict[str, int | None] = {}
    attempted = []

    def stop_once() -> dict[str, int | None]:
        """Stop the nodes in order and release the domain, once; their exit codes."""
        if not attempted:
            attempted.append(True)
            try:
                stopped.update(system.stop())
            finally:
                claim.close()
        return stopped

    try:
        system.start("recorder", "lit_recorder_node", {"bag": str(bag), "run_id": run_id})
        system.wait_ready("recorder")
        with _Client(system, run_id) as client:
            # Episodes wait for this process and the recorder to subscribe (volatile topics).
            system.start(
                "planner",
                "lit_planner_node",
                {
                    "policy": "training",
                    "episodes": args.training_episodes,
                    "time_budget": float(args.training_budget),
                    "run_id": run_id,
                    "learner_wait": 120.0,
                    "wait_for_subscribers": 2,
                },
            )
            system.start(
                "learner",
                "lit_learner_node",
                {
                    "checkpoint": str(runs / "learner" / "checkpoint.pt"),
                    "export_dir": str(runs / "learner" / "tensors"),
                    "run_id": run_id,
                    "wait_for_subscribers": 1,  # its stats from the first the recorder hears
                },
            )
            system.wait_ready("planner")
            system.wait_ready("learner")
            print(
                f"  training: {args.training_episodes} episodes over ROS "
                f"({args.training_budget:g} s planner time each) ..."
                if args.training_episodes
                else "  training: none (--training-episodes 0)",
                flush=True,
            )
            training = client.wait_episodes(args.training_episodes, timeout=600.0)
            for i in range(args.plans):
                seed = args.seed + i
                payload = {"scenario": scenario.key, "policy": args.policy, "seed": seed}
                if args.time is not None:
                    payload["time"] = args.time
                print(f"  inference: /lit/planner/plan {json.dumps(payload)}", flush=True)
                plans.append((seed, *client.plan(payload)))
    except (RuntimeError, TimeoutError, KeyboardInterrupt) as error:
        interrupted = isinstance(error, KeyboardInterrupt)
        reason = "interrupted" if interrupted else str(error)
        print(
            f"lit demo: {reason}; stopping the nodes (the learner writes its checkpoint and "
            "tensors first)",
            file=sys.stderr,
            flush=True,
        )
        codes = stop_once()
        _print_bag(bag)
        _print_stopped(codes, time.monotonic() - started)
        return 130 if interrupted else 1
    finally:
        stop_once()  # any other error too: the nodes stop in order
    codes = stop_once()
    wall = time.monotonic() - started
    budget = args.time if args.time is not None else scenario.time_budget
    status = _report(scenario, training, plans, codes, bag, wall, budget)
    if system.stop_interrupts:  # the work was done, the user still interrupted us (it said 0)
        print(
            "lit demo: interrupted while the nodes stopped (they stopped in order)",
            file=sys.stderr,
        )
        return 130
    return status


def _quiet_echo(line: str) -> None:
    """Show the nodes' warnings and errors only (the demo prints its own account)."""
    if "[WARN]" in line or "[ERROR]" in line or "Traceback" in line:
        print(f"    {line}", flush=True)


def _ignore(_: object) -> None:
    """Callback of the subscriptions that only need to exist."""


class _Client:
    """This process's own node: subscribes to episodes, calls the plan service."""

    def __init__(self, system: Any, run_id: str) -> None:
        self.system = system
        self.run_id = run_id

    def __enter__(self) -> Self:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from std_msgs.msg import String
        from trajectory_msgs.msg import JointTrajectory

        from lit_planner.rosutil import PLAN_SERVICE, TOPICS, ServiceCaller, json_qos

        os.environ.update({k: v for k, v in self.system.env.items() if k.startswith("ROS_")})
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node("lit_demo", context=self.context)
        self.episodes: list[dict[str, Any]] = []
        self.changed = threading.Condition()
        self.node.create_subscription(String, "/lit/episode", self._on_episode, json_qos())
        # The other topics too (ignored), so that the planner's ``wait_for_subscribers: 2``
        # (this process and the recorder on every topic) holds its episodes until we listen.
        for topic in ("observation", "decision", "solution"):
            self.node.create_subscription(String, "/" + TOPICS[topic], _ignore, json_qos())
        self.node.create_subscription(JointTrajectory, "/" + TOPICS["path"], _ignore, json_qos())
        self.caller = ServiceCaller(self.node, "/" + PLAN_SERVICE)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.spinner = threading.Thread(target=self.executor.spin, daemon=True)
        self.spinner.start()
        return self

    def __exit__(self, *_: object) -> None:
        self.executor.shutdown(timeout_sec=1.0)
        self.context.try_shutdown()
        self.spinner.join(timeout=2.0)
        self.node.destroy_node()

    def _on_episode(self, message: Any) -> None:
        from lit_msgs_json.envelope import MessageError, decode

        try:
            envelope = decode(message.data, accept="EpisodeSummary")
        except MessageError:
            return
        if envelope.run_id != self.run_id:
            return
        payload = envelope.payload
        with self.changed:
            self.episodes.append(payload)
            self.changed.notify_all()

    def wait_episodes(self, count: int, timeout: float) -> list[dict[str, Any]]:
        deadline = time.monotonic() + timeout
        printed = 0
        with self.changed:
            while True:
                training = [e for e in self.episodes if e["mode"] == "training"]
                for episode in training[printed:]:  # each one, also when several came at once
                    printed += 1
                    cost = f"cost {episode['cost']:.3f}" if episode["cost"] else "no solution"
                    print(
                        f"    episode {printed}/{count}: {episode['scenario']}, {cost}, "
                        f"{learner_decisions(episode)} learner decisions",
                        flush=True,
                    )
                if len(training) >= count:
                    return training
                if self.system.children["planner"].process.poll() is not None:
                    raise RuntimeError("the planner node exited during training")
                if time.monotonic() > deadline:
                    raise TimeoutError(f"training did not finish {count} episodes in time")
                self.changed.wait(min(1.0, max(0.0, deadline - time.monotonic())))

    def plan(self, payload: dict[str, Any]) -> tuple[dict[str, Any] | None, str]:
        from lit_msgs_json.envelope import Publisher, decode

        from lit_planner.rosutil import CallInterrupted

        if not self.caller.wait(30.0):
            raise RuntimeError("the plan service did not appear")
        text = Publisher("lit_demo", "demo").encode("PlanRequest", payload)
        planner = self.system.children["planner"].process
        try:  # a planner that died will not answer: no need to wait out the timeout
            answer = self.caller.call(text, 600.0, interrupted=lambda: planner.poll() is not None)
        except CallInterrupted:
            raise RuntimeError("the planner node exited while planning") from None
        if answer is None:
            return None, "no answer"
        success, message = answer
        reply = decode(message, accept=("PlanResponse", "Error"))
        if not success:
            return None, reply.payload["message"]
        return reply.payload, ""


def learner_decisions(summary: dict[str, Any]) -> int:
    """A training episode's decisions the learner made (its calls include missed ones)."""
    return sum(summary["decisions"].values()) - summary["fallback_decisions"]


def _report(
    scenario: Scenario,
    training: list[dict[str, Any]],
    plans: list[tuple[int, dict[str, Any] | None, str]],
    codes: dict[str, int | None],
    bag: Path,
    wall: float,
    budget: float,
) -> int:
    print()
    fell_back = sum(e["fallback_decisions"] for e in training)
    if fell_back:
        who = (
            f"{fell_back} decisions fell back to the planner's own policy: the learner was late "
            "or unreachable, see the planner's warnings"
        )
    elif training:
        who = "the learner decided every B and psi_K"
    else:
        who = "none asked for"
    print(f"Training over ROS ({len(training)} episodes; {who}):")
    print("| episode | scenario | solved | c_final | learner decisions | fallbacks |")
    print("|---|---|---|---|---|---|")
    for i, e in enumerate(training):
        cost = f"{e['cost']:.3f}" if e["cost"] else "-"
        print(
            f"| {i + 1} | {e['scenario']} | {e['solved']} | {cost} | {learner_decisions(e)} | "
            f"{e['fallback_decisions']} |"
        )
    optimum = scenario.optimal_cost
    print()
    print(f"Inference on {scenario.key} ({scenario.description}) through /lit/planner/plan:")
    print("| seed | status | t_init | c_init | c_final | c_final / optimum | path re-check |")
    print("|---|---|---|---|---|---|---|")
    ok = bool(plans)
    first: dict[str, Any] | None = None
    for seed, response, error in plans:
        if response is None:
            print(f"| {seed} | error: {error} | | | | | |")
            ok = False
            continue
        check = scenarios.check_path(scenario, response["path"]) if response["path"] else None
        passed = bool(check and check.ok)
        ok = ok and response["solved"] and passed
        ratio = f"{response['cost'] / optimum:.3f}" if response["cost"] and optimum else "-"
        print(
            f"| {seed} | {response['status']} | {_ms(response['t_init'])} | "
            f"{_num(response['c_init'])} | {_num(response['cost'])} | {ratio} | "
            f"{'passed' if passed else 'FAILED'} |"
        )
        if first is None:
            first = dict(response)
            first["path_check"] = None if check is None else dataclasses.asdict(check)
            first["optimal_cost"] = optimum
    if first is not None:
        print()
        print(f"First inference plan in detail (seed {plans[0][0]}):")
        first["improvements"] = [tuple(x) for x in first["improvements"]]
        first["time_budget"] = budget  # what the plan requests asked for
        try:
            print("\n".join(plan_cli.summary_lines(first, scenario)))
        except (KeyError, TypeError):
            pass
    print()
    _print_bag(bag)
    clean = _print_stopped(codes, wall)
    return 0 if ok and clean else 1


def _print_stopped(codes: dict[str, int | None], wall: float) -> bool:
    """Print how the processes exited and the wall time; whether all exited with 0."""
    print(
        f"Processes stopped: {', '.join(f'{n} exit {c}' for n, c in codes.items())}; "
        f"wall time {wall:.1f} s"
    )
    return all(code == 0 for code in codes.values())


def _print_bag(bag: Path) -> None:
    from lit_planner import replay

    try:
        info = replay.bag_info(bag)
    except Exception as error:  # noqa: BLE001 - the demo reports; replay has the details
        print(f"Bag {bag}: unreadable ({error})")
        return
    print(
        f"Bag {bag} (MCAP, rosbag2 v9) — `lit replay info {bag}` lists it, "
        f"`lit replay bench {bag}` tables its queries:"
    )
    for topic in info["topics"]:
        print(f"  {topic['topic']} ({topic['type']}): {topic['messages']} messages")
    publishers = info.get("publishers", [])
    # Leading: numbers before the first recorded one (a recording that started late).
    missing = sum(int(p["missing"]) + int(p["leading"]) for p in publishers)
    print(f"  seq accounting over {len(publishers)} publishers: {missing} messages missing")
    for p in publishers:  # which ones, and where: before the first recorded one or in gaps
        if p["missing"] or p["leading"]:
            print(
                f"    {p['topic']} from {p['source']}: {p['leading']} before seq {p['first_seq']}, "
                f"{p['missing']} in {p['gaps']} gaps"
            )


def _ms(value: float | None) -> str:
    return "-" if value is None else f"{value * 1e3:.1f} ms"


def _num(value: float | None) -> str:
    return "-" if value is None or not math.isfinite(value) else f"{value:.3f}"

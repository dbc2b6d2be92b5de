"""``lit system-bench``: the distributed system's own numbers, measured in one run.

1. **Decide round trip** across processes: ``lit call decide --repeat N`` (a separate client
   process) against a running ``lit_learner_node``, for both agents: median and p99; and the
   round trips the planner node itself recorded (``Decision.latency_ms``) in the training run of
   2.
2. **Planning throughput** in training mode against the tensor policy on the same problems: the
   planner node plans ``--episodes`` draws of the training distribution (same ``--seed``) once
   asking the learner at every decision and once with the tensor policy; wall seconds per
   episode, and the planner clock (which excludes the learner's time) for comparison.
3. **Noticing a dead learner**: during training the learner is SIGKILLed ``--kills`` times (and
   restarted from its checkpoint in between); the time from the kill to the planner's fallback
   warning (its log timestamp) is how long the planner needs to notice.

Every process runs on its own ROS domain with discovery on this host, and is stopped by its PID.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from lit_planner.echo_node import ECHO_SERVICE
from lit_planner.rosutil import add_domain_option, set_domain_id
from lit_planner.up import DomainBusy, System, claim_domain, stop_on_sigterm

DEFAULT_DOMAIN_ID = 94
_LOG_STAMP = re.compile(r"\[(?:WARN|INFO|ERROR)\] \[(\d+\.\d+)\]")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``lit system-bench``."""
    parser.add_argument(
        "--episodes",
        type=_count,
        default=12,
        help="episodes per policy (0: skip part 2; default: %(default)s)",
    )
    parser.add_argument(
        "--budget",
        type=float,
        default=0.3,
        help="planner seconds per episode (default: %(default)s)",
    )
    parser.add_argument(
        "--scenarios", default="np4,np8,rrd4,rrd8", help="training mix (default: %(default)s)"
    )
    parser.add_argument(
        "--seed", type=int, default=7, help="seed of the episode draws (default: %(default)s)"
    )
    parser.add_argument(
        "--calls",
        type=_count,
        default=2000,
        help="decide round trips per agent (0: skip part 1; default: %(default)s)",
    )
    parser.add_argument(
        "--kills",
        type=_count,
        default=3,
        help="learner SIGKILLs (0: skip part 3; default: %(default)s)",
    )
    add_domain_option(parser, DEFAULT_DOMAIN_ID)


def _count(text: str) -> int:
    """A non-negative integer option."""
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be 0 or more, not {value}")
    return value


def run(args: argparse.Namespace) -> int:
    """Run the three measurements (those not switched off with a count of 0) as tables."""
    if not (args.calls or args.episodes or args.kills):
        print("lit system-bench: --calls, --episodes and --kills are all 0: nothing to measure",
              file=sys.stderr)  # fmt: skip
        return 2
    # The domain first: it needs no imports (_check's load torch, whose import runs ldconfig)
    problem = set_domain_id(args, DEFAULT_DOMAIN_ID) or _check(args)
    if problem is not None:
        print(f"lit system-bench: {problem}", file=sys.stderr)
        return 2
    stop_on_sigterm()  # the finally below stops the nodes in order and removes the folder
    try:
        claim = claim_domain(args.domain_id, "lit system-bench")
    except DomainBusy as error:
        print(f"lit system-bench: {error}", file=sys.stderr)
        return 2
    with claim, tempfile.TemporaryDirectory(prefix="lit-system-bench-") as folder:
        work = Path(folder)
        system = System(args.domain_id, work, echo=None)
        try:
            _start_learner(system, work)
            if args.calls:
                _decide_round_trips(system, args)
            if args.episodes:
                _throughput_tables(system, work, args)
            if args.kills:
                _kill_delays(system, work, args)
        finally:
            system.stop()
    return 0


def _check(args: argparse.Namespace) -> str | None:
    """What is wrong with the options, found before any process starts (a bad value used to
    hang the run until a timeout, or to fail with a traceback after the first part); None when
    fine."""
    from lit_learner.train import TrainingDistribution, TrainingError

    from lit_planner import scenarios
    from lit_planner.errors import LitPlannerError
    from lit_planner.planning import MAX_SEED
    from lit_planner.rosutil import MAX_EPISODE_BUDGET, MIN_EPISODE_BUDGET

    if args.episodes or args.kills:  # the parts that plan
        if not (math.isfinite(args.budget) and args.budget > 0):
            return f"--budget must be a finite positive number of seconds, got {args.budget}"
        if args.episodes and not MIN_EPISODE_BUDGET <= args.budget <= MAX_EPISODE_BUDGET:
            # Part 2 trains with it (the planner node refused it only after the nodes had
            # started); part 3's episodes have a budget of their own.
            return (
                f"--budget must be {MIN_EPISODE_BUDGET:g} to {MAX_EPISODE_BUDGET:g} s (a training "
                f"episode's time budget), got {args.budget:g}"
            )
        if not 0 <= args.seed < MAX_SEED:  # the tensor part draws with --seed + 1
            return f"--seed must be between 0 and {MAX_SEED - 1}, got {args.seed}"
        try:
            TrainingDistribution(scenarios.split_names(args.scenarios), None)
        except (LitPlannerError, TrainingError) as error:
            return f"--scenarios {args.scenarios}: {error}"
    return None


def _decide_round_trips(system: System, args: argparse.Namespace) -> None:
    system.start("echo", [sys.executable, "-m", "lit_planner.echo_node"])
    system.wait_ready("echo")
    print("## Decide round trip (lit call decide --repeat, separate process)\n", flush=True)
    print(
        "Baseline, same run: an AddDiagnostics server that echoes the request and does "
        "nothing else (`lit_planner.echo_node`), called with a decide request's text.\n"
    )
    print("| service | calls | median | p99 | max | median / echo median |")
    print("|---|---|---|---|---|---|")
    rows = [
        # --no-probe: the path a planner's request takes (recorded and paired after the answer),
        # as the runs before probes existed measured it; the learner is this run's own.
        (
            f"decide {agent}",
            _round_trips(system, ["decide", "--agent", agent, "--no-probe"], args.calls),
        )
        for agent in ("psi_K", "B")
    ]
    echo = _round_trips(system, ["raw", ECHO_SERVICE, _decide_text()], args.calls)
    rows.append(("echo (baseline)", echo))
    for name, stats in rows:
        print(
            f"| {name} | {stats['calls']} | {stats['median_ms']:.3f} ms | "
            f"{stats['p99_ms']:.2f} ms | {stats['max_ms']:.2f} ms | "
            f"{stats['median_ms'] / echo['median_ms']:.2f}x |",
            flush=True,
        )
    _stop(system, "echo")


def _throughput_tables(system: System, work: Path, args: argparse.Namespace) -> None:
    print("\n## Planning throughput on the same problems\n", flush=True)
    print("| policy | episodes | wall s / episode | planner s / episode | learner calls |")
    print("|---|---|---|---|---|")
    rows = {}
    for policy in ("training", "tensor"):
        rows[policy] = _throughput(system, work, policy, args)
        row = rows[policy]
        print(
            f"| {policy} | {row['episodes']} | {row['wall']:.3f} | {row['planner']:.3f} | "
            f"{row['learner_calls']} |",
            flush=True,
        )
    ratio = rows["training"]["wall"] / rows["tensor"]["wall"]
    print(f"\ntraining / tensor wall time per episode: {ratio:.2f}x")
    latencies = rows["training"]["latencies_ms"]
    if latencies:
        p50, p90, p99 = np.percentile(latencies, [50, 90, 99])
        print(
            f"\nDecide round trip inside the planner node during this training run "
            f"(Decision.latency_ms, from encoding the request to the validated answer; "
            f"{len(latencies)} answered decisions while the learner trained and wrote a "
            f"checkpoint after every episode): median {p50:.3f} ms, p90 {p90:.2f} ms, "
            f"p99 {p99:.2f} ms, max {max(latencies):.2f} ms; "
            f"{rows['training']['fallbacks']} decisions fell back (no answer within "
            f"the 50 ms decision timeout). The planner waits up to 1 s for the learner's first "
            f"answer (first_decision_timeout), which is among these latencies"
        )
    for line in rows["training"]["warnings"]:  # why decisions fell back, if they did
        print(line)


def _kill_delays(system: System, work: Path, args: argparse.Namespace) -> None:
    print("\n## Time for the planner to notice a dead learner (SIGKILL → fallback)\n", flush=True)
    delays = _dead_learner(system, work, args)
    for i, delay in enumerate(delays):
        print(f"kill {i + 1}: {delay * 1e3:.0f} ms")
    if delays:
        print(
            f"median {np.median(delays) * 1e3:.0f} ms, max {max(delays) * 1e3:.0f} ms "
            f"(decision_timeout 50 ms)"
        )


def _start_learner(system: System, work: Path) -> None:
    # A checkpoint after every episode: the kills of part 3 resume from it, and the training
    # run of part 2 measures decisions while checkpoints are being written (the worst case; the
    # node's defaults are every 50 episodes or 30 s).
    system.start(
        "learner",
        "lit_learner_node",
        {
            "checkpoint": str(work / "learner" / "checkpoint.pt"),
            "export_dir": str(work / "learner" / "tensors"),
            "checkpoint_every": 1,
            "checkpoint_period": 1.0,
        },
    )
    system.wait_ready("learner")


def _round_trips(system: System, call: list[str], calls: int) -> dict[str, Any]:
    process = subprocess.run(
        [sys.executable, "-m", "lit_planner.cli", "call", *call, "--repeat", str(calls)],
        env=system.env, capture_output=True, text=True, timeout=600, check=False,
    )  # fmt: skip
    if process.returncode != 0:
        raise SystemExit(f"lit system-bench: lit call {call[0]} failed: {process.stderr.strip()}")
    return json.loads(process.stdout)  # type: ignore[no-any-return]


def _decide_text() -> str:
    """A decide request as ``lit call decide`` sends it (the echo's payload: same size)."""
    from lit_msgs_json.envelope import Publisher

    payload = {
        "agent": "psi_K", "episode_id": "echo", "rho_global": 0.1, "rho_local": 0.1,
        "measure": 0.5, "planning_time": 0.0, "time_budget": 1.0, "cost": None,
        "minimum_cost": 1.0, "improvements": 0, "path_states": 0, "explore": False,
    }  # fmt: skip
    return Publisher("lit_call", "echo").encode("DecideRequest", payload)


def _throughput(system: System, work: Path, policy: str, args: argparse.Namespace) -> dict:
    from lit_planner import replay

    bag = work / f"bag-{policy}"
    learner = system.children["learner"]
    learner_seen = len(learner.lines)
    system.start("recorder", "lit_recorder_node", {"bag": str(bag), "run_id": policy})
    system.wait_ready("recorder")
    planner = system.start(
        "planner",
        "lit_planner_node",
        {
            "policy": policy,
            "episodes_from": "training",
            "training_scenarios": args.scenarios,
            "training_seed": args.seed,
            "episodes": args.episodes,
            "time_budget": float(args.budget),
            "exit_when_done": True,
            "wait_for_subscribers": 1,
            "run_id": policy,
        },
    )
    code = planner.process.wait(3600)
    planner.drain()
    if code != 0:
        raise SystemExit("lit system-bench: the planner failed:\n" + "\n".join(planner.lines[-20:]))
    recorder = system.children["recorder"]
    code = _stop(system, "recorder")
    # A recorder that failed lacks at least what it held when it ended: no numbers from its bag.
    problem = None if code == 0 else f"the recorder exited with code {code}"
    if problem is None:
        try:
            envelopes = _envelopes(replay, bag)
        except replay.ReplayError as error:
            problem = str(error)
    if problem is not None:
        raise SystemExit(
            f"lit system-bench: the {policy} run's bag {bag} cannot be measured: {problem}\n"
            + "\n".join(recorder.lines[-20:])
        )
    summaries = [e.payload for e in envelopes if e.schema == "lit_msgs_json/EpisodeSummary"]
    latencies = [
        e.payload["latency_ms"]
        for e in envelopes
        if e.schema == "lit_msgs_json/Decision"
        and e.payload["source"] == "learner"
        and "latency_ms" in e.payload
    ]
    # From the planner's first message (its first episode has begun) to its last one: startup and
    # the wait for the learner's service (DDS discovery, up to seconds) excluded for both policies.
    stamps = [e.stamp_ns for e in envelopes if e.schema != "lit_msgs_json/LearnerStats"]
    wall = (max(stamps) - min(stamps)) / 1e9
    return {
        "episodes": len(summaries),
        "wall": wall / max(1, len(summaries)),
        "planner": float(np.mean([s["time"] for s in summaries])),
        "learner_calls": sum(s["learner_calls"] for s in summaries),
        "fallbacks": sum(s["fallback_decisions"] for s in summaries),
        "latencies_ms": latencies,
        "warnings": [
            f"{name}: {line.strip()}"
            for name, lines in (
                ("planner", planner.lines),
                ("learner", learner.lines[learner_seen:]),
            )
            for line in lines
            if "[WARN]" in line or "[ERROR]" in line
        ],
    }


def _envelopes(replay: Any, bag: Path) -> list[Any]:
    skipped = replay.Skipped()
    with replay.BagReader(bag) as reader:
        items = [replay.decode(message, skipped) for message in reader.messages()]
    return [item for item in items if isinstance(item, replay.Envelope)]


def _dead_learner(system: System, work: Path, args: argparse.Namespace) -> list[float]:
    planner = system.start(
        "planner",
        "lit_planner_node",
        {
            "policy": "training",
            "training_scenarios": args.scenarios,
            "training_seed": args.seed + 1,
            "episodes": 100_000,
            "time_budget": 1.0,
            "learner_retry": 0.5,
            "run_id": "kills",
        },
    )
    system.wait_ready("planner")
    # The planner's first call waits first_decision_timeout (1 s), not decision_timeout: kill
    # only a learner that has answered (in time or late), or the measure would be that wait.
    first = "learner answered its first call"
    if _wait_for_line(planner, 0, lambda line: first in line, timeout=120.0) is None:
        print("the learner never answered the planner; no kills", file=sys.stderr)
        _stop(system, "planner")
        return []
    delays = []
    for _ in range(args.kills):
        time.sleep(3.0)  # training under way, the learner answering
        seen = len(planner.lines)
        learner = system.children["learner"]
        killed = time.time()
        learner.process.send_signal(signal.SIGKILL)
        learner.process.wait()
        warned = _wait_for_warning(planner, seen, timeout=60.0)
        if warned is not None:
            delays.append(warned - killed)
        _start_learner(system, work)  # resumes from its checkpoint
    _stop(system, "planner")
    return delays


def _wait_for_line(
    child: Any, start: int, wanted: Callable[[str], bool], timeout: float
) -> str | None:
    """The first of ``child``'s log lines from ``start`` on that is ``wanted``, waiting up to
    ``timeout`` s; None if none came."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for line in child.lines[start:]:
            if wanted(line):
                return line
        time.sleep(0.05)
    return None


def _wait_for_warning(child: Any, start: int, timeout: float) -> float | None:
    """The log time of the planner's fallback warning from line ``start`` on."""
    line = _wait_for_line(
        child,
        start,
        lambda text: "[WARN]" in text and "learner" in text and _LOG_STAMP.search(text) is not None,
        timeout,
    )
    return None if line is None else float(_LOG_STAMP.search(line).group(1))  # type: ignore[union-attr]


def _stop(system: System, name: str) -> int:
    """SIGTERM the child ``name`` (SIGKILL after 60 s); its exit code."""
    child = system.children.pop(name)
    if child.process.poll() is None:
        child.process.send_signal(signal.SIGTERM)
        try:
            child.process.wait(60)
        except subprocess.TimeoutExpired:
            child.process.kill()
    code = child.process.wait()
    child.drain()
    return code

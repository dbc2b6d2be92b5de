"""``lit up``: the learner, a planner and the bag recorder as separate ROS 2 processes.

Discovery stays on this host (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` unless set) on the domain
``--domain-id`` (default: ``$ROS_DOMAIN_ID``, else 42). Each process's log lines are streamed with a
``[learner]`` / ``[planner]`` / ``[recorder]`` prefix. Ctrl-C (or SIGTERM) stops the planner, then
the learner (which checkpoints and exports), then the recorder (which closes the bag), each by its
PID with SIGTERM, and SIGKILL only after a grace period.

:class:`System` is the same machinery as a library: ``lit demo`` and the system tests use it.
"""

from __future__ import annotations

import argparse
import ctypes
import fcntl
import json
import math
import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any, Self

from lit_planner import argtypes, signals
from lit_planner.rosutil import (
    DEFAULT_DOMAIN_ID,
    LOCALHOST_ENV,
    add_domain_option,
    episode_budget_limit,
    set_domain_id,
)

STOP_ORDER = ("planner", "learner", "recorder")
"""Processes stop in this order: the recorder last, so it keeps the final messages."""
GRACE_SECONDS = 20.0
"""SIGTERM → SIGKILL grace period per process (the learner may be exporting tensors)."""
LEARNER_START = 180.0
"""Seconds `lit up` waits for the learner's ``ready:`` before it starts a training planner (torch
imports in it). A learner that exits first stops `lit up` without a planner; after this long the
planner starts all the same and falls back until the learner answers."""
KEEP_LINES = 200
"""Output lines `lit up` keeps per process for its error messages (it echoes every line: a run
of days must not keep them all)."""
POLL_SECONDS = 0.1
"""How often an interrupted stop looks at its signal count."""
WHY_WAIT = {
    "learner": "it saves its checkpoint and exports its tensors",
    "recorder": "it writes the rest of the bag and closes it",
    "planner": "it finishes its current plan",
}
"""What each process does when it stops, for the message of an interrupted stop."""


@dataclass
class Child:
    """One started process."""

    name: str
    process: subprocess.Popen[str]
    lines: list[str] = field(default_factory=list)
    """Its output lines: all of them, or the last ``keep_lines`` to ``2 * keep_lines`` of them."""
    keep_lines: int | None = None
    ready: threading.Event = field(default_factory=threading.Event)
    pump: threading.Thread | None = None
    """The thread that reads the process's output into ``lines``."""

    def drain(self, timeout: float = 5.0) -> None:
        """After the process ended: wait until ``lines`` holds all of its output."""
        if self.pump is not None:
            self.pump.join(timeout)


class System:
    """Start, watch and stop the node processes (by their PIDs only)."""

    def __init__(
        self,
        domain_id: int,
        cwd: Path,
        echo: Callable[[str], None] | None = print,
        keep_lines: int | None = None,
    ) -> None:
        """``keep_lines``: how many of each child's last output lines to keep (for its error
        messages); None keeps all (a bounded run that reads them back)."""
        self.keep_lines = keep_lines
        self.env = dict(os.environ)
        for key, value in LOCALHOST_ENV.items():
            self.env.setdefault(key, value)
        self.env["ROS_DOMAIN_ID"] = str(domain_id)
        self.env["PYTHONUNBUFFERED"] = "1"
        self.cwd = cwd
        self.echo = echo
        self.children: dict[str, Child] = {}
        self.stop_interrupts = 0
        """Interrupts (Ctrl-C, SIGTERM) that came while :meth:`stop` ran: a caller whose work
        was done by then still owes its user the exit status of an interrupted program."""

    def start(
        self,
        name: str,
        executable: str | Sequence[str],
        params: Mapping[str, object] = (),
        namespace: str | None = None,
    ) -> Child:
        """Start ``executable`` (a console script next to this Python, or a whole command line)
        with ROS parameters."""
        prefix = [_script(executable)] if isinstance(executable, str) else list(executable)
        command = [*prefix, "--ros-args"]
        if namespace:
            command += ["-r", f"__ns:={namespace}"]
        for key, value in dict(params).items():
            command += ["-p", f"{key}:={_ros_value(value)}"]
        process = subprocess.Popen(
            command,
            cwd=self.cwd,
            env=self.env,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            start_new_session=True,  # our Ctrl-C reaches them only through stop()
            # Only a prctl call, bound before the fork (no imports or allocation in the child).
            preexec_fn=_terminate_with_parent,  # noqa: PLW1509
        )
        child = Child(name, process, keep_lines=self.keep_lines)
        self.children[name] = child
        child.pump = threading.Thread(target=self._pump, args=(child, process.stdout), daemon=True)
        child.pump.start()
        return child

    def _pump(self, child: Child, stream: IO[str] | None) -> None:
        assert stream is not None
        for line in stream:
            line = line.rstrip("\n")
            child.lines.append(line)
            if child.keep_lines is not None and len(child.lines) > 2 * child.keep_lines:
                del child.lines[: -child.keep_lines]  # a long run's output is echoed, not kept
            if "ready:" in line:
                child.ready.set()
            if self.echo is not None:
                try:
                    self.echo(f"[{child.name}] {line}")
                except (BrokenPipeError, ValueError):  # our stdout closed (`lit up | head`)
                    self.echo = None  # the children's pipes are still drained: they never block

    def wait_ready(
        self, name: str, timeout: float = 60.0, stopping: Callable[[], bool] | None = None
    ) -> None:
        """Block until the child logs ``ready:``, or ``stopping()`` (looked at every 0.1 s) is
        true; RuntimeError if it exits or times out."""
        child = self.children[name]
        deadline = time.monotonic() + timeout
        while not child.ready.wait(0.1):
            if stopping is not None and stopping():
                return
            if child.process.poll() is not None:
                raise RuntimeError(
                    f"{name} exited with code {child.process.returncode} before it was ready:\n"
                    + "\n".join(child.lines[-20:])
                )
            if time.monotonic() > deadline:
                raise RuntimeError(f"{name} not ready after {timeout:g} s")

    def stop(self) -> dict[str, int | None]:
        """SIGTERM each child (planner, learner, recorder order), SIGKILL after the grace.

        An interrupt (Ctrl-C, or SIGTERM) while a child is stopping does not leave it behind: the
        wait goes on, and says what it waits for (the learner saves its checkpoint, the recorder
        closes the bag). A second interrupt SIGKILLs every child still running. (From the main
        thread: the signals are counted, not raised, while this runs, so none can land half-way
        through the handling of another.)
        """
        interrupts = [0]
        try:
            with signals.handling(
                signals.STOPS, lambda *_: interrupts.__setitem__(0, interrupts[0] + 1)
            ):
                return self._stop_all(interrupts)
        finally:
            self.stop_interrupts += interrupts[0]

    def _stop_all(self, interrupts: list[int]) -> dict[str, int | None]:
        codes: dict[str, int | None] = {}
        order = [n for n in STOP_ORDER if n in self.children]
        order += [n for n in self.children if n not in order]
        told = killed = False
        for name in order:
            process = self.children[name].process
            if process.poll() is None:
                process.send_signal(signal.SIGTERM)
            deadline = time.monotonic() + GRACE_SECONDS
            while process.poll() is None:
                if interrupts[0] >= 2 and not killed:
                    killed = True
                    self._kill_all()
                elif interrupts[0] == 1 and not told:
                    told = True
                    why = WHY_WAIT.get(name, "its shutdown")
                    left = max(0.0, deadline - time.monotonic())
                    print(
                        f"still stopping: waiting for the {name} to finish ({why}; at most "
                        f"{left:.0f} s more); interrupt again to kill every process now",
                        file=sys.stderr,
                        flush=True,
                    )
                if time.monotonic() >= deadline:
                    process.kill()
                try:
                    process.wait(POLL_SECONDS)
                except subprocess.TimeoutExpired:
                    continue
            codes[name] = process.returncode
        return codes

    def _kill_all(self) -> None:
        for child in self.children.values():
            if child.process.poll() is None:
                child.process.kill()
        print("killed the processes still running", file=sys.stderr, flush=True)


class DomainBusy(RuntimeError):
    """Another launcher of this host runs its nodes on the domain (see :func:`claim_domain`)."""


LAUNCH_LOCK_DIR = Path("/tmp")
"""Where the launchers' domain locks live: one folder for the whole host (not ``$TMPDIR``, which
differs between users and shells, while localhost discovery reaches them all)."""


class DomainClaim:
    """A launcher's hold on a domain (:func:`claim_domain`): released by :meth:`close`, at the
    end of a ``with`` block, or when the process ends however it ends."""

    def __init__(self, fd: int | None) -> None:
        self._fd = fd

    @property
    def held(self) -> bool:
        """Whether the lock is held (False when its file could not be opened)."""
        return self._fd is not None

    def close(self) -> None:
        """Release the domain."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()


def claim_domain(domain_id: int, who: str, *, warn: bool = True) -> DomainClaim:
    """Hold this host's lock of ``domain_id`` (``/tmp/lit-launch-domain-N.lock``).

    ``lit up``, ``lit demo`` and ``lit system-bench`` claim their domain before they start a
    node, and ``lit test`` claims the domain of each run and test (it takes the next free one): two learners (or planners) on one domain serve the same services, DDS hands each
    request to either of them, and both recorders record both runs. Discovery stays on this host,
    so a lock file covers everything that can meet on the domain. It does not see nodes started
    without a launcher; the nodes themselves warn when another server of their service stays
    (:class:`lit_planner.rosutil.DuplicateServerWatch`). A lock file another user created is
    locked read-only; when none can be opened at all, the run goes on unclaimed, with a warning
    (``warn=False``: silently; the claim's :attr:`DomainClaim.held` is then False).

    Raises:
        DomainBusy: another launcher holds the domain; the message names it and its PID.
    """
    path = LAUNCH_LOCK_DIR / f"lit-launch-domain-{domain_id}.lock"
    writable = True
    try:
        # Not inherited by the children; no symbolic link followed in the shared /tmp.
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o666)
    except PermissionError:
        try:
            fd, writable = os.open(path, os.O_RDONLY | os.O_NOFOLLOW), False  # another user's
        except OSError as error:
            return _unclaimed(domain_id, error, warn)
    except OSError as error:
        return _unclaimed(domain_id, error, warn)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = os.pread(fd, 4096, 0).decode("utf-8", "replace").strip()
        os.close(fd)
        raise DomainBusy(
            f"ROS_DOMAIN_ID={domain_id} is in use on this host by {holder or 'another launcher'}; "
            "its nodes would answer this run's service calls. Stop it, or choose another "
            "--domain-id"
        ) from None
    if writable:
        os.ftruncate(fd, 0)
        text = f"{who} (pid {os.getpid()}, since {time.strftime('%H:%M:%S')})\n"
        os.pwrite(fd, text.encode("utf-8"), 0)
    return DomainClaim(fd)


def _unclaimed(domain_id: int, error: OSError, warn: bool) -> DomainClaim:
    if warn:
        print(f"warning: ROS_DOMAIN_ID={domain_id} not claimed: {error}", file=sys.stderr)
    return DomainClaim(None)


DEFAULT_SCENARIO = "np8"
"""``--scenario``'s default for the tensor, fit and fixed policies."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``lit up``."""
    add_domain_option(parser, DEFAULT_DOMAIN_ID)
    parser.add_argument(
        "--policy",
        default="training",
        choices=("training", "tensor", "fit", "fixed"),
        help="the planner's episodes: training (every B / psi_K asked of the learner) or a "
        "policy of its own (default: %(default)s)",
    )
    parser.add_argument(
        "--episodes",
        type=int,
        default=20,
        help="planner episodes (default: %(default)s; 0: only serve requests)",
    )
    parser.add_argument(
        "--scenario",
        default=None,
        help=f"tensor, fit, fixed: the scenario of the episodes (default {DEFAULT_SCENARIO}); "
        "training: the training scenarios, comma-separated family+dimension (default: the "
        "planner node's mix)",
    )
    parser.add_argument(
        "--time-budget",
        type=float,
        default=0.0,
        metavar="SECONDS",
        help="planner time of each episode (default: 0, the scenario's)",
    )
    parser.add_argument(
        "--run-id",
        default=None,
        help="the run's name: bag RUN in the repository's bags/, learner files "
        "runs/RUN/learner/ under the current folder (default: up-<date>-<time>)",
    )
    parser.add_argument(
        "--checkpoint",
        default=None,
        help="learner checkpoint, resumed if found (default: runs/RUN/learner/checkpoint.pt "
        "under the current folder)",
    )
    parser.add_argument("--no-record", action="store_true", help="do not record a bag")
    parser.add_argument(
        "--bag",
        type=argtypes.path,
        default=None,
        help="bag directory (default: RUN in the repository's bags/)",
    )
    parser.add_argument(
        "--planner-param",
        action="append",
        default=[],
        metavar="NAME:=VALUE",
        help="extra planner node parameter (repeatable)",
    )
    parser.add_argument(
        "--learner-param",
        action="append",
        default=[],
        metavar="NAME:=VALUE",
        help="extra learner node parameter (repeatable)",
    )


_RUN_ID = re.compile(r"[A-Za-z][A-Za-z0-9._-]{0,127}")
"""A run id: a single folder name (no path components), as bags and run folders use it, that
starts with a letter (ROS reads a ``-p run_id:=42`` parameter as a number)."""

_YAML_WORDS = frozenset({"y", "n", "yes", "no", "on", "off", "true", "false", "null"})
"""Words ROS parameters read as booleans or null rather than as strings."""


def _check(args: argparse.Namespace, run_id: str, bag: Path | None) -> str | None:
    """What is wrong with the options, checked before any process starts; None when fine."""
    from lit_learner.train import TrainingDistribution, TrainingError

    from lit_learner import node as learner_node
    from lit_planner import node as planner_node
    from lit_planner import scenarios
    from lit_planner.bag import write_problem
    from lit_planner.errors import LitPlannerError

    if not _RUN_ID.fullmatch(run_id) or run_id.lower() in _YAML_WORDS:
        return (
            f"--run-id {run_id!r}: a folder name of letters, digits, '.', '_' and '-' that starts "
            "with a letter and is not a YAML word such as 'yes' or 'null'"
        )
    for option, given, known in (
        ("--planner-param", args.planner_param, planner_node.PARAMETERS),
        ("--learner-param", args.learner_param, learner_node.PARAMETERS),
    ):
        try:
            unknown = sorted(set(_params(given)) - set(known) - {"use_sim_time"})  # ROS's own
            _typed_params(given, known)
        except ValueError as error:
            return f"{option}: {error}"
        if unknown:
            return f"{option}: unknown parameter {', '.join(unknown)}; known: {', '.join(known)}"
    if args.checkpoint is not None and Path(args.checkpoint).is_dir():
        return f"--checkpoint {args.checkpoint}: a folder; give the checkpoint file (checkpoint.pt)"
    if args.no_record and args.bag is not None:
        return "--bag and --no-record contradict each other; give one of them"
    if args.episodes < 0:
        return f"--episodes must be 0 (serve only) or more, got {args.episodes}"
    limit = episode_budget_limit(args.policy)
    if not (0 <= args.time_budget <= limit):  # NaN too
        return (
            f"--time-budget must be 0 (the scenario's) or a positive number of seconds up to "
            f"{limit:g} with --policy {args.policy}, got {args.time_budget}"
        )
    try:
        if args.policy == "training" and args.scenario is not None:
            TrainingDistribution(scenarios.split_names(args.scenario), None)
        else:
            scenarios.get(args.scenario or DEFAULT_SCENARIO)
    except (LitPlannerError, TrainingError) as error:
        return f"--scenario {args.scenario}: {error}"
    if bag is not None and bag.exists():
        return f"bag {bag} exists already; choose another --bag or --run-id"
    # Where the recorder and the learner will write (they failed only after everything started,
    # the learner not before its shutdown).
    for what, path in (
        ("bag", bag),
        ("--checkpoint", Path(args.checkpoint).parent if args.checkpoint else None),
        ("the run folder", Path("runs") / run_id),
    ):
        problem = write_problem(path) if path is not None else None
        if problem is not None:
            return f"{what} {path}: {problem}"
    # The values each node will see (its defaults, what lit up sets, what was given), checked as
    # the node checks them: a bad one ended the node after everything had started.
    planner = {
        **planner_node.PARAMETERS,
        "policy": args.policy,
        "episodes": args.episodes,
        "time_budget": args.time_budget,
        "run_id": run_id,
        **_given_values(args.planner_param, planner_node.PARAMETERS),
    }
    learner = {
        **learner_node.PARAMETERS,
        "export_dir": str(Path("runs") / run_id / "learner" / "tensors"),  # as started below
        "run_id": run_id,
        **_given_values(args.learner_param, learner_node.PARAMETERS),
    }
    for option, problem in (
        ("--planner-param", planner_node.parameter_problem(planner)),
        ("--learner-param", learner_node.parameter_problem(learner)),
    ):
        if problem is not None:
            return f"{option}: {problem}"
    return None


def _given_values(items: Sequence[str], known: dict[str, Any]) -> dict[str, Any]:
    """The values that the ``NAME:=VALUE`` items of known parameters give, with the type of each
    default (raises ValueError as :func:`_typed_params` does)."""
    return {name: value for name, (value, _) in _read_params(items, known).items() if name in known}


def run(args: argparse.Namespace) -> int:
    """Start everything, stream logs, stop on Ctrl-C; 0 when the stop was asked for (Ctrl-C,
    SIGTERM, SIGHUP; or a planner with exit_when_done ended the run) and every process exited
    cleanly; 1 when one failed or another exited on its own; 2 when the options are refused or
    the domain is taken."""
    from lit_learner import node as learner_node
    from lit_planner import node as planner_node
    from lit_planner.bag import default_bag_root

    # "" is refused by _check, not replaced by the default id
    run_id = args.run_id if args.run_id is not None else time.strftime("up-%Y%m%d-%H%M%S")
    bag = None if args.no_record else (args.bag or default_bag_root() / run_id).absolute()
    # The domain first: it needs no imports (_check's took seconds and once imported torch)
    problem = set_domain_id(args, DEFAULT_DOMAIN_ID) or _check(args, run_id, bag)
    if problem is not None:
        print(f"lit up: {problem}", file=sys.stderr)
        return 2
    try:
        claim = claim_domain(args.domain_id, f"lit up (run {run_id})")
    except DomainBusy as error:
        print(f"lit up: {error}", file=sys.stderr)
        return 2
    runs = (Path("runs") / run_id).absolute()  # absolute: the export service answers with it
    runs.mkdir(parents=True, exist_ok=True)
    system = System(args.domain_id, Path.cwd(), keep_lines=KEEP_LINES)
    stop = signals.Flag()
    for number in signals.STOPS:  # SIGHUP too: the terminal closed, stop in order
        signal.signal(number, stop.set)
    print(
        f"lit up: run {run_id} on ROS_DOMAIN_ID={args.domain_id} (localhost discovery); "
        "Ctrl-C stops everything",
        flush=True,
    )
    failure = None
    try:
        if bag is not None:
            system.start("recorder", "lit_recorder_node", {"bag": str(bag), "run_id": run_id})
            # A stop requested meanwhile starts nothing more (the nodes used to start anyway).
            system.wait_ready("recorder", stopping=stop.is_set)
        learner = {
            "checkpoint": args.checkpoint or str(runs / "learner" / "checkpoint.pt"),
            "export_dir": str(runs / "learner" / "tensors"),
            "run_id": run_id,
            # Its stats from the first tick the recorder hears (the topic is volatile).
            "wait_for_subscribers": 0 if bag is None else 1,
            **_typed_params(args.learner_param, learner_node.PARAMETERS),
        }
        if not stop.is_set():
            system.start("learner", "lit_learner_node", learner)
        if args.policy == "training" and "learner" in system.children:
            # Training episodes ask the learner from their first decision: the planner waits
            # only learner_wait (10 s) for it, and torch's start-up on a loaded machine can take
            # longer, which turned the first decisions into fallbacks.
            # Ctrl-C still stops at once; a learner that exits stops lit up (below) before any
            # planner starts; one not ready in time leaves the planner its fallback decisions.
            child, deadline = system.children["learner"], time.monotonic() + LEARNER_START
            while not child.ready.wait(0.2) and child.process.poll() is None:
                if stop.is_set() or time.monotonic() > deadline:
                    break
        learner_gone = (
            "learner" not in system.children
            or system.children["learner"].process.poll() is not None
        )
        planner = {
            "policy": args.policy,
            "episodes": args.episodes,
            # Training draws its episodes from training_scenarios; the others plan `scenario`.
            **(
                {"training_scenarios": args.scenario}
                if args.policy == "training" and args.scenario is not None
                else {"scenario": args.scenario or DEFAULT_SCENARIO}
            ),
            "time_budget": args.time_budget,
            "run_id": run_id,
            # Hold the episodes until the recorder is subscribed to every topic.
            "wait_for_subscribers": 0 if args.no_record else 1,
            **_typed_params(args.planner_param, planner_node.PARAMETERS),
        }
        if not (stop.is_set() or learner_gone):
            system.start("planner", "lit_planner_node", planner)
        # A planner with exit_when_done ends the run itself once its episodes are done (its exit
        # code says whether they all ran); any other node that exits, even cleanly (a SIGTERM
        # from elsewhere), left the system short of what was asked, and the run failed.
        done_when_planner_exits = _given_values(args.planner_param, planner_node.PARAMETERS).get(
            "exit_when_done", False
        )
        while not stop.wait(0.2):
            dead = {n: c.process.poll() for n, c in system.children.items()}
            dead = {n: code for n, code in dead.items() if code is not None}
            if dead and done_when_planner_exits and set(dead) == {"planner"}:
                print(
                    f"lit up: the planner exited (exit {dead['planner']}, exit_when_done); "
                    "stopping the others",
                    flush=True,
                )
                break
            if dead:
                exits = ", ".join(f"{n} (exit {code})" for n, code in dead.items())
                failure = RuntimeError(f"{exits} exited before lit up was asked to stop")
                print(f"lit up: {failure}; stopping the others", flush=True)
                break
    except RuntimeError as error:  # the recorder exited, or hung, before it was ready
        failure = error
        print(f"lit up: {error}", file=sys.stderr, flush=True)
    finally:
        try:
            codes = system.stop()  # counts the interrupts that come while it waits
        finally:
            claim.close()
    stopped = ", ".join(f"{n} (exit {c})" for n, c in codes.items())
    print(f"lit up: stopped {stopped or 'before any process started'}", flush=True)
    return 0 if failure is None and all(code == 0 for code in codes.values()) else 1


_PRCTL = ctypes.CDLL(None, use_errno=True).prctl
_PR_SET_PDEATHSIG = 1


def _terminate_with_parent() -> None:
    """In the child before exec: SIGTERM it when the process that started it dies, even by
    SIGKILL (Linux ``PR_SET_PDEATHSIG``), so a killed ``lit up``/``lit demo`` leaves no nodes."""
    _PRCTL(_PR_SET_PDEATHSIG, int(signal.SIGTERM))


def stop_on_sigterm() -> None:
    """Turn SIGTERM and SIGHUP (the terminal closed) into KeyboardInterrupt, so ``finally``
    blocks stop the children in order (SIGHUP ended the launcher at once: its nodes, orphaned,
    stopped all at one moment, and its domain lock was free while they still ran)."""

    def interrupt(*_: object) -> None:
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, interrupt)
    signal.signal(signal.SIGHUP, interrupt)


def _params(items: Sequence[str]) -> dict[str, str]:
    result = {}
    for item in items:
        if ":=" not in item:
            raise ValueError(f"expected NAME:=VALUE, got {item!r}")
        name, value = item.split(":=", 1)
        result[name] = value
    return result


def _typed_params(items: Sequence[str], known: dict[str, Any]) -> dict[str, str]:
    """``NAME:=VALUE`` items checked against the type of each parameter's default, as the node
    declares it, and written so that rcl reads them as that type: a wrong type ended the node in
    a traceback after lit up had started. rcl reads ``-p`` values as YAML-like scalars (``1e3``
    and ``y`` are not text to it, ``010`` is octal), so text is passed quoted, whole numbers for
    float parameters as floats (it refuses ``time_budget:=1``), integers and booleans in one
    spelling. An empty value keeps an empty default (rcl refuses an empty value)."""
    return {name: RclSpelled(text) for name, (_, text) in _read_params(items, known).items()}


def _read_params(items: Sequence[str], known: dict[str, Any]) -> dict[str, tuple[Any, str]]:
    """Each ``NAME:=VALUE`` item's value, typed as its parameter's default, and the spelling rcl
    reads as that value (see :func:`_typed_params`); an unknown name keeps its text for both
    (the caller reports it, or it is ROS's own, use_sim_time). ValueError names a bad value."""
    result: dict[str, tuple[Any, str]] = {}
    for name, text in _params(items).items():
        if name not in known:
            result[name] = (text, text)
            continue
        default, word = known[name], text.strip()
        value: Any = None
        if isinstance(default, bool):
            ok, kind = word.lower() in _BOOLEAN_WORDS, "true or false"
            if ok:
                value = _BOOLEAN_WORDS[word.lower()]
                text = str(value).lower()
        elif isinstance(default, int):
            ok = re.fullmatch(r"[+-]?(0|[1-9]\d*)", word) is not None and (
                -(2**63) <= int(word) < 2**63
            )
            kind = "a whole number (no leading zeros)"
            if ok:
                value = int(word)
                text = str(value)
        elif isinstance(default, float):
            try:
                value = float(word)
            except ValueError:
                value = math.nan
            ok, kind = math.isfinite(value), "a finite number"
            text = repr(value) if ok else text
        elif not word:
            if default == "":
                continue  # the default already: rcl would refuse the empty value
            ok, kind = False, "text that is not empty"
        else:
            ok, kind = True, "text"
            quoted = len(word) >= 2 and word[0] == word[-1] and word[0] in "'\""
            value = word[1:-1] if quoted else text
            text = word if quoted else "'" + text.replace("'", "''") + "'"
        if not ok:
            raise ValueError(f"{name}:={text}: {name} takes {kind} (default {default!r})")
        result[name] = (value, text)
    return result


_BOOLEAN_WORDS = {"true": True, "false": False, "yes": True, "no": False, "on": True, "off": False}
"""The boolean words ``lit up`` takes (rcl takes these in lower case, among others)."""


class RclSpelled(str):
    """A parameter value spelled as rcl is to read it (:func:`_typed_params`): passed as it is."""


def _ros_value(value: object) -> str:
    """``value`` spelled for ``-p NAME:=VALUE``: text quoted, as rcl reads values as YAML-like
    scalars (``--scenario ,np4`` was a parse error that ended the planner at start; ``yes``
    would be a boolean)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, RclSpelled):
        return str(value)
    if isinstance(value, (str, os.PathLike)):  # YAML's double quotes read JSON's escapes
        return json.dumps(os.fspath(value), ensure_ascii=False)
    return str(value)


def _script(name: str) -> str:
    """A console script of this environment (beside the running interpreter)."""
    candidate = Path(sys.executable).parent / name
    return str(candidate) if candidate.exists() else name

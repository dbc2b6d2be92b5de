"""``lit call``: call the planner's and the learner's services as any other robot program would.

Examples::

    lit call plan --scenario np8 --time 0.5
    lit call plan --world world.json --time 1 --policy fit
    lit call decide --agent psi_K --rho-global 0.2 --rho-local 0.1 --measure 0.6
    lit call export
    lit call cancel --request-id req-7
    lit call raw /lit/planner/plan '{"not": "an envelope"}'

Prints the response as JSON on stdout (the envelope's payload with ``--payload-only``). Exit code
0 for a successful response, 1 for an Error response, 2 when the service is not found (for plan,
decide and raw also: has another type than ``AddDiagnostics``), does not answer in time or goes
away before it answers (no server for :data:`SERVER_GONE` s), or the arguments are wrong.

``plan`` gives its request a ``request_id`` (``call-<hex>`` unless ``--request-id`` or the world
file names one). When it stops waiting (``--timeout``, Ctrl-C, SIGTERM) it asks the planner
node's cancel service to cancel that request, so the query does not go on, and holds up the
queries behind it, for nobody.

A world file is JSON: ``{"lower": [...], "upper": [...], "boxes": [{"lower": [...], "upper":
[...]}, ...], "resolution": 0.001, "start": [...], "goal": [...]}`` (``resolution`` optional), or
a whole PlanRequest payload.
"""

from __future__ import annotations

import argparse
import contextlib
import faulthandler
import json
import math
import os
import signal
import sys
import threading
import time
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any

from lit_planner import argtypes, signals
from lit_planner.guarded_stdout import StdoutError
from lit_planner.rosutil import (
    CANCEL_SERVICE,
    DECIDE_SERVICE,
    DEFAULT_DOMAIN_ID,
    EXPORT_SERVICE,
    MAX_REQUEST_TIME,
    PLAN_RESENDS,
    PLAN_SERVICE,
    CallInterrupted,
    ServerGone,
    ServiceCaller,
    add_domain_option,
    freeze_startup_objects,
    localhost_environment,
    native_output_to_stderr,
    resolve_domain_id,
    spin_quietly,
)

DEFAULT_TIMEOUT = 60.0
"""Seconds to wait for an answer (a plan's own time budget is added)."""
DEFAULT_WAIT = 15.0
"""Seconds to wait for the service to appear."""
TEARDOWN_GRACE = 15.0
"""Seconds the ROS teardown may take once the call is over (well under 1 s as a rule, at most
about 3 s by its own timeouts) before the process exits without it: :func:`_exit_if_stuck`."""
CANCEL_WAIT = 5.0
"""Seconds a plan call that gave up waits for the cancel service to appear, and then for its
answer."""
SERVER_GONE = 1.0
"""Seconds the graph may show no server of the called service before a call stops waiting for
its answer (:class:`~lit_planner.rosutil.ServerGone`): its node stopped, and a request sent just
as it stopped is never answered."""
RESEND = 1.0
"""Seconds without an answer after which a request is sent again (then after 2, 4, ... s), if its
service answers a copy as the request it repeats (:func:`_resends`)."""

ANSWERS_COPIES = frozenset(
    f"lit_msgs_json/{name}" for name in ("DecideRequest", "EpisodeEnd", "CancelRequest")
)
"""Requests whose services answer a client's copy of its latest text as that request: the
learner's decide service from its cache, the planner's cancel service by repeating its answer.
The planner's plan service also takes a copy as the request (answered with its result), but
only a few are sent (:data:`PLAN_RESENDS`): each waits in the node for the whole query."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``lit call {plan,decide,export,raw}``."""
    parser.add_argument(
        "--wait",
        type=float,
        default=DEFAULT_WAIT,
        help="seconds to wait for the service to appear (default: %(default)g)",
    )
    parser.add_argument(
        "--timeout",
        type=float,
        default=None,
        help=f"seconds to wait for the answer, all told (default: {DEFAULT_TIMEOUT:g}, plus the "
        f"plan's --time for plan, or {MAX_REQUEST_TIME:g} with --iterations or --batches alone; a "
        "plan request is then cancelled in the node)",
    )
    parser.add_argument(
        "--payload-only", action="store_true", help="print only the response's payload"
    )
    add_domain_option(parser, DEFAULT_DOMAIN_ID)  # lit up's default: its nodes answer
    commands = parser.add_subparsers(dest="service", required=True)
    plan = commands.add_parser("plan", help="call <namespace>/lit/planner/plan")
    where = plan.add_mutually_exclusive_group(required=True)
    where.add_argument("--scenario", help="registered scenario, e.g. np8 or rrd8/3")
    where.add_argument("--world", type=argtypes.path, help="JSON file with an explicit world")
    plan.add_argument(
        "--time", type=float, help="time budget, s (default: the scenario's; a world's: 1)"
    )
    plan.add_argument(
        "--planner",
        help="litstar, litstar-fit (LIT* with that policy) or an OMPL baseline, e.g. aitstar "
        "(default: litstar)",
    )
    plan.add_argument(
        "--policy",
        choices=("fixed", "fit", "tensor"),
        help="LIT*'s policy (default: the planner node's)",
    )
    plan.add_argument("--seed", type=int, help="seed (default: the planner node's)")
    plan.add_argument(
        "--iterations",
        type=int,
        metavar="N",
        help="LIT*: stop after N iterations (sent as max_iterations; without --time the query "
        "stops on this alone, the same answer for the same seed; default: no limit)",
    )
    plan.add_argument(
        "--batches",
        type=int,
        metavar="N",
        help="LIT*: stop after N batches (max_batches; default: no limit)",
    )
    plan.add_argument(
        "--start",
        type=_vector,
        help="override the start, e.g. 0.1,0.2,... (default: the scenario's or world's)",
    )
    plan.add_argument(
        "--goal", type=_vector, help="override the goal (default: the scenario's or world's)"
    )
    plan.add_argument(
        "--namespace", default="/", help="the planner node's namespace (default: %(default)s)"
    )
    plan.add_argument(
        "--request-id",
        help="echoed in the response, and named by a cancel (default: call-<hex>)",
    )
    cancel = commands.add_parser(
        "cancel", help="call <namespace>/lit/planner/cancel: cancel a plan request by its id"
    )
    cancel.add_argument(
        "--request-id", required=True, help="the request_id of the plan request to cancel"
    )
    cancel.add_argument(
        "--namespace", default="/", help="the planner node's namespace (default: %(default)s)"
    )
    decide = commands.add_parser("decide", help="call /lit/learner/decide")
    decide.add_argument(
        "--agent",
        choices=("B", "psi_K"),
        default="B",
        help="the agent that decides (default: %(default)s)",
    )
    decide.add_argument(
        "--episode-id", default=None, help="the episode (default: a new one, call-<hex>)"
    )
    for option, default, meaning in (
        ("--rho-global", 0.1, "feature rho_global in [0, 1]"),
        ("--rho-local", 0.1, "feature rho_local in [0, 1]"),
        ("--measure", 0.5, "feature m in [0, 1]"),
        ("--planning-time", 0.0, "planner clock since the episode started, s"),
        ("--time-budget", 1.0, "the episode's time budget, s"),
    ):
        decide.add_argument(
            option, type=float, default=default, help=f"{meaning} (default: %(default)g)"
        )
    decide.add_argument(
        "--cost", type=float, default=None, help="current best cost (default: none, no solution)"
    )
    decide.add_argument(
        "--minimum-cost",
        type=float,
        default=1.0,
        help="start-goal straight-line distance (default: %(default)g)",
    )
    decide.add_argument(
        "--improvements", type=int, default=0, help="solution improvements so far (default: 0)"
    )
    decide.add_argument(
        "--path-states", type=int, default=0, help="states on the best path (default: 0)"
    )
    decide.add_argument(
        "--explore", action="store_true", help="exploration noise on (default: off)"
    )
    decide.add_argument(
        "--no-probe",
        dest="probe",
        action="store_false",
        help="send the requests as a planner's steps, which the learner records and trains on "
        "(default: probes, answered and never trained on); for round trips of the planner's own "
        "path against a throwaway learner, as lit system-bench does",
    )
    decide.add_argument(
        "--service-name", default=DECIDE_SERVICE, help="service to call (default: %(default)s)"
    )
    decide.add_argument(
        "--repeat",
        type=int,
        default=1,
        metavar="N",
        help="benchmark: send N requests one after another (after 20 warm-up calls) and print "
        "the round-trip median and p99 (default: %(default)s, no benchmark)",
    )
    commands.add_parser("export", help="call /lit/learner/export (write the lookup tensors)")
    raw = commands.add_parser("raw", help="send TEXT unchanged to an AddDiagnostics service")
    raw.add_argument("name", help="service name, e.g. /lit/planner/plan")
    raw.add_argument("text", help="the request text ('-': read standard input)")
    raw.add_argument(
        "--repeat",
        type=int,
        default=1,
        metavar="N",
        help="benchmark, as for decide (default: %(default)s)",
    )


def run(args: argparse.Namespace) -> int:
    """Build the request, call the service, print the answer."""
    try:
        for label, value in (("--wait", args.wait), ("--timeout", args.timeout)):
            if value is not None and not (math.isfinite(value) and value > 0):
                raise ValueError(
                    f"{label} must be a finite positive number of seconds, got {value}"
                )
        if getattr(args, "repeat", 1) < 1:
            raise ValueError(f"--repeat must be 1 or more, got {args.repeat}")
        for option, value in vars(args).items():
            # Bytes that are not UTF-8 arrive as lone surrogates: rclpy.init() failed on them
            # with a traceback and exit 1 (answered with an Error).
            if isinstance(value, str) and not _is_utf8(value):
                label = option.upper() if option in ("name", "text") else f"--{option}"
                raise ValueError(f"{label.replace('_', '-')}: not valid UTF-8 text: {value!r}")
        # Checked here: rclpy's traceback, or Fast DDS's port errors and exit 1, otherwise.
        os.environ["ROS_DOMAIN_ID"] = str(resolve_domain_id(args.domain_id, DEFAULT_DOMAIN_ID))
        name, text = _request(args)
        if args.timeout is None:  # a long plan must not time out on the client's side for sure
            payload = json.loads(text)["payload"] if args.service == "plan" else {}
            plan_time = payload.get("time")
            if plan_time is None and (payload.get("max_iterations") or payload.get("max_batches")):
                plan_time = MAX_REQUEST_TIME  # what the node then allows
            args.timeout = DEFAULT_TIMEOUT + float(plan_time or 0.0)
    except (OSError, ValueError) as exc:
        print(f"lit call: error: {exc}", file=sys.stderr)
        return 2
    native_output_to_stderr()
    localhost_environment()
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    # Our own handlers: rclpy's shut every context down, so the cancel of a plan request needed
    # a context of its own and had to find the cancel service again (0.45-0.5 s to the node on a
    # quiet machine, about 2 s under load), the query running on meanwhile.
    interrupts = Interrupts()
    with signals.handling((signal.SIGINT, signal.SIGTERM), interrupts):
        # not sys.argv: lit call's own options are no ROS arguments
        rclpy.init(args=[], signal_handler_options=SignalHandlerOptions.NO)
        node = rclpy.create_node(f"lit_call_{uuid.uuid4().hex[:8]}")
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        spinner = threading.Thread(target=spin_quietly, args=(executor, lambda: False), daemon=True)
        spinner.start()
        callers: list[ServiceCaller] = []
        code = 1  # what an exception leaves with, should the teardown hang
        try:
            code = _call(node, args, name, text, callers, interrupts)
            return code
        finally:
            disarm = _exit_if_stuck(code)
            for caller in callers:
                caller.destroy()
            # Stop the spinning thread before tearing down (a joinable C++ thread at exit
            # aborts).
            executor.shutdown(timeout_sec=1.0)
            rclpy.shutdown()
            spinner.join(timeout=2.0)
            node.destroy_node()
            disarm()


class Interrupts:
    """A signal handler that counts Ctrl-Cs and SIGTERMs: the first stops the wait (a plan request
    is then cancelled in the node), a second one that cancel."""

    def __init__(self) -> None:
        self.count = 0

    def __call__(self, *_: object) -> None:
        self.count += 1

    def first(self) -> bool:
        """Whether a signal came."""
        return self.count >= 1

    def again(self) -> bool:
        """Whether a second one came."""
        return self.count >= 2


def _resends(text: str) -> tuple[float | None, int | None]:
    """When to send ``text`` again without an answer, and how many copies at most:
    (:data:`RESEND`, no limit) for a request whose service answers a copy as the request it
    repeats (:data:`ANSWERS_COPIES`), (:data:`RESEND`, :data:`PLAN_RESENDS`) for a plan request,
    else (None, None): sent once. A request or its answer can be lost while a new client is
    still being matched, with no error on either side (in CI: a cancel, and a decide request the
    learner had answered, each followed by 60 s of silence); a copy sent then gets the
    answer."""
    try:
        schema = json.loads(text).get("schema")
    except (ValueError, AttributeError, RecursionError):  # not JSON, not an object: sent once
        return None, None
    if schema == "lit_msgs_json/PlanRequest":
        return RESEND, PLAN_RESENDS
    return (RESEND, None) if schema in ANSWERS_COPIES else (None, None)


def _call(
    node: Any,
    args: argparse.Namespace,
    name: str,
    text: str,
    callers: list[ServiceCaller],
    interrupts: Interrupts,
) -> int:
    """Find the service, call it and print the answer; the exit code. A caller made is added to
    ``callers`` (:func:`run` destroys it)."""
    from rclpy.exceptions import InvalidServiceNameException

    cancel: ServiceCaller | None = None
    try:
        if args.service == "export":
            return _call_export(node, args, interrupts)
        try:
            caller = ServiceCaller(node, name, private=True)
            callers.append(caller)
        except InvalidServiceNameException as exc:  # --namespace "bad ns!", a raw NAME
            reason = str(exc).splitlines()[0].rstrip(":")  # rclpy adds the name and a caret
            print(f"lit call: error: service name {name!r}: {reason}", file=sys.stderr)
            return 2
        if args.service == "plan":
            # Made now, so that DDS has matched it with the cancel service by the time this call
            # gives up on the plan.
            cancel_name = _service_name(args.namespace, CANCEL_SERVICE)
            cancel = ServiceCaller(node, cancel_name, private=True, suffix="cancel")
            callers.append(cancel)
        if not caller.wait(args.wait, interrupted=interrupts.first):
            others = _other_types(node, name)
            if others:  # found, but not one of ours: say so instead of "not found"
                print(
                    f"lit call: error: service {name} has type {', '.join(others)}; lit call "
                    "speaks diagnostic_msgs/srv/AddDiagnostics (JSON envelopes), as the lit "
                    "nodes serve",
                    file=sys.stderr,
                )
                return 2
            print(
                f"lit call: error: service {name} not found within {args.wait:g} s "
                f"(ROS_DOMAIN_ID={_domain()})",
                file=sys.stderr,
            )
            return 2
        if args.service in ("decide", "raw") and args.repeat > 1:
            return _repeat(caller, text, args, interrupts)
        started = time.perf_counter()
        args.sent = True
        # A Ctrl-C or SIGTERM: the wait notices it within 0.1 s.
        resend_after, max_resends = _resends(text)
        answer = caller.call(
            text,
            args.timeout,
            resend_after=resend_after,
            interrupted=interrupts.first,
            server_gone=SERVER_GONE,
            max_resends=max_resends,
        )
        elapsed = time.perf_counter() - started
        if answer is None:
            print(
                f"lit call: error: {name} did not answer within {args.timeout:g} s", file=sys.stderr
            )
            if cancel is not None:
                _cancel_plan(cancel, args, interrupts.first)  # a Ctrl-C stops this cancel
            return 2
        success, message = answer
        _print(message, args.payload_only)
        print(
            f"lit call: {name} answered in {elapsed * 1e3:.1f} ms "
            f"({'success' if success else 'error'})",
            file=sys.stderr,
        )
        if success and _path_failed_recheck(message):
            print(
                "lit call: warning: the returned path failed the node's independent re-check "
                "(path_valid false): it leaves the free space between the planner's collision "
                "checks; do not execute it as it is (exit 3). A registry scenario's edges are "
                "checked at its resolution; an explicit world's exactly, so there this is a bug "
                "to report",
                file=sys.stderr,
            )
            return PATH_INVALID_EXIT
        return 0 if success else 1
    except ServerGone as exc:  # nobody left to cancel a plan request in
        print(f"lit call: error: {exc}", file=sys.stderr)
        return 2
    except CallInterrupted:  # a Ctrl-C or SIGTERM
        print("lit call: interrupted", file=sys.stderr)
        if cancel is not None and getattr(args, "sent", False):
            _cancel_plan(cancel, args, interrupts.again)  # a second one stops the cancel
        return 130


def _exit_if_stuck(code: int) -> Callable[[], None]:
    """Exit if the ROS teardown has not ended :data:`TEARDOWN_GRACE` s from now; the function
    that disarms it (:func:`run` calls it once the teardown is done).

    Armed once the call is over, before the teardown: once in CI a ``lit call`` whose planner
    node was shutting down meanwhile printed its answer and then did not exit (a test waited
    60 s for it). A timer exits with ``code`` after printing where each thread was; rclpy's
    teardown calls into DDS with the GIL held, though, and a hang there would hold that timer up
    too, so :mod:`faulthandler`'s C thread ends the process (exit 1, the stacks first) twice as
    late. A hang in the interpreter's exit after :func:`run` returned is not covered.
    """

    def stuck() -> None:
        print(
            f"lit call: the ROS teardown did not end within {TEARDOWN_GRACE:g} s; exiting with "
            f"{code} without it. Where each thread was:",
            file=sys.stderr,
            flush=True,
        )
        faulthandler.dump_traceback(file=sys.stderr, all_threads=True)
        with contextlib.suppress(OSError, ValueError, StdoutError):
            sys.stdout.flush()
        os._exit(code)

    timer = threading.Timer(TEARDOWN_GRACE, stuck)
    timer.daemon = True
    timer.start()
    faulthandler.dump_traceback_later(2 * TEARDOWN_GRACE, exit=True, file=sys.stderr)

    def disarm() -> None:
        timer.cancel()
        faulthandler.cancel_dump_traceback_later()

    return disarm


def _service_name(namespace: str, service: str) -> str:
    """The absolute name of the planner node's ``service`` in ``namespace``."""
    name = namespace.rstrip("/") + "/" + service
    return name if name.startswith("/") else "/" + name


def _cancel_plan(
    caller: ServiceCaller, args: argparse.Namespace, interrupted: Callable[[], bool]
) -> None:
    """Ask the planner node, through the cancel service's ``caller``, to cancel the plan request
    this call gave up on; say on stderr what it answered. ``interrupted``: stops the cancel (a
    Ctrl-C during it, or a second one after the first stopped the plan's wait)."""
    from lit_msgs_json.envelope import MessageError, Publisher

    name = caller.name
    request_id = args.sent_request_id
    publisher = Publisher(f"lit_call/{os.getpid()}", f"call-{uuid.uuid4().hex[:8]}")
    try:
        text = publisher.encode("CancelRequest", {"request_id": request_id})
    except MessageError:  # a world file's own request_id that the node refused as well
        return
    try:
        if not caller.wait(CANCEL_WAIT, interrupted=interrupted):
            outcome = f"{name} not found within {CANCEL_WAIT:g} s; the query may go on in the node"
        else:
            answer = caller.call(
                text,
                CANCEL_WAIT,
                resend_after=RESEND,
                interrupted=interrupted,
                server_gone=SERVER_GONE,
            )
            outcome = _cancel_outcome(answer, name)
    except ServerGone as exc:
        outcome = str(exc)
    except CallInterrupted:
        print("lit call: interrupted again; the plan request was not cancelled", file=sys.stderr)
        return
    print(f"lit call: cancel of plan request {request_id!r}: {outcome}", file=sys.stderr)


def _cancel_outcome(answer: tuple[bool, str] | None, name: str) -> str:
    """What the cancel service ``name`` answered, in words."""
    from lit_msgs_json.envelope import MessageError, decode

    if answer is None:
        return f"{name} did not answer within {CANCEL_WAIT:g} s"
    try:
        reply = decode(answer[1], accept=("CancelResponse", "Error"))
    except MessageError as exc:
        return f"unreadable answer from {name}: {exc}"
    return str(reply.payload["message"])


def _other_types(node: Any, name: str) -> list[str]:
    """The types the graph shows for service ``name`` other than ours (empty: none seen)."""
    ours = "diagnostic_msgs/srv/AddDiagnostics"
    for found, types in node.get_service_names_and_types():
        if found == (name if name.startswith("/") else "/" + name):
            return [kind for kind in types if kind != ours]
    return []


def _request(args: argparse.Namespace) -> tuple[str, str]:
    from lit_msgs_json.envelope import Publisher

    from lit_planner import planning, scenarios

    publisher = Publisher(f"lit_call/{os.getpid()}", f"call-{uuid.uuid4().hex[:8]}")
    if args.service == "plan":
        payload: dict[str, Any] = {}
        if args.world is not None:
            data = _read_world(args.world)
            try:
                document = json.loads(data.decode("utf-8"))
            except ValueError as exc:  # JSONDecodeError, UnicodeDecodeError
                raise ValueError(f"--world {args.world}: not valid JSON: {exc}") from exc
            if not isinstance(document, dict):
                raise ValueError(f"--world {args.world}: expected a JSON object")
            if "world" in document:
                payload.update(document)
            else:
                world_keys = ("lower", "upper", "boxes", "resolution")
                known = (*world_keys, "start", "goal")
                unknown = sorted(set(document) - set(known))
                if unknown:  # a misspelt "resolution" was dropped and the default used
                    raise ValueError(
                        f"--world {args.world}: unknown key{'s' if len(unknown) > 1 else ''} "
                        f"{', '.join(map(repr, unknown))}; a world file has "
                        f'{", ".join(known)} (or a whole PlanRequest payload with "world")'
                    )
                payload["world"] = {k: document[k] for k in world_keys if k in document}
                for key in ("start", "goal"):
                    if key in document:
                        payload[key] = document[key]
        else:
            # The planner checks the name too; a wrong one is refused here with the message
            # `lit plan` gives instead of the schema's pattern error, and nothing is sent.
            dim = scenarios.get(args.scenario).dim  # ScenarioError is a ValueError
            payload["scenario"] = args.scenario
            for key in ("start", "goal"):  # as the node would refuse them: nothing is sent
                value = getattr(args, key)
                if value is not None and len(value) != dim:
                    raise ValueError(
                        f"--{key} has {len(value)} coordinates; {args.scenario} has {dim} "
                        "dimensions"
                    )
        if args.planner in planning.SHORTHANDS:  # as `lit plan` takes them: litstar-fit
            args.planner, args.policy = planning.resolve_planner(args.planner, args.policy)
        elif args.planner is not None:
            # An unknown name, or a policy for an OMPL planner, gets `lit plan`'s message (the
            # shorthands listed; the schema's enum error lists only the node's names) and
            # nothing is sent: exit 2 as for a shorthand that contradicts --policy (the node's
            # invalid-request Error, exit 1, said "refused by the planner" for a typing error).
            planning.resolve_planner(args.planner, args.policy)
        if args.planner is not None:  # an OMPL planner with --iterations, --batches or --seed
            planning.check_stops_on_count(args.planner, bool(args.iterations or args.batches))
            planning.check_seed_in_node(args.planner, args.seed is not None)
        for key in ("time", "planner", "policy", "seed", "start", "goal", "request_id"):
            value = getattr(args, key)
            if value is not None:
                payload[key] = value
        for option, key in (("iterations", "max_iterations"), ("batches", "max_batches")):
            value = getattr(args, option)
            if value == 0:  # the node's "no limit": it planned on the scenario's time instead
                raise ValueError(f"--{option} must be at least 1 (leave it out for no limit)")
            if value is not None:  # the node refuses a value it cannot take
                payload[key] = value
        # An id of its own, for the cancel this call sends when it stops waiting.
        payload.setdefault("request_id", f"call-{uuid.uuid4().hex[:12]}")
        args.sent_request_id = payload["request_id"]
        return _service_name(args.namespace, PLAN_SERVICE), publisher.encode("PlanRequest", payload)
    if args.service == "cancel":
        return _service_name(args.namespace, CANCEL_SERVICE), publisher.encode(
            "CancelRequest", {"request_id": args.request_id}
        )
    if args.service == "decide":
        payload = {
            "agent": args.agent,
            "episode_id": (
                f"call-{uuid.uuid4().hex[:8]}" if args.episode_id is None else args.episode_id
            ),
            "rho_global": args.rho_global,
            "rho_local": args.rho_local,
            "measure": args.measure,
            "planning_time": args.planning_time,
            "time_budget": args.time_budget,
            "cost": args.cost,
            "minimum_cost": args.minimum_cost,
            "improvements": args.improvements,
            "path_states": args.path_states,
            "explore": args.explore,
            "probe": args.probe,  # made-up features: by default answered, never trained on
        }
        return args.service_name, publisher.encode("DecideRequest", payload)
    if args.service == "export":
        return EXPORT_SERVICE, ""
    text = sys.stdin.read() if args.text == "-" else args.text
    if args.text != "-" and not args.text.lstrip().startswith("{") and Path(args.text).is_file():
        # Sent as is, the node would answer "not valid JSON" about the file's name.
        raise ValueError(
            f"{args.text} is a file, and TEXT is sent as it is; send the file's contents with "
            f"`lit call raw {args.name} - < {args.text}`"
        )
    if not _is_utf8(text):  # bytes read as surrogates: rclpy failed with a traceback
        raise ValueError("the request is not valid UTF-8 (a ROS string carries UTF-8 text)")
    return args.name, text


def _is_utf8(text: str) -> bool:
    """Whether ``text`` encodes to UTF-8 (no lone surrogates, as undecodable bytes become)."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def _read_world(path: Path) -> bytes:
    """The bytes of ``--world``'s file; a missing, unreadable or non-file path as one message."""
    try:
        return path.read_bytes()
    except FileNotFoundError:
        problem = "no such file"
    except IsADirectoryError:
        problem = "a folder, not a file"
    except PermissionError:
        problem = "not readable (permission denied)"
    except OSError as exc:
        problem = f"cannot read it: {exc.strerror or exc}"
    raise ValueError(f"--world {path}: {problem}")


def _repeat(
    caller: ServiceCaller, text: str, args: argparse.Namespace, interrupts: Interrupts
) -> int:
    """Round trips: 20 warm-up calls, then ``--repeat`` timed ones.

    ``decide`` times what the planner pays per decision: encoding a new request (its own seq),
    the call, and decoding and validating the answer. ``raw`` sends ``text`` as it is and times
    the call only.
    """
    import numpy as np
    from lit_msgs_json.envelope import MessageError, Publisher, decode

    request = json.loads(text) if args.service == "decide" else None
    # A source of its own per process: the learner keeps one open episode per source.
    publisher = Publisher(f"lit_call/{os.getpid()}", f"call-{uuid.uuid4().hex[:8]}")
    freeze_startup_objects()  # a full collection here would show up as a round trip's time
    times = []
    for index in range(20 + args.repeat):
        started = time.perf_counter()
        if request is not None:
            text = publisher.encode("DecideRequest", request["payload"])
        answer = caller.call(
            text, args.timeout, interrupted=interrupts.first, server_gone=SERVER_GONE
        )
        if answer is not None and answer[0] and request is not None:
            try:
                decode(answer[1], accept="DecideResponse")
            except MessageError as exc:
                answer = (False, str(exc))
        elapsed = time.perf_counter() - started
        if answer is None:
            print(
                f"lit call: error: call {index}: no answer within --timeout {args.timeout:g} s",
                file=sys.stderr,
            )
            return 2
        if not answer[0]:
            _print(answer[1], args.payload_only)  # the Error, as a single call prints it
            print(f"lit call: error: call {index} was answered with an error", file=sys.stderr)
            return 1
        if index >= 20:
            times.append(elapsed * 1e3)
    ms = np.asarray(times)
    print(
        json.dumps(
            {
                "calls": len(times),
                "median_ms": float(np.median(ms)),
                "p99_ms": float(np.percentile(ms, 99)),
                "mean_ms": float(ms.mean()),
                "max_ms": float(ms.max()),
            },
            indent=2,
        )
    )
    return 0


def _call_export(node: Any, args: argparse.Namespace, interrupts: Interrupts) -> int:
    from std_srvs.srv import Trigger

    caller = ServiceCaller(node, EXPORT_SERVICE, srv_type=Trigger)
    if not caller.wait(args.wait, interrupted=interrupts.first):
        print(
            f"lit call: error: service {EXPORT_SERVICE} not found within {args.wait:g} s "
            f"(ROS_DOMAIN_ID={_domain()})",
            file=sys.stderr,
        )
        return 2
    response = caller.request(
        Trigger.Request(), args.timeout, interrupted=interrupts.first, server_gone=SERVER_GONE
    )
    if response is None:
        print(f"lit call: error: {EXPORT_SERVICE} did not answer", file=sys.stderr)
        return 2
    print(response.message)
    return 0 if response.success else 1


PATH_INVALID_EXIT = 3
"""Exit status of ``lit call plan`` whose answer holds a path that failed the re-check (a script
that only looks at the exit status must not take it for a plan to execute)."""


def _path_failed_recheck(message: str) -> bool:
    """Whether a plan answer says its path failed the independent re-check."""
    try:
        payload = json.loads(message).get("payload")
    except (ValueError, AttributeError):
        return False
    return isinstance(payload, dict) and payload.get("path_valid") is False


def _print(message: str, payload_only: bool) -> None:
    try:
        document = json.loads(message)
    except ValueError:
        print(message)
        return
    if payload_only and isinstance(document, dict) and "payload" in document:
        document = document["payload"]
    print(json.dumps(document, indent=2))


def _vector(text: str) -> list[float]:
    try:
        return [float(x) for x in text.split(",")]
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") from exc


def _domain() -> str:
    import os

    return os.environ.get("ROS_DOMAIN_ID", "0")

"""The ``lit`` command: one entry point whose subcommands live in their own modules.

Each subcommand is a row of :data:`COMMANDS`. Its module is imported only when that subcommand is
chosen, so ``lit --help`` and ``lit test`` never pay for torch, rclpy or the C++ core. A subcommand
module provides ``add_arguments(parser)`` and a run function taking the parsed
:class:`argparse.Namespace` and returning an exit code.
"""

from __future__ import annotations

import argparse
import importlib
import os
import re
import signal
import sys
from collections.abc import Sequence
from dataclasses import dataclass

from lit_planner import signals
from lit_planner.guarded_stdout import GuardedStdout, StdoutError


@dataclass(frozen=True)
class Command:
    """One ``lit`` subcommand."""

    module: str
    """Module that implements it (imported lazily)."""
    help: str
    """One line for ``lit --help``."""
    run: str = "run"
    """Name of the module's ``(args) -> int`` function."""
    stops_like_ctrl_c: bool = False
    """``kill PID`` (SIGTERM) and a closed terminal (SIGHUP) stop it as Ctrl-C does: its
    ``finally`` blocks run (the children it started, its temporary files), it says "interrupted"
    and exits 130. The other commands handle the signals themselves, or end at once."""


COMMANDS: dict[str, Command] = {
    "demo": Command(
        "lit_planner.demo",
        "learner, planner and recorder as ROS 2 processes: training episodes over ROS, then "
        "inference plans of np8 (--local: one plan in-process)",
    ),
    "bench": Command(
        "lit_planner.bench.cli",
        "benchmark planners on the paper's scenarios: statistics, tables, plots (--quick, --paper)",
    ),
    "plan": Command(
        "lit_planner.plan_cli",
        "plan one query with LIT* or an OMPL planner (C++ core)",
        stops_like_ctrl_c=True,
    ),
    "arena": Command(
        "lit_planner.arena",
        "turn a bench run folder's runs.jsonl into OMPL benchmark logs and a Planner Arena database",
        stops_like_ctrl_c=True,
    ),
    "replay": Command(
        "lit_planner.replay",
        "read recorded bags: info, verify, salvage, compact, regenerate bench outputs or tensors",
    ),
    "up": Command(
        "lit_planner.up",
        "start the recorder, the learner and a planner node as ROS 2 processes; Ctrl-C stops all",
    ),
    "system-bench": Command(
        "lit_planner.system_bench",
        "measure the ROS system: decide round trip, training vs tensor throughput, dead learner",
    ),
    "call": Command(
        "lit_planner.call",
        "call the planner's plan service or the learner's decide/export services; print JSON",
    ),
    "crosscheck": Command(
        "lit_planner.crosscheck",
        "independent cross-check: LIT*'s paths and costs against OMPL 2.0.1 (PyPI ompl) planners",
        stops_like_ctrl_c=True,
    ),
    "train": Command(
        "lit_learner.train",
        "train the Fuzzy-DDPG policy (B, then psi_K) in-process against LIT*; export lookup tensors",
    ),
    "toy": Command(
        "lit_learner.toy",
        "train the B agent on a fixed toy query (np2, 1000 iterations as its horizon): greedy "
        "return against constant B",
        stops_like_ctrl_c=True,
    ),
    "tensors": Command(
        "lit_planner.tensors_cli",
        "check lookup tensors as the planner does (info) and make constant ones without "
        "training, a baseline for lit bench --tensors (constant)",
    ),
    "test": Command(
        "lit_planner.testing", "run all tests: C++ (ctest) and Python (pytest)", run="main"
    ),
}


def _load(name: str) -> object:
    module_name = COMMANDS[name].module
    try:
        return importlib.import_module(module_name)
    except ModuleNotFoundError as error:
        if error.name != module_name:
            raise  # a real missing dependency inside the module: show the traceback
        raise SystemExit(f"lit {name}: {module_name} is not available in this checkout") from None


def build_parser(selected: str | None) -> tuple[argparse.ArgumentParser, object | None]:
    """Build the parser; only the ``selected`` subcommand's module is imported."""
    parser = argparse.ArgumentParser(
        prog="lit", description="LIT* (Learning-based Informed Trees) over ROS 2."
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    module = None
    for name, command in COMMANDS.items():
        subparser = subparsers.add_parser(name, help=command.help, description=command.help)
        if name == selected:
            module = _load(name)
            module.add_arguments(subparser)  # type: ignore[attr-defined]
    return parser, module


NEGATIVE_LIST = re.compile(r"-\.?\d[^,\s]*(,[^,\s]+)+")
"""A comma-separated list of numbers whose first is negative, e.g. ``-0.3,0``."""


def _join_negative_lists(argv: list[str]) -> list[str]:
    """``--start -0.3,0`` as ``--start=-0.3,0``: argparse takes a value that starts with '-'
    and is not a plain negative number for an option, and refuses ``--start`` without its
    value (every scenario's start has a negative first coordinate)."""
    joined: list[str] = []
    for index, arg in enumerate(argv):
        if arg == "--":  # what follows is passed on as it is (lit test's pytest arguments)
            return joined + argv[index:]
        if (
            joined
            and NEGATIVE_LIST.fullmatch(arg)
            and joined[-1].startswith("--")
            and joined[-1] != "--"
            and "=" not in joined[-1]
        ):
            joined[-1] = f"{joined[-1]}={arg}"
        else:
            joined.append(arg)
    return joined


def _innermost_parser(
    parser: argparse.ArgumentParser, args: argparse.Namespace
) -> argparse.ArgumentParser:
    """The parser of the innermost subcommand chosen in ``args`` (``lit replay salvage``'s)."""
    while True:
        chosen = next(
            (
                action.choices.get(getattr(args, action.dest, None))
                for action in parser._actions  # argparse keeps no public list of them
                if isinstance(action, argparse._SubParsersAction)
            ),
            None,
        )
        if chosen is None:
            return parser
        parser = chosen


def _quiet_stdout() -> None:
    """Point standard output at /dev/null: Python's flush at exit would fail again."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())


def main(argv: Sequence[str] | None = None) -> int:
    """Parse ``argv`` (default: ``sys.argv[1:]``) and run the chosen subcommand."""
    argv = _join_negative_lists(list(sys.argv[1:] if argv is None else argv))
    for stream in (sys.stdout, sys.stderr):
        # Text that is not Unicode (a lone surrogate in a recorded message or a sidecar) is
        # printed escaped: it ended `lit replay info` and `lit tensors info` with a
        # UnicodeEncodeError, and nothing else of their output.
        if stream is not None and hasattr(stream, "reconfigure"):
            stream.reconfigure(errors="backslashreplace")
    stdout = sys.stdout
    # Guarded from the start, so that --help and usage lines are too (argparse ignores an OSError
    # when it prints them); a closed standard output (`>&-`, sys.stdout None) stays as Python has it.
    guard = None if stdout is None else GuardedStdout(stdout)
    if guard is not None:
        sys.stdout = guard
    name = "lit"
    try:
        selected = next((arg for arg in argv if not arg.startswith("-")), None)
        parser, module = build_parser(selected if selected in COMMANDS else None)
        args, extra = parser.parse_known_args(argv)
        if extra:  # named by the (sub)command they were given to, with its usage, not lit's
            _innermost_parser(parser, args).error(f"unrecognized arguments: {' '.join(extra)}")
        name = f"lit {args.command}"
        run = getattr(module, COMMANDS[args.command].run)
        # A non-interactive shell starts background commands with SIGINT ignored, and Python then
        # installs no KeyboardInterrupt handler: `kill -INT` would do nothing, although every
        # command documents how it stops on it (and children inherit the ignoring). Restore it.
        if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
            signal.signal(signal.SIGINT, signal.default_int_handler)
        stops = (signal.SIGTERM, signal.SIGHUP) if COMMANDS[args.command].stops_like_ctrl_c else ()
        with signals.handling(stops, signal.default_int_handler):
            code = int(run(args) or 0)
        if sys.stdout is not None:
            sys.stdout.flush()  # a write error shows here, not at exit
        return code
    except KeyboardInterrupt:  # Ctrl-C: the command's own finally blocks have stopped its children
        print(f"{name}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # `lit plan --json | head -c 100`: the reader left; no traceback
        _quiet_stdout()
        return 141  # as if killed by SIGPIPE, what a shell reports for such a pipeline
    except StdoutError as error:
        _quiet_stdout()
        print(f"{name}: cannot write to standard output: {error}", file=sys.stderr)
        return 2
    finally:
        if guard is not None and sys.stdout is guard:  # not if the command set its own
            sys.stdout = stdout


if __name__ == "__main__":
    sys.exit(main())

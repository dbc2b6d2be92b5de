"""``lit call`` refuses bad arguments with one line and exit 2 before it sends anything, and its
help names every option's default."""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from lit_planner import call


def lit_call(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """``lit call ARGS``; a long --wait: a refusal must come before any wait for a service."""
    return subprocess.run(
        [sys.executable, "-m", "lit_planner.cli", "call", "--wait", "600", *args],
        cwd=cwd,
        env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST"),
        capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip


def refusal(process: subprocess.CompletedProcess[str]) -> str:
    """The one line of a refused ``lit call``."""
    assert process.returncode == 2, process.stdout + process.stderr
    assert process.stdout == ""
    lines = process.stderr.strip().splitlines()
    assert len(lines) == 1, process.stderr
    assert lines[0].startswith("lit call: error: ")
    return lines[0]


@pytest.mark.parametrize("name", ["foo", "xy8", "NP8", "np8/"])
def test_plan_refuses_an_unknown_scenario_as_lit_plan_does(tmp_path: Path, name: str) -> None:
    """Not the schema's pattern error from the planner: the scenario registry's own message."""
    line = refusal(lit_call("plan", "--scenario", name, cwd=tmp_path))
    assert line == (
        f"lit call: error: unknown scenario {name!r}: expected <family><dim>[/<instance>] with "
        "family one of ['np', 'rr', 'rrd', 'wg'] and numbers without leading zeros, e.g. 'np8' "
        "or 'rrd8/3'"
    )


def test_plan_refuses_a_scenario_the_registry_refuses(tmp_path: Path) -> None:
    line = refusal(lit_call("plan", "--scenario", "np8/3", cwd=tmp_path))
    assert line == "lit call: error: scenario 'np8/3': family 'np' has only instance 0, not 3"


@pytest.mark.parametrize("option", ["--iterations", "--batches"])
def test_plan_refuses_a_limit_of_zero(tmp_path: Path, option: str) -> None:
    """0 is the node's "no limit": `--iterations 0` planned on the scenario's wall-clock budget,
    against the help's "without --time the query stops on this alone"."""
    line = refusal(lit_call("plan", "--scenario", "np8", option, "0", cwd=tmp_path))
    assert line == f"lit call: error: {option} must be at least 1 (leave it out for no limit)"


def test_plan_refuses_a_missing_world_file_or_a_folder(tmp_path: Path) -> None:
    missing = tmp_path / "nonexistent.json"
    line = refusal(lit_call("plan", "--world", str(missing), cwd=tmp_path))
    assert line == f"lit call: error: --world {missing}: no such file"
    line = refusal(lit_call("plan", "--world", str(tmp_path), cwd=tmp_path))
    assert line == f"lit call: error: --world {tmp_path}: a folder, not a file"
    (tmp_path / "bad.json").write_bytes(b"\xff\xfe")
    line = refusal(lit_call("plan", "--world", "bad.json", cwd=tmp_path))
    assert line.startswith("lit call: error: --world bad.json: not valid JSON: ")
    # A misspelt key was dropped without a word (the default resolution used instead).
    (tmp_path / "typo.json").write_text(
        '{"lower": [0, 0], "upper": [1, 1], "boxes": [], "start": [0.1, 0.1], '
        '"goal": [0.9, 0.9], "resolutoin": 0.5}'
    )
    line = refusal(lit_call("plan", "--world", "typo.json", cwd=tmp_path))
    assert "--world typo.json: unknown key 'resolutoin'; a world file has lower, upper" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.json", "typo.json"]


def test_an_unreadable_world_file_is_one_message(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """(Made unreadable by a stand-in: as root, chmod 000 does not stop a read.)"""

    def refuse(self: Path) -> bytes:
        raise PermissionError(13, "Permission denied", str(self))

    monkeypatch.setattr(Path, "read_bytes", refuse)
    world = tmp_path / "world.json"
    with pytest.raises(ValueError, match=r"^--world .*world\.json: not readable \(permission"):
        call._read_world(world)


def _options(parser: argparse.ArgumentParser) -> list[tuple[str, argparse.Action]]:
    """Every option of ``parser`` and of its subcommands that may be left out, with the command it
    belongs to (``plan``'s --scenario and --world: one of them is required, neither defaults)."""
    required = {
        id(a) for g in parser._mutually_exclusive_groups if g.required for a in g._group_actions
    }
    found = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                found += [(f"{name} {option}", a) for option, a in _options(sub)]
        elif (
            action.option_strings
            and not isinstance(action, argparse._HelpAction)
            and not action.required
            and id(action) not in required
        ):
            found.append((action.option_strings[0], action))
    return found


def test_every_option_of_lit_call_names_its_default() -> None:
    parser = argparse.ArgumentParser(prog="lit call")
    call.add_arguments(parser)
    options = _options(parser)
    assert any(name == "--wait" for name, _ in options)
    assert any(name == "decide --rho-global" for name, _ in options)
    assert not any(name == "plan --scenario" for name, _ in options)
    flags = (argparse._StoreTrueAction,)  # off unless given: nothing to name
    missing = [
        name
        for name, action in options
        if not isinstance(action, flags) and "default" not in (action.help or "")
    ]
    assert missing == []


def test_lit_call_help_shows_the_wait_default(tmp_path: Path) -> None:
    process = subprocess.run(
        [sys.executable, "-m", "lit_planner.cli", "call", "--help"],
        cwd=tmp_path, capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert process.returncode == 0, process.stderr
    text = " ".join(process.stdout.split())
    assert f"--wait WAIT seconds to wait for the service to appear (default: {15:g})" in text
    assert call.DEFAULT_WAIT == 15.0  # the README's "--wait (default 15 s)"


@pytest.mark.parametrize(
    ("given", "parsed"),
    [
        (["--start", "-0.3,0", "--goal", "0.3,0"], ["--start=-0.3,0", "--goal", "0.3,0"]),
        (["--goal", "-1e-3,-0.2"], ["--goal=-1e-3,-0.2"]),
        (["--time", "-1"], ["--time", "-1"]),  # a plain negative number: argparse's own
        (["--start=-0.3,0"], ["--start=-0.3,0"]),
        (["--", "-0.3,0"], ["--", "-0.3,0"]),
        (["--", "--x", "-1,2"], ["--", "--x", "-1,2"]),  # passed on untouched
    ],
)
def test_a_negative_first_coordinate_is_the_option_value(
    given: list[str], parsed: list[str]
) -> None:
    """argparse reads ``-0.3,0`` as an option and refused ``--start -0.3,0`` (every scenario's
    start has a negative first coordinate)."""
    from lit_planner import cli

    assert cli._join_negative_lists(["call", "plan", *given]) == ["call", "plan", *parsed]
    if given[0] == "--start":
        args = cli.build_parser("call")[0].parse_args(
            cli._join_negative_lists(["call", "plan", "--scenario", "np2", *given])
        )
        assert (args.start, args.goal) == ([-0.3, 0.0], [0.3, 0.0])


def test_plan_takes_the_litstar_shorthands_as_lit_plan_does(tmp_path: Path) -> None:
    """``--planner litstar-fit`` is LIT* with the fit policy (the planner node's schema knows
    only ``litstar``); a shorthand that contradicts ``--policy`` is refused before sending."""
    import json

    from lit_planner import cli

    args = cli.build_parser("call")[0].parse_args(
        ["call", "plan", "--scenario", "np4", "--planner", "litstar-fit"]
    )
    name, text = call._request(args)
    payload = json.loads(text)["payload"]
    assert name == "/lit/planner/plan"
    assert (payload["planner"], payload["policy"]) == ("litstar", "fit")
    line = refusal(
        lit_call("plan", "--scenario", "np4", "--planner", "litstar-fit", "--policy", "tensor",
                 cwd=tmp_path)
    )  # fmt: skip
    assert "means policy 'fit', but policy 'tensor' was given" in line
    # Any other name is checked the same way: the message lists the shorthands too (the schema's
    # enum error did not), and a plain name is sent as given, without a policy added.
    line = refusal(lit_call("plan", "--scenario", "np4", "--planner", "foo", cwd=tmp_path))
    assert "unknown planner 'foo'" in line and "litstar-fit" in line, line
    for planner in ("litstar", "aitstar"):
        args = cli.build_parser("call")[0].parse_args(
            ["call", "plan", "--scenario", "np4", "--planner", planner]
        )
        payload = json.loads(call._request(args)[1])["payload"]
        assert payload["planner"] == planner and "policy" not in payload
    # Combinations `lit plan` refuses are refused here too, before sending (exit 2; the node's
    # invalid-request Error made them exit 1, "refused by the planner", for a typing error).
    refused = [
        (["--planner", "aitstar", "--policy", "tensor"], "policy 'tensor' applies to litstar only"),
        (["--planner", "aitstar", "--iterations", "500"], "aitstar stops on time only"),
        (["--planner", "bitstar", "--batches", "5"], "bitstar stops on time only"),
        # Answered as "the seed used" while two plans of one seed differed (the node's OMPL
        # generator is seeded once per process).
        (["--planner", "rrtconnect", "--seed", "5"], "rrtconnect cannot take a seed in the"),
        (["--start", "-0.2,0,0"], "--start has 3 coordinates; np4 has 4 dimensions"),
        (["--goal", "0.2,0,0,0,0"], "--goal has 5 coordinates; np4 has 4 dimensions"),
    ]
    for options, message in refused:
        line = refusal(lit_call("plan", "--scenario", "np4", *options, cwd=tmp_path))
        assert message in line, (options, line)


def test_a_bad_namespace_or_non_utf8_raw_text_is_one_line(tmp_path: Path) -> None:
    """Both ended in a Python traceback (rclpy's InvalidServiceNameException, UnicodeEncodeError)."""
    line = refusal(lit_call("plan", "--scenario", "np8", "--namespace", "bad ns!", cwd=tmp_path))
    assert "service name" in line and "bad ns!" in line
    process = subprocess.run(
        [sys.executable, "-m", "lit_planner.cli", "call", "raw", "/lit/planner/plan", "-"],
        input=b'{"schema": "\xff\xfe"}', cwd=tmp_path, capture_output=True, timeout=120,
        env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST"), check=False,
    )  # fmt: skip
    assert process.returncode == 2, process.stderr
    assert process.stderr.decode().strip() == (
        "lit call: error: the request is not valid UTF-8 (a ROS string carries UTF-8 text)"
    )


def test_raw_given_a_file_name_says_how_to_send_the_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``lit call raw NAME req.json`` sent the text ``req.json``, which the node called "not
    valid JSON"; the client now says how to send the file."""
    from lit_planner import cli

    (tmp_path / "req.json").write_text("{}", encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    args = cli.build_parser("call")[0].parse_args(["call", "raw", "/lit/planner/plan", "req.json"])
    with pytest.raises(ValueError) as refused:
        call._request(args)
    assert str(refused.value) == (
        "req.json is a file, and TEXT is sent as it is; send the file's contents with "
        "`lit call raw /lit/planner/plan - < req.json`"
    )


@pytest.mark.parametrize("command", ["plan", "cancel"])
def test_an_argument_that_is_not_utf8_is_one_line(tmp_path: Path, command: str) -> None:
    """rclpy.init() read sys.argv and failed on it with a UnicodeEncodeError traceback, exit 1
    (which says "answered with an Error")."""
    process = subprocess.run(
        [sys.executable.encode(), b"-m", b"lit_planner.cli", b"call", command.encode(),
         *([b"--scenario", b"np4"] if command == "plan" else []), b"--request-id", b"caf\xe9"],
        cwd=tmp_path, capture_output=True, timeout=120,
        env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST"), check=False,
    )  # fmt: skip
    assert process.returncode == 2, process.stderr
    assert process.stderr.decode().strip() == (
        "lit call: error: --request-id: not valid UTF-8 text: 'caf\\udce9'"
    )


def test_a_plan_answer_whose_path_failed_the_recheck_is_flagged() -> None:
    def answer(valid: object) -> str:
        return json.dumps(
            {"schema": "lit_msgs_json/PlanResponse", "payload": {"path_valid": valid}}
        )

    assert call._path_failed_recheck(answer(False))
    assert not call._path_failed_recheck(answer(True))
    assert not call._path_failed_recheck(answer(None))  # not checked (no path)
    assert not call._path_failed_recheck("not JSON")


def _teardown(hang: str) -> subprocess.CompletedProcess[str]:
    """A process that arms ``lit call``'s teardown watchdog (grace 0.5 s, code 3) and then runs
    ``hang`` as its teardown."""
    script = (
        "import re, threading, time\n"
        "from lit_planner import call\n"
        "call.TEARDOWN_GRACE = 0.5\n"
        "print('answer', flush=True)\n"
        "disarm = call._exit_if_stuck(3)\n"
        f"{hang}\n"
    )
    return subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120, check=False
    )


def test_a_teardown_that_hangs_ends_with_the_answers_exit_code_and_says_where() -> None:
    """Once the call is over, a hanging ROS teardown (once in CI) no longer keeps ``lit call``
    alive: the process exits with the answer's code and prints where each thread was."""
    process = _teardown("threading.Event().wait()  # a teardown that never ends")
    assert process.returncode == 3, process
    assert process.stdout == "answer\n"
    assert "the ROS teardown did not end within 0.5 s; exiting with 3" in process.stderr
    assert 'File "<string>", line 6' in process.stderr, process.stderr  # the hanging wait


def test_a_teardown_that_hangs_holding_the_gil_still_ends() -> None:
    """rclpy's teardown calls into DDS with the GIL held: the timer thread cannot run then, and
    faulthandler's C thread ends the process (exit 1) with the stacks."""
    # Catastrophic backtracking: one C call that holds the GIL for hours.
    process = _teardown("re.match(r'(a+)+$', 'a' * 64 + 'b')")
    assert process.returncode == 1, process
    assert process.stdout == "answer\n"
    assert "Timeout (0:00:01)!" in process.stderr, process.stderr
    assert 'File "<string>", line 6' in process.stderr, process.stderr


def test_a_teardown_that_ends_disarms_the_watchdog() -> None:
    """Disarmed, it leaves a process that goes on alone (an in-process caller of ``run``)."""
    process = _teardown("disarm(); time.sleep(1.5); print('still here', flush=True)")
    assert process.returncode == 0, process
    assert process.stdout == "answer\nstill here\n"
    assert process.stderr == ""

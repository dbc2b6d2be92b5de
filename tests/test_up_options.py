"""``lit up`` refuses bad options with one line and exit 2 before it starts any process."""

from __future__ import annotations

import contextlib
import json
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from lit_planner.testing import DescendantWatch, handles_signal, read_until, run_watched
from ros_helpers import ROOT, launcher_domain


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--scenario", "foo", "--policy", "tensor"], "--scenario foo: "),
        (["--scenario", "np8/3"], "--scenario np8/3: "),  # training: family and dimension only
        (["--scenario", "zz8"], "--scenario zz8: "),
        (["--time-budget", "-1"], "--time-budget must be 0"),
        (["--time-budget", "nan"], "--time-budget must be 0"),
        # Beyond 3600 s every training decision failed its schema; beyond 1e9 every query.
        (["--time-budget", "3601"], "up to 3600 with --policy training, got 3601.0"),
        (["--policy", "tensor", "--time-budget", "86401"], "up to 86400 with --policy tensor"),
        (["--planner-param", "time_budget:=1e12"], "time_budget must be 0 (the scenario's) or at"),
        # Below a microsecond the learner refuses every decision (5e-324 had failed its reward).
        (["--time-budget", "1e-9"], "or at least 1e-06 s with policy training"),
        (["--episodes", "-1"], "--episodes must be 0"),
        (["--run-id", "../escape"], "--run-id '../escape': a folder name"),
        (["--run-id", "42"], "starts with a letter"),  # ROS would read -p run_id:=42 as a number
        (["--run-id", "yes"], "not a YAML word"),
        (["--run-id", ""], "--run-id '': a folder name"),  # was replaced by the default id
        (["--planner-param", "bogus"], "expected NAME:=VALUE, got 'bogus'"),
        (["--planner-param", "foo:=1"], "--planner-param: unknown parameter foo; known: scenario"),
        (["--learner-param", "checkpoint_evry:=5"], "unknown parameter checkpoint_evry"),
        # Each type as the node declares it (a wrong one was a node's traceback after the start).
        (["--planner-param", "queue_limit:=abc"], "queue_limit:=abc: queue_limit takes a whole"),
        (["--planner-param", "decision_timeout:=soon"], "decision_timeout takes a finite number"),
        (["--learner-param", "fresh:=maybe"], "fresh:=maybe: fresh takes true or false"),
        (["--planner-param", "queue_limit:=010"], "takes a whole number (no leading zeros)"),
        (["--planner-param", "scenario:="], "scenario takes text that is not empty"),
        # Values as the node checks them (these started every process, then the node exited).
        (["--planner-param", "policy:=foo"], "--planner-param: policy must be one of"),
        (["--planner-param", "decision_timeout:=0"], "decision_timeout must be a finite positive"),
        (["--planner-param", "learner_resend:=-0.01"], "learner_resend must be 0 or more sec"),
        (["--planner-param", "learner_resend:=1e-9"], "learner_resend must be 0 (never send"),
        (["--planner-param", "training_scenarios:=zz4"], "training_scenarios 'zz4': "),
        (["--learner-param", "train:=everything"], "--learner-param: train must be both"),
        (["--learner-param", "stats_period:=-1"], "stats_period must be a finite positive"),
        (["--learner-param", "wait_for_subscribers:=-1"], "wait_for_subscribers must be 0 or"),
        (["--learner-param", "episode_timeout:=-1.0"], "episode_timeout must be 0 (never) or"),
        # Names and run ids the node could not use (they crashed it with a traceback).
        (["--planner-param", "learner_service:=bad-name"], "is not a ROS service name"),
        (["--learner-param", "service:=/lit/x~y"], "is not a ROS service name"),
        (["--learner-param", "service:=bad//name"], "must not contain repeated '/'"),
        (["--planner-param", "learner_service:=/lit//x"], "must not contain repeated '/'"),
        (["--planner-param", "run_id:=" + "r" * 200], "run_id 'rrrr"),
        (["--learner-param", "run_id:=" + "r" * 200], ": it is too long (200 characters; at most"),
        # The planner's episode ids "<run_id>/<index>" (128 characters at most): every message
        # of episodes 10 and later was refused (the episodes failed, and the node exited 0).
        (["--episodes", "11", "--run-id", "r" + "1" * 125], "run_id of 126 characters: with 11"),
        # Stored as 1 by the core, then every LIT* query was refused as the client's fault.
        (["--planner-param", "decision_interval:=4294967296"], "up to 4294967295, got 429"),
        (["--checkpoint", "EXISTING"], "a folder; give the checkpoint file"),
        # A learner export replaces and removes the tensor files there (the shipped ones too).
        (
            ["--learner-param", "export_dir:=SHIPPED"],
            "holds b_tensor.npy, k_tensor.npy, not a learner node's export",
        ),
        (["--bag", "EXISTING"], "exists already"),
        # The recorder and the learner failed after everything had started (the learner only at
        # its shutdown, losing the run's checkpoint).
        (["--bag", "/proc/x/bag"], "bag /proc/x/bag: cannot write in /proc"),
        (["--checkpoint", "/proc/x/y.pt"], "--checkpoint /proc/x: cannot write in /proc"),
        (["--bag", "NEW", "--no-record"], "--bag and --no-record contradict each other"),
        (["--domain-id", "233"], "233 is not a ROS domain id Fast DDS can use (0-232)"),
        (["--domain-id", "x"], "--domain-id: not a whole number: 'x'"),
    ],
)
def test_bad_options_start_nothing(tmp_path: Path, options: list[str], message: str) -> None:
    (tmp_path / "bag").mkdir()
    named = {"EXISTING": tmp_path / "bag", "NEW": tmp_path / "new-bag", "SHIPPED": ROOT / "tensors"}
    options = [
        str(named[o]) if o in named else o.replace("SHIPPED", str(named["SHIPPED"]))
        for o in options
    ]
    process = run_watched(
        # A free domain: should a regression start lit up, it starts on a domain of its own.
        [sys.executable, "-m", "lit_planner.cli", "up", "--domain-id", str(launcher_domain()),
         *options],
        cwd=tmp_path,
        env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST"),
        timeout=120,
    )  # fmt: skip
    assert process.returncode == 2, process.stdout + process.stderr
    assert not process.started, process.started  # nothing started, not even for a moment
    assert message in process.stderr and "Traceback" not in process.stderr
    assert "lit up: run" not in process.stdout  # nothing started
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"]  # no runs/ folder either


@pytest.mark.parametrize(
    ("command", "message"),
    [
        (["demo", "--time", "-1"], "lit demo: --time must be a finite positive number"),
        (["demo", "--local", "--time", "0"], "lit demo: --time must be a finite positive number"),
        (["demo", "--plans", "0"], "lit demo: --plans must be 1 or more"),
        # It trained, then the planner node refused the plan's seed: a traceback, exit 1.
        (["demo", "--seed", "4294967295", "--plans", "2"], "plans seeds up to 4294967296"),
        (["demo", "--training-budget", "0"], "--training-budget must be a finite positive number"),
        (
            ["demo", "--training-budget", "inf"],
            "--training-budget must be a finite positive number",
        ),
        (["demo", "--domain-id", "300"], "300 is not a ROS domain id Fast DDS can use"),
        (["demo", "--local", "--plans", "5"], "without ROS: --plans applies to the ROS demo only"),
        (["demo", "--out", "/proc/nope"], "--out /proc/nope: cannot write in /proc"),
        (["crosscheck", "--json", "/proc/x.json"], "--json /proc/x.json: cannot write in /proc"),
        (["train", "--episodes", "1", "--export", "/proc/x"], "--export /proc/x: cannot write"),
        (["system-bench", "--domain-id", "-1"], "-1 is not a ROS domain id Fast DDS can use"),
        (["call", "--timeout", "-1", "decide"], "--timeout must be a finite positive number"),
        (["call", "--wait", "nan", "decide"], "--wait must be a finite positive number"),
        (["call", "decide", "--repeat", "0"], "--repeat must be 1 or more"),
        (["call", "plan", "--world", "/dev/null"], "/dev/null: not valid JSON"),
        # These hung until a timeout, or failed with a traceback after the first part's 20 s.
        (["system-bench", "--budget", "-1"], "--budget must be a finite positive number"),
        (["system-bench", "--budget", "0"], "--budget must be a finite positive number"),
        (["system-bench", "--budget", "5000"], "--budget must be 1e-06 to 3600 s"),
        (["system-bench", "--seed", "-1"], "--seed must be between 0"),
        (
            ["system-bench", "--scenarios", "foo", "--calls", "0", "--kills", "0"],
            "--scenarios foo:",
        ),
    ],
)
def test_demo_and_call_refuse_bad_options_before_starting(
    tmp_path: Path, command: list[str], message: str
) -> None:
    process = run_watched(
        [sys.executable, "-m", "lit_planner.cli", *command],
        cwd=tmp_path,
        env=dict(
            os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ROS_DOMAIN_ID=str(launcher_domain())
        ),
        timeout=120,
    )  # fmt: skip
    assert process.returncode == 2, process.stdout + process.stderr
    assert not process.started, process.started  # nothing started, not even for a moment
    assert message in process.stderr and "Traceback" not in process.stderr
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize(
    "command",
    [
        ["demo"],
        ["up", "--no-record"],
        ["system-bench", "--calls", "1", "--episodes", "0"],
        ["call", "--wait", "1", "export"],  # an rclpy traceback, or Fast DDS's errors, exit 1
    ],
)
def test_a_bad_ros_domain_id_in_the_environment_is_named(
    tmp_path: Path, command: list[str]
) -> None:
    """``$ROS_DOMAIN_ID`` is the default of ``--domain-id``: a value Fast DDS cannot use stops
    the launcher with one line (it used to be a traceback from building the options, or Fast DDS
    errors from every process)."""
    for value, message in (("abc", "not a whole number: 'abc'"), ("500", "500 is not a ROS")):
        process = run_watched(
            [sys.executable, "-m", "lit_planner.cli", *command],
            cwd=tmp_path,
            env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ROS_DOMAIN_ID=value),
            timeout=120,
        )  # fmt: skip
        assert process.returncode == 2, process.stdout + process.stderr
        assert not process.started, process.started  # nothing started, not even for a moment
        assert f"$ROS_DOMAIN_ID: {message}" in process.stderr
        assert "Traceback" not in process.stderr
        assert not list(tmp_path.iterdir())


def test_sigterm_stops_lit_call_without_a_traceback() -> None:
    """rclpy's own SIGTERM handler shuts the context down under the client's wait."""
    import signal
    import time

    from ros_helpers import reserve_domain

    domain, lock = reserve_domain()
    process = subprocess.Popen(
        [sys.executable, "-m", "lit_planner.cli", "call", "--wait", "60", "decide"],
        env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ROS_DOMAIN_ID=str(domain)),
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        # Waiting for a service nobody serves on this domain once rclpy's handler is in.
        deadline = time.monotonic() + 60.0
        while not handles_signal(process.pid, signal.SIGTERM):
            assert process.poll() is None and time.monotonic() < deadline, process.communicate()
            time.sleep(0.05)
        time.sleep(0.5)
        process.send_signal(signal.SIGTERM)
        _, err = process.communicate(timeout=60)
        assert process.returncode == 130, err
        assert "lit call: interrupted" in err and "Traceback" not in err
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
        if lock is not None:
            lock.close()


def test_parameters_are_passed_with_the_types_the_nodes_declare() -> None:
    """ROS refuses an integer for a float parameter (time_budget:=1 stopped the planner node)."""
    from lit_learner import node as learner_node
    from lit_planner import node as planner_node
    from lit_planner import up

    given = ["decision_timeout:=1e3", "queue_limit:=+8", "tensors_dir:=1e3", "scenario:='np4'",
             "run_id:=it's", "use_sim_time:=true", "explore:=Yes"]  # fmt: skip
    assert up._typed_params(given, planner_node.PARAMETERS) == {
        "decision_timeout": "1000.0", "queue_limit": "8",
        "tensors_dir": "'1e3'",  # rcl would read 1e3 as a number: quoted, it is text
        "scenario": "'np4'", "run_id": "'it''s'", "use_sim_time": "true", "explore": "true",
    }  # fmt: skip
    assert up._typed_params(["fresh:=True"], learner_node.PARAMETERS) == {"fresh": "true"}
    assert up._typed_params(["tensors_dir:="], planner_node.PARAMETERS) == {}  # its default


def test_text_that_lit_up_sets_reaches_the_node_as_that_text() -> None:
    """lit up's own text values (--scenario, paths, run ids) are quoted for rcl, which reads
    ``-p`` values as YAML-like scalars: ``--scenario ,np4`` passed lit up's checks, and the
    planner then failed at start ("Couldn't parse parameter override rule"). rcl's own parser
    reads them here, in a child process."""
    from lit_planner import up

    texts = [",np4", "np4,", "yes", "1e3", "a #b", "it's", '"q"', "[x]", "{y: 1}", "/tmp/a b/c.pt",
             "line\nbreak", "tab\there", "back\\slash", "日本", "-x", "*y"]  # fmt: skip
    child = (
        "import json, sys, rclpy\n"
        "from rclpy.node import Node\n"
        "rclpy.init(args=sys.argv)\n"
        "node = Node('reader')\n"
        f"names = ['p' + str(i) for i in range({len(texts)})]\n"
        "print(json.dumps([node.declare_parameter(n, '').value for n in names]))\n"
    )
    overrides = [a for i, t in enumerate(texts) for a in ("-p", f"p{i}:={up._ros_value(t)}")]
    process = subprocess.run(
        [sys.executable, "-c", child, "--ros-args", *overrides],
        capture_output=True, text=True, timeout=60, check=False,
        env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
                 ROS_DOMAIN_ID=str(launcher_domain())),
    )  # fmt: skip
    assert process.returncode == 0, process.stderr
    assert json.loads(process.stdout) == texts
    # What lit up passes on from --planner-param / --learner-param is spelled already.
    assert up._ros_value(up._typed_params(["scenario:=np4"], {"scenario": "x"})["scenario"]) == (
        "'np4'"
    )
    assert up._ros_value(Path("/tmp/a b")) == '"/tmp/a b"'


def test_service_names_are_checked_as_rcl_expands_them() -> None:
    """A repeated '/' shows only in the expanded name (rcl refused it when the node made its
    service: a traceback at start); substitutions that expand well pass (``{ns}/x`` in a
    namespace of its own)."""
    from lit_planner.rosutil import service_name_problem

    for good in ("/lit/learner/decide", "decide", "~/decide", "{ns}/decide", "{node}/decide"):
        assert service_name_problem("service", good) is None, good
    for bad, reason in (("/lit//x", "must not contain repeated '/'"),
                        ("{nope}/x", "unknown substitution"), ("x~y", "tilde")):  # fmt: skip
        problem = service_name_problem("service", bad)
        assert problem is not None and reason in problem, (bad, problem)
        assert "/project/src" not in problem, problem  # rcl's source location is not for users


@pytest.mark.parametrize(
    ("program", "parameter", "default"),
    [("lit_planner_node", "time_budget", "0.0"), ("lit_learner_node", "stats_period", "1.0")],
)
def test_a_node_started_by_hand_names_a_parameter_of_the_wrong_type(
    tmp_path: Path, program: str, parameter: str, default: str
) -> None:
    """`ros2 run` users write -p time_budget:=1: rclpy's InvalidParameterTypeException traceback."""
    process = subprocess.run(
        [str(Path(sys.executable).parent / program), "--ros-args", "-p", f"{parameter}:=1"],
        cwd=tmp_path, capture_output=True, text=True, timeout=120, check=False,
        env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
                 ROS_DOMAIN_ID=str(launcher_domain())),
    )  # fmt: skip
    assert process.returncode == 1, process.stdout + process.stderr
    assert "Traceback" not in process.stderr, process.stderr
    assert (
        f"{program}: parameter {parameter} takes a number with a decimal point, as its default "
        f"{default} does" in process.stderr
    ), process.stderr


def test_lit_up_keeps_only_the_last_output_lines(tmp_path: Path) -> None:
    """lit up echoes every line of its children and keeps the last KEEP_LINES for its error
    messages (it kept them all: a run of days grew without bound)."""
    from lit_planner import up

    system = up.System(0, tmp_path, echo=None, keep_lines=5)
    script = "for i in range(23):\n    print(i)"
    child = system.start("counter", [sys.executable, "-c", script])
    assert child.process.wait(timeout=60) == 0
    child.drain()
    assert 5 <= len(child.lines) <= 10
    assert child.lines[-5:] == [str(i) for i in range(18, 23)]
    assert up.System(0, tmp_path, echo=None).keep_lines is None  # bounded runs keep all


def test_a_closed_stdout_stops_the_echo_not_the_draining(tmp_path: Path) -> None:
    """``lit up | head -1``: the echo raised BrokenPipeError in each output thread, which ended,
    and the children's pipes were no longer read (a full pipe blocks a node's logging)."""
    from lit_planner import up

    def closed(line: str) -> None:
        raise BrokenPipeError(32, "Broken pipe")

    system = up.System(0, tmp_path, echo=closed)
    script = "for i in range(20000):\n    print(i)"  # far more than a 64 KiB pipe holds
    child = system.start("counter", [sys.executable, "-c", script])
    assert child.process.wait(timeout=60) == 0  # it would block on a full pipe
    child.drain()
    assert child.lines[-1] == "19999" and system.echo is None


_INTERRUPTS_ITS_PARENT = """
import os, signal, time
def stop(*_):
    os.kill(os.getppid(), signal.SIGINT)  # as a user's Ctrl-C while the nodes stop
    os._exit(0)
signal.signal(signal.SIGTERM, stop)
print("ready", flush=True)
time.sleep(60)
"""


def test_an_interrupt_while_the_nodes_stop_is_counted(tmp_path: Path) -> None:
    """lit demo exited 0 after a Ctrl-C during its final stop (its work was done): the stop
    counts the interrupts, and the demo exits 130 for them."""
    from lit_planner import up

    system = up.System(0, tmp_path, echo=None)
    child = system.start("planner", [sys.executable, "-c", _INTERRUPTS_ITS_PARENT])
    deadline = time.monotonic() + 60.0
    while "ready" not in child.lines and child.process.poll() is None:
        assert time.monotonic() < deadline, child.lines
        time.sleep(0.05)
    assert "ready" in child.lines, child.lines
    assert system.stop() == {"planner": 0}
    assert system.stop_interrupts == 1


@contextlib.contextmanager
def _server(code: str) -> Iterator[dict[str, str]]:
    """Run ``code`` (a Python program that prints "ready" once its service is up) in a domain of
    its own; yields the environment for clients of that domain, stops the server afterwards."""
    from ros_helpers import reserve_domain

    domain, lock = reserve_domain()
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ROS_DOMAIN_ID=str(domain))
    server = subprocess.Popen(
        [sys.executable, "-c", code], env=env, stdout=subprocess.PIPE, text=True
    )
    try:
        assert server.stdout is not None
        assert read_until(server.stdout, "ready") == ["ready\n"]
        time.sleep(1.0)  # discovery
        yield env
    finally:
        server.terminate()
        try:
            server.wait(timeout=10)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait()
        if lock is not None:
            lock.close()


def _lit_call(env: dict[str, str], *arguments: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "lit_planner.cli", "call", *arguments],
        env=env, capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip


def test_lit_call_names_a_service_of_another_type() -> None:
    """A service that exists with a type lit call does not speak was reported as not found."""
    server_code = (
        "import rclpy, sys\n"
        "from std_srvs.srv import Trigger\n"
        "rclpy.init()\n"
        "node = rclpy.create_node('trigger_server')\n"
        "node.create_service(Trigger, '/other/trigger', lambda request, response: response)\n"
        "print('ready', flush=True)\n"
        "rclpy.spin(node)\n"
    )
    with _server(server_code) as env:
        process = _lit_call(env, "--wait", "5", "raw", "other/trigger", "{}")
    assert process.returncode == 2, process.stderr
    assert "service other/trigger has type std_srvs/srv/Trigger" in process.stderr
    assert "not found" not in process.stderr and "Traceback" not in process.stderr


_LOSES_FIRST_ANSWERS = """
import rclpy
from diagnostic_msgs.srv import AddDiagnostics
rclpy.init()
node = rclpy.create_node('lossy_server')
answered = set()
def echo(request, response):
    response.success, response.message = True, request.load_namespace
    return response
service = node.create_service(AddDiagnostics, '/lossy/service', echo)
send = service.send_response
def lose_first(response, header):  # the first answer to each text is lost on the way
    if response.message in answered:
        send(response, header)
    answered.add(response.message)
service.send_response = lose_first
print('ready', flush=True)
rclpy.spin(node)
"""


@pytest.mark.parametrize(
    ("schema", "resent"),
    [
        ("DecideRequest", True),
        ("EpisodeEnd", True),
        ("CancelRequest", True),
        ("PlanRequest", True),
        ("PlanResponse", False),
    ],
)
def test_lit_call_sends_again_what_its_service_answers_as_a_copy(schema: str, resent: bool) -> None:
    """A decide request whose answer was lost waited out lit call's whole timeout (seen in CI: 60
    s). lit call sends again the requests whose services answer a copy as the request it
    repeats (the learner's, a cancel, and a plan request, which the planner node answers with
    the request's result; at most three copies of it, ``call._resends``); other text is sent
    once."""
    text = json.dumps({"schema": f"lit_msgs_json/{schema}", "version": 1, "payload": {}})
    with _server(_LOSES_FIRST_ANSWERS) as env:
        process = _lit_call(env, "--wait", "30", "--timeout", "5", "raw", "/lossy/service", text)
    if resent:
        assert process.returncode == 0, process.stderr
        assert json.loads(process.stdout) == json.loads(text)
    else:
        assert process.returncode == 2, process.stderr
        assert "did not answer within 5 s" in process.stderr


def test_a_plan_request_is_sent_again_at_most_three_times() -> None:
    from lit_planner.call import RESEND, _resends

    def text(schema: str) -> str:
        return json.dumps({"schema": f"lit_msgs_json/{schema}", "payload": {}})

    assert _resends(text("PlanRequest")) == (RESEND, 3)  # after 1, 3 and 7 s
    assert _resends(text("DecideRequest")) == (RESEND, None)  # until the deadline
    assert _resends(text("PlanResponse")) == (None, None)
    assert _resends("not JSON") == (None, None)


_STOPS_UNANSWERED = """
import threading
import rclpy
from {module} import {kind}
rclpy.init()
node = rclpy.create_node('stopping_server')
taken = threading.Event()
def take(request, response):  # a request taken just as the node stops: never answered
    taken.set()
    raise SystemExit
node.create_service({kind}, '{service}', take)
print('ready', flush=True)
try:
    rclpy.spin(node)
except SystemExit:
    pass
node.destroy_node()
print('stopped', flush=True)
"""


@pytest.mark.parametrize(
    ("service", "arguments"),
    [
        ("/lit/planner/plan", ("raw", "/lit/planner/plan", '{"schema": "x"}')),
        ("/lit/planner/plan", ("plan", "--scenario", "np4", "--time", "1")),
        ("/lit/learner/export", ("export",)),
    ],
    ids=["raw", "plan", "export"],
)
def test_lit_call_stops_waiting_when_the_service_goes_away(
    service: str, arguments: tuple[str, ...]
) -> None:
    """A request sent just as the planner node stopped (SIGTERM) was never answered, and lit call
    waited out its whole timeout. It now stops once the service has been gone for a second."""
    kind = ("std_srvs.srv", "Trigger") if arguments[0] == "export" else (
        "diagnostic_msgs.srv", "AddDiagnostics")  # fmt: skip
    code = _STOPS_UNANSWERED.format(module=kind[0], kind=kind[1], service=service)
    with _server(code) as env:
        process = _lit_call(env, "--wait", "30", "--timeout", "100", *arguments)
    assert process.returncode == 2, process.stderr
    assert f"{service} went away before it answered" in process.stderr
    assert "did not answer" not in process.stderr and "Traceback" not in process.stderr
    assert "cancel of plan request" not in process.stderr  # nobody left to ask


_TAKES_PLANS_SILENTLY = """
import os, pathlib, signal, time
import rclpy
from diagnostic_msgs.srv import AddDiagnostics
rclpy.init()
signal.signal(signal.SIGTERM, lambda *_: os._exit(0))  # its callback sleeps
node = rclpy.create_node('silent_planner')
def take(request, response):  # a plan that never ends; no cancel service
    pathlib.Path({marker!r}).touch()
    time.sleep(600)
node.create_service(AddDiagnostics, '/lit/planner/plan', take)
print('ready', flush=True)
rclpy.spin(node)
"""


def test_a_second_ctrl_c_stops_the_cancel_of_lit_call_plan(tmp_path: Path) -> None:
    """The first Ctrl-C stops the wait for the plan and sends its cancel; a second one stops
    that (here it waits for a cancel service nobody offers). lit call handles the signals itself:
    rclpy's handler shut every context down, so the cancel needed a new one, made after the
    signal."""
    import signal

    marker = tmp_path / "taken"
    with _server(_TAKES_PLANS_SILENTLY.format(marker=str(marker))) as env:
        process = subprocess.Popen(
            [sys.executable, "-m", "lit_planner.cli", "call", "--wait", "30", "plan",
             "--scenario", "np4", "--time", "300"],
            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        try:
            deadline = time.monotonic() + 60.0
            while not marker.exists():  # the plan request arrived
                assert process.poll() is None and time.monotonic() < deadline
                time.sleep(0.05)
            process.send_signal(signal.SIGINT)
            time.sleep(0.5)  # within the cancel's 5 s wait for its service
            process.send_signal(signal.SIGINT)
            _, stderr = process.communicate(timeout=60)
        finally:
            if process.poll() is None:
                process.kill()
                process.wait()
    assert process.returncode == 130, stderr
    assert "lit call: interrupted\n" in stderr, stderr
    assert "lit call: interrupted again; the plan request was not cancelled" in stderr, stderr
    assert "Traceback" not in stderr and "not found within" not in stderr, stderr


def test_sigterm_stops_system_bench_in_order(tmp_path: Path) -> None:
    """SIGTERM killed lit system-bench at once (exit 143), leaving its folder and, for a moment,
    its nodes; now it stops them as Ctrl-C does."""
    import signal
    import threading
    import time
    from typing import Any

    from ros_helpers import launcher_domain

    domain = launcher_domain()  # claimed by lit system-bench itself
    process = subprocess.Popen(
        [sys.executable, "-m", "lit_planner.cli", "system-bench", "--domain-id", str(domain),
         "--calls", "1000000", "--episodes", "0", "--kills", "0"],
        env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", TMPDIR=str(tmp_path)),
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    nodes = DescendantWatch(process.pid)
    try:
        assert process.stdout is not None
        begun = threading.Event()

        def watch(stream: Any) -> None:  # a thread: a silent stall must not block the test
            for line in stream:
                if line.startswith("## Decide round trip"):  # the nodes are up
                    begun.set()

        threading.Thread(target=watch, args=(process.stdout,), daemon=True).start()
        assert begun.wait(120), "the round trips did not begin"
        time.sleep(2.0)
        process.send_signal(signal.SIGTERM)
        process.wait(timeout=120)
        assert process.stderr is not None
        err = process.stderr.read()
        assert process.returncode == 130, err
        assert "lit system-bench: interrupted" in err and "Traceback" not in err
        assert not [p for p in tmp_path.iterdir() if p.name.startswith("lit-system-bench-")]
        assert nodes.seen and not nodes.alive()  # its nodes and client stopped with it
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
        nodes.kill()


def _serving_lit_up(cwd: Path) -> subprocess.Popen[str]:
    """``lit up`` with a planner that only serves (fixed policy, no recording), started in ``cwd``
    on a domain of its own; returned once the planner is ready (the caller stops it)."""
    process = subprocess.Popen(
        [sys.executable, "-m", "lit_planner.cli", "up", "--domain-id", str(launcher_domain()),
         "--no-record", "--policy", "fixed", "--episodes", "0"],
        cwd=cwd, env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST"),
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip
    try:
        assert process.stdout is not None
        while not read_until(process.stdout, "ready:", timeout=120.0)[-1].startswith("[planner]"):
            pass  # another node's ready line
    except BaseException:
        process.kill()
        process.wait()
        raise
    return process


def test_sighup_stops_lit_up_in_order(tmp_path: Path) -> None:
    """The terminal closing (SIGHUP) ended lit up at once: its nodes, orphaned, stopped all at one
    moment, and its domain lock was free while they still ran. It stops them as Ctrl-C does."""
    import signal

    process = _serving_lit_up(tmp_path)
    try:
        process.send_signal(signal.SIGHUP)
        out, _ = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert "lit up: stopped planner (exit 0)" in out, out
    assert "Traceback" not in out, out


def test_a_node_stopped_from_elsewhere_fails_lit_up(tmp_path: Path) -> None:
    """A node that exits while lit up runs, even cleanly (exit 0 on a SIGTERM that lit up did not
    send), leaves the system short of what was asked: lit up stops the others and exits 1 (it
    exited 0, as if all had gone well)."""
    import signal

    from lit_planner.testing import descendants

    process = _serving_lit_up(tmp_path)
    watch = DescendantWatch(process.pid)
    try:
        planners = [
            pid
            for pid in descendants(process.pid)
            if b"lit_planner_node" in Path(f"/proc/{pid}/cmdline").read_bytes()
        ]
        assert len(planners) == 1, planners
        os.kill(planners[0], signal.SIGTERM)  # the planner stops cleanly on it (exit 0)
        out, _ = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
        watch.kill()
    stopped = "lit up: planner (exit 0) exited before lit up was asked to stop; stopping the others"
    assert stopped in out, out
    assert "lit up: stopped planner (exit 0), learner (exit 0)" in out, out
    assert process.returncode == 1, out
    assert "Traceback" not in out, out


def test_a_planner_with_exit_when_done_ends_lit_up_cleanly(tmp_path: Path) -> None:
    """The planner's documented exit_when_done ends the run once its episodes are done: lit up
    stops the others and exits with the planner's verdict (0), not as if the node had died."""
    process = run_watched(
        [sys.executable, "-m", "lit_planner.cli", "up", "--domain-id", str(launcher_domain()),
         "--no-record", "--policy", "fixed", "--episodes", "2", "--scenario", "np4",
         "--time-budget", "0.05", "--planner-param", "exit_when_done:=true"],
        cwd=tmp_path, env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST"),
        timeout=300,
    )  # fmt: skip
    out = process.stdout + process.stderr
    assert "lit up: the planner exited (exit 0, exit_when_done); stopping the others" in out, out
    assert "lit up: stopped planner (exit 0), learner (exit 0)" in out, out
    assert process.returncode == 0, out

"""System tests of the ROS 2 nodes, each a set of real processes talking over DDS.

The planner node (``lit_planner_node``), the learner node (``lit_learner_node``), ``lit call`` and a
topic recorder (``tests/ros_helpers.py``) run as separate processes, in a ROS domain of their own
per test with discovery on loopback; every process is stopped by PID when the test ends, also when
it fails. Budgets are small and timeouts generous: no assertion depends on the machine's speed.
"""

from __future__ import annotations

import json
import math
import os
import re
import signal
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from lit_msgs_json.envelope import MAX_MESSAGE_BYTES, Publisher
from lit_planner.testing import longest_chord_inside_boxes
from ros_helpers import (
    RECORDER_NODE,
    ROOT,
    Child,
    Recording,
    RosSystem,
    children_of,
    finish_call,
    live_pids,
    ros_arguments,
    session_members,
)

from lit_planner import planning, scenarios, tensor_files

NODE_START = 120.0
"""Seconds a node may take to log ``ready:`` (the learner imports torch)."""
EPISODE = "/lit/episode"
STATS = "/lit/learner/stats"
PATH = "/lit/path"
TRAINING = {
    "policy": "training",
    "time_budget": 0.2,
    "training_scenarios": "np4,np8",
    # Generous: a loaded machine must not turn learner decisions into fallbacks here. 1 s was not
    # enough once on a 2-core CI runner with two planners, the learner and the recorder running
    # (test_two_planners_train_one_learner). A learner that is down still falls back: the tests of
    # fallbacks set their own, short deadlines.
    "decision_timeout": 10.0,
    "learner_wait": 300.0,
}
"""Planner parameters of a short training run."""


def _ready(*children: Child) -> None:
    for child in children:
        child.wait_for_log(r"ready:", timeout=NODE_START)


def _no_traceback(*children: Child) -> None:
    for child in children:
        assert "Traceback" not in child.text(), f"{child.name} raised:\n{child.tail(60)}"


def _checkpoint(ros: RosSystem) -> Path:
    return ros.workdir / "learner" / "checkpoint.pt"


def _learned(summary: dict[str, Any]) -> bool:
    """A training episode whose every decision came from the learner."""
    return summary["learner_calls"] > 0 and summary["fallback_decisions"] == 0


# ---------------------------------------------------------------------- 1. the plan service


def test_plan_service_round_trip(ros: RosSystem, tmp_path: Path) -> None:
    """A separate client plans on a registered scenario and on an explicit world, whose edges are
    checked exactly: a wall thinner than the world's check spacing is not passed (the planner went
    through it and answered path_valid false, lit call exit 3), a box's corner is not clipped."""
    recording = ros.recorder([EPISODE, PATH])
    planner = ros.planner()
    _ready(planner)

    # A 10 m room cut by a 2 mm wall: no solution, though the world's default resolution places
    # its checks 10 mm apart.
    sheet = {"lower": [0, 0], "upper": [10, 10], "boxes": [{"lower": [5, 0], "upper": [5.002, 10]}],
             "start": [1, 5], "goal": [9, 5]}  # fmt: skip
    sheet_file = tmp_path / "sheet.json"
    sheet_file.write_text(json.dumps(sheet), encoding="utf-8")
    result = ros.call("--payload-only", "plan", "--world", str(sheet_file), "--time", "0.2",
                      "--seed", "1", "--request-id", "sheet")  # fmt: skip
    assert result.returncode == 0, result
    response = result.json()
    assert response["solved"] is False and response["path"] == [], response
    assert response["checks_init"] is None and response["iteration_init"] is None

    world = {
        "lower": [0.0, 0.0],
        "upper": [1.0, 1.0],
        "boxes": [{"lower": [0.4, 0.1], "upper": [0.6, 0.9]}],
        "start": [0.1, 0.5],
        "goal": [0.9, 0.5],
    }
    world_file = tmp_path / "world.json"
    world_file.write_text(json.dumps(world), encoding="utf-8")
    result = ros.call("--payload-only", "plan", "--world", str(world_file), "--iterations",
                      "20000", "--request-id", "world")  # fmt: skip
    # At this world's resolution (10^-3 of its size, the default) a path clipped the wall's
    # corner between the planner's checks now and then (path_valid false, lit call exit 3).
    response = result.json()
    assert result.returncode == 0, result
    assert response["path_valid"] is True
    assert response["solved"] is True and response["dimension"] == 2
    assert response["path"][0] == pytest.approx(world["start"])
    assert response["path"][-1] == pytest.approx(world["goal"])
    explicit = scenarios.custom(
        world["lower"],
        world["upper"],
        [(box["lower"], box["upper"]) for box in world["boxes"]],
        world["start"],
        world["goal"],
    )
    assert scenarios.check_path(explicit, response["path"]).ok
    assert longest_chord_inside_boxes(explicit, response["path"]) == 0.0  # exact, corners too
    clipping = [world["start"], [0.39, 0.79], [0.41, 0.99], world["goal"]]  # the wall's corner
    assert longest_chord_inside_boxes(explicit, clipping) > 0.0
    assert response["cost"] > 0.8  # around the wall, never through it

    # No path within 0.1 ms: nothing on lit/path (an empty trajectory went out, which a
    # joint_trajectory_controller takes as "stop").
    result = ros.call("--payload-only", "plan", "--scenario", "np8", "--time", "0.0001",
                      "--request-id", "tiny")  # fmt: skip
    assert result.returncode == 0, result
    assert result.json()["solved"] is False and result.json()["path"] == [], result

    # An iteration limit alone: the node's answer is the one this process computes (the node's
    # defaults: the shipped tensors, seed 1), whatever the machine's speed.
    result = ros.call("--payload-only", "plan", "--scenario", "np4", "--iterations", "2000",
                      "--request-id", "np4")  # fmt: skip
    assert result.returncode == 0, result
    response = result.json()
    scenario = scenarios.get("np4")
    assert response["solved"] is True and response["path_valid"] is True
    assert response["scenario"] == "np4" and response["dimension"] == scenario.dim
    assert response["path"][0] == pytest.approx(list(scenario.start))
    assert response["path"][-1] == pytest.approx(list(scenario.goal))
    assert response["cost"] > 0
    assert response["cost"] >= math.dist(scenario.start, scenario.goal) - 1e-9
    # Registry scenarios are checked at their resolution: a corner may be clipped by less.
    clip = scenario.resolution * scenario.max_extent
    assert longest_chord_inside_boxes(scenario, response["path"]) <= clip
    alone = planning.plan("np4", policy="tensor", max_iterations=2000, seed=1, check_path=False)
    assert 0 < alone["iteration_init"] < 2000 and alone["checks_init"] > 0
    for key in ("checks_init", "iteration_init", "c_init", "counters"):
        assert response[key] == alone[key], key
    assert response["cost"] == alone["cost"] and response["path"] == alone["path"]
    assert response["counters"]["iterations"] == 2000

    # The trajectories come in the order the node published them: the last one's arrival means
    # the others' would have come already.
    recording.wait_until(
        PATH, lambda found: any(p["frame_id"] == "np4" for p in found), timeout=60.0,
        what="the np4 query's trajectory", watch=[planner],
    )  # fmt: skip
    published = [p["frame_id"] for p in recording.payloads(PATH)]
    assert published == ["world", "np4"]
    summaries = {p["episode_id"]: p for p in recording.payloads(EPISODE)}
    assert summaries["sheet"]["solved"] is False and summaries["np4"]["path_valid"] is True
    assert planner.running()
    _no_traceback(planner)


def test_the_planner_node_uses_its_tensors_as_trained_and_sees_them_change(
    ros: RosSystem, tmp_path: Path
) -> None:
    """With the tensor policy the node decides psi_K at the interval its tensor was trained with
    (the shipped tensors: every 10 expansions) and keeps the tensors between queries, but reads
    them again once they change: a defective export is answered with an Error naming the file,
    the node keeps serving, and it plans again once the file is repaired."""
    import shutil

    folder = tmp_path / "tensors"
    folder.mkdir()
    shipped = Path(__file__).resolve().parents[1] / "tensors"
    for name in ("b_tensor.npy", "b_tensor.json", "k_tensor.npy", "k_tensor.json"):
        shutil.copy2(shipped / name, folder / name)
    planner = ros.planner(tensors_dir=str(folder))
    _ready(planner)

    def plan() -> Any:
        return ros.call("--payload-only", "plan", "--scenario", "np4", "--iterations", "5000")

    for _ in range(2):
        result = plan()
        assert result.returncode == 0, result
        counters = result.json()["counters"]
        assert counters["expansions"] > 10
        assert counters["neighbour_decisions"] == -(-counters["expansions"] // 10)

    values = np.load(folder / "k_tensor.npy")
    broken = values.copy()
    broken[5, 5, 5] = np.nan
    np.save(folder / "k_tensor.npy", broken)  # rewritten in place, as an export writes
    result = plan()
    assert result.returncode == 1, result
    error = result.json()
    assert "k_tensor.npy" in error["message"] and "not finite" in error["message"], error
    assert error["code"] == "unavailable", error  # the file's fault: not "internal"
    # The same text sent again once the files are repaired is planned: the copy of an answer
    # kept for resent requests ("unavailable": try again later) answered it before, for good.
    resent = json.dumps(
        {"schema": "lit_msgs_json/PlanRequest", "version": 1, "seq": 0, "stamp_ns": 1,
         "source": "resender", "run_id": "r1",
         "payload": {"scenario": "np4", "max_iterations": 5000, "request_id": "again"}}
    ).encode()  # fmt: skip
    result = ros.call("--payload-only", "raw", "/lit/planner/plan", "-", stdin=resent)
    assert result.returncode == 1 and result.json()["code"] == "unavailable", result
    # Cut short (a copy that stopped half-way), then whole again but not the data its sidecar's
    # SHA-256 names: each answered with an Error naming the file and the defect.
    whole = (folder / "k_tensor.npy").read_bytes()
    (folder / "k_tensor.npy").write_bytes(whole[: len(whole) // 2])
    result = plan()
    assert result.returncode == 1 and result.json()["code"] == "unavailable", result
    assert "k_tensor.npy" in result.json()["message"], result
    assert "data holds 2060538 bytes, expected 4121204" in result.json()["message"], result
    changed = values.copy()
    changed[5, 5, 5] = 7.0  # finite, in range: only the hash can tell
    np.save(folder / "k_tensor.npy", changed)
    result = plan()
    assert result.returncode == 1 and result.json()["code"] == "unavailable", result
    assert "k_tensor.npy" in result.json()["message"], result
    assert "SHA-256" in result.json()["message"], result
    np.save(folder / "k_tensor.npy", values)
    result = plan()
    assert result.returncode == 0 and result.json()["solved"] is True, result
    result = ros.call("--payload-only", "raw", "/lit/planner/plan", "-", stdin=resent)
    assert result.returncode == 0 and result.json()["solved"] is True, result
    assert result.json()["request_id"] == "again", result
    assert planner.running()
    _no_traceback(planner)


def _long_request_running(
    ros: RosSystem, recording: Recording, planner: Child, budget: str
) -> Child:
    """``lit call plan`` of np4 for ``budget`` s (request_id ``long``) to ``planner`` once it is
    ready, returned once the request runs: its first solution was published."""
    _ready(planner)
    recording.wait_for_publishers("/lit/solution")
    long = ros.call_start(
        "--payload-only", "plan", "--scenario", "np4", "--time", budget, "--request-id", "long"
    )
    _wait_for_a_solution(recording, planner, "long")
    return long


def _wait_for_a_solution(recording: Recording, planner: Child, request_id: str) -> None:
    """Until ``recording`` holds a SolutionUpdate of the plan request ``request_id``."""
    recording.wait_until(
        "/lit/solution",
        lambda updates: any(update["episode_id"] == request_id for update in updates),
        timeout=60.0,
        what=f"a solution of the request {request_id}",
        watch=[planner],
    )


def test_plan_requests_wait_in_the_queue_then_busy(ros: RosSystem) -> None:
    """A request arriving during a long one waits its turn; one beyond ``queue_limit`` is refused.

    With ``queue_limit: 1`` one request runs and one waits; of two short requests sent while a long
    one runs, one is answered after the long one and the other gets ``busy`` at once. (The long
    one runs until it is cancelled, once both are in: a fixed 6 s let a slow machine answer both.)
    """
    recording = ros.recorder(["/lit/solution"])
    planner = ros.planner(queue_limit=1)
    long = _long_request_running(ros, recording, planner, "300")
    shorts = [
        ros.call_start(
            "--payload-only", "plan", "--scenario", "np4", "--time", "0.2", "--request-id", name
        )
        for name in ("short-a", "short-b")
    ]
    planner.wait_for_log(r"plan request short-[ab] waits behind 1", timeout=60.0)
    deadline = time.monotonic() + 60.0
    while all(call.running() for call in shorts):  # the other one's busy answer
        assert time.monotonic() < deadline, [call.tail() for call in shorts]
        time.sleep(0.05)
    cancel = ros.call("--payload-only", "cancel", "--request-id", "long")
    assert cancel.returncode == 0 and cancel.json()["running"] == 1, cancel
    results = [finish_call(call) for call in (long, *shorts)]

    assert results[0].returncode == 0, results[0]
    assert results[0].json()["solved"] is True and results[0].json()["status"] == "cancelled"
    assert results[0].json()["request_id"] == "long"
    codes = sorted(result.returncode for result in results[1:])
    assert codes == [0, 1], "\n\n".join(map(str, results))
    answered = next(result for result in results[1:] if result.returncode == 0).json()
    refused = next(result for result in results[1:] if result.returncode == 1).json()
    assert answered["solved"] is True and answered["request_id"] in ("short-a", "short-b")
    assert refused["code"] == "busy", refused
    assert refused["request_schema"] == "PlanRequest"
    assert "queue_limit 1" in refused["message"]
    assert planner.running()
    _no_traceback(planner)


def test_cancel_ends_the_running_query_and_drops_a_queued_one(ros: RosSystem) -> None:
    """``lit call cancel``: a queued plan request is answered without being started and the
    running one stops with what it found; each answers its own caller (status ``cancelled``),
    and the node keeps serving. A cancel naming no request, or a malformed one, changes nothing."""
    recording = ros.recorder(["/lit/solution", EPISODE])
    planner = ros.planner()
    long = _long_request_running(ros, recording, planner, "300")
    queued = ros.call_start(
        "--payload-only", "plan", "--scenario", "np8", "--time", "300", "--request-id", "queued"
    )
    planner.wait_for_log(r"plan request queued waits behind 1", timeout=60.0)

    def cancel(request_id: str) -> dict[str, Any]:
        answer = ros.call("--payload-only", "cancel", "--request-id", request_id)
        assert answer.returncode == 0, answer
        return dict(answer.json())

    answer = cancel("queued")
    assert (answer["running"], answer["queued"]) == (0, 1), answer
    # Answered at once, while the long request still runs: its place in the queue is free.
    dropped = finish_call(queued)
    assert long.running(), finish_call(long)
    assert dropped.returncode == 0, dropped
    payload = dropped.json()
    assert payload["status"] == "cancelled" and payload["solved"] is False, payload
    assert payload["time"] == 0.0 and payload["path"] == [] and payload["request_id"] == "queued"
    # A cancel that came before its plan request (a client that gave up just after sending).
    nobody = cancel("nobody")
    assert (nobody["running"], nobody["queued"]) == (0, 0), nobody
    assert "no plan request 'nobody' is running or queued" in nobody["message"], nobody
    late = ros.call("--payload-only", "plan", "--scenario", "np4", "--request-id", "nobody")
    assert late.returncode == 0 and late.json()["status"] == "cancelled", late
    assert "before it started" in late.json()["message"], late
    answer = cancel("long")
    assert (answer["running"], answer["queued"]) == (1, 0), answer
    stopped = finish_call(long)
    assert stopped.returncode == 0, stopped
    payload = stopped.json()
    assert payload["status"] == "cancelled" and payload["solved"] is True, payload
    assert "cancelled by a CancelRequest after" in payload["message"], payload
    assert payload["time"] < 300.0 and payload["path_valid"] is True, payload
    summary = recording.wait_until(
        EPISODE,
        lambda found: any(s["episode_id"] == "long" for s in found),
        timeout=60.0,
        what="the summary of the cancelled request",
        watch=[planner],
    )
    assert next(s for s in summary if s["episode_id"] == "long")["status"] == "cancelled"

    malformed = ros.call("raw", "/lit/planner/cancel", json.dumps({"not": "an envelope"}))
    assert malformed.returncode == 1 and malformed.json()["payload"]["code"] == "envelope", (
        malformed
    )
    after = ros.call("--payload-only", "plan", "--scenario", "np4", "--time", "0.2")
    assert after.returncode == 0 and after.json()["status"] != "cancelled", after
    assert planner.running()
    _no_traceback(planner)


def test_a_cancel_sent_again_after_a_new_plan_with_its_id_cancels_that_plan(
    ros: RosSystem,
) -> None:
    """The same cancel text twice is one cancel (a client's copy sent again gets the first
    answer) until a new plan request carries the id: then the text cancels the new plan. A
    client that reused its envelope and ids got the first answer again, "1 running", and the
    new plan ran to its end."""
    from lit_msgs_json import Publisher

    recording = ros.recorder(["/lit/solution"])
    planner = ros.planner()
    text = Publisher("my_client", "run-1").encode("CancelRequest", {"request_id": "long"})

    def cancel() -> dict[str, Any]:
        answer = ros.call("raw", "/lit/planner/cancel", text)
        assert answer.returncode == 0, answer
        return dict(answer.json()["payload"])

    def solutions() -> int:
        return sum(u["episode_id"] == "long" for u in recording.payloads("/lit/solution"))

    first = _long_request_running(ros, recording, planner, "300")
    assert cancel()["running"] == 1
    assert finish_call(first).json()["status"] == "cancelled"
    assert cancel()["running"] == 1  # the copy: answered again, nothing cancelled twice
    before = solutions()
    second = ros.call_start(
        "--payload-only", "plan", "--scenario", "np4", "--time", "300", "--request-id", "long"
    )
    recording.wait_until(
        "/lit/solution",
        lambda _: solutions() > before,
        timeout=60.0,
        what="a solution of the second long request",
        watch=[planner],
    )
    answer = cancel()
    assert (answer["running"], answer["queued"]) == (1, 0), answer
    stopped = finish_call(second)
    assert stopped.returncode == 0 and stopped.json()["status"] == "cancelled", stopped
    assert planner.running()
    _no_traceback(planner)


def test_a_plan_request_sent_again_is_answered_with_its_result_not_planned_twice(
    ros: RosSystem,
) -> None:
    """``lit call`` sends a plan request again after 1, 3 and 7 s without an answer (a request
    can be lost while a new client is matched): the node answers such a copy with the request's
    result, and does not plan it again (it was planned once more for each). While the query
    runs at most three copies wait for it, each holding a thread of the node; a fourth is
    answered busy at once."""
    from lit_msgs_json import Publisher

    recording = ros.recorder(["/lit/episode", "/lit/solution"])
    planner = ros.planner()
    _ready(planner)
    recording.wait_for_publishers("/lit/solution")
    text = Publisher("my_client", "run-1").encode(
        "PlanRequest", {"scenario": "np4", "time": 300.0, "request_id": "twice"}
    )
    first = ros.call_start("raw", "/lit/planner/plan", text)
    _wait_for_a_solution(recording, planner, "twice")
    deadline = time.monotonic() + 60.0
    while planner.text().count("plan request twice: a copy came again") < 3:  # its own three
        assert time.monotonic() < deadline and first.running(), planner.tail()
        time.sleep(0.1)
    fourth = ros.call("raw", "/lit/planner/plan", text)
    assert fourth.returncode == 1 and fourth.json()["payload"]["code"] == "busy", fourth
    assert "3 copies of it wait for its result already" in fourth.json()["payload"]["message"]
    cancel = ros.call("--payload-only", "cancel", "--request-id", "twice")
    assert cancel.returncode == 0 and cancel.json()["running"] == 1, cancel
    answer = finish_call(first)
    assert answer.returncode == 0, answer
    assert answer.json()["payload"]["status"] == "cancelled", answer
    recording.wait_until(
        "/lit/episode",
        lambda summaries: any(s["episode_id"] == "twice" for s in summaries),
        timeout=60.0,
        what="the request's episode summary",
        watch=[planner],
    )
    assert "waits behind" not in planner.text()
    assert sum(s["episode_id"] == "twice" for s in recording.payloads("/lit/episode")) == 1
    assert planner.running()
    _no_traceback(planner)


def test_a_plan_request_without_a_request_id_is_cancelled_by_the_id_the_node_logs(
    ros: RosSystem,
) -> None:
    """A request without a ``request_id`` (a client of another make, which then crashed) is
    ``req-<hex>`` in the node's log and on ``/lit/solution``; a cancel naming that stops it. It
    could not be stopped before: a 600 s request held the worker for its whole time."""
    recording = ros.recorder(["/lit/solution"])
    planner = ros.planner()
    _ready(planner)
    recording.wait_for_publishers("/lit/solution")
    text = Publisher("other_client", "run-1").encode(
        "PlanRequest", {"scenario": "np4", "time": 300.0}
    )
    anonymous = ros.call_start("raw", PLAN, text)
    logged = planner.wait_for_log(r"has no request_id: it is (req-[0-9a-f]+) here", timeout=60.0)
    episode_id = logged.group(1)
    recording.wait_until(
        "/lit/solution",
        lambda updates: any(update["episode_id"] == episode_id for update in updates),
        timeout=60.0,
        what="a solution of the request without an id",
        watch=[planner],
    )
    answer = ros.call("--payload-only", "cancel", "--request-id", episode_id)
    assert answer.returncode == 0 and answer.json()["running"] == 1, answer
    stopped = finish_call(anonymous)
    assert stopped.returncode == 0, stopped
    payload = stopped.json()["payload"]
    assert payload["status"] == "cancelled" and payload["request_id"] is None, payload
    assert planner.running()
    _no_traceback(planner)


def test_the_example_client_of_your_own_plans_and_cancels(ros: RosSystem) -> None:
    """``lit_planner/examples/plan_client.py`` (plain rclpy, the README's "Your own client"):
    one request answered with its path, and one it gives up on cancelled, answered with what the
    planner found until then."""
    example = Path(__file__).resolve().parents[1] / "lit_planner" / "examples" / "plan_client.py"
    planner = ros.planner()
    _ready(planner)

    def run(*args: str) -> tuple[int, dict[str, Any], str]:
        client = ros.start("client", [sys.executable, str(example), *args], separate_stdout=True)
        code = client.wait(120.0)
        return code, json.loads(client.output()), client.text()

    code, answer, _ = run("--scenario", "np4", "--time", "0.2")
    assert code == 0 and answer["status"] == "exact_solution", answer
    assert answer["path_valid"] is True and len(answer["path"]) >= 2, answer
    code, answer, log = run("--scenario", "np8", "--time", "300", "--timeout", "3")
    assert code == 0 and answer["status"] == "cancelled", (answer, log)
    assert "cancelled by a CancelRequest after" in answer["message"], answer
    assert "cancel: cancelled the plan request" in log and ": 1 running" in log, log
    code, answer, _ = run("--scenario", "xx4")  # no such family: the node's Error
    assert code == 1 and answer["code"] == "invalid-request", answer
    assert "unknown scenario 'xx4'" in answer["message"], answer
    assert planner.running()
    _no_traceback(planner)


def test_the_example_client_keeps_discovery_on_this_host_and_finds_lit_ups_domain() -> None:
    """Run as the README says, without either variable, it used ROS's defaults: multicast
    discovery on every interface (which this project never sends) and domain 0, where no node of
    ``lit up`` runs. A user's own choice of either is kept."""
    import importlib.util

    example = Path(__file__).resolve().parents[1] / "lit_planner" / "examples" / "plan_client.py"
    spec = importlib.util.spec_from_file_location("plan_client", example)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    bare: dict[str, str] = {}
    module.local_environment(bare)
    assert bare == {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "ROS_DOMAIN_ID": "42"}
    blank = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "", "ROS_DOMAIN_ID": " "}  # ROS's defaults too
    module.local_environment(blank)
    assert blank == {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "ROS_DOMAIN_ID": "42"}
    chosen = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET", "ROS_DOMAIN_ID": "7"}
    module.local_environment(chosen)
    assert chosen == {"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET", "ROS_DOMAIN_ID": "7"}


@pytest.mark.parametrize("how", ["timeout", "sigint", "sigterm"])
def test_lit_call_plan_cancels_the_query_it_stops_waiting_for(ros: RosSystem, how: str) -> None:
    """``lit call plan`` that stops waiting (its ``--timeout``, Ctrl-C or SIGTERM) cancels its
    request in the node, which then serves the next one instead of planning for nobody. (Until
    the wait looked at the signal, a signalled call waited out its whole timeout.)"""
    recording = ros.recorder(["/lit/solution"])
    planner = ros.planner()
    _ready(planner)
    recording.wait_for_publishers("/lit/solution")
    options = ["--timeout", "20"] if how == "timeout" else []
    call = ros.call_start(*options, "plan", "--scenario", "np4", "--time", "300")
    updates = recording.wait_until(  # it runs: a solution of the call's own request_id
        "/lit/solution",
        lambda updates: any(update["episode_id"].startswith("call-") for update in updates),
        timeout=60.0,
        what="a solution of the lit call request",
        watch=[planner, call],
    )
    request_id = next(u["episode_id"] for u in updates if u["episode_id"].startswith("call-"))
    if how != "timeout":
        how_stopped = signal.SIGINT if how == "sigint" else signal.SIGTERM
        assert ros.stop(call, how_stopped, timeout=60.0) == 130, call.text()
    else:
        assert call.wait(timeout=120.0) == 2, call.text()
    assert f"cancel of plan request '{request_id}': cancelled the plan request" in call.text(), (
        call.text()
    )
    planner.wait_for_log(
        rf"plan request {request_id}: cancelled by a CancelRequest after", timeout=60.0
    )
    after = ros.call("--payload-only", "plan", "--scenario", "np4", "--time", "0.2")
    assert after.returncode == 0 and after.json()["status"] != "cancelled", after
    _no_traceback(planner)


# ---------------------------------------------------------------------- 2., 3. training over ROS


def test_training_episodes_reach_the_learner(ros: RosSystem) -> None:
    """Planner (policy training) and learner: every decision and both episode ends over ROS."""
    recording = ros.recorder([EPISODE, STATS])
    # The planner first: its episodes wait for the learner, by then the recorder listens.
    planner = ros.planner(episodes=2, exit_when_done=True, **TRAINING)
    _ready(planner)
    recording.wait_for_publishers(EPISODE)
    learner = ros.learner()
    _ready(learner)
    assert planner.wait(timeout=300.0) == 0, planner.tail()

    summaries = recording.wait_until(
        EPISODE, lambda found: len(found) >= 2, timeout=30.0, what="two EpisodeSummary messages"
    )
    assert len(summaries) == 2
    for summary in summaries:
        assert summary["mode"] == "training" and summary["policy"] == "training"
        assert _learned(summary), summary
        assert summary["dimension"] in (4, 8)
    stats = recording.wait_until(
        STATS,
        lambda found: any(
            item["episodes"] >= 2 and any(n > 0 for n in item["transitions"].values())
            for item in found
        ),
        timeout=30.0,
        what="LearnerStats with two episodes and stored transitions",
        watch=[learner],
    )
    assert "/lit_planner" in stats[-1]["planners"]
    assert stats[-1]["decisions"] >= sum(s["learner_calls"] for s in summaries)
    assert stats[0]["checkpoint"] is None  # a fresh learner: nothing loaded or written yet
    assert "use the fallback policy" not in planner.text()
    _no_traceback(planner, learner)


def test_a_failing_checkpoint_leaves_the_trainer_running_and_probes_train_nothing(
    ros: RosSystem,
) -> None:
    """A checkpoint that cannot be written (its folder is a file) is logged, counted in the
    stats and tried again: the trainer thread used to die with the first one while the node
    went on answering, and the process then exited 0 without its export. `lit call decide`
    sends probes: answered and counted, never stored as transitions (a `--repeat` benchmark
    used to fill the live learner's replay buffer with made-up steps)."""
    blocker = ros.workdir / "not-a-folder"
    blocker.write_text("a file where the checkpoint's folder should be\n", encoding="utf-8")
    recording = ros.recorder([EPISODE, STATS])
    learner = ros.learner(
        checkpoint=str(blocker / "checkpoint.pt"), checkpoint_period=1.0, stats_period=0.2
    )
    _ready(learner)
    probes = ros.call("--payload-only", "decide", "--repeat", "30")
    assert probes.returncode == 0, probes
    stats = recording.wait_until(
        STATS, lambda found: any(p["decisions"] >= 50 for p in found), timeout=60.0,
        what="the probes counted as answered decisions", watch=[learner],
    )  # fmt: skip
    assert all(n == 0 for n in stats[-1]["transitions"].values()), stats[-1]
    planner = ros.planner(episodes=2, exit_when_done=True, **TRAINING)
    assert planner.wait(timeout=300.0) == 0, planner.tail()
    recording.wait_until(
        STATS,
        lambda found: any(p["metrics"].get("trainer/errors", 0) >= 2 for p in found),
        timeout=60.0, what="two failed checkpoints counted", watch=[learner],
    )  # fmt: skip
    assert "is tried again in 5 s" in learner.text()
    # No checkpoint was ever written: the stats name none (they named the parameter's path).
    assert all(p["checkpoint"] is None for p in recording.payloads(STATS))
    answer = ros.call("--payload-only", "decide")  # still serving
    assert answer.returncode == 0, answer
    # The shutdown's own checkpoint fails too: logged, the export is still written, and the
    # exit code says so.
    assert ros.stop(learner, signal.SIGTERM, timeout=60.0) == 1, learner.tail()
    assert "shutdown failed" in learner.text()
    # (A copy of the checkpoint: no agent is past its warm-up, so no tensor.)
    assert (ros.workdir / "learner" / "tensors" / "checkpoint.pt").is_file(), learner.tail(30)
    assert re.search(r"exported to \S+ \(shutdown\): a checkpoint copy", learner.text())
    assert "Exception in thread" not in learner.text(), learner.tail(60)


def test_a_planner_whose_episodes_failed_exits_1(ros: RosSystem, tmp_path: Path) -> None:
    """With exit_when_done the node exited 0 although every episode had failed."""
    planner = ros.planner(policy="tensor", tensors_dir=str(tmp_path), scenario="np4",
                          time_budget=0.2, episodes=1, exit_when_done=True)  # fmt: skip
    assert planner.wait(timeout=120.0) == 1, planner.tail()
    assert "1 tensor episodes done (1 of them failed)" in planner.text(), planner.tail()
    assert "the tensor policy found no lookup tensors in" in planner.text()


def test_two_planners_train_one_learner(ros: RosSystem) -> None:
    """Planners in ``/robot1`` and ``/robot2`` train the same learner at the same time, on
    problems of their own although their training seeds are the same (the default)."""
    topics = ["/robot1" + EPISODE, "/robot2" + EPISODE]
    recording = ros.recorder([*topics, STATS])
    planners = [
        ros.planner(
            f"planner{robot}",
            namespace=f"/robot{robot}",
            episodes=2,
            exit_when_done=True,
            **TRAINING,
        )
        for robot in (1, 2)
    ]
    _ready(*planners)
    for topic in topics:
        recording.wait_for_publishers(topic)
    learner = ros.learner()
    _ready(learner)
    for planner in planners:
        assert planner.wait(timeout=300.0) == 0, planner.tail()

    stats = recording.wait_until(
        STATS,
        lambda found: bool(found) and found[-1]["episodes"] >= 4,
        timeout=30.0,
        what="LearnerStats with four episodes",
        watch=[learner],
    )
    assert {"/robot1/lit_planner", "/robot2/lit_planner"} <= set(stats[-1]["planners"])
    drawn = []
    for topic in topics:
        summaries = recording.payloads(topic)
        assert len(summaries) == 2, (topic, summaries)
        drawn.append([(s["scenario"], s["seed"]) for s in summaries])
        assert all(_learned(summary) for summary in summaries), (
            [(s["episode_id"], s["learner_calls"], s["fallback_decisions"]) for s in summaries],
            *(child.tail(15) for child in (*planners, learner)),
        )
    assert drawn[0] != drawn[1], drawn
    _no_traceback(learner, *planners)


# ---------------------------------------------------------------------- 4. a learner crash


@contextmanager
def _learner_stopped_before_the_first_call(
    ros: RosSystem, **planner_params: Any
) -> Iterator[tuple[Child, Child]]:
    """A learner and a training planner that has found it; the learner is stopped (SIGSTOP)
    before the first episode starts (the episodes wait for a recorder started after the stop),
    and runs again (SIGCONT) when the block ends."""
    learner = ros.learner()
    _ready(learner)
    planner = ros.planner(
        policy="training",
        exit_when_done=True,
        training_scenarios="np4",
        learner_wait=120.0,
        wait_for_subscribers=1,
        **planner_params,
    )
    planner.wait_for_log(r"learner service \S+ found", timeout=NODE_START)
    os.kill(learner.pid, signal.SIGSTOP)
    try:
        ros.start(
            "recorder", [RECORDER_NODE, *ros_arguments({"bag": str(ros.workdir / "bag")}, None)]
        )
        yield learner, planner
    finally:
        os.kill(learner.pid, signal.SIGCONT)


def test_the_first_call_waits_longer(ros: RosSystem) -> None:
    """Fast DDS drops a server's first answers to a client it has not matched yet (the server
    sends again about 100 ms later), so the planner's first call waits
    ``first_decision_timeout``, not ``decision_timeout`` (the killed-learner test below checks
    the short deadline after answers). The learner is stopped before the first call: that call
    waits the long deadline; once the learner runs again its late answer resumes the calls."""
    with _learner_stopped_before_the_first_call(
        ros,
        episodes=2,
        time_budget=0.05,
        learner_retry=600.0,
        first_decision_timeout=2.0,
        decision_timeout=0.5,
    ) as (learner, planner):
        missed = planner.wait_for_log(r"learner did not answer within (\d+) ms", timeout=60.0)
        assert missed.group(1) == "2000", planner.tail()
    planner.wait_for_log(
        r"the learner (answered the missed call late|took the episode end); calls resume",
        timeout=60.0,
    )
    assert planner.wait(timeout=120.0) == 0, planner.tail()
    assert planner.text().count("did not answer within 2000 ms") == 1, planner.tail()
    assert re.search(r"learner answered its first call (late|\(an episode end\))", planner.text())
    _no_traceback(planner, learner)


def test_a_silent_learner_costs_the_long_first_deadline_once(ros: RosSystem) -> None:
    """Only the first call waits ``first_decision_timeout``: a learner that is found and then
    never answers (stopped for the whole run) costs each later call ``decision_timeout``, and
    an episode end after two misses in a row waits no longer than a decision."""
    with _learner_stopped_before_the_first_call(
        ros,
        episodes=3,
        time_budget=0.3,
        learner_retry=0.1,
        first_decision_timeout=0.6,
        decision_timeout=0.05,
    ) as (learner, planner):
        assert planner.wait(timeout=120.0) == 0, planner.tail()
    text = planner.text()
    decisions = re.findall(r"learner did not answer within (\d+) ms", text)
    # One warning per episode: the first names the long deadline, the later ones the short one.
    assert len(decisions) >= 2 and decisions[0] == "600", planner.tail()
    assert set(decisions[1:]) == {"50"}, planner.tail()
    ends = re.findall(r"did not take the episode end within (\d+) ms", text)
    # Episode 0 ends after one miss or more; later episodes after two in a row at least.
    assert len(ends) == 3 and set(ends[1:]) == {"50"}, planner.tail()
    assert "learner answered its first call" not in text, planner.tail()
    assert "calls resume" not in text, planner.tail()
    _no_traceback(planner, learner)


def _training_under_way(
    ros: RosSystem, learner_params: dict[str, Any], learner_retry: float
) -> tuple[Recording, Child, Child]:
    """A recorder of the episodes, a learner and a planner training without end (deadline
    300 ms), once an episode was trained by the learner."""
    recording = ros.recorder([EPISODE])
    learner = ros.learner(**learner_params)
    _ready(learner)
    planner = ros.planner(
        episodes=10_000,  # stopped by the test
        policy="training",
        time_budget=0.5,
        training_scenarios="np4,np8",
        decision_timeout=0.3,
        learner_retry=learner_retry,
    )
    _ready(planner)
    recording.wait_until(
        EPISODE,
        lambda found: any(_learned(summary) for summary in found),
        timeout=120.0,
        what="an episode trained by the learner",
        watch=[planner, learner],
    )
    return recording, learner, planner


def test_planner_survives_a_killed_learner_and_resumes(ros: RosSystem) -> None:
    """SIGKILL the learner mid-training: fallback decisions, then training resumes on restart."""
    checkpoint = _checkpoint(ros)
    learner_params = {"checkpoint_every": 1, "checkpoint_period": 1.0}
    recording, learner, planner = _training_under_way(ros, learner_params, learner_retry=0.5)
    learner.wait_for_log(r"checkpoint \S+ \([1-9]\d* episodes\)", timeout=60.0)
    assert checkpoint.is_file()

    before_kill = len(recording.payloads(EPISODE))
    log_at_kill = len(planner.text())
    assert ros.stop(learner, signal.SIGKILL) == -signal.SIGKILL
    # after answers the short deadline (decision_timeout) applies, not first_decision_timeout
    planner.wait_for_log(
        r"learner did not answer within 300 ms",
        timeout=60.0,
        start=log_at_kill,
    )
    recording.wait_until(
        EPISODE,
        lambda found: any(summary["fallback_decisions"] > 0 for summary in found[before_kill:]),
        timeout=60.0,
        what="an episode with fallback decisions",
        watch=[planner],
    )

    restarted = ros.learner("learner-restarted", **learner_params)
    resumed = restarted.wait_for_log(r"resumed from \S+: (\d+) episodes", timeout=NODE_START)
    assert int(resumed.group(1)) >= 1
    _ready(restarted)
    after_restart = len(recording.payloads(EPISODE))
    recording.wait_until(
        EPISODE,
        lambda found: any(_learned(summary) for summary in found[after_restart:]),
        timeout=120.0,
        what="an episode trained by the restarted learner",
        watch=[planner, restarted],
    )

    assert planner.running(), planner.tail()
    assert ros.stop(planner, timeout=60.0) == 0, planner.tail()
    assert ros.stop(restarted, timeout=60.0) == 0, restarted.tail()
    _no_traceback(planner, restarted)
    # Requests after fallbacks (after_fallback) and episode ends naming the agents that fell back
    # (fallback_agents) are valid messages: the learner took every one of them.
    assert "rejected:" not in restarted.text(), restarted.tail(40)
    assert not re.search(r"episode \S+: learner: ", planner.text()), planner.tail(40)


def test_a_late_answer_resumes_calls_before_learner_retry(ros: RosSystem) -> None:
    """A learner that is alive but slow once (here: stopped with SIGSTOP until a call has missed
    its deadline, as a busy machine would hold it) misses a call; the planner falls back until
    the late answer arrives, then calls the learner again within the same episode.
    ``learner_retry`` is ten minutes, so learner decisions after the fallbacks show the early
    resumption. If the pause catches an episode end instead (the episode's fallbacks run to its
    end first), the episode end answered in time resumes the calls, and the test tries again; it
    does too when the call made on the late answer misses as well (the learner still busy on a
    loaded machine), once that second miss was warned of and an episode end ended its window."""
    decisions = "/lit/decision"
    recording = ros.recorder([EPISODE, decisions])
    planner = ros.planner(
        episodes=10_000,  # stopped by the test
        policy="training",
        time_budget=5.0,  # long episodes: a late answer comes while the episode still runs
        training_scenarios="np4,np8",
        decision_timeout=0.3,
        learner_retry=600.0,
        learner_wait=300.0,
    )
    _ready(planner)
    for topic in (EPISODE, decisions):  # matched before the first episode: every message counts
        recording.wait_for_publishers(topic)
    learner = ros.learner()
    _ready(learner)
    planner.wait_for_log(r"learner answered its first call", timeout=NODE_START)
    for _attempt in range(3):
        start = len(planner.text())
        os.kill(learner.pid, signal.SIGSTOP)
        try:
            missed = planner.wait_for_log(
                r"episode (\S+): (learner did not answer within 300 ms; this decision and "
                r"those until the learner answers it late \(at most 600 s\) use the fallback "
                r"policy|the learner did not take the episode end within 6000 ms)",
                timeout=60.0,
                start=start,
            )
        finally:
            os.kill(learner.pid, signal.SIGCONT)
        resumed = planner.wait_for_log(
            r"episode (\S+): the learner (answered the missed call late|took the episode end); "
            r"calls resume",
            timeout=60.0,
            start=start,
        )
        # A missed episode end's late answer resumes the next episode before any fallback.
        if not (missed.group(2).startswith("learner") and resumed.group(2).startswith("answered")):
            continue
        episode = missed.group(1)
        assert resumed.group(1) == episode, planner.tail()  # resumed where the decision missed
        sources = _decision_sources(recording, episode, planner)
        first_fallback = next(
            i for i, source in enumerate(sources) if source.startswith("fallback")
        )
        # From the shipped tensors (they failed to load, and every fallback played B = 100 and
        # psi_K = e, with an error in the log).
        assert sources[first_fallback] == "fallback-tensor", sources
        assert "unusable" not in planner.text(), planner.tail()
        if "learner" in sources[first_fallback:]:
            break
        # The call made on the late answer missed too (a learner still busy after the pause, on
        # a loaded machine): that second miss in a row starts the learner_retry window, with a
        # warning of its own, and an episode end answered in time ends the window.
        second = planner.wait_for_log(
            rf"episode {re.escape(episode)}: learner did not answer within 300 ms "
            r"\(2 calls in a row\); this decision and those in the next 600 s use the fallback",
            timeout=10.0,
            start=resumed.end(),
        )
        planner.wait_for_log(
            r"the learner took the episode end; calls resume", timeout=120.0, start=second.end()
        )
    else:
        raise AssertionError(
            f"in 3 pauses no late answer to a decision resumed the calls:\n{planner.tail()}"
        )

    assert ros.stop(planner, timeout=60.0) == 0, planner.tail()
    assert ros.stop(learner, timeout=60.0) == 0, learner.tail()
    _no_traceback(planner, learner)
    assert "rejected:" not in learner.text(), learner.tail(40)


def _decision_sources(recording: Recording, episode: str, planner: Child) -> list[str]:
    """The sources of episode ``episode``'s decisions in order, once its summary and all the
    decisions it counts were recorded."""
    found = recording.wait_until(
        EPISODE,
        lambda found: any(s["episode_id"] == episode for s in found),
        timeout=120.0,
        what=f"the summary of episode {episode}",
        watch=[planner],
    )
    summary = next(s for s in found if s["episode_id"] == episode)
    total = sum(summary["decisions"].values())
    recorded = recording.wait_until(
        "/lit/decision",
        lambda found: sum(d["episode_id"] == episode for d in found) >= total,
        timeout=60.0,
        what=f"the {total} decisions of episode {episode}",
        watch=[planner],
    )
    sources = [d["source"] for d in recorded if d["episode_id"] == episode]
    assert len(sources) == total, (len(sources), summary)
    return sources


# ---------------------------------------------------------------------- 5. bad input


def _envelope(name: str, payload: dict[str, Any], **changes: Any) -> dict[str, Any]:
    envelope = Publisher("/test_client", "bad-input").envelope(name, payload)
    envelope.update(changes)
    return envelope


def _decide_payload(**changes: Any) -> dict[str, Any]:
    payload: dict[str, Any] = {
        "agent": "B",
        "episode_id": "bad-input",
        "rho_global": 0.1,
        "rho_local": 0.1,
        "measure": 0.5,
        "planning_time": 0.0,
        "time_budget": 1.0,
        "cost": None,
        "minimum_cost": 1.0,
        "improvements": 0,
        "path_states": 0,
    }
    payload.update(changes)
    return payload


def _bad_payload(name: str, payload: dict[str, Any], **changes: Any) -> str:
    """A valid envelope of ``payload`` whose payload then gets ``changes`` (schema violations)."""
    envelope = _envelope(name, payload)
    envelope["payload"].update(changes)
    return json.dumps(envelope)


def _nan_text(name: str, payload: dict[str, Any], key: str) -> str:
    envelope = _envelope(name, payload)
    envelope["payload"][key] = float("nan")
    text = json.dumps(envelope)  # allow_nan: the literal NaN, which JSON does not have
    assert "NaN" in text
    return text


FREE_SQUARE = {
    "world": {"lower": [-0.5, -0.5], "upper": [0.5, 0.5], "boxes": []},
    "start": [-0.3, 0.0],
    "goal": [0.3, 0.0],
    "time": 0.2,
}
TOO_FINE = {**FREE_SQUARE["world"], "resolution": 1e-10}
PLAN = "/lit/planner/plan"
DECIDE = "/lit/learner/decide"
CANCEL = "/lit/planner/cancel"
EPISODE_END = {"episode_id": "bad-input", "planning_time": 0.3, "time_budget": 1.0, "cost": None,
               "minimum_cost": 1.0, "improvements": 0, "path_states": 0, "truncated": False,
               "fallback_decisions": 0}  # fmt: skip
OVERSIZE = ('{"text": "' + "x" * (MAX_MESSAGE_BYTES + 16) + '"}').encode()
BAD_INPUT: list[tuple[str, list[str], bytes | None, str, str | None, str]] = [
    # (case, lit call arguments, standard input, code, field, words of the message)
    ("plan: malformed JSON", ["raw", PLAN, '{"schema": '], None, "json", "$", "not valid JSON"),
    (
        "plan: a DecideRequest",
        ["raw", PLAN, json.dumps(_envelope("DecideRequest", _decide_payload()))],
        None,
        "unexpected-schema",
        "$.schema",
        "DecideRequest is not accepted",
    ),
    (
        "plan: version 2",
        ["raw", PLAN, json.dumps(_envelope("PlanRequest", {"scenario": "np4"}, version=2))],
        None,
        "version",
        "$.version",
        "got version 2",
    ),
    (
        "plan: NaN",
        ["raw", PLAN, _nan_text("PlanRequest", {"scenario": "np4", "time": 0.1}, "time")],
        None,
        "json",
        "$",
        "NaN",
    ),
    ("plan: oversize", ["raw", PLAN, "-"], OVERSIZE, "oversize", "$", "more than the limit"),
    (
        # An integer too large for a double: the world's arrays overflowed (OverflowError), the
        # executor ended and the node with it; the learner answered an empty message.
        "plan: a 401-digit integer in start",
        [
            "raw",
            PLAN,
            json.dumps(_envelope("PlanRequest", {"scenario": "np4", "start": [10**400] * 4})),
        ],
        None,
        "payload",
        "$.payload.start[0]",
        "is not a finite number",
    ),
    (
        "decide: a 401-digit integer in minimum_cost",
        [
            "raw",
            DECIDE,
            json.dumps(_envelope("DecideRequest", _decide_payload(minimum_cost=10**400))),
        ],
        None,
        "payload",
        "$.payload.minimum_cost",
        "is not a finite number",
    ),
    (
        # Valid JSON (json.dumps escapes it) whose string is not Unicode text: the planner's
        # logger raised on it and its worker thread ended; no plan request was answered again.
        "plan: a lone surrogate in request_id",
        [
            "raw",
            PLAN,
            json.dumps(
                _envelope("PlanRequest", {"scenario": "np4", "time": 0.1, "request_id": "\ud800"})
            ),
        ],
        None,
        "json",
        "$.payload.request_id",
        "lone UTF-16 surrogate",
    ),
    (
        "decide: a lone surrogate in episode_id",
        [
            "raw",
            DECIDE,
            json.dumps(_envelope("DecideRequest", _decide_payload(episode_id="x\udfff"))),
        ],
        None,
        "json",
        "$.payload.episode_id",
        "lone UTF-16 surrogate",
    ),
    (
        "plan: payload violates the schema",
        ["raw", PLAN, _bad_payload("PlanRequest", {"scenario": "np4"}, time="soon")],
        None,
        "payload",
        "$.payload.time",
        "soon",
    ),
    (
        # A NUL cut /lit/path's frame_id there: the path no longer matched its request.
        "plan: a NUL in request_id",
        ["raw", PLAN, _bad_payload("PlanRequest", {"scenario": "np4"}, request_id="a\x00b")],
        None,
        "payload",
        "$.payload.request_id",
        "holds a control character",
    ),
    (
        "plan: start out of bounds",  # a negative first coordinate: `--start -5,...` parses
        ["plan", "--scenario", "np4", "--start", "-5,5,5,5"],
        None,
        "invalid-request",
        "$.payload.start",
        "start is out of bounds",
    ),
    (
        "plan: start inside an obstacle",
        ["plan", "--scenario", "np4", "--start", "0,0.3,0,0"],
        None,
        "invalid-request",
        "$.payload.start",
        "start is in collision",
    ),
    (
        "plan: goal inside an obstacle",
        ["plan", "--scenario", "np4", "--goal", "0,0.3,0,0"],
        None,
        "invalid-request",
        "$.payload.goal",
        "goal is in collision",
    ),
    (
        "plan: goal out of bounds",
        ["plan", "--scenario", "np4", "--goal", "0.7,0,0,0"],
        None,
        "invalid-request",
        "$.payload.goal",
        "goal is out of bounds",
    ),
    (
        "cancel: version 2",
        ["raw", CANCEL, json.dumps(_envelope("CancelRequest", {"request_id": "a"}, version=2))],
        None,
        "version",
        "$.version",
        "got version 2",
    ),
    (
        "cancel: payload violates the schema",
        ["raw", CANCEL, _bad_payload("CancelRequest", {"request_id": "a"}, request_id="")],
        None,
        "payload",
        "$.payload.request_id",
        "should be non-empty",
    ),
    (
        "episode end: version 3",
        ["raw", DECIDE, json.dumps(_envelope("EpisodeEnd", EPISODE_END, version=3))],
        None,
        "version",
        "$.version",
        "got version 3 of EpisodeEnd",
    ),
    (
        "episode end: payload violates the schema",
        ["raw", DECIDE, _bad_payload("EpisodeEnd", EPISODE_END, improvements=-1)],
        None,
        "payload",
        "$.payload.improvements",
        "-1",
    ),
    (
        # sent raw: lit call plan refuses it itself before sending (exit 2)
        "plan: start of the wrong dimension",
        ["raw", PLAN, json.dumps(_envelope("PlanRequest", {"scenario": "np4", "start": [0, 0]}))],
        None,
        "invalid-request",
        "$.payload.start",
        "start has 2 coordinates",
    ),
    (
        "plan: start equals goal",  # answered with an internal SolutionUpdate error before
        ["plan", "--scenario", "np4", "--start", "0.2,0,0,0"],
        None,
        "invalid-request",
        "$.payload.goal",
        "nothing to plan",
    ),
    (
        "plan: a goal 1e-170 from the start",  # AIT* aborted the planner node's process
        ["plan", "--scenario", "np4", "--planner", "aitstar", "--goal=-0.2,1e-170,0,0"],
        None,
        "invalid-request",
        "$.payload.goal",
        "start and goal are the same state",
    ),
    (
        "plan: an iteration limit for an OMPL planner",  # was an internal Error
        [
            "raw",
            PLAN,
            json.dumps(
                _envelope(
                    "PlanRequest", {"scenario": "np8", "planner": "aitstar", "max_iterations": 10}
                )
            ),
        ],
        None,
        "invalid-request",
        "$.payload.max_iterations",
        "aitstar stops on time only",
    ),
    (
        "plan: a seed for an OMPL planner",  # answered as the seed used; its plans differed
        [
            "raw",
            PLAN,
            json.dumps(
                _envelope("PlanRequest", {"scenario": "np4", "planner": "rrtconnect", "seed": 5})
            ),
        ],
        None,
        "invalid-request",
        "$.payload.seed",
        "rrtconnect cannot take a seed in the planner node",
    ),
    (
        "plan: a policy for an OMPL planner",  # was silently ignored; lit call refuses it (exit 2)
        [
            "raw",
            PLAN,
            json.dumps(
                _envelope(
                    "PlanRequest", {"scenario": "np4", "planner": "aitstar", "policy": "tensor"}
                )
            ),
        ],
        None,
        "invalid-request",
        "$.payload.policy",
        "aitstar takes no policy",
    ),
    (
        # sent raw: lit call plan refuses the name itself before sending (exit 2)
        "plan: unknown scenario",
        ["raw", PLAN, json.dumps(_envelope("PlanRequest", {"scenario": "zz9"}))],
        None,
        "invalid-request",
        "$.payload.scenario",
        "zz9",
    ),
    (
        "plan: a world too large for double precision",  # ran the planner node out of memory
        [
            "raw",
            PLAN,
            json.dumps(
                _envelope(
                    "PlanRequest",
                    {
                        "world": {"lower": [-1e308, -1e308], "upper": [1e308, 1e308], "boxes": []},
                        "start": [-0.3, 0.0],
                        "goal": [0.3, 0.0],
                        "time": 0.2,
                    },
                )
            ),
        ],
        None,
        "invalid-request",
        "$.payload.world",
        "the world is too large",
    ),
    (
        "plan: a resolution too fine",  # 1e-10 ran the planner node out of memory on one edge
        ["raw", PLAN, _bad_payload("PlanRequest", FREE_SQUARE, world=TOO_FINE)],
        None,
        "payload",
        "$.payload.world.resolution",
        "less than the minimum",
    ),
    ("decide: malformed JSON", ["raw", DECIDE, "[1, 2"], None, "json", "$", "not valid JSON"),
    (
        "decide: a PlanRequest",
        ["raw", DECIDE, json.dumps(_envelope("PlanRequest", {"scenario": "np4"}))],
        None,
        "unexpected-schema",
        "$.schema",
        "PlanRequest is not accepted",
    ),
    (
        "decide: version 4",
        ["raw", DECIDE, json.dumps(_envelope("DecideRequest", _decide_payload(), version=4))],
        None,
        "version",
        "$.version",
        "got version 4 of DecideRequest, expected versions 1, 2, 3",
    ),
    (
        "decide: NaN",
        ["raw", DECIDE, _nan_text("DecideRequest", _decide_payload(), "rho_global")],
        None,
        "json",
        "$",
        "NaN",
    ),
    ("decide: oversize", ["raw", DECIDE, "-"], OVERSIZE, "oversize", "$", "more than the limit"),
    (
        "decide: feature out of range",
        ["raw", DECIDE, _bad_payload("DecideRequest", _decide_payload(), rho_global=1.5)],
        None,
        "payload",
        "$.payload.rho_global",
        "1.5",
    ),
]


def test_bad_input_is_answered_with_errors(ros: RosSystem) -> None:
    """Every kind of bad request gets an Error naming the problem; both nodes keep serving."""
    planner = ros.planner()
    learner = ros.learner()
    _ready(planner, learner)
    # The small requests go out eight at a time; the two of over 1 MiB one at a time afterwards.
    # Fast DDS carries a message larger than its shared-memory segment (512 KiB) in fragments, and
    # with a dozen other clients starting at once one such request was seen lost (60 s without an
    # answer). With all 26 small ones at once, the learner's answer to one was lost once in CI:
    # lit call now sends such a request again (a plan request at most three times, in its first
    # 7 s).
    small = [case for case in BAD_INPUT if case[2] is not OVERSIZE]
    results = []
    for first in range(0, len(small), 8):
        wave = small[first : first + 8]
        # Clients discover the services at once on two cores, after whatever ran before: more
        # than lit call's default 15 s to find a service (exit 2) is not what this test is about.
        calls = [
            ros.call_start("--wait", "120", "--payload-only", *arguments, stdin=stdin)
            for _, arguments, stdin, *_ in wave
        ]
        results += [finish_call(call) for call in calls]
    for _, arguments, stdin, *_ in BAD_INPUT:
        if stdin is OVERSIZE:
            results.append(finish_call(ros.call_start("--payload-only", *arguments, stdin=stdin)))
    ordered = small + [case for case in BAD_INPUT if case[2] is OVERSIZE]
    for (case, _, _, code, field, words), result in zip(ordered, results, strict=True):
        assert result.returncode == 1, (
            f"{case}: {result}\nplanner:\n{planner.tail(60)}\nlearner:\n{learner.tail(30)}"
        )
        error = result.json()
        assert error["code"] == code, f"{case}: {error}"
        assert error["field"] == field, f"{case}: {error}"
        assert words in error["message"], f"{case}: {error}"
        if code == "invalid-request" and case.startswith("plan"):  # the request it answers
            assert error["request_schema"] == "PlanRequest" and error["request_seq"] is not None

    # Time running backwards within an episode: the learner can pair no transition from it.
    episode = {"episode_id": "backwards", "agent": "psi_K"}
    later = _envelope("DecideRequest", _decide_payload(planning_time=0.5, **episode))
    earlier = _envelope("DecideRequest", _decide_payload(planning_time=0.2, **episode))
    result = ros.call("--payload-only", "raw", DECIDE, json.dumps(later))
    assert result.returncode == 0 and result.json()["agent"] == "psi_K", result
    result = ros.call("--payload-only", "raw", DECIDE, json.dumps(earlier))
    assert result.returncode == 1, result
    error = result.json()
    assert error["code"] == "invalid-request", error
    assert error["field"] == "$.payload.planning_time", error
    assert error["rule"] == "order", error
    assert "before the previous message's 0.5" in error["message"], error
    # Two planners' episodes whose names joined with bars read alike ("/a|x", "r", "e" and "/a",
    # "x|r", "e") are two episodes: they were one, and the second's earlier time was refused.
    for source, run_id, planning_time in (("/a|x", "r", 0.5), ("/a", "x|r", 0.2)):
        text = json.dumps(
            _envelope(
                "DecideRequest",
                _decide_payload(planning_time=planning_time, episode_id="e"),
                source=source,
                run_id=run_id,
            )
        )
        result = ros.call("--payload-only", "raw", DECIDE, text)
        assert result.returncode == 0 and result.json()["agent"] == "B", (source, result)

    result = ros.call("--payload-only", "plan", "--scenario", "np4", "--iterations", "2000")
    assert result.returncode == 0, result
    assert result.json()["solved"] is True
    result = ros.call("--payload-only", "decide", "--agent", "psi_K", "--measure", "0.3")
    assert result.returncode == 0, result
    assert result.json()["agent"] == "psi_K" and math.isfinite(result.json()["value"])
    assert planner.running() and learner.running()
    _no_traceback(planner, learner)


def test_a_path_too_long_for_a_trajectory_is_answered_and_not_published(ros: RosSystem) -> None:
    """A world 3e9 wide: its path takes more seconds at unit speed than a JointTrajectory's int32
    can say. The message could not be built (the request was answered with an internal error),
    or its times wrapped; now the plan is answered and the path is not published."""
    planner = ros.planner()
    _ready(planner)
    world = {"lower": [0, 0], "upper": [3e9, 3e9], "boxes": []}
    payload = {"world": world, "start": [3e7, 3e7], "goal": [2.97e9, 2.97e9], "time": 0.2}
    result = ros.call("--payload-only", "raw", PLAN, json.dumps(_envelope("PlanRequest", payload)))
    assert result.returncode == 0 and result.json()["solved"] is True, result
    planner.wait_for_log(r"more than a JointTrajectory's time can say; not published on lit/path")
    assert planner.running()
    _no_traceback(planner)


def test_an_episode_without_decisions_for_episode_timeout_is_abandoned(ros: RosSystem) -> None:
    """A planner that died mid-episode left its episode in the learner's memory and checkpoints
    for good; after ``episode_timeout`` s without a decision it is abandoned with a warning."""
    learner = ros.learner(episode_timeout=1.0, stats_period=0.2)
    _ready(learner)
    # Its time budget (0.2 s) doubled is shorter than episode_timeout: that is the limit.
    result = ros.call("--payload-only", "decide", "--no-probe", "--episode-id", "idle-1",
                      "--time-budget", "0.2")  # fmt: skip
    assert result.returncode == 0, result
    learner.wait_for_log(
        r"episode \S*idle-1 never ended \(no decision for 1 s\): its open steps are dropped",
        timeout=60.0,
    )
    result = ros.call("--payload-only", "decide", "--no-probe", "--episode-id", "idle-2")
    assert result.returncode == 0, result
    assert "rejected:" not in learner.text(), learner.tail()
    _no_traceback(learner)


def test_open_episodes_and_named_planners_are_bounded(ros: RosSystem) -> None:
    """A client sending each decision under a new source and episode grew the learner's memory
    (about 2 KB an episode until the idle sweep, hours later) and the provenance of every
    checkpoint and export without bound: beyond ``max_open_episodes`` the episode idle the
    longest is abandoned, and beyond ``max_sources`` planners the provenance names no more."""
    learner = ros.learner(max_open_episodes=2, max_sources=2, stats_period=0.2)
    _ready(learner)
    for n in range(3):
        payload = _decide_payload(episode_id=f"crowd-{n}")
        text = json.dumps(_envelope("DecideRequest", payload, source=f"/planner_{n}"))
        result = ros.call("--payload-only", "raw", DECIDE, text)
        assert result.returncode == 0, result
    learner.wait_for_log(
        r"episode /planner_0\|\S*\|crowd-0 never ended \(more than max_open_episodes 2 "
        r"episodes are open; 1 crowded out so far\)"
    )
    learner.wait_for_log(r"more than max_sources 2 planners sent experience")
    assert learner.running()
    _no_traceback(learner)


def test_a_learner_leaves_out_old_transitions_not_finite_and_refuses_networks_not_finite(
    ros: RosSystem,
) -> None:
    """A checkpoint of a learner from before the check at storing: its transitions with values
    that are not finite are left out with a warning, and the learner serves. One whose network
    is not finite would answer NaN: the node exits 2 with one line naming it."""
    import torch
    from lit_learner.config import LearnerConfig
    from lit_learner.core import LearnerCore

    core = LearnerCore(LearnerConfig(seed=0))
    for i in range(20):
        core.agents["B"].replay.add((0.1, 0.2, 0.3), 0.5, -0.01 * i, (0.2, 0.3, 0.4), False)
    state = core.state_dict()
    state["agents"]["B"]["replay"]["reward"][3] = np.nan
    old = ros.workdir / "old.pt"
    torch.save(state, old)
    learner = ros.learner(checkpoint=str(old))
    learner.wait_for_log(
        r"old\.pt: left out replay transitions holding values that are not finite \(B 1; ",
        timeout=NODE_START,
    )
    _ready(learner)
    result = ros.call("--payload-only", "decide", "--agent", "B")
    assert result.returncode == 0, result
    assert math.isfinite(result.json()["value"]), result
    assert ros.stop(learner, timeout=60.0) == 0, learner.tail()
    _no_traceback(learner)

    network = state["agents"]["psi_K"]["actor"]
    name = next(iter(network))
    network[name] = torch.full_like(network[name], float("inf"))
    broken = ros.workdir / "broken.pt"
    torch.save(state, broken)
    refused = ros.learner("refused", checkpoint=str(broken))
    assert refused.wait(timeout=NODE_START) == 2, refused.tail()
    assert re.search(
        rf"lit_learner_node: error: \S*broken\.pt: agent psi_K: the actor holds weights that are "
        rf"not finite: {re.escape(name)}; restore the file, or start anew",
        refused.text(),
    ), refused.tail()
    _no_traceback(refused)


# ---------------------------------------------------------------------- 6. domains


def _nice_values(pid: int) -> dict[int, int]:
    """Nice value of each thread of ``pid`` (field 19 of /proc/<pid>/task/<tid>/stat)."""
    values = {}
    for task in Path(f"/proc/{pid}/task").iterdir():
        fields = (task / "stat").read_text().rsplit(")", 1)[1].split()
        values[int(task.name)] = int(fields[16])  # fields after the name start at field 3
    return values


WRONG_AGENT_LEARNER = """
import rclpy
from diagnostic_msgs.srv import AddDiagnostics
from lit_msgs_json import Publisher
from lit_msgs_json.envelope import decode
from lit_planner.rosutil import service_qos

rclpy.init()
node = rclpy.create_node("wrong_agent_learner")
reply = Publisher("wrong_agent_learner", "fake")


def serve(request, response):
    message = decode(request.load_namespace)
    payload = message.payload
    response.success = True
    if message.name == "EpisodeEnd":
        response.message = reply.encode("EpisodeEndResponse", {
            "episode_id": payload["episode_id"], "transitions_stored": 0, "pending_updates": 0,
            "policy_version": 0, "episodes": 1})
        return response
    other = "psi_K" if payload["agent"] == "B" else "B"  # a B value for psi_K, and the reverse
    response.message = reply.encode("DecideResponse", {
        "agent": other, "episode_id": payload["episode_id"], "value": 100.0 if other == "B" else 5.0,
        "policy_version": 0, "explore": False})
    return response


node.create_service(AddDiagnostics, "/lit/learner/decide", serve, qos_profile=service_qos())
print("ready: wrong-agent learner", flush=True)
try:
    rclpy.spin(node)
except KeyboardInterrupt:
    pass
"""
"""A learner that answers every decision for the other agent."""


def test_a_learner_answer_for_another_agent_is_not_executed(ros: RosSystem) -> None:
    """A DecideResponse for another agent (or episode) than the request's was executed as it
    was: a psi_K request answered with a B value planned with psi_K = 15 (clamped), without a
    word. It is a fallback now, with a warning naming what was answered."""
    learner = ros.start("fake-learner", [sys.executable, "-c", WRONG_AGENT_LEARNER])
    learner.wait_for_log(r"ready:", timeout=NODE_START)
    recording = ros.recorder([EPISODE])
    planner = ros.planner(episodes=1, exit_when_done=True, **TRAINING)
    assert planner.wait(timeout=300.0) == 0, planner.tail()
    planner.wait_for_log(r"the learner answered for agent '(B|psi_K)' of episode", timeout=1.0)
    summary = recording.wait_until(
        EPISODE, lambda found: len(found) >= 1, timeout=30.0, what="the EpisodeSummary"
    )[0]
    assert summary["fallback_decisions"] == summary["learner_calls"] > 0, summary
    _no_traceback(planner)


def test_learner_trains_at_a_lower_priority_than_it_answers(ros: RosSystem) -> None:
    """Only the trainer thread is niced; the thread that answers decisions is not."""
    learner = ros.learner()
    _ready(learner)
    deadline = time.monotonic() + 30
    while 10 not in _nice_values(learner.pid).values() and time.monotonic() < deadline:
        time.sleep(0.1)
    values = _nice_values(learner.pid)
    assert sorted(values.values()).count(10) == 1, values
    assert values[learner.pid] == 0 and sum(v == 0 for v in values.values()) >= 2, values
    result = ros.call("decide", "--agent", "psi_K")
    assert result.returncode == 0, result


def test_domains_are_isolated(ros: RosSystem) -> None:
    """A planner in one ROS domain is invisible from another one; ``lit call --domain-id``
    reaches it from a shell whose ``$ROS_DOMAIN_ID`` is the other one."""
    planner = ros.planner()
    _ready(planner)
    other = ros.other_domain()
    assert other != ros.domain
    result = ros.call("--wait", "3", "plan", "--scenario", "np4", "--time", "0.1", domain=other)
    assert result.returncode == 2, result
    assert "not found" in result.stderr and f"ROS_DOMAIN_ID={other}" in result.stderr
    result = ros.call(
        "--wait", "30", "--payload-only", "plan", "--scenario", "np4", "--time", "0.1"
    )
    assert result.returncode == 0, result
    chosen = ("--domain-id", str(ros.domain), "--wait", "30", "--payload-only")
    result = ros.call(*chosen, "plan", "--scenario", "np4", "--time", "0.1", domain=other)
    assert result.returncode == 0, result


# ---------------------------------------------------------------------- 7. shutdown


def test_sigterm_cuts_a_long_query_short_and_answers_the_waiting_ones(ros: RosSystem) -> None:
    """A node asked to plan for 600 s used to finish that query before stopping, so lit up's grace
    ran out and it was killed. Now the running query ends at once and is answered with the best
    path found until then (status shutdown; it was an unavailable Error that threw the path
    away), and the queued one ``unavailable``; the node exits 0."""
    recording = ros.recorder(["/lit/solution"])
    planner = ros.planner()
    _ready(planner)
    # --wait 60: the default 15 s to find the service was not always enough on a loaded
    # machine, and the test then waited in vain for the solution.
    running = ros.call_start("--wait", "60", "--payload-only", "plan", "--scenario", "np8",
                             "--time", "600", "--request-id", "long")  # fmt: skip
    recording.wait_until(  # it runs: its first solution came
        "/lit/solution", lambda found: len(found) >= 1, timeout=120.0, what="a first solution",
        watch=[planner, running],
    )  # fmt: skip
    queued = ros.call_start("--wait", "60", "--payload-only", "plan", "--scenario", "np4",
                            "--time", "600", "--request-id", "queued")  # fmt: skip
    planner.wait_for_log(r"plan request queued waits behind 1", timeout=120.0)
    assert ros.stop(planner, signal.SIGTERM, timeout=60.0) == 0, planner.tail()
    result = finish_call(running, timeout=60.0)  # not the 600 s
    assert result.returncode == 0, result
    response = result.json()
    assert response["status"] == "shutdown", response
    assert response["message"].startswith("cut short by the planner node's shutdown after"), (
        response
    )
    assert "the best path found until then" in response["message"], response
    assert response["solved"] is True and response["path_valid"] is True, response
    assert response["time"] < 600.0 and len(response["path"]) >= 2, response
    assert response["cost"] <= response["c_init"], response
    result = finish_call(queued, timeout=60.0)
    assert result.returncode == 1, result
    error = result.json()
    assert error["code"] == "unavailable", error
    assert "the query was not started" in error["message"], error
    _no_traceback(planner)


def test_sigterm_answers_a_running_query_without_a_path_unavailable(
    ros: RosSystem, tmp_path: Path
) -> None:
    """A query cut short by the shutdown before it found any path (a wall across the world:
    there is none) is answered with an unavailable Error that says so."""
    planner = ros.planner()
    _ready(planner)
    walled = {"lower": [0, 0], "upper": [1, 1], "boxes": [{"lower": [0.45, 0], "upper": [0.55, 1]}],
              "start": [0.1, 0.5], "goal": [0.9, 0.5]}  # fmt: skip
    world_file = tmp_path / "walled.json"
    world_file.write_text(json.dumps(walled), encoding="utf-8")
    running = ros.call_start("--wait", "60", "--payload-only", "plan", "--world", str(world_file),
                             "--time", "600", "--request-id", "walled")  # fmt: skip
    planner.wait_for_log(r"plan request walled started", timeout=120.0)
    assert ros.stop(planner, signal.SIGTERM, timeout=60.0) == 0, planner.tail()
    result = finish_call(running, timeout=60.0)
    assert result.returncode == 1, result
    error = result.json()
    assert error["code"] == "unavailable", error
    assert re.search(
        r"\(unavailable\): the planner node is stopping; the query was cut short after \S+ s of "
        r"planning, before any path was found$",
        error["message"],
    ), error
    _no_traceback(planner)


def test_a_training_episode_cut_short_goes_to_the_learner_and_is_not_published(
    ros: RosSystem,
) -> None:
    """SIGTERM during a long training episode: the planner stops at once, the learner still gets
    the episode's end (as truncated: the state is not terminal), and no EpisodeSummary says it
    finished (``lit replay tensors`` would learn a terminal state from one)."""
    recording = ros.recorder([EPISODE, STATS])
    learner = ros.learner(checkpoint_every=1_000_000, checkpoint_period=1e6)
    _ready(learner)
    planner = ros.planner(episodes=1, **TRAINING | {"time_budget": 600.0})
    planner.wait_for_log(r"learner answered its first call", timeout=120.0)
    assert ros.stop(planner, signal.SIGTERM, timeout=60.0) == 0, planner.tail()
    assert re.search(
        r"training episode \S+ cut short by the shutdown; (the learner took its end as "
        r"truncated|its end was sent to the learner as truncated, without an answer)",
        planner.text(),
    ), planner.tail()
    assert "episodes done" not in planner.text(), planner.tail()  # it said "1 ... done"
    assert ros.stop(learner, signal.SIGTERM, timeout=60.0) == 0, learner.tail()
    # The final stats were published at the learner's shutdown; the recorder may still be writing
    # them (or the tick before them), so wait for stats that count the episode.
    final = recording.wait_until(
        STATS, lambda stats: bool(stats) and stats[-1]["episodes"] == 1, 60.0, "the final stats"
    )[-1]
    assert final["transitions"]["B"] + final["transitions"]["psi_K"] >= 1, final
    assert recording.payloads(EPISODE) == []
    _no_traceback(planner, learner)


def test_learner_stats_wait_for_their_subscribers(ros: RosSystem) -> None:
    """With ``wait_for_subscribers: 1`` the first stats a late subscriber (a recorder) hears are
    seq 0: ticks before it matched are not published (a demo's bag counted one as missing when
    the recorder matched the learner after its first tick). The other learner, without it, had
    published ticks by then: the test tells the two apart."""
    waiting = ros.learner(stats_period=0.05, wait_for_subscribers=1)
    eager = ros.learner(
        "eager",
        stats_period=0.05,
        service="/eager/decide",
        checkpoint=str(ros.workdir / "eager" / "checkpoint.pt"),
        export_dir=str(ros.workdir / "eager" / "tensors"),
        ros_namespace="/eager",
    )
    _ready(waiting, eager)
    time.sleep(1.0)  # ticks of both, before anyone listens
    recording = ros.recorder([STATS])
    sources = {"/lit_learner", "/eager/lit_learner"}
    recording.wait_until(
        STATS,
        lambda _: {m["source"] for m in recording.messages(STATS)} == sources,
        timeout=60.0,
        what="stats of both learners",
        watch=[waiting, eager],
    )
    first: dict[str, int] = {}
    for message in recording.messages(STATS):
        first.setdefault(message["source"], message["seq"])
    assert first["/lit_learner"] == 0, first
    assert first["/eager/lit_learner"] > 0, first
    assert "stats: 1 subscribers on /lit/learner/stats; publishing" in waiting.text()
    _no_traceback(waiting, eager)


def _quick_learner_checkpoint(path: Path) -> Path:
    """A fresh learner's checkpoint whose agents make a gradient step from their first
    transition on (a learner resumes its checkpoint's configuration): two short episodes train
    both. The learner's own warm-ups (500 and 10 000 transitions) take hundreds of episodes."""
    from lit_learner.config import AgentConfig, LearnerConfig
    from lit_learner.core import LearnerCore

    quick = {"warmup": 1, "batch_size": 1}
    core = LearnerCore(
        LearnerConfig(
            b=AgentConfig.batch_size_agent(**quick), k=AgentConfig.neighbour_agent(**quick)
        )
    )
    LearnerCore.write_checkpoint(core.checkpoint_state(), path)
    return path


def test_the_learner_exports_only_the_agents_that_trained(ros: RosSystem, tmp_path: Path) -> None:
    """An export before any gradient update writes no tensor (as `lit train`'s): the answer
    names the checkpoint copy and says why each agent was left out, and the tensors an earlier
    export of a learner node left in the folder are removed. It exported the initial actors,
    which the tensor policy played (psi_K about 9 where its fixed value is e). Tensors of
    anything else there (the shipped ones) are not the node's to replace or remove: it does not
    start, and an export refuses them."""
    exports = tmp_path / "exports"
    exports.mkdir()
    shipped = ("b_tensor.npy", "b_tensor.json", "k_tensor.npy", "k_tensor.json")
    for name in shipped:
        (exports / name).write_bytes((ROOT / "tensors" / name).read_bytes())
    refused = ros.learner("refused", export_dir=str(exports))
    assert refused.wait(timeout=NODE_START) == 1, refused.tail()
    assert (
        f"lit_learner_node: export_dir {exports} holds b_tensor.npy, k_tensor.npy, not a learner "
        "node's export (an export replaces and removes the tensor files there); choose another "
        "folder, or move them" in refused.text()
    ), refused.tail()
    assert sorted(path.name for path in exports.iterdir()) == sorted(shipped)

    for name in ("b_tensor.json", "k_tensor.json"):  # now an earlier export of a learner node
        sidecar = json.loads((exports / name).read_text(encoding="utf-8"))
        sidecar["provenance"] = {"exported_by": "lit_learner_node"}
        (exports / name).write_text(json.dumps(sidecar), encoding="utf-8")
    learner = ros.learner(export_dir=str(exports))
    _ready(learner)
    result = ros.call("export")
    assert result.returncode == 0, result
    answer = json.loads(result.stdout)
    assert answer == {
        "checkpoint": str(exports / "checkpoint.pt"),
        "left_out": {
            "B": "no tensor (no gradient update yet: 0 of the 500 transitions its updates wait "
            "for); the tensor policy keeps its fixed value (B = 100)",
            "psi_K": "no tensor (no gradient update yet: 0 of the 10000 transitions its updates "
            "wait for); the tensor policy keeps its fixed value (psi_K = e)",
        },
    }, answer
    assert sorted(path.name for path in exports.iterdir()) == ["checkpoint.pt"]
    learner.wait_for_log(
        rf"exported to {re.escape(str(exports))} \(request\): a checkpoint copy; B: no tensor",
        timeout=30,
    )

    (exports / "b_tensor.npy").write_bytes((ROOT / "tensors" / "b_tensor.npy").read_bytes())
    result = ros.call("export")
    assert result.returncode == 1, result
    assert result.stdout.startswith(f"export failed: export_dir {exports} holds b_tensor.npy, "), (
        result
    )
    assert sorted(path.name for path in exports.iterdir()) == ["b_tensor.npy", "checkpoint.pt"]
    assert learner.running()
    _no_traceback(learner, refused)


def test_the_learner_exports_after_max_episodes_and_on_request(
    ros: RosSystem, tmp_path: Path
) -> None:
    """With max_episodes the learner exports by itself once that many training episodes ended;
    an export folder it cannot write makes that export fail, and it is tried again until it
    works (it was not, until the shutdown). `lit call export`: success false with the reason
    (exit 1) while the folder cannot be written, the learner going on; then both tensors (both
    agents made gradient steps) with the node's provenance, and the answer names them."""
    exports = tmp_path / "exports"
    exports.write_text("a file where the export folder should be", encoding="utf-8")
    learner = ros.learner(
        checkpoint=str(_quick_learner_checkpoint(tmp_path / "checkpoint.pt")),
        export_dir=str(exports),
        max_episodes=2,
    )
    _ready(learner)
    result = ros.call("export")
    assert result.returncode == 1, result
    assert result.stdout.startswith("export failed:") and str(exports) in result.stdout, result
    decided = ros.call("--payload-only", "decide", "--agent", "B", "--measure", "0.3")
    assert decided.returncode == 0 and math.isfinite(decided.json()["value"]), decided

    planner = ros.planner(episodes=2, exit_when_done=True, **TRAINING)
    assert planner.wait(timeout=300.0) == 0, planner.tail()
    learner.wait_for_log(r"checkpoint or export is tried again", timeout=120.0)
    exports.unlink()
    learner.wait_for_log(r"exported to .* \(end of training\)", timeout=120.0)
    for name in ("b_tensor.npy", "k_tensor.npy"):
        _, sidecar = tensor_files.read_tensor(exports / name)
        assert sidecar.provenance["reason"] == "end of training", sidecar.provenance
        assert sidecar.provenance["episodes"] >= 2, sidecar.provenance
        assert sidecar.provenance["planners"] == ["/lit_planner"], sidecar.provenance
        assert sidecar.training["updates"] > 0, sidecar.training

    result = ros.call("export")
    assert result.returncode == 0, result
    paths = json.loads(result.stdout)
    assert set(paths) == {"B", "psi_K", "checkpoint"}, paths
    for key, name in (("B", "b_tensor.npy"), ("psi_K", "k_tensor.npy")):
        assert Path(paths[key]) == exports / name, paths
        values, sidecar = tensor_files.read_tensor(exports / name)
        assert values.shape == (101, 101, 101)
        assert sidecar.provenance["reason"] == "request", sidecar.provenance
    assert learner.running()
    _no_traceback(planner, learner)


def test_a_learner_shutting_down_answers_unavailable(ros: RosSystem) -> None:
    """Requests that reach the learner while it shuts down (checkpoint, export) are answered with
    an unavailable Error: they went unanswered, and a `lit call decide --repeat` waited out its
    --timeout and said "call N failed: None"."""
    recording = ros.recorder([STATS])
    learner = ros.learner(stats_period=0.2)
    _ready(learner)
    calls = ros.call_start("--timeout", "600", "--payload-only", "decide", "--repeat", "100000000")
    recording.wait_until(
        STATS, lambda found: any(p["decisions"] >= 50 for p in found), timeout=120.0,
        what="decisions answered", watch=[learner, calls],
    )  # fmt: skip
    assert ros.stop(learner, signal.SIGTERM, timeout=60.0) == 0, learner.tail()
    result = finish_call(calls, timeout=60.0)  # not the 600 s timeout
    assert result.returncode == 1, result
    error = result.json()
    assert error["code"] == "unavailable", error
    assert "the learner is shutting down" in error["message"], error
    assert error["request_schema"] == "DecideRequest", error
    assert "was answered with an error" in result.stderr, result
    _no_traceback(learner)


def test_sigterm_shuts_both_nodes_down_cleanly(ros: RosSystem) -> None:
    """SIGTERM mid-training: exit code 0, no processes left behind, a checkpoint written."""
    recording = ros.recorder([EPISODE])
    checkpoint = _checkpoint(ros)
    # No periodic checkpoint: the file can only come from the shutdown.
    learner = ros.learner(checkpoint_every=1_000_000, checkpoint_period=1e6)
    _ready(learner)
    planner = ros.planner(episodes=10_000, **TRAINING | {"decision_timeout": 0.5})
    recording.wait_until(
        EPISODE,
        lambda found: len(found) >= 1,
        timeout=120.0,
        what="a training episode",
        watch=[planner, learner],
    )
    assert not checkpoint.exists()
    nodes = {"planner": planner, "learner": learner}
    spawned = {name: children_of(node.pid) for name, node in nodes.items()}

    for name, node in nodes.items():  # planner first: its episode ends while the learner runs
        assert ros.stop(node, signal.SIGTERM, timeout=60.0) == 0, f"{name}:\n{node.tail()}"
        # Nothing it started lives on: nothing else in its session (orphans are adopted by
        # another parent, but keep the session), none of the children it had.
        assert session_members(node.pid) == [], f"{name} left processes behind"
        assert not set(spawned[name]) & live_pids(), f"{name}'s children {spawned[name]} live on"
    assert checkpoint.is_file()
    assert "checkpoint" in learner.text()
    # It made progress: exported on shutdown (the checkpoint copy alone: before its warm-up ends
    # no agent has a tensor to export).
    assert (ros.workdir / "learner" / "tensors" / "checkpoint.pt").is_file()
    _no_traceback(planner, learner)

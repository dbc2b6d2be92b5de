"""Tests of ``lit plan`` and ``lit demo`` as users run them: real processes, real planner runs."""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from cli_helpers import lit
from lit_planner.testing import DescendantWatch, read_until, reserve_ros_domain, run_watched

from lit_planner import scenarios
from lit_planner import tensor_files as tf

ROOT = Path(__file__).resolve().parents[2]

REQUIRED_FIELDS = {
    "status", "solved", "cost", "t_init", "c_init", "improvements", "path", "counters",
    "planner", "scenario", "seed", "policy", "time", "message", "decisions", "path_check",
}  # fmt: skip


def plan_json(*args: str, returncode: int = 0) -> dict[str, Any]:
    process = lit("plan", *args, "--json")
    assert process.returncode == returncode, process.stderr
    assert len(process.stdout.strip().splitlines()) == 1  # exactly one JSON object
    document: dict[str, Any] = json.loads(process.stdout)
    return document


def test_plan_json_litstar() -> None:
    doc = plan_json(
        "--scenario", "np4", "--planner", "litstar", "--policy", "fixed",
        "--iterations", "2000", "--seed", "7",
    )  # fmt: skip
    assert REQUIRED_FIELDS <= doc.keys()
    assert (doc["planner"], doc["policy"], doc["scenario"], doc["seed"]) == (
        "litstar", "fixed", "np4", 7,
    )  # fmt: skip
    assert doc["status"] == "exact_solution" and doc["solved"] is True
    assert doc["counters"]["iterations"] == 2000 and doc["counters"]["batches"] > 0
    improvements = doc["improvements"]
    assert all(isinstance(item, list) and len(item) == 2 for item in improvements)
    assert [doc["t_init"], doc["c_init"]] == improvements[0]
    assert doc["cost"] == improvements[-1][1]
    costs = [cost for _, cost in improvements]
    assert costs == sorted(costs, reverse=True)
    scenario = scenarios.get("np4")
    check = scenarios.check_path(scenario, doc["path"])
    assert check.ok and math.isclose(check.cost, doc["cost"], rel_tol=1e-9)
    assert doc["path_check"]["ok"] is True
    assert doc["optimal_cost"] == pytest.approx(scenario.optimal_cost)
    assert {d["kind"] for d in doc["decisions"]} == {"B"}
    # Same seed and iteration budget in another process: the same plan.
    again = plan_json(
        "--scenario", "np4", "--planner", "litstar-fixed", "--iterations", "2000", "--seed", "7",
    )  # fmt: skip
    assert again["path"] == doc["path"] and again["cost"] == doc["cost"]


def test_plan_json_ompl_baseline() -> None:
    doc = plan_json("--scenario", "np4", "--planner", "rrtconnect", "--time", "0.2", "--seed", "3")
    assert REQUIRED_FIELDS <= doc.keys()
    assert (doc["planner"], doc["policy"], doc["seed"], doc["time_budget"]) == (
        "rrtconnect", None, 3, 0.2,
    )  # fmt: skip
    assert doc["solved"] and doc["path_check"]["ok"]
    assert scenarios.check_path(scenarios.get("np4"), doc["path"]).ok


def test_plan_json_unsolved_uses_null() -> None:
    doc = plan_json("--scenario", "np4", "--iterations", "1", returncode=1)
    assert doc["status"] == "timeout" and doc["solved"] is False
    assert doc["cost"] is None and doc["t_init"] is None and doc["c_init"] is None
    assert doc["improvements"] == [] and doc["path"] == [] and doc["path_check"] is None


def test_plan_json_tensor_policy(tmp_path: Path) -> None:
    tf.write_tensor(
        tmp_path / "b_tensor.npy", tf.affine_test_tensor(*tf.AFFINE_TEST_COEFFICIENTS), "B"
    )
    doc = plan_json(
        "--scenario", "rrd4", "--instance", "0", "--planner", "litstar-tensor",
        "--tensors", str(tmp_path), "--interpolation", "nearest", "--iterations", "1500",
    )  # fmt: skip
    assert doc["policy"] == "tensor" and doc["scenario"] == "rrd4" and doc["instance"] == 0
    batch_decisions = [d for d in doc["decisions"] if d["kind"] == "B"]
    assert batch_decisions and all(d["policy"] == "tensor" for d in doc["decisions"])
    b_values = tf.affine_test_tensor(*tf.AFFINE_TEST_COEFFICIENTS)
    for decision in batch_decisions:  # B is rounded to a whole number of samples
        x = (decision["rho_global"], decision["rho_local_b"], decision["measure"])
        assert abs(decision["value"] - float(tf.lookup(b_values, x, "nearest"))) <= 0.5 + 1e-6


def test_plan_summary_is_readable() -> None:
    process = lit("plan", "--scenario", "wg4", "--iterations", "2000")
    assert process.returncode == 0, process.stderr
    assert "exact_solution: solved" in process.stdout
    assert "independent re-check passed" in process.stdout
    assert "optimum 0.6308" in process.stdout
    # The first solution is not counted as an improvement of itself.
    final = next(line for line in process.stdout.splitlines() if line.startswith("final"))
    assert final.endswith("the first solution"), final
    process = lit("plan", "--scenario", "np4", "--iterations", "20000")
    final = next(line for line in process.stdout.splitlines() if line.startswith("final"))
    assert re.search(r"the first solution improved [1-9]\d* time\(s\)$", final), final
    # OMPL calls every stop a timeout; with no time limit it was the iteration limit.
    for limits in (["--iterations", "1"], ["--iterations", "1", "--time", "5"]):
        process = lit("plan", "--scenario", "np4", *limits)
        assert process.returncode == 1, process.stderr
        assert "stopped before the time budget (iteration or batch limit): not solved" in (
            process.stdout
        )


def test_a_path_that_fails_the_recheck_exits_3(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Exit 3 followed path_check.valid (collisions only) while the summary's verdict and the
    node's path_valid follow ok: a path not ending at the goal printed FAILED and exited 0."""
    import argparse

    from lit_planner import plan_cli, planning

    real = planning.plan_interruptibly

    def not_at_the_goal(*args: Any, **kwargs: Any) -> dict[str, Any]:
        result = real(*args, **kwargs)
        result["path_check"] = {**result["path_check"], "ok": False, "ends_at_goal": False}
        return result

    monkeypatch.setattr(planning, "plan_interruptibly", not_at_the_goal)
    parser = argparse.ArgumentParser()
    plan_cli.add_arguments(parser)
    args = parser.parse_args(["--scenario", "np4", "--iterations", "2000"])
    assert plan_cli.run(args) == plan_cli.EXIT_PATH_INVALID
    assert "FAILED" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--scenario", "xx9"], "unknown scenario 'xx9'"),
        (["--planner", "eitstar"], "unknown planner 'eitstar'"),
        (["--policy", "learned"], "unknown policy 'learned'"),
        (["--policy", "external"], "external policy needs a callable"),
        (["--planner", "aitstar", "--policy", "fit"], "applies to litstar only"),
        (
            ["--policy", "tensor", "--tensors", "/nonexistent/tensors"],
            "no lookup tensors in /nonexistent/tensors (given); the folder does not exist",
        ),
        (["--planner", "bitstar", "--iterations", "5"], "stops on time only"),
        (["--seed", "-1"], "seed must be"),
        # OMPL's generator takes 0 as 1: silently the run of --seed 1.
        (["--planner", "rrtconnect", "--seed", "0"], "cannot take seed 0"),
        (["--iterations", "-5"], "--iterations must be a whole number"),
        (["--batches", "4294967296"], "--batches must be a whole number"),
        (["--policy", "fixed", "--interpolation", "nearest"], "are for the tensor policy"),
        (["--planner", "aitstar", "--tensors", str(ROOT / "tensors")], "not for aitstar"),
        (["--policy", "tensor", "--tensors", str(ROOT / "README.md")], "README.md: a file"),
    ],
)
def test_plan_bad_input_is_one_line(args: list[str], message: str) -> None:
    process = lit("plan", *args, "--json")
    assert process.returncode == 2
    assert process.stdout == ""
    lines = process.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("lit plan: ") and message in lines[0]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--planners", "foo"], "no planner 'foo'; expected one of litstar-tensor, litstar-fit"),
        (["--planners", "litstar"], "no planner 'litstar'; expected one of litstar-tensor"),
        (["--scenarios", "xx9"], "unknown scenario 'xx9': expected <family><dim> with"),
        (["--scenarios", "rrd4/5"], "give the instance with --instance"),
    ],
)
def test_bench_bad_input_suggests_only_what_bench_takes(
    tmp_path: Path, args: list[str], message: str
) -> None:
    """The hints came from lit plan's lists: 'litstar' (which lit bench then refused as not one
    of its planners) and the example 'rrd8/3' (refused: the instance goes in --instance)."""
    process = lit("bench", *args, "--out", str(tmp_path / "out"), "--no-bag")
    assert process.returncode == 2 and process.stdout == ""
    lines = process.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("lit bench: ") and message in lines[0], lines
    assert "rrd8/3" not in lines[0] and "litstar," not in lines[0]
    assert not (tmp_path / "out").exists()


def _close(shown: Any, actual: Any) -> bool:
    """Equal, real numbers to 1e-12 (an OMPL built with fused multiply-adds differs in their last
    bits), everything else (counters, flags) exactly, through lists and objects."""
    if isinstance(shown, float) or isinstance(actual, float):
        return (
            isinstance(shown, int | float)
            and isinstance(actual, int | float)
            and math.isclose(shown, actual, rel_tol=1e-12, abs_tol=1e-15)
        )
    if isinstance(shown, list) and isinstance(actual, list):
        return len(shown) == len(actual) and all(map(_close, shown, actual))
    if isinstance(shown, dict) and isinstance(actual, dict):
        return shown.keys() == actual.keys() and all(_close(shown[k], actual[k]) for k in shown)
    return type(shown) is type(actual) and shown == actual


def test_the_readme_json_example_is_what_lit_plan_gives_apart_from_the_times() -> None:
    """The README calls its `lit plan --json` example repeatable exactly apart from the times;
    a change of the search (fewer iterations to the first solution) left five of its numbers
    stale. Every value but the times, and the shortened path and decisions, is compared."""
    command = "./lit plan --scenario np8 --planner litstar --policy fixed --iterations 3000 --seed 7 --json"
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    block = readme.split(f"$ {command}\n```\n```json\n", 1)[1].split("\n```", 1)[0]
    shown = json.loads(block)
    process = lit(*command.split()[1:])
    assert process.returncode == 0, process.stderr
    actual = json.loads(process.stdout)
    times = {"t_init", "time"}
    for key, value in shown.items():
        if key in times:
            continue
        if key == "improvements":  # [time, cost] pairs
            assert _close([c for _, c in value], [c for _, c in actual[key]])
        elif key == "path":  # shortened: its ends
            assert _close([value[0], value[-1]], [actual[key][0], actual[key][-1]])
        elif key == "decisions":  # shortened: its first
            assert _close(
                {k: v for k, v in value[0].items() if k != "time"},
                {k: v for k, v in actual[key][0].items() if k != "time"},
            )
        else:
            assert _close(value, actual[key]), (key, value, actual[key])
    assert set(shown) == set(actual)


def test_seed_0_plans_litstar_without_ompls_warning() -> None:
    """LIT* takes seed 0 (its own generator); OMPL's global one warned that it used 1 instead."""
    process = lit("plan", "--seed", "0", "--iterations", "200", "--json")
    assert process.returncode in (0, 1), process.stderr
    assert json.loads(process.stdout)["seed"] == 0
    assert "seed cannot be 0" not in process.stderr, process.stderr


def test_every_command_says_when_it_cannot_write_its_answer(tmp_path: Path) -> None:
    """An answer that could not be written (a full disk) was a traceback and exit 1, which lit
    plan uses for "not solved"; --help went through argparse, which ignores the write error
    (exit 0, nothing said); lit replay turned it into its generic error, and replay bench then removed the whole
    outputs it had written. A closed standard output (`>&-`) stays Python's no-op."""
    expected = "cannot write to standard output: [Errno 28] No space left on device"
    out = tmp_path / "replayed"
    for args, prefix in (
        (["plan", "--iterations", "200"], "lit plan"),
        (["--help"], "lit"),
        (["plan", "--help"], "lit"),
        (["replay", "info", str(ROOT / "bags/samples/bench_np4")], "lit replay"),
        (
            ["replay", "bench", str(ROOT / "bags/samples/bench_np4"), "--out", str(out)],
            "lit replay",
        ),
    ):
        with open("/dev/full", "w") as full:  # a device, written as a shell would
            written = subprocess.run(
                [sys.executable, "-m", "lit_planner.cli", *args],
                stdout=full, stderr=subprocess.PIPE, text=True, timeout=300, check=False,
            )  # fmt: skip
        assert written.returncode == 2, (args, written.stderr)
        assert written.stderr.splitlines()[-1] == f"{prefix}: {expected}", (args, written.stderr)
    assert (out / "summary.md").is_file()  # the outputs were whole: kept
    closed = subprocess.run(
        ["bash", "-c", f'exec "{sys.executable}" -m lit_planner.cli tensors info >&-'],
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    assert closed.returncode == 0 and "Traceback" not in closed.stderr, closed.stderr


def test_plan_offers_only_the_policies_it_takes() -> None:
    """``external`` needs a callable: an unknown policy's message must not offer it."""
    process = lit("plan", "--policy", "foo", "--json")
    assert process.returncode == 2 and process.stdout == ""
    assert process.stderr == "lit plan: unknown policy 'foo'; expected one of fixed, fit, tensor\n"


def test_ctrl_c_stops_lit_plan_during_its_query() -> None:
    """Ctrl-C 3 s into a 600 s query ends it (exit 130): Python's handler could only run once
    the core returned, so lit plan used to plan out its whole budget first."""
    process = subprocess.Popen(
        [sys.executable, "-m", "lit_planner.cli", "plan", "--scenario", "np8", "--time", "600"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        with pytest.raises(subprocess.TimeoutExpired):
            process.wait(timeout=3.0)  # set up and planning by then
        process.send_signal(signal.SIGINT)
        _, err = process.communicate(timeout=120)  # far short of the budget
        assert process.returncode == 130, err
        assert "lit plan: interrupted" in err and "Traceback" not in err, err
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()


LONG_BENCH = ["bench", "--scenarios", "np2", "--planners", "litstar-fixed", "--runs", "1",
              "--time-scale", "1e4", "--no-bag"]  # fmt: skip
"""A bench of one LIT* run of about 1500 s (np2: 0.15 s at time scale 1)."""


@pytest.mark.parametrize(
    ("command", "signum"),
    [
        (["plan", "--scenario", "np8", "--time", "600"], signal.SIGTERM),
        (LONG_BENCH, signal.SIGINT),
        (LONG_BENCH, signal.SIGTERM),
        (["crosscheck", "--scenarios", "np2", "--runs", "1", "--time", "600"], signal.SIGTERM),
    ],
    ids=["plan-sigterm", "bench-sigint", "bench-sigterm", "crosscheck-sigterm"],
)
def test_a_signal_stops_a_planning_command_during_its_query(
    tmp_path: Path, command: list[str], signum: int
) -> None:
    """Ctrl-C or ``kill PID`` a few seconds into a query of 600 s or more ends the command
    (exit 130, "interrupted"): lit bench and lit crosscheck planned out the run's whole budget
    first (their Python handler could only run once the core returned), and SIGTERM ended lit
    plan and lit crosscheck at once, without a word."""
    if command[0] == "bench":
        command = [*command, "--out", str(tmp_path / "out")]
    process = subprocess.Popen(
        [sys.executable, "-m", "lit_planner.cli", *command],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        if command[0] == "bench":  # its run plans right after this line (not in its imports)
            read_until(process.stderr, "lit bench: writing to")
            time.sleep(2.0)
        else:
            with pytest.raises(subprocess.TimeoutExpired):
                process.wait(timeout=5.0)  # set up and planning by then
        process.send_signal(signum)
        _, err = process.communicate(timeout=120)  # far short of the budget
        assert process.returncode == 130, err
        assert f"lit {command[0]}: interrupted" in err and "Traceback" not in err, err
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()


def test_sigterm_to_lit_crosscheck_ends_its_ompl_worker(tmp_path: Path) -> None:
    """``kill PID`` while the OMPL 2.0.1 worker plans: the worker ends with lit crosscheck, and
    its temporary folder goes (the worker planned on as an orphan, its folder left behind)."""
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    process = subprocess.Popen(
        [sys.executable, "-m", "lit_planner.cli", "crosscheck", "--scenarios", "np2", "--runs",
         "1", "--time", "2"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env=dict(os.environ, TMPDIR=str(scratch)),
    )  # fmt: skip
    watch = DescendantWatch(process.pid)
    try:
        worker = None
        for _ in range(1200):  # LIT*'s 2 s, then the worker
            worker = next((pid for pid, _ in watch.seen if _is_ompl2_worker(pid)), None)
            if worker is not None or process.poll() is not None:
                break
            time.sleep(0.05)
        assert worker is not None, process.communicate(timeout=60)
        process.send_signal(signal.SIGTERM)
        _, err = process.communicate(timeout=120)
        assert process.returncode == 130, err
        assert "lit crosscheck: interrupted" in err and "Traceback" not in err, err
        assert watch.alive() == []
        assert list(scratch.iterdir()) == []
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
        watch.kill()


def _is_ompl2_worker(pid: int) -> bool:
    try:
        return b"lit_planner.ompl2.crosscheck" in Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return False


def test_demo_local_plans_once_in_this_process_without_ros(tmp_path: Path) -> None:
    """`lit demo --local`: one query of the default scenario in-process, its summary with the
    independent re-check, exit 0; no process started, no bag written."""
    process = run_watched(
        [sys.executable, "-m", "lit_planner.cli", "demo", "--local", "--seed", "7"],
        cwd=tmp_path, timeout=300,
    )  # fmt: skip
    assert process.returncode == 0, process.stderr
    assert f"LIT* demo: litstar on {scenarios.DEFAULT_SCENARIO}" in process.stdout
    assert "status     exact_solution: solved" in process.stdout, process.stdout
    assert "seed 7" in process.stdout and "independent re-check passed" in process.stdout
    assert not list(tmp_path.iterdir()) and not process.started  # no run folder, bag or process


def test_demo_solves_the_default_scenario(tmp_path: Path) -> None:
    # A free domain of its own: lit test holds the run's domain, and the demo claims the one it
    # runs on (found free here, then released to the demo).
    domain, claim = reserve_ros_domain(range(101, 233))
    if claim is not None:
        claim.close()
    # Its nodes run in sessions of their own: every one it started is ended by PID afterwards.
    process = run_watched(
        [sys.executable, "-m", "lit_planner.cli", "demo", "--out", str(tmp_path), "--domain-id",
         str(domain)],
        env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST"), timeout=600,
    )  # fmt: skip
    assert process.returncode == 0, process.stderr
    # Two ROS processes trained over ROS, the plan service answered, the bag accounts for all.
    assert "4 episodes over ROS" in process.stdout
    # Each training episode's progress line, also when summaries arrive together.
    progress = re.findall(r"^    episode (\d)/4: ", process.stdout, re.MULTILINE)
    assert progress == ["1", "2", "3", "4"], process.stdout
    assert "0 messages missing" in process.stdout
    (bag,) = tmp_path.glob("*-bag")
    assert (bag / "metadata.yaml").is_file()
    info = lit("replay", "info", str(bag))
    assert info.returncode == 0, info.stderr
    assert "/lit/observation" in info.stdout and "no gaps" in info.stdout
    table = lit("replay", "bench", str(bag), "--out", str(tmp_path / "replay"))
    assert table.returncode == 0, table.stderr
    assert "| training | " in table.stdout, table.stdout
    assert "| service | np8 | litstar | tensor | 0.4 s | its limits | 3 | 3 |" in table.stdout
    assert "solved" in process.stdout
    assert scenarios.get(scenarios.DEFAULT_SCENARIO).description in process.stdout
    for words in ("t_init", "c_init", "ratio", "the first solution", "batches", "collision checks",
                  "fully checked by the forward search", "re-check passed"):  # fmt: skip
        assert words in process.stdout
    # the effort to the first solution, from the PlanResponse (version 2)
    assert re.search(r"^checks .* collision checks, \d+ up to the first solution$", process.stdout,
                     re.MULTILINE), process.stdout  # fmt: skip


@contextlib.contextmanager
def _demo(
    tmp_path: Path, *options: str, program: str | None = None
) -> Iterator[tuple[subprocess.Popen[str], DescendantWatch]]:
    """``lit demo --out tmp_path OPTIONS`` (``program``, run with ``python -c``, in place of the
    ``lit`` command if given) in a free domain and a session of its own, and a watch over the
    processes it starts (its nodes run in sessions of their own); all ended afterwards."""
    domain, claim = reserve_ros_domain(range(101, 233))
    if claim is not None:
        claim.close()
    command = ["-m", "lit_planner.cli"] if program is None else ["-c", program]
    process = subprocess.Popen(
        [sys.executable, *command, "demo", "--out", str(tmp_path), "--domain-id", str(domain),
         *options],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST"),
        start_new_session=True,
    )  # fmt: skip
    watch = DescendantWatch(process.pid)
    try:
        yield process, watch
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
        watch.kill()


def test_ctrl_c_stops_the_demo_and_reports_what_it_kept(tmp_path: Path) -> None:
    """Ctrl-C during training: the nodes are stopped in order, the bag is summarised and the
    processes' exits printed, exit 130 (it used to print 'lit demo: ; stopping the nodes')."""
    with _demo(tmp_path, "--training-episodes", "100000") as (process, watch):
        assert process.stdout is not None
        # training under way: the first episode's progress line
        seen = read_until(process.stdout, "    episode 1/100000:", timeout=300)
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=120)
        out = "".join(seen) + out
        assert process.returncode == 130, out + err
        assert "lit demo: interrupted; stopping the nodes" in err and "Traceback" not in err
        (stopped,) = re.findall(r"^Processes stopped: (.*);", out, re.MULTILINE)
        assert sorted(stopped.split(", ")) == [
            "learner exit 0", "planner exit 0", "recorder exit 0",
        ], out  # fmt: skip
        assert re.search(r"0 messages missing", out), out
        assert len(watch.seen) >= 3 and not watch.alive(), watch.alive()  # no node left behind


# A demo whose client fails with an error the demo does not expect, once training is under way.
_FAILING_DEMO = """
import sys
from lit_planner import cli, demo

original = demo._Client.wait_episodes

def wait_then_fail(self, count, timeout):
    original(self, 1, timeout)
    raise ValueError("injected by the test")

demo._Client.wait_episodes = wait_then_fail
sys.exit(cli.main(sys.argv[1:]))
"""


def test_an_unexpected_error_in_the_demo_still_stops_the_nodes_in_order(tmp_path: Path) -> None:
    """Not one of the errors the demo reports (a bug, say): it surfaces as a traceback, and the
    nodes are still stopped in order: the learner saves its checkpoint, the recorder closes the
    bag, and no process is left behind."""
    demo = _demo(tmp_path, "--training-episodes", "100000", program=_FAILING_DEMO)
    with demo as (process, watch):
        out, err = process.communicate(timeout=300)
        assert process.returncode == 1, out + err
        assert "ValueError: injected by the test" in err, err
        assert "    episode 1/1:" in out, out  # the patched wait's count
        assert len(watch.seen) >= 3 and not watch.alive(), watch.alive()  # no node left
        checkpoints = list(tmp_path.glob("**/learner/checkpoint.pt"))
        assert checkpoints, sorted(str(p) for p in tmp_path.rglob("*"))
        (bag,) = tmp_path.glob("*-bag")
        info = lit("replay", "info", str(bag))  # closed: its metadata written
        assert info.returncode == 0 and (bag / "metadata.yaml").is_file(), info.stderr
        assert re.search(r"/lit/episode from /lit_planner .*no gaps", info.stdout), info.stdout


# A demo whose planner node is killed (SIGKILL) 3 s into its first inference plan.
_PLANNER_DIES_DEMO = """
import sys, threading
from lit_planner import cli, demo

original = demo._Client.plan

def plan_while_the_planner_is_killed(self, payload):
    planner = self.system.children["planner"].process
    threading.Timer(3.0, planner.kill).start()
    return original(self, payload)

demo._Client.plan = plan_while_the_planner_is_killed
sys.exit(cli.main(sys.argv[1:]))
"""


def test_a_planner_that_dies_while_planning_ends_the_demo(tmp_path: Path) -> None:
    """The demo waited 600 s for the answer of a planner node that had died mid-plan; now it
    notices within a moment, says so and stops the other nodes in order."""
    demo = _demo(tmp_path, "--training-episodes", "0", "--time", "300", program=_PLANNER_DIES_DEMO)
    with demo as (process, watch):
        out, err = process.communicate(timeout=240)  # the planner's plan alone would take 300 s
        assert process.returncode == 1, out + err
        assert "lit demo: the planner node exited while planning; stopping" in err, err
        assert "Traceback" not in err, err
        (stopped,) = re.findall(r"^Processes stopped: (.*);", out, re.MULTILINE)
        assert sorted(stopped.split(", ")) == [
            "learner exit 0", "planner exit -9", "recorder exit 0",
        ], out  # fmt: skip
        assert len(watch.seen) >= 3 and not watch.alive(), watch.alive()


def test_an_untrained_tensor_is_named_when_the_tensor_policy_plays_it(tmp_path: Path) -> None:
    """A learner's export of agents without a gradient update (a run stopped before its psi_K
    phase) was played without a word: psi_K about 9 where a folder without the file gives e.
    `lit tensors info` marked it; `lit plan` now says so too, and plans on."""
    from lit_learner.config import LearnerConfig
    from lit_learner.core import LearnerCore

    LearnerCore(LearnerConfig(seed=0)).export_tensors(tmp_path, {"note": "untrained"})
    planned = lit("plan", "--scenario", "np4", "--policy", "tensor", "--tensors", str(tmp_path),
                  "--iterations", "300")  # fmt: skip
    assert planned.returncode in (0, 1), planned.stderr
    for name in ("b_tensor.npy", "k_tensor.npy"):
        assert f"lit plan: warning: {tmp_path / name} is UNTRAINED (initial weights)" in (
            planned.stderr
        ), planned.stderr
    shipped = lit("plan", "--scenario", "np4", "--policy", "tensor", "--iterations", "300",
                  "--tensors", str(Path(__file__).resolve().parents[2] / "tensors"))  # fmt: skip
    assert "warning" not in shipped.stderr, shipped.stderr

"""System test: `lit bench` as a user runs it, through the repository's `./lit` wrapper.

A tiny real benchmark (np4, two planners, two runs, np4's full 0.12 s budget) must write every
output. One assertion depends on speed, with a wide margin: a LIT* run solves np4 (in a few ms of
LIT*'s own clock, which leaves out the time it is not running, against the 0.12 s budget).
"""

from __future__ import annotations

import json
import os
import re
import sqlite3
import subprocess
from pathlib import Path
from typing import Any

import pytest

from lit_msgs_json import codec

ROOT = Path(__file__).resolve().parents[1]
PLANNERS = ("litstar-fixed", "aitstar")


def _lit(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    full_env = dict(os.environ, LIT_SKIP_SETUP="1", ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    full_env.update(env or {})
    return subprocess.run(
        [str(ROOT / "lit"), *args],
        cwd=ROOT,
        env=full_env,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )


@pytest.fixture(scope="module")
def bench_run(
    tmp_path_factory: pytest.TempPathFactory,
) -> tuple[Path, subprocess.CompletedProcess[str]]:
    out = tmp_path_factory.mktemp("bench") / "tmp"
    no_tensors = tmp_path_factory.mktemp("no_tensors")
    result = _lit(
        "bench",
        "--scenarios", "np4",
        "--planners", ",".join(("litstar-tensor", *PLANNERS)),
        "--runs", "2",
        "--out", str(out),
        "--bag-dir", str(out.parent / "bags"),
        env={"LIT_TENSORS": str(no_tensors)},
    )  # fmt: skip
    return out, result


def test_bench_writes_every_output(
    bench_run: tuple[Path, subprocess.CompletedProcess[str]],
) -> None:
    out, result = bench_run
    assert result.returncode == 0, result.stderr
    for name in ("summary.json", "summary.md", "runs.jsonl", "plots/np4.png", "plots/np4.pdf"):
        assert (out / name).is_file(), name
    assert (out / "plots/np4.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (out / "plots/np4.pdf").read_bytes()[:5] == b"%PDF-"
    # The Planner Arena database, made from OMPL benchmark logs in a separate process.
    assert (out / "arena" / "np4.log").is_file()
    with sqlite3.connect(out / "benchmark.db") as db:
        runs = db.execute("SELECT COUNT(*) FROM runs").fetchone()[0]
        planners = {row[0] for row in db.execute("SELECT name FROM plannerConfigs")}
    assert runs == 4
    assert len(planners) == 2
    assert "planning time alone: 2 runs x 2 planners" in result.stderr
    assert "| np4 |" in result.stdout and "## Every planner" in result.stdout


def test_bench_records_same_seeds_and_valid_paths(
    bench_run: tuple[Path, subprocess.CompletedProcess[str]],
) -> None:
    out, _ = bench_run
    lines = (out / "runs.jsonl").read_text(encoding="utf-8").splitlines()
    records = [codec.loads("BenchRun", line) for line in lines]
    assert sorted((r["planner"], r["run"], r["seed"]) for r in records) == sorted(
        (p, run, run + 1) for p in PLANNERS for run in (0, 1)
    )
    # LIT* finds np4's first solution in a few ms of its own clock (which leaves out the time
    # it is not running), far inside the 0.12 s budget: the checks below are not left without a
    # solved run.
    assert any(r["solved"] for r in records if r["planner"] == "litstar-fixed")
    for record in records:
        assert record["instance"] == 0 and record["time_budget"] == pytest.approx(0.12)
        if record["solved"]:
            assert record["path_valid"] is True and record["path"]
            assert record["improvements"][0] == [record["t_init"], record["c_init"]]
            assert 0 < record["checks_init"] <= record["counters"]["validity_checks"]
        else:
            assert record["checks_init"] is None


def test_bench_summary_is_complete_and_names_the_skipped_tensor_planner(
    bench_run: tuple[Path, subprocess.CompletedProcess[str]],
) -> None:
    out, result = bench_run
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    codec.validate("BenchSummary", summary)
    assert summary["config"]["planners"] == list(PLANNERS)
    assert [s["planner"] for s in summary["skipped"]] == ["litstar-tensor"]
    assert "litstar-tensor skipped: no trained tensors (the tensor policy found no lookup " in (
        result.stderr
    )
    assert "(from $LIT_TENSORS)" in result.stderr  # the folder it looked in, and why there
    assert "litstar-tensor skipped: no trained tensors" in (out / "summary.md").read_text()
    assert summary["comparisons"]["litstar"] == "litstar-fixed"
    assert summary["machine"]["cores"] >= 1 and summary["versions"]["python"]
    assert summary["command"]["argv"][:2] == ["lit", "bench"]
    assert len(summary["runs"]) == 4 and all("path" not in r for r in summary["runs"])
    np4 = summary["scenarios"]["np4"]
    assert set(np4["planners"]) == set(PLANNERS) and set(np4["curves"]) == set(PLANNERS)
    assert len(np4["curves"]["aitstar"]["success"]) == len(np4["time_grid"])
    assert np4["planners"]["aitstar"]["t_init"]["ci"] is None  # 2 runs: no 99% interval


def test_bench_rejects_bad_input(tmp_path: Path) -> None:
    result = _lit(
        "bench", "--planners", "litstar-fixed,nosuchplanner", "--out", str(tmp_path / "x")
    )
    assert result.returncode == 2 and "nosuchplanner" in result.stderr
    assert "Traceback" not in result.stderr
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "keep.txt").write_text("mine")
    result = _lit("bench", "--quick", "--out", str(tmp_path / "full"))
    assert result.returncode == 2 and "exists and is not empty" in result.stderr
    for option in ("--scenarios", "--planners"):
        result = _lit("bench", option, " ", "--out", str(tmp_path / "y"))
        assert result.returncode == 2 and "need at least one scenario" in result.stderr
    result = _lit("bench", "--time-scale", "1e12", "--out", str(tmp_path / "w"))
    assert result.returncode == 2 and "Traceback" not in result.stderr, result.stderr
    assert re.search(r"--time-scale 1e\+12 gives budgets up to .* the 1e\+09 s", result.stderr)
    # A budget scaled to (almost) nothing: a traceback from the time grid after all the runs.
    result = _lit("bench", "--time-scale", "1e-320", "--out", str(tmp_path / "tiny"))
    assert result.returncode == 2 and "Traceback" not in result.stderr, result.stderr
    assert "less than the 1e-06 s --time-scale allows" in result.stderr, result.stderr
    assert not (tmp_path / "tiny").exists()
    (tmp_path / "empty").mkdir()
    result = _lit(
        "bench", "--planners", "litstar-tensor", "--tensors", str(tmp_path / "empty"),
        "--out", str(tmp_path / "z"),
    )  # fmt: skip
    assert result.returncode == 2, result.stderr
    assert f"found no lookup tensors in {tmp_path / 'empty'} (given)" in result.stderr
    # Skipped (the folder was not given), and nothing else to run: the reason comes with the
    # refusal (it was printed only once a configuration stood: never here).
    result = _lit(
        "bench", "--planners", "litstar-tensor", "--out", str(tmp_path / "z"),
        env={"LIT_TENSORS": str(tmp_path / "empty")},
    )  # fmt: skip
    assert result.returncode == 2, result.stderr
    assert "none of the requested planners can run: litstar-tensor skipped: no trained" in (
        result.stderr
    )
    result = _lit(
        "bench", "--planners", "litstar-fit,rrtconnect", "--tensors", str(tmp_path / "empty"),
        "--out", str(tmp_path / "t"),
    )  # fmt: skip  # --tensors with no planner that reads them was silently ignored
    assert result.returncode == 2, result.stderr
    assert "--tensors is for litstar-tensor, which is not among the planners" in result.stderr
    assert not (tmp_path / "y").exists() and not (tmp_path / "z").exists()
    assert not (tmp_path / "t").exists()
    # Checked before any run: --instance -1 failed only when the summary was written.
    result = _lit("bench", "--scenarios", "np4", "--instance", "-1", "--out", str(tmp_path / "i"))
    assert result.returncode == 2 and "--instance must be 0 or more" in result.stderr
    (tmp_path / "file").write_text("")
    result = _lit("bench", "--scenarios", "np4", "--out", str(tmp_path / "file" / "sub"))
    assert result.returncode == 2, result.stderr
    assert f"{tmp_path / 'file'} is a file, not a folder" in result.stderr
    assert "Traceback" not in result.stderr


def test_bench_times_lit_star_first_solutions_repeatedly(tmp_path: Path) -> None:
    """--t-init-repeats K: each solved LIT* run's first solution is timed K times (the run, then
    reruns stopped at the iteration that found it) and t_init is the smallest; the rest of the
    record is the full run's. OMPL planners, whose reruns are other searches, are refused."""
    out = tmp_path / "repeats"
    result = _lit(
        "bench", "--scenarios", "np4", "--planners", "litstar-fit,litstar-fixed", "--runs", "2",
        "--time-scale", "0.25", "--t-init-repeats", "3", "--out", str(out), "--no-bag",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert "and 2 reruns to each first solution" in result.stderr
    records = [
        codec.loads("BenchRun", line)
        for line in (out / "runs.jsonl").read_text(encoding="utf-8").splitlines()
    ]
    assert len(records) == 4 and any(record["solved"] for record in records)
    for record in filter(lambda record: record["solved"], records):
        runs = record["t_init_runs"]
        assert len(runs) == 3 and record["t_init"] == min(runs)
        assert record["improvements"][0] == [runs[0], record["c_init"]]  # the full run's curve
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    codec.validate("BenchSummary", summary)
    assert summary["config"]["t_init_repeats"] == 3
    assert "the smallest of 3 timings of its first solution" in result.stdout

    for planners, repeats, message in (
        ("litstar-fit,bitstar", "2", "benchmark those without it"),
        ("litstar-fit", "0", "--t-init-repeats must be at least 1, got 0"),
    ):
        refused = _lit(
            "bench", "--planners", planners, "--t-init-repeats", repeats,
            "--out", str(tmp_path / "refused"), "--no-bag",
        )  # fmt: skip
        assert refused.returncode == 2 and message in refused.stderr, refused.stderr
        assert not (tmp_path / "refused").exists()


def test_reruns_stop_at_the_first_solution_and_must_repeat_it(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The reruns run to the iteration that found the first solution with no time limit; they
    must repeat the search: a record whose first solution they do not reproduce (here: a
    tampered cost) is refused rather than given a smallest time of unlike runs. The record's
    t_init is the smallest time, wherever it is."""
    from lit_planner.bench import runner
    from lit_planner.errors import PlannerError

    from lit_planner import planning, scenarios

    problem = scenarios.get("np4")
    result = planning.plan(problem, "litstar-fit", time=0.1, seed=3, check_path=False)
    assert result["solved"] and result["iteration_init"] >= 1
    policy = runner.benchmark_policies(["litstar-fit"])["litstar-fit"]
    options = {"repeats": 2, "seed": 3, "policy": policy}
    calls: list[dict[str, object]] = []
    real_plan = planning.plan

    def spy(*args: object, **kwargs: object) -> dict[str, object]:
        calls.append(kwargs)
        return real_plan(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(planning, "plan", spy)
    times = runner.time_first_solution(result, problem, "litstar-fit", **options)
    assert times is not None and len(times) == 2 and times[0] == result["t_init"]
    assert [(c["max_iterations"], c["time"], c["seed"], c["policy"]) for c in calls] == [
        (result["iteration_init"], None, 3, policy)
    ]
    record = runner.make_record(
        result, planner="litstar-fit", run=0, order=0, budget=0.1, wall_time=0.1,
        scenario=problem, params={}, t_init_runs=[0.003, 0.001, 0.002],
    )  # fmt: skip
    assert record["t_init"] == 0.001 and record["t_init_runs"] == [0.003, 0.001, 0.002]
    assert (
        runner.time_first_solution(result, problem, "litstar-fit", **options | {"repeats": 1})
        is None
    )
    tampered = dict(result, c_init=result["c_init"] * 1.5)
    with pytest.raises(PlannerError, match="not deterministic"):
        runner.time_first_solution(tampered, problem, "litstar-fit", **options)


def test_a_benchmark_reads_its_tensors_once(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """Each LIT* policy object is made once per benchmark and reused by every run and rerun, so
    the tensor files are read (and the caches refilled) before the first run only, not before
    every timed run; the runs still use the tensors (their policy is ``tensor``)."""
    from lit_planner.bench import runner

    from lit_planner import planning

    loads: list[str] = []
    policies: list[object] = []
    real_load, real_plan = planning.load_tensor, planning.plan

    def counting_load(path: Path, output: str) -> object:
        loads.append(output)
        return real_load(path, output)

    def spy_plan(*args: object, **kwargs: object) -> dict[str, object]:
        policies.append(args[2] if len(args) > 2 else kwargs.get("policy"))
        return real_plan(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(planning, "load_tensor", counting_load)
    monkeypatch.setattr(planning, "plan", spy_plan)
    shipped = Path(__file__).resolve().parents[1] / "tensors"
    config = runner.BenchConfig(
        ("np4",),
        ("litstar-tensor", "litstar-fit"),
        3,
        time_scale=0.5,
        tensors_dir=shipped,
        t_init_repeats=2,
    )
    with open(os.devnull, "w") as sink:
        records = runner.run_benchmark(config, progress_file=sink)
    assert sorted(loads) == ["B", "psi_K"]  # the shipped pair, once
    assert len(records) == 6 and {r["policy"] for r in records} == {"tensor", "fit"}
    assert sum(1 for r in records if r.get("t_init_runs")) == sum(r["solved"] for r in records)
    assert len(policies) == len(records) + sum(r["solved"] for r in records)  # and the reruns
    assert len({id(p) for p in policies}) == 2  # one object per planner for all of them
    tensor_records = [r for r in records if r["policy"] == "tensor"]
    assert all(r["params"] == {"decision_interval": "10"} for r in tensor_records)  # as trained
    # The summary names the parameter the tensor set.
    from datetime import UTC, datetime

    from lit_planner.bench import cli

    setups = cli.planner_setups(config, runner.benchmark_policies(config.planners, shipped))
    now = datetime.now(UTC)
    cli.write_outputs(
        tmp_path, records, config, preset=None, requested=list(config.planners), started=now,
        finished=now, duration=0.0, estimate=(0.0, "-"), planners=setups,
    )  # fmt: skip
    summary = (tmp_path / "summary.md").read_text(encoding="utf-8")
    assert "Planner parameters set: litstar-tensor: decision_interval 10 (" in summary


def test_the_bench_command_reads_its_tensors_once(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """``lit bench`` checks that the tensor planner can run (selecting the planners) and then
    benchmarks with the very policy object that check made: through the command's own ``run``,
    the files are read once."""
    import argparse

    from lit_planner.bench import cli

    from lit_planner import planning

    loads: list[str] = []
    real_load = planning.load_tensor

    def counting_load(path: Path, output: str) -> object:
        loads.append(output)
        return real_load(path, output)

    monkeypatch.setattr(planning, "load_tensor", counting_load)
    shipped = Path(__file__).resolve().parents[1] / "tensors"
    parser = argparse.ArgumentParser()
    cli.add_arguments(parser)
    args = parser.parse_args(
        ["--scenarios", "np4", "--planners", "litstar-tensor,litstar-fit", "--runs", "1",
         "--time-scale", "0.5", "--tensors", str(shipped), "--no-bag",
         "--out", str(tmp_path / "out")]
    )  # fmt: skip
    assert cli.run(args) == 0
    assert sorted(loads) == ["B", "psi_K"]
    records = (tmp_path / "out" / "runs.jsonl").read_text(encoding="utf-8").splitlines()
    assert {json.loads(line)["policy"] for line in records} == {"tensor", "fit"}


def test_bench_refuses_a_bag_dir_with_no_bag(tmp_path: Path) -> None:
    """``--bag-dir`` says where the bag goes, ``--no-bag`` that there is none: refused together,
    before the run folder or the bag folder exists."""
    out, bags = tmp_path / "out", tmp_path / "bags"
    result = _lit("bench", "--quick", "--bag-dir", str(bags), "--no-bag", "--out", str(out))
    assert result.returncode == 2, result.stderr
    assert result.stderr.splitlines() == [
        f"lit bench: --bag-dir {bags} and --no-bag contradict each other: choose one"
    ]
    assert result.stdout == ""
    assert not out.exists() and not bags.exists()


def test_runs_that_cannot_be_appended_still_reach_the_bag(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A ``runs.jsonl`` that cannot be appended to (here a folder where the file was) ends the
    benchmark in one line with exit 1, and the scenario's records still reach the bag."""
    from lit_planner.bench import cli, runner

    from lit_planner import replay

    out, bags = tmp_path / "out", tmp_path / "bags"
    real_run = runner.run_benchmark

    def run_with_a_folder_in_the_way(*args: object, **kwargs: object) -> object:
        (out / "runs.jsonl").unlink()
        (out / "runs.jsonl").mkdir()
        return real_run(*args, **kwargs)

    monkeypatch.setattr(runner, "run_benchmark", run_with_a_folder_in_the_way)
    assert cli.run(_np4_fit_args(out, bags)) == 1
    errors = [line for line in capsys.readouterr().err.splitlines() if "Is a directory" in line]
    assert len(errors) == 1 and "holds the runs of the finished scenarios" in errors[0], errors
    (bag_path,) = bags.iterdir()
    recorded = replay.read_bench([bag_path])
    assert [run.payload["seed"] for run in recorded.runs] == [1, 2]
    assert not (out / "summary.json").exists()  # no tables from a run that lost its records


def _np4_fit_args(out: Path, bags: Path) -> object:
    """``lit bench``'s arguments for two np4 runs of LIT* (fit), recorded into ``bags``."""
    import argparse

    from lit_planner.bench import cli

    parser = argparse.ArgumentParser()
    cli.add_arguments(parser)
    return parser.parse_args(
        ["--scenarios", "np4", "--planners", "litstar-fit", "--runs", "2", "--time-scale", "0.5",
         "--out", str(out), "--bag-dir", str(bags)]
    )  # fmt: skip


@pytest.mark.parametrize("stage", ["start", "after-a-scenario", "writing"])
def test_ctrl_c_says_what_is_kept_and_names_the_replay_that_makes_tables(
    monkeypatch: pytest.MonkeyPatch,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    stage: str,
) -> None:
    """Ctrl-C before the first scenario finished (nothing is kept in --out), after one while it
    plans on, or after the planning while the tables are written: exit 130 with a line that says
    which runs ``runs.jsonl`` holds and which ``lit replay bench`` makes the tables."""
    from lit_planner.bench import cli, runner

    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    run_benchmark = runner.run_benchmark

    def interrupted_after_a_scenario(*args: Any, on_scenario_done: Any, **kwargs: Any) -> Any:
        def done(records: Any) -> None:
            on_scenario_done(records)
            raise KeyboardInterrupt

        return run_benchmark(*args, on_scenario_done=done, **kwargs)

    if stage == "start":
        monkeypatch.setattr(runner, "run_benchmark", interrupted)
    elif stage == "after-a-scenario":
        monkeypatch.setattr(runner, "run_benchmark", interrupted_after_a_scenario)
    else:
        monkeypatch.setattr(cli, "write_outputs", interrupted)
    out, bags = tmp_path / "out", tmp_path / "bags"
    assert cli.run(_np4_fit_args(out, bags)) == 130
    (bag_path,) = bags.iterdir()
    runs = out / "runs.jsonl"
    expected = {
        "start": f"lit bench: interrupted before a scenario finished: nothing kept in {out}; the "
        f"bag {bag_path} holds no runs",
        "after-a-scenario": f"lit bench: interrupted; {runs} holds the runs of the finished scenarios (not"
        f" those of the scenario it was planning); `lit replay bench {bag_path}` makes tables of"
        " them",
        "writing": f"lit bench: interrupted while writing the outputs (those in {out} may be "
        f"partial); {runs} holds every run; `lit replay bench {bag_path}` writes them",
    }[stage]
    assert capsys.readouterr().err.splitlines()[-1] == expected
    if stage == "start":
        # An empty runs.jsonl in --out refused the retry ("exists and is not empty").
        assert not out.exists()
        monkeypatch.undo()
        assert cli.run(_np4_fit_args(out, tmp_path / "bags-retry")) == 0
    assert len(runs.read_text(encoding="utf-8").splitlines()) == 2

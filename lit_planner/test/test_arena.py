"""``lit arena``: runs.jsonl -> OMPL benchmark logs -> Planner Arena SQLite database.

The fixture is a tiny hand-written runs.jsonl in the shape ``lit bench`` writes (BenchRun records).
The conversion must happen in a separate process that has PyPI ompl but not lit_core.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import sqlite3
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from lit_planner import arena

LIT_CORE_PROCESS = "import lit_core"


def record(scenario: str, planner: str, seed: int, **fields: Any) -> dict[str, Any]:
    solved = fields.get("improvements") is not None
    improvements = fields.pop("improvements", None) or []
    base: dict[str, Any] = {
        "schema": "lit_msgs_json/BenchRun", "version": 1,
        "scenario": scenario.split("/")[0], "scenario_key": scenario,
        "instance": int(scenario.split("/")[1]) if "/" in scenario else 0,
        "dimension": int("".join(ch for ch in scenario.split("/")[0] if ch.isdigit())),
        "run": seed - 1, "seed": seed, "order": 0, "planner": planner,
        "core_planner": "litstar" if planner.startswith("litstar") else planner,
        "policy": "fixed" if planner.startswith("litstar") else None, "params": {},
        "time_budget": 0.12, "status": "exact_solution" if solved else "timeout", "message": "",
        "solved": solved,
        "t_init": improvements[0][0] if solved else None,
        "c_init": improvements[0][1] if solved else None,
        "c_final": improvements[-1][1] if solved else None,
        "improvements": improvements, "time": 0.12, "wall_time": 0.125,
        "path_valid": True if solved else None, "path_check": None,
        "path_states": 5 if solved else 0, "path": [],
        "counters": {"validity_checks": 1000 + seed}, "optimal_cost": None,
    }  # fmt: skip
    base.update(fields)
    return base


RECORDS = [
    record("np4", "litstar-fixed", 1, improvements=[[0.003, 1.45], [0.01, 0.8], [0.05, 0.459]],
           counters={"validity_checks": 741934, "iterations": 3000, "order": 12}),
    record("np4", "bitstar", 1),  # unsolved: null costs, no improvements
    record("np4", "litstar-fixed", 2, improvements=[[0.002, 1.3], [0.1, 0.47]]),
    record("np4", "bitstar", 2, improvements=[[0.02, 0.9], [0.08, 0.6]]),
    record("rrd8/3", "litstar-fixed", 1, improvements=[[0.01, 3.0], [0.2, 2.0]], time_budget=0.3,
           time=0.3),
]  # fmt: skip


@pytest.fixture()
def bench_dir(tmp_path: Path) -> Path:
    folder = tmp_path / "results" / "tiny"
    folder.mkdir(parents=True)
    (folder / arena.RUNS_FILE).write_text("".join(json.dumps(r) + "\n" for r in RECORDS) + "\n")
    return folder


def query(database: Path, sql: str) -> list[tuple[Any, ...]]:
    with contextlib.closing(sqlite3.connect(database)) as connection:
        return connection.execute(sql).fetchall()


def test_export_writes_logs_and_database_in_a_separate_process(bench_dir: Path) -> None:
    import lit_core  # noqa: F401 -- this process has lit_core; the converter must not

    assert "lit_core" in sys.modules
    export = arena.export_arena(bench_dir)

    assert [log.name for log in export.logs] == ["np4.log", "rrd8.log"]
    assert all(log.parent == bench_dir / arena.LOG_DIR for log in export.logs)
    assert export.database == (bench_dir / arena.DATABASE_NAME).resolve()
    assert export.runs == len(RECORDS)
    process = export.process
    assert process["pid"] != os.getpid()
    assert process["lit_core_loaded"] is False
    assert process["ompl_loaded"] is True and process["ompl_version"] == "2.0.1"
    assert "readBenchmarkLog" in export.converter

    db = export.database
    tables = {name for (name,) in query(db, "SELECT name FROM sqlite_master WHERE type='table'")}
    assert {"experiments", "plannerConfigs", "runs", "progress", "enums"} <= tables
    views = {name for (name,) in query(db, "SELECT name FROM sqlite_master WHERE type='view'")}
    assert {"bestPlannerConfigs", "bestPlannerConfigsPerExperiment"} <= views

    experiments = query(db, "SELECT name, timelimit, runcount, version, dimension, optimal_cost "
                            "FROM experiments ORDER BY id")  # fmt: skip
    assert experiments[0][:5] == ("np4", 0.12, 2, "OMPL 1.5.2", 4)
    assert experiments[0][5] == pytest.approx(0.4236067977)
    assert experiments[1][:5] == ("rrd8", 0.3, 1, "OMPL 1.5.2", 8)
    assert experiments[1][5] is None  # random scenarios have no known optimum

    planners = [name for (name,) in query(db, "SELECT name FROM plannerConfigs ORDER BY id")]
    assert planners == ["litstar-fixed", "bitstar"]
    assert query(db, "SELECT settings FROM plannerConfigs WHERE name = 'litstar-fixed'")[0][
        0
    ].startswith("policy = fixed")
    runs = query(db, "SELECT p.name, r.seed, r.solved, r.status, r.best_cost, r.final_cost, "
                     "r.initial_cost, r.time_to_first_solution, r.time, r.validity_checks, "
                     "r.improvements, r.instance, r.correct_solution FROM runs r "
                     "JOIN plannerConfigs p ON p.id = r.plannerid ORDER BY r.id")  # fmt: skip
    assert len(runs) == len(RECORDS)
    assert runs[0] == ("litstar-fixed", 1, 1, 6, 0.459, 0.459, 1.45, 0.003, 0.12, 741934, 3, 0, 1)
    assert runs[2][:3] == ("bitstar", 1, 0)
    assert runs[2][3] == 4  # Timeout in OMPL's PlannerStatus order
    assert runs[2][4:8] == (None, None, None, None)  # an unsolved run's costs are NULL
    assert runs[4][0] == "litstar-fixed" and runs[4][11] == 3  # rrd8/3 -> instance 3
    assert query(db, "SELECT iterations FROM runs WHERE iterations IS NOT NULL") == [(3000,)]
    # a counter named like an SQL keyword gets a prefix (the converter adds columns unquoted)
    assert query(db, "SELECT counter_order FROM runs WHERE counter_order IS NOT NULL") == [(12,)]
    assert query(db, "SELECT planner_order, run_index FROM runs WHERE id = 4") == [(0, 1)]

    enums = query(db, "SELECT value, description FROM enums WHERE name = 'status' ORDER BY value")
    assert enums[4] == (4, "Timeout") and enums[6] == (6, "Exact solution") and len(enums) == 9

    progress = query(db, "SELECT r.id, COUNT(*), COUNT(g.best_cost), MIN(g.time), MAX(g.time), "
                         "MIN(g.best_cost) FROM progress g JOIN runs r ON r.id = g.runid "
                         "GROUP BY r.id ORDER BY r.id")  # fmt: skip
    assert len(progress) == len(RECORDS)  # every run has a progress curve
    first = progress[0]
    # 100 grid points up to 0.12 s plus the improvement times off the grid
    assert first[1] >= arena.PROGRESS_POINTS + 2
    assert first[4] == pytest.approx(0.12) and first[5] == pytest.approx(0.459)
    assert progress[2][2] == 0  # the unsolved run: best cost NULL throughout
    curve = query(db, "SELECT time, best_cost FROM progress WHERE runid = 1 ORDER BY time")
    assert (0.003, 1.45) in curve and (0.05, 0.459) in curve
    assert all(cost is None for t, cost in curve if t < 0.003)
    costs = [cost for _, cost in curve if cost is not None]
    assert costs == sorted(costs, reverse=True)


def test_log_text_follows_the_ompl_format(bench_dir: Path) -> None:
    records = arena.read_runs(bench_dir / arena.RUNS_FILE)
    text = arena.benchmark_log("np4", [r for r in records if r["scenario"] == "np4"])
    lines = text.splitlines()
    assert lines[0] == "OMPL version 1.5.2" and lines[1] == "Experiment np4"
    for expected in (
        "0.12 seconds per run",
        "2 runs per planner",
        "1 enum type",
        "2 planners",
        "2 progress properties for each run",
        "best cost REAL",
        "status ENUM",
    ):
        assert expected in lines, expected
    assert lines[lines.index("1 enum type") + 1].startswith("status|Unknown status|Invalid start")
    assert lines[-1] == "."
    run_lines = [line for line in lines if line.endswith("; ")]
    assert len(run_lines) == 4 and all(line.count("; ") == run_lines[0].count("; ")
                                       for line in run_lines[:2])  # fmt: skip


def test_lit_arena_command(bench_dir: Path) -> None:
    process = subprocess.run([sys.executable, "-m", "lit_planner.cli", "arena", str(bench_dir)],
                             capture_output=True, text=True, timeout=120, check=False)  # fmt: skip
    assert process.returncode == 0, process.stderr
    assert "2 OMPL benchmark logs" in process.stdout and "benchmark.db" in process.stdout
    assert "lit_core loaded there: False" in process.stdout
    assert (bench_dir / "benchmark.db").is_file()


@pytest.mark.parametrize("name", ["../escape.db", "sub/arena.db", "..", ".", ""])
def test_database_must_be_a_file_name_in_the_run_folder(bench_dir: Path, name: str) -> None:
    """``--database`` names a file in RESULTS_DIR: a path out of (or into) it is refused."""
    before = sorted(p.relative_to(bench_dir.parent) for p in bench_dir.parent.rglob("*"))
    process = subprocess.run(
        [sys.executable, "-m", "lit_planner.cli", "arena", str(bench_dir), "--database", name],
        capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert process.returncode == 2, process.stdout + process.stderr
    assert process.stdout == ""
    assert process.stderr == (
        f"lit arena: --database {name!r}: expected a file name inside RESULTS_DIR, without a "
        "path separator or '..'\n"
    )
    # Nothing written: no logs, no database here or beside the run folder.
    assert sorted(p.relative_to(bench_dir.parent) for p in bench_dir.parent.rglob("*")) == before
    with pytest.raises(arena.ArenaError, match=re.escape(f"database {name!r}: expected a file")):
        arena.export_arena(bench_dir, database=name)
    assert sorted(p.relative_to(bench_dir.parent) for p in bench_dir.parent.rglob("*")) == before


@pytest.mark.parametrize("name", [arena.RUNS_FILE, "summary.md", arena.LOG_DIR])
def test_the_database_never_replaces_a_file_of_the_run(bench_dir: Path, name: str) -> None:
    """``--database runs.jsonl`` replaced the run's records with the database, exit 0."""
    (bench_dir / "summary.md").write_text("# the run's summary\n")
    (bench_dir / arena.LOG_DIR).mkdir()
    before = {p: p.read_bytes() for p in bench_dir.rglob("*") if p.is_file()}
    process = subprocess.run(
        [sys.executable, "-m", "lit_planner.cli", "arena", str(bench_dir), "--database", name],
        capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert process.returncode == 2, process.stdout + process.stderr
    assert process.stderr.startswith(f"lit arena: database {name!r}: ")
    assert "choose another name" in process.stderr
    assert {p: p.read_bytes() for p in bench_dir.rglob("*") if p.is_file()} == before


def test_an_earlier_export_is_replaced(bench_dir: Path) -> None:
    """Its database is written anew, and the log of a scenario the runs no longer have goes.
    An empty file is an empty SQLite database (what a converter killed after connect() leaves)."""
    (bench_dir / "arena.db").touch()
    arena.export_arena(bench_dir, database="arena.db")
    assert sorted(p.name for p in (bench_dir / arena.LOG_DIR).iterdir()) == [
        "np4.log",
        "rrd8.log",
    ]
    np4_only = [r for r in RECORDS if r["scenario"] == "np4"]
    (bench_dir / arena.RUNS_FILE).write_text("".join(json.dumps(r) + "\n" for r in np4_only))
    export = arena.export_arena(bench_dir, database="arena.db")
    assert sorted(p.name for p in (bench_dir / arena.LOG_DIR).iterdir()) == ["np4.log"]
    assert export.runs == len(np4_only)
    assert query(bench_dir / "arena.db", "SELECT COUNT(*) FROM runs") == [(len(np4_only),)]


def test_scenarios_whose_names_give_one_file_name_get_a_log_each(tmp_path: Path) -> None:
    """np4 and NP4 were both written to np4.log, the second over the first, and the first one's
    runs were lost from the database; a name of no letters or digits was a hidden ``.log``. A
    name empty before its instance's '/' is refused (it had an empty experiment name)."""
    for empty in ("/", "/tmp/world.json"):
        (tmp_path / arena.RUNS_FILE).write_text(json.dumps(dict(RECORDS[0], scenario=empty)))
        with pytest.raises(arena.ArenaError, match=r"run record 0: its scenario .* before '/'"):
            arena.export_arena(tmp_path)
    records = [dict(RECORDS[0], scenario=name) for name in ("np4", "NP4", "np_4", "-")]
    (tmp_path / arena.RUNS_FILE).write_text("".join(json.dumps(r) + "\n" for r in records))
    export = arena.export_arena(tmp_path)
    names = [log.name for log in export.logs]
    assert len(set(names)) == 4 and all(re.fullmatch(r"[a-z0-9_]+\.log", n) for n in names)
    assert [n.split("_")[0] for n in names] == ["np4", "np4", "np", "scenario"]
    assert export.runs == 4
    experiments = query(export.database, "SELECT name FROM experiments ORDER BY id")
    assert sorted(name for (name,) in experiments) == sorted(["np4", "NP4", "np_4", "-"])
    # A name alone keeps its plain file name, so a later export replaces its log.
    (tmp_path / arena.RUNS_FILE).write_text(json.dumps(RECORDS[0]) + "\n")
    export = arena.export_arena(tmp_path)
    assert [p.name for p in (tmp_path / arena.LOG_DIR).iterdir()] == ["np4.log"]


def test_missing_and_malformed_runs_files(tmp_path: Path) -> None:
    with pytest.raises(arena.ArenaError, match="run `lit bench` first"):
        arena.export_arena(tmp_path)
    (tmp_path / arena.RUNS_FILE).write_text(json.dumps(RECORDS[0]) + "\n{not json\n")
    with pytest.raises(arena.ArenaError, match=r"runs.jsonl:2: not JSON"):
        arena.export_arena(tmp_path)
    (tmp_path / arena.RUNS_FILE).write_text(json.dumps({"planner": "bitstar"}) + "\n")
    with pytest.raises(arena.ArenaError, match="no 'scenario' name"):
        arena.export_arena(tmp_path)
    process = subprocess.run([sys.executable, "-m", "lit_planner.cli", "arena", str(tmp_path)],
                             capture_output=True, text=True, timeout=60, check=False)  # fmt: skip
    assert process.returncode == 2 and "no 'scenario' name" in process.stderr
    (tmp_path / arena.RUNS_FILE).write_bytes(b"\xff\xfe")  # was a UnicodeDecodeError traceback
    with pytest.raises(arena.ArenaError, match="not UTF-8 text"):
        arena.export_arena(tmp_path)
    # A file holding a benchmark twice (cat of two runs.jsonl) counted every run twice.
    line = json.dumps(RECORDS[0]) + "\n"
    (tmp_path / arena.RUNS_FILE).write_text(line + line)
    with pytest.raises(arena.ArenaError, match=r"runs.jsonl:2: a second record of scenario"):
        arena.export_arena(tmp_path)
    # Another schema's record was taken as a run.
    other = dict(RECORDS[0], schema="lit_msgs_json/Foo")
    (tmp_path / arena.RUNS_FILE).write_text(json.dumps(other) + "\n")
    with pytest.raises(arena.ArenaError, match=r'runs.jsonl:1: a record of schema "lit_msgs'):
        arena.export_arena(tmp_path)
    # A lone surrogate in a name: a UnicodeEncodeError traceback and an empty log file.
    unnamed = {k: v for k, v in RECORDS[0].items() if k not in ("schema", "version")}
    (tmp_path / arena.RUNS_FILE).write_text(json.dumps(dict(unnamed, planner="\ud800")) + "\n")
    with pytest.raises(arena.ArenaError, match=r"its planner name '\\ud800' is not printable"):
        arena.export_arena(tmp_path)
    assert not list((tmp_path / arena.LOG_DIR).glob("*.log"))


def test_worker_refuses_a_process_with_lit_core(tmp_path: Path) -> None:
    request, response = tmp_path / "request.json", tmp_path / "response.json"
    request.write_text(json.dumps({"logs": [], "database": str(tmp_path / "x.db")}))
    code = ("import sys, runpy, lit_core; sys.argv = ['arena_db', sys.argv[1], sys.argv[2]]; "
            "runpy.run_module('lit_planner.ompl2.arena_db', run_name='__main__')")  # fmt: skip
    process = subprocess.run([sys.executable, "-c", code, str(request), str(response)],
                             capture_output=True, text=True, timeout=60, check=False)  # fmt: skip
    assert process.returncode == 1
    answer = json.loads(response.read_text())
    assert "must not run in a process that has imported lit_core" in answer["error"]
    assert answer["process"]["ompl_loaded"] is False
    assert not (tmp_path / "x.db").exists()


def test_a_run_counts_as_the_bench_tables_count_it() -> None:
    """The log's solved flag and final cost agree with `lit bench`'s tables: an improvement after
    the budget does not count (an OMPL planner's final cost was the one it returned, 1.81 where
    the summary said 1.84), and a first solution after the budget is no solution."""
    on_time = record("np4", "informed_rrtstar", 1, improvements=[[0.05, 2.0], [0.11, 1.84],
                                                                  [0.13, 1.81]])  # fmt: skip
    properties = arena._run_properties(on_time, 0.12)
    assert properties["final cost REAL"] == properties["best cost REAL"] == "1.84"
    assert properties["solved BOOLEAN"] == "1" and properties["improvements INTEGER"] == "2"
    assert properties["time of last improvement REAL"] == "0.11"
    assert [t for t, _ in arena._progress(on_time, 0.12, 4)] == [0.03, 0.05, 0.06, 0.09, 0.11,
                                                                 0.12]  # fmt: skip
    late = record("np4", "informed_rrtstar", 2, improvements=[[0.125, 2.0]])
    late["status"] = "exact_solution"
    properties = arena._run_properties(late, 0.12)
    assert properties["solved BOOLEAN"] == "0"
    assert properties["status ENUM"] == str(arena.STATUS_INDEX["timeout"])  # as solved says
    approximate = record("np4", "informed_rrtstar", 3, solved=False)
    approximate["status"] = "approximate_solution"  # never solved: stays what it was
    status = arena._run_properties(approximate, 0.12)["status ENUM"]
    assert status == str(arena.STATUS_INDEX["approximate_solution"])
    assert properties["final cost REAL"] == properties["time to first solution REAL"] == "inf"
    assert all(math.isinf(cost) for _, cost in arena._progress(late, 0.12, 4))

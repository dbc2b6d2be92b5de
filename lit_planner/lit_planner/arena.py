"""``lit arena``: a bench run folder's ``runs.jsonl`` as OMPL benchmark logs and a Planner Arena database.

Two steps:

1. :func:`write_logs` writes one OMPL benchmark log per scenario into ``<folder>/arena/``, in the
   text format of ``ompl::tools::Benchmark::saveResultsToStream`` (the format that
   ``ompl_benchmark_statistics.py`` reads): version, experiment name and properties, host, date,
   setup and CPU blocks, seed, time and memory limits, runs per planner, total time, the ``status``
   enum, then per planner its common properties, its per-run properties, one line per run, and its
   per-run progress (time, best cost).
2. :func:`convert_logs` turns them into ``<folder>/benchmark.db`` with PyPI ``ompl``'s own converter
   (``ompl.tools.readBenchmarkLog`` and ``computeViews``), run in a separate process by the
   :mod:`lit_planner.ompl2.arena_db` worker because PyPI ``ompl`` must not share a process with
   ``lit_core``.

:func:`export_arena` does both; it is the function for ``lit bench`` to call at the end of a run. Upload ``benchmark.db``
to https://plannerarena.org (or a local Planner Arena) to browse the results.

Per-run properties (column names in the ``runs`` table in brackets): ``time REAL`` [time] (the
run's planning time: the record's ``time``, else its time budget), ``solved BOOLEAN`` [solved],
``status ENUM`` [status] (OMPL's ``PlannerStatus`` order), ``best cost REAL`` [best_cost] and
``final cost REAL`` [final_cost] (c_final), ``initial cost REAL`` [initial_cost] (c_init), ``time to
first solution REAL`` [time_to_first_solution] (t_init), ``time of last improvement REAL``,
``improvements INTEGER``, ``seed INTEGER``, ``instance INTEGER``, ``run index INTEGER``, ``planner
order INTEGER`` (position in the run's shuffled order), ``wall time REAL``, ``solution segments
INTEGER``, ``correct solution BOOLEAN`` (when the record says whether the path passed the independent
check) and every numeric counter (e.g. ``validity checks INTEGER``; a counter whose name is an SQL
keyword gets the prefix ``counter``). Costs and times of unsolved runs are written as ``inf``, which the
converter stores as NULL. Progress (table ``progress``, columns ``time`` and ``best_cost``): the
best cost after each solution improvement, plus the step curve sampled at
:data:`PROGRESS_POINTS` evenly spaced times up to the time limit (OMPL samples progress every
``timeBetweenUpdates``; Planner Arena averages progress over runs at common times).
"""

from __future__ import annotations

import argparse
import collections
import hashlib
import json
import math
import os
import platform
import re
import socket
import sys
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

from lit_planner import argtypes, ompl2
from lit_planner.errors import LitPlannerError, ScenarioError

RUNS_FILE = "runs.jsonl"
BENCH_RUN_SCHEMA = "lit_msgs_json/BenchRun"
"""The bench runner's per-run records, one JSON object per line."""
DATABASE_NAME = "benchmark.db"
"""The Planner Arena database, written into the results folder."""
LOG_DIR = "arena"
"""Subfolder of the results folder that receives the benchmark logs."""
PROGRESS_POINTS = 100
"""Evenly spaced progress samples per run up to the time limit (besides every improvement)."""
LIBRARY_LINE = "OMPL version 1.5.2"
"""First log line: every planner of the benchmark runs on Debian's OMPL 1.5.2 (LIT* included)."""
STATUS_NAMES = (
    ("unknown", "Unknown status"),
    ("invalid_start", "Invalid start"),
    ("invalid_goal", "Invalid goal"),
    ("unrecognized_goal_type", "Unrecognized goal type"),
    ("timeout", "Timeout"),
    ("approximate_solution", "Approximate solution"),
    ("exact_solution", "Exact solution"),
    ("crash", "Crashed"),
    ("abort", "Aborted"),
)
"""``lit_core``'s status names with OMPL's ``PlannerStatus`` descriptions, in OMPL's enum order."""
STATUS_INDEX = {name: index for index, (name, _) in enumerate(STATUS_NAMES)}
BUDGET_KEYS = ("time_budget", "budget", "time_limit")
"""Record keys that may hold a run's time budget, in order of preference."""
PROGRESS_PROPERTIES = ("best cost REAL", "time REAL")
"""Progress columns, in OMPL's (alphabetical) order."""
SQLITE_KEYWORDS = frozenset(
    """
    abort action add after all alter always analyze and as asc attach autoincrement before begin
    between by cascade case cast check collate column commit conflict constraint create cross
    current current_date current_time current_timestamp database default deferrable deferred
    delete desc detach distinct do drop each else end escape except exclude exclusive exists
    explain fail filter first following for foreign from full generated glob group groups having
    if ignore immediate in index indexed initially inner insert instead intersect into is isnull
    join key last left like limit match materialized natural no not nothing notnull null nulls of
    offset on or order others outer over partition plan pragma preceding primary query raise range
    recursive references regexp reindex release rename replace restrict returning right rollback
    row rows savepoint select set table temp temporary then ties to transaction trigger unbounded
    union unique update using vacuum values view virtual when where window with without
    """.split()  # noqa: SIM905 -- a word list reads better than 147 quoted strings
)
"""SQLite's keywords: the converter adds columns with unquoted names, so none may be one."""
_UNSAFE = re.compile(r"[^a-z0-9]+")


class ArenaError(LitPlannerError, ValueError):
    """The runs file is missing or malformed, or the conversion failed; names the cause."""


@dataclass(frozen=True)
class ArenaExport:
    """What :func:`export_arena` wrote."""

    database: Path
    """The Planner Arena SQLite database."""
    logs: tuple[Path, ...]
    """One OMPL benchmark log per scenario."""
    runs: int
    """Records exported."""
    rows: dict[str, int] = field(default_factory=dict)
    """Row count of every table of the database."""
    converter: str = ""
    """What converted the logs (PyPI ompl's functions)."""
    process: dict[str, Any] = field(default_factory=dict)
    """The converter process's report (pid, whether ``lit_core`` / ``ompl`` were loaded)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``lit arena``."""
    parser.add_argument("results_dir", metavar="RESULTS_DIR", type=argtypes.path,
                        help=f"a bench run folder holding {RUNS_FILE}")  # fmt: skip
    parser.add_argument("--database", default=DATABASE_NAME,
                        help="database file name inside RESULTS_DIR (default: %(default)s)")  # fmt: skip


def run(args: argparse.Namespace) -> int:
    """``lit arena RESULTS_DIR``: exit 0 on success, 2 on bad input or a failed conversion."""
    problem = database_name_problem(args.database)
    if problem is not None:
        print(f"lit arena: --database {args.database!r}: {problem}", file=sys.stderr)
        return 2
    try:
        export = export_arena(args.results_dir, database=args.database)
    except (ArenaError, ompl2.Ompl2Error) as error:
        print(f"lit arena: {error}", file=sys.stderr)
        return 2
    print(f"lit arena: {export.runs} runs -> {len(export.logs)} OMPL benchmark logs in "
          f"{export.logs[0].parent}")  # fmt: skip
    for log in export.logs:
        print(f"  {log.name}")
    rows = ", ".join(f"{table} {count}" for table, count in sorted(export.rows.items()))
    print(f"lit arena: {export.database} ({rows})")
    print(f"lit arena: converted by {export.converter} in process {export.process.get('pid')} "
          f"(lit_core loaded there: {export.process.get('lit_core_loaded')})")  # fmt: skip
    print("lit arena: open it at https://plannerarena.org (Change database -> upload)")
    return 0


def export_arena(
    results_dir: str | Path,
    records: Iterable[Mapping[str, Any]] | None = None,
    *,
    database: str = DATABASE_NAME,
    progress_points: int = PROGRESS_POINTS,
    timeout: float | None = 600.0,
) -> ArenaExport:
    """Write the OMPL benchmark logs and the Planner Arena database of a bench run folder.

    Args:
        results_dir: the run folder; logs go to ``<results_dir>/arena/<scenario>.log`` and the
            database to ``<results_dir>/<database>`` (an earlier database there is replaced;
            any other file is refused). Logs of an earlier export that these records do not
            make are removed.
        records: the per-run records; None reads ``<results_dir>/runs.jsonl``.
        database: file name of the database inside ``results_dir``.
        progress_points: evenly spaced progress samples per run (see the module docstring).
        timeout: seconds the converter process may take.

    Raises:
        ArenaError: no records, a malformed runs file or record, a database name that is not
            a plain file name or names a file of the run that is not a database.
        lit_planner.ompl2.Ompl2Error: the converter process failed.
    """
    problem = database_name_problem(database)
    if problem is not None:
        raise ArenaError(f"database {database!r}: {problem}")
    folder = Path(results_dir)
    taken = _taken_name_problem(folder / database)
    if taken is not None:
        raise ArenaError(f"database {database!r}: {taken}")
    runs_path = folder / RUNS_FILE
    if records is None:
        records = read_runs(runs_path)
    records = list(records)
    if not records:
        raise ArenaError(f"no runs to export from {folder}")
    date = datetime.fromtimestamp(runs_path.stat().st_mtime) if runs_path.exists() else None
    logs = write_logs(records, folder / LOG_DIR, date=date, progress_points=progress_points)
    response = convert_logs(logs, folder / database, timeout=timeout)
    return ArenaExport(
        database=Path(response["database"]),
        logs=tuple(logs),
        runs=len(records),
        rows=dict(response.get("rows", {})),
        converter=str(response.get("converter", "")),
        process=dict(response.get("process", {})),
    )


def database_name_problem(name: str) -> str | None:
    """Why ``name`` is not a plain file name inside the run folder, or None when it is.

    A path separator or ``..`` would put the database elsewhere (``../escape.db``).
    """
    separators = "/" + os.sep + (os.altsep or "")
    if name in ("", ".", "..") or any(sep in name for sep in separators):
        return "expected a file name inside RESULTS_DIR, without a path separator or '..'"
    return None


SQLITE_HEADER = b"SQLite format 3\x00"
"""The first 16 bytes of every SQLite database file."""


def _taken_name_problem(path: Path) -> str | None:
    """Why the database may not be written to ``path`` (it is the run's own file or folder:
    ``--database runs.jsonl`` replaced the run's records with the database), or None."""
    if path.name == LOG_DIR or path.is_dir():
        return f"{path.name} is a folder of the run; choose another name"
    if not path.exists() or (path.is_file() and path.stat().st_size == 0):
        return None  # an empty file is an empty SQLite database (connect() creates one)
    try:
        with path.open("rb") as handle:
            is_database = handle.read(len(SQLITE_HEADER)) == SQLITE_HEADER
    except OSError as error:
        return f"{path} cannot be read: {error.strerror or error}"
    if not is_database:
        return (
            f"{path.name} in the run folder is not an SQLite database (only an earlier "
            f"database is replaced); choose another name"
        )
    return None


def convert_logs(
    logs: Sequence[Path], database: Path, *, timeout: float | None = 600.0
) -> dict[str, Any]:
    """Convert ``logs`` into ``database`` with PyPI ompl in its own process; the worker's answer."""
    return ompl2.run_worker(
        "arena_db",
        {
            "logs": [str(Path(log).resolve()) for log in logs],
            "database": str(Path(database).resolve()),
            "append": False,
        },
        timeout=timeout,
        capture_stderr=True,
    )


def read_runs(path: Path) -> list[dict[str, Any]]:
    """The records of a ``runs.jsonl`` file (blank lines skipped).

    Raises:
        ArenaError: the file is missing, a line is not a JSON object, or a record lacks
            ``scenario`` or ``planner``.
    """
    from lit_msgs_json import codec

    if not path.is_file():
        raise ArenaError(f"{path} not found: run `lit bench` first (it writes {RUNS_FILE})")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as error:
        raise ArenaError(f"{path}: not UTF-8 text ({error.reason} at byte {error.start})") from None
    records = []
    seen: dict[tuple[Any, ...], int] = {}
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        try:
            record = json.loads(line)
        except json.JSONDecodeError as error:
            raise ArenaError(f"{path}:{number}: not JSON ({error})") from error
        if not isinstance(record, dict):
            raise ArenaError(
                f"{path}:{number}: expected a JSON object, got {type(record).__name__}"
            )
        schema = record.get("schema")
        if schema is not None and schema != BENCH_RUN_SCHEMA:  # it was taken as a run
            raise ArenaError(
                f"{path}:{number}: a record of schema {json.dumps(schema)[:100]}, not a lit "
                f"bench run ({BENCH_RUN_SCHEMA})"
            )
        if schema == BENCH_RUN_SCHEMA:
            try:  # a lit bench record: as lit bench wrote it (no NaN, no negative cost, ...)
                codec.loads(BENCH_RUN_SCHEMA, line)
            except codec.SchemaError as error:
                raise ArenaError(f"{path}:{number}: not a valid run record: {error}") from None
        key = tuple(record.get(k) for k in ("scenario", "instance", "planner", "run"))
        if None not in key[2:] and key in seen:
            raise ArenaError(
                f"{path}:{number}: a second record of scenario {key[0]}, planner {key[2]}, run "
                f"{key[3]} (the first is line {seen[key]}): two benchmarks in one file?"
            )
        seen.setdefault(key, number)
        records.append(record)
    return records


def write_logs(
    records: Iterable[Mapping[str, Any]],
    log_dir: Path,
    *,
    date: datetime | None = None,
    host: str | None = None,
    progress_points: int = PROGRESS_POINTS,
) -> list[Path]:
    """Write one OMPL benchmark log per scenario of ``records`` into ``log_dir``; their paths."""
    by_scenario: dict[str, list[Mapping[str, Any]]] = {}
    for index, record in enumerate(records):
        for key in ("scenario", "planner"):
            if not isinstance(record.get(key), str) or not record[key]:
                raise ArenaError(f"run record {index} has no {key!r} name: {dict(record)}")
            if not record[key].isprintable():  # a lone surrogate failed the write (traceback)
                raise ArenaError(
                    f"run record {index}: its {key} name {ascii(record[key])[:200]} is not "
                    "printable text"
                )
        if not _scenario_name(record):  # "/x": the experiment had an empty name
            raise ArenaError(
                f"run record {index}: its scenario {record['scenario']!r} has no name before '/'"
            )
        by_scenario.setdefault(_scenario_name(record), []).append(record)
    log_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    names = _log_names(by_scenario)
    for scenario, group in by_scenario.items():
        path = log_dir / names[scenario]
        path.write_text(benchmark_log(scenario, group, date=date, host=host,
                                      progress_points=progress_points))  # fmt: skip
        paths.append(path)
    # An earlier export's log of a scenario these records no longer have would stay beside
    # the new ones and out of the database.
    for stale in set(log_dir.glob("*.log")) - set(paths):
        stale.unlink()
    return paths


def benchmark_log(
    scenario: str,
    records: Sequence[Mapping[str, Any]],
    *,
    date: datetime | None = None,
    host: str | None = None,
    progress_points: int = PROGRESS_POINTS,
) -> str:
    """The OMPL benchmark log of one scenario's runs (all planners), as text."""
    facts = _scenario_facts(scenario)
    for key, record_key in (("dim", "dimension"), ("optimal_cost", "optimal_cost")):
        if facts.get(key) is None:
            facts[key] = next((r[record_key] for r in records
                               if isinstance(r.get(record_key), int | float)), None)  # fmt: skip
    budgets = [b for b in (_budget(r) for r in records) if b is not None]
    time_limit = max(budgets) if budgets else facts.get("time_budget")
    planners: dict[str, list[Mapping[str, Any]]] = {}
    for record in records:
        planners.setdefault(str(record["planner"]), []).append(record)
    seeds = [int(r["seed"]) for r in records if isinstance(r.get("seed"), int)]
    instances = sorted({_instance(r) for r in records} - {None})  # type: ignore[type-var]
    total_time = sum(t for t in (_run_time(r, time_limit) for r in records) if t is not None)

    properties = {"dimension INTEGER": facts.get("dim"),
                  "optimal_cost REAL": facts.get("optimal_cost"),
                  "resolution REAL": facts.get("resolution"),
                  "instances INTEGER": len(instances) or None}  # fmt: skip
    properties = {key: value for key, value in properties.items() if value is not None}
    lines = [LIBRARY_LINE, f"Experiment {scenario}", f"{len(properties)} experiment properties"]
    lines += [f"{key} = {_number(value)}" for key, value in properties.items()]
    lines += [
        f"Running on {host or _host(records)}",
        f"Starting at {(date or datetime.now()).strftime('%Y-%m-%d %H:%M:%S')}",
        "<<<|",
        *_setup_lines(scenario, facts, instances, time_limit),
        "|>>>",
        "<<<|",
        *_cpu_lines(),
        "|>>>",
        f"{min(seeds) if seeds else 0} is the random seed",
        f"{_number(time_limit if time_limit is not None else 0.0)} seconds per run",
        "0 MB per run",  # the bench runner sets no memory limit
        f"{max(len(runs) for runs in planners.values())} runs per planner",
        f"{_number(total_time)} seconds spent to collect the data",
        "1 enum type",
        "status|" + "|".join(description for _, description in STATUS_NAMES),
        f"{len(planners)} planners",
    ]
    for planner, runs in planners.items():
        lines += _planner_section(planner, runs, time_limit, progress_points)
    return "\n".join(lines) + "\n"


def _planner_section(
    planner: str,
    runs: Sequence[Mapping[str, Any]],
    time_limit: float | None,
    progress_points: int,
) -> list[str]:
    common = _common_properties(runs)
    values = [_run_properties(run, time_limit) for run in runs]
    names = sorted({name for run in values for name in run})
    lines = [planner, f"{len(common)} common properties"]
    lines += [f"{key} = {value}" for key, value in sorted(common.items())]
    lines += [f"{len(names)} properties for each run", *names, f"{len(runs)} runs"]
    lines += ["".join(f"{run.get(name, '')}; " for name in names) for run in values]
    curves = [_progress(run, time_limit, progress_points) for run in runs]
    if any(curves):
        lines += [f"{len(PROGRESS_PROPERTIES)} progress properties for each run",
                  *PROGRESS_PROPERTIES, f"{len(runs)} runs"]  # fmt: skip
        lines += ["".join(f"{_number(cost)},{_number(t)},;" for t, cost in curve)
                  for curve in curves]  # fmt: skip
    lines.append(".")
    return lines


def _run_properties(record: Mapping[str, Any], time_limit: float | None) -> dict[str, str]:
    """One run's ``name TYPE -> value`` (strings as the log holds them): as ``lit bench``'s
    tables count it, solved when the first solution came within the budget, and the final cost
    the cost at the budget (:func:`_in_budget`)."""
    solved, improvements = _in_budget(record, time_limit)
    c_final = _float(record.get("c_final", record.get("cost")))
    if improvements:
        c_final = min(cost for _, cost in improvements)
    c_init = _float(record.get("c_init"))
    t_init = _float(record.get("t_init"))
    if not solved:
        c_final = c_init = t_init = math.inf
    values: dict[str, object] = {
        "time REAL": _run_time(record, time_limit),
        "solved BOOLEAN": int(solved),
        "status ENUM": _status(record, solved),
        "best cost REAL": c_final,
        "final cost REAL": c_final,
        "initial cost REAL": c_init,
        "time to first solution REAL": t_init,
        "time of last improvement REAL": improvements[-1][0]
        if improvements and solved
        else math.inf,
        "improvements INTEGER": len(improvements),
    }
    for key, name in (("seed", "seed"), ("instance", "instance"), ("run", "run index"),
                      ("order", "planner order")):  # fmt: skip
        number = _instance(record) if key == "instance" else record.get(key)
        if isinstance(number, int) and not isinstance(number, bool):
            values[f"{name} INTEGER"] = number
    wall_time = _float(record.get("wall_time"))
    if math.isfinite(wall_time):
        values["wall time REAL"] = wall_time
    states = record.get("path_states")
    if isinstance(states, int) and not isinstance(states, bool) and states > 0:
        values["solution segments INTEGER"] = states - 1
    correct = _path_valid(record)
    if correct is not None:
        values["correct solution BOOLEAN"] = int(correct)
    counters = record.get("counters")
    if isinstance(counters, Mapping):
        taken = {name.rsplit(" ", 1)[0] for name in values}
        for key, value in counters.items():
            name = " ".join(_UNSAFE.sub(" ", str(key).lower()).split())
            if not name or name in taken or name[0].isdigit() or name in SQLITE_KEYWORDS:
                name = f"counter {name}".strip()
            if isinstance(value, bool):
                values[f"{name} BOOLEAN"] = int(value)
            elif isinstance(value, int):
                values[f"{name} INTEGER"] = value
            elif isinstance(value, float):
                values[f"{name} REAL"] = value
    return {key: _number(value) for key, value in values.items() if value is not None}


def _progress(
    record: Mapping[str, Any], time_limit: float | None, points: int
) -> list[tuple[float, float]]:
    """(time, best cost) at every improvement within the budget and on an even grid up to the
    time limit."""
    solved, improvements = _in_budget(record, time_limit)
    if not solved:
        improvements = []
    horizon = time_limit if time_limit and time_limit > 0 else None
    times = {t for t, _ in improvements}
    if horizon is not None and points > 0:
        times |= {round(horizon * k / points, 12) for k in range(1, points + 1)}
    curve, best, index = [], math.inf, 0
    for t in sorted(times):
        while index < len(improvements) and improvements[index][0] <= t:
            best = min(best, improvements[index][1])
            index += 1
        curve.append((t, best))
    return curve


def _improvements(record: Mapping[str, Any]) -> list[tuple[float, float]]:
    pairs = []
    for item in record.get("improvements") or []:
        if isinstance(item, Sequence) and len(item) >= 2:
            t, cost = _float(item[0]), _float(item[1])
            if math.isfinite(t) and math.isfinite(cost):
                pairs.append((t, cost))
    return sorted(pairs)


def _in_budget(
    record: Mapping[str, Any], time_limit: float | None
) -> tuple[bool, list[tuple[float, float]]]:
    """Whether the run counts as solved and its improvements up to its budget (the record's own,
    else the scenario's time limit), as ``lit bench``'s tables count them
    (:func:`lit_planner.bench.report.solved_in_budget`): a run whose first solution came after
    the budget (LIT* checks it between iterations, OMPL's planners stop on the wall clock) has no
    solution at the budget, and an improvement after it does not count."""
    improvements = _improvements(record)
    budget = _budget(record) or time_limit
    if not budget:
        return _solved(record), improvements
    within = [(t, cost) for t, cost in improvements if t <= budget]
    return _solved(record) and (not improvements or bool(within)), within


def _solved(record: Mapping[str, Any]) -> bool:
    if "solved" in record:
        return bool(record["solved"])
    return math.isfinite(_float(record.get("c_final", record.get("cost"))))


def _status(record: Mapping[str, Any], solved: bool) -> int:
    """The run's status as recorded; an exact solution of a run that does not count as solved
    (its first solution came after the budget) is a timeout, as the solved column says."""
    status = record.get("status")
    if isinstance(status, str) and status in STATUS_INDEX:
        if not solved and status == "exact_solution":
            return STATUS_INDEX["timeout"]
        return STATUS_INDEX[status]
    return STATUS_INDEX["exact_solution" if solved else "timeout"]


def _path_valid(record: Mapping[str, Any]) -> bool | None:
    if isinstance(record.get("path_valid"), bool):
        return bool(record["path_valid"])
    check = record.get("path_check")
    if isinstance(check, Mapping) and isinstance(check.get("ok"), bool):
        return bool(check["ok"])
    return None


def _budget(record: Mapping[str, Any]) -> float | None:
    for key in BUDGET_KEYS:
        value = _float(record.get(key))
        if math.isfinite(value) and value > 0:
            return value
    return None


def _run_time(record: Mapping[str, Any], time_limit: float | None) -> float | None:
    for value in (_float(record.get("time")), _budget(record) or math.nan, time_limit or math.nan):
        if math.isfinite(value) and value >= 0:
            return value
    return None


def _log_names(scenarios: Iterable[str]) -> dict[str, str]:
    """A log file name for each scenario name: its letters and digits (``np4.log``), with a hash
    of the name when that leaves nothing (``-``) or is another scenario's too (``np4`` and
    ``NP4``: one log was written over the other, and its runs were lost from the database)."""
    stems = {name: _UNSAFE.sub("_", name.lower()).strip("_") for name in scenarios}
    counts = collections.Counter(stems.values())
    return {
        name: (
            f"{stem}.log"
            if stem and counts[stem] == 1
            else f"{stem or 'scenario'}_{hashlib.sha256(name.encode()).hexdigest()[:12]}.log"
        )
        for name, stem in stems.items()
    }


def _scenario_name(record: Mapping[str, Any]) -> str:
    return str(record["scenario"]).split("/", 1)[0]


def _instance(record: Mapping[str, Any]) -> int | None:
    value = record.get("instance")
    if isinstance(value, int) and not isinstance(value, bool):
        return value
    _, _, suffix = str(record["scenario"]).partition("/")
    return int(suffix) if suffix.isdigit() else None


def _common_properties(runs: Sequence[Mapping[str, Any]]) -> dict[str, str]:
    """Settings every run of a planner shares: its policy and planner parameters."""
    common: dict[str, str] = {}
    policies = {str(run.get("policy")) for run in runs if run.get("policy") is not None}
    if len(policies) == 1 and len([run for run in runs if run.get("policy") is not None]) == len(
        runs
    ):
        common["policy"] = policies.pop()
    params = [run.get("params") for run in runs]
    if params and all(isinstance(p, Mapping) for p in params):
        for key, value in params[0].items():  # type: ignore[union-attr]
            if all(p.get(key) == value for p in params):  # type: ignore[union-attr]
                common[str(key)] = str(value)
    return common


def _scenario_facts(name: str) -> dict[str, Any]:
    """The registry's facts about ``name`` (empty for a scenario the registry does not know)."""
    from lit_planner import scenarios  # numpy only: safe in any process

    try:
        scenario = scenarios.get(name)
    except ScenarioError:
        return {}
    return {
        "dim": scenario.dim,
        "optimal_cost": scenario.optimal_cost,
        "resolution": scenario.resolution,
        "time_budget": scenario.time_budget,
        "description": scenario.description,
        "randomised": scenario.family_spec.randomised,
    }


def _setup_lines(
    scenario: str, facts: Mapping[str, Any], instances: Sequence[int], limit: float | None
) -> list[str]:
    lines = [f"LIT* benchmark of scenario {scenario}, written by `lit arena` from {RUNS_FILE}."]
    if facts.get("description"):
        lines.append(f"Scenario: {facts['description']}")
        lines.append(f"State validity checking resolution: {facts['resolution']:g} of the "
                     "space's maximum extent; objective: path length.")  # fmt: skip
        if facts.get("randomised"):
            lines.append(f"Instances (random obstacle draws) in this experiment: "
                         f"{', '.join(map(str, instances)) or 'unknown'}.")  # fmt: skip
    else:
        lines.append("Scenario not in this checkout's registry: no further facts.")
    if limit is not None:
        lines.append(f"Time limit per run: {limit:g} s. Memory was not limited.")
    lines.append("Every planner ran on Debian's OMPL 1.5.2 with the same validity checker.")
    lines.append("A run's seed is LIT*'s seed for it; OMPL's planners draw from OMPL's "
                 "process-wide generator, seeded once per benchmark from its first seed, so for "
                 "them the seed names the query, not a seed of their own.")  # fmt: skip
    lines.append("The seconds spent to collect the data are the runs' planning times added up "
                 "(each planner's own clock), not the benchmark's wall time.")  # fmt: skip
    return lines


def _cpu_lines() -> list[str]:
    lines = [f"Platform: {platform.platform()}", f"Processor count: {os.cpu_count()}"]
    try:
        with open("/proc/cpuinfo") as cpuinfo:
            model = next((line.split(":", 1)[1].strip() for line in cpuinfo
                          if line.startswith("model name")), None)  # fmt: skip
    except OSError:
        model = None
    if model:
        lines.insert(0, f"Model name: {model}")
    return lines


def _host(records: Sequence[Mapping[str, Any]]) -> str:
    for record in records:
        for key in ("host", "hostname"):
            if isinstance(record.get(key), str) and record[key].strip():
                return str(record[key]).split()[0]
    return socket.gethostname() or "UNKNOWN"


def _float(value: Any) -> float:
    if value is None or isinstance(value, bool):
        return math.inf if value is None else math.nan
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def _number(value: object) -> str:
    """A value as the log holds it: ``inf`` for unsolved costs, shortest exact float text."""
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf"
        return repr(value)
    return str(value)

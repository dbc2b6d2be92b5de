"""The benchmark runner: every planner on every scenario, run after run, one record per run.

Fairness rules (PDT's): every planner of a run gets the same scenario instance and seed; the
planner order is shuffled per run (seeded, so a benchmark repeats its order); each run plans with
a fresh planner (``lit_core.solve`` builds planner, problem and validity checker per call). LIT*
draws from its own generator, seeded with the run's seed. OMPL 1.5.2's planners draw from OMPL's
process-wide generator, which :func:`run_benchmark` seeds once with the first run's seed
(OMPL accepts that seed once per process), so their runs are seeded as a sequence, not one by one.
Runs stop on time, so no run repeats exactly anyway. Each LIT* planner's policy object is made
once per benchmark and shared by its runs (the planner resets it per problem), so no run reads
the tensor files just before it is timed.

Paths are re-checked independently (:func:`lit_planner.scenarios.check_path`) after each
scenario's planning, in parallel worker processes, so the check neither runs while a planner is
being timed nor doubles the benchmark's duration.

Each record is a ``lit_msgs_json/BenchRun`` document (see that schema): JSON-ready, with ``null``
for the times and costs of a run without a solution (they count as infinite).
"""

from __future__ import annotations

import ctypes
import dataclasses
import hashlib
import multiprocessing
import os
import random
import signal
import sys
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tqdm import tqdm

from lit_planner import planning, scenarios
from lit_planner.errors import MissingTensorsError, PlannerError, TensorFileError

if TYPE_CHECKING:
    import lit_core

RUN_SCHEMA = "lit_msgs_json/BenchRun"
"""Schema of one run record (a line of ``runs.jsonl``)."""
RUN_SCHEMA_VERSION = 1
"""Version of :data:`RUN_SCHEMA` that this module writes."""
PAPER_SCENARIOS = ("np4", "np8", "np16", "rrd4", "rrd8", "rrd16")
"""The LIT* paper's six benchmark scenarios (narrow passage, dense random rectangles)."""
ALL_PLANNERS = (
    "litstar-tensor",
    "litstar-fit",
    "litstar-fixed",
    "aitstar",
    "bitstar",
    "abitstar",
    "irrtstar",
    "rrtconnect",
)
"""Every planner the benchmark knows, LIT*'s three policies first."""
TENSOR_PLANNER = "litstar-tensor"
"""The planner that needs trained lookup tensors."""
SKIPPED_NO_TENSORS = "skipped: no trained tensors"
"""Reason recorded when ``litstar-tensor`` cannot run (the folder is named in the detail)."""
SHUFFLE_KEY = "lit bench/{scenario}/{instance}/{run}/{seed}"
"""String seeding each run's planner order (``random.Random`` hashes strings stably)."""


@dataclass(frozen=True)
class Preset:
    """Named benchmark sizes: ``--quick`` and ``--paper``."""

    scenarios: tuple[str, ...]
    """Scenarios it runs."""
    runs: int
    """Runs per scenario and planner."""
    purpose: str
    """One line for ``--help``."""


PRESETS: dict[str, Preset] = {
    "quick": Preset(("np4", "rrd4"), 5, "np4 and rrd4, 5 runs, every planner: for development"),
    "paper": Preset(PAPER_SCENARIOS, 100, "the paper's six scenarios, 100 runs: the reproduction"),
}
"""The presets by name."""


@dataclass(frozen=True)
class BenchConfig:
    """What one benchmark runs."""

    scenarios: tuple[str, ...]
    """Scenario names (registry names without instance suffix)."""
    planners: tuple[str, ...]
    """Planners to run (after skipping the unavailable ones)."""
    runs: int
    """Runs per scenario and planner."""
    first_seed: int = 1
    """Seed of run 0; run i has seed ``first_seed + i``."""
    instance: int = 0
    """Instance of the random scenario families (the fixed ones always run their only one, 0)."""
    time_scale: float = 1.0
    """Factor on every scenario's own (the paper's) time budget."""
    tensors_dir: Path | None = None
    """Tensor folder of ``litstar-tensor``; None: :func:`planning.default_tensors_dir`."""
    check_jobs: int = 1
    """Worker processes for the independent path checks."""
    t_init_repeats: int = 1
    """LIT* planners only: each solved run's first solution is timed this many times in all, the
    full run and then reruns of the same seed stopped at the first solution's iteration (the same
    search, so only the timing noise differs); the record's t_init is the smallest."""
    skipped: tuple[Skip, ...] = ()
    """Planners that were asked for but do not run, with the reason."""

    def __post_init__(self) -> None:
        try:
            budgets = [scenario_for(name, self.instance).time_budget for name in self.scenarios]
        except ValueError:  # an unknown scenario: named where it is used
            budgets = []
        problem = planning.scale_problem(
            "--time-scale", self.time_scale, max(budgets, default=0.0), min(budgets, default=0.0)
        )
        if problem is not None:
            raise ValueError(problem)
        if self.t_init_repeats < 1:
            raise ValueError(f"--t-init-repeats must be at least 1, got {self.t_init_repeats}")
        others = [p for p in self.planners if planning.resolve_planner(p)[0] != planning.LITSTAR]
        if self.t_init_repeats > 1 and others:
            raise ValueError(
                f"--t-init-repeats {self.t_init_repeats} repeats LIT* runs only (OMPL's planners "
                "draw from a shared generator, so a rerun is another search); the smallest of "
                f"several times would be compared with single times of {', '.join(others)}: "
                "benchmark those without it"
            )

    def time_budget(self, scenario: scenarios.Scenario) -> float:
        """The budget every planner gets on ``scenario``."""
        return scenario.time_budget * self.time_scale


@dataclass(frozen=True)
class Skip:
    """A requested planner that the benchmark does not run."""

    planner: str
    """Its name."""
    reason: str
    """Short reason, e.g. :data:`SKIPPED_NO_TENSORS`."""
    detail: str = ""
    """Where it looked, what is missing."""


@dataclass
class PlannerSetup:
    """How a planner is configured; the same for every run."""

    name: str
    core_planner: str
    policy: str | None
    params: dict[str, str] = field(default_factory=dict)
    """Parameter overrides by ``declareParam`` name; empty: the planner's defaults."""
    tensors: dict[str, Any] | None = None
    """For the tensor policy: folder and SHA-256 of each tensor file."""

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def _is_terminal(stream: Any) -> bool:
    """Whether ``stream`` is a terminal (False for one without ``isatty``, or closed)."""
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


def scenario_for(name: str, instance: int = 0) -> scenarios.Scenario:
    """Scenario ``name``; ``instance`` applies to the random families, the fixed ones have only 0."""
    family = scenarios.get(name, suffix=False).family_spec
    return scenarios.get(name, instance if family.randomised else 0, suffix=False)


def select_planners(
    planners: Sequence[str], tensors_dir: Path | None = None
) -> tuple[list[str], list[Skip], dict[str, Any]]:
    """Split ``planners`` into those that run and those skipped (no trained tensors in the
    default folder, ``$LIT_TENSORS`` or the checkout's ``tensors/``); the third item holds the
    policy objects made on the way (the ``tensor`` policy's, to be handed to
    :func:`benchmark_policies` so that the files are read once).

    Raises:
        MissingTensorsError: ``tensors_dir`` was given and holds no tensors.
        PlannerError: an unknown planner name.
        TensorFileError: tensors exist but are defective (never skipped silently).
    """
    for name in planners:
        if name not in ALL_PLANNERS:  # planning's own list holds names that lit bench does not run
            raise PlannerError(
                f"lit bench has no planner {name!r}; expected one of {', '.join(ALL_PLANNERS)}"
            )
    running, skipped, made = [], [], {}
    for name in planners:
        if name == TENSOR_PLANNER:
            try:
                made[name] = planning.make_policy("tensor", tensors_dir)
            except MissingTensorsError as error:
                if tensors_dir is not None:  # asked for by name: not skipped quietly
                    raise
                skipped.append(Skip(name, SKIPPED_NO_TENSORS, str(error)))
                continue
        running.append(name)
    return running, skipped, made


def benchmark_policies(
    planners: Sequence[str], tensors_dir: Path | None = None, made: dict[str, Any] | None = None
) -> dict[str, Any]:
    """Each planner's LIT* policy object (None for the OMPL planners), made once per benchmark
    and reused by all its runs and reruns (the planner resets a policy for each problem);
    ``made``: policy objects already made (:func:`select_planners`), used as they are.

    The ``tensor`` policy's files are read here, before the first run, as a planner node reads
    them once: reading them (two 4 MB tensors, checked and hashed) just before every timed run
    evicted the planner's data from the caches and cost ``litstar-tensor`` about 6 % of its
    np4 t_init, a handicap no other planner had.

    Raises:
        MissingTensorsError, TensorFileError: as :func:`planning.make_policy`.
    """
    policies: dict[str, Any] = {}
    for name in planners:
        _, policy = planning.resolve_planner(name)
        if made is not None and name in made:
            policies[name] = made[name]
        else:
            policies[name] = (
                None
                if policy is None
                else planning.make_policy(policy, tensors_dir if policy == "tensor" else None)
            )
    return policies


def planner_setup(
    name: str, tensors_dir: Path | None = None, policy_object: Any = None
) -> PlannerSetup:
    """The configuration of planner ``name`` as the benchmark runs it; ``policy_object``: its
    :func:`benchmark_policies` entry, whose parameters (:func:`planning.policy_params`) are
    listed."""
    core, policy = planning.resolve_planner(name)
    tensors = None
    if policy == "tensor":
        folder = planning.default_tensors_dir() if tensors_dir is None else Path(tensors_dir)
        tensors = {"folder": str(folder)}
        origins: dict[str, str | None] = {}
        for output, file_name in planning.TENSOR_FILES.items():
            path = folder / file_name
            tensors[output] = _sha256(path) if path.exists() else None
            origins[output] = tensor_origin(path) if path.exists() else None
        tensors["origins"] = origins
    return PlannerSetup(name, core, policy, planning.policy_params(policy_object), tensors)


def tensor_origin(path: Path) -> str | None:
    """What made the tensor at ``path``, from its sidecar: ``constant <value>`` (``lit tensors
    constant``), ``trained, policy version <n>``, or ``UNTRAINED (initial weights), policy
    version <n>`` for a learner's export whose agent made no gradient update (such an export, of
    the learner node or of an older ``lit train``, was called trained); None when the sidecar
    does not read."""
    from lit_planner import tensor_files

    try:
        sidecar = tensor_files.read_sidecar(path)
    except (TensorFileError, OSError):
        return None
    constant = sidecar.provenance.get("constant")
    if isinstance(constant, int | float) and not isinstance(constant, bool):
        return f"constant {constant:g}"
    updates = sidecar.training.get("updates") if isinstance(sidecar.training, dict) else None
    if updates == 0:
        return f"UNTRAINED (initial weights), policy version {sidecar.policy_version}"
    return f"trained, policy version {sidecar.policy_version}"


def planning_estimate(
    scenario_names: Sequence[str], planner_count: int, runs: int, time_scale: float = 1.0
) -> float:
    """Seconds of planning alone: runs x planners x the sum of the scenarios' budgets."""
    budgets = sum(scenarios.get(name).time_budget for name in scenario_names)
    return runs * planner_count * budgets * time_scale


def run_order(
    planners: Sequence[str], scenario: str, instance: int, run: int, seed: int
) -> list[str]:
    """The planners of one run in their shuffled, reproducible order."""
    order = list(planners)
    key = SHUFFLE_KEY.format(scenario=scenario, instance=instance, run=run, seed=seed)
    random.Random(key).shuffle(order)
    return order


def make_record(
    result: dict[str, Any],
    *,
    planner: str,
    run: int,
    order: int,
    budget: float,
    wall_time: float,
    scenario: scenarios.Scenario,
    params: dict[str, str],
    t_init_runs: Sequence[float] | None = None,
) -> dict[str, Any]:
    """A ``BenchRun`` record from :func:`planning.plan`'s result (path not yet checked).

    ``t_init_runs``: the first solution's times of the repeated runs (:func:`time_first_solution`),
    the full run's first; the record's ``t_init`` is then their minimum.
    """
    solved = bool(result["solved"])
    core_planner, _ = planning.resolve_planner(planner)
    repeated = solved and t_init_runs is not None and len(t_init_runs) > 1
    record = planning.json_safe(
        {
            "schema": RUN_SCHEMA,
            "version": RUN_SCHEMA_VERSION,
            "scenario": scenario.name,
            "scenario_key": scenario.key,
            "instance": scenario.instance,
            "dimension": scenario.dim,
            "run": run,
            "seed": result["seed"],
            "order": order,
            "planner": planner,
            "core_planner": core_planner,
            "policy": result.get("policy"),
            "params": params,
            "time_budget": budget,
            "status": result["status"],
            "message": result.get("message", ""),
            "solved": solved,
            "t_init": (min(t_init_runs) if repeated else result["t_init"]) if solved else None,
            "c_init": result["c_init"] if solved else None,
            "c_final": result["cost"] if solved else None,
            "checks_init": result["checks_init"] if solved else None,
            "improvements": [list(pair) for pair in result["improvements"]] if solved else [],
            "time": result["time"],
            "wall_time": wall_time,
            "path_valid": None,
            "path_check": None,
            "path_states": len(result["path"]),
            "path": result["path"],
            "counters": dict(result["counters"]),
            "optimal_cost": scenario.optimal_cost,
        }
    )
    if repeated:
        record["t_init_runs"] = [float(value) for value in t_init_runs]
    return record


def time_first_solution(
    result: dict[str, Any],
    problem: scenarios.Scenario,
    planner: str,
    *,
    repeats: int,
    seed: int,
    policy: lit_core.ParameterPolicy | None,
) -> list[float] | None:
    """The first solution's time of a solved LIT* run, then of ``repeats - 1`` reruns of the same
    seed stopped at the iteration that found it (None when there is nothing to repeat).
    ``policy``: the run's policy object (:func:`benchmark_policies`), reused by the reruns.

    LIT*'s search is a function of its seed and policy, so every rerun finds the same first
    solution after the same work, and only the timing noise differs; a rerun that does not is an
    error, as the comparison would then not be like for like.

    Raises:
        PlannerError: a rerun found another first solution (cost or validity checks differ).
    """
    if repeats <= 1 or not result["solved"] or result.get("iteration_init") is None:
        return None
    times = [float(result["t_init"])]
    for _ in range(repeats - 1):
        # No time limit: the iteration limit alone ends the rerun (a budget could cut off a
        # rerun a little slower than a run that solved near its end).
        rerun = planning.plan_interruptibly(
            problem,
            planner,
            time=None,
            policy=policy,
            seed=seed,
            max_iterations=int(result["iteration_init"]),
            check_path=False,
            features=False,
        )
        if not rerun["solved"]:
            raise PlannerError(
                f"{planner} on {problem.name} seed {seed}: a rerun stopped at iteration "
                f"{result['iteration_init']} found no solution ({rerun['status']}), the run found "
                f"its first there: not deterministic, so --t-init-repeats cannot compare its times"
            )
        same = rerun["c_init"] == result["c_init"] and rerun["checks_init"] == result["checks_init"]
        if not same:
            raise PlannerError(
                f"{planner} on {problem.name} seed {seed}: a rerun to the first solution found "
                f"c_init {rerun['c_init']} after {rerun['checks_init']} checks, the run "
                f"{result['c_init']} after {result['checks_init']}: not deterministic, so "
                "--t-init-repeats cannot compare its times"
            )
        times.append(float(rerun["t_init"]))
    return times


def check_record_paths(records: list[dict[str, Any]], jobs: int = 1) -> None:
    """Fill ``path_valid`` and ``path_check`` of every record with a path, in place."""
    todo = [record for record in records if record["path"]]
    tasks = [(record["scenario"], record["instance"], record["path"]) for record in todo]
    if jobs > 1 and len(tasks) > 1:
        # spawn: a fresh interpreter per worker, unaffected by the planner's threads and state.
        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(
            min(jobs, len(tasks)),
            mp_context=context,
            initializer=end_with_parent,
            initargs=(os.getpid(),),
        ) as pool:
            checks = list(pool.map(_check_path, tasks, chunksize=max(1, len(tasks) // (4 * jobs))))
    else:
        checks = [_check_path(task) for task in tasks]
    for record, check in zip(todo, checks, strict=True):
        record["path_check"] = planning.json_safe(check)
        record["path_valid"] = bool(check["ok"])


PR_SET_PDEATHSIG = 1
"""prctl(2) option: the signal the calling process gets when its parent thread ends."""


def end_with_parent(parent: int) -> None:
    """Worker initializer: end this process with SIGTERM when ``parent`` ends (Linux's
    ``PR_SET_PDEATHSIG``). A ``lit bench`` that is SIGKILLed runs no clean-up, and its idle
    path-check workers used to stay behind. Elsewhere, or if prctl fails, nothing changes."""
    if not sys.platform.startswith("linux"):
        return
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        zero = ctypes.c_ulong(0)
        if libc.prctl(PR_SET_PDEATHSIG, ctypes.c_ulong(signal.SIGTERM), zero, zero, zero) != 0:
            return
    except (OSError, AttributeError):
        return
    if os.getppid() != parent:  # the parent ended before prctl took effect
        os.kill(os.getpid(), signal.SIGTERM)


def _check_path(task: tuple[str, int, list[list[float]]]) -> dict[str, Any]:
    name, instance, path = task
    return dataclasses.asdict(scenarios.check_path(scenarios.get(name, instance), path))


def run_benchmark(
    config: BenchConfig,
    on_scenario_done: Callable[[list[dict[str, Any]]], None] | None = None,
    progress_file: Any = None,
    policies: Mapping[str, Any] | None = None,
) -> list[dict[str, Any]]:
    """Run the benchmark; return every record in execution order.

    Args:
        config: what to run.
        on_scenario_done: called with a scenario's records once they are checked (the CLI
            appends them to ``runs.jsonl`` there, so an interrupted benchmark keeps its data).
        progress_file: where the progress bar goes (default stderr).
        policies: :func:`benchmark_policies` of ``config``'s planners, made here when None.

    Raises:
        MissingTensorsError, TensorFileError: making the policies here failed.
        PlannerError: a ``t_init_repeats`` rerun did not repeat its run.
    """
    import lit_core  # the C++ extension: only when planning really starts

    lit_core.set_global_seed(planning.ompl_global_seed(config.first_seed))
    problems = [scenario_for(name, config.instance) for name in config.scenarios]
    if policies is None:
        policies = benchmark_policies(config.planners, config.tensors_dir)
    total = sum(config.time_budget(p) for p in problems) * config.runs * len(config.planners)
    records: list[dict[str, Any]] = []
    stream = progress_file or sys.stderr
    on_terminal = _is_terminal(stream)
    bar = tqdm(
        total=total,
        unit="s",
        file=stream,
        dynamic_ncols=True,
        # Not on a terminal (a log file, CI): a frame every 30 s at most, not 10 a second (a
        # 15 s --quick run left 13 KB of them).
        mininterval=0.1 if on_terminal else 30.0,
        maxinterval=10.0 if on_terminal else 30.0,  # tqdm's monitor redraws after maxinterval
        bar_format="{desc} |{bar}| {percentage:3.0f}% of planning time [{elapsed}<{remaining}]",
    )
    with bar:
        for problem in problems:
            budget = config.time_budget(problem)
            scenario_records = []
            for run, seed, order in _runs(config, problem):
                for position, planner in enumerate(order):
                    bar.set_description_str(
                        f"{problem.name} run {run + 1}/{config.runs} {planner:<14}",
                        refresh=on_terminal,
                    )
                    planning.quiet_ompl(planner)
                    started = time.perf_counter()
                    result = planning.plan_interruptibly(
                        problem,
                        planner,
                        policy=policies[planner],
                        time=budget,
                        seed=seed,
                        check_path=False,
                        features=False,  # no record keeps the decisions
                    )
                    wall = time.perf_counter() - started
                    t_init_runs = time_first_solution(
                        result,
                        problem,
                        planner,
                        repeats=config.t_init_repeats,
                        seed=seed,
                        policy=policies[planner],
                    )
                    scenario_records.append(
                        make_record(
                            result,
                            planner=planner,
                            run=run,
                            order=position,
                            budget=budget,
                            wall_time=wall,
                            scenario=problem,
                            params=planning.policy_params(policies[planner]),
                            t_init_runs=t_init_runs,
                        )
                    )
                    bar.update(min(budget, bar.total - bar.n))  # float sums overshoot
            bar.set_description_str(
                f"{problem.name} checking {len(scenario_records)} paths", refresh=on_terminal
            )
            check_record_paths(scenario_records, config.check_jobs)
            records.extend(scenario_records)
            if on_scenario_done is not None:
                on_scenario_done(scenario_records)
    return records


def _runs(config: BenchConfig, problem: scenarios.Scenario) -> Iterator[tuple[int, int, list[str]]]:
    for run in range(config.runs):
        seed = config.first_seed + run
        planning.check_seed(seed)
        yield run, seed, run_order(config.planners, problem.name, problem.instance, run, seed)


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()

"""``lit bench``: the benchmark in the manner of the Planner Developer Tools.

::

    lit bench --quick                  # np4 and rrd4, 5 runs, every planner (development)
    lit bench --paper                  # the paper's six scenarios, 100 runs (the reproduction)
    lit bench --scenarios np8 --planners litstar-fixed,aitstar --runs 20 --out results/np8

Writes into the run folder (``--out``, default ``results/<timestamp>``): ``runs.jsonl`` (one
``BenchRun`` record per line, appended scenario by scenario), ``summary.json`` (a validated
``BenchSummary``), ``summary.md`` (the tables) and ``plots/<scenario>.png|.pdf``. It also records
a bag ``bags/<run folder name>/`` (``--bag-dir``, ``--no-bag``): a ``/lit/bench/config`` message,
then one ``/lit/bench/run`` message per record, from which ``lit replay bench`` regenerates the
outputs.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import signal
import sys
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from lit_planner import argtypes, bag, planning, scenarios, signals
from lit_planner.bench import runner
from lit_planner.errors import LitPlannerError

RUNS_FILE = "runs.jsonl"
SUMMARY_JSON = "summary.json"
SUMMARY_MD = "summary.md"
PLOTS_DIR = "plots"
DEFAULT_OUT = "results/{timestamp}"
"""Run folder when ``--out`` is not given (relative to the working directory)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``lit bench``."""
    presets = parser.add_mutually_exclusive_group()
    for name, preset in runner.PRESETS.items():
        presets.add_argument(f"--{name}", action="store_true", help=preset.purpose)
    parser.add_argument(
        "--scenarios",
        help="comma-separated scenario names (default: the preset's, else "
        f"{','.join(runner.PAPER_SCENARIOS)})",
    )
    parser.add_argument(
        "--planners",
        help=f"comma-separated planners (default: all: {','.join(runner.ALL_PLANNERS)})",
    )
    parser.add_argument(
        "--runs", type=int, help="runs per scenario and planner (default: the preset's, else 100)"
    )
    parser.add_argument(
        "--out",
        type=argtypes.path,
        help="run folder (default: results/<timestamp>); must be new or empty",
    )
    parser.add_argument(
        "--time-scale",
        type=float,
        default=1.0,
        metavar="F",
        help="multiply every scenario's (the paper's) time budget by F (default: 1)",
    )
    parser.add_argument(
        "--t-init-repeats",
        type=int,
        default=1,
        metavar="K",
        help="LIT* planners only: time each solved run's first solution K times in all (reruns "
        "of the same seed stopped there: the same search) and keep the smallest, which removes "
        "most timing noise from t_init (default: 1)",
    )
    parser.add_argument("--seed", type=int, default=1, help="seed of the first run (default: 1)")
    parser.add_argument(
        "--instance",
        type=int,
        default=0,
        help="instance of the random scenario families (rr, rrd) for every run (default: 0)",
    )
    parser.add_argument(
        "--tensors",
        type=argtypes.path,
        metavar="DIR",
        help="trained tensors for litstar-tensor (default: $LIT_TENSORS, else tensors/)",
    )
    parser.add_argument(
        "--check-jobs",
        type=int,
        default=os.cpu_count() or 1,
        metavar="N",
        help="processes for the independent path checks between scenarios (default: all cores)",
    )
    parser.add_argument(
        "--bag-dir",
        type=argtypes.path,
        metavar="DIR",
        help="record the bag into DIR/<run folder name> (default: the repository's bags/)",
    )
    parser.add_argument("--no-bag", action="store_true", help="do not record a bag")


def _remove_if_nothing_ran(runs_path: Path, out: Path, out_existed: bool) -> bool:
    """Remove an empty ``runs_path``, and ``out`` if this run made it and nothing else is in
    it; whether ``runs_path`` was empty."""
    try:
        if runs_path.stat().st_size:
            return False
        runs_path.unlink()
        if not out_existed:
            out.rmdir()  # only if empty: whatever else is there stays
    except OSError:
        pass
    return True


def run(args: argparse.Namespace) -> int:
    """Run ``lit bench``; 0 on success, 1 when a returned path failed the re-check, 2 bad input."""
    try:
        config, preset, requested, made = _config(args)
        # The policies (the tensor files) are read once, when the planners are selected, before
        # anything starts; the configuration with their SHA-256 is taken right after and goes
        # into bag and summary.
        policies = runner.benchmark_policies(config.planners, config.tensors_dir, made)
        setups = planner_setups(config, policies)
        out_existed = args.out is not None and args.out.resolve().exists()
        out = _out_dir(args.out)
    except (LitPlannerError, ValueError) as error:
        print(f"lit bench: {error}", file=sys.stderr)
        return 2
    for skip in config.skipped:
        print(f"lit bench: {skip.planner} {skip.reason} ({skip.detail})", file=sys.stderr)
    estimate = runner.planning_estimate(
        config.scenarios, len(config.planners), config.runs, config.time_scale
    )
    formula = _estimate_formula(config, estimate)
    print(f"lit bench: {formula}", file=sys.stderr)
    print(f"lit bench: writing to {out}", file=sys.stderr)

    started = datetime.now(UTC)
    # The machine and the versions as the benchmark starts (the checkout or the built core may
    # change while it runs): the bag and both outputs record these.
    facts = _environment_facts()
    clock = time.perf_counter()
    runs_path = out / RUNS_FILE
    runs_path.touch()
    recording = None
    if not args.no_bag:
        try:
            recording = _start_recording(
                args, out, config, preset, requested, started, estimate, setups, facts
            )
        except (bag.BagError, OSError) as error:
            print(f"lit bench: {error}", file=sys.stderr)
            # Nothing ran: leave no output folder behind, which would block the retry.
            runs_path.unlink(missing_ok=True)
            if not out_existed:
                shutil.rmtree(out, ignore_errors=True)
            return 2
        print(f"lit bench: recording the bag {recording.recorder.path}", file=sys.stderr)

    def append(records: list[dict[str, Any]]) -> None:
        """A scenario's records into runs.jsonl and the bag: each tried even when the other
        fails (a full disk, a folder in the way), so they are kept where they can be."""
        from lit_msgs_json import codec

        errors: list[Exception] = []
        try:
            with runs_path.open("a", encoding="utf-8") as handle:
                for record in records:
                    handle.write(codec.dumps(runner.RUN_SCHEMA, record) + "\n")
        except OSError as error:
            errors.append(error)
        if recording is not None:
            try:
                recording.add_runs(records)
            except (bag.BagError, OSError) as error:
                errors.append(error)
        if errors:
            raise errors[0]

    # `kill PID`, or the terminal closing (SIGHUP), stops like Ctrl-C: the bag gets its summary
    # and metadata.yaml on the way out.
    try:
        with signals.handling((signal.SIGTERM, signal.SIGHUP), signal.default_int_handler):
            records = runner.run_benchmark(config, on_scenario_done=append, policies=policies)
            duration = time.perf_counter() - clock
            finished = datetime.now(UTC)
            if recording is not None:  # for `lit replay bench`: the stamps do not span all of it
                recording.finish(finished, duration)
    except KeyboardInterrupt:
        if _remove_if_nothing_ran(runs_path, out, out_existed):
            # An empty runs.jsonl blocked the retry with the same --out ("not empty").
            empty_bag = (
                f"; the bag {recording.recorder.path} holds no runs"
                if recording is not None
                else ""
            )
            print(
                f"lit bench: interrupted before a scenario finished: nothing kept in {out}"
                f"{empty_bag}",
                file=sys.stderr,
            )
            return 130
        tables = (
            f"; `lit replay bench {recording.recorder.path}` makes tables of them"
            if recording is not None
            else ""
        )
        print(
            f"lit bench: interrupted; {runs_path} holds the runs of the finished scenarios (not "
            f"those of the scenario it was planning){tables}",
            file=sys.stderr,
        )
        return 130
    except (LitPlannerError, OSError) as error:
        # A --t-init-repeats rerun that did not repeat its run; records that could not be
        # written (a full disk, a folder in the way): one line, not a traceback.
        print(
            f"lit bench: {error}; {runs_path} holds the runs of the finished scenarios",
            file=sys.stderr,
        )
        return 1
    finally:
        if recording is not None:
            recording.close()

    # Planner Arena database from OMPL benchmark logs (PyPI ompl, in its own process).
    from lit_planner import arena, ompl2

    try:
        write_outputs(
            out,
            records,
            config,
            preset=preset,
            requested=requested,
            started=started,
            finished=finished,
            duration=duration,
            estimate=(estimate, formula),
            planners=setups,
            environment_facts=facts,
        )
        print((out / SUMMARY_MD).read_text(encoding="utf-8"))
        export = arena.export_arena(out, records)
        print(
            f"lit bench: Planner Arena database {export.database} ({len(export.logs)} OMPL logs)",
            file=sys.stderr,
        )
    except (arena.ArenaError, ompl2.Ompl2Error) as error:
        print(f"lit bench: Planner Arena export failed: {error}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:  # every run is recorded: only the tables and plots are missing
        again = (
            f"; `lit replay bench {recording.recorder.path}` writes them"
            if recording is not None
            else ""
        )
        print(
            f"lit bench: interrupted while writing the outputs (those in {out} may be partial); "
            f"{runs_path} holds every run" + again,
            file=sys.stderr,
        )
        return 130
    invalid = sum(1 for r in records if r["solved"] and r["path_valid"] is False)
    print(
        f"lit bench: {len(records)} runs in "
        + (f"{duration:.1f} s" if duration < 60 else f"{duration / 60:.1f} min")
        + f"; {invalid} returned paths "
        f"failed the independent re-check; outputs in {out}",
        file=sys.stderr,
    )
    return 1 if invalid else 0


def write_outputs(
    out: Path,
    records: list[dict[str, Any]],
    config: runner.BenchConfig,
    *,
    preset: str | None,
    requested: list[str],
    started: datetime,
    finished: datetime,
    duration: float,
    estimate: tuple[float, str],
    argv: list[str] | None = None,
    recorded: dict[str, Any] | None = None,
    planners: dict[str, Any] | None = None,
    incomplete: dict[str, Any] | None = None,
    environment_facts: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Compute the statistics, draw the plots, validate and write summary.json and summary.md.

    ``recorded`` (``lit replay bench``): the recorded run's ``cwd``, ``machine``, ``versions`` and
    ``planners`` instead of this process's. ``planners``: the planners' configuration as taken
    when the benchmark read its policies (:func:`planner_setups` now when None). ``incomplete``
    (``lit replay bench``): ``planned``, ``read`` and ``note`` when records are missing; both
    files then say so first. ``environment_facts``: ``machine`` and ``versions`` as taken when
    the benchmark started (now when None and not ``recorded``).
    """
    from lit_msgs_json import codec
    from lit_planner.bench import plots, report, stats

    scenario_info = {}
    for name in config.scenarios:
        problem = runner.scenario_for(name, config.instance)
        scenario_info[name] = {
            "name": problem.name,
            "key": problem.key,
            "instance": problem.instance,
            "dimension": problem.dim,
            "time_budget": config.time_budget(problem),
            "optimal_cost": problem.optimal_cost,
            "description": problem.description,
        }
    summaries, curves = report.scenario_summaries(records, scenario_info, config.planners)
    plot_files: dict[str, list[str]] = {}
    for name, (_, planner_curves) in curves.items():
        if planner_curves:
            paths = plots.plot_scenario(name, summaries[name], planner_curves, out / PLOTS_DIR)
            plot_files[name] = [str(path.relative_to(out)) for path in paths]
    facts = environment_facts if environment_facts is not None else _environment_facts()
    setups = recorded["planners"] if recorded else planners or planner_setups(config)
    cwd = recorded["cwd"] if recorded else os.getcwd()
    summary = {
        "schema": report.SUMMARY_SCHEMA,
        "version": report.SUMMARY_SCHEMA_VERSION,
        **({"incomplete": incomplete} if incomplete else {}),
        "started": started.isoformat(timespec="seconds"),
        "finished": finished.isoformat(timespec="seconds"),
        "duration_s": duration,
        "command": {
            "argv": argv if argv is not None else ["lit", *sys.argv[1:]],
            "cwd": cwd,
            "preset": preset,
        },
        "config": summary_config(config, requested),
        "estimate": {"planning_s": estimate[0], "formula": estimate[1]},
        "skipped": [
            {"planner": s.planner, "reason": s.reason, "detail": s.detail} for s in config.skipped
        ],
        "machine": (recorded or facts)["machine"],
        "versions": (recorded or facts)["versions"],
        "planners": setups,
        "scenarios": summaries,
        "comparisons": report.comparisons(
            summaries,
            config.planners,
            [s.planner for s in config.skipped],
            records,
            (setups.get(runner.TENSOR_PLANNER) or {}).get("tensors"),
            cwd,
        ),
        "statistics": {
            "interval_rule": report.CI_RULE,
            "paired_rule": report.PAIRED_RULE,
            "min_runs_for_interval": stats.MIN_RUNS_FOR_INTERVAL,
        },
        "runs": [{k: v for k, v in r.items() if k != "path"} for r in records],
        "outputs": {"summary_md": SUMMARY_MD, "runs_jsonl": RUNS_FILE, "plots": plot_files},
    }
    codec.validate(report.SUMMARY_SCHEMA, summary)
    (out / SUMMARY_JSON).write_text(
        json.dumps(summary, allow_nan=False, indent=1), encoding="utf-8"
    )
    (out / SUMMARY_MD).write_text(report.markdown(summary), encoding="utf-8")
    return summary


def summary_config(config: runner.BenchConfig, requested: list[str]) -> dict[str, Any]:
    """The ``config`` section of summary.json (also the core of the recorded BenchConfig)."""
    from lit_planner.bench import stats

    return {
        "scenarios": list(config.scenarios),
        "planners_requested": requested,
        "planners": list(config.planners),
        "runs": config.runs,
        "first_seed": config.first_seed,
        "instance": config.instance,
        "time_scale": config.time_scale,
        "t_init_repeats": config.t_init_repeats,
        "confidence": stats.CONFIDENCE,
        "ompl_global_seed": planning.ompl_global_seed(config.first_seed),
        "shuffle": f"random.Random({runner.SHUFFLE_KEY!r}).shuffle(planners) per run",
        "check_jobs": config.check_jobs,
        "tensors_dir": str(config.tensors_dir or planning.default_tensors_dir()),
    }


def planner_setups(
    config: runner.BenchConfig, policies: dict[str, Any] | None = None
) -> dict[str, Any]:
    """The ``planners`` section of summary.json: every planner's configuration (``policies``:
    the benchmark's policy objects, whose parameters are listed)."""
    policies = policies or {}
    return {
        name: runner.planner_setup(name, config.tensors_dir, policies.get(name)).to_dict()
        for name in config.planners
    }


def _start_recording(
    args: argparse.Namespace,
    out: Path,
    config: runner.BenchConfig,
    preset: str | None,
    requested: list[str],
    started: datetime,
    estimate: float,
    setups: dict[str, Any],
    facts: dict[str, Any],
) -> bag.BenchRecording:
    """Open the run's bag and record its BenchConfig: everything ``lit replay bench`` needs
    besides the run records (the summary's config, command and environment)."""
    payload = {
        "config": summary_config(config, requested),
        "preset": preset,
        "argv": ["lit", *sys.argv[1:]],
        "cwd": os.getcwd(),
        "started": started.isoformat(timespec="seconds"),
        "estimate": {"planning_s": estimate, "formula": _estimate_formula(config, estimate)},
        "skipped": [
            {"planner": s.planner, "reason": s.reason, "detail": s.detail} for s in config.skipped
        ],
        "machine": facts["machine"],
        "versions": facts["versions"],
        "planners": setups,
    }
    parent = args.bag_dir if args.bag_dir is not None else bag.default_bag_root()
    return bag.BenchRecording(bag.unique_directory(parent, out.name), out.name, payload)


def _environment_facts() -> dict[str, Any]:
    """This machine and the versions of the code and libraries (``machine``, ``versions``)."""
    from lit_planner.bench import environment

    root = Path(__file__).resolve().parents[3]
    return {"machine": environment.machine(), "versions": environment.versions(root)}


def _config(
    args: argparse.Namespace,
) -> tuple[runner.BenchConfig, str | None, list[str], dict[str, Any]]:
    if args.no_bag and args.bag_dir is not None:
        raise ValueError(f"--bag-dir {args.bag_dir} and --no-bag contradict each other: choose one")
    preset_name = next((name for name in runner.PRESETS if getattr(args, name)), None)
    preset = runner.PRESETS[preset_name] if preset_name else runner.PRESETS["paper"]
    # An option given but empty (--scenarios "") is an error below, not the preset's list.
    scenario_names = (
        scenarios.split_names(args.scenarios)
        if args.scenarios is not None
        else list(preset.scenarios)
    )
    planners = (
        scenarios.split_names(args.planners)
        if args.planners is not None
        else list(runner.ALL_PLANNERS)
    )
    runs = args.runs if args.runs is not None else preset.runs
    if runs < 1:
        raise ValueError(f"--runs must be at least 1, got {runs}")
    if not (math.isfinite(args.time_scale) and args.time_scale > 0):
        raise ValueError(f"--time-scale must be a positive number, got {args.time_scale}")
    if args.check_jobs < 1:
        raise ValueError(f"--check-jobs must be at least 1, got {args.check_jobs}")
    if args.instance < 0:  # the fixed scenarios ignore it: checked here, not after the runs
        raise ValueError(f"--instance must be 0 or more, got {args.instance}")
    planning.check_seed(args.seed)
    if args.seed + runs - 1 > planning.MAX_SEED:
        raise ValueError(
            f"--runs {runs} from --seed {args.seed} would use seeds up to {args.seed + runs - 1}, "
            f"beyond the largest seed {planning.MAX_SEED}"
        )
    if not scenario_names or not planners:
        raise ValueError("need at least one scenario and one planner")
    scenarios.refuse_duplicates("scenario", scenario_names)
    scenarios.refuse_duplicates("planner", planners)
    for name in scenario_names:
        if "/" in name:
            raise ValueError(
                f"scenario {name!r}: give the instance with --instance, not in the name"
            )
        runner.scenario_for(name, args.instance)
    if args.tensors is not None and runner.TENSOR_PLANNER not in planners:
        raise ValueError(
            f"--tensors is for {runner.TENSOR_PLANNER}, which is not among the planners "
            f"({', '.join(planners)})"
        )
    running, skipped, made = runner.select_planners(planners, args.tensors)
    if not running:  # with the reasons, which are printed only once a configuration stands
        raise ValueError(
            "none of the requested planners can run: "
            + "; ".join(f"{skip.planner} {skip.reason} ({skip.detail})" for skip in skipped)
        )
    config = runner.BenchConfig(  # checks --t-init-repeats against the planners
        scenarios=tuple(scenario_names),
        planners=tuple(running),
        runs=runs,
        first_seed=args.seed,
        instance=args.instance,
        time_scale=args.time_scale,
        tensors_dir=args.tensors,
        check_jobs=args.check_jobs,
        skipped=tuple(skipped),
        t_init_repeats=args.t_init_repeats,
    )
    return config, preset_name, planners, made


def _out_dir(requested: Path | None) -> Path:
    if requested is None:
        stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
        requested = Path(DEFAULT_OUT.format(timestamp=stamp))
    out = requested.resolve()
    problem = bag.output_folder_problem(out)
    if problem is not None:
        raise ValueError(f"--out {requested}: {problem}; choose a new or empty folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:  # a path under a file, a folder we may not write, ...
        raise ValueError(f"--out {requested}: {error.strerror or error}") from None
    return out


def _estimate_formula(config: runner.BenchConfig, estimate: float) -> str:
    budgets = [scenarios.get(name).time_budget * config.time_scale for name in config.scenarios]
    return (
        f"planning time alone: {_count(config.runs, 'run')} x "
        f"{_count(len(config.planners), 'planner')} x {sum(budgets):.3g} s (budgets of "
        f"{_count(len(budgets), 'scenario')}: "
        f"{' + '.join(f'{b:g}' for b in budgets)}) = {estimate:.4g} s = {estimate / 60:.3g} min; "
        "set-up and the path checks add to this"
        + (
            f", and {config.t_init_repeats - 1} reruns to each first solution"
            if config.t_init_repeats > 1
            else ""
        )
    )


def _count(number: int, noun: str) -> str:
    """``1 run``, ``2 runs``."""
    return f"{number} {noun}{'' if number == 1 else 's'}"

"""``lit train``: Fuzzy-DDPG training driven in-process through LIT*'s external policy.

One episode is one planning query: a scenario instance drawn from the training distribution, planned
by LIT* with a training seed until the scenario's time budget (planner time; the learner's time is
outside the planner's clock). Every decision the planner asks for becomes a
:class:`~lit_learner.messages.DecisionRequest` to the :class:`~lit_learner.core.LearnerCore`; after
the query the episode is closed with an :class:`~lit_learner.messages.EpisodeEnd`, which runs the
gradient updates outside the timed loop.

**Training distribution.** Each episode draws a scenario uniformly from ``--scenarios``. Fixed
families (NP, WG) have only instance 0; random families (RR, RRD) draw an instance from
:data:`TRAINING_INSTANCES`. The planner seed is drawn from :data:`TRAINING_SEEDS`. ``lit bench``
uses seeds 1..100 on instance 0, so training never plans a benchmark query: the seeds are disjoint
everywhere and the random obstacle layouts are disjoint too. All draws come from one generator
seeded by ``--seed``, saved with every checkpoint, so a resumed run continues the same sequence.

**Schedule** (``LEARNER.md``). ``b-then-k``: the first half (of ``--episodes``, or of
``--minutes``) trains the B agent with psi_K fixed at e; then the B agent is exported to a lookup
tensor (``<run>/b_phase_tensors/``) and the second half trains the psi_K agent while B comes from
that tensor by trilinear lookup, exactly as the shipped ``tensor`` policy will answer it (so K
learns against the B it will meet in deployment, and B's transitions stop). ``joint``: both agents
decide and learn in every episode.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import math
import os
import shlex
import sys
import time
import types
import typing
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from lit_learner.config import AGENT_NAMES
from lit_learner.errors import ExportError
from lit_learner.metrics import (
    CURVES_FILE,
    METRICS_FILE,
    MetricsLog,
    histogram_column,
    plot_training_curves,
)
from lit_learner.offline import TRAIN_SOURCE
from lit_planner import argtypes, signals

TRAINING_SEEDS = (1_000_000, 2**32 - 1)
"""Inclusive range of planner seeds for training episodes (benchmarks use 1..100)."""
TRAINING_INSTANCES = (1, 10_000)
"""Inclusive range of instances of random families for training (benchmarks use instance 0)."""
DEFAULT_SCENARIOS = ("np4", "np8", "np16", "wg4", "wg8", "wg16", "rrd4", "rrd8", "rrd16")
"""The default training mix: NP, WG and RRD in R^4, R^8 and R^16."""
SCHEDULES = ("b-then-k", "joint")
"""Training schedules; see the module docstring."""
DEFAULT_EPISODES = 200
"""Episodes when neither ``--episodes`` nor ``--minutes`` is given."""
DEFAULT_DECISION_INTERVAL = 1
"""psi_K is decided every this many expansions (the planner's ``decision_interval``). The exported
psi_K tensor records it (``provenance.decision_interval``) and the ``tensor`` policy applies it,
so a K step means the same in training and in use."""
DECISION_INTERVAL_KEY = "lit.decision_interval"
"""Bag metadata key of the run's decision interval (``lit replay tensors`` reads it)."""
DEFAULT_CHECKPOINT_EVERY = 100
"""Episodes between periodic checkpoints."""
KEEP_CHECKPOINTS = 2
"""Periodic checkpoints kept (older ones are deleted); the final one is always kept."""
HISTOGRAM_BINS = 10
"""Bins of the per-episode action histograms (over each agent's consequent range)."""
FIXED_NEIGHBOUR_FACTOR = math.e
"""psi_K while only the B agent trains (the fixed policy's value)."""
BUDGET_TOLERANCE = 1e-3
"""An episode whose planner time reaches (1 - this) of the budget ran out of time: truncated."""

PHASE_B, PHASE_K, PHASE_JOINT = "B", "psi_K", "joint"
CHECKPOINT_DIR = "checkpoints"
B_PHASE_TENSORS = "b_phase_tensors"
PROVENANCE_FILE = "provenance.json"
STATE_SUFFIX = ".driver.json"
LOCK_FILE = ".lit-train.lock"

METRIC_COLUMNS = (
    "episode",
    "phase",
    "scenario",
    "instance",
    "seed",
    "solved",
    "truncated",
    "cost",
    "minimum_cost",
    "t_init",
    "improvements",
    "planner_time",
    "wall_time",
    "learner_time",
    "decisions_B",
    "decisions_psi_K",
    "mean_B",
    "mean_psi_K",
    "policy_version",
)
"""Driver columns of ``metrics.csv``; the learner's metrics (``charts/...``, ``losses/...``) and
the action histograms (``actions/B_bin0`` ...) follow them."""


class TrainingError(RuntimeError):
    """A training run could not start or continue (bad options, a failed callback, ...)."""


# --------------------------------------------------------------------------------------------
# Training distribution


@dataclass(frozen=True)
class EpisodeSpec:
    """One training query: which scenario instance, planned with which seed."""

    index: int
    """Episode number in the run (0-based)."""
    scenario: str
    """Registry name without instance suffix (``rrd8``)."""
    instance: int
    """Scenario instance (0 for fixed families, from :data:`TRAINING_INSTANCES` otherwise)."""
    seed: int
    """LIT*'s seed, from :data:`TRAINING_SEEDS`."""


class TrainingDistribution:
    """Draws training queries; benchmark queries (seeds 1..100, instance 0) are never drawn."""

    def __init__(self, scenario_names: Sequence[str], rng: np.random.Generator) -> None:
        from lit_planner import scenarios

        if not scenario_names:
            raise TrainingError("no training scenarios given")
        twice = sorted({name for name in scenario_names if list(scenario_names).count(name) > 1})
        if twice:  # a silent double weight in the uniform draw
            raise TrainingError(
                f"training scenario{'s' if len(twice) > 1 else ''} "
                f"{', '.join(map(repr, twice))} given more than once; each is drawn equally often"
            )
        self.names = list(scenario_names)
        self.randomised = {}
        self.longest_budget = 0.0
        """The longest time budget of the scenarios, in seconds (an instance keeps its family's)."""
        self.shortest_budget = math.inf
        """The shortest one."""
        for name in self.names:
            try:
                problem = scenarios.get(name)
            except Exception as error:  # ScenarioError: "unknown scenario 'xx9': expected ..."
                raise TrainingError(str(error)) from error
            if problem.instance != 0 or "/" in name:
                raise TrainingError(
                    f"training scenario {name!r}: give the family and dimension only; the "
                    "instance is drawn from the training distribution"
                )
            self.randomised[name] = problem.family_spec.randomised
            self.longest_budget = max(self.longest_budget, problem.time_budget)
            self.shortest_budget = min(self.shortest_budget, problem.time_budget)
        self.rng = rng

    def draw(self, index: int) -> EpisodeSpec:
        """The query of episode ``index`` (consumes the generator)."""
        name = self.names[int(self.rng.integers(len(self.names)))]
        low, high = TRAINING_INSTANCES
        instance = int(self.rng.integers(low, high + 1)) if self.randomised[name] else 0
        seed = int(self.rng.integers(TRAINING_SEEDS[0], TRAINING_SEEDS[1] + 1))
        return EpisodeSpec(index, name, instance, seed)


# --------------------------------------------------------------------------------------------
# One episode


@dataclass
class EpisodeOutcome:
    """What one episode produced: the planner's result, the learner's metrics, the actions."""

    spec: EpisodeSpec
    phase: str
    result: dict[str, Any]
    metrics: dict[str, float]
    actions: dict[str, list[float]] = field(default_factory=dict)
    wall_time: float = 0.0
    learner_time: float = 0.0
    """Seconds spent in the callback and ``end_episode`` (outside the planner's clock)."""
    truncated: bool = True
    minimum_cost: float = 0.0
    interrupted: bool = False
    """Ctrl-C arrived during the query: the episode was still closed normally; stop after it."""


def round_batch_size(value: float, low: float, high: float) -> float:
    """B as the planner executes it: rounded half away from zero, clamped to ``[low, high]``."""
    from lit_learner.agent import round_half_away_from_zero

    return float(min(max(round_half_away_from_zero(value), low), high))


def run_episode(
    core: Any,
    spec: EpisodeSpec,
    phase: str,
    episode_id: str,
    *,
    decision_interval: int = DEFAULT_DECISION_INTERVAL,
    b_tensor: Any = None,
    b_range: tuple[float, float] = (20.0, 200.0),
    explore: bool = True,
    time_budget: float | None = None,
    max_iterations: int = 0,
    effort_clock: float = 0.0,
    limit_terminates: bool = False,
    recording: Any = None,
    learn: bool = True,
) -> EpisodeOutcome:
    """Plan one training query with the learner deciding, then close the episode.

    Args:
        core: the :class:`~lit_learner.core.LearnerCore`.
        spec: the query.
        phase: :data:`PHASE_B` (B learns, psi_K fixed at e), :data:`PHASE_K` (psi_K learns, B from
            ``b_tensor``) or :data:`PHASE_JOINT` (both learn).
        episode_id: unique per episode (the learner pairs messages by it).
        decision_interval: psi_K is decided every this many expansions.
        b_tensor: ``lit_core.LookupTensor`` answering B in :data:`PHASE_K`.
        explore: exploration noise on (training) or off (evaluation).
        learn: end the episode with its gradient steps (training); False stores its transitions
            and leaves the steps pending (``core.close_episode``: an evaluation's next query sees
            the same policy).
        time_budget: planner seconds; the scenario's budget when None.
        max_iterations: also end the query after this many LIT* iterations (0: no limit), a
            truncation as the budget's end is (unless ``limit_terminates``). With the default
            reward constants and a budget at least 1000 times the query's planner time, every
            reward's time term is at its floor (t-hat = 0.01, no search cost), so the returns
            are a function of the actions alone: noise-free.
        effort_clock: 0 (default) gives the learner the planner clock. A positive value gives it
            an effort clock instead: the planning time of every decision and of the episode's end
            is the number of states LIT* has checked so far times ``effort_clock`` seconds. Its
            rewards then depend on the seed and the actions alone, time terms included, unlike
            the floored ones of ``max_iterations`` under a large budget, provided the query ends
            on ``max_iterations`` (required with this clock): the planner still stops on its own
            clock at ``time_budget``, so choose a budget the iterations never reach. The budget
            also normalises the effort times (t-hat = effort time / budget, which may exceed 1).
        limit_terminates: an end on ``max_iterations`` (required) is a termination instead of a
            truncation: the learner does not bootstrap across it. The limit is then the task's
            horizon, as in a fixed-horizon toy task; real training keeps every end on a limit or
            the budget a truncation (LEARNER.md), and an end on the budget stays one here too.
        recording: a :class:`lit_planner.bag.EpisodeRecording` that gets the query's messages
            (solution updates, observations, decisions, summary, path), or None.

    Raises:
        TrainingError: the callback raised (the planner would otherwise silently fall back to the
            fixed values), the phase needs a tensor that is missing, ``recording`` is given
            with ``max_iterations`` or ``effort_clock``, or ``effort_clock`` is negative, not
            finite, or ``effort_clock`` or ``limit_terminates`` is given without
            ``max_iterations``.
    """
    import lit_core
    from lit_planner.episode_messages import DecisionSources, EventLog, unit

    from lit_learner.messages import DecisionRequest, EpisodeEnd
    from lit_planner import planning, scenarios

    if phase == PHASE_K and b_tensor is None:
        raise TrainingError("the psi_K phase needs the B lookup tensor of the B phase")
    if not (math.isfinite(effort_clock) and effort_clock >= 0.0):
        raise TrainingError(f"effort_clock must be finite and >= 0, got {effort_clock}")
    if recording is not None and effort_clock:
        # The bag's messages carry the planner clock; a replay would pair other rewards.
        raise TrainingError("an episode on the effort clock cannot be recorded")
    if recording is not None and max_iterations:
        # Bags do not record the limit, so a replay (lit replay tensors) would close the episode
        # as terminated rather than truncated.
        raise TrainingError("an episode limited by max_iterations cannot be recorded")
    if effort_clock and not max_iterations:
        raise TrainingError(
            "effort_clock needs max_iterations (the planner's clock ends the query)"
        )
    if limit_terminates and not max_iterations:
        raise TrainingError("limit_terminates needs max_iterations (the limit that terminates)")
    problem = scenarios.get(spec.scenario, spec.instance)
    budget = problem.time_budget if time_budget is None else time_budget
    actions: dict[str, list[float]] = {"B": [], "psi_K": []}
    errors: list[BaseException] = []
    interrupts: list[bool] = []
    learner_seconds = [0.0]

    events = EventLog(episode_id)
    sources = DecisionSources()

    def answer(context: lit_core.DecisionContext) -> float:
        features = (context.rho_global, context.rho_local, context.measure)
        if not all(math.isfinite(value) for value in features):  # unit() would make them 0
            raise TrainingError(f"episode {episode_id}: the planner's features {features}")
        request = DecisionRequest(  # features clamped as the planner node sends them
            agent=context.kind,
            episode_id=episode_id,
            rho_global=unit(context.rho_global),
            rho_local=unit(context.rho_local),
            measure=unit(context.measure),
            planning_time=(
                context.checks * effort_clock if effort_clock else context.planning_time
            ),
            time_budget=budget,
            cost=context.cost if context.has_solution else None,
            minimum_cost=context.minimum_cost,
            improvements=context.improvements,
            path_states=context.path_states,
            explore=explore,
        )
        if context.kind == "B" and phase == PHASE_K:
            sources.add("tensor")
            value = round_batch_size(
                b_tensor.trilinear(context.rho_global, context.rho_local, context.measure),
                *b_range,
            )
            core.progress(request)  # B is decided at each improvement: its time, exactly
        else:
            sources.add("learner")
            sources.learner_calls += 1
            value = core.decide(request)
        actions[context.kind].append(float(value))
        return float(value)

    def decide(context: lit_core.DecisionContext) -> float:
        started = time.perf_counter()
        try:
            try:
                return answer(context)
            except KeyboardInterrupt:
                # Ctrl-C: finish this query normally (at most its budget), then the driver stops.
                interrupts.append(True)
                return answer(context)
        except BaseException as error:
            errors.append(error)
            raise
        finally:
            learner_seconds[0] += time.perf_counter() - started

    policy = lit_core.ExternalPolicy(decide, decides_neighbour_factor=phase != PHASE_B)
    started = time.perf_counter()
    result = planning.plan(
        problem,
        policy=policy,
        time=budget,
        seed=spec.seed,
        max_iterations=max_iterations,
        params={"decision_interval": decision_interval},
        listener=events,
        check_path=False,
    )
    if errors:
        raise TrainingError(
            f"episode {spec.index} ({problem.name}, seed {spec.seed}): the learner's decision "
            f"failed: {errors[0]!r}"
        ) from errors[0]
    if policy.failures:
        raise TrainingError(
            f"episode {spec.index} ({problem.name}, seed {spec.seed}): {policy.failures} "
            f"decision{'s' if policy.failures != 1 else ''} fell back to the fixed values "
            "(NaN answers)"
        )
    truncated = result["time"] >= budget * (1.0 - BUDGET_TOLERANCE) or (
        max_iterations > 0
        and result["counters"]["iterations"] >= max_iterations
        and not limit_terminates
    )
    # Recorded before the learner closes the episode: a bag that cannot be written (a full disk)
    # stops the run while the checkpoint can still match the episodes done (the rerun of this
    # one is recorded again, which the replay tools count).
    if recording is not None:
        recording.write_query(
            episode_id, "training", problem, spec.seed, "training", result, events, sources
        )
    ended = time.perf_counter()
    metrics = (core.end_episode if learn else core.close_episode)(
        EpisodeEnd(
            episode_id=episode_id,
            planning_time=(
                result["counters"]["collision_checks"] * effort_clock
                if effort_clock
                else float(result["time"])
            ),
            time_budget=budget,
            cost=float(result["cost"]) if result["solved"] else None,
            minimum_cost=minimum_cost(problem),
            improvements=len(result["improvements"]),
            path_states=len(result["path"]) if result["path"] else 0,
            truncated=truncated,
            final_features=final_features(result, episode_id),
        )
    )
    finished = time.perf_counter()
    return EpisodeOutcome(
        spec=spec,
        phase=phase,
        result=result,
        metrics=dict(metrics or {}),
        actions=actions,
        wall_time=finished - started,
        learner_time=learner_seconds[0] + (finished - ended),
        truncated=truncated,
        minimum_cost=minimum_cost(problem),
        interrupted=bool(interrupts),
    )


DRAW_STREAM = 0x6C697464
"""Second word of the seed of a new run's episode draws (scenario, instance, seed)."""


def draw_generator(seed: int, namespace: str = "/") -> np.random.Generator:
    """The generator of a new run's episode draws: a stream of its own. The agents' generators
    are seeded with seed + 0 (B) and seed + 1 (psi_K); one seeded with the bare seed would repeat
    the B agent's numbers (its warm-up actions and exploration noise) in its draws.

    ``namespace``: a planner node's ROS namespace. Planners in other namespaces than the root
    draw streams of their own for the same seed (they would otherwise feed one learner the same
    problems); the root's stream is the plain seed's, as ``lit train``'s.
    """
    extra = [] if namespace == "/" else [zlib.crc32(namespace.encode("utf-8"))]
    return np.random.default_rng([seed, DRAW_STREAM, *extra])


def final_features(
    result: dict[str, Any], episode_id: str = ""
) -> dict[str, tuple[float, float, float]] | None:
    """Each agent's features at the end of a LIT* query (``lit_core.solve``'s
    ``final_features``), clamped into [0, 1] as every feature sent is: the s' of its last
    transition.

    Raises:
        TrainingError: a feature is NaN or infinite (as in a decision: ``unit`` would make it 0).
    """
    from lit_planner.episode_messages import unit

    final = result.get("final_features")
    if not final:
        return None
    for agent, values in final.items():
        if not all(math.isfinite(value) for value in values):
            raise TrainingError(
                f"episode {episode_id}: the planner's final features of {agent}: {tuple(values)}"
            )
    return {
        agent: tuple(unit(v) for v in values)  # type: ignore[misc]
        for agent, values in final.items()
    }


def minimum_cost(problem: Any) -> float:
    """c_min of the rewards: the start-goal distance."""
    return float(np.linalg.norm(np.asarray(problem.goal) - np.asarray(problem.start)))


def histogram(values: Sequence[float], low: float, high: float, bins: int) -> list[int]:
    """Counts of ``values`` in ``bins`` equal bins over ``[low, high]`` (ends included)."""
    counts, _ = np.histogram(np.clip(values, low, high), bins=bins, range=(low, high))
    return [int(count) for count in counts]


# --------------------------------------------------------------------------------------------
# Evaluation


def evaluate(
    core: Any, scenario: str, seeds: Sequence[int], *, agent: str = "B", **options: Any
) -> list[float]:
    """Returns of ``agent`` without exploration noise on fixed queries, measured on a throwaway
    copy of ``core``; ``options`` (``scratch`` required) as in :func:`evaluate_outcomes`.
    ``time_budget``, ``max_iterations``, ``effort_clock`` and ``limit_terminates`` act as in
    :func:`run_episode` (an iteration limit under a budget 1000 times the planner time, or an
    iteration limit on the effort clock, makes the returns deterministic).

    The copy (saved to and loaded from ``scratch``) absorbs the evaluation's transitions and
    takes no gradient steps, so every query is answered by the policy being evaluated and
    evaluating never changes the learner being trained.
    """
    outcomes = evaluate_outcomes(core, scenario, seeds, agent=agent, **options)
    return [float(outcome.metrics[f"charts/return_{agent}"]) for outcome in outcomes]


def evaluate_outcomes(
    core: Any,
    scenario: str,
    seeds: Sequence[int],
    *,
    instance: int = 0,
    agent: str = "B",
    decision_interval: int = DEFAULT_DECISION_INTERVAL,
    time_budget: float | None = None,
    max_iterations: int = 0,
    effort_clock: float = 0.0,
    limit_terminates: bool = False,
    scratch: Path,
) -> list[EpisodeOutcome]:
    """:func:`evaluate`'s episodes whole (actions, planner result, every metric)."""
    from lit_learner.core import LearnerCore

    scratch.mkdir(parents=True, exist_ok=True)
    path = scratch / "evaluation.ckpt"
    try:
        core.save_checkpoint(path)
        probe = LearnerCore.load_checkpoint(path)
    finally:
        path.unlink(missing_ok=True)
    phase = PHASE_B if agent == "B" else PHASE_JOINT
    outcomes = []
    for number, seed in enumerate(seeds):
        spec = EpisodeSpec(number, scenario, instance, seed)
        outcomes.append(
            run_episode(
                probe,
                spec,
                phase,
                f"evaluation-{scenario}-{instance}-{seed}-{number}",
                decision_interval=decision_interval,
                explore=False,
                time_budget=time_budget,
                max_iterations=max_iterations,
                effort_clock=effort_clock,
                limit_terminates=limit_terminates,
                learn=False,
            )
        )
    return outcomes


# --------------------------------------------------------------------------------------------
# Run state, checkpoints, provenance


@dataclass
class DriverState:
    """Everything besides the learner that a resumed run needs (saved beside each checkpoint)."""

    run_id: str
    scenarios: list[str]
    schedule: str
    decision_interval: int
    seed: int
    episodes: int | None
    minutes: float | None
    command: list[str]
    """The command that started the run."""
    episode: int = 0
    """Episodes finished."""
    elapsed: float = 0.0
    """Wall seconds of training so far (resumes add to it)."""
    phase: str = PHASE_B
    b_tensor_dir: str | None = None
    """Folder of the B tensor exported at the phase switch (relative to the run folder)."""
    rng_state: dict[str, Any] = field(default_factory=dict)
    episodes_per_phase: dict[str, int] = field(default_factory=dict)
    started_utc: str = ""
    resumed_with: list[list[str]] = field(default_factory=list)
    """Commands that resumed the run, in order."""
    commits: list[str | None] = field(default_factory=list)
    """The checkout's commit (:func:`git_commit`) of the session that started the run and of
    each that resumed it, in order: the code that trained (None for the sessions of a run
    begun by an older version, which kept none)."""
    checkpoint_every: int = DEFAULT_CHECKPOINT_EVERY
    """``--checkpoint-every`` of the run (a resume keeps it unless given again)."""
    max_iterations: int = 0
    """``--max-iterations``: each query also ends after this many LIT* iterations (0: none)."""
    effort_clock: float = 0.0
    """``--effort-clock``: seconds of learner time per checked state (0: the planner clock)."""
    limit_terminates: bool = False
    """``--limit-terminates``: an end on the iteration limit is a termination."""
    budget_scale: float = 1.0
    """``--budget-scale``: each query's time budget is the scenario's times this."""
    record_bag: bool = True
    """Whether episodes are recorded (``--no-bag``: False); a resume keeps it unless told."""
    bag_dir: str | None = None
    """``--bag-dir`` (absolute), or None for the checkout's ``bags/``."""

    def save(self, path: Path) -> None:
        """Written whole or not at all (a kill mid-write leaves the previous file)."""
        partial = path.with_name(path.name + ".partial")
        partial.write_text(json.dumps(dataclasses.asdict(self), indent=2) + "\n")
        os.replace(partial, path)

    @classmethod
    def load(cls, path: Path) -> DriverState:
        if not path.exists():
            raise TrainingError(
                f"{path}: the driver state of this checkpoint is missing; `lit train --resume` "
                "needs the checkpoint and its .driver.json written by `lit train`"
            )
        try:
            state = cls(**json.loads(path.read_text()))
            # A field of another type ("episode": "six") was taken and failed later, confusingly.
            hints = typing.get_type_hints(cls)
            wrong = [f.name for f in dataclasses.fields(cls)
                     if not _fits(getattr(state, f.name), hints[f.name])]  # fmt: skip
            if wrong:
                raise TypeError(f"wrong type of {', '.join(wrong)}")
            np.random.default_rng().bit_generator.state = state.rng_state
        # Bad JSON or UTF-8; fields, types; an RNG state numpy refuses (a number too large for
        # its integers is an OverflowError, a missing entry a KeyError).
        except (ValueError, TypeError, OverflowError, KeyError) as exc:
            raise TrainingError(
                f"{path}: not a readable driver state of `lit train` ({exc}); restore it or "
                "resume from another checkpoint of the run"
            ) from exc
        return state


def _fits(value: object, hint: Any) -> bool:
    """Whether a JSON value fits a :class:`DriverState` field's type (the types it uses)."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if hint is Any:
        return True
    if origin in (typing.Union, types.UnionType):
        return any(_fits(value, arg) for arg in args)
    if hint is type(None):
        return value is None
    if hint is bool:
        return isinstance(value, bool)
    if hint is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if hint is float:
        return isinstance(value, int | float) and not isinstance(value, bool)
    if hint is str:
        return isinstance(value, str)
    if origin is list:
        return isinstance(value, list) and all(_fits(item, args[0]) for item in value)
    if origin is dict:
        return isinstance(value, dict) and all(
            _fits(key, args[0]) and _fits(item, args[1]) for key, item in value.items()
        )
    return True


def state_path(checkpoint: Path) -> Path:
    """The driver state file beside ``checkpoint``."""
    return checkpoint.with_name(checkpoint.name + STATE_SUFFIX)


def git_commit() -> str | None:
    """The checkout's commit, with ``-dirty`` when tracked files are modified; None outside git."""
    from lit_planner.bench.environment import commit_label

    return commit_label(Path(__file__).resolve().parents[2])


def provenance(state: DriverState, run_dir: Path) -> dict[str, Any]:
    """What made these tensors: command, seeds, distribution, episodes, wall time, commit."""
    return {
        "command": shlex.join(state.command),
        "resumed_with": [shlex.join(command) for command in state.resumed_with],
        "run_folder": str(run_dir.resolve()),
        "run_id": state.run_id,
        "git_commit": git_commit(),  # the export's
        "session_commits": state.commits,  # the training's: the first session's, each resume's
        "started_utc": state.started_utc,
        "finished_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "wall_time_s": round(state.elapsed, 1),
        "episodes": state.episode,
        "episodes_per_phase": state.episodes_per_phase,
        "schedule": state.schedule,
        "scenarios": state.scenarios,
        "decision_interval": state.decision_interval,
        "episode_limits": {
            "max_iterations": state.max_iterations,
            "effort_clock_s_per_check": state.effort_clock,
            "limit_terminates": state.limit_terminates,
            "budget_scale": state.budget_scale,
        },
        "seed": state.seed,
        "training_seeds": list(TRAINING_SEEDS),
        "training_instances_of_random_families": list(TRAINING_INSTANCES),
        "seed_rule": (
            "planner seeds drawn from training_seeds and random-family instances from "
            "training_instances, all from a generator seeded by `seed`; benchmarks use seeds "
            "1..100 on instance 0, so no training query is a benchmark query"
        ),
    }


# --------------------------------------------------------------------------------------------
# The command


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``lit train``."""
    parser.add_argument(
        "--episodes",
        type=int,
        help=f"episodes to train (default {DEFAULT_EPISODES} without "
        "--minutes; with --resume: the new total)",
    )
    parser.add_argument(
        "--minutes",
        type=float,
        help="wall-clock minutes to train (stops at whichever of "
        "--episodes and --minutes comes first; with --resume: the new total)",
    )
    # The next four are a run's own: None when not given, so --resume can refuse a change.
    parser.add_argument(
        "--scenarios",
        help="comma-separated training scenarios (family+dimension; instances are drawn; "
        f"default {','.join(DEFAULT_SCENARIOS)}; a new run only)",
    )
    parser.add_argument(
        "--schedule",
        choices=SCHEDULES,
        help="b-then-k: B with psi_K = e, then psi_K with B from the B tensor; joint: both "
        f"(default {SCHEDULES[0]}; a new run only)",
    )
    parser.add_argument(
        "--decision-interval",
        type=int,
        help="decide psi_K every N expansions (planner parameter decision_interval; default "
        f"{DEFAULT_DECISION_INTERVAL}; a new run only)",
    )
    parser.add_argument(
        "--seed", type=int, help="seed of the learner and the draws (default 0; a new run only)"
    )
    parser.add_argument(
        "--max-iterations",
        type=int,
        default=None,
        metavar="N",
        help="also end each query after N LIT* iterations, a truncation like the budget's end "
        "(default 0: no limit; needs --no-bag; a new run only)",
    )
    parser.add_argument(
        "--limit-terminates",
        action="store_true",
        default=None,
        help="an end on --max-iterations is a termination (a fixed horizon, as `lit toy` "
        "uses), not a truncation (a new run only)",
    )
    parser.add_argument(
        "--effort-clock",
        type=float,
        default=None,
        metavar="SECONDS",
        help="the learner's clock counts checked states, SECONDS each, instead of planner time: "
        "rewards free of timing noise (needs --max-iterations to end the queries, and a "
        "--budget-scale they never reach; a new run only)",
    )
    parser.add_argument(
        "--budget-scale",
        type=float,
        default=None,
        metavar="X",
        help="each query's time budget is the scenario's times X (default 1; a new run only)",
    )
    parser.add_argument(
        "--w-search",
        type=float,
        default=None,
        metavar="W",
        help="weight of the psi_K agent's search cost before the first solution (default 1; a "
        "new run only: a resumed run keeps its checkpoint's)",
    )
    parser.add_argument(
        "--out", type=argtypes.path, help="run folder (default runs/train-<UTC time>)"
    )
    parser.add_argument("--resume", type=argtypes.path, metavar="CHECKPOINT", help="continue a run")
    parser.add_argument(
        "--rollback",
        action="store_true",
        help="with --resume of a checkpoint older than the run's newest: train from it again "
        "(removes the later checkpoints and metrics rows)",
    )
    parser.add_argument(
        "--export",
        type=argtypes.path,
        metavar="DIR",
        help="write the lookup tensors here at the end (only of agents that made a gradient "
        "update)",
    )
    parser.add_argument(
        "--checkpoint-every",
        type=int,
        default=None,
        metavar="N",
        help=f"checkpoint every N episodes, the last {KEEP_CHECKPOINTS} kept (0: final only; "
        f"default {DEFAULT_CHECKPOINT_EVERY}, or the resumed run's)",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument(
        "--bag-dir",
        type=argtypes.path,
        default=None,
        help="record every episode's messages to BAG_DIR/<run folder name> (default: the "
        "repository's bags/)",
    )
    parser.add_argument("--no-bag", action="store_true", help="do not record a bag")


STOP_REQUESTED = signals.Flag()
"""Set by ``lit train``'s SIGINT / SIGTERM handler: :func:`train` stops after the running
episode."""


FINISHING = signals.Flag()
"""Set by :func:`train` once its episodes are over (final checkpoint, curves, provenance and
export follow): a signal then no longer stops at once, which could leave an export half
written."""


def _say(text: str) -> None:
    """One line on standard error from a signal handler (``print`` to ``sys.stderr`` may be
    mid-write there: a reentrant call)."""
    os.write(2, f"\n{text}\n".encode())


def _request_stop(signum: int, frame: Any) -> None:
    """First Ctrl-C (or SIGTERM): note it; the episode, its end and any checkpoint finish, then
    the run stops cleanly. A KeyboardInterrupt raised wherever Python happened to be (inside a
    decision the core calls back, a listener, a gradient step) aborted the query or left the
    learner's episode open: the final checkpoint then could not be resumed, or was not written.
    A second one stops at once, unless the final outputs are being written."""
    del frame
    if FINISHING.is_set():
        _say("lit train: writing the final checkpoint and outputs; a few seconds")
    elif STOP_REQUESTED.is_set():
        _say(
            "lit train: stopped at once; the run keeps its last periodic checkpoint, if one was "
            "written (a bag is left unfinished: `lit replay salvage` recovers it)"
        )
        os._exit(128 + signum)
    else:
        STOP_REQUESTED.set()
        _say(
            "lit train: stopping after this episode (then the final checkpoint, curves and "
            "provenance); Ctrl-C again stops at once without them"
        )


def run(args: argparse.Namespace) -> int:
    """Train, checkpoint, plot and (with ``--export``) export; returns the exit code."""

    from lit_planner.errors import LitPlannerError

    from lit_learner.errors import LearnerError

    # Ctrl-C and `kill PID` stop after the running episode (:func:`_request_stop`); SIGINT too
    # when a non-interactive shell started us in the background with SIGINT ignored.
    STOP_REQUESTED.clear()
    FINISHING.clear()
    try:
        with signals.handling(signals.STOPS, _request_stop):  # SIGHUP: the terminal closed
            result = train(args, hooks=None)
    except (TrainingError, LearnerError, LitPlannerError, OSError) as error:
        # OSError: a metrics, checkpoint or bag file that could not be written (a full disk, a
        # folder in the way), after what could be saved was (_save_after_failure).
        print(f"lit train: {error}", file=sys.stderr)
        return 2
    finally:
        STOP_REQUESTED.clear()  # a later train() in this process starts afresh
        FINISHING.clear()
    print(result.summary)
    return 130 if result.interrupted else 0


@dataclass(frozen=True)
class TrainingResult:
    """What :func:`train` did."""

    summary: str
    """A readable paragraph: episodes, time, run folder, files written."""
    interrupted: bool
    """Stopped by Ctrl-C or SIGTERM before its episodes or minutes were done."""


@dataclass
class TrainingHooks:
    """Test seams: a learner-config override and a per-episode observer."""

    learner_config: Any = None
    """``LearnerConfig`` for a fresh run (default: the learner's defaults with ``--seed``)."""
    on_episode: Callable[[EpisodeOutcome], None] | None = None


def _phase_for(state: DriverState) -> str:
    if state.schedule == "joint":
        return PHASE_JOINT
    half_episodes = state.episodes is not None and state.episode >= math.ceil(state.episodes / 2)
    half_time = state.minutes is not None and state.elapsed >= state.minutes * 30.0
    return PHASE_K if (state.phase == PHASE_K or half_episodes or half_time) else PHASE_B


def _finished(state: DriverState) -> bool:
    return (state.episodes is not None and state.episode >= state.episodes) or (
        state.minutes is not None and state.elapsed >= state.minutes * 60.0
    )


def _refuse_a_total_the_other_stops(state: DriverState, args: argparse.Namespace) -> None:
    """A resume that gives a new total in one unit while the run's total in the other is
    reached already would train nothing and exit 0: refused, naming the total to raise as well.

    Raises:
        TrainingError: only totals this command did not give stop the run.
    """
    if args.episodes is None and args.minutes is None:
        return  # the run's own totals: a finished run exports (or does nothing), as documented
    if args.episodes is not None and state.episode >= args.episodes:
        return  # the total given stops it: --episodes at the checkpoint's count exports only
    reached = []
    if state.episodes is not None and state.episode >= state.episodes and args.episodes is None:
        reached.append(("--episodes", f"{state.episodes} episodes ({state.episode} trained)"))
    if state.minutes is not None and state.elapsed >= state.minutes * 60.0 and args.minutes is None:
        reached.append(
            ("--minutes", f"{state.minutes:g} minutes ({state.elapsed / 60.0:.2f} trained)")
        )
    if not reached:
        return
    option, total = reached[0]
    given = "--episodes" if args.episodes is not None else "--minutes"
    raise TrainingError(
        f"{given} with --resume: the run's total of {total} is reached already, and the totals "
        f"apply together (whichever comes first), so nothing would train; give a larger {option} "
        "as well"
    )


def _episode_limits(args: argparse.Namespace) -> dict[str, Any]:
    """The episode options given (``--max-iterations``, ``--limit-terminates``,
    ``--effort-clock``, ``--budget-scale``) as :class:`DriverState` fields, checked.

    Raises:
        TrainingError: a value out of range, or a combination :func:`run_episode` refuses.
    """
    limits = {
        name: getattr(args, name, None)
        for name in ("max_iterations", "limit_terminates", "effort_clock", "budget_scale")
    }
    limits = {name: value for name, value in limits.items() if value is not None}
    iterations = limits.get("max_iterations", 0)
    clock = limits.get("effort_clock", 0.0)
    scale = limits.get("budget_scale", 1.0)
    if iterations < 0:
        raise TrainingError(f"--max-iterations must be 0 or more, got {iterations}")
    if not (math.isfinite(clock) and clock >= 0.0):
        raise TrainingError(f"--effort-clock must be finite and >= 0, got {clock}")
    if not (math.isfinite(scale) and scale > 0.0):
        raise TrainingError(f"--budget-scale must be finite and positive, got {scale}")
    if (clock or limits.get("limit_terminates")) and not iterations:
        needs = "--effort-clock" if clock else "--limit-terminates"
        raise TrainingError(f"{needs} needs --max-iterations (the limit that ends the queries)")
    if (iterations or clock) and not args.no_bag and args.resume is None:
        raise TrainingError(
            "episodes with --max-iterations or --effort-clock cannot be recorded (a bag carries "
            "neither, so lit replay tensors would pair other rewards); add --no-bag"
        )
    return limits


def _time_budget(spec: EpisodeSpec, scale: float) -> float | None:
    """The query's time budget: the scenario's, times ``scale`` (None: the scenario's)."""
    if scale == 1.0:
        return None
    from lit_planner import scenarios

    return scenarios.get(spec.scenario, spec.instance).time_budget * scale


def _shown(value: Any) -> str:
    """A setting as the command line gives it (a list of scenarios comma-separated)."""
    return ",".join(value) if isinstance(value, list) else str(value)


def _check_folders(args: argparse.Namespace) -> None:
    """Refuse, before any training, folders that cannot be written (a file in the way, no write
    permission): found after the training, they cost the run's export."""
    from lit_planner.bag import write_problem
    from lit_planner.tensor_files import holds_files

    for label, value in (
        ("--out", args.out),
        ("--export", args.export),
        ("--bag-dir", args.bag_dir),
    ):
        if value is None:
            continue
        problem = write_problem(value)
        if problem is not None:
            raise TrainingError(f"{label} {value}: {problem}")
    if (
        args.export is not None
        and Path(args.export).is_dir()
        and holds_files(Path(args.export))  # what a killed export left is not
        and not _own_export(Path(args.export), args.resume)
    ):
        # Found now, not after an hour of training; an export never replaces another one (the
        # shipped tensors in tensors/ included) nor mixes with files that describe something else.
        raise TrainingError(
            f"--export {args.export}: exists and is not empty; choose a new or empty folder "
            "(lit train overwrites only an earlier export of the run it resumes)"
        )


def _tensor_files_state(folder: str | Path | None) -> dict[str, tuple[int, int]]:
    """(modification time, size) of each tensor file in the export ``folder`` now."""
    from lit_planner import planning

    state = {}
    for name in planning.TENSOR_FILES.values() if folder is not None else ():
        try:
            stat = (Path(folder) / name).stat()
        except OSError:
            continue
        state[name] = (stat.st_mtime_ns, stat.st_size)
    return state


def _own_export(folder: Path, resume: Path | None) -> bool:
    """Whether ``folder`` holds an export of the run that ``resume`` continues (an interrupted
    run exports the state it reached; the resumed run replaces that export)."""
    if resume is None:
        return False
    try:
        record = json.loads((folder / PROVENANCE_FILE).read_text(encoding="utf-8"))
        exported_by = record["run_id"]
        resumed = DriverState.load(state_path(Path(resume))).run_id
    except (OSError, ValueError, KeyError, TypeError, TrainingError):
        return False
    # The run id, not the run folder: a relative run folder (runs/train-...) named another run's
    # when resolved from another directory (the shipped tensors' among them).
    return isinstance(exported_by, str) and exported_by == resumed


def agent_range(agent_config: Any, fallback: tuple[float, float]) -> tuple[float, float]:
    """``[min f, max f]`` of an agent's consequents (``fallback`` if the config has none)."""
    if not hasattr(agent_config, "action_min"):
        return fallback
    return float(agent_config.action_min), float(agent_config.action_max)


def train(args: argparse.Namespace, hooks: TrainingHooks | None = None) -> TrainingResult:
    """The body of ``lit train``."""
    import lit_core
    from lit_planner.scenarios import split_names

    from lit_learner.config import LearnerConfig
    from lit_planner import planning

    hooks = hooks or TrainingHooks()
    lit_core.set_log_level("warn")
    command = ["lit", "train", *(sys.argv[2:] if sys.argv[1:2] == ["train"] else sys.argv[1:])]
    if args.decision_interval is not None and not (
        1 <= args.decision_interval <= planning.MAX_DECISION_INTERVAL
    ):  # the planner's parameter is unsigned 32-bit: refused now, not in the first episode
        raise TrainingError(
            f"--decision-interval must be between 1 and {planning.MAX_DECISION_INTERVAL}, "
            f"got {args.decision_interval}"
        )
    if args.no_bag and args.bag_dir is not None:
        raise TrainingError(f"--bag-dir {args.bag_dir} and --no-bag contradict each other")
    started = {  # a run's own settings, as given (None: not given)
        "scenarios": None if args.scenarios is None else split_names(args.scenarios),
        "schedule": args.schedule,
        "decision_interval": args.decision_interval,
        "seed": args.seed,
    }
    if args.seed is not None and not 0 <= args.seed <= planning.MAX_SEED:
        raise TrainingError(f"--seed must be between 0 and {planning.MAX_SEED}, got {args.seed}")
    if args.checkpoint_every is not None and args.checkpoint_every < 0:
        raise TrainingError(f"--checkpoint-every must be 0 or more, got {args.checkpoint_every}")
    if args.episodes is not None and not args.episodes > 0:
        raise TrainingError(f"--episodes must be positive, got {args.episodes}")
    if args.minutes is not None and not (args.minutes > 0 and math.isfinite(args.minutes)):
        raise TrainingError(f"--minutes must be a positive finite number, got {args.minutes}")

    _check_folders(args)
    exported_before = _tensor_files_state(args.export)  # an earlier export of the run resumed
    limits = _episode_limits(args)
    w_search = args.w_search
    if w_search is not None and not (math.isfinite(w_search) and w_search >= 0):
        raise TrainingError(f"--w-search must be finite and >= 0, got {w_search}")
    if args.resume is not None:
        if w_search is not None:
            raise TrainingError("--w-search is set when a run starts; --resume keeps the run's")
        checkpoint = Path(args.resume)
        if not checkpoint.exists():
            raise TrainingError(f"--resume {checkpoint}: no such checkpoint")
        if checkpoint.is_dir():
            raise TrainingError(
                f"--resume {checkpoint}: a folder; give a checkpoint file, such as "
                f"{checkpoint / CHECKPOINT_DIR / 'final.ckpt'}"
            )
        run_dir = checkpoint.resolve().parent.parent
        if (
            checkpoint.resolve().parent.name != CHECKPOINT_DIR
            or not (run_dir / METRICS_FILE).is_file()
        ):
            # Its metrics, B-phase tensor and bag settings live in the run folder; resuming a
            # stray copy wrote a new run's files into whatever folder held it.
            raise TrainingError(
                f"--resume {checkpoint}: not in a run folder (lit train keeps checkpoints in "
                f"RUN/{CHECKPOINT_DIR}/ beside RUN/{METRICS_FILE}); resume it there, or copy the "
                "whole run folder"
            )
        state = DriverState.load(state_path(checkpoint))
        # Before the checks that trust the driver state's episode (a later checkpoint, the metrics
        # rows): a driver state of another checkpoint sent the user to --rollback first.
        from lit_learner.core import LearnerCore  # torch: after the options' checks (below)

        core = LearnerCore.load_checkpoint(checkpoint)
        warning = core.load_warning()
        if warning:
            print(f"lit train: warning: {checkpoint}: {warning}", file=sys.stderr, flush=True)
        if core.episodes != state.episode:  # a kill between writing the two files
            raise TrainingError(
                f"--resume {checkpoint}: the checkpoint holds {core.episodes} episodes and its "
                f"driver state {state_path(checkpoint).name} {state.episode}; they were not "
                "written together: resume another checkpoint of the run"
            )
        rows = _metrics_rows(run_dir)
        if state.episode > rows:
            raise TrainingError(
                f"--resume {checkpoint}: it holds {state.episode} episodes and {METRICS_FILE} "
                f"{rows} rows: a checkpoint of a history an earlier resume went back from; resume "
                "one of the run's periodic checkpoints"
            )
        newer = _newer_checkpoints(run_dir, state.episode, checkpoint)
        if newer and not args.rollback:
            episode, path = newer[-1]
            raise TrainingError(
                f"--resume {checkpoint} (episode {state.episode}): the run has a later "
                f"checkpoint, {path} (episode {episode}); resume that one to continue, or add "
                f"--rollback to train from episode {state.episode} again (it removes the "
                f"{len(newer)} later checkpoint(s) and the metrics rows after episode "
                f"{state.episode})"
            )
        if args.out is not None and Path(args.out).resolve() != run_dir:
            raise TrainingError(
                f"--out {args.out} with --resume: the run folder is the checkpoint's ({run_dir}); "
                "copy that folder to continue the run elsewhere"
            )
        given = {name: value for name, value in started.items() if value is not None}
        changed = [
            name for name, value in {**limits, **given}.items() if getattr(state, name) != value
        ]
        if changed:
            given = ", ".join(
                f"--{name.replace('_', '-')} (the run's: {_shown(getattr(state, name))})"
                for name in changed
            )
            raise TrainingError(f"{given}: set when a run starts; --resume keeps the run's")
        if args.episodes is not None and args.episodes < state.episode:
            raise TrainingError(
                f"--episodes {args.episodes} with --resume is the new total, and the checkpoint "
                f"has {state.episode} episodes already (--episodes {state.episode} stops there: "
                "with --export, it exports an interrupted run without training more)"
            )
        if args.minutes is not None and args.minutes * 60.0 <= state.elapsed:
            raise TrainingError(
                f"--minutes {args.minutes:g} with --resume is the new total, and the checkpoint "
                f"has trained {state.elapsed / 60.0:.1f} minutes already"
            )
        # Its bag settings, unless this command gives others.
        if args.no_bag:
            state.record_bag, state.bag_dir = False, None
        elif args.bag_dir is not None:
            state.record_bag, state.bag_dir = True, str(Path(args.bag_dir).resolve())
        if (state.max_iterations or state.effort_clock) and state.record_bag:
            raise TrainingError(
                "this run limits its episodes (--max-iterations or --effort-clock), which a bag "
                "cannot carry; resume it with --no-bag"
            )
        if args.episodes is not None:
            state.episodes = args.episodes
        if args.minutes is not None:
            state.minutes = args.minutes
        _refuse_a_total_the_other_stops(state, args)
        if not _finished(state):
            # An interrupted run resumed to its own total trains on: said before it does.
            totals = [f"{state.episodes} episodes"] if state.episodes is not None else []
            totals += (
                [f"{state.minutes:g} minute{'' if state.minutes == 1 else 's'}"]
                if state.minutes is not None
                else []
            )
            print(
                f"lit train: resuming at episode {state.episode} "
                f"({state.elapsed / 60.0:.1f} minutes trained) to the run's total of "
                f"{' or '.join(totals)}{', whichever comes first' if len(totals) > 1 else ''}"
                + (
                    f" (--episodes {state.episode} would export without training)"
                    if args.export is not None and args.episodes is None
                    else ""
                ),
                file=sys.stderr,
            )
        # A run of an older version has none: its first session's and earlier resumes' unknown.
        state.commits += [None] * (len(state.resumed_with) + 1 - len(state.commits))
        state.resumed_with.append(command)
        state.commits.append(git_commit())
        if state.phase == PHASE_K and state.schedule != "joint" and not _finished(state):
            print(
                f"lit train: the psi_K phase began at episode {state.episodes_per_phase.get(PHASE_B, 0)}"
                "; the rest of the run trains psi_K",
                file=sys.stderr,
            )
        if args.checkpoint_every is not None:
            state.checkpoint_every = args.checkpoint_every
        rng = np.random.default_rng()
        rng.bit_generator.state = state.rng_state
    else:
        if args.rollback:
            raise TrainingError("--rollback goes with --resume")
        stamp = time.strftime("%Y%m%d-%H%M%S", time.gmtime())
        run_dir = Path(args.out) if args.out else Path("runs") / f"train-{stamp}"
        if (run_dir / METRICS_FILE).exists():
            raise TrainingError(
                f"{run_dir} already holds a training run; choose another --out or --resume"
            )
        others = [p for p in run_dir.iterdir() if p.name != LOCK_FILE] if run_dir.is_dir() else []
        if others:  # a run's files mixed with others (a crashed start leaves only the lock)
            raise TrainingError(f"--out {run_dir}: not empty; choose a new or empty folder")
        seed = 0 if args.seed is None else args.seed
        episodes = args.episodes
        if episodes is None and args.minutes is None:
            episodes = DEFAULT_EPISODES
        state = DriverState(
            run_id=f"train-{stamp}-s{seed}",
            scenarios=(
                list(DEFAULT_SCENARIOS) if started["scenarios"] is None else started["scenarios"]
            ),
            schedule=args.schedule or SCHEDULES[0],
            decision_interval=args.decision_interval or DEFAULT_DECISION_INTERVAL,
            seed=seed,
            record_bag=not args.no_bag,
            bag_dir=None if args.bag_dir is None else str(Path(args.bag_dir).resolve()),
            episodes=episodes,
            minutes=args.minutes,
            command=command,
            commits=[git_commit()],
            started_utc=time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            checkpoint_every=(
                DEFAULT_CHECKPOINT_EVERY if args.checkpoint_every is None else args.checkpoint_every
            ),
            **limits,
        )
        config = hooks.learner_config or LearnerConfig(seed=seed)
        if w_search is not None:
            config = dataclasses.replace(
                config, reward=dataclasses.replace(config.reward, w_search=w_search)
            )
        # torch (whose import starts `ldconfig -p`) only once the options passed their checks: a
        # refused --export /proc/x did start that child.
        from lit_learner.core import LearnerCore

        core = LearnerCore(config)
        rng = draw_generator(seed)
    distribution = TrainingDistribution(state.scenarios, rng)  # checks the names first
    # Refused here, not by the first episode's planner after the learner has started.
    problem = planning.scale_problem(
        "--budget-scale",
        state.budget_scale,
        distribution.longest_budget,
        distribution.shortest_budget,
    )
    if problem is not None:
        raise TrainingError(problem)
    if args.export is not None and Path(args.export).resolve() == run_dir.resolve():
        # Its provenance.json and curves would be copied onto themselves after the whole run.
        raise TrainingError(
            f"--export {args.export} is the run folder; export into a folder of its own"
        )
    run_dir.mkdir(parents=True, exist_ok=True)
    lock = _lock_run_folder(run_dir)  # held until this process ends
    b_range = agent_range(core.config.b, (20.0, 200.0))
    k_range = agent_range(core.config.k, (3.0, 12.0 + 3.0))
    ranges = {"B": b_range, "psi_K": k_range}
    b_tensor = None
    if state.b_tensor_dir is not None:
        b_tensor = planning.load_tensor(
            run_dir / state.b_tensor_dir / planning.TENSOR_FILES["B"], "B"
        )

    columns = [*METRIC_COLUMNS] + [
        histogram_column(agent, index) for agent in ranges for index in range(HISTOGRAM_BINS)
    ]
    log = MetricsLog(run_dir / METRICS_FILE, columns)
    # No bag for a resume that only exports (its episodes are done): it would stay empty.
    record_bag = state.record_bag and not _finished(state)
    if record_bag:  # before anything of the run changes: a --rollback dropped the metrics rows
        _check_bag_parent(state)  # first, and then refused the bag folder
    dropped = log.keep_episodes_before(state.episode)
    if dropped:  # resumed from an earlier checkpoint: those episodes are trained again
        print(
            f"lit train: {run_dir / METRICS_FILE}: dropped the rows of {dropped} episodes after "
            f"the checkpoint (episode {state.episode}); they run again",
            file=sys.stderr,
        )
    recording = _open_bag(state, run_dir) if record_bag else None
    progress = _progress(state, disable=args.no_progress)
    session_start = time.perf_counter() - state.elapsed
    periodic = _earlier_checkpoints(run_dir, state.episode)  # a resumed run prunes them too
    if args.resume is not None:  # --rollback: the history dropped above
        for _, later in _newer_checkpoints(run_dir, state.episode, Path(args.resume)):
            later.unlink(missing_ok=True)
            state_path(later).unlink(missing_ok=True)
            print(f"lit train: removed {later} (--rollback)", file=sys.stderr)
        stale = _stale_final(run_dir, state.episode, Path(args.resume))
        if stale is not None:  # of a history an earlier resume went back from
            stale.unlink(missing_ok=True)
            state_path(stale).unlink(missing_ok=True)
            print(f"lit train: removed {stale} (past the metrics rows)", file=sys.stderr)
    interrupted = broke_off = False
    failure: Exception | None = None
    failed = "the run"  # where ``failure`` came, said with the final checkpoint saved after it
    episode_id: str | None = None
    try:
        while not (_finished(state) or interrupted or STOP_REQUESTED.is_set()):
            failed = f"the run after {state.episode} episodes"
            phase = _phase_for(state)
            if phase == PHASE_K and state.phase != PHASE_K:
                progress.write(
                    "lit train: B phase done; exporting its B tensor (a few seconds)",
                    file=sys.stderr,
                )
                failed = "the B phase's export of its B tensor"
                b_tensor = _switch_to_k(core, state, run_dir)
            state.phase = phase
            spec = distribution.draw(state.episode)
            episode_id = f"{state.run_id}-{spec.index:07d}"
            failed = f"episode {state.episode}"
            outcome = run_episode(
                core,
                spec,
                phase,
                episode_id,
                decision_interval=state.decision_interval,
                b_tensor=b_tensor,
                b_range=b_range,
                recording=recording,
                time_budget=_time_budget(spec, state.budget_scale),
                max_iterations=state.max_iterations,
                effort_clock=state.effort_clock,
                limit_terminates=state.limit_terminates,
            )
            log.append(_row(outcome, core, ranges))  # first: an interrupt between the two
            state.episode += 1  # leaves a row to drop, never a counted episode without its row
            state.elapsed = time.perf_counter() - session_start
            state.episodes_per_phase[phase] = state.episodes_per_phase.get(phase, 0) + 1
            if hooks.on_episode is not None:
                hooks.on_episode(outcome)
            _advance(progress, state, outcome)
            interrupted = outcome.interrupted or STOP_REQUESTED.is_set()
            if state.checkpoint_every > 0 and state.episode % state.checkpoint_every == 0:
                failed = f"the checkpoint after {state.episode} episodes"
                periodic.append(
                    _checkpoint(core, state, rng, run_dir, f"episode-{state.episode:07d}")
                )
                while len(periodic) > KEEP_CHECKPOINTS:
                    old = periodic.pop(0)
                    old.unlink(missing_ok=True)
                    state_path(old).unlink(missing_ok=True)
    except KeyboardInterrupt:
        # lit train's own handler raises none (it sets STOP_REQUESTED); a caller's Ctrl-C in
        # Python's default handler lands wherever Python is, often inside a query (it now leaves
        # plan() from the policy callback): that episode's open steps are dropped below.
        interrupted = broke_off = True
    except Exception as error:  # noqa: BLE001 - saved below, then raised again
        failure = error
    finally:
        progress.close()
        if recording is not None:
            try:
                recording.close()
            except Exception as error:  # noqa: BLE001 - a full disk: saved below, raised again
                if failure is None:  # the first error is the one raised
                    failure, failed = error, "closing the bag"
    if failure is not None:
        _save_after_failure(core, state, rng, run_dir, episode_id, failure, failed)
        lock.close()
        raise failure
    interrupted = interrupted or STOP_REQUESTED.is_set()
    FINISHING.set()
    final: Path | None = None
    if broke_off and core.episodes != state.episode:
        print(
            f"lit train: interrupted after the learner had closed episode {state.episode}; no "
            "final checkpoint written (it would not match the metrics): resume the last "
            "periodic one",
            file=sys.stderr,
        )
    else:
        if broke_off and episode_id is not None:
            core.abandon_episode(episode_id)  # its pending steps would pair with its rerun
        final = _checkpoint(core, state, rng, run_dir, "final")
    curves = plot_training_curves(run_dir / METRICS_FILE, run_dir / CURVES_FILE, HISTOGRAM_BINS)
    record = provenance(state, run_dir)
    (run_dir / PROVENANCE_FILE).write_text(json.dumps(record, indent=2) + "\n")
    lines = [
        (
            f"lit train: {state.episode} episodes in {state.elapsed / 60:.1f} min "
            f"({', '.join(f'{count} {phase}' for phase, count in state.episodes_per_phase.items())}"
            f"), run folder {run_dir}"
            + (
                (
                    " (interrupted: --resume the final checkpoint to continue)"
                    if final is not None
                    else " (interrupted: --resume the last periodic checkpoint to continue)"
                )
                if interrupted
                else ""
            )
        ),
        f"  checkpoint {final or 'not written'}, metrics {run_dir / METRICS_FILE}, curves {curves}",
    ]
    if recording is not None:
        lines.append(f"  bag {recording.recorder.path} (lit replay info / tensors)")
    if args.export is not None and final is None:
        lines.append(f"  not exported to {args.export}: the learner's state matches no checkpoint")
    elif args.export is not None:
        # Written there by something else while this run trained (an earlier export of the run
        # it resumes was there from the start, and is what it replaces).
        replaced = _tensor_files_state(args.export) != exported_before
        agents = exported_agents(core, state)
        try:
            written = export(core, Path(args.export), record, curves, agents)
        except ExportError as error:
            lock.close()
            raise TrainingError(
                f"{error}. The run is saved in {final}: `lit train --resume {final} --episodes "
                f"{state.episode} --export {args.export}` exports it without training"
            ) from None
        lines.append(
            f"  tensors {', '.join(str(path) for path in written.values())}"
            if agents
            else f"  tensors: none in {args.export} (no agent made a gradient update yet; "
            "it holds the checkpoint and provenance)"
        )
        left_out = core.export_plan()[1]
        for name in AGENT_NAMES:  # said here, not only by `lit tensors info`
            if name in agents and name in left_out:
                lines.append(
                    f"  {name}: UNTRAINED, the actor's initial weights (exported as the B "
                    "phase's tensor, which the psi_K agent trained against; "
                    f"{core.untrained_reason(name)})"
                )
            elif name in left_out:
                lines.append(f"  {name}: {left_out[name]}")
        if replaced:
            lines.append(
                f"  (replaced or removed the tensors written to {args.export} during this run; "
                "other files there still describe those)"
            )
    lock.close()
    return TrainingResult("\n".join(lines), interrupted)


def _save_after_failure(
    core: Any,
    state: DriverState,
    rng: np.random.Generator,
    run_dir: Path,
    episode_id: str | None,
    failure: Exception,
    failed: str,
) -> None:
    """An error stopped the run (``failed``: where, as "episode 3" or "closing the bag"): drop
    the running episode's open steps and save the episodes done as the final checkpoint (up to
    --checkpoint-every episodes would be lost otherwise); the resumed run goes on with the next
    query (the failed one's was drawn)."""
    if core.episodes != state.episode:  # the learner closed it before the error: no match
        print(
            f"lit train: episode {state.episode} failed after the learner had closed it; no "
            "final checkpoint written (it would not match the metrics): resume the last "
            "periodic one",
            file=sys.stderr,
        )
        return
    if episode_id is not None:
        core.abandon_episode(episode_id)
    try:
        final = _checkpoint(core, state, rng, run_dir, "final")
    except Exception as error:  # noqa: BLE001 - the first error is the one raised
        print(
            f"lit train: {failed} failed, and so did saving the final checkpoint ({error})",
            file=sys.stderr,
        )
        return
    print(
        f"lit train: {failed} failed ({type(failure).__name__}); the {state.episode} episodes "
        f"done are in {final}: --resume it to continue",
        file=sys.stderr,
    )


def _newer_checkpoints(run_dir: Path, episode: int, resumed: Path) -> list[tuple[int, Path]]:
    """(episode, path) of the run's checkpoints past ``episode``, oldest first: the periodic
    ones and the final one (an older final one is left after a crash), ``resumed`` excepted."""
    newer = []
    for number, path in _periodic_checkpoints(run_dir):
        if number <= episode or path.resolve() == resumed.resolve():
            continue
        try:
            DriverState.load(state_path(path))
        except TrainingError:  # no (readable) driver state: it cannot be resumed
            continue
        newer.append((number, path))
    final = _final_checkpoint(run_dir, resumed)
    # One past the metrics rows is a final checkpoint of a branch an earlier resume abandoned
    # (before --rollback, such a resume removed only the periodic ones): see _stale_final.
    if final is not None and episode < final[0] <= _metrics_rows(run_dir):
        newer.append(final)
    return sorted(newer)


def _stale_final(run_dir: Path, episode: int, resumed: Path) -> Path | None:
    """The run's final checkpoint if it lies past ``episode`` and past the metrics rows (left by
    a resume, before --rollback, that went back to an earlier checkpoint); None otherwise."""
    final = _final_checkpoint(run_dir, resumed)
    if final is None or final[0] <= max(episode, _metrics_rows(run_dir)):
        return None
    return final[1]


def _final_checkpoint(run_dir: Path, resumed: Path) -> tuple[int, Path] | None:
    """(episode, path) of the run's final checkpoint, unless it is ``resumed`` or its driver
    state is gone or damaged (it cannot be resumed then)."""
    final = run_dir / CHECKPOINT_DIR / "final.ckpt"
    if not final.exists() or final.resolve() == resumed.resolve():
        return None
    try:
        return DriverState.load(state_path(final)).episode, final
    except TrainingError:
        return None


def _metrics_rows(run_dir: Path) -> int:
    """Episode rows in the run's metrics file (0 without one), read as MetricsLog reads it."""
    try:
        with (run_dir / METRICS_FILE).open(newline="") as handle:
            return sum(1 for _ in csv.DictReader(handle))
    except OSError:
        return 0


def _periodic_checkpoints(run_dir: Path) -> list[tuple[int, Path]]:
    """(episode, path) of the run's periodic checkpoints, oldest first."""
    found = []
    for path in (run_dir / CHECKPOINT_DIR).glob("episode-*.ckpt"):
        number = path.stem.removeprefix("episode-")
        if number.isdigit():
            found.append((int(number), path))
    return sorted(found)


def _earlier_checkpoints(run_dir: Path, episode: int) -> list[Path]:
    """The run's periodic checkpoints up to ``episode``, oldest first."""
    return [path for number, path in _periodic_checkpoints(run_dir) if number <= episode]


def _lock_run_folder(run_dir: Path) -> Any:
    """An exclusive lock on the run folder: two `lit train` processes appending to one run's
    metrics and checkpoints would interleave them."""
    import fcntl

    handle = (run_dir / LOCK_FILE).open("w")
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        handle.close()
        raise TrainingError(f"{run_dir} is in use by another lit train process") from None
    return handle


def exported_agents(core: Any, state: DriverState) -> tuple[str, ...]:
    """The agents whose tensor ``lit train`` exports: those whose actor made a gradient update
    (an initial actor played by the tensor policy decided psi_K about 9 where the fixed value
    is e), and B when the psi_K phase began against B's tensor of the B phase, whatever it was
    (psi_K learns against the B it meets in use)."""
    trained = core.export_plan()[0]
    return tuple(
        name
        for name in AGENT_NAMES
        if name in trained or (name == "B" and state.b_tensor_dir is not None)
    )


def export(
    core: Any,
    directory: Path,
    record: dict[str, Any],
    curves: Path | None,
    agents: Sequence[str],
) -> dict:
    """Write the tensors of ``agents`` (none is fine) with ``record`` as provenance, plus
    ``provenance.json``, the curves and the checkpoint, and remove the other agent's tensor
    files from ``directory`` (an earlier export of the run that this one resumes may hold them;
    they would be played beside this run's): all or nothing, see
    :meth:`~lit_learner.core.LearnerCore.export_tensors`."""
    extra = {PROVENANCE_FILE: (json.dumps(record, indent=2) + "\n").encode()}
    if curves is not None and curves.exists():
        extra[CURVES_FILE] = curves.read_bytes()
    return core.export_tensors(directory, record, agents=agents, extra=extra, remove_others=True)


def _bag_parent(state: DriverState) -> Path:
    """The folder the run's bags go into."""
    from lit_planner.bag import default_bag_root

    return Path(state.bag_dir) if state.bag_dir is not None else default_bag_root()


def _check_bag_parent(state: DriverState) -> None:
    """Raise :class:`TrainingError` when the run's bag folder cannot be made or written (a
    resumed run's stored one, which ``--bag-dir``'s check does not see)."""
    from lit_planner.bag import write_problem

    parent = _bag_parent(state)
    problem = write_problem(parent)
    if problem is not None:
        raise TrainingError(f"bag folder {parent}: {problem}")


def _open_bag(state: DriverState, run_dir: Path) -> Any:
    """The run's bag (a resumed run records a new one beside the first: ``<name>-2``, ...)."""
    from lit_planner.bag import EpisodeRecording, unique_directory

    parent = _bag_parent(state)
    try:
        parent.mkdir(parents=True, exist_ok=True)
    except OSError as error:  # a resumed run's --bag-dir replaced by a file, say
        raise TrainingError(f"bag folder {parent}: {error}") from None
    return EpisodeRecording(
        unique_directory(parent, run_dir.resolve().name),
        state.run_id,
        TRAIN_SOURCE,
        metadata={
            "lit.run_folder": str(run_dir),
            # lit replay tensors records it with the tensors it retrains from this bag.
            DECISION_INTERVAL_KEY: str(state.decision_interval),
        },
    )


def _switch_to_k(core: Any, state: DriverState, run_dir: Path) -> Any:
    """End of the B phase: export B so that the psi_K phase answers B from its tensor."""
    from lit_planner import planning

    folder = run_dir / B_PHASE_TENSORS
    record = provenance(state, run_dir) | {"note": "B tensor at the end of the B phase"}
    # B only: the psi_K agent has not trained yet, and an export of its initial actor was
    # shown by `lit tensors info` like a trained tensor.
    written = core.export_tensors(folder, record, agents=("B",))
    state.b_tensor_dir = B_PHASE_TENSORS
    return planning.load_tensor(Path(written["B"]), "B")


def _checkpoint(
    core: Any, state: DriverState, rng: np.random.Generator, run_dir: Path, name: str
) -> Path:
    folder = run_dir / CHECKPOINT_DIR
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{name}.ckpt"
    core.save_checkpoint(path)
    state.rng_state = rng.bit_generator.state
    state.save(state_path(path))
    return path


def _row(outcome: EpisodeOutcome, core: Any, ranges: dict[str, tuple[float, float]]) -> dict:
    result = outcome.result
    row: dict[str, object] = {
        "episode": outcome.spec.index,
        "phase": outcome.phase,
        "scenario": outcome.spec.scenario,
        "instance": outcome.spec.instance,
        "seed": outcome.spec.seed,
        "solved": bool(result["solved"]),
        "truncated": outcome.truncated,
        "cost": float(result["cost"]) if result["solved"] else None,
        "minimum_cost": outcome.minimum_cost,
        "t_init": result.get("t_init") if result["solved"] else None,  # not inf
        "improvements": len(result["improvements"]),
        "planner_time": float(result["time"]),
        "wall_time": outcome.wall_time,
        "learner_time": outcome.learner_time,
        "policy_version": getattr(core, "policy_version", None),
    }
    for agent, (low, high) in ranges.items():
        values = outcome.actions.get(agent, [])
        row[f"decisions_{agent}"] = len(values)
        row[f"mean_{agent}"] = float(np.mean(values)) if values else None
        for index, count in enumerate(histogram(values, low, high, HISTOGRAM_BINS)):
            row[histogram_column(agent, index)] = count
    row.update(outcome.metrics)
    return row


class _NoProgress:
    """``--no-progress``: no bar; its notes are printed all the same (the B phase's end was
    silent)."""

    def update(self, *_: object) -> None: ...
    def write(self, text: str, file: Any = None, **_: object) -> None:
        print(text, file=sys.stdout if file is None else file, flush=True)

    def set_postfix(self, *_: object, **__: object) -> None: ...
    def close(self) -> None: ...


def _progress(state: DriverState, disable: bool) -> Any:
    if disable:
        return _NoProgress()
    from tqdm import tqdm

    return tqdm(
        total=state.episodes,
        initial=state.episode,
        unit="ep",
        desc="lit train",
        dynamic_ncols=True,
    )


def _advance(progress: Any, state: DriverState, outcome: EpisodeOutcome) -> None:
    returns = {
        key.split("_", 1)[1]: value
        for key, value in outcome.metrics.items()
        if key.startswith("charts/return_")
    }
    left = []
    if state.minutes is not None:
        left.append(max(0.0, state.minutes * 60 - state.elapsed))
    if state.episodes is not None and state.episode:
        left.append(state.elapsed / state.episode * (state.episodes - state.episode))
    progress.update(1)
    progress.set_postfix(
        {
            "phase": outcome.phase,
            "scenario": f"{outcome.spec.scenario}/{outcome.spec.instance}",
            **{f"R_{agent}": f"{value:.3g}" for agent, value in returns.items()},
            "left": time.strftime("%H:%M:%S", time.gmtime(min(left))) if left else "?",
        },
        refresh=False,
    )

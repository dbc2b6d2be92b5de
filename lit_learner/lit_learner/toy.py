"""``lit toy``: a fixed toy task on which a short training run of the B agent raises the greedy
return, measured against constant batch sizes on the same query.

**The task.** One query (np2, instance 0, training seed 1 000 007 by default) planned by LIT* with
the B agent deciding and psi_K at e (the B phase of ``lit train``). Its horizon is 1000 LIT*
iterations, and the end on that limit is a *termination*: the learner does not bootstrap across
it (``run_episode(limit_terminates=True)``). Real training keeps an end on the budget a truncation
(LEARNER.md); a fixed horizon is what makes this a task whose return a policy can be judged on.
The learner's clock is the effort clock (planning time = states checked x 0.1 us, budget 1 s), so
every episode is a function of the seed and the actions alone: the greedy return is
deterministic, and a rerun on the same machine gives the same returns. The planner still stops
on its own clock at the budget; the command refuses a query that ended there (a machine too slow
for 1000 iterations of np2 in a second).

**Why it can learn here.** B is decided at solution improvements, so a small B gets the next
improvement within fewer iterations, and within the fixed horizon more improvements (each earns a
reward) fit. With a termination the critic sees that a large B leaves the horizon with fewer
improvements; with a truncation it would bootstrap across the end and value "no improvement yet"
as almost free (README, "What the tests show of learning").

**What it does not show.** The state (rho_global, rho_local, the measure) has no time or
iteration feature, so seen from the state the fixed horizon is not Markov: what the agent learns
here ("small B, for this horizon and this query") says nothing about real training, whose episodes
end on a time budget as truncations. The toy shows that the training machinery (rewards,
pairing, replay, the actor-critic updates, all against the real planner) turns a return signal
into a better policy; it is not evidence that ``lit train`` improves planning.

**Learner.** ``LearnerConfig`` defaults except for the B agent's warm-up (96 transitions), batch
(16), buffer (4096), beta annealing (500 steps) and exploration noise (0.1 of the action range).
"""

from __future__ import annotations

import argparse
import csv
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from lit_learner import train
from lit_planner import argtypes

DEFAULT_LEARNER_SEEDS = (1,)
DEFAULT_EPISODES = 600
DEFAULT_EVERY = 100
DEFAULT_CONSTANTS = (20, 35, 50, 65, 80, 110, 140, 200)
CURVES_FILE = "curves.csv"
CONSTANTS_FILE = "constants.csv"
PLOT_FILE = "toy.png"
SUMMARY_FILE = "summary.md"


class ToyError(RuntimeError):
    """The toy task cannot run as asked (bad option, or a query that did not end on its limit)."""


@dataclass(frozen=True)
class ToyTask:
    """The query and its horizon (see the module docstring)."""

    scenario: str = "np2"
    instance: int = 0
    seed: int = 1_000_007
    max_iterations: int = 1000
    effort_clock: float = 1e-7
    """Seconds per checked state on the learner's clock."""
    time_budget: float = 1.0
    """The planner's own budget (never reached on this machine) and the times' normaliser."""

    def check(self) -> None:
        low, high = train.TRAINING_SEEDS
        if not low <= self.seed <= high:
            raise ToyError(
                f"query seed {self.seed} is not a training seed ({low}..{high}); benchmark "
                "seeds are never trained on"
            )
        if self.max_iterations < 1:
            raise ToyError(f"max_iterations must be >= 1, got {self.max_iterations}")
        from lit_planner import scenarios

        if "/" in self.scenario:
            raise ToyError(
                f"--scenario {self.scenario}: give the family and dimension only (e.g. np2, wg4)"
            )
        if scenarios.get(self.scenario, self.instance).family_spec.randomised:
            raise ToyError(
                f"--scenario {self.scenario}: the toy plans instance {self.instance}, a benchmark "
                "layout of a family with random layouts; use a fixed-layout family (np, wg)"
            )

    def run(self, core: Any, index: int, episode_id: str, explore: bool) -> train.EpisodeOutcome:
        """One episode of the task with ``core`` deciding B."""
        outcome = train.run_episode(
            core,
            train.EpisodeSpec(index, self.scenario, self.instance, self.seed),
            train.PHASE_B,
            episode_id,
            explore=explore,
            time_budget=self.time_budget,
            max_iterations=self.max_iterations,
            effort_clock=self.effort_clock,
            limit_terminates=True,
        )
        self.ended_on_the_limit(outcome)
        return outcome

    def ended_on_the_limit(self, outcome: train.EpisodeOutcome) -> None:
        """Refuse an episode that did not end on the horizon; Ctrl-C during it (the episode
        was closed) stops here as ``KeyboardInterrupt``."""
        if outcome.interrupted:
            raise KeyboardInterrupt
        iterations = outcome.result["counters"]["iterations"]
        # truncated: the planner's clock reached the budget too (perhaps at the last iteration)
        if iterations != self.max_iterations or outcome.truncated:
            raise ToyError(
                f"the toy query ended after {iterations} of its {self.max_iterations} iterations "
                f"(planner time {outcome.result['time']:.3f} s of a {self.time_budget} s budget): "
                "its return would depend on this machine's speed"
            )


def toy_config(learner_seed: int) -> Any:
    """The learner of the toy task (see the module docstring)."""
    from lit_learner.config import AgentConfig, LearnerConfig

    return LearnerConfig(
        b=AgentConfig.batch_size_agent(
            warmup=96, batch_size=16, buffer_size=4096, beta_steps=500, noise_std=0.1
        ),
        # Unused in the B phase; small so that the core is cheap to make and to copy.
        k=AgentConfig.neighbour_agent(warmup=32, batch_size=32, buffer_size=256, beta_steps=500),
        seed=learner_seed,
    )


@dataclass(frozen=True)
class Evaluation:
    """One greedy episode of the task (no exploration noise)."""

    episode: int
    """Training episodes before it (0: the untrained actor)."""
    greedy_return: float
    mean_b: float
    """Mean executed B of the episode."""
    decisions: int
    improvements: int
    cost: float


def _evaluation(episode: int, outcome: train.EpisodeOutcome) -> Evaluation:
    actions = outcome.actions["B"]
    return Evaluation(
        episode=episode,
        greedy_return=float(outcome.metrics["charts/return_B"]),
        mean_b=sum(actions) / len(actions) if actions else float("nan"),
        decisions=len(actions),
        improvements=len(outcome.result["improvements"]),
        cost=float(outcome.result["cost"]) if outcome.result["solved"] else float("inf"),
    )


def greedy(core: Any, task: ToyTask, episode: int, scratch: Path) -> Evaluation:
    """The greedy return of ``core``'s actor on the task, on a throwaway copy of ``core``."""
    (outcome,) = train.evaluate_outcomes(
        core,
        task.scenario,
        [task.seed],
        instance=task.instance,
        time_budget=task.time_budget,
        max_iterations=task.max_iterations,
        effort_clock=task.effort_clock,
        limit_terminates=True,
        scratch=scratch,
    )
    task.ended_on_the_limit(outcome)
    return _evaluation(episode, outcome)


class _ConstantB:
    """Stands in for the learner in ``run_episode``: answers a constant B and records each
    decision on a fresh core as executed, so its rewards and return are the learner's own."""

    def __init__(self, value: float) -> None:
        from lit_learner.core import LearnerCore

        self.value = value
        self.core = LearnerCore(toy_config(0))

    def decide(self, request: Any) -> float:
        self.core.record(request, self.value)
        return self.value

    def end_episode(self, end: Any) -> dict[str, float]:
        return self.core.end_episode(end)


def check_constant(value: int) -> None:
    low, high = toy_config(0).b.action_min, toy_config(0).b.action_max
    if not low <= value <= high:
        raise ToyError(f"constant B {value} is outside the B agent's range {low:g}..{high:g}")


def constant(task: ToyTask, value: int) -> Evaluation:
    """The return of a constant B on the task (what the learner's rewards give it)."""
    check_constant(value)
    outcome = task.run(_ConstantB(float(value)), 0, f"toy-constant-{value}", explore=False)
    return _evaluation(0, outcome)


def train_toy(
    task: ToyTask,
    learner_seed: int,
    episodes: int,
    every: int,
    scratch: Path,
    on_episode: Callable[[int, Evaluation | None], None] | None = None,
    updates: list[int] | None = None,
) -> list[Evaluation]:
    """Train a fresh B agent for ``episodes`` episodes of the task (with exploration noise) and
    return its greedy evaluations: before training, every ``every`` episodes, and at the end.
    ``on_episode(episode, evaluation or None)`` is called after each training episode; the B
    agent's gradient updates at the end are appended to ``updates``."""
    from lit_learner.core import LearnerCore

    if episodes < 0 or every < 1:
        raise ToyError(f"need episodes >= 0 and every >= 1, got {episodes} and {every}")
    task.check()
    core = LearnerCore(toy_config(learner_seed))
    curve = [greedy(core, task, 0, scratch)]
    for index in range(episodes):
        task.run(core, index, f"toy-{learner_seed}-{index}", explore=True)
        done = index + 1
        evaluation = None
        if done % every == 0 or done == episodes:
            evaluation = greedy(core, task, done, scratch)
            curve.append(evaluation)
        if on_episode is not None:
            on_episode(done, evaluation)
    if updates is not None:
        updates.append(core.agents["B"].updates)
    return curve


# --------------------------------------------------------------------------------------------
# The command


def _seeds(text: str) -> list[int]:
    """``1,3,5-8`` -> [1, 3, 5, 6, 7, 8]."""
    seeds: list[int] = []
    for part in text.split(","):
        first, dash, last = part.strip().partition("-")
        try:
            low, high = int(first), int(last if dash else first)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"not a list of seeds like 1,3,5-8: {text!r}"
            ) from None
        if high < low:
            raise argparse.ArgumentTypeError(f"empty seed range {part.strip()!r} in {text!r}")
        seeds.extend(range(low, high + 1))
    repeated = sorted({seed for seed in seeds if seeds.count(seed) > 1})
    if repeated:
        raise argparse.ArgumentTypeError(f"seeds given twice in {text!r}: {repeated}")
    return seeds


def _integers(text: str) -> list[int]:
    try:
        values = [int(part) for part in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"not a comma-separated list of integers: {text!r}"
        ) from None
    repeated = sorted({value for value in values if values.count(value) > 1})
    if repeated:
        raise argparse.ArgumentTypeError(f"values given twice in {text!r}: {repeated}")
    return values


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``lit toy``."""
    task = ToyTask()
    parser.add_argument(
        "--learner-seeds",
        type=_seeds,
        default=list(DEFAULT_LEARNER_SEEDS),
        metavar="SEEDS",
        help="one training run per learner seed, e.g. 1-8 (default 1)",
    )
    parser.add_argument(
        "--episodes",
        type=int,
        default=DEFAULT_EPISODES,
        help=f"training episodes per run (default {DEFAULT_EPISODES})",
    )
    parser.add_argument(
        "--every",
        type=int,
        default=DEFAULT_EVERY,
        metavar="N",
        help=f"greedy evaluation every N episodes (default {DEFAULT_EVERY})",
    )
    parser.add_argument(
        "--constants",
        type=_integers,
        default=list(DEFAULT_CONSTANTS),
        metavar="B,B,...",
        help="constant batch sizes to compare with (default "
        + ",".join(map(str, DEFAULT_CONSTANTS))
        + ")",
    )
    parser.add_argument(
        "--scenario",
        default=task.scenario,
        help=f"the toy query's scenario, a fixed-layout family (default {task.scenario})",
    )
    parser.add_argument(
        "--query-seed",
        type=int,
        default=task.seed,
        help=f"its planner seed, a training seed (default {task.seed})",
    )
    parser.add_argument(
        "--out",
        type=argtypes.path,
        help="output folder, written at the end (default runs/toy-<UTC time>); its earlier toy "
        "files are overwritten, other files kept",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    """Train on the toy task, write the curves, the plot and the summary; print the summary."""
    from lit_planner.errors import LitPlannerError

    try:
        summary = toy(args)
    except KeyboardInterrupt:
        print("lit toy: interrupted; nothing written", file=sys.stderr)
        return 130
    except (ToyError, train.TrainingError, LitPlannerError) as error:
        print(f"lit toy: {error}", file=sys.stderr)
        return 2
    print(summary)
    return 0


def toy(args: argparse.Namespace) -> str:
    """What ``lit toy`` does; returns the summary it printed into ``summary.md``."""
    import lit_core

    lit_core.set_log_level("warn")  # OMPL's parameter messages, once per episode, say nothing
    task = ToyTask(scenario=args.scenario, seed=args.query_seed)
    task.check()  # an unknown or random-layout scenario fails before any output
    if args.episodes < 1 or args.every < 1:
        raise ToyError(f"need --episodes >= 1 and --every >= 1, got {args.episodes}, {args.every}")
    for value in args.constants:
        check_constant(value)
    out = args.out or Path("runs") / time.strftime("toy-%Y%m%dT%H%M%SZ", time.gmtime())
    _check_writable(out)

    started = time.perf_counter()
    # A machine too slow for the horizon is refused here, before the long part.
    constants = [(value, constant(task, value)) for value in args.constants]
    curves: dict[int, list[Evaluation]] = {}
    updates: list[int] = []
    progress = _progress(len(args.learner_seeds) * args.episodes, args.no_progress)
    # The greedy evaluations' checkpoint copies, outside --out: a failed or killed run leaves
    # nothing there.
    scratch = tempfile.TemporaryDirectory(prefix="lit-toy-")
    try:
        for seed in args.learner_seeds:

            def step(done: int, evaluation: Evaluation | None, seed: int = seed) -> None:
                progress.update(1)
                if evaluation is not None:
                    progress.set_postfix(
                        {"seed": seed, "greedy": f"{evaluation.greedy_return:.2f}"}
                    )

            curves[seed] = train_toy(
                task, seed, args.episodes, args.every, Path(scratch.name), step, updates
            )
    finally:
        progress.close()
        scratch.cleanup()
    seconds = time.perf_counter() - started

    out.mkdir(parents=True, exist_ok=True)
    _write_csv(
        out / CURVES_FILE,
        [{"learner_seed": seed, **asdict(e)} for seed, curve in curves.items() for e in curve],
    )
    _write_csv(out / CONSTANTS_FILE, [{"b": value, **asdict(e)} for value, e in constants])
    _plot(out / PLOT_FILE, task, curves, constants)
    summary = _summary(task, args, curves, constants, seconds, out)
    untrained = [seed for seed, count in zip(curves, updates, strict=True) if count == 0]
    if untrained:  # the curves then show the untrained actor throughout
        summary += (
            f"\n\nNo gradient step for learner seed(s) {', '.join(map(str, untrained))}: all "
            f"{args.episodes} episodes were within the B agent's warm-up "
            f"({toy_config(0).b.warmup} stored transitions); train more episodes."
        )
    (out / SUMMARY_FILE).write_text(summary + "\n")
    return summary


def _check_writable(out: Path) -> None:
    """Refuse an --out folder that cannot be made, before any training (made and removed again
    if it is new: the results are written only at the end, so a failed run leaves nothing)."""
    if out.exists():
        if not out.is_dir():
            raise ToyError(f"--out {out} is a file")
        return
    try:
        out.mkdir(parents=True)
        out.rmdir()
    except OSError as error:
        raise ToyError(f"cannot make --out {out}: {error}") from None


def _progress(total: int, disabled: bool) -> Any:
    from tqdm import tqdm

    return tqdm(total=total, unit="ep", desc="lit toy", dynamic_ncols=True, disable=disabled)


def _write_csv(path: Path, rows: Sequence[dict[str, Any]]) -> None:
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def _summary(
    task: ToyTask,
    args: argparse.Namespace,
    curves: dict[int, list[Evaluation]],
    constants: list[tuple[int, Evaluation]],
    seconds: float,
    out: Path,
) -> str:
    points = [e.episode for e in next(iter(curves.values()))]
    lines = [
        (
            f"# lit toy: {task.scenario} instance {task.instance}, query seed {task.seed}, "
            f"{task.max_iterations} iterations as the horizon (a termination), effort clock "
            f"{task.effort_clock:g} s per checked state, budget {task.time_budget:g} s"
        ),
        "",
        (
            f"Greedy B return after N training episodes ({len(curves)} learner seed(s), "
            f"{seconds:.0f} s in all); last B: the mean executed B of the last greedy episode."
        ),
        "",
        "| learner seed | " + " | ".join(f"N = {n}" for n in points) + " | last B |",
        "|---|" + "---|" * (len(points) + 1),
    ]
    for seed, curve in curves.items():
        cells = " | ".join(f"{e.greedy_return:.2f}" for e in curve)
        lines.append(f"| {seed} | {cells} | {curve[-1].mean_b:.0f} |")
    lines += [
        "",
        "Constant B on the same query (return, improvements):",
        "",
        "| B | " + " | ".join(str(value) for value, _ in constants) + " |",
        "|---|" + "---|" * len(constants),
        "| return | " + " | ".join(f"{e.greedy_return:.2f}" for _, e in constants) + " |",
        "| improvements | " + " | ".join(str(e.improvements) for _, e in constants) + " |",
    ]
    if constants:
        best_value, best = max(constants, key=lambda item: item[1].greedy_return)
        # At least one more solution improvement within the horizon: a return that only moved by
        # its small terms (4.14 -> 4.16 at the same improvements) is not learning.
        improved = sum(
            curve[-1].improvements > curve[0].improvements
            and curve[-1].greedy_return > curve[0].greedy_return
            for curve in curves.values()
        )
        reached = sum(
            curve[-1].greedy_return >= best.greedy_return - 0.05 * abs(best.greedy_return)
            for curve in curves.values()
        )
        lines += [
            "",
            (
                f"Improved on the untrained actor (a higher return with more solution "
                f"improvements): {improved} of {len(curves)}; within 5 % of the "
                f"best constant (B = {best_value}, {best.greedy_return:.2f}): {reached} of "
                f"{len(curves)}."
            ),
        ]
    files = (CURVES_FILE, CONSTANTS_FILE, PLOT_FILE, SUMMARY_FILE)
    lines += ["", f"Files: {', '.join(str(out / name) for name in files)} (this summary)."]
    return "\n".join(lines)


def _plot(
    path: Path,
    task: ToyTask,
    curves: dict[int, list[Evaluation]],
    constants: list[tuple[int, Evaluation]],
) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(7.5, 4.5))
    for seed, curve in curves.items():
        axis.plot(
            [e.episode for e in curve],
            [e.greedy_return for e in curve],
            marker="o",
            markersize=3,
            label=f"learner seed {seed}",
        )
    if constants:
        ranked = sorted(constants, key=lambda item: item[1].greedy_return)
        for (value, evaluation), style in ((ranked[-1], "--"), (ranked[0], ":")):
            axis.axhline(
                evaluation.greedy_return,
                color="black",
                linestyle=style,
                linewidth=1,
                label=f"constant B = {value}",
            )
    axis.set_xlabel("training episodes")
    axis.set_ylabel("greedy return of the B agent")
    axis.set_title(
        f"lit toy: {task.scenario} seed {task.seed}, horizon {task.max_iterations} iterations"
    )
    axis.grid(alpha=0.3)
    axis.legend(fontsize=7, ncol=2)
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    plt.close(figure)

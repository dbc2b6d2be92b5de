"""``lit train`` against the real planner and real torch: a short run on np4 with a small warm-up.

Planner runs stop on LIT*'s own clock, so episodes are not bit-for-bit repeatable; nothing here
compares wall-clock times.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import re
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from lit_learner.config import AgentConfig, LearnerConfig
from lit_learner.metrics import CURVES_FILE, METRICS_FILE, histogram_column

from lit_learner import train
from lit_planner import planning


def small_config(seed: int = 0) -> LearnerConfig:
    """Defaults except for a warm-up and batches small enough for a few dozen np4 episodes."""
    return LearnerConfig(
        b=AgentConfig.batch_size_agent(warmup=24, batch_size=16, buffer_size=4096, beta_steps=500),
        k=AgentConfig.neighbour_agent(warmup=32, batch_size=32, buffer_size=4096, beta_steps=500),
        seed=seed,
    )


def tiny_config(seed: int = 0) -> LearnerConfig:
    """Both agents update from their first transition: a run of one or two episodes exports
    (``lit train`` exports only agents that made a gradient update)."""
    tiny = {"warmup": 1, "batch_size": 1}
    return LearnerConfig(
        b=AgentConfig.batch_size_agent(**tiny), k=AgentConfig.neighbour_agent(**tiny), seed=seed
    )


def arguments(out: Path, **overrides: object) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    train.add_arguments(parser)
    # The bag goes beside the run folder, not into the repository's bags/.
    args = parser.parse_args(["--out", str(out), "--no-progress", "--bag-dir", str(out.parent)])
    for name, value in overrides.items():
        setattr(args, name, value)
    if args.no_bag:
        args.bag_dir = None  # refused together
    return args


def test_training_distribution_never_draws_a_benchmark_query() -> None:
    import numpy as np

    distribution = train.TrainingDistribution(["np4", "rrd8"], np.random.default_rng(3))
    specs = [distribution.draw(index) for index in range(200)]
    assert {spec.scenario for spec in specs} == {"np4", "rrd8"}
    assert all(spec.seed >= train.TRAINING_SEEDS[0] for spec in specs)
    assert all(spec.instance == 0 for spec in specs if spec.scenario == "np4")
    assert all(
        spec.instance >= train.TRAINING_INSTANCES[0] for spec in specs if spec.scenario == "rrd8"
    )


def test_episode_draws_do_not_repeat_an_agents_random_numbers() -> None:
    from lit_learner.core import AGENT_SEED_OFFSET, LearnerCore

    for seed in (0, 11):
        core = LearnerCore(small_config(seed=seed))
        draws = train.draw_generator(seed).random(8)
        for name in AGENT_SEED_OFFSET:
            assert not np.isin(core.agents[name].rng.random(8), draws).any()


def test_planners_in_namespaces_draw_problems_of_their_own() -> None:
    """Two robots' planners with the same training seed fed one learner the same problems."""
    names = ["np4", "np8", "wg4", "rrd4", "rrd8"]

    def problems(namespace: str) -> list[tuple[str, int, int]]:
        distribution = train.TrainingDistribution(names, train.draw_generator(7, namespace))
        return [(d.scenario, d.instance, d.seed) for d in map(distribution.draw, range(20))]

    root = problems("/")
    assert root == [
        (d.scenario, d.instance, d.seed)
        for d in map(train.TrainingDistribution(names, train.draw_generator(7)).draw, range(20))
    ]  # lit train's and the root namespace's: the seed's own stream
    robot1, robot2 = problems("/robot1"), problems("/robot2")
    # The same in every process (a hash() of the namespace would differ with PYTHONHASHSEED):
    # a planner node restarted under /robot1 draws its problems again.
    assert robot1[:4] == [
        ("wg4", 0, 2076210052),
        ("np8", 0, 3396848681),
        ("rrd4", 2536, 1349753081),
        ("rrd8", 7607, 1339967847),
    ]
    assert len({tuple(root), tuple(robot1), tuple(robot2)}) == 3
    assert not {seed for *_, seed in robot1} & {seed for *_, seed in robot2}


def test_training_distribution_rejects_an_instance_suffix() -> None:
    import numpy as np

    with pytest.raises(train.TrainingError, match="rrd8/3.*family and dimension only"):
        train.TrainingDistribution(["rrd8/3"], np.random.default_rng(0))


def test_short_run_writes_metrics_checkpoints_resumes_and_exports(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run_dir = tmp_path / "run"
    export_dir = tmp_path / "tensors"
    phases: list[str] = []
    hooks = train.TrainingHooks(
        learner_config=small_config(), on_episode=lambda outcome: phases.append(outcome.phase)
    )
    args = arguments(
        run_dir, episodes=12, scenarios="np4", checkpoint_every=5, decision_interval=10
    )
    train.train(args, hooks)

    # b-then-k: B first (psi_K fixed), then psi_K with B from the exported B tensor.
    assert phases == [train.PHASE_B] * 6 + [train.PHASE_K] * 6
    # Said also with --no-progress (the arguments' default here), where it was silent.
    assert "lit train: B phase done; exporting its B tensor" in capsys.readouterr().err

    # The run's bag holds every episode's messages, unbroken, in the planner node's format.
    from lit_learner.offline import read_episodes

    from lit_planner import replay

    bag = tmp_path / "run-bag"
    (bag_dir,) = [p for p in tmp_path.iterdir() if (p / "metadata.yaml").exists()]
    bag_dir.rename(bag)
    info = replay.bag_info(bag)
    assert all(p["missing"] == 0 and p["leading"] == 0 for p in info["publishers"])
    episodes, _ = read_episodes([bag])
    assert len(episodes) == 12
    # One observation and one decision of an episode lost (a recording gap) left as many of
    # each: `lit replay tensors` trained on the episode as if it were complete.
    gapped = tmp_path / "gapped" / "bag"  # not beside the run's bags, which the test counts
    _without_one_pair(bag, gapped, episodes[0].key)
    rest, counts = read_episodes([gapped])
    assert [e.key for e in rest] == [e.key for e in episodes[1:]]
    assert counts.counts["incomplete training episode"] == 1
    # A SolutionUpdate lost: every later decision of the episode counted one improvement too
    # few, and the B step that ended at it was rewarded as a step without one.
    solved = next(e for e in episodes if len(e.solutions) > 1)
    lost = tmp_path / "lost-solution" / "bag"
    _without_first(bag, lost, solved.key, ("lit_msgs_json/SolutionUpdate",))
    rest, counts = read_episodes([lost])
    assert [e.key for e in rest] == [e.key for e in episodes if e is not solved]
    assert counts.counts["incomplete training episode"] == 1
    # The bag and a copy of it (a compacted or salvaged one): each message counts once.
    import shutil

    shutil.copytree(bag, tmp_path / "copy")
    twice, skipped = read_episodes([bag, tmp_path / "copy"])
    assert [e.key for e in twice] == [e.key for e in episodes]
    assert [len(e.decisions) for e in twice] == [len(e.decisions) for e in episodes]
    assert skipped.counts["message read twice (a bag and its copy?)"] > 0
    from lit_learner.offline import recorded_decision_interval

    assert recorded_decision_interval([bag]).value == 10  # the bag names its interval
    assert all(e.summary is not None and e.summary["mode"] == "training" for e in episodes)
    # Each summary carries the final features the live EpisodeEnd had, and the offline replay
    # closes the episode with them (it used the last request's features: s' = s).
    from lit_learner import offline

    ends: list[Any] = []

    class Capture:
        def record(self, *_: object) -> None:
            pass

        def end_episode(self, end: object) -> None:
            ends.append(end)

    for episode in episodes:
        final = episode.summary["final_features"]
        assert set(final) == {"B", "psi_K"} and all(0 <= v <= 1 for f in final.values() for v in f)
        offline._replay_episode(Capture(), episode)
        assert ends[-1].final_features == {k: tuple(v) for k, v in final.items()}
    sources = {d["source"] for e in episodes for d in e.decisions}
    assert sources == {"learner", "tensor"}  # psi_K phase: B from the B-phase tensor
    assert (run_dir / train.B_PHASE_TENSORS / "b_tensor.npy").exists()
    assert not (run_dir / train.B_PHASE_TENSORS / "k_tensor.npy").exists()  # not trained yet

    with (run_dir / METRICS_FILE).open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert [int(row["episode"]) for row in rows] == list(range(12))
    columns = set(rows[0])
    assert set(train.METRIC_COLUMNS) <= columns
    assert {histogram_column(agent, index) for agent in ("B", "psi_K") for index in range(10)} <= (
        columns
    )
    assert {"charts/return_B", "charts/return_psi_K"} & columns
    b_rows, k_rows = rows[:6], rows[6:]
    assert all(int(row["decisions_psi_K"]) == 0 for row in b_rows)
    assert all(int(row["decisions_psi_K"]) > 0 for row in k_rows)
    for row in b_rows:  # every B decision is counted in exactly one histogram bin
        assert sum(int(row[histogram_column("B", i)]) for i in range(10)) == int(row["decisions_B"])
    assert all(row["solved"] == "1" for row in rows)
    assert (run_dir / CURVES_FILE).stat().st_size > 10_000

    checkpoints = run_dir / train.CHECKPOINT_DIR
    assert sorted(path.name for path in checkpoints.glob("*.ckpt")) == [
        "episode-0000005.ckpt",
        "episode-0000010.ckpt",
        "final.ckpt",
    ]

    # Resume from the final checkpoint with a larger total: continues the numbering and phase.
    resumed = arguments(run_dir, episodes=14, resume=checkpoints / "final.ckpt", export=export_dir)
    train.train(resumed, train.TrainingHooks(on_episode=lambda o: phases.append(o.phase)))
    assert phases[12:] == [train.PHASE_K, train.PHASE_K]
    with (run_dir / METRICS_FILE).open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert [int(row["episode"]) for row in rows] == list(range(14))
    seeds = [int(row["seed"]) for row in rows]
    assert len(set(seeds)) == 14  # the generator continued instead of restarting
    # The resumed session's bag (same run id, seq from 0 again) is not a copy of the first one:
    # both together give all 14 episodes (its messages were skipped as read twice).
    (resumed_bag,) = [p for p in tmp_path.iterdir()
                      if (p / "metadata.yaml").exists() and p not in (bag, tmp_path / "copy")]  # fmt: skip
    both, skipped = read_episodes([bag, resumed_bag])
    assert len(both) == 14 and not skipped.counts["message read twice (a bag and its copy?)"]
    checked = replay.VerifyReport()
    for path in (bag, resumed_bag):
        replay.verify_bag(path, checked)
    assert checked.checked == 14 and checked.valid == 14, checked

    # Export: readable by the planner's tensor policy, usable for planning, with provenance.
    record = json.loads((export_dir / train.PROVENANCE_FILE).read_text())
    assert record["episodes"] == 14
    assert record["scenarios"] == ["np4"]
    assert record["command"].startswith("lit train")
    # The code of each session that trained (it named only the export's commit).
    commit = train.git_commit()
    assert record["session_commits"] == [commit, commit] and record["git_commit"] == commit
    # A run begun by an older version kept no commits: its sessions' are unknown, in place.
    final = checkpoints / "final.ckpt"
    document = json.loads(train.state_path(final).read_text())
    del document["commits"]
    train.state_path(final).write_text(json.dumps(document))
    train.train(arguments(run_dir, episodes=14, resume=final, export=export_dir))
    record = json.loads((export_dir / train.PROVENANCE_FILE).read_text())
    assert record["session_commits"] == [None, None, commit]
    assert (export_dir / CURVES_FILE).exists()
    policy = planning.make_policy("tensor", export_dir)
    assert policy.decision_interval == 10  # used as trained
    result = planning.plan("np4", policy=policy, seed=1_000_321, time=0.05)
    assert result["solved"]


def test_resume_needs_the_driver_state(tmp_path: Path) -> None:
    checkpoint = tmp_path / "run" / "checkpoints" / "lonely.ckpt"
    checkpoint.parent.mkdir(parents=True)
    checkpoint.write_bytes(b"")
    (tmp_path / "run" / train.METRICS_FILE).write_text("episode\n")
    with pytest.raises(train.TrainingError, match="driver state of this checkpoint is missing"):
        train.train(arguments(tmp_path / "run", resume=checkpoint))


def test_the_episode_end_carries_each_agents_final_state() -> None:
    """LEARNER.md: a transition pairs consecutive messages of one agent, and the planner closes
    each episode with a final message; the last transition's s' is the state at the end (the
    planner's features then), not a copy of the last decision's state."""
    from lit_learner.core import LearnerCore

    core = LearnerCore(small_config(seed=2))
    ends = []
    end_episode = core.end_episode
    core.end_episode = lambda end: ends.append(end) or end_episode(end)  # type: ignore[method-assign]
    spec = train.EpisodeSpec(0, "rrd4", 3, train.TRAINING_SEEDS[0] + 5)
    outcome = train.run_episode(core, spec, train.PHASE_JOINT, "final-state")
    assert outcome.actions["B"] and outcome.actions["psi_K"]
    (end,) = ends
    assert set(end.final_features) == {"B", "psi_K"}
    for values in end.final_features.values():
        assert len(values) == 3 and all(0.0 <= v <= 1.0 for v in values)
    b, k = end.final_features["B"], end.final_features["psi_K"]
    assert b[0] == k[0] and b[2] == k[2]  # rho_global and the measure are the agents' common part


def test_training_moves_the_b_policy_towards_higher_value_on_np4(tmp_path: Path) -> None:
    """Honest stand-in for "the return improves".

    On np4 the B return of a whole episode is far noisier than the differences between policies
    (constant B = 20, 60, 110, 160, 200 on 20 training seeds: means 5.2..6.0, standard deviations
    2.2..3.1), so a before/after comparison of noise-free returns cannot show an improvement in a
    test-sized budget. What a short run can show on real planner data: the critic, fitted to the
    rewards of real episodes, values the trained actor's actions above the initial actor's on the
    states the planner visited, and the actor really moved.
    """
    import copy

    import torch
    from lit_learner.core import LearnerCore

    core = LearnerCore(small_config(seed=1))
    agent = core.agents["B"]
    initial_actor = copy.deepcopy(agent.actor)
    evaluation_seeds = [train.TRAINING_SEEDS[0] + 7, train.TRAINING_SEEDS[0] + 8]
    before = train.evaluate(core, "np4", evaluation_seeds, scratch=tmp_path / "scratch")
    assert len(before) == 2 and all(isinstance(value, float) for value in before)
    assert core.policy_version == 0 and agent.transitions == 0  # evaluation used a copy

    for index in range(40):
        spec = train.EpisodeSpec(index, "np4", 0, train.TRAINING_SEEDS[0] + 100 + index)
        outcome = train.run_episode(core, spec, train.PHASE_B, f"toy-{index}")
        assert outcome.actions["psi_K"] == []  # psi_K stays at e in the B phase
    assert agent.updates > 100

    replay = agent.replay
    states = agent.state(torch.from_numpy(replay.state[: replay.size]))
    with torch.no_grad():
        value_before = agent.critic(states, initial_actor.normalised(states)).mean().item()
        value_after = agent.critic(states, agent.actor.normalised(states)).mean().item()
        moved = (agent.actor(states) - initial_actor(states)).abs().max().item()
    assert value_after > value_before
    assert moved > 0.5  # at least half a unit of B somewhere on the visited states


def test_evaluation_answers_every_query_with_the_same_policy(tmp_path: Path) -> None:
    """An evaluation's episodes take no gradient steps: a query evaluated again after another
    one, with the B agent past its warm-up, gets the same actions and return (the copy trained
    on each episode it evaluated, so later queries saw another actor)."""
    from lit_learner.core import LearnerCore

    core = LearnerCore(small_config(seed=1))
    for index in range(3):  # enough transitions for the copy to train at each episode's end
        spec = train.EpisodeSpec(index, "np4", 0, train.TRAINING_SEEDS[0] + 200 + index)
        train.run_episode(core, spec, train.PHASE_B, f"warm-{index}")
    assert core.agents["B"].transitions >= core.agents["B"].config.warmup
    seed = train.TRAINING_SEEDS[0] + 7
    first, other, again = train.evaluate_outcomes(
        core, "np4", [seed, seed + 1, seed], time_budget=10_000.0, max_iterations=1500,
        scratch=tmp_path / "scratch",
    )  # fmt: skip
    assert first.actions["B"] and other.actions["B"] != first.actions["B"]
    assert again.actions == first.actions and again.metrics == first.metrics


def test_an_iteration_limit_under_a_large_budget_gives_noise_free_returns(tmp_path: Path) -> None:
    """Episodes that end on LIT*'s iterations, with a budget far above their planner time, have
    every reward's time term at its floor: the same greedy policy earns the same return twice,
    and the end counts as a truncation."""
    from lit_learner.core import LearnerCore

    core = LearnerCore(small_config(seed=1))
    seed = train.TRAINING_SEEDS[0] + 7
    returns = [
        train.evaluate(
            core,
            "np4",
            [seed, seed + 1],
            time_budget=10_000.0,
            max_iterations=1500,
            scratch=tmp_path / f"scratch{i}",
        )
        for i in range(2)
    ]
    assert returns[0] == returns[1] and returns[0][0] != returns[0][1]
    spec = train.EpisodeSpec(0, "np4", 0, seed)
    outcome = train.run_episode(
        core, spec, train.PHASE_B, "limited", time_budget=10_000.0, max_iterations=1500
    )
    assert outcome.result["counters"]["iterations"] == 1500 and outcome.truncated
    # A bag does not record the limit (its replay would call the end a termination): refused.
    with pytest.raises(train.TrainingError, match="max_iterations cannot be recorded"):
        train.run_episode(
            core, spec, train.PHASE_B, "recorded", max_iterations=10, recording=object()
        )


def test_the_effort_clock_gives_noise_free_returns_with_their_time_terms(tmp_path: Path) -> None:
    """On the effort clock (planning time = states checked x a constant) the learner's times are
    counts: every time the learner sees is the check count at that moment times the constant, the
    same greedy policy earns the same return twice, and unlike the floored returns of a large
    budget the time terms are alive (a tenth of the budget changes the return)."""
    from lit_learner.core import LearnerCore

    seed = train.TRAINING_SEEDS[0] + 7
    spec = train.EpisodeSpec(0, "np4", 0, seed)
    clock = 2.0**-20  # about 1 us per state, exact in binary: times / clock are integers
    core = LearnerCore(small_config(seed=1))

    # What run_episode sends: the planning times of the requests and of the episode's end.
    times: list[float] = []
    ends: list[float] = []
    decide, end_episode = core.decide, core.end_episode

    def seen_decide(request: Any) -> float:
        times.append(request.planning_time)
        return decide(request)

    def seen_end(end: Any) -> Any:
        ends.append(end.planning_time)
        return end_episode(end)

    core.decide, core.end_episode = seen_decide, seen_end  # type: ignore[method-assign]
    outcome = train.run_episode(
        core,
        spec,
        train.PHASE_JOINT,
        "effort",
        time_budget=1.0,
        max_iterations=1500,
        effort_clock=clock,
    )
    counts = [value / clock for value in times]
    assert len(counts) > 2 and counts == sorted(counts) and counts[-1] > counts[0]
    # The same query replayed with the learner's actions (the search is deterministic per seed)
    # has the same check count at every decision.
    import lit_core

    from lit_planner import planning

    queued = {kind: list(values) for kind, values in outcome.actions.items()}
    replayed: list[int] = []

    def replay(context: lit_core.DecisionContext) -> float:
        replayed.append(context.checks)
        return queued[context.kind].pop(0)

    planning.plan(
        "np4",
        policy=lit_core.ExternalPolicy(replay, decides_neighbour_factor=True),
        time=1.0,
        seed=seed,
        max_iterations=1500,
        params={"decision_interval": train.DEFAULT_DECISION_INTERVAL},
        check_path=False,
    )
    assert counts == replayed
    assert outcome.result["counters"]["iterations"] == 1500  # the limit, not the budget, ended it
    assert ends == [outcome.result["counters"]["collision_checks"] * clock]
    assert ends[0] >= times[-1]

    def returns(budget: float, name: str) -> list[float]:
        return train.evaluate(
            LearnerCore(small_config(seed=1)),
            "np4",
            [seed],
            agent="psi_K",
            time_budget=budget,
            max_iterations=1500,
            effort_clock=clock,
            scratch=tmp_path / name,
        )

    first, again = returns(1.0, "a"), returns(1.0, "b")
    assert first == again
    # A tenth of the budget makes every t / T ten times larger: the return changes.
    assert returns(0.1, "c") != first

    with pytest.raises(train.TrainingError, match="effort_clock must be finite and >= 0"):
        train.run_episode(core, spec, train.PHASE_B, "bad", max_iterations=10, effort_clock=-1.0)
    with pytest.raises(train.TrainingError, match="effort_clock needs max_iterations"):
        train.run_episode(core, spec, train.PHASE_B, "unlimited", effort_clock=clock)
    with pytest.raises(
        train.TrainingError, match="an episode on the effort clock cannot be recorded"
    ):
        train.run_episode(core, spec, train.PHASE_B, "rec", effort_clock=clock, recording=object())


def test_run_reports_bad_input_as_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert train.run(arguments(tmp_path / "run", scenarios="np4,xx9", episodes=1)) == 2
    err = capsys.readouterr().err
    assert "unknown scenario 'xx9'" in err and err.count("xx9") == 1, err
    assert train.run(arguments(tmp_path / "run", scenarios="np4,rrd8,np4", episodes=1)) == 2
    assert "training scenario 'np4' given more than once" in capsys.readouterr().err
    assert train.run(arguments(tmp_path / "run", decision_interval=0)) == 2
    assert "--decision-interval must be between 1 and 4294967295, got 0" in capsys.readouterr().err
    # Beyond the planner's unsigned 32-bit parameter: refused before a run folder or bag exists
    # (it failed in the first episode and left a run that could not be resumed).
    assert train.run(arguments(tmp_path / "run", decision_interval=2**32)) == 2
    assert "got 4294967296" in capsys.readouterr().err
    for minutes in (0.0, math.inf, math.nan):  # inf was taken (its driver state: Infinity)
        assert train.run(arguments(tmp_path / "run", minutes=minutes)) == 2
        assert f"--minutes must be a positive finite number, got {minutes}" in (
            capsys.readouterr().err
        )
    assert list(tmp_path.iterdir()) == []
    assert train.run(arguments(tmp_path / "run", w_search=-1.0)) == 2
    assert "--w-search must be finite and >= 0, got -1.0" in capsys.readouterr().err
    assert train.run(arguments(tmp_path / "run", resume=tmp_path / "x.ckpt", w_search=2.0)) == 2
    assert "--w-search is set when a run starts" in capsys.readouterr().err


def test_w_search_sets_the_search_cost_of_a_new_run(tmp_path: Path) -> None:
    from lit_learner.core import LearnerCore

    train.train(arguments(tmp_path / "run", scenarios="np4", episodes=2, w_search=2.5))
    core = LearnerCore.load_checkpoint(tmp_path / "run" / "checkpoints" / "final.ckpt")
    assert core.config.reward.w_search == 2.5


def test_ctrl_c_finishes_the_query_then_stops_with_a_final_checkpoint(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from lit_learner.core import LearnerCore

    original = LearnerCore.decide
    calls = {"count": 0}

    def decide_with_one_interrupt(self: LearnerCore, request: object) -> float:
        calls["count"] += 1
        if calls["count"] == 30:  # in the third or so episode
            raise KeyboardInterrupt
        return original(self, request)

    monkeypatch.setattr(LearnerCore, "decide", decide_with_one_interrupt)
    outcomes: list[train.EpisodeOutcome] = []
    hooks = train.TrainingHooks(learner_config=small_config(), on_episode=outcomes.append)
    result = train.train(arguments(tmp_path / "run", episodes=50, scenarios="np4"), hooks)
    assert result.interrupted and "(interrupted: --resume" in result.summary
    assert 1 <= len(outcomes) < 50 and outcomes[-1].interrupted
    assert not any(outcome.interrupted for outcome in outcomes[:-1])
    assert outcomes[-1].result["solved"]  # the interrupted query still ran to its budget
    state = train.DriverState.load(
        train.state_path(tmp_path / "run" / train.CHECKPOINT_DIR / "final.ckpt")
    )
    assert state.episode == len(outcomes)


def test_ctrl_c_that_leaves_a_query_leaves_a_checkpoint_that_resumes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Python's own Ctrl-C lands wherever Python is: a second one while the first is handled
    leaves the policy callback and plan(). The final checkpoint held the episode's open steps
    and its resume failed (the rerun episode has the same id)."""
    from lit_learner.core import LearnerCore

    original = LearnerCore.decide
    calls = {"count": 0}

    def decide_interrupted_twice(self: LearnerCore, request: object) -> float:
        calls["count"] += 1
        if calls["count"] in (30, 31):
            raise KeyboardInterrupt
        return original(self, request)

    monkeypatch.setattr(LearnerCore, "decide", decide_interrupted_twice)
    run_dir = tmp_path / "run"
    hooks = train.TrainingHooks(learner_config=small_config())
    result = train.train(arguments(run_dir, episodes=50, scenarios="np4", no_bag=True), hooks)
    assert result.interrupted
    final = run_dir / train.CHECKPOINT_DIR / "final.ckpt"
    done = train.DriverState.load(train.state_path(final)).episode
    assert LearnerCore.load_checkpoint(final).open_episodes() == set()
    monkeypatch.setattr(LearnerCore, "decide", original)
    train.train(arguments(run_dir, episodes=done + 2, resume=final))
    assert train.DriverState.load(train.state_path(final)).episode == done + 2


def test_ctrl_c_exits_with_130(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from lit_learner.core import LearnerCore

    original = LearnerCore.decide
    calls = {"count": 0}

    def decide_with_one_interrupt(self: LearnerCore, request: object) -> float:
        calls["count"] += 1
        if calls["count"] == 5:
            raise KeyboardInterrupt
        return original(self, request)

    monkeypatch.setattr(LearnerCore, "decide", decide_with_one_interrupt)
    assert train.run(arguments(tmp_path / "run", episodes=50, scenarios="np4")) == 130
    assert "(interrupted: --resume the final checkpoint" in capsys.readouterr().out
    assert train.run(arguments(tmp_path / "again", episodes=1, scenarios="np4")) == 0


def test_a_rollback_refused_for_its_bag_folder_changes_nothing(tmp_path: Path) -> None:
    """The run's stored bag folder is checked before --rollback drops anything: it dropped the
    metrics rows first and then refused the folder, and the later checkpoints no longer resumed
    ("holds 6 episodes and metrics.csv 3 rows")."""
    run_dir, bags = tmp_path / "run", tmp_path / "bags"
    hooks = train.TrainingHooks(learner_config=small_config())
    train.train(
        arguments(run_dir, episodes=6, scenarios="np4", checkpoint_every=3, bag_dir=str(bags)),
        hooks,
    )
    rows = (run_dir / METRICS_FILE).read_text()
    shutil.rmtree(bags)
    bags.write_text("a file where the run's bag folder was")
    earlier = run_dir / train.CHECKPOINT_DIR / "episode-0000003.ckpt"
    with pytest.raises(train.TrainingError, match=f"bag folder {bags}: .* is a file"):
        train.train(
            arguments(run_dir, episodes=5, resume=earlier, rollback=True, bag_dir=None), hooks
        )
    assert (run_dir / METRICS_FILE).read_text() == rows  # nothing dropped
    assert (run_dir / train.CHECKPOINT_DIR / "episode-0000006.ckpt").is_file()  # nor removed


def test_resume_from_an_earlier_checkpoint_trains_its_episodes_again_once(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Rows of episodes after the checkpoint leave metrics.csv: they are trained again, and
    must not appear twice."""
    run_dir = tmp_path / "run"
    hooks = train.TrainingHooks(learner_config=small_config())
    train.train(arguments(run_dir, episodes=6, scenarios="np4", checkpoint_every=3), hooks)
    earlier = run_dir / train.CHECKPOINT_DIR / "episode-0000003.ckpt"
    rows = (run_dir / METRICS_FILE).read_text()
    # Not without --rollback: a stale final.ckpt resumed after a crash lost the later episodes.
    with pytest.raises(train.TrainingError) as refused:
        train.train(arguments(run_dir, episodes=5, resume=earlier))
    assert "has a later checkpoint" in str(refused.value) and "final.ckpt (episode 6)" in str(
        refused.value
    )
    assert "removes the 2 later checkpoint(s)" in str(refused.value)
    assert (run_dir / METRICS_FILE).read_text() == rows  # nothing touched
    train.train(arguments(run_dir, episodes=5, resume=earlier, rollback=True))
    err = capsys.readouterr().err
    assert "dropped the rows of 3 episodes after the checkpoint" in err
    assert "removed" in err and "episode-0000006.ckpt" in err  # of the dropped history
    names = sorted(path.name for path in (run_dir / train.CHECKPOINT_DIR).glob("*.ckpt"))
    assert names == ["episode-0000003.ckpt", "final.ckpt"]
    with (run_dir / METRICS_FILE).open(newline="") as handle:
        assert [int(row["episode"]) for row in csv.DictReader(handle)] == [0, 1, 2, 3, 4]

    # lit replay tensors of both sessions' bags: episodes 3 and 4 once each, as the resumed
    # session recorded them (same ids: the two recordings merged and both were left out as
    # incomplete); episode 5, which only the first session ran, stays.
    from lit_learner import offline

    first, again = sorted(p for p in tmp_path.iterdir() if (p / "metadata.yaml").exists())
    ids = [f"{e.key[2]}" for e in offline.read_episodes([first])[0]]
    (resumed, _) = offline.read_episodes([again])
    assert [e.key[2] for e in resumed] == ids[3:5]
    for bags in ([first, again], [again, first]):
        episodes, skipped = offline.read_episodes(bags)
        assert sorted(e.key[2] for e in episodes) == ids, bags
        assert (
            skipped.counts[offline.RECORDED_AGAIN] == 2 and not skipped.counts[offline.INCOMPLETE]
        )
        used = {e.key[2]: e.summary_stamp_ns for e in episodes}
        assert [used[e.key[2]] for e in resumed] == [e.summary_stamp_ns for e in resumed]
    assert [e.key[2] for e in offline.read_episodes([first, again])[0]] == ids
    # The first session stopped at once inside episode 4 (a second Ctrl-C: no summary), and the
    # resumed one ran it again: its partial first recording is not mixed into the second.
    stopped = tmp_path / "stopped" / "bag"
    cut = {"done": False}

    def after_the_cut(item: Any) -> bool:
        if item.schema == offline.SUMMARY and item.payload["episode_id"] == ids[4]:
            cut["done"] = True
        return cut["done"]

    _copy_bag(first, stopped, after_the_cut)
    episodes, skipped = offline.read_episodes([stopped, again])
    assert [e.key[2] for e in episodes] == ids[:5] and not skipped.counts[offline.INCOMPLETE]
    # ... and the cut-off recording is not counted as left out: the resumed run's is used. Alone,
    # it is (it was dropped without a word).
    assert not skipped.counts[offline.NO_SUMMARY]
    assert offline.read_episodes([stopped])[1].counts[offline.NO_SUMMARY] == 1

    final = run_dir / train.CHECKPOINT_DIR / "final.ckpt"
    with pytest.raises(train.TrainingError, match="has 5 episodes already"):
        train.train(arguments(run_dir, episodes=4, resume=final))
    with pytest.raises(train.TrainingError, match="a folder; give a checkpoint file"):
        train.train(arguments(run_dir, episodes=9, resume=run_dir))
    train.state_path(final).write_text("{")
    with pytest.raises(train.TrainingError, match="not a readable driver state"):
        train.train(arguments(run_dir, episodes=9, resume=final))


@pytest.mark.parametrize("option", ["out", "export", "bag_dir"])
def test_a_file_in_the_way_is_refused_before_training(tmp_path: Path, option: str) -> None:
    blocker = tmp_path / "afile"
    blocker.write_text("not a folder\n")
    args = arguments(tmp_path / "run", episodes=2, scenarios="np4")
    setattr(args, option, blocker / "sub" if option == "out" else blocker)
    with pytest.raises(train.TrainingError, match="is a file, not a folder"):
        train.train(args)
    assert sorted(path.name for path in tmp_path.iterdir()) == ["afile"]  # nothing trained


def test_an_earlier_export_is_refused_before_training_and_a_run_exports_without_training(
    tmp_path: Path,
) -> None:
    earlier = tmp_path / "shipped"
    earlier.mkdir()
    (earlier / "b_tensor.npy").write_bytes(b"earlier export")
    with pytest.raises(train.TrainingError, match="exists and is not empty"):
        train.train(arguments(tmp_path / "run", episodes=2, scenarios="np4", export=earlier))
    assert sorted(path.name for path in tmp_path.iterdir()) == ["shipped"]  # nothing trained
    assert (earlier / "b_tensor.npy").read_bytes() == b"earlier export"

    run_dir = tmp_path / "run"
    hooks = train.TrainingHooks(learner_config=tiny_config())
    train.train(arguments(run_dir, episodes=2, scenarios="np4", no_bag=True), hooks)
    final = run_dir / train.CHECKPOINT_DIR / "final.ckpt"
    rows = (run_dir / METRICS_FILE).read_text()
    export_dir = tmp_path / "export"
    train.train(arguments(run_dir, resume=final, export=export_dir, no_bag=True))
    assert (run_dir / METRICS_FILE).read_text() == rows  # no episode trained
    assert json.loads((export_dir / train.PROVENANCE_FILE).read_text())["episodes"] == 2
    assert planning.make_policy("tensor", export_dir) is not None


def test_a_final_checkpoint_past_the_metrics_rows_is_not_resumed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A resume that went back to an earlier checkpoint (before --rollback) left final.ckpt of
    the abandoned history: resuming it would continue that history beside the new rows."""
    run_dir = tmp_path / "run"
    hooks = train.TrainingHooks(learner_config=small_config())
    train.train(
        arguments(run_dir, episodes=6, scenarios="np4", checkpoint_every=3, no_bag=True), hooks
    )
    metrics = run_dir / METRICS_FILE
    metrics.write_text("".join(metrics.read_text().splitlines(keepends=True)[:5]))  # 4 rows
    final = run_dir / train.CHECKPOINT_DIR / "final.ckpt"
    with pytest.raises(train.TrainingError, match="holds 6 episodes and metrics.csv 4 rows"):
        train.train(arguments(run_dir, episodes=8, resume=final))
    earlier = run_dir / train.CHECKPOINT_DIR / "episode-0000003.ckpt"
    train.train(arguments(run_dir, episodes=5, resume=earlier, rollback=True, no_bag=True))
    err = capsys.readouterr().err
    assert "episode-0000006.ckpt (--rollback)" in err and "(past the metrics rows)" in err
    assert train.DriverState.load(train.state_path(final)).episode == 5


def test_a_file_that_cannot_be_written_ends_lit_train_in_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A full disk (or a folder where metrics.csv was) ended `lit train` in a traceback (exit 1):
    now one line, exit 2, after what could be saved was."""
    from lit_learner.core import LearnerCore

    def full_disk(self: LearnerCore, end: Any) -> Any:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(LearnerCore, "close_episode", full_disk)
    code = train.run(arguments(tmp_path / "run", episodes=2, scenarios="np4", no_bag=True))
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.rstrip().splitlines()[-1] == "lit train: [Errno 28] No space left on device"


def _full_disk_for(path: Path) -> None:
    """Make the temporary file that :meth:`LearnerCore.write_checkpoint` writes ``path`` through
    (from this process's main thread) a link to /dev/full: every write to it fails as on a full
    disk, and torch reports that as a RuntimeError."""
    import threading

    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_name(f"{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    temporary.symlink_to("/dev/full")


def test_a_checkpoint_that_cannot_be_written_is_an_os_error(tmp_path: Path) -> None:
    """torch reports a full disk as RuntimeError ("unexpected pos ..."), which the callers'
    handling of OSError let through as a traceback."""
    from lit_learner.core import LearnerCore

    path = tmp_path / "final.ckpt"
    _full_disk_for(path)
    core = LearnerCore(small_config())
    with pytest.raises(OSError, match=r"final.ckpt: the checkpoint could not be written \("):
        core.save_checkpoint(path)
    assert list(tmp_path.iterdir()) == []  # neither the checkpoint nor the link left


def test_a_full_disk_at_a_periodic_checkpoint_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """It was a traceback (exit 1) that blamed episode 2, which had finished."""
    run_dir = tmp_path / "run"
    checkpoints = run_dir / train.CHECKPOINT_DIR

    def disk_fills(outcome: Any) -> None:  # after the first episode: both checkpoints fail
        if outcome.spec.index == 0:
            for name in ("episode-0000002.ckpt", "final.ckpt"):
                _full_disk_for(checkpoints / name)

    hooks = train.TrainingHooks(learner_config=small_config(), on_episode=disk_fills)
    options = {"episodes": 4, "scenarios": "np4", "no_bag": True, "checkpoint_every": 2}
    with pytest.raises(OSError, match="the checkpoint could not be written"):
        train.train(arguments(run_dir, **options), hooks)
    err = capsys.readouterr().err
    assert "lit train: the checkpoint after 2 episodes failed, and so did saving the final" in err
    assert not list(checkpoints.glob("*.ckpt"))


def test_a_bag_that_cannot_be_written_saves_the_episodes_done(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The bag was written after the learner had closed the episode, so a full bag disk never
    left a final checkpoint; and a bag that failed to close replaced the error and skipped it."""
    from lit_planner.bag import EpisodeRecording

    original = EpisodeRecording.write_query
    calls = {"count": 0}

    def failing_second(self: EpisodeRecording, *args: Any) -> Any:
        calls["count"] += 1
        if calls["count"] == 2:
            raise OSError(28, "No space left on device")
        return original(self, *args)

    monkeypatch.setattr(EpisodeRecording, "write_query", failing_second)
    run_dir = tmp_path / "run"
    hooks = train.TrainingHooks(learner_config=small_config())
    with pytest.raises(OSError, match="No space left"):
        train.train(arguments(run_dir, episodes=4, scenarios="np4"), hooks)
    final = run_dir / train.CHECKPOINT_DIR / "final.ckpt"
    assert "episode 1 failed (OSError); the 1 episodes done are in" in capsys.readouterr().err
    assert train.DriverState.load(train.state_path(final)).episode == 1

    monkeypatch.setattr(EpisodeRecording, "write_query", original)

    def failing_close(self: EpisodeRecording) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(EpisodeRecording, "close", failing_close)
    again = tmp_path / "again"
    with pytest.raises(OSError, match="No space left"):
        train.train(arguments(again, episodes=2, scenarios="np4"), hooks)
    final = again / train.CHECKPOINT_DIR / "final.ckpt"
    assert "closing the bag failed (OSError); the 2 episodes done are in" in (
        capsys.readouterr().err
    )
    assert train.DriverState.load(train.state_path(final)).episode == 2


def test_a_failed_b_phase_export_is_named_and_the_episodes_kept(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """An error between episodes was blamed on the last place that had been named (the
    checkpoint after them, which had been written)."""

    def full_disk(*_: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(train, "_switch_to_k", full_disk)
    run_dir = tmp_path / "run"
    hooks = train.TrainingHooks(learner_config=small_config())
    options = {"episodes": 4, "scenarios": "np4", "no_bag": True, "checkpoint_every": 2}
    with pytest.raises(OSError, match="No space left"):
        train.train(arguments(run_dir, **options), hooks)
    err = capsys.readouterr().err
    assert "lit train: the B phase's export of its B tensor failed (OSError); the 2 episodes" in err
    final = run_dir / train.CHECKPOINT_DIR / "final.ckpt"
    assert train.DriverState.load(train.state_path(final)).episode == 2


def test_an_error_in_an_episode_saves_the_episodes_before_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Only Ctrl-C used to reach the final checkpoint: any other error lost the episodes since
    the last periodic one (up to --checkpoint-every - 1)."""
    from lit_learner.core import LearnerCore

    original = LearnerCore.close_episode
    calls = {"count": 0}

    def failing_third(self: LearnerCore, end: Any) -> Any:
        calls["count"] += 1
        if calls["count"] == 3:  # the query planned, its decisions taken
            raise OSError(28, "No space left on device")
        return original(self, end)

    monkeypatch.setattr(LearnerCore, "close_episode", failing_third)
    run_dir = tmp_path / "run"
    hooks = train.TrainingHooks(learner_config=tiny_config())  # exports after two episodes
    with pytest.raises(OSError, match="No space left"):
        train.train(arguments(run_dir, episodes=6, scenarios="np4", no_bag=True), hooks)
    final = run_dir / train.CHECKPOINT_DIR / "final.ckpt"
    assert "episode 2 failed (OSError); the 2 episodes done are in" in capsys.readouterr().err
    assert train.DriverState.load(train.state_path(final)).episode == 2
    monkeypatch.setattr(LearnerCore, "close_episode", original)
    # Exported as it is: --episodes at the checkpoint's count trains nothing (it was refused, and
    # --resume --export alone trains on to the run's total).
    as_it_is = tmp_path / "as-it-is"
    train.train(arguments(run_dir, resume=final, episodes=2, export=as_it_is))
    assert json.loads((as_it_is / train.PROVENANCE_FILE).read_text())["episodes"] == 2
    assert train.DriverState.load(train.state_path(final)).episode == 2
    capsys.readouterr()
    result = train.train(arguments(run_dir, resume=final, episodes=6))  # open steps dropped
    out, err = result.summary, capsys.readouterr().err
    assert "resuming at episode 2" in err
    # One total: said without "whichever comes first"; the summary counts each phase in words.
    assert "to the run's total of 6 episodes\n" in err and "whichever" not in err, err
    assert re.search(r"lit train: 6 episodes in [\d.]+ min \(\d+ B(, \d+ psi_K)?\)", out), out
    assert train.DriverState.load(train.state_path(final)).episode == 6
    with (run_dir / METRICS_FILE).open(newline="") as handle:
        assert [int(row["episode"]) for row in csv.DictReader(handle)] == list(range(6))


def test_export_into_the_run_folder_is_refused_and_an_export_records_no_bag(
    tmp_path: Path,
) -> None:
    run_dir = tmp_path / "run"
    with pytest.raises(train.TrainingError, match="is the run folder"):
        train.train(arguments(run_dir, episodes=1, scenarios="np4", export=run_dir))
    assert not run_dir.exists()
    hooks = train.TrainingHooks(learner_config=tiny_config())
    train.train(arguments(run_dir, episodes=1, scenarios="np4"), hooks)  # bag beside the run
    before = sorted(path.name for path in tmp_path.iterdir())
    final = run_dir / train.CHECKPOINT_DIR / "final.ckpt"
    result = train.train(arguments(run_dir, resume=final, export=tmp_path / "tensors"))
    assert "bag" not in result.summary
    assert sorted(path.name for path in tmp_path.iterdir()) == sorted([*before, "tensors"])
    # A resume may replace its own run's export (an interrupted run exports what it reached),
    # never another run's; it does not take its own earlier export for somebody else's.
    again = train.train(arguments(run_dir, resume=final, episodes=2, export=tmp_path / "tensors"))
    provenance = json.loads((tmp_path / "tensors" / train.PROVENANCE_FILE).read_text())
    assert provenance["episodes"] == 2
    assert "replaced" not in again.summary, again.summary
    # Tensors that something else writes into the export folder while the run trains are named.
    meanwhile = tmp_path / "meanwhile"

    def write_there(outcome: train.EpisodeOutcome) -> None:
        meanwhile.mkdir(exist_ok=True)
        (meanwhile / "k_tensor.npy").write_bytes(b"another writer")

    hooks_writing = train.TrainingHooks(learner_config=tiny_config(), on_episode=write_there)
    crossed = train.train(
        arguments(tmp_path / "crossed", episodes=1, scenarios="np4", no_bag=True, export=meanwhile),
        hooks_writing,
    )
    assert f"replaced or removed the tensors written to {meanwhile} during this run" in (
        crossed.summary
    )
    # Only an agent that made a gradient update is exported: one episode of the B phase trains
    # B only, and psi_K's file (the other writer's) goes rather than stay beside B's.
    assert (meanwhile / "b_tensor.npy").is_file()
    assert not list(meanwhile.glob("k_tensor.*")), sorted(meanwhile.iterdir())
    assert (
        "  psi_K: no tensor (no gradient update yet: 0 of the 1 transitions its updates wait "
        "for); the tensor policy keeps its fixed value (psi_K = e)"
    ) in crossed.summary, crossed.summary
    # Resumed into its own earlier export that holds psi_K's initial actor (as exports did before
    # only trained agents were exported): that tensor goes, B's is written again.
    from lit_learner.core import LearnerCore

    LearnerCore(small_config()).export_tensors(tmp_path / "old", {"note": "untrained"})
    for name in ("k_tensor.npy", "k_tensor.json"):
        shutil.copy2(tmp_path / "old" / name, meanwhile / name)
    resumed = train.train(
        arguments(tmp_path / "crossed", resume=tmp_path / "crossed" / train.CHECKPOINT_DIR
                  / "final.ckpt", episodes=1, export=meanwhile, no_bag=True)
    )  # fmt: skip
    assert sorted(path.name for path in meanwhile.glob("*_tensor.*")) == [
        "b_tensor.json", "b_tensor.npy"
    ], resumed.summary  # fmt: skip
    # An agent without an update has no tensor (its initial actor, played by the tensor policy,
    # decided psi_K about 9 where the fixed value is e); with none, the export holds no tensor.
    untrained = train.train(
        arguments(tmp_path / "short", episodes=1, scenarios="np4", no_bag=True,
                  export=tmp_path / "none"),
        train.TrainingHooks(learner_config=small_config()),
    )  # fmt: skip
    assert f"tensors: none in {tmp_path / 'none'} (no agent made a gradient update yet" in (
        untrained.summary
    )
    assert not list((tmp_path / "none").glob("*_tensor.*"))
    assert (tmp_path / "none" / train.PROVENANCE_FILE).is_file()
    for name, warmup, fixed in (("B", 24, "B = 100"), ("psi_K", 32, "psi_K = e")):
        line = rf"  {name}: no tensor \(no gradient update yet: \d+ of the {warmup} transitions "
        assert re.search(
            line + rf"its updates wait for\); the tensor policy keeps its fixed value \({fixed}\)",
            untrained.summary,
        ), untrained.summary
    other = tmp_path / "other"
    train.train(arguments(other, episodes=1, scenarios="np4", no_bag=True), hooks)
    with pytest.raises(train.TrainingError, match="exists and is not empty"):
        train.train(
            arguments(other, resume=other / train.CHECKPOINT_DIR / "final.ckpt",
                      export=tmp_path / "tensors", no_bag=True)
        )  # fmt: skip
    # What an export killed mid-way left (its staging folder) does not refuse the retry.
    stale = tmp_path / "after-a-kill" / ".staged-older"
    stale.mkdir(parents=True)
    train.train(
        arguments(other, resume=other / train.CHECKPOINT_DIR / "final.ckpt",
                  export=stale.parent, no_bag=True)
    )  # fmt: skip
    assert (stale.parent / "b_tensor.npy").is_file() and not stale.exists()


def test_a_checkpoint_and_driver_state_of_different_writes_are_refused(tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    hooks = train.TrainingHooks(learner_config=small_config())
    train.train(arguments(run_dir, episodes=2, scenarios="np4", no_bag=True), hooks)
    final = run_dir / train.CHECKPOINT_DIR / "final.ckpt"
    state = json.loads(train.state_path(final).read_text())
    state["episode"] = 1  # as the previous write left it
    train.state_path(final).write_text(json.dumps(state))
    with pytest.raises(train.TrainingError, match="holds 2 episodes and its driver state"):
        train.train(arguments(run_dir, episodes=4, resume=final))


def test_unknown_scenario_leaves_no_run_folder(tmp_path: Path) -> None:
    with pytest.raises(train.TrainingError, match="unknown scenario 'foo4'"):
        train.train(arguments(tmp_path / "run", episodes=2, scenarios="foo4"))
    assert not (tmp_path / "run").exists()


def test_resume_keeps_the_runs_checkpoint_interval_and_one_process_per_run(
    tmp_path: Path,
) -> None:
    import fcntl

    run_dir = tmp_path / "run"
    hooks = train.TrainingHooks(learner_config=small_config())
    train.train(arguments(run_dir, episodes=2, scenarios="np4", checkpoint_every=1), hooks)
    final = run_dir / train.CHECKPOINT_DIR / "final.ckpt"
    train.train(arguments(run_dir, episodes=4, resume=final))  # no --checkpoint-every: the run's
    names = sorted(path.name for path in (run_dir / train.CHECKPOINT_DIR).glob("*.ckpt"))
    assert names == ["episode-0000003.ckpt", "episode-0000004.ckpt", "final.ckpt"]

    with (run_dir / train.LOCK_FILE).open("w") as held:  # as another lit train would hold it
        fcntl.flock(held, fcntl.LOCK_EX | fcntl.LOCK_NB)
        with pytest.raises(train.TrainingError, match="in use by another lit train process"):
            train.train(arguments(run_dir, episodes=6, resume=final))
    with pytest.raises(train.TrainingError, match="--checkpoint-every must be 0 or more"):
        train.train(arguments(tmp_path / "other", episodes=2, checkpoint_every=-1))


def test_episode_limits_apply_to_every_episode_and_carry_over_a_resume(tmp_path: Path) -> None:
    """``--max-iterations``, ``--limit-terminates``, ``--effort-clock`` and ``--budget-scale``
    reach every episode of the run (and of its resumption, which keeps them), and the provenance
    names them."""
    from lit_planner import scenarios

    seen: list[train.EpisodeOutcome] = []
    hooks = train.TrainingHooks(learner_config=small_config(), on_episode=seen.append)
    limits = {
        "max_iterations": 300,
        "limit_terminates": True,
        "effort_clock": 1e-7,
        "budget_scale": 20.0,
        "no_bag": True,
    }
    run = tmp_path / "run"
    train.train(arguments(run, scenarios="np4", episodes=2, **limits), hooks=hooks)
    train.train(
        arguments(run, episodes=3, no_bag=True, resume=run / "checkpoints" / "final.ckpt"),
        hooks=hooks,
    )
    assert len(seen) == 3
    np4_budget = scenarios.get("np4").time_budget
    for outcome in seen:  # each ended on the limit, as a termination (not on the budget)
        assert outcome.result["counters"]["iterations"] == 300
        assert not outcome.truncated
        assert outcome.result["time_budget"] == pytest.approx(20.0 * np4_budget)
    record = json.loads((run / train.PROVENANCE_FILE).read_text())
    assert record["episode_limits"] == {
        "max_iterations": 300,
        "effort_clock_s_per_check": 1e-7,
        "limit_terminates": True,
        "budget_scale": 20.0,
    }


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"max_iterations": -1, "no_bag": True}, "--max-iterations must be 0 or more, got -1"),
        ({"effort_clock": 1e-7, "no_bag": True}, "--effort-clock needs --max-iterations"),
        ({"limit_terminates": True, "no_bag": True}, "--limit-terminates needs --max-iterations"),
        ({"max_iterations": 10, "effort_clock": float("nan"), "no_bag": True}, "finite and >= 0"),
        ({"budget_scale": 0.0}, "--budget-scale must be finite and positive, got 0.0"),
        # np4's budget times 1e12 is beyond what the planner accepts: refused before the learner
        (
            {"budget_scale": 1e12, "no_bag": True},
            r"--budget-scale 1e\+12 gives budgets up to .* more than the 1e\+09 s",
        ),
        (
            {"budget_scale": 1e-9, "no_bag": True},
            r"--budget-scale 1e-09 gives budgets down to .* less than the 1e-06 s --budget-scale allows",
        ),
        ({"max_iterations": 10}, "cannot be recorded .* add --no-bag"),
    ],
)
def test_episode_limits_refuse_bad_values(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], options: dict[str, object], message: str
) -> None:
    import re

    args = arguments(tmp_path / "run", scenarios="np4", episodes=1, **options)
    assert train.run(args) == 2
    assert re.search(message, capsys.readouterr().err)
    assert not (tmp_path / "run").exists()  # refused before anything was written


def test_a_resume_keeps_the_episode_limits(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run"
    limited = {"max_iterations": 200, "no_bag": True}
    train.train(arguments(run, scenarios="np4", episodes=1, **limited))
    final = run / "checkpoints" / "final.ckpt"
    assert train.run(arguments(run, episodes=2, resume=final, max_iterations=300)) == 2
    assert "--max-iterations (the run's: 200): set when a run starts" in capsys.readouterr().err
    assert train.run(arguments(run, episodes=2, resume=final)) == 2  # would record a bag
    assert "resume it with --no-bag" in capsys.readouterr().err
    # the run's own values, given again, are fine
    assert train.run(arguments(run, episodes=2, resume=final, max_iterations=200, no_bag=True)) == 0


def test_a_new_total_in_one_unit_is_refused_when_the_other_stops_the_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """It trained nothing and exited 0: the run's total in the other unit still applied."""
    run = tmp_path / "run"
    # 0.03 s: the run stops on its minutes after its first episode, long before 50 episodes.
    assert train.run(arguments(run, scenarios="np4", episodes=50, minutes=0.0005, no_bag=True)) == 0
    final = run / "checkpoints" / "final.ckpt"
    capsys.readouterr()
    assert train.run(arguments(run, episodes=60, resume=final, no_bag=True)) == 2
    err = capsys.readouterr().err
    assert "--episodes with --resume: the run's total of 0.0005 minutes" in err, err
    assert "give a larger --minutes as well" in err, err
    episodes = train.DriverState.load(train.state_path(final)).episode
    # Raising the reached total trains on; the other way round is refused the same way.
    assert train.run(arguments(run, resume=final, minutes=1.0, episodes=episodes + 1,
                               no_bag=True)) == 0  # fmt: skip
    assert train.DriverState.load(train.state_path(final)).episode == episodes + 1
    capsys.readouterr()
    assert train.run(arguments(run, resume=final, minutes=2.0, no_bag=True)) == 2
    err = capsys.readouterr().err
    assert f"the run's total of {episodes + 1} episodes" in err and "larger --episodes" in err
    # --episodes at the checkpoint's count still exports without training, whatever stops the run.
    first = tmp_path / "first"
    train.train(
        arguments(first, scenarios="np4", episodes=50, minutes=0.0005, no_bag=True),
        train.TrainingHooks(learner_config=tiny_config()),  # B trains in the first episode
    )
    final = first / "checkpoints" / "final.ckpt"
    episodes = train.DriverState.load(train.state_path(final)).episode
    export = tmp_path / "export"
    assert train.run(arguments(first, resume=final, episodes=episodes, export=export)) == 0
    assert (export / "b_tensor.npy").is_file()
    assert train.DriverState.load(train.state_path(final)).episode == episodes


def test_a_driver_state_of_another_checkpoint_is_named_before_a_rollback_is_offered(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The driver state of an earlier checkpoint beside the final one: the first answer was
    "add --rollback", and following it failed on the real cause."""
    import shutil

    run = tmp_path / "run"
    options = {"scenarios": "np4", "max_iterations": 200, "no_bag": True, "checkpoint_every": 1}
    assert train.run(arguments(run, episodes=3, **options)) == 0
    final = run / "checkpoints" / "final.ckpt"
    earlier = min((run / "checkpoints").glob("episode-*.ckpt"))
    shutil.copyfile(train.state_path(earlier), train.state_path(final))
    capsys.readouterr()
    assert train.run(arguments(run, episodes=4, resume=final, max_iterations=200, no_bag=True)) == 2
    err = capsys.readouterr().err
    assert "the checkpoint holds 3 episodes and its driver state" in err, err
    assert "--rollback" not in err, err


def _pcg64(**state: int) -> dict[str, Any]:
    return {"bit_generator": "PCG64", "state": state, "has_uint32": 0, "uinteger": 0}


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"episode": "six"}, "wrong type of episode"),
        ({"scenarios": "np4"}, "wrong type of scenarios"),
        ({"rng_state": {}}, "not a readable driver state"),  # a traceback from numpy
        # A wrong digit: numpy's OverflowError was a traceback, also from a checkpoint of the
        # run that was not the one resumed (the newer ones are read to warn of them).
        ({"rng_state": _pcg64(state=10**40, inc=1)}, "Python int too large to convert"),
        ({"rng_state": _pcg64(state=1)}, "'inc'"),  # numpy's KeyError
    ],
)
def test_a_damaged_driver_state_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], change: dict, message: str
) -> None:
    """A .driver.json whose fields have the wrong types or whose RNG state is gone: a numpy
    traceback, or a confusing refusal later; now one line naming the file."""
    run = tmp_path / "run"
    assert train.run(arguments(run, episodes=1, scenarios="np4", max_iterations=200,
                               no_bag=True)) == 0  # fmt: skip
    final = run / "checkpoints" / "final.ckpt"
    document = json.loads(train.state_path(final).read_text())
    train.state_path(final).write_text(json.dumps({**document, **change}))
    capsys.readouterr()
    resumed = arguments(run, episodes=2, resume=final, max_iterations=200, no_bag=True)
    assert train.run(resumed) == 2
    err = capsys.readouterr().err
    assert f"{train.state_path(final)}: not a readable driver state" in err and message in err
    assert "Traceback" not in err


def _bags(folder: Path) -> set[Path]:
    return {path.parent for path in folder.glob("*/metadata.yaml")}


def test_a_resume_keeps_the_runs_own_settings(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Scenarios, schedule, decision interval and seed are the run's: a resume that gives
    others is refused (they used to be ignored while the provenance recorded the command), as
    is another run folder (whose metrics and provenance the resume mixed with its own). The
    bag settings carry over unless the resume gives others."""
    from lit_planner.bag import default_bag_root

    run = tmp_path / "run"
    assert train.run(arguments(run, scenarios="np4", episodes=1, seed=3)) == 0
    final = run / "checkpoints" / "final.ckpt"
    recorded = _bags(tmp_path)
    assert len(recorded) == 1
    capsys.readouterr()
    for options, message in (
        ({"scenarios": "np8"}, "--scenarios (the run's: np4): set when a run starts"),
        ({"seed": 4}, "--seed (the run's: 3): set when a run starts"),
        ({"schedule": "joint"}, "--schedule (the run's: b-then-k)"),
        ({"decision_interval": 7}, "--decision-interval (the run's: 1)"),
    ):
        args = arguments(run, episodes=2, resume=final, **options)
        assert train.run(args) == 2, options
        assert message in capsys.readouterr().err, options
    assert train.run(arguments(tmp_path / "other", episodes=2, resume=final)) == 2
    assert "copy that folder to continue the run elsewhere" in capsys.readouterr().err
    assert not (tmp_path / "other").exists()
    # A copy of the checkpoint outside its run folder: its metrics and B-phase tensor are not
    # there, and the resume wrote a new run's files into the folder above the copy.
    stray = tmp_path / "copies" / "final"
    stray.mkdir(parents=True)
    for path in (final, train.state_path(final)):
        shutil.copy(path, stray)
    args = arguments(run, episodes=2, resume=stray / "final.ckpt")
    args.out = None
    assert train.run(args) == 2
    assert "not in a run folder" in capsys.readouterr().err
    assert sorted(p.name for p in (tmp_path / "copies").rglob("*")) == sorted(
        ["final", "final.ckpt", train.state_path(final).name]
    )
    # The run's own values given again are fine; its bag folder is kept without --bag-dir.
    parser = argparse.ArgumentParser()
    train.add_arguments(parser)
    again = parser.parse_args(
        ["--resume", str(final), "--episodes", "2", "--no-progress", "--scenarios", "np4"]
    )
    assert train.run(again) == 0
    assert len(_bags(tmp_path)) == 2  # a second bag beside the first

    unrecorded = tmp_path / "unrecorded"
    assert train.run(arguments(unrecorded, scenarios="np4", episodes=1, no_bag=True)) == 0
    again = parser.parse_args(
        ["--resume", str(unrecorded / "checkpoints" / "final.ckpt"), "--episodes", "2",
         "--no-progress"]
    )  # fmt: skip
    assert train.run(again) == 0
    assert not list(default_bag_root().glob("unrecorded*"))  # --no-bag kept: no bag in bags/
    assert len(_bags(tmp_path)) == 2


def test_a_bad_seed_or_a_folder_of_other_files_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--seed -1 ended in a numpy traceback; --out naming a folder of other files (a benchmark's,
    say) mixed the run's files into it."""
    for seed in (-1, 2**32):
        assert train.run(arguments(tmp_path / "run", episodes=1, seed=seed)) == 2
        assert "--seed must be between 0 and 4294967295" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()
    (tmp_path / "bench").mkdir()
    (tmp_path / "bench" / "summary.md").write_text("mine")
    assert train.run(arguments(tmp_path / "bench", episodes=1)) == 2
    assert "not empty; choose a new or empty folder" in capsys.readouterr().err
    assert sorted(p.name for p in (tmp_path / "bench").iterdir()) == ["summary.md"]


def test_no_bag_and_bag_dir_contradict_each_other(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = arguments(tmp_path / "run", scenarios="np4", episodes=1)
    args.no_bag = True  # the helper's --bag-dir stays
    assert train.run(args) == 2
    assert "and --no-bag contradict each other" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


def test_empty_scenarios_are_refused_not_the_default_mix(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--scenarios ""`` (an empty shell variable) is not "not given"."""
    assert train.run(arguments(tmp_path / "run", scenarios="", episodes=1)) == 2
    assert "no training scenarios" in capsys.readouterr().err


def _without_one_pair(source: Path, target: Path, victim: tuple[str, str, str]) -> None:
    """Copy bag ``source`` to ``target`` without the first observation and the first decision
    of episode ``victim`` (as a recording gap loses them)."""
    _without_first(source, target, victim, ("lit_msgs_json/Observation", "lit_msgs_json/Decision"))


def _without_first(
    source: Path, target: Path, victim: tuple[str, str, str], schemas: tuple[str, ...]
) -> None:
    """Copy bag ``source`` to ``target`` without the first message of each of ``schemas`` of
    episode ``victim``."""
    dropped = dict.fromkeys(schemas, 0)

    def drop(item: Any) -> bool:
        if (
            item.schema in dropped
            and not dropped[item.schema]
            and (item.source, item.run_id, str(item.payload.get("episode_id"))) == victim
        ):
            dropped[item.schema] += 1
            return True
        return False

    _copy_bag(source, target, drop)
    assert dropped == dict.fromkeys(schemas, 1)


def test_a_restarted_planner_nodes_episodes_are_kept_beside_the_first_ones(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A planner node restarted under the same run id numbers its episodes from 0 again (the same
    ids, its seq from 0: a later publishing session). The learner node, which went on, trained on
    both: lit replay tensors kept only the later ones, as for a resumed lit train run (whose
    checkpoint had rolled the first ones back), which it still does."""
    import json as json_module

    from lit_learner import offline
    from lit_planner import bag, replay

    train.train(arguments(tmp_path / "run", episodes=3, scenarios="np4", checkpoint_every=0),
                train.TrainingHooks(learner_config=small_config()))  # fmt: skip
    (recorded,) = [p for p in tmp_path.iterdir() if (p / "metadata.yaml").exists()]
    later = 10**10  # the restarted process sends 10 s after the first one's last message

    def twice(source: str, target: Path, cut: str = "") -> None:  # 2 processes of one publisher
        skipped = replay.Skipped()
        with replay.BagReader(recorded) as reader, bag.BagRecorder(target, run_id="r") as out:
            messages = [m for m in reader.messages() if m.msgtype == bag.STRING_TYPE]
            for topic in sorted({m.topic for m in messages}):
                out.add_topic(topic, bag.STRING_TYPE)
            for shift in (0, later):
                for message in messages:
                    item = replay.decode(message, skipped)
                    assert isinstance(item, replay.Envelope)
                    if (
                        not shift
                        and item.schema == offline.SUMMARY
                        and item.payload["episode_id"] == cut
                    ):  # the first process killed in that episode
                        continue
                    text = bag.typestore().deserialize_cdr(message.data, bag.STRING_TYPE).data
                    envelope = json_module.loads(text)
                    envelope["source"] = source
                    envelope["stamp_ns"] += shift
                    out.write_string(
                        message.topic, json_module.dumps(envelope), message.log_ns + shift
                    )

    node_bag, train_bag = tmp_path / "node-bag", tmp_path / "train-bag"
    twice("/lit_planner", node_bag)
    twice(offline.TRAIN_SOURCE, train_bag)
    capsys.readouterr()
    first, _ = offline.read_episodes([recorded], progress=True)  # lit replay tensors: a terminal
    assert len(first) == 3 and f"reading {recorded.name}" in capsys.readouterr().err
    episodes, skipped = offline.read_episodes([node_bag])
    assert [e.key[2] for e in episodes] == [e.key[2] for e in first] * 2
    assert not skipped.counts[offline.RECORDED_AGAIN] and not skipped.counts[offline.INCOMPLETE]
    # Killed in its last episode (no summary): counted as cut off, not dropped without a word.
    twice("/lit_planner", tmp_path / "cut-bag", cut=first[-1].key[2])
    episodes, skipped = offline.read_episodes([tmp_path / "cut-bag"])
    assert [e.key[2] for e in episodes] == [e.key[2] for e in first][:-1] + [
        e.key[2] for e in first
    ]
    assert skipped.counts[offline.NO_SUMMARY] == 1
    episodes, skipped = offline.read_episodes([train_bag])
    assert [e.key[2] for e in episodes] == [e.key[2] for e in first]
    assert skipped.counts[offline.RECORDED_AGAIN] == 3
    assert all(e.summary_stamp_ns > later for e in episodes)  # the later recordings


def _copy_bag(source: Path, target: Path, drop: Callable[[Any], bool]) -> None:
    """Copy the envelopes of bag ``source`` to ``target``, leaving out those ``drop`` says."""
    from lit_planner import bag, replay

    skipped = replay.Skipped()
    with replay.BagReader(source) as reader, bag.BagRecorder(target, run_id="copy") as recorder:
        topics: set[str] = set()
        for message in reader.messages():
            if message.msgtype != bag.STRING_TYPE:
                continue
            item = replay.decode(message, skipped)
            if isinstance(item, replay.Envelope) and drop(item):
                continue
            if message.topic not in topics:
                recorder.add_topic(message.topic, bag.STRING_TYPE)
                topics.add(message.topic)
            text = bag.typestore().deserialize_cdr(message.data, bag.STRING_TYPE).data
            recorder.write_string(message.topic, text, message.log_ns)


def test_an_export_that_fails_is_one_line_that_says_how_to_export_again(tmp_path: Path) -> None:
    """A full disk during the export printed a traceback (exit 1) and left a truncated tensor
    that blocked the retry. ``ulimit -f`` stands in for the full disk."""
    import subprocess
    import sys

    from lit_planner import tensor_files

    run_dir = tmp_path / "run"
    hooks = train.TrainingHooks(learner_config=tiny_config())  # a trained agent to export
    train.train(arguments(run_dir, episodes=1, scenarios="np4", no_bag=True), hooks)
    final = run_dir / train.CHECKPOINT_DIR / "final.ckpt"
    export = tmp_path / "tensors"
    command = [sys.executable, "-m", "lit_planner.cli", "train", "--resume", str(final),
               "--episodes", "1", "--export", str(export), "--no-progress"]  # fmt: skip
    limited = subprocess.run(
        ["bash", "-c", 'ulimit -f 2900 && exec "$@"', "bash", *command],  # a tensor: 4.1 MB
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    assert limited.returncode == 2, limited.stderr
    assert "Traceback" not in limited.stderr, limited.stderr
    (line,) = [x for x in limited.stderr.splitlines() if "export to" in x]
    assert line.startswith(f"lit train: export to {export} failed (")
    assert "nothing of it was written there" in line
    advice = f"`lit train --resume {final} --episodes 1 --export {export}` exports it"
    assert advice in line, line
    assert not export.exists()
    again = subprocess.run(command, capture_output=True, text=True, timeout=300, check=False)
    assert again.returncode == 0, again.stderr
    tensor_files.read_tensor(export / "b_tensor.npy")

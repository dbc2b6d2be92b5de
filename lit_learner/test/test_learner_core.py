"""LearnerCore: decisions, metrics, untrained agents, message errors, exact resume."""

from __future__ import annotations

import json
import math
import threading
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch
from lit_learner.config import AgentConfig, LearnerConfig
from lit_learner.core import LearnerCore
from lit_learner.errors import CheckpointError, MessageError, PairingError
from lit_learner.messages import DecisionRequest, EpisodeEnd

Message = DecisionRequest | EpisodeEnd


def small_config(**overrides: object) -> LearnerConfig:
    b = AgentConfig.batch_size_agent(batch_size=8, buffer_size=400, warmup=12, beta_steps=50)
    k = AgentConfig.neighbour_agent(batch_size=16, buffer_size=1000, warmup=40, beta_steps=200)
    return replace(LearnerConfig(b=b, k=k, seed=3), **overrides)  # type: ignore[arg-type]


def random_request(
    rng: np.random.Generator,
    agent: str,
    episode: str,
    t: float,
    cost: float | None,
    improvements: int,
) -> DecisionRequest:
    g, l, m = (float(v) for v in rng.uniform(0.0, 1.0, 3))
    path_states = 0 if cost is None else 10 + improvements
    return DecisionRequest(agent, episode, g, l, m, t, 2.0, cost, 1.0, improvements, path_states)


def script(episodes: int, seed: int = 0) -> list[Message]:
    """A synthetic planner: K decisions every 0.1 s, B decisions at improvements, then an end
    (time budget 2 s, c_min 1)."""
    rng = np.random.default_rng(seed)
    messages: list[Message] = []
    for e in range(episodes):
        episode = f"ep{e}"
        cost: float | None = None
        improvements = 0
        messages.append(random_request(rng, "B", episode, 0.0, cost, improvements))
        for step in range(1, 15):
            t = 0.1 * step
            if rng.uniform() < 0.3:
                improvements += 1
                cost = 1.0 + 1.0 / improvements
                messages.append(random_request(rng, "B", episode, t, cost, improvements))
            messages.append(random_request(rng, "psi_K", episode, t, cost, improvements))
        path_states = 0 if cost is None else 10 + improvements
        messages.append(
            EpisodeEnd(
                episode, 2.0, 2.0, cost, 1.0, improvements, path_states, truncated=e % 2 == 0
            )
        )
    return messages


def feed(core: LearnerCore, messages: list[Message]) -> list[object]:
    return [
        core.decide(m) if isinstance(m, DecisionRequest) else core.end_episode(m) for m in messages
    ]


def test_decisions_are_executed_values() -> None:
    core = LearnerCore(small_config())
    for m in script(3):
        if isinstance(m, DecisionRequest):
            value = core.decide(m)
            assert isinstance(value, float)
            if m.agent == "B":
                assert 20.0 <= value <= 200.0 and value == int(value)
            else:
                assert 3.0 <= value <= 15.0
        else:
            core.end_episode(m)


def test_metrics_after_warm_up() -> None:
    core = LearnerCore(small_config())
    outputs = feed(core, script(8, seed=1))  # its last episode has psi_K terms of every kind
    metrics = [o for o in outputs if isinstance(o, dict)]
    last = metrics[-1]
    for agent in ("B", "psi_K"):
        for key in (
            "charts/return_",
            "charts/steps_",
            "losses/critic_",
            "losses/actor_",
            "losses/mean_q_",
            "charts/beta_",
            "charts/updates_",
        ):
            assert f"{key}{agent}" in last, f"{key}{agent}"
        terms = ("time", "cost", "penalty") + (("search",) if agent == "psi_K" else ())
        assert all(last[f"rewards/{agent}_{term}"] != 0.0 for term in terms), last
        assert last[f"charts/return_{agent}"] == pytest.approx(
            sum(last[f"rewards/{agent}_{term}"] for term in terms)
        )
    # One update per transition from warm-up on: updates = transitions - warmup + 1.
    b, k = core.agents["B"], core.agents["psi_K"]
    assert b.updates == b.transitions - core.config.b.warmup + 1
    assert k.updates == k.transitions - core.config.k.warmup + 1
    assert core.policy_version == b.updates + k.updates == last["charts/policy_version"]
    assert "losses/critic_B" not in metrics[0]  # still warming up after the first episode


def test_untrained_agent_acts_noise_free_and_stores_nothing() -> None:
    core = LearnerCore(small_config(train_b=False))
    feed(core, script(6))
    assert core.agents["B"].transitions == 0 and core.agents["B"].updates == 0
    assert core.agents["psi_K"].transitions > 0
    request = next(m for m in script(1) if isinstance(m, DecisionRequest) and m.agent == "B")
    agent = core.agents["B"]
    greedy = core.policy("B", request.features)
    assert core.decide(request) == agent.value_of(greedy)


def test_a_recorded_value_outside_the_agents_range_opens_no_step() -> None:
    """lit replay tensors records the planner's decisions: a fixed fallback psi_K = e (below the
    agent's 3) was stored as the action 3, which the planner had not executed. It opens no step
    now; the step before it is closed at it as usual."""
    import math

    from lit_learner.messages import EpisodeEnd

    def request(t: float) -> DecisionRequest:
        return DecisionRequest("psi_K", "e", 0.1, 0.2, 0.3, t, 2.0, None, 1.0, 0, 0)

    def stored(values: list[float]) -> list[float]:
        core = LearnerCore(small_config())
        for step, value in enumerate(values):
            core.record(request(0.1 * (step + 1)), value)
        core.end_episode(EpisodeEnd("e", 1.0, 2.0, None, 1.0, 0, 0))
        replay = core.agents["psi_K"].replay
        return sorted(float(a) for a in replay.action[: len(replay)])

    assert stored([9.0, math.e, 15.0]) == [0.5, 1.0]  # 9 closed at e, 15 at the end
    assert stored([9.0, 3.0, 15.0]) == [0.0, 0.5, 1.0]  # the range's end is an action


def test_bad_messages_are_rejected_with_their_field() -> None:
    core = LearnerCore(small_config())
    good = DecisionRequest("B", "e", 0.1, 0.2, 0.3, 0.0, 1.0, None, 1.0, 0, 0)
    with pytest.raises(MessageError, match="unknown agent 'K'") as caught:
        core.decide(replace(good, agent="K"))
    assert caught.value.field == "agent"
    with pytest.raises(
        MessageError, match=r"rho_local = nan is not a number in \[0, 1\]"
    ) as caught:
        core.decide(replace(good, rho_local=float("nan")))
    assert caught.value.field == "rho_local"
    with pytest.raises(MessageError, match=r"measure = 1.5 is not a number in \[0, 1\]"):
        core.decide(replace(good, measure=1.5))  # as DecideRequest's schema refuses it
    with pytest.raises(MessageError, match="time_budget 0.0 must be finite and at least 1e-06 s"):
        core.end_episode(EpisodeEnd("e", 1.0, 0.0, None, 1.0, 0, 0))
    # 5e-324 > 0: the search cost's floor underflowed to 0 (a ZeroDivisionError lost the step).
    with pytest.raises(MessageError, match="time_budget 5e-324 must be finite and at least"):
        core.decide(replace(good, time_budget=5e-324))
    # A cost below the straight line's (1e-300 against 1) made c_min / c = 1e300: a reward that
    # is inf in the float32 buffer failed every gradient step that sampled it.
    for below in (replace(good, cost=1e-300), replace(good, cost=0.999)):
        with pytest.raises(
            MessageError, match="is below minimum_cost 1.0, the straight line's"
        ) as caught:
            core.decide(below)
        assert caught.value.field == "cost"  # the learner node's Error names $.payload.cost
    core.decide(replace(good, cost=1.0 - 1e-12))  # rounding: accepted
    # An episode end's final features become the last s' in the replay buffer: a NaN there
    # reached every network (the next decision then failed for good).
    end = EpisodeEnd("e", 1.0, 2.0, None, 1.0, 0, 0)
    for final, message in (
        ({"B": (float("nan"), 0.2, 0.3)}, r"final_features\[B\]: rho_global = nan is not"),
        ({"psi_K": (0.1, 0.2, 1.5)}, r"final_features\[psi_K\]: measure = 1.5 is not"),
        ({"B": (0.1, 0.2)}, r"final_features\[B\]: 2 values, not 3"),
        ({"K": (0.1, 0.2, 0.3)}, "final_features: unknown agent 'K'"),
    ):
        with pytest.raises(MessageError, match=message):
            core.end_episode(replace(end, final_features=final))


def test_choose_then_commit_is_decide() -> None:
    """The node answers after choose() and commits after sending: the same values, transitions
    and training as decide(); a request choose() rejects changes nothing."""
    messages = script(8, seed=2)
    whole = LearnerCore(small_config())
    expected = feed(whole, messages)

    split = LearnerCore(small_config())
    got: list[object] = []
    for m in messages:
        if isinstance(m, DecisionRequest):
            if m.planning_time > 0.15 and m.episode_id == "ep5":  # after messages at >= 0.1
                with pytest.raises(PairingError, match="before the previous message"):
                    split.choose(replace(m, planning_time=0.0))
            value, a_norm, version = split.choose(m)
            assert version == split.policy_version
            split.commit(m, a_norm)
            got.append(value)
        else:
            got.append(split.end_episode(m))
    assert got == expected
    assert_same_state(whole, split)


def test_published_decisions_read_the_snapshot_of_the_last_step() -> None:
    """choose(published=True) (the node decides while the trainer steps) reads the snapshots and
    policy version published after the last gradient step, never parameters in mid-step."""
    core = LearnerCore(small_config(train_b=False))  # untrained B: noise-free, no pairing state
    request = DecisionRequest("B", "e", 0.1, 0.2, 0.3, 0.0, 1.0, None, 1.0, 0, 0)
    with pytest.raises(RuntimeError, match="no published actor snapshots"):
        core.choose(request, published=True)
    core.publish()
    before = core.choose(request, published=True)
    assert before == core.choose(request) and before.policy_version == 0
    actor = core.agents["B"].actor
    with torch.no_grad():  # a step half-way: parameters changed, nothing published yet
        for parameter in actor.parameters():
            parameter.add_(0.3)
    assert core.choose(request, published=True) == before
    assert core.choose(request).value != before.value  # looks at the parameters
    core.publish()
    assert core.choose(request, published=True).value != before.value


def test_a_gradient_step_publishes_its_snapshot_with_its_version() -> None:
    core = LearnerCore(small_config())
    feed(core, script(6))  # past both warm-ups; every owed step taken
    core.publish()
    version = core.policy_version
    k = core.agents["psi_K"]
    old = core.choose(DecisionRequest("psi_K", "x", 0.1, 0.2, 0.3, 0.0, 1.0, None, 1.0, 0, 0))
    core._pending_updates["psi_K"] += 1  # one more step owed
    lock = threading.Lock()
    assert core.update_step("psi_K", lock=lock) is not None
    assert not lock.locked()
    published_version, snapshots = core._published  # type: ignore[misc]
    assert published_version == version + 1 == core.policy_version
    assert snapshots["psi_K"] is k.snapshot() and snapshots["psi_K"] is not None
    assert old.policy_version == version


def test_gradient_steps_are_owed_from_the_end_of_their_episode(tmp_path: Path) -> None:
    """LEARNER.md: one update per new transition, run at episode end. Transitions stored while
    an episode is still open (a decision closes the agent's previous step) owe their steps only
    when the episode ends, also across a checkpoint taken in the middle of the episode."""
    core = LearnerCore(small_config())
    feed(core, script(6))  # past both warm-ups; every owed step taken
    assert core.pending_updates == 0
    (*decisions, end) = script(1, seed=4)
    stored = {name: agent.transitions for name, agent in core.agents.items()}
    for m in decisions:
        core.decide(m)
        assert core.pending_updates == 0  # the episode is still open
    during = {n: a.transitions - stored[n] for n, a in core.agents.items()}
    assert during["psi_K"] > 0  # transitions were stored, their steps wait

    core.save_checkpoint(tmp_path / "mid.pt")
    for c in (core, LearnerCore.load_checkpoint(tmp_path / "mid.pt")):
        assert c.pending_updates == 0
        c.close_episode(end)
        new = {n: a.transitions - stored[n] for n, a in c.agents.items()}
        assert new["psi_K"] == during["psi_K"] + 1  # the end closes the last step
        assert c._pending_updates == new
        assert not c._owed_updates


def test_an_abandoned_episode_releases_its_steps_and_is_forgotten() -> None:
    """An episode whose end never comes (the end message was lost, the planner died): when it is
    abandoned, the steps its stored transitions owe become due and nothing of it stays open."""
    core = LearnerCore(small_config())
    feed(core, script(6))  # past both warm-ups
    (*decisions, _end) = script(1, seed=5)
    before = {name: agent.transitions for name, agent in core.agents.items()}
    for m in decisions:
        core.decide(m)
    stored = {n: a.transitions - before[n] for n, a in core.agents.items()}
    assert core.pending_updates == 0 and core.open_episodes() == {decisions[0].episode_id}
    assert core.abandon_episode(decisions[0].episode_id)
    assert core._pending_updates == stored  # due now; the pending steps were dropped
    assert core.open_episodes() == set()
    assert not core.abandon_episode(decisions[0].episode_id)  # nothing left of it


def test_deciding_while_another_thread_trains() -> None:
    """The learner node's pattern: one thread chooses from published snapshots and commits
    under the core's lock; another takes gradient steps holding that lock only for bookkeeping
    and the replay. Nothing raises, every owed step is taken, and the sum tree stays the sum of
    its leaves."""
    core = LearnerCore(small_config())
    feed(core, script(4))  # past warm-up
    core.publish()
    lock, stop, errors = threading.Lock(), threading.Event(), []

    def train() -> None:
        try:
            while not stop.is_set():
                if core.update_step(lock=lock) is None:
                    stop.wait(0.001)
        except Exception as exc:  # noqa: BLE001 - reported below
            errors.append(exc)

    trainer = threading.Thread(target=train)
    trainer.start()
    try:
        versions = []
        for m in script(12, seed=9):
            stop.wait(0.002)  # the planner plans between messages; the trainer runs meanwhile
            if isinstance(m, DecisionRequest):
                choice = core.choose(m, published=True)
                versions.append(choice.policy_version)
                with lock:
                    core.commit(m, choice.a_norm)
            else:
                with lock:
                    core.close_episode(m)
    finally:
        while core.pending_updates and not errors:
            stop.wait(0.01)
        stop.set()
        trainer.join()
    assert not errors
    assert versions == sorted(versions) and versions[-1] > versions[0]  # it did train meanwhile
    for agent in core.agents.values():
        tree = agent.replay.tree
        leaves = tree.get(np.arange(agent.replay.size))
        assert tree.total == pytest.approx(float(leaves.sum()), rel=1e-12)


def test_missing_checkpoint(tmp_path: Path) -> None:
    with pytest.raises(CheckpointError, match="checkpoint not found"):
        LearnerCore.load_checkpoint(tmp_path / "none.pt")
    with pytest.raises(CheckpointError, match="a folder, not a checkpoint file"):
        LearnerCore.load_checkpoint(tmp_path)  # was "not found" too


def test_a_checkpoint_with_parts_missing_is_one_error(tmp_path: Path) -> None:
    """A checkpoint edited or written by something else: CheckpointError, not a KeyError."""
    path = tmp_path / "core.pt"
    LearnerCore(LearnerConfig(seed=0)).save_checkpoint(path)
    state = torch.load(path, weights_only=False)
    del state["agents"]["B"]["replay"]
    torch.save(state, path)
    with pytest.raises(CheckpointError, match="incomplete or inconsistent checkpoint"):
        LearnerCore.load_checkpoint(path)


def _checkpoint_with_a_pending_step(path: Path) -> dict[str, Any]:
    """Save a fresh core with one pending B step of episode ``e`` to ``path``; its state as
    ``torch.load`` reads it (to edit and save again)."""
    core = LearnerCore(LearnerConfig(seed=0))
    request = DecisionRequest("B", "e", 0.1, 0.1, 0.1, 0.5, 10.0, 3.0, 2.0, 1, 4)
    core.commit(request, core.choose(request).a_norm)
    core.save_checkpoint(path)
    return torch.load(path, weights_only=False)


@pytest.mark.parametrize(
    ("edit", "value", "message"),
    [
        (("policy_version",), "x", r"policy_version is 'x', not a whole number >= 0"),
        (("episodes",), -5, r"episodes is -5, not a whole number >= 0"),
        (("pending_updates", "B"), 1.5, r"pending_updates\['B'\] is 1.5"),
        (("agents", "psi_K", "updates"), True, r"agents\['psi_K'\].updates is True"),
        (("pairing", "e", "last_time"), math.nan, r"pairing\['e'\].last_time is nan"),
        (("pairing", "e", "best_cost"), "1", r"pairing\['e'\].best_cost is '1'"),
        # An edited replay position: the next transition was written at capacity - 3, and
        # every commit after it failed.
        (("agents", "B", "replay", "position"), -3, "replay position -3 of a ring of 0 not"),
        (("agents", "B", "replay", "size"), -1, r"replay size -1 is outside 0\.\.100000"),
        (("agents", "B", "replay", "position"), 0.0, r"replay position 0\.0 is not a whole"),
        # Was a ReplayError out of load_checkpoint, not the CheckpointError it documents.
        (("agents", "B", "replay", "tree", "capacity"), 7, "sum tree of capacity 7 loaded"),
        # Config values its checks let through failed in torch or numpy: a bare ValueError or
        # RuntimeError out of load_checkpoint, and a traceback out of lit train --resume.
        (("config", "b", "lr_actor"), -1.0, r"bad config in checkpoint: B: lr_actor -1\.0 must"),
        (("config", "num_threads"), 0, r"bad config in checkpoint: num_threads 0 must be"),
        (("config", "seed"), -1, r"bad config in checkpoint: seed -1 must be"),
    ],
    ids=[
        "version",
        "episodes",
        "pending",
        "updates",
        "time",
        "cost",
        "position",
        "size",
        "position-type",
        "tree",
        "learning-rate",
        "threads",
        "seed",
    ],
)
def test_a_checkpoint_value_of_the_wrong_type_is_refused_at_load(
    tmp_path: Path, edit: tuple[str, ...], value: object, message: str
) -> None:
    """The learner node loaded a checkpoint whose policy_version was 'x' (or whose episodes
    were -5), its statistics then failed with a traceback, and its shutdown wrote the
    checkpoint over."""
    path = tmp_path / "core.pt"
    state = _checkpoint_with_a_pending_step(path)
    *parents, key = edit
    target = state
    for part in parents:
        target = target[part]
    target[key] = value
    torch.save(state, path)
    with pytest.raises(CheckpointError, match=message):
        LearnerCore.load_checkpoint(path)


def test_a_checkpoint_whose_pending_steps_have_no_time_still_loads(tmp_path: Path) -> None:
    """Checkpoints from before 2026-11-30 keep a pending step as (features, action,
    improvements); the pairing loads them (time 0), and the value checks took them as damaged."""
    path = tmp_path / "core.pt"
    state = _checkpoint_with_a_pending_step(path)
    pending = state["pairing"]["e"]["pending"]
    pending["B"] = tuple(pending["B"])[:3]
    torch.save(state, path)
    assert LearnerCore.load_checkpoint(path).pairing.episodes["e"].pending["B"].time == 0.0


def test_a_killed_writers_temporary_checkpoint_is_removed(tmp_path: Path) -> None:
    """A process killed while it wrote a checkpoint left ``<name>.<pid>.<thread>.tmp`` beside it,
    and nothing removed it. One that a writer still holds (its flock) is left alone."""
    import fcntl
    import os

    path = tmp_path / "final.ckpt"
    left = tmp_path / "final.ckpt.4242.17.tmp"
    left.write_bytes(b"half a checkpoint")
    held = tmp_path / "final.ckpt.4243.18.tmp"
    held.write_bytes(b"being written")
    other = tmp_path / "episode-0000010.ckpt.4242.17.tmp"  # another checkpoint's: not looked at
    other.write_bytes(b"half")
    holder = os.open(held, os.O_RDONLY)
    try:
        fcntl.flock(holder, fcntl.LOCK_EX)
        LearnerCore(LearnerConfig(seed=0)).save_checkpoint(path)
    finally:
        os.close(holder)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([path.name, held.name, other.name])
    LearnerCore.load_checkpoint(path)


def test_a_checkpoint_is_written_while_another_writer_cleans_up_beside_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Another writer of the same checkpoint (another thread or process) removes the temporary
    files no writer holds. It came between this writer's creation of its temporary file and its
    lock, and again while torch wrote the file anew under that name, unheld: the write ended in
    FileNotFoundError. The temporary file is held from before torch writes it."""
    import os

    import lit_learner.core as core_module

    path = tmp_path / "final.ckpt"
    state = LearnerCore(LearnerConfig(seed=0)).checkpoint_state()

    def other_writer() -> None:  # its own thread: its own temporary file
        thread = threading.Thread(target=LearnerCore.write_checkpoint, args=(state, path))
        thread.start()
        thread.join()

    real_open, real_save = os.open, core_module.torch.save
    gaps = []  # where the other writer cleaned up: this writer's own calls only
    this_writer = threading.get_ident()

    def open_then_clean(name: Any, flags: int, *args: Any, **kwargs: Any) -> int:
        descriptor = real_open(name, flags, *args, **kwargs)
        mine = threading.get_ident() == this_writer
        if mine and flags & os.O_CREAT and str(name).endswith(".tmp") and not gaps:
            gaps.append(name)  # this writer's, just created
            other_writer()
        return descriptor

    def save_then_clean(obj: Any, name: Any, *args: Any, **kwargs: Any) -> None:
        real_save(obj, name, *args, **kwargs)
        if threading.get_ident() == this_writer and len(gaps) == 1:
            gaps.append(name)
            other_writer()

    monkeypatch.setattr(os, "open", open_then_clean)
    monkeypatch.setattr(core_module.torch, "save", save_then_clean)
    LearnerCore.write_checkpoint(state, path)
    assert len(gaps) == 2 and [p.name for p in tmp_path.iterdir()] == [path.name]
    LearnerCore.load_checkpoint(path)


def test_a_flipped_bit_in_a_checkpoint_is_refused(tmp_path: Path) -> None:
    """torch.load does not check the archive's CRCs: a checkpoint with a bit flipped in an
    actor's weights was loaded and trained on without a word."""
    import struct
    import zipfile

    path = tmp_path / "core.pt"
    LearnerCore(LearnerConfig(seed=0)).save_checkpoint(path)
    with zipfile.ZipFile(path) as archive:
        entry = max(archive.infolist(), key=lambda info: info.file_size)  # a tensor's bytes
    data = bytearray(path.read_bytes())
    names, extra = struct.unpack("<HH", data[entry.header_offset + 26 : entry.header_offset + 30])
    start = entry.header_offset + 30 + names + extra  # where the (stored) bytes begin
    data[start + entry.file_size // 2] ^= 0x10
    path.write_bytes(bytes(data))
    with pytest.raises(CheckpointError, match=f"its entry {entry.filename} does not match"):
        LearnerCore.load_checkpoint(path)
    # A bit of the central directory's flags: zipfile takes the entry as encrypted (a
    # RuntimeError, which ended the load in a traceback).
    LearnerCore(LearnerConfig(seed=0)).save_checkpoint(path)
    data = bytearray(path.read_bytes())
    directory = data.rindex(b"PK\x01\x02")  # the last entry's central directory header
    data[directory + 8] ^= 0x01
    path.write_bytes(bytes(data))
    with pytest.raises(CheckpointError, match=r"damaged checkpoint: its directory \(RuntimeError"):
        LearnerCore.load_checkpoint(path)


def flat_state(core: LearnerCore) -> dict[str, object]:
    state: dict[str, object] = {}
    for name, agent in core.agents.items():
        for net in ("actor", "critic", "actor_target", "critic_target"):
            for key, value in getattr(agent, net).state_dict().items():
                state[f"{name}.{net}.{key}"] = value
        for opt in ("actor_optimizer", "critic_optimizer"):
            for index, slots in getattr(agent, opt).state_dict()["state"].items():
                for key, value in slots.items():
                    state[f"{name}.{opt}.{index}.{key}"] = value
        replay = agent.replay
        state[f"{name}.tree"] = torch.from_numpy(replay.tree.nodes.copy())
        state[f"{name}.actions"] = torch.from_numpy(replay.action[: len(replay)].copy())
        state[f"{name}.counters"] = (agent.updates, agent.transitions, replay.max_priority)
    state["version"] = core.policy_version
    return state


def assert_same_state(x: LearnerCore, y: LearnerCore) -> None:
    """Networks, optimisers, replay and counters equal, tensors bit for bit."""
    a, b = flat_state(x), flat_state(y)
    assert a.keys() == b.keys()
    for key in a:
        if isinstance(a[key], torch.Tensor):
            assert torch.equal(a[key], b[key]), key  # bitwise
        else:
            assert a[key] == b[key], key


def test_resume_from_checkpoint_is_exact(tmp_path: Path) -> None:
    messages = script(10, seed=5)
    # Cut in the middle of an episode after both agents passed warm-up: pending steps included.
    cut = (
        next(
            i
            for i, m in enumerate(messages)
            if isinstance(m, DecisionRequest) and m.episode_id == "ep6" and m.agent == "psi_K"
        )
        + 3
    )
    uninterrupted = LearnerCore(small_config())
    expected = feed(uninterrupted, messages)

    first = LearnerCore(small_config())
    got = feed(first, messages[:cut])
    assert first.policy_version > 0 and first.pairing.episodes["ep6"].pending
    first.save_checkpoint(tmp_path / "mid.pt")
    resumed = LearnerCore.load_checkpoint(tmp_path / "mid.pt")
    got += feed(resumed, messages[cut:])

    assert got == expected
    assert_same_state(uninterrupted, resumed)


def test_the_sources_of_the_experience_outlive_a_restart(tmp_path: Path) -> None:
    """The planners that fed a learner are named in its exports' provenance: those of before a
    restart too (the learner node kept them in memory only, so an export after a resume named the
    planners heard since). A checkpoint from before they were kept names none."""
    core = LearnerCore(small_config())
    core.sources.update({"/robot2/lit_planner", "/robot1/lit_planner"})
    core.save_checkpoint(tmp_path / "c.pt")
    assert LearnerCore.load_checkpoint(tmp_path / "c.pt").sources == {
        "/robot1/lit_planner",
        "/robot2/lit_planner",
    }
    state = core.state_dict()
    del state["sources"]
    torch.save(state, tmp_path / "old.pt")
    assert LearnerCore.load_checkpoint(tmp_path / "old.pt").sources == set()


def test_checkpoint_files_hold_the_arrays_as_tensors_and_old_files_still_load(
    tmp_path: Path,
) -> None:
    """torch.save pickles a numpy array holding the GIL (a full replay stalled the decide thread
    for 0.2 s) but writes a tensor's bytes without it: arrays go to the file as tensors and come
    back as the same numpy arrays. A file written with the arrays themselves (before) loads to
    the same state."""
    core = LearnerCore(small_config())
    feed(core, script(6, seed=2))
    core.save_checkpoint(tmp_path / "new.pt")
    raw = torch.load(tmp_path / "new.pt", weights_only=False)
    stored = raw["agents"]["psi_K"]["replay"]["state"]
    assert set(stored) == {"__numpy_array__"} and isinstance(
        stored["__numpy_array__"], torch.Tensor
    )
    actor = raw["agents"]["psi_K"]["actor"]  # an OrderedDict with nn.Module's version metadata
    assert type(actor) is type(core.agents["psi_K"].actor.state_dict())
    assert actor._metadata == core.agents["psi_K"].actor.state_dict()._metadata
    loaded = LearnerCore.load_checkpoint(tmp_path / "new.pt")
    replay = loaded.agents["psi_K"].replay
    assert isinstance(replay.state, np.ndarray) and replay.state.dtype == np.float32
    state = core.state_dict()  # the old layout: numpy arrays, every sum-tree node
    for name, agent in core.agents.items():
        state["agents"][name]["replay"]["tree"] = {
            "capacity": agent.replay.capacity,
            "nodes": agent.replay.tree.nodes.copy(),
        }
    torch.save(state, tmp_path / "old.pt")
    old = LearnerCore.load_checkpoint(tmp_path / "old.pt")
    assert_same_state(loaded, old)
    np.testing.assert_array_equal(
        old.agents["B"].replay.next_state, loaded.agents["B"].replay.next_state
    )


def test_a_checkpoint_state_is_a_copy_later_training_does_not_touch(tmp_path: Path) -> None:
    """The learner node copies the state under its locks and writes the file after releasing
    them, while decisions and gradient steps go on: the file must hold the state at the copy."""
    messages = script(10, seed=5)
    cut = len(messages) // 2
    core = LearnerCore(small_config())
    got = feed(core, messages[:cut])
    assert core.policy_version > 0
    state = core.checkpoint_state()
    core.save_checkpoint(tmp_path / "at-copy.pt")
    feed(core, messages[cut:])  # decisions, episode ends and gradient steps after the copy
    LearnerCore.write_checkpoint(state, tmp_path / "late.pt")
    late = LearnerCore.load_checkpoint(tmp_path / "late.pt")
    at_copy = LearnerCore.load_checkpoint(tmp_path / "at-copy.pt")
    assert_same_state(at_copy, late)
    assert late.policy_version < core.policy_version
    # and it resumes exactly like the core it was copied from
    uninterrupted = LearnerCore(small_config())
    assert got + feed(late, messages[cut:]) == feed(uninterrupted, messages)


def test_configs_from_before_the_logit_penalty_and_search_cost_keep_training_without_them() -> None:
    doc = LearnerConfig().to_dict()
    for agent in ("b", "k"):
        del doc[agent]["logit_penalty"]
    del doc["reward"]["w_search"]
    old = LearnerConfig.from_dict(doc)
    assert old.b.logit_penalty == 0.0 and old.k.logit_penalty == 0.0
    assert old.reward.w_search == 0.0
    assert LearnerConfig.from_dict(LearnerConfig().to_dict()) == LearnerConfig()


def test_the_metrics_file_keeps_a_diverged_loss(tmp_path: Path) -> None:
    """NaN and inf were written as empty cells, as if no update had been made."""
    from lit_learner.metrics import MetricsLog, read_metrics

    log = MetricsLog(tmp_path / "metrics.csv", ["episode"])
    log.append({"episode": 0, "losses/critic_B": float("nan"), "losses/actor_B": float("inf")})
    log.append({"episode": 1, "losses/critic_B": 0.5})
    text = (tmp_path / "metrics.csv").read_text()
    assert "nan" in text and "inf" in text
    columns = read_metrics(tmp_path / "metrics.csv")
    assert math.isnan(columns["losses/critic_B"][0]) and columns["losses/critic_B"][1] == 0.5
    assert columns["losses/actor_B"][0] == math.inf


def test_configs_that_would_divide_by_zero_or_diverge_are_refused() -> None:
    from lit_learner.config import RewardConfig
    from lit_learner.errors import ConfigError

    for bad in ({"t_hat_min": 0.0}, {"search_floor": 0.0}, {"path_states_scale": -1.0},
                {"w_c": float("nan")}, {"nu_min": float("nan")}, {"nu_min": -1.0}):  # fmt: skip
        with pytest.raises(ConfigError, match=next(iter(bad))):
            RewardConfig(**bad)
    nan = float("nan")
    # Each was accepted and failed later: a NaN consequent or centre at every decision (min and
    # max skip a NaN), sigma 1e-200 as a division by zero, beta -0.5 as importance weights
    # above 1, a NaN beta or priority_eps as NaN losses blamed on the networks.
    for bad in ({"fuzzy_sigma": 0.0}, {"noise_std": -0.1}, {"alpha": -1.0},
                {"logit_penalty": float("inf")}, {"consequents": (3.0, nan, 15.0)},
                {"consequents": (3.0, 9.0)}, {"fuzzy_sigma": 1e-200},
                {"fuzzy_centres": (0.0, nan, 1.0)}, {"fuzzy_centres": (1.0, 0.5, 0.0)},
                {"beta_start": -0.5}, {"beta_end": nan}, {"priority_eps": nan},
                {"lr_actor": -1.0}, {"lr_critic": nan}, {"batch_size": 64.0},
                {"conv_kernels": (3, 4)}, {"hidden": ()}, {"actor_last_init": nan}):  # fmt: skip
        with pytest.raises(ConfigError, match=next(iter(bad))):
            AgentConfig.neighbour_agent(**bad)
    for bad in ({"seed": -1}, {"seed": 1.5}, {"num_threads": 0}, {"train_b": "yes"}):
        with pytest.raises(ConfigError, match=next(iter(bad))):
            LearnerConfig(**bad)
    # numpy's numbers are taken as Python's (they failed the sidecar's JSON at the first export)
    plain = LearnerConfig(seed=np.int64(3), b=AgentConfig.batch_size_agent(tau=np.float32(0.5)))
    assert type(plain.seed) is int and type(plain.b.tau) is float
    json.dumps(plain.to_dict())
    assert LearnerConfig(seed=2**63 - 2).seed == 2**63 - 2  # the psi_K agent's is 2^63 - 1
    for bad in ({"seed": 2**63 - 1}, {"seed": True}):
        with pytest.raises(ConfigError, match="seed"):
            LearnerConfig(**bad)
    for bad in ({"tau": True}, {"gamma": 10**400}, {"lr_actor": 10**400}):
        with pytest.raises(ConfigError, match=next(iter(bad))):
            AgentConfig.neighbour_agent(**bad)
    with pytest.raises(ConfigError, match="w_t"):
        RewardConfig(w_t=10**400)
    RewardConfig(w_search=0.0, nu_min=0.0)  # allowed: no search cost, no kappa floor


def test_an_end_of_an_episode_without_open_steps_is_counted_only_when_asked() -> None:
    """The learner node's clients could send ends of episodes that never were, or one end twice:
    each counted as an episode, and brought its checkpoints and the end-of-training export
    forward. ``lit train`` keeps counting them (its episodes are all real)."""
    core = LearnerCore(small_config())
    request = DecisionRequest("B", "e", 0.1, 0.2, 0.3, 0.0, 1.0, None, 1.0, 0, 0)
    core.decide(request)
    end = EpisodeEnd("e", 0.5, 1.0, None, 1.0, 0, 0)
    core.close_episode(end, count_unknown=False)
    assert core.episodes == 1 and core.agents["B"].transitions == 1
    core.close_episode(end, count_unknown=False)  # the same end again
    core.close_episode(replace(end, episode_id="never"), count_unknown=False)
    assert core.episodes == 1 and core.agents["B"].transitions == 1
    core.close_episode(replace(end, episode_id="never"))
    assert core.episodes == 2


def test_replay_transitions_not_finite_are_left_out_when_a_checkpoint_loads(
    tmp_path: Path,
) -> None:
    """Learners before the check at storing kept transitions with values that are not finite
    (and priorities computed from them), and each failed every gradient step whose batch held
    it: loading leaves them out and keeps the rest in order, with their priorities."""
    core = LearnerCore(small_config())
    feed(core, script(6, seed=2))
    state = core.state_dict()
    replay = state["agents"]["psi_K"]["replay"]
    n = replay["size"]
    assert n >= 10 and replay["position"] == n  # not full: the ring has not wrapped
    replay["reward"][2] = np.nan
    replay["next_state"][5, 1] = np.inf
    replay["tree"]["leaves"][7] = np.nan
    replay["max_priority"] = float("nan")
    kept = [i for i in range(n) if i not in (2, 5, 7)]
    rewards, leaves = replay["reward"][kept].copy(), replay["tree"]["leaves"][kept].copy()
    torch.save(state, tmp_path / "old.pt")

    loaded = LearnerCore.load_checkpoint(tmp_path / "old.pt")
    assert loaded.dropped_at_load == {"B": 0, "psi_K": 3}
    buffer = loaded.agents["psi_K"].replay
    assert (buffer.size, buffer.position) == (n - 3, n - 3)
    np.testing.assert_array_equal(buffer.reward[: n - 3], rewards)
    np.testing.assert_array_equal(buffer.tree.get(np.arange(n - 3)), leaves)
    assert buffer.tree.total == pytest.approx(float(leaves.sum()), rel=1e-12)
    assert buffer.max_priority == pytest.approx(float(leaves.max()) ** (1.0 / buffer.alpha))
    batch = buffer.sample(64, 0.4, np.random.default_rng(0))
    assert np.isfinite(batch.reward).all() and np.isfinite(batch.weight).all()
    assert loaded.agents["B"].replay.size == core.agents["B"].replay.size


def test_a_checkpoint_whose_network_is_not_finite_is_refused(tmp_path: Path) -> None:
    """A network with NaN weights would answer NaN to every decision: the checkpoint is refused
    with the agent and the tensors named."""
    path = tmp_path / "nan.pt"
    state = LearnerCore(LearnerConfig(seed=0)).state_dict()
    network = state["agents"]["B"]["critic_target"]
    name = next(iter(network))
    network[name] = torch.full_like(network[name], float("nan"))
    torch.save(state, path)
    with pytest.raises(
        CheckpointError,
        match=rf"nan\.pt: agent B: the critic_target holds weights that are not finite: {name}$",
    ):
        LearnerCore.load_checkpoint(path)


def test_a_checkpoint_whose_optimiser_moments_are_not_finite_is_refused(tmp_path: Path) -> None:
    """An Adam moment that is not finite would make the weights NaN at the first step."""
    core = LearnerCore(small_config())
    feed(core, script(6, seed=2))  # past warm-up: the optimisers have state
    state = core.state_dict()
    slots = state["agents"]["B"]["actor_optimizer"]["state"]
    assert slots, "the B actor's optimiser has taken no step"
    index = next(iter(slots))
    slots[index]["exp_avg_sq"] = torch.full_like(slots[index]["exp_avg_sq"], float("nan"))
    torch.save(state, tmp_path / "moments.pt")
    with pytest.raises(
        CheckpointError,
        match=rf"agent B: the actor_optimizer holds moments that are not finite: {index}\.exp_avg_sq$",
    ):
        LearnerCore.load_checkpoint(tmp_path / "moments.pt")

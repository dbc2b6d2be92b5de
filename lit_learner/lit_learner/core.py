"""The learner core: decision requests in, actions out; transitions, updates, checkpoints, export.

It knows nothing about ROS or the planner: ``lit train`` and the learner node feed it
:class:`DecisionRequest` and :class:`EpisodeEnd` messages. Gradient steps run only in
:meth:`LearnerCore.end_episode` (or :meth:`LearnerCore.update_step` after
:meth:`LearnerCore.close_episode`), so they never sit inside the planner's timed loop; a decision
is one actor forward pass (plus pairing and a replay insert).
"""

from __future__ import annotations

import copy
import glob
import hashlib
import os
import random
import shutil
import threading
import zipfile
from collections.abc import Callable, Mapping, Sequence
from contextlib import AbstractContextManager, nullcontext
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import torch

from lit_learner.agent import DDPGAgent
from lit_learner.config import AGENT_NAMES, LearnerConfig, left_out_note
from lit_learner.errors import (
    CheckpointError,
    ConfigError,
    ExportError,
    NonFiniteWeights,
    ReplayError,
)
from lit_learner.export import CHECKPOINT_FILE, TENSOR_FILES, policy_grid
from lit_learner.messages import DecisionRequest, EpisodeEnd
from lit_learner.networks import ActorSnapshot
from lit_learner.pairing import Pairing, Transition

CHECKPOINT_FORMAT = 1
"""Version of the checkpoint layout written by :meth:`LearnerCore.save_checkpoint`."""
AGENT_SEED_OFFSET = {"B": 0, "psi_K": 1}
"""Agent seed = config seed + offset, so the two agents never share random streams."""


class Choice(NamedTuple):
    """A chosen decision (:meth:`LearnerCore.choose`)."""

    value: float
    """The executed value."""
    a_norm: float | None
    """What :meth:`LearnerCore.commit` records (None for an agent that is not trained)."""
    policy_version: int
    """The policy version that chose it."""


class LearnerCore:
    """Both agents, the message pairing and the bookkeeping of training."""

    def __init__(self, config: LearnerConfig) -> None:
        self.config = config
        torch.set_num_threads(config.num_threads)
        self.agents = {
            name: DDPGAgent(config.agent(name), config.seed + AGENT_SEED_OFFSET[name])
            for name in AGENT_NAMES
        }
        self.pairing = Pairing(config.reward)
        self.episodes = 0
        """Episodes ended so far."""
        self.sources: set[str] = set()
        """Who sent the experience (the learner node puts the planners' envelope sources here;
        an export's provenance names them). Kept in checkpoints."""
        self._policy_version = 0
        self._pending_updates = dict.fromkeys(AGENT_NAMES, 0)
        """Gradient steps owed to the transitions of ended episodes (counted from warm-up on)."""
        self._owed_updates: dict[str, dict[str, int]] = {}
        """Per open episode and agent: steps owed to its transitions stored so far. They become
        pending when the episode ends: gradient work happens at episode ends (LEARNER.md), not
        while the episode's planner is still planning."""
        self._published: tuple[int, dict[str, ActorSnapshot]] | None = None
        """(policy version, actor snapshot per agent) for decisions taken concurrently."""
        self._episode_terms: dict[str, dict[str, list[float]]] = {}
        """Per episode and agent: summed reward terms [time, cost, penalty, search] and the step
        count."""
        self.dropped_at_load: dict[str, int] = dict.fromkeys(AGENT_NAMES, 0)
        """Per agent: replay transitions :meth:`load_checkpoint` left out (values not finite)."""

    def load_warning(self) -> str | None:
        """What :meth:`load_checkpoint` left out, to be said where it was loaded (None: nothing)."""
        dropped = {name: n for name, n in self.dropped_at_load.items() if n}
        if not dropped:
            return None
        return (
            "left out replay transitions holding values that are not finite "
            f"({', '.join(f'{name} {n}' for name, n in dropped.items())}; a learner older than "
            "the check at storing kept them, and they failed its gradient steps)"
        )

    @property
    def policy_version(self) -> int:
        """Gradient steps taken by both agents together; 0 before the first one."""
        return self._policy_version

    def policy(self, agent: str, features: tuple[float, float, float]) -> float:
        """Noise-free z*(features) of ``agent`` before rounding: what the exported tensor holds
        at grid points. Touches no state (no pairing, no random numbers)."""
        return self.agents[agent].policy(features)

    def trains(self, agent: str) -> bool:
        """Whether ``agent`` stores transitions and learns."""
        return self.config.train_b if agent == "B" else self.config.train_k

    def untrained_reason(self, agent: str) -> str | None:
        """Why ``agent``'s actor still holds its initial weights, for the user; None once it made
        a gradient update."""
        state = self.agents[agent]
        if state.updates:
            return None
        if not self.trains(agent):
            return "this run does not train it"
        if state.transitions < state.config.warmup:
            return (
                f"no gradient update yet: {state.transitions} of the {state.config.warmup} "
                "transitions its updates wait for"
            )
        return (
            f"no gradient update yet: its {state.transitions} transitions passed the warm-up "
            f"({state.config.warmup}); its first steps are still owed"
        )

    def export_plan(self) -> tuple[tuple[str, ...], dict[str, str]]:
        """The agents an export writes a tensor of, those that made a gradient update (in
        :data:`AGENT_NAMES` order), and for each other what the export says of it
        (:func:`~lit_learner.config.left_out_note`). An initial actor is not exported: the
        tensor policy played it (psi_K about 9, where the fixed value it keeps without the
        tensor is e)."""
        left_out = {
            name: left_out_note(name, reason)
            for name in AGENT_NAMES
            if (reason := self.untrained_reason(name)) is not None
        }
        return tuple(name for name in AGENT_NAMES if name not in left_out), left_out

    # ------------------------------------------------------------------ messages

    def decide(self, request: DecisionRequest) -> float:
        """The executed value for a request: B rounded half away from zero and clamped to
        20..200 (as a float), psi_K clamped to [3, 15]. Closes the agent's previous step of the
        episode and records this one as pending (only for trained agents)."""
        choice = self.choose(request)
        self.commit(request, choice.a_norm)
        return choice.value

    def choose(self, request: DecisionRequest, published: bool = False) -> Choice:
        """The first half of :meth:`decide`: checks the request (as :meth:`decide` would, so that
        :meth:`commit` cannot fail on it) and chooses the action without recording anything.

        A server answers with the value and calls :meth:`commit` after the answer is sent (the
        pairing and the replay insert are then off the caller's critical path). Commits must come
        in the order chosen (the pairing needs the episode's steps in order); a caller that
        chooses before the previous commit is applied must check time order against it itself
        (the learner node does, see ``LearnerNode._check_order``), since :meth:`choose` checks
        against the committed ones.

        ``published`` (the learner node): the actor snapshots and policy version published
        together after the last gradient step (:meth:`publish`, :meth:`update_step`), so that a
        decision can be chosen while another thread takes a gradient step, without waiting for
        it. The pairing only the deciding thread changes; the agent's generator is shared with
        the trainer's replay sampling (numpy locks it; the order of draws then depends on timing).

        Raises:
            MessageError: the request is invalid.
            PairingError: its planning time is before the episode's previous message.
            RuntimeError: ``published`` before anything was published.
        """
        request.validate()
        self.pairing.check(request)
        agent = self.agents[request.agent]
        snapshot = None
        version = self._policy_version
        if published:
            if self._published is None:
                raise RuntimeError("no published actor snapshots: call publish() first")
            version, snapshots = self._published
            snapshot = snapshots[request.agent]
        if self.trains(request.agent):
            value, a_norm = agent.act(request.features, request.explore, snapshot)
            return Choice(value, a_norm, version)
        value = agent.value_of(agent.policy(request.features, snapshot))
        return Choice(value, None, version)

    def publish(self) -> None:
        """Publish the actor snapshots (and the policy version they belong to) that
        ``choose(published=True)`` reads; :meth:`update_step` publishes after each step."""
        self._published = (
            self._policy_version,
            {name: agent.snapshot() for name, agent in self.agents.items()},
        )

    def commit(self, request: DecisionRequest, a_norm: float | None) -> None:
        """The second half of :meth:`decide`: closes the agent's previous step of the episode
        and records this one as pending (only for trained agents)."""
        self._step(request, a_norm)

    def progress(self, request: DecisionRequest) -> None:
        """A decision another policy took, of which no agent learns: only the episode's time
        and improvements are noted (:meth:`Pairing.progress`), so that step times stay exact."""
        request.validate()
        self.pairing.progress(request)

    def record(self, request: DecisionRequest, executed: float) -> None:
        """A decision that was already taken (``executed`` is the value the planner applied):
        pairs and stores it exactly as :meth:`decide` would have, without choosing an action.
        Offline training from recorded runs (``lit replay tensors``) feeds decisions this way;
        DDPG learns off-policy, so actions of other policies (fallbacks) are usable too, if the
        agent can take them: a value outside its range (the fixed psi_K = e below 3) opens no
        step (it was stored as 3, an action the planner had not executed); the step before it
        is closed as usual."""
        request.validate()
        agent = self.agents[request.agent]
        a_norm = agent.normalise(executed)
        if self.trains(request.agent) and -_RANGE_SLACK <= a_norm <= 1.0 + _RANGE_SLACK:
            self._step(request, min(max(a_norm, 0.0), 1.0))
        else:
            self._step(request, None)

    def _step(self, request: DecisionRequest, a_norm: float | None) -> None:
        closed = self.pairing.step(request, a_norm)
        if closed is not None:
            self._store(closed)

    def end_episode(self, end: EpisodeEnd) -> dict[str, float]:
        """Close the episode's pending steps, then run one gradient step per transition stored
        since the last round for every agent past warm-up (:meth:`close_episode`, then
        :meth:`update_step` until nothing is pending).

        Returns:
            Metrics: ``charts/return_<A>``, ``charts/steps_<A>``,
            ``rewards/<A>_time|cost|penalty`` (and ``rewards/psi_K_search``)
            (sums over the episode's steps) for agents that stepped in this episode;
            ``losses/critic_<A>``, ``losses/actor_<A>``, ``losses/mean_q_<A>``,
            ``losses/td_abs_<A>`` (means over this round's updates) and ``charts/beta_<A>`` for
            agents that updated; ``charts/updates_<A>``, ``charts/transitions_<A>``,
            ``charts/warming_up_<A>`` for trained agents; ``charts/policy_version``,
            ``charts/episodes``. ``<A>`` is ``B`` or ``psi_K``.
        """
        metrics = self.close_episode(end)
        for name in self.agents:
            if not self.trains(name):
                continue
            history = []
            while self._pending_updates[name] > 0:
                step = self.update_step(name)
                assert step is not None  # a step was pending
                history.append(step[1])
            if history:
                for key in ("critic", "actor", "mean_q", "td_abs"):
                    metrics[f"losses/{key}_{name}"] = float(np.mean([h[key] for h in history]))
                metrics[f"charts/beta_{name}"] = history[-1]["beta"]
        metrics.update(self.counters())
        return metrics

    def is_open(self, episode_id: str) -> bool:
        """Whether the episode has begun and not ended (nor been abandoned)."""
        return (
            episode_id in self.pairing.episodes
            or episode_id in self._owed_updates
            or episode_id in self._episode_terms
        )

    def open_episodes(self) -> set[str]:
        """Episodes begun and not ended (or abandoned)."""
        return set(self.pairing.episodes) | set(self._owed_updates) | set(self._episode_terms)

    def abandon_episode(self, episode_id: str) -> bool:
        """An episode whose end will not come (its planner moved on to the next one: the end
        message was lost, or the planner died): the gradient steps its stored transitions owe
        become due, its pending steps are dropped (they have no s'), and nothing of it is kept.
        Returns whether anything of it was open."""
        owed = self._owed_updates.pop(episode_id, {})
        for name, count in owed.items():
            self._pending_updates[name] += count
        terms = self._episode_terms.pop(episode_id, None)
        return self.pairing.abandon(episode_id) or bool(owed) or terms is not None

    def close_episode(self, end: EpisodeEnd, count_unknown: bool = True) -> dict[str, float]:
        """Close the episode's pending steps and store their transitions, without training.

        An episode the core never saw (for example one that began before a learner restart)
        closes with no transitions, and counts as an episode only with ``count_unknown`` (the
        learner node's clients could inflate the count, and with it the checkpoint and export
        schedule, with ends of episodes that never were, or with the same end sent again). The gradient steps the new transitions call for are left
        pending for :meth:`update_step` (the learner node runs them in a background thread so
        that decisions keep being answered).

        Returns:
            The episode's ``charts/return_<A>``, ``charts/steps_<A>`` and
            ``rewards/<A>_time|cost|penalty`` (and ``rewards/psi_K_search``) for agents that
            stepped in it.
        """
        end.validate()
        known = self.is_open(end.episode_id)
        closed, _ = self.pairing.end(end)
        for transition in closed:
            self._store(transition)
        for name, owed in self._owed_updates.pop(end.episode_id, {}).items():
            self._pending_updates[name] += owed
        if known or count_unknown:
            self.episodes += 1
        metrics: dict[str, float] = {}
        for name, (time, cost, penalty, search, steps) in self._episode_terms.pop(
            end.episode_id, {}
        ).items():
            metrics[f"charts/return_{name}"] = time + cost + penalty + search
            metrics[f"charts/steps_{name}"] = steps
            metrics[f"rewards/{name}_time"] = time
            metrics[f"rewards/{name}_cost"] = cost
            metrics[f"rewards/{name}_penalty"] = penalty
            if name == "psi_K":  # only R_K has a search cost
                metrics[f"rewards/{name}_search"] = search
        return metrics

    @property
    def pending_updates(self) -> int:
        """Gradient steps owed to stored transitions, summed over the trained agents."""
        return sum(n for name, n in self._pending_updates.items() if self.trains(name))

    def update_step(
        self, agent: str | None = None, lock: AbstractContextManager[Any] | None = None
    ) -> tuple[str, dict[str, float]] | None:
        """One gradient step of ``agent`` (None: the first trained agent with pending steps).

        ``lock`` guards what the thread that decides and commits shares with this one (the
        counters, the replay buffer): it is held for the bookkeeping and the replay's sample
        and priority update, not for the gradient computation, so that commits and episode
        ends need not wait for a step. Nobody else may change the networks meanwhile (the learner
        node holds a lock of its own for them).

        Returns:
            The agent that stepped and its update record (``critic``, ``actor``, ``mean_q``,
            ``td_abs``, ``beta``), or None when no step was pending.
        """
        guard = lock if lock is not None else nullcontext()
        names = [agent] if agent is not None else list(self.agents)
        with guard:
            name = next((n for n in names if self.trains(n) and self._pending_updates[n] > 0), None)
            if name is None:
                return None
            self._pending_updates[name] -= 1
        record = self.agents[name].update(replay_lock=lock)
        snapshot = self.agents[name].snapshot()  # rebuilt here, not in the next decision
        with guard:
            self._policy_version += 1
            if self._published is not None:  # one assignment: version and snapshots agree
                self._published = (self._policy_version, {**self._published[1], name: snapshot})
        return name, record

    def counters(self) -> dict[str, float]:
        """``charts/updates_<A>``, ``charts/transitions_<A>``, ``charts/warming_up_<A>`` of the
        trained agents, ``charts/policy_version`` and ``charts/episodes``."""
        metrics: dict[str, float] = {}
        for name, agent in self.agents.items():
            if not self.trains(name):
                continue
            metrics[f"charts/updates_{name}"] = agent.updates
            metrics[f"charts/transitions_{name}"] = agent.transitions
            metrics[f"charts/warming_up_{name}"] = float(agent.warming_up)
        metrics["charts/policy_version"] = self._policy_version
        metrics["charts/episodes"] = self.episodes
        return metrics

    def _store(self, transition: Transition) -> None:
        agent = self.agents[transition.agent]
        agent.remember(
            transition.state,
            transition.action,
            transition.reward.total,
            transition.next_state,
            transition.terminated,
        )
        if not agent.warming_up:
            owed = self._owed_updates.setdefault(transition.episode_id, {})
            owed[transition.agent] = owed.get(transition.agent, 0) + 1
        terms = self._episode_terms.setdefault(transition.episode_id, {}).setdefault(
            transition.agent, [0.0, 0.0, 0.0, 0.0, 0.0]
        )
        reward = transition.reward
        for i, value in enumerate((reward.time, reward.cost, reward.penalty, reward.search, 1.0)):
            terms[i] += value

    # ------------------------------------------------------------------ checkpoints

    def state_dict(self) -> dict[str, Any]:
        """Everything training depends on, including the global RNG states."""
        return {
            "format": CHECKPOINT_FORMAT,
            "config": self.config.to_dict(),
            "agents": {name: agent.state_dict() for name, agent in self.agents.items()},
            "pairing": self.pairing.state_dict(),
            "episodes": self.episodes,
            "sources": sorted(self.sources),
            "policy_version": self._policy_version,
            "pending_updates": dict(self._pending_updates),
            "owed_updates": {e: dict(d) for e, d in self._owed_updates.items()},
            "episode_terms": {
                e: {a: list(t) for a, t in d.items()} for e, d in self._episode_terms.items()
            },
            "rng": {
                "torch": torch.get_rng_state(),
                "numpy": np.random.get_state(),
                "python": random.getstate(),
            },
        }

    def save_checkpoint(self, path: str | Path) -> None:
        """Write the state atomically (a temporary file renamed into place)."""
        self.write_checkpoint(self.checkpoint_state(), path)

    def checkpoint_state(self) -> dict[str, Any]:
        """A deep copy of :meth:`state_dict` that later changes of the core do not touch: a
        caller that serialises the core's state under a lock copies it under the lock (tens of
        ms) and writes it with :meth:`write_checkpoint` after releasing it (about 0.1 s more,
        which decisions would otherwise wait for)."""
        return copy.deepcopy(self.state_dict())

    @staticmethod
    def write_checkpoint(state: dict[str, Any], path: str | Path) -> None:
        """Write a :meth:`checkpoint_state` atomically (a temporary file renamed into place).

        The writer holds a lock (``flock``) on its temporary file from its creation: the
        temporary files of ``path`` that no writer holds (a process killed while it wrote) are
        removed first, where they piled up beside the checkpoints."""
        from lit_planner.tensor_files import held_new, remove_unheld

        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        for stale in path.parent.glob(f"{glob.escape(path.name)}.*.tmp"):
            # Only files as a writer leaves them (a link or folder of that name is not ours).
            if stale.is_file() and not stale.is_symlink():
                remove_unheld(stale)
        temporary = path.with_name(f"{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")

        def create() -> Path:
            os.close(os.open(temporary, os.O_WRONLY | os.O_CREAT, 0o644))
            return temporary

        temporary, holder = held_new(create)
        try:
            try:
                torch.save(_arrays_as_tensors(state), temporary)
            except RuntimeError as error:  # torch's writer: a full disk is "unexpected pos ..."
                if not any(words in str(error) for words in _WRITE_FAILED):
                    raise
                free = shutil.disk_usage(path.parent).free
                raise OSError(
                    f"{path}: the checkpoint could not be written ({error}; {free} bytes free "
                    "on its file system)"
                ) from error
            os.replace(temporary, path)
        except BaseException:
            temporary.unlink(missing_ok=True)  # a full disk left it, beside the checkpoints
            raise
        finally:
            os.close(holder)

    @classmethod
    def load_checkpoint(cls, path: str | Path) -> LearnerCore:
        """A core that continues exactly where the saved one stopped (less any replay transitions
        with values that are not finite: :meth:`load_warning`).

        Raises:
            CheckpointError: missing, unreadable or incompatible checkpoint.
        """
        path = Path(path)
        if not path.is_file():
            # A folder there was "not found": the learner node then seemed to look elsewhere.
            if path.is_dir():
                raise CheckpointError(f"{path}: a folder, not a checkpoint file")
            if path.exists():
                raise CheckpointError(f"{path}: not a regular file, so not a checkpoint")
            raise CheckpointError(f"{path}: checkpoint not found")
        damage = _archive_damage(path)
        if damage is not None:  # torch.load does not check: a flipped bit was trained on
            raise CheckpointError(f"{path}: damaged checkpoint: {damage}")
        try:
            # Not weights_only: the replay buffer and RNG states are numpy objects and tuples.
            state = _arrays_from_tensors(torch.load(path, map_location="cpu", weights_only=False))
        except Exception as exc:  # torch raises many types for a damaged file
            raise CheckpointError(
                f"{path}: cannot read checkpoint (damaged or not a checkpoint: "
                f"{type(exc).__name__}: {exc})"
            ) from exc
        if not isinstance(state, dict) or state.get("format") != CHECKPOINT_FORMAT:
            found = state.get("format") if isinstance(state, dict) else type(state).__name__
            raise CheckpointError(
                f"{path}: checkpoint format {found!r}, expected {CHECKPOINT_FORMAT}"
            )
        try:
            core = cls(LearnerConfig.from_dict(state["config"]))
        except (ConfigError, TypeError, KeyError) as exc:
            raise CheckpointError(f"{path}: bad config in checkpoint: {exc}") from exc
        try:
            core._restore(state)
        except (CheckpointError, ReplayError) as exc:
            raise CheckpointError(f"{path}: {exc}") from exc
        except (KeyError, TypeError, ValueError, IndexError, RuntimeError) as exc:
            # Parts missing or of the wrong shape (written by something else, or edited): one
            # line, not a traceback; torch reports shape mismatches as RuntimeError.
            raise CheckpointError(
                f"{path}: incomplete or inconsistent checkpoint ({type(exc).__name__}: {exc})"
            ) from exc
        return core

    def _restore(self, state: dict[str, Any]) -> None:
        """The saved state of :meth:`load_checkpoint` into this fresh core."""
        _check_values(state)
        core = self
        for name, agent in core.agents.items():
            try:
                core.dropped_at_load[name] = agent.load_state_dict(state["agents"][name])
            except NonFiniteWeights as exc:
                raise CheckpointError(f"agent {name}: {exc}") from exc
        core.pairing.load_state_dict(state["pairing"])
        core.episodes = state["episodes"]
        core.sources = set(state.get("sources", ()))  # checkpoints from before it: none known
        core._policy_version = state["policy_version"]
        core._pending_updates = dict(state["pending_updates"])
        # Checkpoints written before owed updates existed counted them as pending already.
        core._owed_updates = {e: dict(d) for e, d in state.get("owed_updates", {}).items()}
        core._episode_terms = {
            # Checkpoints from before the search term had its own slot: [time, cost, penalty, n].
            e: {a: list(t) if len(t) == 5 else [*t[:3], 0.0, t[3]] for a, t in d.items()}
            for e, d in state["episode_terms"].items()
        }
        torch.set_rng_state(state["rng"]["torch"])
        np.random.set_state(state["rng"]["numpy"])
        random.setstate(state["rng"]["python"])

    # ------------------------------------------------------------------ export

    def export_tensors(
        self,
        directory: str | Path,
        provenance: dict[str, Any],
        agents: Sequence[str] = AGENT_NAMES,
        lock: AbstractContextManager[Any] | None = None,
        extra: Mapping[str, bytes] | None = None,
        remove_others: bool = False,
    ) -> dict[str, Path]:
        """Write ``checkpoint.pt`` and each agent's lookup tensor with its sidecar into
        ``directory``, with the ``extra`` files (name: content); ``remove_others``: remove the
        tensor files of the agents not in ``agents`` from ``directory`` (an earlier export's).

        ``lock`` (held by whoever else uses the core, e.g. the learner node's decision service)
        is taken only while the state and the actors are copied; the checkpoint file and the
        lookup grids, which take seconds, are written from those copies without it. Every file
        is written in a staging folder first and then renamed into ``directory``: a reader sees
        each file whole, and an export that fails leaves nothing of itself.

        Returns:
            Paths keyed ``B`` (b_tensor.npy), ``psi_K`` (k_tensor.npy) and ``checkpoint``.

        Raises:
            lit_planner.errors.TensorFileError: a tensor or sidecar failed validation.
            ExportError: a file could not be written (a full disk, say).
        """
        chosen = (tuple(agents), {})
        return self._export(directory, provenance, lambda: chosen, lock, extra, remove_others)[0]

    def export_trained(
        self,
        directory: str | Path,
        provenance: dict[str, Any],
        lock: AbstractContextManager[Any] | None = None,
        extra: Mapping[str, bytes] | None = None,
        remove_others: bool = False,
    ) -> tuple[dict[str, Path], dict[str, str]]:
        """:meth:`export_tensors` of the agents of :meth:`export_plan`, chosen under ``lock``
        with the copy of the state (an agent's first step cannot fall between the two).

        Returns:
            The written files' paths, and what the export says of each agent it left out.
        """
        return self._export(directory, provenance, self.export_plan, lock, extra, remove_others)

    def _export(
        self,
        directory: str | Path,
        provenance: dict[str, Any],
        choose: Callable[[], tuple[tuple[str, ...], dict[str, str]]],
        lock: AbstractContextManager[Any] | None,
        extra: Mapping[str, bytes] | None,
        remove_others: bool,
    ) -> tuple[dict[str, Path], dict[str, str]]:
        """The body of :meth:`export_tensors` and :meth:`export_trained`; ``choose`` (called
        under ``lock``) gives the agents and the notes of those left out."""
        from lit_planner.tensor_files import sidecar_path, staged_folder

        directory = Path(directory)
        others: list[str] = []  # staged_folder removes them after the block: filled in there
        try:
            with staged_folder(directory, remove=others) as stage:
                agents, left_out = self._export_into(stage, provenance, choose, lock)
                others += [
                    name
                    for agent, file_name in TENSOR_FILES.items()
                    if remove_others and agent not in agents
                    for name in (file_name, sidecar_path(file_name).name)
                ]
                for name, content in (extra or {}).items():
                    (stage / name).write_bytes(content)
        except OSError as error:
            raise ExportError(
                f"export to {directory} failed ({error}); nothing of it was written there"
            ) from None
        paths = {"checkpoint": directory / CHECKPOINT_FILE} | {
            name: directory / TENSOR_FILES[name] for name in agents
        }
        return paths, left_out

    def _export_into(
        self,
        directory: Path,
        provenance: dict[str, Any],
        choose: Callable[[], tuple[tuple[str, ...], dict[str, str]]],
        lock: AbstractContextManager[Any] | None,
    ) -> tuple[tuple[str, ...], dict[str, str]]:
        """:meth:`_export`'s files, written into ``directory``; returns what ``choose`` gave."""
        from lit_planner.tensor_files import write_tensor  # pulls in the JSON-Schema validator

        checkpoint = directory / CHECKPOINT_FILE
        with lock if lock is not None else nullcontext():
            agents, left_out = choose()
            state = self.checkpoint_state()  # written below, after the lock
            frozen = {
                name: (
                    copy.deepcopy(self.agents[name].actor),
                    {
                        "agent": self.agents[name].config.to_dict(),
                        "seed": self.config.seed,
                        "trained": self.trains(name),
                        "updates": self.agents[name].updates,
                        "transitions": self.agents[name].transitions,
                        "episodes": self.episodes,
                    },
                )
                for name in agents
            }
            policy_version = self._policy_version
        self.write_checkpoint(state, checkpoint)
        checkpoint_sha256 = _sha256(checkpoint)
        for name, (actor, training) in frozen.items():
            config = self.agents[name].config  # immutable
            write_tensor(
                directory / TENSOR_FILES[name],
                policy_grid(actor, config),
                name,
                interpolation="trilinear",
                consequents=config.consequents,
                fuzzy_centres=config.fuzzy_centres,
                fuzzy_sigma=config.fuzzy_sigma,
                reward=self.config.reward.to_dict(),
                training=training,
                policy_version=policy_version,
                checkpoint_sha256=checkpoint_sha256,
                provenance=provenance,
            )
        return agents, left_out


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as stream:
        for block in iter(lambda: stream.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


_ARRAY_TAG = "__numpy_array__"
"""Key of the one-entry dict that stands for a numpy array in a checkpoint file."""
_TENSOR_DTYPES = frozenset(
    np.dtype(t) for t in (np.float32, np.float64, np.int32, np.int64, np.uint8, np.bool_)
)


_RANGE_SLACK = 1e-9
"""How far (in a_norm) a recorded value may lie outside its agent's range and still be taken as
the range's end: rounding only (the planner clamps to the range)."""

_WRITE_FAILED = ("unexpected pos", "failed writing")
"""Words of torch's writer when the file could not be written (a full disk: "unexpected pos 64 vs
0"; "PytorchStreamWriter failed writing file ...")."""


def _whole(label: str, value: Any) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise CheckpointError(f"{label} is {value!r}, not a whole number >= 0")


def _real(label: str, value: Any, *, least: float = -np.inf) -> None:
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float, np.integer, np.floating))
        or not least <= float(value) < np.inf
    ):
        raise CheckpointError(f"{label} is {value!r}, not a finite number >= {least:g}")


def _mapping(label: str, value: Any) -> Mapping[Any, Any]:
    if not isinstance(value, Mapping):
        raise CheckpointError(f"{label} is a {type(value).__name__}, not a mapping")
    return value


def _check_values(state: Mapping[str, Any]) -> None:
    """Raise CheckpointError for a count, time or cost of the wrong type or out of range: such a
    checkpoint loaded, and the learner node then failed at its first statistics (a traceback,
    and a shutdown that wrote the checkpoint over). Structure that is missing raises KeyError
    (or TypeError), which the caller reports."""
    _whole("episodes", state["episodes"])
    _whole("policy_version", state["policy_version"])
    for source in state.get("sources", ()):
        if not isinstance(source, str):
            raise CheckpointError(f"sources holds {source!r}, not a name")
    for agent, count in _mapping("pending_updates", state["pending_updates"]).items():
        _whole(f"pending_updates[{agent!r}]", count)
    for episode, owed in _mapping("owed_updates", state.get("owed_updates", {})).items():
        for agent, count in _mapping(f"owed_updates[{episode!r}]", owed).items():
            _whole(f"owed_updates[{episode!r}][{agent!r}]", count)
    for episode, terms in _mapping("episode_terms", state["episode_terms"]).items():
        for agent, values in _mapping(f"episode_terms[{episode!r}]", terms).items():
            for i, value in enumerate(values):
                _real(f"episode_terms[{episode!r}][{agent!r}][{i}]", value)
    for name, agent in _mapping("agents", state["agents"]).items():
        _whole(f"agents[{name!r}].updates", agent["updates"])
        _whole(f"agents[{name!r}].transitions", agent["transitions"])
    for episode, progress in _mapping("pairing", state["pairing"]).items():
        where = f"pairing[{episode!r}]"
        for count, time in _mapping(
            f"{where}.improvement_times", progress["improvement_times"]
        ).items():
            _whole(f"{where}.improvement_times key", count)
            _real(f"{where}.improvement_times[{count}]", time, least=0.0)
        _real(f"{where}.last_time", progress["last_time"], least=0.0)
        if progress.get("best_cost") is not None:
            _real(f"{where}.best_cost", progress["best_cost"], least=0.0)
        for agent, value in _mapping(f"{where}.returns", progress["returns"]).items():
            _real(f"{where}.returns[{agent!r}]", value)
        for agent, pending in _mapping(f"{where}.pending", progress["pending"]).items():
            # (features, action, improvements, time); before 2026-11-30 without the time
            features, action, improvements, *time = pending
            for i, feature in enumerate(features):
                _real(f"{where}.pending[{agent!r}] feature {i}", feature)
            _real(f"{where}.pending[{agent!r}] action", action)
            _whole(f"{where}.pending[{agent!r}] improvements", improvements)
            for value in time:
                _real(f"{where}.pending[{agent!r}] time", value, least=0.0)


def _archive_damage(path: Path) -> str | None:
    """What is damaged in the checkpoint archive (torch.save writes a zip): an entry whose bytes
    do not match their CRC, or a directory zipfile cannot follow; None when every entry checks
    (also for a file that is no zip: torch.load names that)."""
    try:
        with zipfile.ZipFile(path) as archive:
            bad = archive.testzip()
    except (zipfile.BadZipFile, OSError, EOFError):
        return None
    except Exception as error:  # noqa: BLE001 - a flipped flag bit reads as encryption, say
        return f"its directory ({type(error).__name__}: {error})"
    return None if bad is None else f"its entry {bad} does not match its CRC"


def _arrays_as_tensors(value: Any) -> Any:
    """``value`` with every numpy array that torch can view replaced by ``{_ARRAY_TAG: tensor}``
    (a zero-copy view). torch.save writes a tensor's bytes with the GIL released, but pickles a
    numpy array as one bytes object with the GIL held: saving a full psi_K replay buffer (about
    40 MB) that way stopped every other thread of the learner node (the one answering decisions)
    for up to 0.2 s at a time, against about 1 ms as tensors (one-off measurement)."""
    if isinstance(value, np.ndarray) and value.dtype in _TENSOR_DTYPES and value.ndim > 0:
        return {_ARRAY_TAG: torch.from_numpy(np.ascontiguousarray(value))}
    if isinstance(value, dict):
        return _same_mapping(value, {k: _arrays_as_tensors(v) for k, v in value.items()})
    if isinstance(value, (list, tuple)) and type(value) in (list, tuple):
        return type(value)(_arrays_as_tensors(item) for item in value)
    return value


def _arrays_from_tensors(value: Any) -> Any:
    """Undoes :func:`_arrays_as_tensors` (files written before it hold the arrays themselves)."""
    if isinstance(value, dict):
        if len(value) == 1 and _ARRAY_TAG in value:
            return value[_ARRAY_TAG].numpy()
        return _same_mapping(value, {k: _arrays_from_tensors(v) for k, v in value.items()})
    if isinstance(value, (list, tuple)) and type(value) in (list, tuple):
        return type(value)(_arrays_from_tensors(item) for item in value)
    return value


def _same_mapping(original: dict[Any, Any], items: dict[Any, Any]) -> dict[Any, Any]:
    """``items`` in a mapping of ``original``'s type, with its ``_metadata`` (module versions
    that ``nn.Module.state_dict`` attaches to its OrderedDict)."""
    if type(original) is dict:
        return items
    mapping = type(original)(items)
    if hasattr(original, "_metadata"):
        mapping._metadata = original._metadata  # type: ignore[attr-defined]
    return mapping

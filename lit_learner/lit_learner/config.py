"""Configuration dataclasses of the Fuzzy-DDPG learner (LEARNER.md; values marked "ours" there are
our choices, not the paper's, and are recorded in every exported tensor's sidecar)."""

from __future__ import annotations

import math
import numbers
from dataclasses import asdict, dataclass, field, fields
from typing import Any

import numpy as np

from lit_learner.errors import ConfigError

AGENT_NAMES = ("B", "psi_K")
"""The two agents: batch size B and neighbour factor psi_K."""
FIXED_VALUES = {"B": "B = 100", "psi_K": "psi_K = e"}
"""What the ``tensor`` policy plays for an agent whose tensor a folder lacks."""
MAX_SEED = 2**63 - 2
"""The largest learner seed: the psi_K agent's (seed + 1) is still a 64-bit signed integer, as a
ROS parameter and torch's seed take."""


def left_out_note(agent: str, why: str) -> str:
    """What an export says of ``agent``, whose tensor it left out for the reason ``why``."""
    return f"no tensor ({why}); the tensor policy keeps its fixed value ({FIXED_VALUES[agent]})"


@dataclass(frozen=True)
class AgentConfig:
    """One DDPG agent (B-Net or K-Net): its action range, networks and update constants."""

    name: str
    """Agent and output name: ``B`` or ``psi_K``."""
    consequents: tuple[float, float, float]
    """Zero-order TSK consequents f; (min f, max f) is the action range."""
    rounding: str = "none"
    """Rounding of the executed value: ``half_away_from_zero`` (B) or ``none`` (psi_K)."""
    gamma: float = 0.99
    """Discount factor."""
    tau: float = 0.005
    """Polyak factor of both target networks (1 copies)."""
    lr_actor: float = 3e-4
    """Adam learning rate of the actor."""
    lr_critic: float = 3e-4
    """Adam learning rate of the critic."""
    batch_size: int = 64
    """Transitions per gradient step."""
    buffer_size: int = 100_000
    """Replay capacity in transitions (oldest overwritten first)."""
    warmup: int = 500
    """Stored transitions before the first gradient step; actions are uniform until then."""
    alpha: float = 0.6
    """Priority exponent: sampling probability p_i^alpha / sum p^alpha."""
    beta_start: float = 0.4
    """Importance-weight exponent at the first gradient step."""
    beta_end: float = 1.0
    """Importance-weight exponent after ``beta_steps`` gradient steps."""
    beta_steps: int = 50_000
    """Gradient steps over which beta rises linearly from start to end (ours)."""
    priority_eps: float = 1e-6
    """Added to |y - Q| so no transition gets priority 0."""
    noise_std: float = 0.05
    """Std of the Gaussian exploration noise on a_norm (clipped to [0, 1] afterwards)."""
    fuzzy_centres: tuple[float, float, float] = (0.0, 0.5, 1.0)
    """Gaussian membership centres per feature."""
    fuzzy_sigma: float = 0.2123
    """Gaussian membership width (neighbours cross at 0.5)."""
    conv_kernels: tuple[int, ...] = (3, 5, 7)
    """Kernel sizes of the trunk's parallel Conv1d(1 -> 3) layers (same padding)."""
    conv_channels: int = 3
    """Output channels of each trunk convolution."""
    hidden: tuple[int, ...] = (64, 128, 128, 64, 32)
    """Hidden widths of the actor's and the critic's MLP (ReLU)."""
    actor_last_init: float = 3e-3
    """Half-width of the uniform init of the actor's last layer, so z* starts mid-range (ours)."""
    logit_penalty: float = 1e-2
    """Weight of the mean squared rule logit in the actor's loss (ours; 0 turns it off): without
    it the softmax can saturate at a rule corner, where the actor's gradient vanishes for good
    (seen as the B agent stuck at B = 20, and as 2 of 8 seeds of the one-step bandit at 1.0)."""

    def __post_init__(self) -> None:
        _make_plain(self)
        if self.name not in AGENT_NAMES:
            raise ConfigError(f"agent name {self.name!r} is not one of {AGENT_NAMES}")
        # min() and max() skip a NaN: (20, nan, 200) passed, and every decision then failed.
        if not (
            isinstance(self.consequents, tuple)
            and len(self.consequents) == 3
            and all(_is_number(c) for c in self.consequents)
            and min(self.consequents) < max(self.consequents)
        ):
            raise ConfigError(
                f"{self.name}: consequents {self.consequents} must be three finite numbers "
                f"spanning a range"
            )
        if self.rounding not in ("half_away_from_zero", "none"):
            raise ConfigError(f"{self.name}: unknown rounding {self.rounding!r}")
        if not (_is_number(self.tau) and 0.0 < self.tau <= 1.0):
            raise ConfigError(f"{self.name}: tau {self.tau} not in (0, 1]")
        if not (_is_number(self.gamma) and 0.0 <= self.gamma <= 1.0):
            raise ConfigError(f"{self.name}: gamma {self.gamma} not in [0, 1]")
        for name in ("batch_size", "buffer_size", "warmup", "beta_steps"):
            if not _is_int(getattr(self, name)):
                raise ConfigError(f"{self.name}: {name} {getattr(self, name)!r} is not an integer")
        for name in ("lr_actor", "lr_critic"):
            if not (_is_number(getattr(self, name)) and getattr(self, name) > 0.0):
                raise ConfigError(f"{self.name}: {name} {getattr(self, name)} must be > 0")
        if self.batch_size < 1 or self.buffer_size < self.batch_size:
            raise ConfigError(
                f"{self.name}: batch_size {self.batch_size} must be >= 1 and <= buffer_size "
                f"{self.buffer_size}"
            )
        if self.warmup < self.batch_size:
            raise ConfigError(
                f"{self.name}: warmup {self.warmup} must be >= batch_size {self.batch_size}"
            )
        if not (_is_number(self.priority_eps) and self.priority_eps > 0.0):
            raise ConfigError(f"{self.name}: priority_eps {self.priority_eps} must be > 0")
        if self.beta_steps < 1:
            raise ConfigError(f"{self.name}: beta_steps {self.beta_steps} must be >= 1")
        # beta below 0 gave importance weights above 1, a NaN beta NaN weights and a loss blamed
        # on the networks.
        for name in ("beta_start", "beta_end"):
            if not (_is_number(getattr(self, name)) and 0.0 <= getattr(self, name) <= 1.0):
                raise ConfigError(f"{self.name}: {name} {getattr(self, name)} not in [0, 1]")
        for name in ("alpha", "noise_std", "logit_penalty"):
            if not (_is_number(getattr(self, name)) and getattr(self, name) >= 0.0):
                raise ConfigError(f"{self.name}: {name} {getattr(self, name)} must be >= 0")
        if not (
            isinstance(self.fuzzy_centres, tuple)
            and len(self.fuzzy_centres) == 3
            and all(_is_number(c) for c in self.fuzzy_centres)
            and self.fuzzy_centres[0] < self.fuzzy_centres[1] < self.fuzzy_centres[2]
        ):
            raise ConfigError(
                f"{self.name}: fuzzy_centres {self.fuzzy_centres} must be three increasing "
                f"finite numbers"
            )
        # 2 sigma^2 is a divisor: 1e-200 passed and made it 0.
        if not (_is_number(self.fuzzy_sigma) and 1e-6 <= self.fuzzy_sigma <= 1e6):
            raise ConfigError(f"{self.name}: fuzzy_sigma {self.fuzzy_sigma} not in [1e-6, 1e6]")
        if not (
            isinstance(self.conv_kernels, tuple)
            and self.conv_kernels
            and all(_is_int(k) and k >= 1 and k % 2 == 1 for k in self.conv_kernels)
            and _is_int(self.conv_channels)
            and self.conv_channels >= 1
            and isinstance(self.hidden, tuple)
            and self.hidden
            and all(_is_int(h) and h >= 1 for h in self.hidden)
        ):
            raise ConfigError(
                f"{self.name}: conv_kernels {self.conv_kernels} (odd, >= 1), conv_channels "
                f"{self.conv_channels} and hidden {self.hidden} (each >= 1) do not make a network"
            )
        if not (_is_number(self.actor_last_init) and self.actor_last_init >= 0.0):
            raise ConfigError(f"{self.name}: actor_last_init {self.actor_last_init} must be >= 0")

    @property
    def action_min(self) -> float:
        """Smallest executable value (min f)."""
        return float(min(self.consequents))

    @property
    def action_max(self) -> float:
        """Largest executable value (max f)."""
        return float(max(self.consequents))

    @classmethod
    def batch_size_agent(cls, **overrides: Any) -> AgentConfig:
        """B-Net with LEARNER.md's defaults: f = (20, 110, 200), batch 64, buffer 1e5, warm-up 500."""
        values: dict[str, Any] = {
            "name": "B",
            "consequents": (20.0, 110.0, 200.0),
            "rounding": "half_away_from_zero",
            "batch_size": 64,
            "buffer_size": 100_000,
            "warmup": 500,
            "beta_steps": 50_000,
        }
        return cls(**(values | overrides))

    @classmethod
    def neighbour_agent(cls, **overrides: Any) -> AgentConfig:
        """K-Net with LEARNER.md's defaults: f = (3, 9, 15), batch 256, buffer 1e6, warm-up 1e4."""
        values: dict[str, Any] = {
            "name": "psi_K",
            "consequents": (3.0, 9.0, 15.0),
            "rounding": "none",
            "batch_size": 256,
            "buffer_size": 1_000_000,
            "warmup": 10_000,
            "beta_steps": 500_000,
        }
        return cls(**(values | overrides))

    def to_dict(self) -> dict[str, Any]:
        """JSON-able form (tuples become lists)."""
        return _jsonable(asdict(self))


@dataclass(frozen=True)
class RewardConfig:
    """Reward weights of R_B and R_K and the constants of kappa (LEARNER.md, all ours)."""

    w_t: float = 0.01
    """Weight of the speed term 1 / t_hat."""
    w_c: float = 1.0
    """Weight of the cost term c_min / c."""
    w_u: float = 0.05
    """B: penalty per solution improvement so far."""
    w_s: float = 0.1
    """K: penalty per 50 states on the current best path."""
    w_search: float = 1.0
    """K: weight of the search cost, w_search * ln(t_end / t_start) per step before the first
    solution (ours: the paper's R_K rewards speed only in the step that improves, which one
    decision out of hundreds earns; the log makes a relative speed-up count alike everywhere)."""
    search_floor: float = 1e-3
    """K: planner times below search_floor * T_budget are free (the log's floor)."""
    nu: float = 1.0
    """Scale of kappa(n) = nu * log2(6.8 - n)."""
    nu_min: float = 0.1
    """Floor of kappa, also its value once 6.8 - n <= 0."""
    kappa_offset: float = 6.8
    """The 6.8 in kappa(n) = nu * log2(6.8 - n)."""
    t_hat_min: float = 0.01
    """Floor of the normalised step time t_hat = t / T_budget."""
    path_states_scale: float = 50.0
    """K: path states are divided by this before weighting with w_s."""

    def __post_init__(self) -> None:
        _make_plain(self)
        # Divisors and log arguments: 0 gave a ZeroDivisionError at the first reward.
        for name in ("search_floor", "t_hat_min", "path_states_scale"):
            if not (_is_number(getattr(self, name)) and getattr(self, name) > 0.0):
                raise ConfigError(f"rewards: {name} {getattr(self, name)} must be > 0")
        for name in ("w_t", "w_c", "w_u", "w_s", "w_search", "nu", "kappa_offset"):
            if not _is_number(getattr(self, name)):
                raise ConfigError(f"rewards: {name} {getattr(self, name)} is not a number")
        if not (_is_number(self.nu_min) and self.nu_min >= 0.0):  # kappa's floor
            raise ConfigError(f"rewards: nu_min {self.nu_min} must be a number >= 0")

    def to_dict(self) -> dict[str, Any]:
        """JSON-able form."""
        return _jsonable(asdict(self))


@dataclass(frozen=True)
class LearnerConfig:
    """The whole learner: both agents, the rewards, the seed and what is trained."""

    b: AgentConfig = field(default_factory=AgentConfig.batch_size_agent)
    """B-Net."""
    k: AgentConfig = field(default_factory=AgentConfig.neighbour_agent)
    """K-Net."""
    reward: RewardConfig = field(default_factory=RewardConfig)
    """Reward weights."""
    seed: int = 0
    """Seed of network initialisation, exploration and replay sampling."""
    train_b: bool = True
    """Store B transitions and update B-Net; False: B decisions are noise-free, nothing stored."""
    train_k: bool = True
    """Same for K-Net."""
    device: str = "cpu"
    """Torch device; the learner is written for the CPU."""
    num_threads: int = 1
    """torch.set_num_threads at construction: one thread is fastest for these small batches and
    makes results independent of the machine's core count."""

    def __post_init__(self) -> None:
        _make_plain(self)
        if self.b.name != "B" or self.k.name != "psi_K":
            raise ConfigError(
                f"LearnerConfig.b must be the B agent and .k the psi_K agent, got "
                f"{self.b.name!r} and {self.k.name!r}"
            )
        if self.device != "cpu":
            raise ConfigError(f"device {self.device!r}: the learner runs on the CPU only")
        # Both failed later, inside torch or numpy, as a bare ValueError or RuntimeError.
        if not (_is_int(self.seed) and 0 <= self.seed <= MAX_SEED):
            raise ConfigError(f"seed {self.seed!r} must be an integer in [0, 2^63 - 2]")
        if not (_is_int(self.num_threads) and self.num_threads >= 1):
            raise ConfigError(f"num_threads {self.num_threads!r} must be an integer >= 1")
        for name in ("train_b", "train_k"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"{name} {getattr(self, name)!r} is not true or false")

    def agent(self, name: str) -> AgentConfig:
        """The config of agent ``name``."""
        if name == "B":
            return self.b
        if name == "psi_K":
            return self.k
        raise ConfigError(f"unknown agent {name!r}; expected one of {AGENT_NAMES}")

    def to_dict(self) -> dict[str, Any]:
        """JSON-able form."""
        return _jsonable(asdict(self))

    @classmethod
    def from_dict(cls, doc: dict[str, Any]) -> LearnerConfig:
        """Inverse of :meth:`to_dict`."""

        def agent(d: dict[str, Any]) -> AgentConfig:
            d = {"logit_penalty": 0.0, **d}  # configs from before the penalty trained without it
            return AgentConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in d.items()})

        rest = {k: v for k, v in doc.items() if k not in ("b", "k", "reward")}
        reward = {"w_search": 0.0, **doc["reward"]}  # likewise without the K search cost
        return cls(b=agent(doc["b"]), k=agent(doc["k"]), reward=RewardConfig(**reward), **rest)


def _is_number(value: Any) -> bool:
    """A finite real number (not a bool)."""
    if not isinstance(value, numbers.Real) or isinstance(value, (bool, np.bool_)):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:  # an int beyond a float's range (10**400 in an edited checkpoint)
        return False


def _plain(value: Any) -> Any:
    """``value`` with numpy scalars as Python's own numbers and lists as tuples: np.int64 and
    np.float32 passed the checks and then failed the sidecar's JSON at the first export."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, np.floating):
        return float(value)
    if isinstance(value, (tuple, list)):
        return tuple(_plain(item) for item in value)
    return value


def _make_plain(config: Any) -> None:
    """:func:`_plain` on every field of the frozen dataclass ``config``."""
    for item in fields(config):
        object.__setattr__(config, item.name, _plain(getattr(config, item.name)))


def _is_int(value: Any) -> bool:
    """An integer (not a bool)."""
    return isinstance(value, numbers.Integral) and not isinstance(value, (bool, np.bool_))


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    return value

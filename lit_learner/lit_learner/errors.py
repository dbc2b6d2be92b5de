"""Errors of the learner; each names the input that caused it."""

from __future__ import annotations


class LearnerError(Exception):
    """Base class of every learner error. ``field``: the message field it is about (a JSON
    path below the payload, such as ``cost`` or ``final_features.B``), when it is about one."""

    def __init__(self, *args: object, field: str | None = None) -> None:
        super().__init__(*args)
        self.field = field


class ConfigError(LearnerError, ValueError):
    """A configuration value is out of its valid range."""


class MessageError(LearnerError, ValueError):
    """A decision request or episode end is malformed (unknown agent, non-finite feature, ...)."""


class PairingError(LearnerError):
    """Messages arrive in an order that cannot form transitions (e.g. time running backwards)."""


class ReplayError(LearnerError):
    """The replay buffer was asked for something it cannot give (e.g. sampling while empty)."""


class CheckpointError(LearnerError):
    """A checkpoint is missing, unreadable, or of an incompatible version."""


class NonFiniteWeights(LearnerError, ValueError):
    """A network (or its optimiser) loaded from a checkpoint holds values that are NaN or
    infinite."""


class ExportError(LearnerError):
    """An export could not be written (a full disk, say); nothing of it was left behind."""

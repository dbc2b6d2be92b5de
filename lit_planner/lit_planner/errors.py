"""Exceptions raised by the planner-side Python code of ``lit_planner``.

Every exception is a ``ValueError`` as well, so callers that only care about "bad input" can catch
that, while callers that care can tell a bad scenario name from a corrupt tensor file.
"""

from __future__ import annotations


class LitPlannerError(Exception):
    """Base class of all ``lit_planner`` errors."""


class ScenarioError(LitPlannerError, ValueError):
    """A scenario name, dimension, instance or path argument is not acceptable."""

    def __init__(self, message: str, *, part: str | None = None) -> None:
        super().__init__(message)
        self.part = part
        """The input at fault when one is: ``start``, ``goal`` or ``time`` (a request's field)."""


class TensorFileError(LitPlannerError, ValueError):
    """A lookup tensor or its sidecar cannot be written or read; names the file and the problem."""


class TensorLookupError(LitPlannerError, ValueError):
    """A lookup into a tensor got a malformed tensor, query point or interpolation mode."""


class PlannerError(LitPlannerError, ValueError):
    """An unknown planner or policy name, or planning options that do not fit together."""


class MissingTensorsError(TensorFileError):
    """The ``tensor`` policy found no lookup tensor; says where it looked and how to get some."""

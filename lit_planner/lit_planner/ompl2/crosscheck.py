"""Worker: OMPL 2.0.1 (PyPI ompl) solves a scenario and re-validates LIT*'s paths, independently.

Nothing of LIT*'s stack is used here: the world comes in as data (bounds, closed boxes, start,
goal, resolution from the scenario registry), validity is decided by the numpy
:class:`~lit_planner.ompl2.checker.BoxWorldChecker`, and the planners are OMPL 2.0.1's.

- **Re-validation of a path** (each entry of ``paths``): OMPL 2.0.1's own
  ``SpaceInformation.checkMotion`` on every segment, i.e. its ``DiscreteMotionValidator`` at the
  scenario's resolution calling our numpy checker through a ``StateValidityChecker`` subclass for
  every intermediate state, plus ``isValid`` on the first waypoint; then the dense numpy check
  (:meth:`BoxWorldChecker.check_path`, four times finer than the resolution); the path length as
  ``PathGeometric.length()`` computes it, compared with the cost the planner reported; and the
  endpoints against start and goal.
- **Planning**: ``BITstar`` and ``InformedRRTstar`` with the path-length objective, a
  ``StateValidityChecker`` subclass for samples and a ``MotionValidator`` subclass that makes
  OMPL's discrete decision at the scenario's resolution exactly but without a Python call per
  intermediate state (:meth:`BoxWorldChecker.motion_valid`); per-state callbacks at PDT's
  resolution would leave the planners a few edges per second. The cost curve is read through the
  termination condition, which ``solve`` evaluates in its own thread every iteration.
  Every returned path is re-validated like LIT*'s.

Request: ``{"scenario": Scenario.to_dict(), "paths": [{"label", "path", "cost"}], "planners":
[...], "runs": int, "time": seconds, "seed": int}``. Response: ``{"validations": [...], "runs":
[...], "ompl_version": ...}`` plus the process report. Start it with
:func:`lit_planner.ompl2.run_worker`.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Mapping, Sequence
from typing import Any

from lit_planner.ompl2 import worker_main
from lit_planner.ompl2.checker import BoxWorldChecker

PLANNERS = {"bitstar": "BITstar", "irrtstar": "InformedRRTstar"}
"""OMPL 2.0.1 planners of the cross-check: our name -> class in ``ompl.geometric``."""
COST_TOLERANCE = 1e-9
"""Relative difference allowed between a reported cost and the path length recomputed here."""


def handle(request: Mapping[str, Any]) -> dict[str, Any]:
    """Validate the request's paths, then run each planner ``runs`` times."""
    from ompl import util as ou  # only here: enter_worker has checked the process first

    ou.setLogLevel(ou.LogLevel.LOG_WARN)
    ou.RNG.setSeed(int(request.get("seed", 1)))  # before any planner creates a generator
    definition = request["scenario"]
    checker = BoxWorldChecker.from_definition(definition)
    world = OmplWorld(definition, checker)
    validations = [
        world.validate(str(item.get("label", index)), item["path"], item.get("cost"))
        for index, item in enumerate(request.get("paths", []))
    ]
    runs = []
    planners = list(request.get("planners", PLANNERS))
    unknown = [name for name in planners if name not in PLANNERS]
    if unknown:
        raise ValueError(f"unknown OMPL 2.0.1 planners {unknown}; known: {', '.join(PLANNERS)}")
    for run in range(int(request.get("runs", 0))):
        for name in planners:
            print(f"ompl2 crosscheck: {definition.get('key', definition.get('name'))} {name} "
                  f"run {run + 1}/{request['runs']}", file=sys.stderr, flush=True)  # fmt: skip
            result = world.plan(name, float(request["time"]))
            result["run"] = run
            runs.append(result)
    from importlib import metadata

    return {"validations": validations, "runs": runs, "ompl_version": metadata.version("ompl")}


class OmplWorld:
    """One scenario in OMPL 2.0.1 terms: a space, a validating and a planning SpaceInformation."""

    def __init__(self, definition: Mapping[str, Any], checker: BoxWorldChecker) -> None:
        from ompl import base as ob

        self.checker = checker
        self.dim = checker.dim
        self.start = [float(x) for x in definition["start"]]
        self.goal = [float(x) for x in definition["goal"]]
        self.space = ob.RealVectorStateSpace(self.dim)
        bounds = ob.RealVectorBounds(self.dim)
        for axis in range(self.dim):
            bounds.setLow(axis, float(checker.lower[axis]))
            bounds.setHigh(axis, float(checker.upper[axis]))
        self.space.setBounds(bounds)
        self.state_checker_class = _state_checker_class(checker, self.dim)
        # Re-validation: OMPL's default DiscreteMotionValidator over our state checker.
        self.check_si = self._space_information(motion_validator=False)
        self._keep: list[object] = []

    def _space_information(self, motion_validator: bool) -> Any:
        from ompl import base as ob

        si = ob.SpaceInformation(self.space)
        svc = self.state_checker_class(si)
        si.setStateValidityChecker(svc)
        si.setStateValidityCheckingResolution(self.checker.resolution)
        keep = [svc]
        if motion_validator:
            mv = _motion_validator_class(self.checker, self.dim)(si)
            si.setMotionValidator(mv)
            keep.append(mv)
        si.setup()
        self._keep = [*getattr(self, "_keep", []), *keep]  # the C++ side holds raw references
        return si

    def _state(self, si: Any, values: Sequence[float]) -> Any:
        state = si.allocState()
        for axis, value in enumerate(values):
            state[axis] = float(value)
        return state

    def validate(self, label: str, path: Sequence[Sequence[float]], cost: Any) -> dict[str, Any]:
        """Re-validate one path with OMPL 2.0.1's motion validator and the dense numpy check."""
        from ompl import geometric as og

        si = self.check_si
        states = [self._state(si, waypoint) for waypoint in path]
        first_invalid = None
        if not si.isValid(states[0]):
            first_invalid = 0
        else:
            for index in range(len(states) - 1):
                if not si.checkMotion(states[index], states[index + 1]):
                    first_invalid = index
                    break
        ompl_length = og.PathGeometric(si, states).length() if len(states) > 1 else 0.0
        dense = self.checker.check_path(path, self.start, self.goal)
        reported = _finite(cost)
        cost_matches = reported is not None and math.isclose(
            reported, ompl_length, rel_tol=COST_TOLERANCE, abs_tol=COST_TOLERANCE
        )
        valid = (first_invalid is None and dense["valid"] and dense["starts_at_start"]
                 and dense["ends_at_goal"] and cost_matches)  # fmt: skip
        return {
            "label": label,
            "valid": bool(valid),
            "ompl_motion_valid": first_invalid is None,
            "ompl_first_invalid_segment": first_invalid,
            "segments": len(states) - 1,
            "dense_valid": bool(dense["valid"]),
            "dense": dense,
            "length": ompl_length,
            "reported_cost": reported,
            "cost_matches": bool(cost_matches),
        }

    def plan(self, name: str, time_limit: float) -> dict[str, Any]:
        """One fresh run of an OMPL 2.0.1 planner; its costs over time and the validated path."""
        from ompl import base as ob
        from ompl import geometric as og

        si = self._space_information(motion_validator=True)
        pdef = ob.ProblemDefinition(si)
        pdef.setStartAndGoalStates(self._state(si, self.start), self._state(si, self.goal))
        pdef.setOptimizationObjective(ob.PathLengthOptimizationObjective(si))
        planner = getattr(og, PLANNERS[name])(si)
        planner.setProblemDefinition(pdef)
        planner.setup()
        improvements: list[tuple[float, float]] = []
        began = time.perf_counter()

        def should_stop() -> bool:
            elapsed = time.perf_counter() - began
            cost = planner.bestCost().value()
            if math.isfinite(cost) and (not improvements or cost < improvements[-1][1]):
                improvements.append((elapsed, cost))
            return elapsed >= time_limit

        status = planner.solve(ob.PlannerTerminationCondition(should_stop))
        elapsed = time.perf_counter() - began
        solved = bool(pdef.hasExactSolution())
        result: dict[str, Any] = {
            "planner": name,
            "ompl_class": PLANNERS[name],
            "status": status.asString(),
            "solved": solved,
            "time": elapsed,
            "t_init": None,
            "c_init": None,
            "c_final": None,
            "improvements": [list(item) for item in improvements],
            "validation": None,
        }
        if solved:
            solution = pdef.getSolutionPath()
            path = [[float(state[axis]) for axis in range(self.dim)]
                    for state in solution.getStates()]  # fmt: skip
            final = solution.length()
            if not improvements or final < improvements[-1][1]:
                improvements.append((elapsed, final))
            result.update(
                t_init=improvements[0][0],
                c_init=improvements[0][1],
                c_final=final,
                improvements=[list(item) for item in improvements],
                validation=self.validate(f"{name} run", path, final),
            )
            result["validation"]["path"] = path
        return result


def _state_checker_class(checker: BoxWorldChecker, dim: int) -> type:
    from ompl import base as ob

    class NumpyStateValidityChecker(ob.StateValidityChecker):  # type: ignore[misc]
        """OMPL 2.0.1 state validity through the numpy box-world checker."""

        def isValid(self, state: Any) -> bool:  # OMPL's method name
            return checker.is_state_valid(state[0:dim])

    return NumpyStateValidityChecker


def _motion_validator_class(checker: BoxWorldChecker, dim: int) -> type:
    from ompl import base as ob

    class NumpyMotionValidator(ob.MotionValidator):  # type: ignore[misc]
        """OMPL's discrete motion check at the resolution, decided by the numpy checker at once."""

        def checkMotion(self, s1: Any, s2: Any) -> bool:  # OMPL's method name
            return checker.motion_valid(s1[0:dim], s2[0:dim])

    return NumpyMotionValidator


def _finite(value: Any) -> float | None:
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    return number if math.isfinite(number) else None


if __name__ == "__main__":
    worker_main("crosscheck", handle)

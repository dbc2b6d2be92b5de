"""The search's fingerprints: exact results of a few fixed-iteration LIT* runs.

Speed-ups of the core (the neighbour scans, the cached edge lengths, the checker's grid of boxes)
must leave the search as it was, bit for bit: the same samples, neighbours, queue order, checks,
costs and decisions. These runs pin that down. A change that is meant to alter the search (a new
rule, different tie-breaking) changes them too, and so do new shipped tensors (the ``tensor``
runs): then check that the change is wanted and write the new values into
``search_fingerprints.json`` with
``.venv/bin/python lit_planner/test/test_search_fingerprints.py``.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import pytest
from lit_planner.planning import plan

ITERATIONS = 20_000
"""Enough for prunes and reverse-search restarts on all of them, under a second each."""

FINGERPRINTS_FILE = Path(__file__).with_name("search_fingerprints.json")
"""Per run key (scenario/policy/seed): its exact fingerprint (``fingerprint()``)."""


def fingerprint(key: str) -> dict[str, Any]:
    """Everything but timings of one run: costs as exact floats, every counter, the decisions and
    the path (as a digest of its coordinates' exact values)."""
    scenario, policy, seed = key.split("/")
    result = plan(scenario, "litstar", policy=policy, seed=int(seed), max_iterations=ITERATIONS)
    path = json.dumps(result["path"], allow_nan=True).encode()
    decisions = json.dumps([(d["kind"], d["value"]) for d in result["decisions"]]).encode()
    return {
        "c_init": result["c_init"],
        "cost": result["cost"],
        "iteration_init": result["iteration_init"],
        "checks_init": result["checks_init"],
        "counters": dict(sorted(result["counters"].items())),
        "decisions": hashlib.sha256(decisions).hexdigest()[:16],
        "path": hashlib.sha256(path).hexdigest()[:16],
    }


def recorded() -> dict[str, dict[str, Any]]:
    return json.loads(FINGERPRINTS_FILE.read_text())


@pytest.mark.parametrize("key", sorted(recorded()))
def test_the_search_is_as_it_was(key: str) -> None:
    expected = recorded()[key]
    assert expected["c_init"] is not None and expected["counters"]["prunes"] > 0  # a telling run
    assert fingerprint(key) == expected, (
        f"{key}: the search or the shipped tensors changed (see this module's docstring)"
    )


if __name__ == "__main__":
    FINGERPRINTS_FILE.write_text(
        json.dumps({key: fingerprint(key) for key in sorted(recorded())}, indent=1) + "\n"
    )
    print(f"wrote {FINGERPRINTS_FILE}")

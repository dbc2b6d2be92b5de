"""``docker/compose.yaml`` against the code it runs (no Docker engine here to run it): every node
it starts is one of ours with parameters the node declares and accepts, discovery stays on
loopback, and the planner waits for the learner as long as ``lit demo``'s does."""

from __future__ import annotations

from pathlib import Path

import yaml

from lit_learner import node as learner_node
from lit_planner import node as planner_node
from lit_planner import recorder

ROOT = Path(__file__).resolve().parents[2]
NODES = {
    ".venv/bin/lit_learner_node": (learner_node.PARAMETERS, learner_node.parameter_problem),
    ".venv/bin/lit_planner_node": (planner_node.PARAMETERS, planner_node.parameter_problem),
    ".venv/bin/lit_recorder_node": (recorder.PARAMETERS, None),
}


def _services() -> dict[str, dict]:
    return yaml.safe_load((ROOT / "docker" / "compose.yaml").read_text(encoding="utf-8"))[
        "services"
    ]


def _parameters(command: list[str], defaults: dict) -> dict:
    """The ``-p NAME:=VALUE`` of a node's command, typed as the defaults are."""
    given = {}
    for flag, assignment in zip(command[2::2], command[3::2], strict=True):
        assert flag == "-p", command
        name, value = assignment.split(":=", 1)
        assert name in defaults, f"{name} is not a parameter of {command[0]}"
        default = defaults[name]
        if isinstance(default, bool):
            given[name] = value == "true"
        else:
            given[name] = type(default)(value)
    return given


def test_every_node_in_compose_gets_parameters_it_declares_and_accepts() -> None:
    started = set()
    for name, service in _services().items():
        command = service["command"]
        if command[0] not in NODES:
            assert command == ["./lit", "test"], name
            continue
        started.add(command[0])
        assert command[1] == "--ros-args", name
        defaults, problem = NODES[command[0]]
        given = _parameters(command, defaults)
        if problem is not None:
            assert problem({**defaults, **given}) is None, name
        if name == "planner":
            assert given["learner_wait"] >= 120.0  # as lit demo's: torch starts slowly
    assert started == set(NODES)


def test_compose_keeps_discovery_on_loopback_and_the_nodes_on_one_host() -> None:
    text = (ROOT / "docker" / "compose.yaml").read_text(encoding="utf-8")
    anchor = yaml.safe_load(text)["x-lit"]
    assert anchor["environment"]["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    for name, service in _services().items():
        assert service["environment"]["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST", name
        if name in ("learner", "planner"):  # the recorder's loopback and shared memory
            assert service["network_mode"] == service["ipc"] == "service:recorder", name

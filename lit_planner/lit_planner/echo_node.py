"""A bare ``diagnostic_msgs/srv/AddDiagnostics`` server that answers every request with its own
text: the transport's floor for ``lit system-bench``, measured in the same run as the learner's
decide round trip (same message type, same executor kind as ``lit_learner_node``, no work).

Run: ``python -m lit_planner.echo_node --ros-args -p service:=/lit/bench/echo``.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any

from lit_planner.rosutil import spin_node

ECHO_SERVICE = "/lit/bench/echo"
"""Default service name."""


class EchoNode:
    """Owns the node; answers ``success = True`` and the request text."""

    def __init__(self) -> None:
        from diagnostic_msgs.srv import AddDiagnostics
        from rclpy.node import Node

        self.node = Node("lit_echo")
        self.node.declare_parameter("service", ECHO_SERVICE)
        name = self.node.get_parameter("service").value
        self.node.create_service(AddDiagnostics, name, self._serve)
        self.node.get_logger().info(f"ready: {name}")

    @staticmethod
    def _serve(request: Any, response: Any) -> Any:
        response.success = True
        response.message = request.load_namespace
        return response


def main(args: Sequence[str] | None = None) -> int:
    """Serve until SIGINT/SIGTERM (single-threaded executor, like the learner)."""
    return spin_node(EchoNode, sys.argv if args is None else args, threads=1)


if __name__ == "__main__":
    sys.exit(main())

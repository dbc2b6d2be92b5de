"""A bare ``diagnostic_msgs/srv/AddDiagnostics`` server that answers every request with its own
text: the transport's floor for ``lit system-bench``, measured in the same run as the learner's
decide round trip (same message type, served the same way as ``lit_learner_node``'s decide:
a :class:`~lit_planner.rosutil.DirectService`; no work).

Run: ``python -m lit_planner.echo_node --ros-args -p service:=/lit/bench/echo``.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any

from lit_planner.rosutil import DirectService, spin_node

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
        self._service = DirectService(
            self.node, "lit_echo_service", AddDiagnostics, name, self._serve
        )
        self.node.get_logger().info(f"ready: {name}")

    def shutdown(self) -> None:
        """Stop serving (before the node goes)."""
        self._service.shutdown()

    @staticmethod
    def _serve(request: Any, response: Any) -> Any:
        response.success = True
        response.message = request.load_namespace
        return response


def main(args: Sequence[str] | None = None) -> int:
    """Serve until SIGINT/SIGTERM."""
    return spin_node(EchoNode, sys.argv if args is None else args, threads=1)


if __name__ == "__main__":
    sys.exit(main())

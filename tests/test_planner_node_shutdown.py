"""The planner node's shutdown while its episodes thread still waits for the learner service.

The node runs in a child process of its own (rclpy's global state stays out of pytest's), in a ROS
domain of its own; ``shutdown()`` is called directly, as ``spin_node`` calls it on SIGTERM.
"""

from __future__ import annotations

import textwrap

from ros_helpers import run_node_script

SCRIPT = textwrap.dedent(
    """
    import json, time
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    rclpy.init(args=["--ros-args", "-p", "policy:=training", "-p", "episodes:=1",
                     "-p", "learner_wait:=30.0", "-p", "learner_service:=/nobody/decide"],
               signal_handler_options=SignalHandlerOptions.NO)
    from lit_planner import rosutil
    from lit_planner.node import PlannerNode

    planner = PlannerNode()
    time.sleep(1.0)  # its episodes thread waits for a learner that never comes
    out = {"waiting": planner._driver.is_alive()}
    planner.shutdown()
    out["driver_after_shutdown"] = planner._driver.is_alive()
    time.sleep(1.0)  # a wait still polling the destroyed client raised InvalidHandle by now
    out["failed"] = rosutil._FAILED.is_set()
    planner.node.destroy_node()
    rclpy.shutdown()
    print("RESULT " + json.dumps(out))
    """
)


def test_a_shutdown_while_the_episodes_wait_for_the_learner_is_clean() -> None:
    """The shutdown destroyed the learner client while the episodes thread was still waiting
    for the service on it: the next poll raised InvalidHandle, the thread's traceback was
    printed and the node exited 1 after a clean Ctrl-C (when the rest of the shutdown took
    longer than the poll). The wait now ends on the shutdown, which joins the thread first."""
    process, out = run_node_script(SCRIPT)
    assert out == {"waiting": True, "driver_after_shutdown": False, "failed": False}, (
        out,
        process.stderr[-3000:],
    )
    assert "InvalidHandle" not in process.stderr and "Traceback" not in process.stderr

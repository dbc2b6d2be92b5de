"""A planner node client of your own: plain rclpy, no lit package.

Sends one PlanRequest to ``<ns>/lit/planner/plan`` and prints the answer's payload as JSON. When
no answer comes within ``--timeout`` it cancels the request (``<ns>/lit/planner/cancel``); the
plan service then answers with what the planner found until then (status ``cancelled``).

    python3 lit_planner/examples/plan_client.py --scenario np8 --time 0.5

It keeps DDS discovery on this host and uses ROS domain 42, as ``lit up`` and the nodes do,
unless ``ROS_AUTOMATIC_DISCOVERY_RANGE`` or ``ROS_DOMAIN_ID`` say otherwise.

Exit status: 0 with a PlanResponse, 1 with an Error (the node's verdict on the request), 2 when
no planner node answered. The README's "Your own client" says what each part is for.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import uuid

import rclpy
from diagnostic_msgs.srv import AddDiagnostics
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

# Every client of a service receives every answer of its server and takes out its own: with
# ROS's default history of 10, an answer is lost for good once more than ten answers to other
# clients came in before this client read its own.
SERVICE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1000,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)


def local_environment(environ: dict[str, str] | os._Environ[str] = os.environ) -> None:
    """This project's defaults for a ROS process, where the environment gives none: discovery
    on this host only (Fast DDS's own default sends multicast on every interface) and domain 42,
    where ``lit up`` and the nodes run by default (ROS's default, 0, would not find them)."""
    for name, default in (("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST"), ("ROS_DOMAIN_ID", "42")):
        if not environ.get(name, "").strip():  # set but empty: ROS takes its own default
            environ[name] = default


class Envelopes:
    """The JSON envelope around every payload; ``seq`` rises by one per message sent."""

    def __init__(self, source: str) -> None:
        self.source, self.run_id, self.seq = source, f"client-{uuid.uuid4().hex[:12]}", 0

    def text(self, schema: str, version: int, payload: dict) -> str:
        envelope = {
            "schema": f"lit_msgs_json/{schema}",
            "version": version,
            "seq": self.seq,
            "stamp_ns": time.time_ns(),
            "source": self.source,
            "run_id": self.run_id,
            "payload": payload,
        }
        self.seq += 1
        return json.dumps(envelope, allow_nan=False)


def call(node, client, text: str, timeout: float):
    """The service's answer ``(success, envelope dict)``, or None after ``timeout`` s."""
    request = AddDiagnostics.Request()
    request.load_namespace = text
    future = client.call_async(request)
    rclpy.spin_until_future_complete(node, future, timeout_sec=timeout)
    if not future.done():
        return None, future
    response = future.result()
    return (response.success, json.loads(response.message)), future


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--namespace", default="", help="the planner node's namespace")
    parser.add_argument("--scenario", default="np8")
    parser.add_argument("--time", type=float, default=0.5, help="planning time, s")
    parser.add_argument(
        "--timeout",
        type=float,
        help="wait this long for the answer, then cancel (default: time + 30 s)",
    )
    args = parser.parse_args(argv)

    local_environment()  # read by rclpy.init
    rclpy.init()
    node = rclpy.create_node(f"plan_client_{uuid.uuid4().hex[:8]}")
    prefix = args.namespace.rstrip("/")
    plan = node.create_client(AddDiagnostics, f"{prefix}/lit/planner/plan", qos_profile=SERVICE_QOS)
    cancel = node.create_client(
        AddDiagnostics, f"{prefix}/lit/planner/cancel", qos_profile=SERVICE_QOS
    )
    try:
        # Both: the node serves cancel from a node of its own, which a client matches on its own.
        if not (
            plan.wait_for_service(timeout_sec=15.0) and cancel.wait_for_service(timeout_sec=15.0)
        ):
            print("no planner node serves the plan and cancel services", file=sys.stderr)
            return 2
        envelopes = Envelopes("my_robot")
        request_id = str(uuid.uuid4())  # a fresh id per request: cancels name it
        payload = {"scenario": args.scenario, "time": args.time, "request_id": request_id}
        timeout = args.time + 30.0 if args.timeout is None else args.timeout
        answer, future = call(node, plan, envelopes.text("PlanRequest", 1, payload), timeout)
        if answer is None:  # gave up waiting: stop the query, then read what it found
            stop = {"request_id": request_id}
            cancelled, _ = call(node, cancel, envelopes.text("CancelRequest", 1, stop), 10.0)
            said = "no answer" if cancelled is None else cancelled[1]["payload"]["message"]
            print(f"gave up after {timeout:g} s; cancel: {said}", file=sys.stderr)
            rclpy.spin_until_future_complete(node, future, timeout_sec=10.0)
            if not future.done():
                print("no answer", file=sys.stderr)
                return 2
            response = future.result()
            answer = response.success, json.loads(response.message)
        success, envelope = answer
        print(json.dumps(envelope["payload"]))
        return 0 if success else 1
    finally:
        node.destroy_node()
        rclpy.shutdown()


if __name__ == "__main__":
    sys.exit(main())

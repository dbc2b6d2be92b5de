"""``lit_recorder_node``: records every ``/lit/*`` topic of a run into a rosbag2 MCAP bag.

Subscribes with the publishers' QoS (reliable, keep-all: reliable keep-last drops in bursts) to the
root namespace's contract topics at start and to every other topic whose name contains ``/lit/``
(planners in namespaces, e.g. ``/robot1/lit/episode``) as soon as discovery shows it. Messages
arrive serialized (``raw=True``) and go into the bag unchanged, stamped with their receive time, so
the recorder never parses or re-encodes anything. The bag (``BagRecorder``: rosbag2 version 9,
MCAP, run metadata in ``custom_data``) is closed on SIGTERM/SIGINT, which writes its
``metadata.yaml``. The open chunk is written out when it holds ``chunk_bytes`` and every
``FLUSH_PERIOD`` s, so a crash loses at most one chunk of a busy stream or the last second of a
quiet one; ``lit replay salvage`` recovers the rest.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from lit_planner.rosutil import STATS_TOPIC, TOPICS, declare_parameters, json_qos, spin_node

NODE_NAME = "lit_recorder"
PARAMETERS: dict[str, Any] = {"bag": "", "run_id": "", "chunk_bytes": 64 * 1024}
"""The node's ROS parameters and their defaults: the bag folder (default
``bags/<run_id>``), the run id (default ``run-<date>-<time>``), the chunk size in bytes."""
TYPES = {
    "std_msgs/msg/String": ("std_msgs.msg", "String"),
    "trajectory_msgs/msg/JointTrajectory": ("trajectory_msgs.msg", "JointTrajectory"),
}
"""Topic types the recorder takes (the contract's)."""
DISCOVERY_PERIOD = 0.5
"""Seconds between scans of the ROS graph for new ``/lit/`` topics."""
FLUSH_PERIOD = 1.0
"""Seconds between writes of the open chunk to the file. Only full chunks were written: a killed
recorder of a quiet run (a few episodes, the learner's stats) lost everything it had received."""
DRAIN_QUIET = 1.0
"""On shutdown, the bag closes once no message has arrived for this many seconds (the executor
still delivers what the readers hold: a burst published just before the signal)."""
DRAIN_LIMIT = 5.0
"""The longest shutdown waits for messages to stop arriving (a publisher that never stops)."""


class Recorder:
    """Owns the node and the bag."""

    def __init__(self) -> None:
        import importlib

        from rclpy.node import Node

        from lit_planner.bag import BagError, BagRecorder, default_bag_root, unique_directory

        self.node = node = Node(NODE_NAME)
        self.log = node.get_logger()
        p = declare_parameters(node, PARAMETERS, "lit_recorder_node")
        run_id = p["run_id"] or time.strftime("run-%Y%m%d-%H%M%S")
        # An explicit bag folder that exists is refused (BagRecorder); the default one, named
        # after the run id, takes a free name (<run_id>-2, ...): a second `docker compose up`
        # with the same run id failed at start.
        bag = p["bag"] or str(unique_directory(default_bag_root(), run_id))
        try:
            self.bag = BagRecorder(
                Path(bag),
                run_id=run_id,
                metadata={"lit.recorder": "lit_recorder_node"},
                chunk_bytes=p["chunk_bytes"],
            )
        except (BagError, OSError) as exc:  # a bag folder that exists, a bad chunk size
            raise SystemExit(f"lit_recorder_node: error: {exc}") from None
        self._importlib = importlib
        self._lock = threading.Lock()
        self._subscriptions: dict[str, Any] = {}
        self._closing = False
        self.counts: dict[str, int] = {}
        self.dropped = 0
        """Messages that arrived after the bag was closed (after the drain: not recorded), or
        after a write failed."""
        self.write_error: OSError | None = None
        """The first write of the bag that failed (a full disk): recording stopped there, and the
        node stops (``finished``, exit 1)."""
        self.finished = False
        self.exit_code = 0
        self._foreign: set[tuple[str, str]] = set()
        """(topic, type) pairs under /lit/ of a type not recorded (warned of once)."""
        for name in TOPICS.values():
            topic = "/" + name
            self._subscribe(topic, _topic_type(name))
        self._subscribe(STATS_TOPIC, "std_msgs/msg/String")
        node.create_timer(DISCOVERY_PERIOD, self._discover)
        node.create_timer(FLUSH_PERIOD, self._flush)
        self.log.info(f"ready: recording /lit/ topics to {self.bag.path}")

    def _subscribe(self, topic: str, msgtype: str) -> None:
        with self._lock:
            if self._closing or topic in self._subscriptions or msgtype not in TYPES:
                return
            module, name = TYPES[msgtype]
            cls = getattr(self._importlib.import_module(module), name)
            self.bag.add_topic(topic, msgtype, qos="reliable-keep-all")
            self.counts[topic] = 0
            self._subscriptions[topic] = self.node.create_subscription(
                cls, topic, lambda data, t=topic: self._write(t, data), json_qos(), raw=True
            )

    def _discover(self) -> None:
        for topic, types in self.node.get_topic_names_and_types():
            if "/lit/" in topic or topic.startswith("/lit/"):
                for msgtype in types:
                    if msgtype in TYPES:
                        self._subscribe(topic, msgtype)
                    elif (topic, msgtype) not in self._foreign:
                        # An Int32 publisher on /lit/episode went unrecorded without a word.
                        self._foreign.add((topic, msgtype))
                        self.log.warning(
                            f"{topic} has a publisher of {msgtype}, a type the recorder does not "
                            f"take ({', '.join(TYPES)}): its messages are not recorded"
                        )

    def _write(self, topic: str, data: bytes) -> None:
        from lit_planner.bag import BagError

        if self.write_error is not None:
            with self._lock:
                self.dropped += 1
            return
        try:
            self.bag.write_raw(topic, bytes(data), time.time_ns())
        except BagError:
            if not self.bag.closed:
                raise
            with self._lock:
                self.dropped += 1  # after the drain: counted, not a traceback in the executor
            return
        except OSError as exc:
            self._write_failed(exc)
            return
        with self._lock:
            self.counts[topic] += 1

    def _flush(self) -> None:
        if self.write_error is not None:
            return
        try:
            self.bag.flush()
        except OSError as exc:
            self._write_failed(exc)

    def _write_failed(self, exc: OSError) -> None:
        """Stop recording after the first failed write (a full disk), say so in one line, and
        stop the node (exit 1): what is in the file stays readable with ``lit replay salvage``."""
        with self._lock:
            if self.write_error is not None:
                self.dropped += 1
                return
            self.write_error = exc
            self.dropped += 1
        self.log.error(
            f"cannot write the bag {self.bag.path}: {exc.strerror or exc}; recording stopped "
            f"and the recorder exits (1). What was written before reads with `lit replay "
            f"salvage {self.bag.path}`"
        )
        self.exit_code = 1
        self.finished = True

    def _received(self) -> int:
        with self._lock:
            return sum(self.counts.values())

    def shutdown(self) -> None:
        """Write what has arrived, then close the bag (writes metadata.yaml) and log what it
        holds. The executor still runs here: messages the readers already hold (a burst sent
        just before the signal; `ros2 launch` and compose stop every node at once) are written
        until none has arrived for ``DRAIN_QUIET`` s (long enough for an executor starved of the
        CPU for a moment), at most ``DRAIN_LIMIT`` s; closing at once lost them (851 of 2000
        acknowledged messages recorded)."""
        deadline = time.monotonic() + DRAIN_LIMIT
        seen = self._received()
        while time.monotonic() < deadline:
            time.sleep(DRAIN_QUIET)
            now = self._received()
            if now == seen:
                break
            seen = now
        with self._lock:
            self._closing = True
            subscriptions = list(self._subscriptions.values())
        for subscription in subscriptions:
            self.node.destroy_subscription(subscription)
        try:
            self.bag.close()
        except OSError as exc:
            if self.write_error is None:
                raise
            self.log.error(
                f"the bag {self.bag.path} could not be closed either ({exc.strerror or exc}): "
                f"it is left unfinished; `lit replay salvage {self.bag.path}` reads it"
            )
            return
        total = self._received()
        after = "after a write failed" if self.write_error is not None else "after it closed"
        dropped = f"; {self.dropped} arrived {after}" if self.dropped else ""
        self.log.info(
            f"closed {self.bag.path}: {total} messages on "
            f"{sum(1 for n in self.counts.values() if n)} topics{dropped}"
        )


def _topic_type(name: str) -> str:
    return (
        "trajectory_msgs/msg/JointTrajectory" if name.endswith("/path") else "std_msgs/msg/String"
    )


def main(args: Sequence[str] | None = None) -> int:
    """Console script ``lit_recorder_node`` (``--ros-args -p bag:=DIR -p run_id:=ID``)."""
    return spin_node(Recorder, sys.argv if args is None else args, threads=2)


if __name__ == "__main__":
    sys.exit(main())

"""Recording at the system's peak rate loses nothing: the bag accounts for every ``seq``.

A real ``lit_recorder_node`` and a real ``lit_planner_node`` (tensor policy, psi_K decided at
every expansion, np8 with a 0.5 s budget: the densest stream of observations and decisions the
planner publishes, in bursts after every query) on their own ROS domain. The planner holds its
episodes until the recorder is subscribed (``wait_for_subscribers``). Afterwards the bag must hold,
for every publisher, an unbroken run of ``seq`` from 0, and exactly as many observations and
decisions as the episodes' summaries say were made.
"""

from __future__ import annotations

import contextlib
import re
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from lit_planner.up import Child, System
from ros_helpers import reserve_domain

from lit_planner import replay

EPISODES = 4


@contextlib.contextmanager
def _recording(
    bag: Path, run_id: str, command: str | list[str] = "lit_recorder_node"
) -> Iterator[tuple[System, Child, dict[str, int | None]]]:
    """A real recorder (``command``) into ``bag`` on a domain of its own, ready; on the way out
    every process is stopped by its PID and the exit codes go into the dict it yields."""
    domain, lock = reserve_domain()
    system = System(domain, bag.parent, echo=None)
    codes: dict[str, int | None] = {}
    try:
        recorder = system.start("recorder", command, {"bag": str(bag), "run_id": run_id})
        system.wait_ready("recorder")
        yield system, recorder, codes
    finally:
        codes.update(system.stop())
        if lock is not None:
            lock.close()


def _publish_acked(system: System, count: int) -> None:
    """Publish ``count`` messages on /lit/observation from another process (a real publisher
    with the contract's QoS) and return once every subscriber acknowledged them all."""
    import sys

    import ros_helpers

    publisher = system.start(
        "publisher",
        [sys.executable, ros_helpers.__file__, "publish", "/lit/observation", str(count)],
    )
    deadline = time.monotonic() + 120.0
    while not any(line.startswith(("acked", "not acked")) for line in publisher.lines):
        assert publisher.process.poll() is None, "\n".join(publisher.lines[-30:])
        assert time.monotonic() < deadline, "\n".join(publisher.lines[-30:])
        time.sleep(0.01)
    assert "acked" in publisher.lines, publisher.lines


def test_recorder_keeps_every_message_at_peak_rate(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    with _recording(bag, "peak") as (system, recorder, codes):
        planner = system.start(
            "planner",
            "lit_planner_node",
            {
                "policy": "tensor",
                "scenario": "np8",
                "episodes": EPISODES,
                "time_budget": 0.5,
                "decision_interval": 1,
                "exit_when_done": True,
                "wait_for_subscribers": 1,
                "learner_wait": 60.0,
                "run_id": "peak",
            },
        )
        assert planner.process.wait(300) == 0, "\n".join(planner.lines[-30:])
    assert codes["recorder"] == 0, "\n".join(recorder.lines[-30:])

    info = replay.bag_info(bag)
    planner_accounts = [p for p in info["publishers"] if p["source"] == "/lit_planner"]
    assert {p["topic"] for p in planner_accounts} == {
        "/lit/observation", "/lit/decision", "/lit/solution", "/lit/episode",
    }  # fmt: skip
    for account in planner_accounts:
        assert account["leading"] == 0, account  # recording started with seq 0
        assert account["missing"] == 0 and account["gaps"] == 0, account
        assert account["duplicates"] == 0 and account["reused"] == 0, account

    skipped = replay.Skipped()
    summaries = []
    with replay.BagReader(bag) as reader:
        for message in reader.messages():
            item = replay.decode(message, skipped)
            if isinstance(item, replay.Envelope) and item.topic == "/lit/episode":
                summaries.append(item.payload)
    assert len(summaries) == EPISODES
    decisions = sum(s["decisions"]["B"] + s["decisions"]["psi_K"] for s in summaries)
    assert decisions > 100  # the stream is dense, not a trickle
    counts = {topic["topic"]: topic["messages"] for topic in info["topics"]}
    assert counts["/lit/observation"] == decisions
    assert counts["/lit/decision"] == decisions
    assert counts["/lit/path"] == EPISODES
    assert counts["/lit/solution"] == sum(s["improvements"] for s in summaries)


def test_training_run_bag_gives_deterministic_offline_tensors(tmp_path: Path) -> None:
    """Record a real training run (recorder, learner, planner), then ``lit replay tensors``:
    the same bag and seed give identical tensors, another seed other ones."""
    import subprocess
    import sys

    import numpy as np

    domain, lock = reserve_domain()
    bag = tmp_path / "bag"
    system = System(domain, tmp_path, echo=None)
    try:
        system.start("recorder", "lit_recorder_node", {"bag": str(bag), "run_id": "train"})
        system.wait_ready("recorder")
        system.start(
            "learner",
            "lit_learner_node",
            {"checkpoint": str(tmp_path / "ck.pt"), "export_dir": str(tmp_path / "online")},
        )
        planner = system.start(
            "planner",
            "lit_planner_node",
            {
                "policy": "training",
                "episodes": 3,
                "time_budget": 0.2,
                "training_scenarios": "np4,rrd4",
                "decision_timeout": 1.0,
                "exit_when_done": True,
                "wait_for_subscribers": 1,
                "learner_wait": 120.0,
                "run_id": "train",
            },
        )
        assert planner.process.wait(300) == 0, "\n".join(planner.lines[-30:])
    finally:
        codes = system.stop()
        if lock is not None:
            lock.close()
    assert codes["recorder"] == 0

    def offline(out: Path, seed: int, *options: str) -> str:
        process = subprocess.run(
            [
                sys.executable, "-m", "lit_planner.cli", "replay", "tensors", str(bag),
                "--out", str(out), "--seed", str(seed), "--warmup", "16", "--batch-size", "16",
                *options,
            ],
            capture_output=True, text=True, timeout=600, check=False,
        )  # fmt: skip
        assert process.returncode == 0, process.stderr
        return process.stdout

    first = offline(tmp_path / "a", 3)
    assert "3 episodes" in first
    version = int(re.findall(r"policy version (\d+)$", first, re.MULTILINE)[0])
    assert re.search(r"^  messages: \d+ skipped", first, re.MULTILINE), first
    assert version > 0  # gradient steps ran on the recorded transitions
    from lit_planner import tensor_files

    exported = []
    for agent, name in (("B", "b_tensor.npy"), ("psi_K", "k_tensor.npy")):
        (line,) = [x for x in first.splitlines() if x.startswith(f"  {agent}: ")]
        if (tmp_path / "a" / name).exists():  # only an agent that made a gradient step
            assert tensor_files.read_tensor(tmp_path / "a" / name)[1].training["updates"] > 0
            assert line == f"  {agent}: {tmp_path / 'a' / name}", line
            exported.append(name)
        else:
            assert line.startswith(f"  {agent}: no tensor (no gradient update yet: "), line
    assert exported, first
    offline(tmp_path / "b", 3)
    offline(tmp_path / "c", 4)
    for name in exported:
        a, b, c = (np.load(tmp_path / run / name) for run in ("a", "b", "c"))
        assert np.array_equal(a, b), name
        assert not np.array_equal(a, c), name
    # One agent trained: only its tensor (the other's initial actor was exported too, and the
    # tensor policy played it: psi_K about 9 instead of the fixed e). An earlier export's cannot
    # be left beside it: --out must be a new or empty folder.
    b_only = offline(tmp_path / "b-only", 3, "--train", "B", "--warmup", "1", "--batch-size", "1")
    assert (tmp_path / "b-only" / "b_tensor.npy").is_file()
    assert not list((tmp_path / "b-only").glob("k_tensor.*"))
    assert (
        "  psi_K: no tensor (this run does not train it); the tensor policy keeps its fixed "
        "value (psi_K = e)" in b_only
    ), b_only
    # No agent trained: an error, and nothing written.
    refused = subprocess.run(
        [
            sys.executable, "-m", "lit_planner.cli", "replay", "tensors", str(bag),
            "--out", str(tmp_path / "none"), "--warmup", "100000",
        ],
        capture_output=True, text=True, timeout=600, check=False,
    )  # fmt: skip
    assert refused.returncode != 0 and refused.stdout == "", refused
    assert (
        "no agent made a gradient update, so there is no tensor to export (B: no gradient "
        "update yet: " in refused.stderr
    ), refused.stderr
    assert "nothing was written" in refused.stderr and "Traceback" not in refused.stderr
    assert not (tmp_path / "none").exists()


def test_recorder_writes_what_it_received_before_it_stops(tmp_path: Path) -> None:
    """SIGTERM right after a burst that every subscriber acknowledged: the bag holds all of it.
    The recorder closed its bag while the executor still held the burst (851 of 2000 messages
    recorded, a BagError traceback for the rest); `ros2 launch` and compose stop every node at
    once, so the end of a run was lost."""
    import os
    import signal

    burst = 2000
    bag = tmp_path / "bag"
    with _recording(bag, "burst") as (system, recorder, codes):
        _publish_acked(system, burst)
        os.kill(recorder.process.pid, signal.SIGTERM)  # our own child, by its PID
        assert recorder.process.wait(60) == 0, "\n".join(recorder.lines[-30:])
    assert codes["recorder"] == 0
    assert not any("Traceback" in line for line in recorder.lines), recorder.lines[-30:]
    counts = {topic["topic"]: topic["messages"] for topic in replay.bag_info(bag)["topics"]}
    assert counts["/lit/observation"] == burst


def test_a_killed_recorder_of_a_quiet_run_loses_nothing_written_a_second_before(
    tmp_path: Path,
) -> None:
    """Twenty messages, far from a full chunk: the recorder writes its open chunk every second,
    so the file holds them while it runs and a SIGKILL loses none (only full 64 KiB chunks were
    written: the .mcap stayed empty, and salvage found nothing)."""
    import os
    import signal

    count = 20
    bag = tmp_path / "bag"
    with _recording(bag, "quiet") as (system, recorder, _):
        _publish_acked(system, count)
        deadline = time.monotonic() + 120.0
        found: dict[str, int] = {}
        attempt = 0
        while found.get("/lit/observation") != count:  # read while it runs, as after a crash
            assert recorder.process.poll() is None, "\n".join(recorder.lines[-30:])
            assert time.monotonic() < deadline, (found, "\n".join(recorder.lines[-30:]))
            time.sleep(0.2)
            attempt += 1
            try:
                _, results = replay.salvage(bag, tmp_path / f"read-{attempt}")
            except replay.ReplayError:
                continue  # nothing in the file yet
            found = results[0].messages
        os.kill(recorder.process.pid, signal.SIGKILL)  # our own child, by its PID
        recorder.process.wait(60)
    salvaged, results = replay.salvage(bag, tmp_path / "salvaged")
    assert results[0].messages == {"/lit/observation": count}
    assert not (bag / "metadata.yaml").exists()  # it did not close the bag: killed
    assert replay.bag_info(salvaged)["custom_data"]["lit.run_id"] == "quiet"  # its metadata too


def test_a_lit_topic_of_a_type_the_recorder_does_not_take_is_named(tmp_path: Path) -> None:
    """An Int32 publisher on /lit/episode went unrecorded without a word."""
    import sys

    script = (
        "import rclpy, time\n"
        "from std_msgs.msg import Int32\n"
        "rclpy.init()\n"
        "node = rclpy.create_node('int_publisher')\n"
        "publisher = node.create_publisher(Int32, '/lit/episode', 10)\n"
        "for i in range(600):\n"
        "    publisher.publish(Int32(data=i))\n"
        "    time.sleep(0.1)\n"
    )
    warning = "/lit/episode has a publisher of std_msgs/msg/Int32, a type the recorder does not"
    with _recording(tmp_path / "bag", "foreign") as (system, recorder, _):
        publisher = system.start("int-publisher", [sys.executable, "-c", script])
        deadline = time.monotonic() + 60.0
        while not any(warning in line for line in recorder.lines):
            assert publisher.process.poll() is None, "\n".join(publisher.lines[-30:])
            assert time.monotonic() < deadline, "\n".join(recorder.lines[-30:])
            time.sleep(0.1)
    assert sum(warning in line for line in recorder.lines) == 1  # once, not every scan


def test_a_full_disk_stops_the_recorder_with_one_line(tmp_path: Path) -> None:
    """A bag write that failed (a full disk) ended the recorder's executor in a long traceback,
    a second one from closing the bag and "exception was never retrieved"; now one line names the
    bag and `lit replay salvage`, and the recorder exits 1."""
    import sys

    import ros_helpers
    from lit_planner.up import _script

    limit = ros_helpers.file_size_limited(16 * 1024, _script("lit_recorder_node"))
    bag = tmp_path / "bag"
    with _recording(bag, "full", limit) as (system, recorder, codes):
        system.start(
            "publisher",
            [sys.executable, ros_helpers.__file__, "publish", "/lit/observation", "2000"],
        )
        assert recorder.process.wait(120) == 1, "\n".join(recorder.lines[-30:])
    output = "\n".join(recorder.lines)
    assert f"cannot write the bag {bag}: File too large; recording stopped" in output, output
    assert "Traceback" not in output and "never retrieved" not in output, output
    assert codes["recorder"] == 1


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (["-p", "bag:=EXISTING"], "exists already"),
        (["-p", "chunk_bytes:=0"], "chunk_bytes must be within 1..1048576, got 0"),
        (["-p", "chunk_bytes:=abc"], "parameter chunk_bytes takes a whole number"),
        (["-p", "bag:=NEW", "-p"], "Couldn't parse trailing -p flag"),  # rcl's words, one line
    ],
)
def test_the_recorder_refuses_bad_parameters_in_one_line(
    tmp_path: Path, arguments: list[str], message: str
) -> None:
    """A bag folder that exists, a bad chunk size or ROS arguments rcl cannot parse ended `ros2
    run`'s or compose's recorder in a Python traceback; now one line names the problem (exit 1),
    as the other nodes do."""
    import os
    import subprocess
    import sys

    arguments = [
        a.replace("EXISTING", str(tmp_path)).replace("NEW", str(tmp_path / "new"))
        for a in arguments
    ]
    if not any(a.startswith("bag:=") for a in arguments):
        arguments += ["-p", f"bag:={tmp_path / 'new'}"]
    domain, lock = reserve_domain()
    try:
        result = subprocess.run(
            [str(Path(sys.executable).parent / "lit_recorder_node"), "--ros-args", *arguments],
            env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
                     ROS_DOMAIN_ID=str(domain)),
            capture_output=True, text=True, timeout=120, check=False,
        )  # fmt: skip
    finally:
        if lock is not None:
            lock.close()
    assert result.returncode == 1, result.stderr
    assert message in result.stderr and "lit_recorder_node" in result.stderr, result.stderr
    assert "Traceback" not in result.stderr
    assert not (tmp_path / "new").exists()

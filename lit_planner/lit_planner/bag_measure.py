"""``lit replay measure``: how fast :class:`~lit_planner.bag.BagRecorder` writes, and what a crash
costs.

- **Write rate**: ``--messages`` envelopes of about 1 KiB written with ``write_string`` into a new
  bag, timed from the first write to the end of ``close()`` (metadata.yaml included; opening the
  bag is not timed).
- **Crash loss**: ``--kills`` times, a writer process writes envelopes as fast as it can and
  reports each returned ``write_string``; after a random number of confirmed messages
  (200 … 3000) it is killed with SIGKILL while it writes on, the reports it made before it died
  are read to the end (the confirmed count), the bag is salvaged
  (:func:`lit_planner.replay.salvage`) and the loss is confirmed minus recovered. The bound is one
  chunk (``--chunk-bytes``; :func:`messages_per_chunk`).
"""

from __future__ import annotations

import argparse
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

PAYLOAD_BYTES = 900
"""Filler per message; with the envelope the text is about 1 KiB."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``lit replay measure``."""
    from lit_planner.bag import DEFAULT_CHUNK_BYTES

    parser.add_argument(
        "--messages", type=int, default=100_000, help="write-rate messages (default: %(default)s)"
    )
    parser.add_argument(
        "--kills", type=int, default=5, help="crash trials (SIGKILL; default: %(default)s)"
    )
    parser.add_argument(
        "--chunk-bytes",
        type=int,
        default=DEFAULT_CHUNK_BYTES,
        help="bag chunk size (default: %(default)s)",
    )
    parser.add_argument(
        "--seed", type=int, default=1, help="seed of the kill points (default: %(default)s)"
    )


def run(args: argparse.Namespace) -> int:
    """Measure and print both; 0 when every crash lost at most one chunk."""
    with tempfile.TemporaryDirectory(prefix="lit-bag-measure-") as folder:
        rate = write_rate(Path(folder) / "rate", args.messages, args.chunk_bytes)
        print(
            f"write rate: {args.messages} messages of {_text_bytes()} bytes in "
            f"{args.messages / rate:.3f} s = {rate:,.0f} messages/s "
            f"(chunk {args.chunk_bytes} bytes)",
            flush=True,  # progress, also through a pipe
        )
        per_chunk = messages_per_chunk(args.chunk_bytes)
        rng = random.Random(args.seed)
        losses = []
        for trial in range(args.kills):
            target = rng.randint(200, 3000)
            confirmed, recovered = crash_trial(
                Path(folder) / f"kill{trial}", target, args.chunk_bytes
            )
            # A write can return and be killed before its report: one more recovered than
            # confirmed is a write that was not lost, not a negative loss.
            losses.append(max(0, confirmed - recovered))
            unreported = (
                f" ({recovered - confirmed} written after the last report)"
                if recovered > confirmed
                else ""
            )
            print(
                f"crash {trial + 1}/{args.kills}: SIGKILL after {confirmed} confirmed writes, "
                f"{recovered} recovered, {losses[-1]} lost{unreported}",
                flush=True,
            )
    if losses:
        print(
            f"crash loss: min {min(losses)}, max {max(losses)} messages over {len(losses)} kills "
            f"(bound: one chunk, about {per_chunk} messages of this size)"
        )
    return 0 if all(loss <= per_chunk for loss in losses) else 1


def write_rate(path: Path, messages: int, chunk_bytes: int) -> float:
    """Messages per second through ``BagRecorder.write_string``, ``close()`` included."""
    from lit_planner.bag import BagRecorder

    texts = [_text(seq) for seq in range(1000)]  # prepared outside the timing, then cycled
    # Opened outside the timing too: the first bag of a process costs about 75 ms of imports and
    # type registration (a review helper's one-off), which halved the rate of a short run.
    with BagRecorder(path, run_id="measure", chunk_bytes=chunk_bytes) as recorder:
        recorder.add_topic("/lit/observation", "std_msgs/msg/String")
        started = time.perf_counter()
        for seq in range(messages):
            recorder.write_string("/lit/observation", texts[seq % 1000], time.time_ns())
    return messages / (time.perf_counter() - started)


def messages_per_chunk(chunk_bytes: int) -> int:
    """The most of these messages one chunk holds: a chunk is written once its records reach
    ``chunk_bytes``, and each record is the serialized message plus MCAP's 31 bytes of message
    header (the text alone gave 62 for 64 KiB, where chunks hold 60)."""
    from lit_planner.bag import STRING_TYPE, typestore

    store = typestore()
    message = store.types[STRING_TYPE](data=_text(0))
    record = len(store.serialize_cdr(message, STRING_TYPE)) + 31
    return -(-chunk_bytes // record)


def crash_trial(path: Path, target: int, chunk_bytes: int) -> tuple[int, int]:
    """Kill a writer after ``target`` confirmed messages; (confirmed, recovered by salvage)."""
    from lit_planner.replay import salvage

    child = subprocess.Popen(
        [sys.executable, "-m", "lit_planner.bag_measure", "--writer", str(path)],
        stdout=subprocess.PIPE,
        text=True,
        env=dict(os.environ, LIT_CHUNK_BYTES=str(chunk_bytes)),
        # Out of the terminal's process group: a Ctrl-C reaches the measurement, which kills
        # the writer, instead of printing the writer's own KeyboardInterrupt traceback.
        start_new_session=True,
    )
    confirmed = 0
    try:
        assert child.stdout is not None
        for line in child.stdout:
            confirmed = int(line)
            if confirmed >= target:
                break
        os.kill(child.pid, signal.SIGKILL)
        # The writer went on between that line and the kill: the lines it printed meanwhile are
        # still in the pipe. The last whole one is the number of writes that returned (a count
        # short of it undercounts, and the loss came out negative).
        for line in child.stdout:
            if line.endswith("\n"):
                confirmed = int(line)
    finally:
        child.kill()
        child.wait(timeout=30)
    if not any(file.stat().st_size for file in path.glob("*.mcap")):
        # Killed before its first chunk reached the file (chunks as large as the messages
        # written): nothing to salvage, everything confirmed is lost.
        return confirmed, 0
    _, results = salvage(path)
    return confirmed, sum(sum(result.messages.values()) for result in results)


def _text(seq: int) -> str:
    from lit_planner.bag import envelope

    return envelope(
        "lit_msgs_json/Observation", seq, "measure", "measure", {"filler": "x" * PAYLOAD_BYTES}
    )


def _text_bytes() -> int:
    return len(_text(0))


def _writer(path: str) -> None:
    """The crash trial's child: write until killed, printing each confirmed seq count."""
    from lit_planner.bag import BagRecorder

    recorder = BagRecorder(path, run_id="killed", chunk_bytes=int(os.environ["LIT_CHUNK_BYTES"]))
    recorder.add_topic("/lit/observation", "std_msgs/msg/String")
    seq = 0
    try:
        while True:
            recorder.write_string("/lit/observation", _text(seq), time.time_ns())
            seq += 1
            print(seq, flush=True)
    except BrokenPipeError:  # the measurement ended (a Ctrl-C while it started this writer)
        os._exit(0)  # without Python's flush of the broken pipe at exit


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--writer":
        _writer(sys.argv[2])

"""Recording rosbag2 bags (version 9, MCAP storage) of LIT*'s topics, without ROS.

:class:`BagRecorder` writes with ``rosbags.rosbag2.Writer``: rosbag2 metadata version 9, storage
``mcap``, no compression, the run's metadata in ``custom_data`` (``lit.run_id``, ``lit.command``,
``lit.git_commit``, ``lit.created``, ``lit.chunk_bytes`` and whatever the caller adds) and every
topic's offered QoS profile in rosbag2's version-9 YAML form. The result reads back with rosbags'
``Reader``, with ``mcap`` + ``mcap_ros2.decoder`` and with rclpy's ``deserialize_message``, and its
``metadata.yaml`` has the keys of Jazzy's ``ros2 bag info``. Messages are serialized to CDR with
rosbags' ROS 2 Jazzy typestore, so recording needs no rclpy; already serialized messages (e.g. from
``rclpy.serialization.serialize_message``) go in with :meth:`BagRecorder.write_raw`.

Flush policy and crash loss
---------------------------
rosbags' MCAP storage collects messages in an in-memory chunk and writes the chunk to the file
once it holds more than 1 MiB (a constant in ``McapWriter.write``); ``metadata.yaml`` and the MCAP
summary and footer are only written by ``close()``. A writer killed with SIGKILL therefore leaves
an MCAP file without footer and no ``metadata.yaml``; everything up to the last written chunk can be
recovered (``lit replay salvage``), the open chunk is lost. So that such a bag keeps its run
metadata, :class:`BagRecorder` writes its ``custom_data`` to :data:`UNFINISHED_METADATA` in the
bag folder when it opens the bag and removes that file once ``metadata.yaml`` is written; salvage
reads it. :class:`ChunkedWriter` makes the chunk
size a parameter: its storage closes the chunk as soon as it holds ``chunk_bytes`` bytes (the
1 MiB threshold of rosbags stays the upper limit) and then flushes Python's file buffer to the
operating system, so a SIGKILL loses at most the last ``chunk_bytes`` bytes of message records
(each record is the serialized message plus 31 bytes). :meth:`BagRecorder.flush` closes the open
chunk on demand (e.g. from a timer of a node that publishes rarely). Nothing is ``fsync``-ed: the
data survive the death of the process, not a power cut.

Measured here (Python 3.11, 2 cores): with the default ``chunk_bytes = 64 KiB`` and JSON
envelopes of about 1 KiB (1 062 characters, 1 102-byte records), a chunk holds 60 messages; eight
writers SIGKILLed at random points after confirming N messages each (N = 634 … 2 662) left
N - 1 … N - 55 of them recoverable (``tests/test_replay.py`` asserts N - 60 or more). Writing 1 KiB strings with :meth:`write_string` runs at
about 160 000 messages/s (100 000 messages, lock and ``close()`` included), no slower than with
rosbags' 1 MiB chunks (150 000/s); the smaller chunks add 0.2 % to the file (chunk indexes).
"""

from __future__ import annotations

import functools
import json
import re
import shlex
import shutil
import struct
import sys
import threading
import time
import zlib
from collections.abc import Mapping, Sequence
from datetime import UTC, datetime
from pathlib import Path
from types import TracebackType
from typing import Any, Self

import numpy as np
from rosbags.interfaces import (
    Connection,
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
from rosbags.rosbag2.storage_mcap import McapWriter
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

from lit_planner.errors import LitPlannerError

BAG_VERSION = 9
"""rosbag2 metadata version written (Jazzy's)."""
STRING_TYPE = "std_msgs/msg/String"
"""Carrier of every JSON envelope."""
TRAJECTORY_TYPE = "trajectory_msgs/msg/JointTrajectory"
"""Type of ``/lit/path``."""
SUPPORTED_TYPES = (STRING_TYPE, TRAJECTORY_TYPE)
"""Message types that :meth:`BagRecorder.add_topic` accepts."""
DEFAULT_CHUNK_BYTES = 64 * 1024
"""Default chunk size: the most a SIGKILL can lose."""
MAX_CHUNK_BYTES = 1 << 20
"""rosbags closes a chunk beyond this size anyway."""
UNFINISHED_METADATA = "lit-unfinished.json"
"""File in the folder of a bag being written by :class:`BagRecorder`: its ``custom_data`` as a
JSON object, for ``lit replay salvage`` when the writer dies before ``metadata.yaml`` is written;
removed when the bag is closed."""
DEFAULT_QOS = "reliable-keep-all"
"""Offered QoS of a topic unless given (what LIT*'s publishers use)."""
INFINITE_DURATION = QosTime(9_223_372_036, 854_775_807)
"""How rosbag2 writes an infinite deadline, lifespan and lease (RMW_DURATION_INFINITE)."""
RUN_ID_KEY = "lit.run_id"
"""``custom_data`` key of the run id; the other keys of the recorder use the same prefix."""
BENCH_RUN_TOPIC = "/lit/bench/run"
"""``lit bench``: one BenchRun envelope per run record (with its path)."""
BENCH_CONFIG_TOPIC = "/lit/bench/config"
"""``lit bench``: the benchmark's configuration, first message of the bag."""
BENCH_RUN_SCHEMA = "lit_msgs_json/BenchRun"
"""Envelope schema of :data:`BENCH_RUN_TOPIC` messages (the ``runs.jsonl`` record schema)."""
BENCH_CONFIG_SCHEMA = "lit_msgs_json/BenchConfig"
"""Envelope schema of the :data:`BENCH_CONFIG_TOPIC` message."""
BENCH_SOURCE = "lit_bench"
"""Envelope ``source`` of ``lit bench``'s messages."""
BENCH_DURATION_KEY = "lit.bench.duration_s"
"""``custom_data`` key of a finished ``lit bench`` bag: the benchmark's own wall time in seconds
(set-up and path checks included), which ``lit replay bench`` prints as ``lit bench`` did; the
messages' stamps span only the configuration message to the last run record."""
BENCH_FINISHED_KEY = "lit.bench.finished"
"""``custom_data`` key of a finished ``lit bench`` bag: when it finished (ISO 8601, UTC)."""
ENVELOPE_VERSION = 1
"""Envelope version written by :func:`envelope`."""

_QOS_PATTERN = re.compile(
    r"(?P<reliability>reliable|best-effort)-keep-(?:(?P<all>all)|last-(?P<depth>[1-9]\d*))"
)
_ROOT = Path(__file__).resolve().parents[2]


class BagError(LitPlannerError, ValueError):
    """A bag cannot be created or written; names the bag and the cause."""


@functools.cache
def typestore() -> Typestore:
    """rosbags' ROS 2 Jazzy typestore (built once)."""
    return get_typestore(Stores.ROS2_JAZZY)


def parse_qos(spec: str) -> Qos:
    """The offered QoS profile of ``spec``: ``reliable-keep-all``, ``reliable-keep-last-10``, ….

    Reliability ``reliable`` or ``best-effort``; history ``keep-all`` (depth 0, as rosbag2 writes
    it) or ``keep-last-<depth>``; durability volatile, liveliness automatic, infinite deadline,
    lifespan and lease, as a publisher created with default rclpy settings offers them.

    Raises:
        BagError: ``spec`` is not of that form.
    """
    match = _QOS_PATTERN.fullmatch(spec)
    if match is None:
        raise BagError(
            f"QoS {spec!r}: expected <reliable|best-effort>-keep-all or "
            "<reliable|best-effort>-keep-last-<depth>, e.g. 'reliable-keep-all'"
        )
    reliability = (
        QosReliability.RELIABLE
        if match["reliability"] == "reliable"
        else QosReliability.BEST_EFFORT
    )
    history = QosHistory.KEEP_ALL if match["all"] else QosHistory.KEEP_LAST
    return Qos(
        history=history,
        depth=0 if match["all"] else int(match["depth"]),
        reliability=reliability,
        durability=QosDurability.VOLATILE,
        deadline=INFINITE_DURATION,
        lifespan=INFINITE_DURATION,
        liveliness=QosLiveliness.AUTOMATIC,
        liveliness_lease_duration=INFINITE_DURATION,
        avoid_ros_namespace_conventions=False,
    )


CHUNK_CRC_OFFSET = 1 + 8 + 8 + 8 + 8
"""Byte offset of the uncompressed CRC-32 in an MCAP chunk record."""


class ChunkedMcapWriter(McapWriter):
    """rosbags' MCAP storage with a chunk size of ``chunk_bytes`` and a flush after each chunk."""

    def __init__(self, path: Path, compression: CompressionMode, *, chunk_bytes: int) -> None:
        super().__init__(path, compression)
        self.chunk_bytes = chunk_bytes
        """Close the open chunk once it holds this many bytes."""

    def write(self, connection: Connection, timestamp: int, data: bytes | memoryview) -> None:
        """Append a message to the open chunk; close the chunk when it is full."""
        super().write(connection, timestamp, data)
        if self.chunk.bio.tell() >= self.chunk_bytes:
            self.close_chunk()

    def close_chunk(self) -> None:
        """Write the open chunk with its message indexes and hand them to the operating system.

        rosbags writes 0 for the chunk's CRC-32 (MCAP: "not computed"), so a flipped bit in a
        number went unnoticed by every reader; this writes the CRC-32 of the uncompressed records
        into the chunk record, which rosbags' and mcap's readers check.
        """
        records = self.chunk.bio.getbuffer()
        crc = zlib.crc32(records)
        del records  # a view would keep the BytesIO from being replaced
        start = self.bio.tell()
        super().close_chunk()
        end = self.bio.tell()
        # The chunk record: opcode (1), length (8), start and end time (8 + 8), uncompressed
        # size (8), then the CRC-32 (4).
        self.bio.seek(start + CHUNK_CRC_OFFSET)
        self.bio.write(struct.pack("<I", crc))
        self.bio.seek(end)
        self.bio.flush()

    def flush(self) -> None:
        """Close the open chunk now if it holds messages; either way hand what is written to the
        operating system (before any message, the header and the topics' records)."""
        if self.chunk.msgs:
            self.close_chunk()
        else:
            self.bio.flush()


class ChunkedWriter(Writer):
    """A rosbag2 version-9 MCAP bag writer (rosbags' ``Writer``) with :class:`ChunkedMcapWriter`."""

    def __init__(
        self, path: Path | str, *, chunk_bytes: int = DEFAULT_CHUNK_BYTES, compress: bool = False
    ) -> None:
        if not 1 <= chunk_bytes <= MAX_CHUNK_BYTES:
            raise BagError(f"chunk_bytes must be within 1..{MAX_CHUNK_BYTES}, got {chunk_bytes}")
        super().__init__(path, version=BAG_VERSION, storage_plugin=StoragePlugin.MCAP)
        self.chunk_bytes = chunk_bytes
        """The chunk size it writes (before compression)."""
        if compress:
            # zstd inside the MCAP chunks (rosbag2's MCAP storage compression): metadata.yaml
            # still says no compression, every MCAP reader decompresses the chunks itself.
            self.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        # Writer.open() instantiates STORAGE_PLUGINS[plugin](path, compression): give this
        # instance a table whose MCAP entry carries the chunk size.
        self.STORAGE_PLUGINS = {
            StoragePlugin.MCAP: functools.partial(ChunkedMcapWriter, chunk_bytes=chunk_bytes)
        }  # type: ignore[misc]

    def flush(self) -> None:
        """Write the open chunk to the file now (see :meth:`ChunkedMcapWriter.flush`)."""
        if isinstance(self.storage, ChunkedMcapWriter):
            self.storage.flush()


class BagRecorder:
    """A rosbag2 bag (version 9, MCAP) of std_msgs/String and JointTrajectory topics.

    Thread-safe: ``write_*`` and :meth:`flush` may be called from several threads. Use it as a
    context manager or call :meth:`close` (idempotent); until then the bag has no
    ``metadata.yaml``.

    Args:
        directory: the bag directory to create; it must not exist yet.
        run_id: the run's id, stored as ``custom_data["lit.run_id"]``.
        metadata: more ``custom_data`` entries (strings); they override the recorder's own.
        chunk_bytes: chunk size in bytes (1 … 1 MiB): the most message data a crash loses.

    Raises:
        BagError: the directory exists, a metadata value is not a string, a bad chunk size.
    """

    def __init__(
        self,
        directory: str | Path,
        *,
        run_id: str,
        metadata: Mapping[str, str] | None = None,
        chunk_bytes: int = DEFAULT_CHUNK_BYTES,
    ) -> None:
        self.path = Path(directory)
        """The bag directory."""
        self.messages = 0
        """Messages written so far."""
        self._lock = threading.Lock()
        self._connections: dict[str, Connection] = {}
        self._closed = False
        if self.path.exists():
            raise BagError(f"bag {self.path}: exists already; a bag needs a new directory")
        custom = {
            RUN_ID_KEY: run_id,
            "lit.command": shlex.join(sys.argv),
            "lit.git_commit": _git_commit(),
            "lit.created": datetime.now(UTC).isoformat(timespec="seconds"),
            "lit.chunk_bytes": str(chunk_bytes),
            **(metadata or {}),
        }
        for key, value in custom.items():
            if not isinstance(key, str) or not isinstance(value, str):
                raise BagError(f"bag {self.path}: metadata {key!r}: {value!r} is not a string")
        self._writer = ChunkedWriter(self.path, chunk_bytes=chunk_bytes)
        for key, value in custom.items():
            self._writer.set_custom_data(key, value)
        try:
            self._writer.open()
        except Exception as error:  # rosbags' WriterError, OSError
            raise BagError(f"bag {self.path}: cannot create it: {error}") from error
        try:
            (self.path / UNFINISHED_METADATA).write_text(json.dumps(custom, indent=1) + "\n")
        except OSError as error:
            self._writer.abort()
            shutil.rmtree(self.path, ignore_errors=True)
            raise BagError(f"bag {self.path}: cannot create it: {error}") from error

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` has run (writes raise :class:`BagError` then)."""
        return self._closed

    def add_topic(self, topic: str, msgtype: str, *, qos: str = DEFAULT_QOS) -> None:
        """Declare ``topic`` with its type and offered QoS (see :func:`parse_qos`).

        Raises:
            BagError: the topic exists already, the bag is closed, or a bad QoS string.
            ValueError: ``msgtype`` is not one of :data:`SUPPORTED_TYPES`.
        """
        if msgtype not in SUPPORTED_TYPES:
            raise ValueError(
                f"topic {topic}: type {msgtype!r} is not supported; use one of {SUPPORTED_TYPES}"
            )
        profile = parse_qos(qos)
        with self._lock:
            self._check_open()
            if topic in self._connections:
                raise BagError(f"bag {self.path}: topic {topic} was added already")
            self._connections[topic] = self._writer.add_connection(
                topic, msgtype, typestore=typestore(), offered_qos_profiles=[profile]
            )

    def write_raw(self, topic: str, cdr: bytes, stamp_ns: int) -> None:
        """Write an already CDR-serialized message of ``topic``'s type at time ``stamp_ns``."""
        with self._lock:
            self._check_open()
            connection = self._connections.get(topic)
            if connection is None:
                raise BagError(f"bag {self.path}: topic {topic} was not added (add_topic)")
            if not 0 <= stamp_ns < 2**63:
                raise BagError(f"bag {self.path}: stamp {stamp_ns} ns out of range")
            self._writer.write(connection, stamp_ns, cdr)
            self.messages += 1

    def write_string(self, topic: str, text: str, stamp_ns: int) -> None:
        """Write a ``std_msgs/msg/String`` with ``data = text``."""
        store = typestore()
        message = store.types[STRING_TYPE](data=text)
        self.write_raw(topic, bytes(store.serialize_cdr(message, STRING_TYPE)), stamp_ns)

    def write_trajectory(
        self,
        topic: str,
        path: Sequence[Sequence[float]],
        stamp_ns: int,
        joint_names: Sequence[str] | None = None,
        *,
        frame_id: str = "",
    ) -> None:
        """Write ``path`` as a ``JointTrajectory``: one point per state (positions = the state).

        As the planner node publishes it: ``joint_names`` default to ``q0 … q{n-1}``; the header
        has stamp ``stamp_ns`` and ``frame_id`` (the node's episode id); ``time_from_start`` is
        the path length so far (unit speed); velocities, accelerations and efforts are empty.

        Raises:
            BagError: the states differ in length, are not finite, or do not fit the names.
        """
        cdr = serialize_trajectory(path, stamp_ns, joint_names, frame_id=frame_id)
        self.write_raw(topic, cdr, stamp_ns)

    def flush(self) -> None:
        """Write the open chunk to the file now, so that a crash cannot lose it."""
        with self._lock:
            if not self._closed:
                self._writer.flush()

    def set_metadata(self, key: str, value: str) -> None:
        """Set a ``custom_data`` entry of ``metadata.yaml``, written when the bag closes.

        Raises:
            BagError: the bag is closed, or the key or value is not a string.
        """
        if not isinstance(key, str) or not isinstance(value, str):
            raise BagError(f"bag {self.path}: metadata {key!r}: {value!r} is not a string")
        with self._lock:
            self._check_open()
            self._writer.set_custom_data(key, value)

    def close(self) -> None:
        """Write the MCAP summary and ``metadata.yaml``; later calls do nothing."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._writer.close()
            (self.path / UNFINISHED_METADATA).unlink(missing_ok=True)  # metadata.yaml has it

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()

    def _check_open(self) -> None:
        if self._closed:
            raise BagError(f"bag {self.path} is closed")


def serialize_trajectory(
    path: Sequence[Sequence[float]],
    stamp_ns: int,
    joint_names: Sequence[str] | None = None,
    *,
    frame_id: str = "",
) -> bytes:
    """CDR bytes of a ``trajectory_msgs/msg/JointTrajectory`` holding ``path`` (see
    :meth:`BagRecorder.write_trajectory`)."""
    store = typestore()
    states = [np.asarray(state, dtype=np.float64) for state in path]
    dim = len(states[0]) if states else len(joint_names or ())
    names = list(joint_names) if joint_names is not None else [f"q{i}" for i in range(dim)]
    for index, state in enumerate(states):
        if state.shape != (len(names),):
            raise BagError(
                f"path state {index} has shape {state.shape}, expected ({len(names)},) "
                f"like the joint names"
            )
        if not np.all(np.isfinite(state)):
            raise BagError(f"path state {index} is not finite: {state.tolist()}")
    types = store.types
    empty = np.empty(0, dtype=np.float64)
    header = types["std_msgs/msg/Header"](
        stamp=types["builtin_interfaces/msg/Time"](
            sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000
        ),
        frame_id=frame_id,
    )
    points, elapsed = [], 0.0
    for index, state in enumerate(states):
        if index:
            elapsed += float(np.linalg.norm(state - states[index - 1]))
        seconds = int(elapsed)
        points.append(
            types["trajectory_msgs/msg/JointTrajectoryPoint"](
                positions=state,
                velocities=empty,
                accelerations=empty,
                effort=empty,
                time_from_start=types["builtin_interfaces/msg/Duration"](
                    sec=seconds, nanosec=int((elapsed - seconds) * 1e9)
                ),
            )
        )
    message = types[TRAJECTORY_TYPE](header=header, joint_names=names, points=points)
    return bytes(store.serialize_cdr(message, TRAJECTORY_TYPE))


def envelope(
    schema: str, seq: int, source: str, run_id: str, payload: Any, *, stamp_ns: int | None = None
) -> str:
    """A JSON envelope (version :data:`ENVELOPE_VERSION`) as text; NaN is rejected."""
    return json.dumps(
        {
            "schema": schema,
            "version": ENVELOPE_VERSION,
            "seq": seq,
            "stamp_ns": time.time_ns() if stamp_ns is None else stamp_ns,
            "source": source,
            "run_id": run_id,
            "payload": payload,
        },
        allow_nan=False,
    )


def unique_directory(parent: Path, name: str) -> Path:
    """``parent/name``, or ``parent/name-2``, ``-3``, … if it exists."""
    candidate, number = parent / name, 1
    while candidate.exists():
        number += 1
        candidate = parent / f"{name}-{number}"
    return candidate


def output_folder_problem(path: Path) -> str | None:
    """Why ``path`` cannot take a new run's outputs (``lit bench --out``, ``lit replay bench
    --out``): a file is in the way, it holds files already (new outputs never mix with stale
    ones, nothing is overwritten), or it cannot be made or written (:func:`write_problem`: asked
    before the work, which failed at its end after minutes); None when it is new or empty and
    writable."""
    from lit_planner import tensor_files

    if path.exists() and not path.is_dir():
        return "exists and is not a folder"
    if path.is_dir() and tensor_files.holds_files(path):  # what a killed export left is not
        return "exists and is not empty"
    return write_problem(path)


def write_problem(path: str | Path) -> str | None:
    """Why a folder (or a file) cannot be created at ``path``: the nearest existing folder on its
    way is a file, or cannot be written (tried: a probe folder is made and removed there, which
    also catches what permission bits do not show, such as ``/proc`` for root). None when it
    can. For a command to ask before its work rather than fail at its end."""
    import os
    import tempfile

    ancestor = Path(path).absolute()
    while not ancestor.exists() and ancestor != ancestor.parent:
        if ancestor.is_symlink():  # exists() follows links: this one points nowhere
            return f"{ancestor} is a symbolic link to nothing ({os.readlink(ancestor)})"
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        return f"{ancestor} is a file, not a folder"
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".lit-write-probe-", dir=ancestor))
    except OSError as error:
        # The errno is the probe folder's (ENOENT in /proc, which exists): said as such.
        return f"cannot write in {ancestor} (creating a folder there failed: {error.strerror or error})"
    return None


def default_bag_root() -> Path:
    """The repository's ``bags/`` folder (beside the ``lit_planner`` package folder)."""
    return _ROOT / "bags"


class BenchRecording:
    """The bag that ``lit bench`` records: a BenchConfig message, then one BenchRun per record.

    Args:
        directory: the bag directory (new).
        run_id: the run folder's name.
        config: the ``BenchConfig`` payload (written at once).
    """

    def __init__(self, directory: Path, run_id: str, config: Mapping[str, Any]) -> None:
        self.run_id = run_id
        """Envelope ``run_id`` of every message."""
        self.recorder = BagRecorder(directory, run_id=run_id, metadata={"lit.source": BENCH_SOURCE})
        """The bag."""
        self._seq: dict[str, int] = {}  # per topic: each topic is its own publisher
        self.recorder.add_topic(BENCH_CONFIG_TOPIC, STRING_TYPE)
        self.recorder.add_topic(BENCH_RUN_TOPIC, STRING_TYPE)
        self._write(BENCH_CONFIG_TOPIC, BENCH_CONFIG_SCHEMA, dict(config))

    def add_runs(self, records: Sequence[Mapping[str, Any]]) -> None:
        """Record run records (with their paths), then flush them to the file."""
        for record in records:
            self._write(BENCH_RUN_TOPIC, BENCH_RUN_SCHEMA, dict(record))
        self.recorder.flush()

    def finish(self, finished: datetime, duration_s: float) -> None:
        """Record when the benchmark finished and its wall time (:data:`BENCH_FINISHED_KEY`,
        :data:`BENCH_DURATION_KEY`); a bag closed without it was interrupted."""
        self.recorder.set_metadata(BENCH_FINISHED_KEY, finished.isoformat())
        self.recorder.set_metadata(BENCH_DURATION_KEY, repr(float(duration_s)))

    def close(self) -> None:
        """Finish the bag (idempotent)."""
        self.recorder.close()

    def _write(self, topic: str, schema: str, payload: dict[str, Any]) -> None:
        stamp = time.time_ns()
        seq = self._seq.get(topic, 0)
        text = envelope(schema, seq, BENCH_SOURCE, self.run_id, payload, stamp_ns=stamp)
        self.recorder.write_string(topic, text, stamp)
        self._seq[topic] = seq + 1


class EpisodeRecording:
    """A bag of planning queries written by the process that plans (``lit train``): the same
    ``/lit/*`` messages the planner node publishes, one :class:`~lit_msgs_json.envelope.Publisher`
    (one ``seq``) per topic, so ``lit replay info``/``verify``/``tensors`` read it like a recorded
    ROS run.

    Args:
        directory: the bag directory (new).
        run_id: envelope ``run_id`` and ``custom_data["lit.run_id"]``.
        source: envelope ``source`` (the writing program's name).
        metadata: more ``custom_data`` entries.
    """

    TOPICS = ("/lit/observation", "/lit/decision", "/lit/solution", "/lit/episode")

    def __init__(
        self,
        directory: Path,
        run_id: str,
        source: str,
        metadata: Mapping[str, str] | None = None,
    ) -> None:
        from lit_msgs_json.envelope import Publisher

        self.recorder = BagRecorder(
            directory, run_id=run_id, metadata={"lit.source": source, **(metadata or {})}
        )
        """The bag."""
        self._publishers = {topic: Publisher(source, run_id) for topic in self.TOPICS}
        for topic in self.TOPICS:
            self.recorder.add_topic(topic, STRING_TYPE)
        self.recorder.add_topic("/lit/path", "trajectory_msgs/msg/JointTrajectory")

    def write_query(
        self,
        episode_id: str,
        mode: str,
        scenario: Any,
        seed: int,
        policy: str,
        result: dict[str, Any],
        log: Any,
        sources: Any = None,
    ) -> None:
        """One query: its solution updates, observations and decisions, summary and path (see
        :mod:`lit_planner.episode_messages`), then a flush."""
        from lit_planner.episode_messages import decision_payloads, summary_payload

        for payload in log.solutions:
            self._write("/lit/solution", "SolutionUpdate", payload)
        for observation, decision in decision_payloads(episode_id, result, log, policy, sources):
            self._write("/lit/observation", "Observation", observation)
            self._write("/lit/decision", "Decision", decision)
        summary = summary_payload(episode_id, mode, scenario, seed, policy, result, sources)
        self._write("/lit/episode", "EpisodeSummary", summary)
        if result["path"]:
            self.recorder.write_trajectory(
                "/lit/path", result["path"], time.time_ns(), frame_id=episode_id
            )
        self.recorder.flush()

    def close(self) -> None:
        """Finish the bag (idempotent)."""
        self.recorder.close()

    def _write(self, topic: str, schema: str, payload: dict[str, Any]) -> None:
        text = self._publishers[topic].encode(schema, payload)
        self.recorder.write_string(topic, text, time.time_ns())


def _git_commit() -> str:
    """The checkout's commit, with ``-dirty`` when tracked files are modified, as the tensors'
    provenance names it."""
    from lit_planner.bench.environment import commit_label

    return commit_label(_ROOT) or "unknown"

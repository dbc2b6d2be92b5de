"""``lit replay``: read recorded bags back — summary, path re-check, salvage, benchmark outputs.

::

    lit replay info BAG [--json]           # topics, time span, run metadata, seq accounting
    lit replay verify BAG...               # re-check every recorded path against its world
    lit replay salvage BAG [-o OUT]        # rescue a bag whose writer died or whose file is damaged
    lit replay bench BAG... [--out DIR]    # regenerate lit bench's summary, tables and plots

A BAG is a rosbag2 bag directory or one of its ``.mcap`` files. Messages on ``/lit/*`` topics
(optionally below a namespace, e.g. ``/robot1/lit/observation``) are ``std_msgs/msg/String``
envelopes ``{"schema", "version", "seq", "stamp_ns", "source", "run_id", "payload"}`` or, on
``/lit/path``, ``trajectory_msgs/msg/JointTrajectory``. ``seq`` rises by one per publisher, that
is per (topic, source, run id) and process (:class:`SeqAccount`): ``info`` counts, per publisher,
the gaps (runs of missing numbers), the missing messages, the duplicates (a seq recorded again
with the same bytes), the reused seqs (other bytes: two publishers of one name and run id) and
``leading`` (the numbers before the first recorded one, when a publisher started at 0 before the
recording did).

What cannot be used is skipped and counted, never fatal: messages on other topics, envelopes of an
unknown schema or an unsupported version, text that is not an envelope, undecodable messages, and
payloads that fail their schema (checked by the commands that read payloads: verify, bench,
tensors; ``info`` accounts for envelopes). A bag that cannot be read at all (a missing path, an empty
directory or file, a writer killed before ``close()``, a truncated or damaged file) is a one-line
error with exit status 2; ``salvage`` then recovers what is readable.

A bag given twice (also as a folder and its ``.mcap`` file) is refused; ``bench`` counts a run
record once when copies of a bag hold it (same topic, source, run id and seq; a warning says how
many were left out) and refuses two different records under one run id and seq. Output folders
(``bench --out`` or its default ``<first BAG>/replay``, ``<stem>-replay`` beside an ``.mcap``
file, ``tensors --out``) must be new or empty.
"""

from __future__ import annotations

import argparse
import bisect
import contextlib
import hashlib
import itertools
import json
import math
import os
import re
import shutil
import signal
import sys
from collections import Counter
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from functools import cache
from pathlib import Path
from typing import Any, Self

import numpy as np

from lit_planner import argtypes, bag, rosutil, scenarios, signals
from lit_planner.errors import LitPlannerError
from lit_planner.guarded_stdout import StdoutError
from lit_planner.safe_logger import SafeLogger

PROG = "lit replay"
"""Prefix of every message."""
ENVELOPE_KEYS = ("schema", "version", "seq", "stamp_ns", "source", "run_id", "payload")
"""Keys of a JSON envelope."""
SCHEMA_PREFIX = "lit_msgs_json/"
"""Every envelope schema name starts with this."""
SUPPORTED_VERSIONS = frozenset({1})
"""Envelope versions this replay reads of the schemas ``lit_msgs_json`` does not version as
messages (``BenchConfig``, ``BenchRun``); a message's are :func:`supported_versions`."""
MESSAGE_SCHEMAS = frozenset({"BenchConfig", "BenchRun"})
"""Envelope schemas besides those that ``lit_msgs_json`` ships (BenchConfig is read only here)."""
EPISODE_SCHEMA = "lit_msgs_json/EpisodeSummary"
"""Schema of ``/lit/episode`` messages."""
PATH_TOPIC = "/lit/path"
"""Topic (below any namespace) of the typed paths."""
SALVAGED_SUFFIX = "-salvaged"
"""Default output of ``salvage``: the bag's path with this suffix."""
REPLAY_DIR = "replay"
"""Default output folder of ``bench``, inside the (first) bag."""
LIT_TOPIC_BASES = (
    *(f"/{name}" for name in rosutil.TOPICS.values()),
    rosutil.STATS_TOPIC,
    bag.BENCH_RUN_TOPIC,
    bag.BENCH_CONFIG_TOPIC,
)
"""The system's topics (any namespace may precede them); another program's topic under
``/lit/`` is foreign: its messages used to count as damaged LIT* messages and failed verify."""
_NAMESPACE = re.compile(r"(?:/[^/]+)*")
_MCAP_MAGIC = b"\x89MCAP0\r\n"


class ReplayError(LitPlannerError, ValueError):
    """A bag or an argument that replay cannot use; the message is one line naming the input."""


class NotBenchBagError(ReplayError):
    """A readable bag without the config of a ``lit bench`` run."""

    def __init__(self, message: str, path: str | Path) -> None:
        super().__init__(message)
        self.path = Path(path)
        """The bag."""


class EmptyBenchBagError(ReplayError):
    """A ``lit bench`` bag with its config but no run record (interrupted before its first
    scenario finished): nothing to tabulate, but not bad input."""


# --- Reading bags ----------------------------------------------------------------------------


@dataclass(frozen=True)
class TopicSummary:
    """A topic of a bag."""

    topic: str
    msgtype: str
    messages: int


@dataclass(frozen=True)
class BagFacts:
    """What a bag's metadata says."""

    path: Path
    storage: str | None
    version: int | None
    ros_distro: str | None
    compression: str | None
    custom_data: dict[str, str]
    topics: list[TopicSummary]
    messages: int


@dataclass(frozen=True)
class RawMessage:
    """One serialized message as read from a bag."""

    topic: str
    msgtype: str
    log_ns: int
    data: bytes


@dataclass(frozen=True)
class Envelope:
    """A decoded JSON envelope and where it was recorded."""

    topic: str
    log_ns: int
    schema: str
    version: int
    seq: int
    stamp_ns: int
    source: str
    run_id: str
    payload: Any

    @property
    def namespace(self) -> str:
        """The topic's namespace ('' for ``/lit/...``)."""
        return split_topic(self.topic)[0]


def message_identity(item: Envelope | Trajectory) -> tuple[str, str, str, int, int]:
    """What makes a message the same message in another bag. An envelope: its topic, source, run
    id, seq and the stamp its publisher gave it (a resumed ``lit train`` run records under the same
    run id with its seq from 0 again, at later stamps). A ``/lit/path``: its topic, frame id (the
    episode) and log time. A compacted or salvaged copy keeps all of these."""
    if isinstance(item, Trajectory):
        return (item.topic, item.frame_id, "", -1, item.log_ns)
    return (item.topic, item.source, item.run_id, item.seq, item.stamp_ns)


_BENCH_TOPICS = {
    bag.BENCH_CONFIG_SCHEMA: bag.BENCH_CONFIG_TOPIC,
    bag.BENCH_RUN_SCHEMA: bag.BENCH_RUN_TOPIC,
}


def on_its_topic(item: Envelope, skipped: Skipped) -> bool:
    """Whether a ``lit bench`` envelope is on its kind's topic (other envelopes: True); counted
    in ``skipped`` as :data:`WRONG_TOPIC` when not."""
    topic = _BENCH_TOPICS.get(item.schema)
    if topic is None or item.topic == topic:
        return True
    skipped.add(WRONG_TOPIC, f"{item.topic} seq {item.seq}", f"{item.schema} belongs on {topic}")
    return False


def read_before(
    seen: dict[tuple[str, str, str, int, int], bytes], item: Envelope | Trajectory, data: bytes
) -> str | None:
    """None for a message not read before (noted in ``seen``: its :func:`message_identity` and a
    hash of its serialized ``data``, which a compacted or salvaged copy keeps byte for byte);
    :data:`READ_TWICE` for a copy of one read before, :data:`CONFLICTING` for a different message
    under the same identity."""
    identity, digest = message_identity(item), hashlib.blake2b(data, digest_size=16).digest()
    first = seen.get(identity)
    if first is None:
        seen[identity] = digest
        return None
    return READ_TWICE if first == digest else CONFLICTING


@dataclass(frozen=True)
class Trajectory:
    """A decoded ``/lit/path`` message."""

    topic: str
    log_ns: int
    frame_id: str
    """The planner node writes the episode's ``episode_id`` here."""
    joint_names: list[str]
    path: list[list[float]]


READ_TWICE = "message read twice (a bag and its copy?)"
"""Why a message is skipped that one of the bags read before held (:func:`message_identity`: a
bag given with its compacted or salvaged copy)."""
CONFLICTING = "another message under the topic, source, run, seq and stamp of one read before"
"""Why a message is skipped whose identity (:func:`message_identity`) a different message read
before had: not a copy, and which one is right cannot be told (damage: verify exits 1)."""
WRONG_TOPIC = "on another topic than its kind's"
"""Why a ``lit bench`` record on a topic not its own (a BenchRun on ``/lit/episode``) is left out
(damage); it was tabulated, and its own topic's seq then showed a gap."""
PAYLOAD_INVALID = "payload fails its schema"
"""Skip reason of an envelope whose payload does not pass its schema (damage: verify exits 1)."""
BENIGN_SKIPS = frozenset({"foreign topic", "unknown schema", "unsupported version", READ_TWICE})
"""Reasons to skip a message that say nothing against the bag: another program's topics,
messages of a newer LIT* (counted and shown, as a reader of an older version must), and a copy's
messages read once already."""


@dataclass
class Skipped:
    """Messages left out, counted by reason, with the first few examples."""

    counts: Counter[str] = field(default_factory=Counter)
    examples: list[str] = field(default_factory=list)
    max_examples: int = 5

    def add(self, reason: str, where: str, detail: str = "") -> None:
        """Count one message skipped for ``reason`` (``where``: topic and seq)."""
        self.counts[reason] += 1
        if len(self.examples) < self.max_examples:
            self.examples.append(f"{where}: {reason}" + (f" ({detail})" if detail else ""))

    def merge(self, other: Skipped) -> None:
        """Count ``other``'s messages here too (its examples while there is room)."""
        self.counts.update(other.counts)
        self.examples += other.examples[: max(0, self.max_examples - len(self.examples))]

    @property
    def total(self) -> int:
        """Messages skipped."""
        return sum(self.counts.values())

    @property
    def damaged(self) -> int:
        """Messages skipped for a reason that speaks against the bag (not :data:`BENIGN_SKIPS`)."""
        return sum(n for reason, n in self.counts.items() if reason not in BENIGN_SKIPS)

    def to_dict(self) -> dict[str, Any]:
        """JSON form."""
        return {"total": self.total, "reasons": dict(self.counts), "examples": self.examples}

    def line(self) -> str:
        """One line: ``3 skipped: 2 foreign topic, 1 unknown schema``."""
        parts = ", ".join(f"{count} {reason}" for reason, count in self.counts.most_common())
        return f"{self.total} skipped" + (f": {parts}" if parts else "")


def split_topic(topic: str) -> tuple[str, str] | tuple[None, None]:
    """(namespace, ``/lit/...`` base) of a LIT* topic (:data:`LIT_TOPIC_BASES`); (None, None)
    for any other topic."""
    for base in LIT_TOPIC_BASES:
        if topic.endswith(base) and _NAMESPACE.fullmatch(topic[: -len(base)]):
            return topic[: -len(base)], base
    return None, None


def known_schema(name: str) -> bool:
    """Whether ``name`` is one of the system's envelope schemas (``lit_msgs_json/<Name>``)."""
    if not name.startswith(SCHEMA_PREFIX):
        return False
    return name.removeprefix(SCHEMA_PREFIX) in _schema_names()


@cache
def supported_versions(schema: str) -> frozenset[int]:
    """The versions of envelope schema ``schema`` this replay reads: for a message of
    ``lit_msgs_json`` its current and older versions (``accepted_versions``), else
    :data:`SUPPORTED_VERSIONS`."""
    try:
        from lit_msgs_json.envelope import MESSAGE_VERSIONS, accepted_versions
    except Exception:  # noqa: BLE001 -- replay must work without the schemas package
        return SUPPORTED_VERSIONS
    short = schema.removeprefix(SCHEMA_PREFIX)
    if short in MESSAGE_VERSIONS:
        return frozenset(accepted_versions(short))
    return SUPPORTED_VERSIONS


@cache
def _schema_names() -> frozenset[str]:
    return MESSAGE_SCHEMAS | _schema_names_shipped()


class BagReader:
    """A bag opened for reading with rosbags' ``Reader``; every failure is a :class:`ReplayError`.

    Args:
        path: a bag directory (with ``metadata.yaml``) or an ``.mcap`` file.
    """

    def __init__(self, path: str | Path) -> None:
        from rosbags.rosbag2 import Reader

        self.path = Path(path)
        """The bag as given."""
        _check_readable(self.path)
        try:
            self._reader = Reader(self.path)
            self._reader.open()
        except Exception as error:  # noqa: BLE001 -- damaged files raise anything
            foreign = _not_ros2(self.path) or _not_cdr(self.path)
            if foreign:
                raise ReplayError(f"{self.path}: {foreign}") from None
            reason = _mcap_damage(self.path) or _metadata_damage(self.path) or _describe(error)
            raise ReplayError(
                f"cannot read bag {self.path}: {reason}; if its writer was killed or the "
                f"file is damaged, recover it with `lit replay salvage {self.path}`"
            ) from None
        try:
            summaries = _mcap_summaries(self.path)
            self.facts = self._facts(summaries)
            """Its metadata."""
            mismatch = _metadata_mismatch(self.path, self.facts, summaries)
            if mismatch:
                # rosbags reads the topics metadata.yaml lists: the others' messages would be
                # left out without a word.
                raise ReplayError(
                    f"bag {self.path}: its metadata.yaml does not match its MCAP file(s): "
                    f"{mismatch}; rebuild the bag from its files with `lit replay salvage "
                    f"{self.path}`"
                )
        except BaseException:
            self.close()
            raise

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Close the reader."""
        try:
            self._reader.close()
        except Exception:  # noqa: BLE001, S110 -- closing a damaged bag must not mask the cause
            pass

    def messages(self) -> Iterator[RawMessage]:
        """Every message in time order.

        Raises:
            ReplayError: the data cannot be read on (names how many messages were read).
        """
        for connection, stamp, data in self.raw_messages():
            yield RawMessage(connection.topic, connection.msgtype, stamp, bytes(data))

    def raw_messages(self) -> Iterator[tuple[Any, int, bytes | memoryview]]:
        """Every message in time order as rosbags' ``Reader.messages()`` gives it: (connection,
        log time, serialized data).

        Raises:
            ReplayError: the data cannot be read on (names how many messages were read).
        """
        per_topic: dict[str, int] = {}
        iterator = self._reader.messages()
        while True:
            try:
                item = next(iterator)
            except StopIteration:
                self._check_all_read(per_topic)
                return
            except Exception as error:  # noqa: BLE001 -- damaged files raise anything
                raise ReplayError(
                    f"bag {self.path} is damaged after {sum(per_topic.values())} messages: "
                    f"{_describe(error)}; "
                    f"recover it with `lit replay salvage {self.path}`"
                ) from None
            per_topic[item[0].topic] = per_topic.get(item[0].topic, 0) + 1
            yield item

    def _check_all_read(self, per_topic: Mapping[str, int]) -> None:
        """Raise :class:`ReplayError` when fewer messages of a topic were read than the bag
        lists: a damaged byte in an MCAP file's summary (a channel's encoding, a schema's or a
        chunk index's opcode) makes the reader leave out messages without an error."""
        for topic in self.facts.topics:
            got = per_topic.get(topic.topic, 0)
            if got < topic.messages:
                raise ReplayError(
                    f"bag {self.path}: {got} of the {topic.messages} messages of "
                    f"{topic.topic} it lists could be read (a damaged index or summary in its "
                    f"MCAP file hides the others); recover them with `lit replay salvage "
                    f"{self.path}`"
                )

    def _facts(self, summaries: Sequence[Any]) -> BagFacts:
        reader = self._reader
        meta = getattr(reader.storage, "metadata", None)
        custom = getattr(meta, "custom", None)
        custom = dict(custom) if isinstance(custom, dict) else {}  # else load_metadata says why
        version, storage = None, None
        metadata_file = self.path / "metadata.yaml"
        if self.path.is_dir() and metadata_file.is_file():
            info = load_metadata(metadata_file)
            version = info.get("version")
            storage = info.get("storage_identifier")
            custom = dict(info.get("custom_data") or custom)
        elif self.path.suffix == ".mcap":
            storage = "mcap"
            # One file of a bag folder: the run's metadata is its folder's (info showed "no
            # metadata", and bench another duration than for the folder).
            info = _folder_metadata(self.path)
            if info is not None:
                version = info.get("version")
                custom = dict(info.get("custom_data") or custom)
        compression = " ".join(
            filter(None, (reader.compression_mode or "", reader.compression_format or ""))
        ) or _chunk_compression(summaries)
        topics = [
            TopicSummary(topic, info.msgtype or "?", info.msgcount)
            for topic, info in sorted(reader.topics.items())
        ]
        return BagFacts(
            path=self.path,
            storage=storage,
            version=version,
            ros_distro=reader.ros_distro,
            compression=compression or None,
            custom_data={str(k): str(v) for k, v in custom.items()},
            topics=topics,
            messages=reader.message_count,
        )


def _folder_metadata(mcap: Path) -> dict[str, Any] | None:
    """The ``metadata.yaml`` of the bag folder that holds ``mcap`` and lists it among its files;
    None when there is none (a file on its own) or it cannot be read."""
    metadata_file = mcap.parent / "metadata.yaml"
    if not metadata_file.is_file():
        return None
    try:
        info = load_metadata(metadata_file)
    except ReplayError:
        return None
    files = info.get("relative_file_paths") or []
    return info if isinstance(files, list) and mcap.name in map(str, files) else None


def _metadata_mismatch(path: Path, facts: BagFacts, summaries: Sequence[Any]) -> str | None:
    """How a bag folder's ``metadata.yaml`` disagrees with the message counts in its MCAP files'
    summaries (a topic it leaves out, a count it misstates), in words; None when they agree, for
    an ``.mcap`` file given alone, or when a file has no summary statistics to compare with.
    ``summaries`` are the :func:`_mcap_summaries` of ``path``."""
    if not path.is_dir():
        return None
    listed = load_metadata(path / "metadata.yaml").get("relative_file_paths") or []
    listed_files = {Path(str(name)).name for name in listed}  # as rosbags reads them
    if len(listed_files) < len(listed):  # every reader read such a file twice
        names = [Path(str(name)).name for name in listed]
        twice = sorted({name for name in names if names.count(name) > 1})
        return f"it lists {', '.join(twice)} more than once"
    for file in sorted(path.glob("*.mcap")):
        if file.name not in listed_files:
            return (
                f"{file.name} is in the folder, not in the files it lists (a file of another "
                "bag? then move it out rather than salvage, which would merge the two)"
            )
    in_files: dict[str, int] = {}
    for summary in summaries:
        if isinstance(summary, Exception):  # damage: the reader reports it when it gets there
            return None
        if summary is None or summary.statistics is None:
            return None
        for channel_id, count in summary.statistics.channel_message_counts.items():
            channel = summary.channels.get(channel_id)
            if channel is not None and count:
                in_files[channel.topic] = in_files.get(channel.topic, 0) + count
    listed = {topic.topic: topic.messages for topic in facts.topics}
    for topic, count in sorted(in_files.items()):
        if topic not in listed:
            return f"{count} messages of {topic} in the files, a topic it does not list"
        if listed[topic] != count:
            return f"it says {listed[topic]} messages of {topic}, the files hold {count}"
    for topic, count in sorted(listed.items()):
        if count and topic not in in_files:
            return f"it says {count} messages of {topic}, the files hold none"
    total = sum(in_files.values())
    if facts.messages != total:
        return f"it says {facts.messages} messages in all, the files hold {total}"
    return None


def _check_readable(path: Path) -> None:
    """Clear errors for paths that are no bag at all."""
    if not path.exists():
        raise ReplayError(f"{path}: no such file or directory")
    if path.is_dir():
        entries = list(path.iterdir())
        if not entries:
            raise ReplayError(f"{path} is an empty directory, not a bag")
        if not (path / "metadata.yaml").is_file():
            foreign = _not_ros2(path)
            if foreign:
                raise ReplayError(f"{path}: {foreign}")
            mcaps = [entry for entry in entries if entry.suffix == ".mcap"]
            if mcaps and not any(e.is_file() and e.stat().st_size > 0 for e in mcaps):
                # salvage refuses such a folder too ("is an empty file"): no hint to it
                raise ReplayError(
                    f"{path} has no metadata.yaml and its .mcap file"
                    + ("s are" if len(mcaps) > 1 else " is")
                    + " empty: nothing was recorded (a writer killed before its first write?)"
                )
            if mcaps:
                raise ReplayError(
                    f"{path} has no metadata.yaml: its writer did not finish (killed?); recover it "
                    f"with `lit replay salvage {path}`"
                )
            raise ReplayError(f"{path} is not a bag: no metadata.yaml and no .mcap file")
        _check_storage(path)
        return
    if path.stat().st_size == 0:
        raise ReplayError(f"{path} is an empty file")
    if path.suffix != ".mcap":
        raise ReplayError(f"{path} is not a bag: expected a bag directory or an .mcap file")


def _check_storage(folder: Path) -> None:
    """A bag folder whose ``metadata.yaml`` names a storage other than MCAP (sqlite3) is named as
    such: it was "its files hold none" with a salvage hint, and salvage found no .mcap file."""
    try:
        info = load_metadata(folder / "metadata.yaml")
    except ReplayError:
        return  # a damaged or missing metadata.yaml: reported where the bag is read
    storage = info.get("storage_identifier")
    if storage not in (None, "", "mcap"):
        raise ReplayError(
            f"{folder}: a rosbag2 bag in {storage!r} storage; lit replay reads MCAP bags "
            "(convert it with `ros2 bag convert`, storage_id mcap)"
        )
    # Files it lists that are gone: named, with the salvage hint only when another .mcap file is
    # there to salvage (salvage said "holds no .mcap file" after the hint sent the user to it).
    files = info.get("relative_file_paths")
    missing = (
        [str(f) for f in files if not (folder / str(f)).is_file()]
        if isinstance(files, list)
        else []
    )
    if missing:
        rest = any(folder.glob("*.mcap"))
        raise ReplayError(
            f"{folder}: its metadata.yaml lists {', '.join(missing)}, which "
            f"{'is' if len(missing) == 1 else 'are'} not there"
            + (
                f"; `lit replay salvage {folder}` recovers what the other files hold"
                if rest
                else " (no .mcap file is left in the folder: restore the file)"
            )
        )


def _not_ros2(path: Path) -> str | None:
    """Why the MCAP file(s) of ``path`` are no ROS 2 bag (their header's profile is not "ros2",
    as another program's MCAP files), in words; None when one is, or none can be read (damage:
    the salvage hint applies then)."""
    from mcap.reader import make_reader

    files = sorted(path.glob("*.mcap")) if path.is_dir() else [path]
    profiles = []
    for file in files:
        try:
            with file.open("rb") as handle:
                profiles.append(make_reader(handle).get_header().profile)
        except Exception:  # noqa: BLE001 -- damage: reported elsewhere
            return None
    if not profiles or "ros2" in profiles:
        return None
    return (
        f"MCAP data of another kind (profile {profiles[0]!r}, not 'ros2'): not a ROS 2 bag; "
        "lit replay reads rosbag2 bags (MCAP with the ros2 profile)"
    )


def _mcap_summaries(path: Path) -> list[Any]:
    """The MCAP summary of each MCAP file of a bag (a folder's in name order, or the file given),
    read once for every check that needs one: None for a file without one, the exception for a
    file that cannot be read."""
    from mcap.reader import make_reader

    found: list[Any] = []
    for file in sorted(path.glob("*.mcap")) if path.is_dir() else [path]:
        try:
            with file.open("rb") as handle:
                found.append(make_reader(handle).get_summary())
        except Exception as error:  # noqa: BLE001 -- damaged files raise anything
            found.append(error)
    return found


def _chunk_compression(summaries: Sequence[Any]) -> str:
    """The MCAP chunk compression of a bag's files ("chunks zstd") from their
    :func:`_mcap_summaries`, which rosbag2's metadata does not record; "" when uncompressed or
    unknown (a damaged file: the reader reports it elsewhere)."""
    found: set[str] = set()
    for summary in summaries:
        if summary is not None and not isinstance(summary, Exception):
            found.update(index.compression for index in summary.chunk_indexes if index.compression)
    return f"chunks {', '.join(sorted(found))}" if found else ""


def _mcap_damage(path: Path) -> str | None:
    """What is visibly wrong with the framing of a bag's MCAP file(s) (the magic at both ends),
    in words; None when both ends look right (or there is no MCAP file to look at)."""
    files = sorted(path.glob("*.mcap")) if path.is_dir() else [path]
    for file in files:
        try:
            size = file.stat().st_size
            with file.open("rb") as handle:
                head = handle.read(len(_MCAP_MAGIC))
                handle.seek(max(0, size - len(_MCAP_MAGIC)))
                tail = handle.read(len(_MCAP_MAGIC))
        except OSError:
            continue
        where = f"{file.name} " if path.is_dir() else ""
        if head != _MCAP_MAGIC:
            return f"{where}does not start with the MCAP magic: not an MCAP file, or damaged"
        if size <= len(_MCAP_MAGIC):
            return f"{where}holds only the {size}-byte MCAP magic and no record: truncated"
        if size < 2 * len(_MCAP_MAGIC) or tail != _MCAP_MAGIC:
            return f"{where}does not end with the MCAP magic: truncated (or damaged at its end)"
        try:
            first = _record_header(file, len(_MCAP_MAGIC))
        except OSError:
            continue
        if first is None:
            return f"{where}ends inside its first record's header: truncated"
        length, name = first
        if name != "HEADER":
            return f"{where}its first record is {name}, not the MCAP header: damaged"
        if len(_MCAP_MAGIC) + 9 + length > size:
            # mcap's reader asks for that many bytes at once: a MemoryError without a message.
            return (
                f"{where}its HEADER record at byte {len(_MCAP_MAGIC)} claims {length} bytes, more "
                f"than the file's {size}: the record's length is damaged"
            )
    return None


def _not_cdr(path: Path) -> str | None:
    """The topics of bag ``path`` serialized otherwise than as CDR, which rosbags' reader refuses
    for the whole bag, in words; None when there are none (or none can be told). The error
    blamed damage and sent the user to salvage, which cannot make such a topic readable."""
    topics: dict[str, str] = {}
    metadata_file = path / "metadata.yaml"
    try:
        if path.is_dir() and metadata_file.is_file():  # what rosbags reads
            for entry in load_metadata(metadata_file).get("topics_with_message_count") or []:
                meta = entry["topic_metadata"]
                topics[str(meta["name"])] = str(meta.get("serialization_format", "cdr"))
        else:
            from mcap.reader import make_reader

            for file in sorted(path.glob("*.mcap")) if path.is_dir() else [path]:
                with file.open("rb") as handle:
                    summary = make_reader(handle).get_summary()
                for channel in (summary.channels if summary else {}).values():
                    topics[channel.topic] = channel.message_encoding
    except Exception:  # noqa: BLE001, S110 -- damage: reported elsewhere
        pass
    odd = {topic: form for topic, form in topics.items() if form != "cdr"}
    if not odd:
        return None
    named = ", ".join(f"{topic} ({form})" for topic, form in sorted(odd.items()))
    return (
        f"topics not serialized as CDR: {named}; rosbags, which lit replay reads bags with, "
        "reads no bag that holds one (this is not damage: `lit replay salvage` writes a copy "
        "without them)"
    )


def _metadata_damage(path: Path) -> str | None:
    """What is wrong with a bag folder's ``metadata.yaml`` in words (rosbags says "'NoneType'
    object is not subscriptable" of an empty one); None when it reads as rosbag2 metadata."""
    metadata_file = path / "metadata.yaml"
    if not (path.is_dir() and metadata_file.is_file()):
        return None
    try:
        if not metadata_file.read_text(encoding="utf-8", errors="replace").strip():
            return "its metadata.yaml is empty"
        info = load_metadata(metadata_file)
    except (OSError, ReplayError) as error:
        return str(error)
    # rosbags computes with these and said "TypeError: can only concatenate str (not "int") to
    # str" of a duration that is not a number.
    duration, start = info.get("duration"), info.get("starting_time")
    numbers = {
        "duration.nanoseconds": duration.get("nanoseconds") if isinstance(duration, dict) else 0,
        "starting_time.nanoseconds_since_epoch": (
            start.get("nanoseconds_since_epoch") if isinstance(start, dict) else 0
        ),
        "message_count": info.get("message_count"),
    }
    for entry in info.get("topics_with_message_count") or []:
        if isinstance(entry, dict) and not _whole(entry.get("message_count")):
            numbers["message_count of a topic"] = entry.get("message_count")
    for name, value in numbers.items():
        if value is not None and not _whole(value):
            return f"its metadata.yaml's {name} is {value!r}, not a whole number"
    return None


def _whole(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def load_metadata(path: Path) -> dict[str, Any]:
    """The ``rosbag2_bagfile_information`` of a bag's ``metadata.yaml``.

    Raises:
        ReplayError: not a rosbag2 metadata file (names the file).
    """
    from ruamel.yaml import YAML

    try:
        document = YAML(typ="safe").load(path.read_text(encoding="utf-8"))
        info = document["rosbag2_bagfile_information"]
    except Exception as error:  # noqa: BLE001 -- YAML errors, a damaged file
        raise ReplayError(f"{path}: not a rosbag2 metadata file: {_describe(error)}") from None
    if not isinstance(info, dict):
        raise ReplayError(f"{path}: not a rosbag2 metadata file")
    custom = info.get("custom_data")
    if custom is not None and not isinstance(custom, dict):  # every reader of it failed vaguely
        raise ReplayError(
            f"{path}: its custom_data is a {type(custom).__name__}, not a mapping of names to "
            "values"
        )
    return info


def _describe(error: BaseException) -> str:
    if isinstance(error, MemoryError):
        # mcap's reader allocates what a record's length field claims.
        return "a record claims more bytes than memory holds: its length field is damaged"
    text = " ".join(str(error).split()).rstrip(".") or "no details"
    if len(text) > 200:
        text = text[:200] + "…"
    return f"{type(error).__name__}: {text}"


def decode(message: RawMessage, skipped: Skipped) -> Envelope | Trajectory | None:
    """The envelope or trajectory a message holds; None (and counted in ``skipped``) otherwise."""
    _, base = split_topic(message.topic)
    if base is None:
        skipped.add("foreign topic", message.topic)
        return None
    if message.msgtype == bag.TRAJECTORY_TYPE and base == PATH_TOPIC:
        return _decode_trajectory(message, skipped)
    if message.msgtype != bag.STRING_TYPE:
        skipped.add("unexpected type", message.topic, message.msgtype)
        return None
    try:
        text = bag.typestore().deserialize_cdr(message.data, bag.STRING_TYPE).data
    except Exception as error:  # noqa: BLE001 -- damaged CDR raises anything
        skipped.add("undecodable", message.topic, _describe(error))
        return None
    return parse_envelope(text, message.topic, message.log_ns, skipped)


def parse_envelope(text: str, topic: str, log_ns: int, skipped: Skipped) -> Envelope | None:
    """Check an envelope's fields, schema name and version; None (counted) when it does not fit."""
    try:
        document = json.loads(text)
    except (ValueError, RecursionError):  # nested deeper than Python's stack: one message
        skipped.add("not JSON", topic)
        return None
    if not isinstance(document, dict) or any(key not in document for key in ENVELOPE_KEYS):
        skipped.add("not an envelope", topic, "missing " + ", ".join(
            key for key in ENVELOPE_KEYS if not isinstance(document, dict) or key not in document
        ))  # fmt: skip
        return None
    schema, version, seq = document["schema"], document["version"], document["seq"]
    where = f"{topic} seq {seq}"
    if not isinstance(schema, str) or not known_schema(schema):
        skipped.add("unknown schema", where, str(schema))
        return None
    if type(version) is not int or version < 1:  # damage, not a version some LIT* wrote
        skipped.add("not an envelope", where, f"version {version!r} is not an integer >= 1")
        return None
    if version not in supported_versions(schema):
        skipped.add("unsupported version", where, f"{schema} version {version!r}")
        return None
    integers = (seq, document["stamp_ns"])
    if any(type(value) is not int or value < 0 for value in integers):
        skipped.add("not an envelope", where, "seq and stamp_ns must be integers >= 0")
        return None
    if not isinstance(document["source"], str) or not isinstance(document["run_id"], str):
        skipped.add("not an envelope", where, "source and run_id must be strings")
        return None
    return Envelope(
        topic=topic,
        log_ns=log_ns,
        schema=schema,
        version=version,
        seq=seq,
        stamp_ns=document["stamp_ns"],
        source=document["source"],
        run_id=document["run_id"],
        payload=document["payload"],
    )


def payload_ok(item: Envelope, skipped: Skipped) -> bool:
    """Whether the envelope's payload passes its schema; a payload that fails is counted in
    ``skipped`` as :data:`PAYLOAD_INVALID` (damage). The commands that read payloads (verify,
    bench, tensors) ask this first: a summary without ``scenario`` was a KeyError, or a run
    "without a path". A schema ``lit_msgs_json`` does not ship (``BenchConfig``) passes. An
    older version of a message is held to the current schema, which it passes when it lacks
    only the fields added since (as ``lit_msgs_json.envelope.decode`` takes it)."""
    codec = _codec()
    short = item.schema.removeprefix(SCHEMA_PREFIX)
    if codec is None or short not in _schema_names_shipped():
        return True
    try:
        codec.validate(short, item.payload)
    except codec.SchemaError as error:
        problem = str(error)
    except RecursionError:
        problem = "nested too deeply to validate"
    else:
        return True
    skipped.add(PAYLOAD_INVALID, f"{item.topic} seq {item.seq}", problem)
    return False


@cache
def _codec() -> Any:
    try:
        from lit_msgs_json import codec
    except Exception:  # noqa: BLE001 -- replay must work without the schemas package
        return None
    return codec


@cache
def _schema_names_shipped() -> frozenset[str]:
    codec = _codec()
    return frozenset(codec.schema_names()) if codec is not None else frozenset()


def _decode_trajectory(message: RawMessage, skipped: Skipped) -> Trajectory | None:
    try:
        decoded = bag.typestore().deserialize_cdr(message.data, bag.TRAJECTORY_TYPE)
        path = [[float(x) for x in point.positions] for point in decoded.points]
    except Exception as error:  # noqa: BLE001 -- damaged CDR raises anything
        skipped.add("undecodable", message.topic, _describe(error))
        return None
    return Trajectory(
        message.topic, message.log_ns, decoded.header.frame_id, list(decoded.joint_names), path
    )


# --- info ------------------------------------------------------------------------------------


RESTART_GAP_NS = 500_000_000
"""A publisher's message whose seq it has sent already, stamped this much later than anything it
sent before, comes from a new process of it (see :class:`SeqAccount`)."""


@dataclass
class SeqAccount:
    """The sequence numbers of one publisher: (topic, source, run id) in one process.

    A node restarted under the same name and run id (``lit up`` and compose pass one) counts from
    0 again. Its messages are told apart by their stamps: a seq at or below the highest one seen,
    sent more than :data:`RESTART_GAP_NS` after everything seen so far, starts a new
    ``instance`` (1, 2, ...), accounted on its own. A copy of a message keeps its stamp and a
    message recorded out of order was sent before the later ones, so neither starts one.
    """

    topic: str
    source: str
    instance: int = 1
    seqs: list[int] = field(default_factory=list)
    run_ids: set[str] = field(default_factory=set)
    schemas: Counter[str] = field(default_factory=Counter)
    last_seq: int = -1
    """The highest seq seen."""
    last_stamp_ns: int = -1
    """The latest send time seen."""
    contents: dict[int, int | set[int]] = field(default_factory=dict)
    """Hash of the recorded bytes of each seq's message (a set once a seq has several: a set for
    every seq took about 320 bytes a message)."""
    duplicates: int = 0
    """Messages recorded again: a seq seen before with the same bytes."""
    reused: int = 0
    """Messages under a seq seen before with other bytes (two publishers of one name and run)."""

    def restarted_by(self, seq: int, stamp_ns: int) -> bool:
        """Whether a message (``seq``, ``stamp_ns``) comes from a new process of the publisher."""
        return (
            0 <= self.last_seq
            and seq <= self.last_seq
            and (stamp_ns > self.last_stamp_ns + RESTART_GAP_NS)
        )

    def add(self, item: Envelope, content: bytes) -> None:
        """Account ``item``, whose recorded message is ``content``."""
        digest = hash(content)
        seen = self.contents.get(item.seq)
        if seen is None:
            self.contents[item.seq] = digest
        elif seen == digest or (isinstance(seen, set) and digest in seen):
            self.duplicates += 1
        else:
            self.reused += 1
            self.contents[item.seq] = (seen if isinstance(seen, set) else {seen}) | {digest}
        self.seqs.append(item.seq)
        self.run_ids.add(item.run_id)
        self.schemas[item.schema] += 1
        self.last_seq = max(self.last_seq, item.seq)
        self.last_stamp_ns = max(self.last_stamp_ns, item.stamp_ns)

    def to_dict(self) -> dict[str, Any]:
        """First/last seq, count, gaps, missing, duplicates, reused seqs, leading, run ids and
        schemas."""
        unique = sorted(set(self.seqs))
        steps = [b - a for a, b in itertools.pairwise(unique)]
        reordered = sum(1 for a, b in itertools.pairwise(self.seqs) if b < a)
        return {
            "topic": self.topic,
            "source": self.source,
            "instance": self.instance,
            "run_ids": sorted(self.run_ids),
            "first_seq": unique[0],
            "last_seq": unique[-1],
            "count": len(self.seqs),
            "gaps": sum(1 for step in steps if step > 1),
            "missing": sum(step - 1 for step in steps if step > 1),
            "duplicates": self.duplicates,
            "reused": self.reused,
            "reordered": reordered,
            "leading": unique[0],
            "schemas": dict(self.schemas),
        }


def bag_info(path: str | Path) -> dict[str, Any]:
    """Everything ``lit replay info`` reports, as JSON-ready data."""
    skipped = Skipped()
    accounts: dict[tuple[str, str, str], list[SeqAccount]] = {}  # a publisher's processes
    schemas: Counter[str] = Counter()
    counts: Counter[str] = Counter()
    trajectories = 0
    first_ns, last_ns = None, None
    with BagReader(path) as reader:
        facts = reader.facts
        for message in reader.messages():
            counts[message.topic] += 1
            first_ns = message.log_ns if first_ns is None else min(first_ns, message.log_ns)
            last_ns = message.log_ns if last_ns is None else max(last_ns, message.log_ns)
            item = decode(message, skipped)
            if isinstance(item, Trajectory):
                trajectories += 1
            elif isinstance(item, Envelope):
                instances = accounts.setdefault((item.topic, item.source, item.run_id), [])
                if not instances or instances[-1].restarted_by(item.seq, item.stamp_ns):
                    instances.append(SeqAccount(item.topic, item.source, len(instances) + 1))
                instances[-1].add(item, message.data)
                schemas[item.schema] += 1
    types = {t.topic: t.msgtype for t in facts.topics}
    return {
        "bag": str(facts.path),
        "storage": facts.storage,
        "rosbag2_version": facts.version,
        "ros_distro": facts.ros_distro,
        "compression": facts.compression,
        "custom_data": facts.custom_data,
        "messages": sum(counts.values()),
        "start_ns": first_ns,
        "end_ns": last_ns,
        "start": _iso(first_ns),
        "end": _iso(last_ns),
        "duration_s": None if first_ns is None else (last_ns - first_ns) / 1e9,
        "topics": [
            {"topic": t.topic, "type": t.msgtype, "messages": counts.get(t.topic, 0)}
            for t in facts.topics
        ]
        + [
            {"topic": topic, "type": "?", "messages": count}
            for topic, count in sorted(counts.items())
            if topic not in types
        ],
        "publishers": [account.to_dict() for key in sorted(accounts) for account in accounts[key]],
        "schemas": dict(sorted(schemas.items())),
        "trajectories": trajectories,
        "skipped": skipped.to_dict(),
    }


def _iso(stamp_ns: int | None) -> str | None:
    if stamp_ns is None:
        return None
    moment = datetime.fromtimestamp(stamp_ns / 1e9, UTC)
    return moment.isoformat(timespec="milliseconds").replace("+00:00", "Z")


def format_info(info: dict[str, Any]) -> str:
    """``info`` as text for people."""
    lines = [
        f"bag         {info['bag']}",
        (
            f"storage     {info['storage'] or '?'}, rosbag2 version "
            f"{info['rosbag2_version'] or '?'}, ros_distro {info['ros_distro'] or '?'}, "
            f"compression {info['compression'] or 'none'}"
        ),
    ]
    if info["start_ns"] is None:
        lines.append("messages    0")
    else:
        lines.append(
            f"messages    {info['messages']} from {info['start']} to {info['end']} "
            f"(duration {info['duration_s']:.3f} s)"
        )
    lines.append("run         " + (", ".join(
        f"{SafeLogger.text(key)}={SafeLogger.text(value)}"
        for key, value in sorted(info["custom_data"].items())
    ) or "no metadata"))  # fmt: skip
    lines.append("topics")
    width = max([len(t["topic"]) for t in info["topics"]] + [5])
    for topic in info["topics"]:
        name, kind = SafeLogger.text(topic["topic"]), SafeLogger.text(topic["type"])
        lines.append(f"  {name:<{width}}  {kind:<38} {topic['messages']:>8}")
    lines.append("publishers (seq per topic and source)")
    if not info["publishers"]:
        lines.append("  none")
    for pub in info["publishers"]:
        problems = [
            f"{pub[key]} {key}"
            for key in ("gaps", "missing", "duplicates", "reordered")
            if pub[key]
        ]
        if pub["reused"]:  # not copies: other messages under seqs seen already
            problems.append(f"{pub['reused']} reused seqs (two publishers of one name and run?)")
        restart = f", process {pub['instance']}" if pub["instance"] > 1 else ""
        lines.append(
            f"  {SafeLogger.text(pub['topic'])} from {SafeLogger.text(pub['source'])} "
            f"(run {', '.join(map(SafeLogger.text, pub['run_ids']))}{restart}): "
            f"seq {pub['first_seq']}..{pub['last_seq']}, {pub['count']} messages, "
            + (", ".join(problems) if problems else "no gaps")
            + (f", {pub['leading']} before the first" if pub["leading"] else "")
            + f"; {', '.join(map(SafeLogger.text, pub['schemas']))}"
        )
    skipped = info["skipped"]
    lines.append(f"skipped     {Skipped(Counter(skipped['reasons'])).line()}")
    lines.extend(f"  {SafeLogger.text(example)}" for example in skipped["examples"])
    return "\n".join(lines)


# --- verify ----------------------------------------------------------------------------------


@dataclass
class VerifyReport:
    """Counts of ``verify``."""

    checked: int = 0
    valid: int = 0
    invalid: list[str] = field(default_factory=list)
    disagreements: list[str] = field(default_factory=list)
    unsolved: int = 0
    unchecked: Skipped = field(default_factory=Skipped)
    seen: dict[tuple[str, str, str, int, int], bytes] = field(default_factory=dict)
    """The records checked (:func:`read_before`: a copy's are checked once)."""
    seqs: dict[tuple[str, str, str, str], set[int]] = field(default_factory=dict)
    """The seqs of the run records read, by (schema, topic, source, run id)."""

    def missing(self) -> int:
        """Run records absent from the bags: the numbers missing between a publisher's first
        and last seq, and for ``lit bench``'s records (whose writer numbers them from 0 in the
        bag it writes) those before its first one. A recording that began after a ROS
        publisher had sent episodes does not count them as missing; records lost at a bag's end
        cannot be counted."""
        missing = 0
        for (schema, *_), seqs in self.seqs.items():
            ordered = sorted(seqs)
            missing += sum(b - a - 1 for a, b in itertools.pairwise(ordered))
            if schema == bag.BENCH_RUN_SCHEMA:
                missing += ordered[0]
        return missing


VERIFIED_SCHEMAS = frozenset({bag.BENCH_RUN_SCHEMA, EPISODE_SCHEMA})
"""The envelopes ``verify`` reads (with the ``/lit/path`` trajectories)."""


def verify_bag(path: str | Path, report: VerifyReport) -> Skipped:
    """Re-check every path of a bag (BenchRun records; episodes with their ``/lit/path``); a
    record that a bag checked before into ``report`` held is skipped as read twice."""
    skipped = Skipped()
    episodes: list[Envelope] = []
    trajectories: list[Trajectory] = []
    with BagReader(path) as reader:
        for message in reader.messages():
            item = decode(message, skipped)
            if isinstance(item, Envelope) and item.schema in VERIFIED_SCHEMAS and item.seq >= 0:
                key = (item.schema, item.topic, item.source, item.run_id)
                report.seqs.setdefault(key, set()).add(item.seq)
            if isinstance(item, Envelope | Trajectory):
                again = read_before(report.seen, item, message.data)
                if again is not None:
                    skipped.counts[again] += 1
                    continue
            if isinstance(item, Trajectory):
                trajectories.append(item)
            elif (
                not isinstance(item, Envelope)
                or item.schema not in VERIFIED_SCHEMAS
                or not on_its_topic(item, skipped)
                or not payload_ok(item, skipped)
            ):
                continue
            elif item.schema == bag.BENCH_RUN_SCHEMA:
                _verify_bench_run(item, report)
            else:
                episodes.append(item)
    for episode, path_item in _pair_episodes(episodes, trajectories, report):
        payload = episode.payload
        where = f"{episode.topic} seq {episode.seq}"
        if path_item is None:
            report.unsolved += 1
            continue
        scenario, instance = _episode_scenario(payload)
        _check(
            report,
            where,
            scenario,
            instance,
            path_item,
            payload.get("path_valid"),
            world=payload.get("world"),
        )
    return skipped


def _verify_bench_run(item: Envelope, report: VerifyReport) -> None:
    record = item.payload
    where = f"{item.topic} seq {item.seq}"
    if not isinstance(record, dict):
        report.unchecked.add("payload not an object", where)
        return
    if not record.get("solved"):
        report.unsolved += 1
        return
    if not record.get("path"):  # was counted as unsolved: verify passed a run it never checked
        report.unchecked.add("solved without a path", where)
        return
    label = f"{where} ({record.get('planner')} run {record.get('run')})"
    _check(
        report,
        label,
        record.get("scenario"),
        record.get("instance"),
        record.get("path"),
        record.get("path_valid"),
    )


def _episode_scenario(payload: dict[str, Any]) -> tuple[Any, Any]:
    key = payload.get("scenario_key") or payload.get("scenario")
    return key, (None if isinstance(key, str) and "/" in key else payload.get("instance"))


def _pair_episodes(
    episodes: list[Envelope], trajectories: list[Trajectory], report: VerifyReport
) -> Iterator[tuple[Envelope, Any]]:
    """Each episode with its path, or None when it has none (unsolved).

    An episode's path is the ``/lit/path`` message of the same namespace whose ``frame_id`` is the
    episode's ``episode_id`` (what the planner node writes), else the one recorded closest in time
    among those not claimed by another episode's id; each path serves one episode.
    """
    by_namespace: dict[str, list[Trajectory]] = {}
    for trajectory in sorted(trajectories, key=lambda t: t.log_ns):
        namespace, _ = split_topic(trajectory.topic)
        by_namespace.setdefault(namespace or "", []).append(trajectory)
    ids = {
        (e.namespace, e.payload.get("episode_id"))
        for e in episodes
        if isinstance(e.payload, dict) and e.payload.get("episode_id")
    }
    used: set[int] = set()
    for episode in episodes:
        payload = episode.payload
        where = f"{episode.topic} seq {episode.seq}"
        if not isinstance(payload, dict):
            report.unchecked.add("payload not an object", where)
            continue
        candidates = by_namespace.get(episode.namespace, [])
        episode_id = payload.get("episode_id")
        match = next(
            (
                t
                for t in candidates
                if episode_id and t.frame_id == episode_id and id(t) not in used
            ),
            None,
        )
        # A path the node's own check found invalid is never published: none is its by time.
        flagged = bool(payload.get("solved")) and payload.get("path_valid") is False
        if match is None and not flagged:
            free = [t for t in candidates if (episode.namespace, t.frame_id) not in ids]
            index = _nearest_unused([t.log_ns for t in free], episode.log_ns, used, free)
            match = None if index is None else free[index]
        if match is not None:
            used.add(id(match))
        if payload.get("solved") is False:  # an approximate path is no solution to check
            yield episode, None
        elif match is not None and match.path:
            yield episode, match.path
        elif flagged:
            # The planner node does not publish a path its own check (the one done here) finds
            # invalid, but it returned it: an invalid path, not one that cannot be checked.
            report.checked += 1
            report.invalid.append(
                f"{where}: the planner node's own check found the path it returned invalid "
                f"(such a path is not published on {PATH_TOPIC})"
            )
        elif payload.get("solved"):
            report.unchecked.add("solved episode without a recorded path", where)
        else:
            yield episode, None
    for namespace, candidates in by_namespace.items():
        for trajectory in candidates:
            if id(trajectory) not in used and trajectory.path:
                report.unchecked.add("path without an episode", f"{namespace}{PATH_TOPIC}")


def _nearest_unused(
    times: list[int], target: int, used: set[int], items: Sequence[object]
) -> int | None:
    position = bisect.bisect_left(times, target)
    left, right = position - 1, position
    while left >= 0 or right < len(times):
        left_gap = target - times[left] if left >= 0 else math.inf
        right_gap = times[right] - target if right < len(times) else math.inf
        index = left if left_gap <= right_gap else right
        if id(items[index]) not in used:
            return index
        if index == left:
            left -= 1
        else:
            right += 1
    return None


def _check(
    report: VerifyReport,
    where: str,
    scenario_name: Any,
    instance: Any,
    path: Any,
    recorded_valid: Any,
    *,
    world: Any = None,
) -> None:
    """Re-check ``path`` in the registry's scenario ``scenario_name`` (instance ``instance``), or
    in ``world`` (an EpisodeSummary's ``world``: a custom scenario's bounds, boxes, resolution,
    start and goal) when given."""
    if not isinstance(scenario_name, str):
        report.unchecked.add("no scenario name", where)
        return
    try:
        if world is not None:
            problem = scenarios.from_world(world, world["start"], world["goal"])
        elif scenario_name.startswith(scenarios.CUSTOM_FAMILY):
            report.unchecked.add(
                "custom world not recorded",
                where,
                f"{scenario_name}: recorded before EpisodeSummary version 2 carried the world",
            )
            return
        else:
            problem = scenarios.get(scenario_name, instance if isinstance(instance, int) else None)
        check = scenarios.check_path(problem, path)
    except (LitPlannerError, ValueError, TypeError, KeyError) as error:
        report.unchecked.add("cannot check", where, _describe(error))
        return
    report.checked += 1
    if check.ok:
        report.valid += 1
    else:
        if not check.valid:
            reason = (
                f"segment {check.first_invalid_index} leaves the free space at "
                f"({', '.join(f'{x:.4g}' for x in check.first_invalid_point or ())})"
            )
        else:
            reason = "does not start at the start" if not check.starts_at_start else ""
            reason = reason or "does not end at the goal"
        report.invalid.append(f"{where}: {problem.key}: {reason}")
    if isinstance(recorded_valid, bool) and recorded_valid != check.ok:
        report.disagreements.append(
            f"{where}: recorded path_valid={recorded_valid}, re-check says {check.ok}"
        )


# --- salvage ---------------------------------------------------------------------------------


@dataclass
class SalvageResult:
    """What ``salvage`` read from one MCAP file."""

    file: Path
    """The file."""
    size: int
    """Its size in bytes."""
    stopped_at: int = 0
    """Byte offset where reading stopped: the end of the last readable record."""
    complete: bool = False
    """The file was read to its end: every record, the footer and the end magic."""
    reason: str = ""
    """Why reading stopped."""
    messages: dict[str, int] = field(default_factory=dict)
    """Messages recovered per topic."""
    dropped: int = 0
    """Messages read but dropped: no channel or schema, a definition that does not parse, a
    serialization other than CDR, or bytes that do not deserialize."""
    dropped_why: dict[str, int] = field(default_factory=dict)
    """The dropped messages per topic and reason (``<topic>: <reason>``)."""
    damaged_chunks: list[str] = field(default_factory=list)
    """Chunks whose inner records broke off (the records before the break are kept)."""
    notes: list[str] = field(default_factory=list)
    """Other damage found and what was done about it: records skipped, chunks read through the
    summary's chunk index."""
    copies: dict[Path, int] = field(default_factory=dict)
    """Messages left out as copies of those of an earlier file (same topic, time and bytes)."""
    left_out: bool = False
    """Not read: not a file, or empty (``reason`` says which)."""


class _StrictStream:
    """A read-only file wrapper that counts bytes and raises on a short read (truncation)."""

    def __init__(self, handle: Any) -> None:
        self._handle = handle
        self.position = 0

    def read(self, size: int = -1) -> bytes:
        data = self._handle.read(size)
        self.position += len(data)
        if size > 0 and len(data) < size:
            raise EOFError(
                f"end of file at byte {self.position} inside a record ({size} bytes wanted)"
                if data
                else f"end of file at byte {self.position}"
            )
        return bytes(data)


@dataclass
class _Salvaged:
    """Records gathered from the files; messages are resolved against the channels at the end
    (a damaged first chunk loses the channel records that the summary section repeats).
    Schemas and channels are kept by (file, id): MCAP ids are unique within one file only (two
    files of a folder numbered their channels differently, and messages went under each
    other's topics)."""

    schemas: dict[tuple[Path, int], Any] = field(default_factory=dict)
    channels: dict[tuple[Path, int], Any] = field(default_factory=dict)
    messages: list[tuple[SalvageResult, int, int, bytes]] = field(default_factory=list)
    unverified: set[tuple[str, Path, int]] = field(default_factory=set)
    """Schemas and channels taken from a chunk whose CRC-32 failed or that was cut off."""

    def take(self, record: object, result: SalvageResult, verified: bool = True) -> None:
        """Keep ``record``. A schema or channel id seen again keeps its first record, which is
        the data section's (the summary repeats it), unless that one is unverified: a flipped
        bit in the summary's copy of a schema name made salvage drop every message of it."""
        from mcap.records import Channel, Message, Schema

        if isinstance(record, Message):
            self.messages.append((result, record.channel_id, record.log_time, record.data))
            return
        if not isinstance(record, Schema | Channel):
            return
        kind, kept = (
            ("schema", self.schemas) if isinstance(record, Schema) else ("channel", self.channels)
        )
        key = (result.file, record.id)
        if key in kept and (kind, *key) not in self.unverified:
            return
        kept[key] = record
        if verified:
            self.unverified.discard((kind, *key))
        else:
            self.unverified.add((kind, *key))


def salvage(
    source: str | Path, out: str | Path | None = None, keep_unverified: bool = False
) -> tuple[Path, list[SalvageResult]]:
    """Read everything readable from a bag's MCAP file(s) and write it as a new, valid bag.

    Each file is read with ``mcap``'s ``StreamReader`` up to the first record that cannot be
    read (a truncation, a damaged record header); a chunk whose inner records break off keeps the
    records before the break and reading goes on with the next chunk; a chunk cut off by the end
    of the file gives its complete inner records (of a zstd chunk, those the compressed bytes
    present decode to). Chunks that the summary's chunk index lists and that were not read (after
    the record that stopped the reading, or behind a damaged record header) are then read at the
    index's offsets. Every message must belong to a known channel and deserialize as its type.
    A chunk whose CRC-32 does not match loses its messages, unless ``keep_unverified``: then
    those that read are kept, and the result's ``damaged_chunks`` say how many.

    Returns:
        The new bag and, per file, where reading stopped and the messages recovered per topic.

    Raises:
        ReplayError: no bag there, the output exists, or nothing could be recovered.
    """
    source = _named(Path(source))
    files, unusable = _mcap_files(source)
    if out is not None:
        target = Path(out)
    elif source.is_dir():
        target = source.with_name(source.name + SALVAGED_SUFFIX)
    else:
        target = source.with_name(source.stem + SALVAGED_SUFFIX)
    if target.exists():
        raise ReplayError(f"{target} exists already; choose another output with -o")
    gathered = _Salvaged()
    results = [SalvageResult(path, path.stat().st_size) for path in files]
    for result in results:
        _read_mcap(result, gathered, keep_unverified)
    kept: list[tuple[Any, Any, int, bytes]] = []
    # A message another file of the folder held already (the same topic, time and bytes: a
    # copy of a file beside it) is written once.
    first_file: dict[tuple[str, int, bytes], Path] = {}
    # A type Jazzy lacks is written with the definition its topic's first message came with: one
    # that came with another (two files recorded apart) would be written under the wrong one.
    definitions: dict[tuple[str, str], bytes] = {}
    for result, channel_id, log_ns, data in gathered.messages:
        channel = gathered.channels.get((result.file, channel_id))
        schema = (
            gathered.schemas.get((result.file, channel.schema_id)) if channel is not None else None
        )
        why = (
            f"channel {channel_id}: no channel record"
            if channel is None
            else f"{channel.topic}: no schema record"
            if schema is None
            else _unusable(channel, schema, data)
        )
        if why is None and schema.name not in bag.typestore().types:  # Jazzy's: its own definition
            first = definitions.setdefault((channel.topic, schema.name), bytes(schema.data))
            if first != bytes(schema.data):
                why = (
                    f"{channel.topic}: its definition of {schema.name} differs from the one its "
                    "earlier messages came with"
                )
        if why is not None:
            result.dropped += 1
            result.dropped_why[why] = result.dropped_why.get(why, 0) + 1
            continue
        where = (
            first_file.setdefault((channel.topic, log_ns, data), result.file)
            if len(files) > 1
            else result.file
        )
        if where != result.file:
            result.copies[where] = result.copies.get(where, 0) + 1
            continue
        kept.append((channel, schema, log_ns, data))
        result.messages[channel.topic] = result.messages.get(channel.topic, 0) + 1
    results += [SalvageResult(path, 0, reason=why, left_out=True) for path, why in unusable.items()]
    if not kept:
        where = "; ".join(
            f"{r.file}: "
            + (r.reason if r.left_out else f"stopped at byte {r.stopped_at}: {r.reason}")
            + "".join(f"; damaged {damage}" for damage in r.damaged_chunks)
            + "".join(f"; {n} messages dropped ({why})" for why, n in r.dropped_why.items())
            for r in results
        )
        raise ReplayError(f"nothing to salvage from {source} ({where})")
    _write_salvaged(target, source, kept, results)
    return target, results


def _named(path: Path) -> Path:
    """``path`` resolved when it has no name of its own (``.``, ``..``): the salvaged copy is
    named after the bag's folder (``salvage .`` failed with "PosixPath('.') has an empty name",
    and ``compact . OUT`` recorded an empty ``lit.compacted_from``)."""
    return path.resolve() if path.name in ("", "..") else path


def _mcap_files(source: Path) -> tuple[list[Path], dict[Path, str]]:
    """The MCAP files to read of bag folder or file ``source``, and those of a folder left out
    with the reason (an empty file, a folder or a link to nothing named ``*.mcap``: `lit replay
    info` sends such a folder here to be rebuilt from its other files, and salvage refused it
    whole)."""
    if not source.exists():
        raise ReplayError(f"{source}: no such file or directory")
    if source.is_dir():
        if not any(source.iterdir()):
            raise ReplayError(f"{source} is an empty directory, not a bag")
        files = sorted(source.glob("*.mcap"))
        if not files:
            if (source / "metadata.yaml").is_file():
                _check_storage(source)
            raise ReplayError(f"{source} holds no .mcap file to salvage")
    else:
        files = [source]
    unusable: dict[Path, str] = {}
    for path in files:
        if not path.is_file():  # a folder named *.mcap, a dangling link: raw OSError text before
            unusable[path] = "not a file (a folder, or a link to nothing)"
        elif path.stat().st_size == 0:
            unusable[path] = "an empty file"
    usable = [path for path in files if path not in unusable]
    if not usable:
        raise ReplayError("; ".join(f"{path} is {why}" for path, why in unusable.items()))
    return usable, unusable


def _salvage_reader(stream: _StrictStream, size: int, path: Path) -> Any:
    """A ``StreamReader`` that emits chunks and notes where each chunk record starts and which
    records it skipped for an unknown opcode (a damaged opcode byte: the stock reader skips such
    a record without a word, and a chunk's messages went missing from a "complete" file).
    Overrides the reader's ``_read_record`` (mcap 1.6.0, pinned in requirements.lock)."""
    from mcap.opcode import Opcode
    from mcap.stream_reader import StreamReader

    known = {int(opcode) for opcode in Opcode}

    class Reader(StreamReader):
        last_start = 0
        """Where the record read last starts."""
        chunk_starts: set[int]
        """Where the chunks read whole start (the loop adds them)."""
        skipped: list[tuple[int, int, int]]
        """(start, opcode, length) of the records skipped for their opcode."""
        misplaced_footers: list[tuple[int, int]]
        """(start, length) of the footer records skipped for not ending the file."""
        record_lengths: list[tuple[int, int, int]]
        """(start, length the record says, length its chunk's fields give) of the chunk records
        read by their records-length field."""
        chunk_lengths: list[tuple[int, int, int, bool]]
        """(start, records length the chunk's field says, bytes its record holds after the
        fields, whether the chunk was left unread) of the chunks whose field and record length
        disagree."""

        def _read_record(self, opcode: int, length: int) -> Any:
            self.last_start = stream.position - 9  # the opcode and length were just read
            if opcode not in known:
                self.skipped.append((self.last_start, opcode, length))
            if opcode == Opcode.FOOTER and not _footer_ends_file(path, self.last_start, size):
                # A damaged opcode byte (a chunk's 0x06 read as 0x02) ended the reading as if
                # the file ended there, and every chunk after it was lost: skipped, the chunk is
                # read through the summary's chunk index.
                self.misplaced_footers.append((self.last_start, length))
                self._stream.read(length)
                return None
            if opcode == Opcode.CHUNK:
                # The whole record is read, so the next record starts where this one says it
                # ends (a records-length field claiming more read on into the next record).
                body = self._stream.read(length)
                chunk, disagreement = _chunk_of_record(body)
                if chunk is None and disagreement is not None:
                    # The field claims more: the record's length may be the damaged one (short).
                    # The rest of the records as the field gives them, when they check out,
                    # also puts the reading back in step with the next record.
                    extra = disagreement[0] - disagreement[1]
                    if stream.position + extra <= size:
                        with path.open("rb") as handle:  # looked at, not taken from the stream
                            handle.seek(stream.position)
                            more = handle.read(extra)
                        by_field, _ = _chunk_of_record(body + more)
                        if by_field is not None and _chunk_checks_out(by_field):
                            self._stream.read(extra)
                            self.record_lengths.append((self.last_start, length, length + extra))
                            return by_field
                if disagreement is not None:
                    self.chunk_lengths.append((self.last_start, *disagreement, chunk is None))
                return chunk
            return super()._read_record(opcode, length)

    # The size limit keeps a damaged length field from allocating gigabytes.
    source: Any = stream  # StreamReader only calls read(); its annotation lists file types
    reader = Reader(source, emit_chunks=True, record_size_limit=max(1, size))
    reader.chunk_starts, reader.skipped = set(), []
    reader.misplaced_footers, reader.chunk_lengths, reader.record_lengths = [], [], []
    return reader


def _footer_ends_file(path: Path, start: int, size: int) -> bool:
    """Whether a footer record at byte ``start`` of ``path`` is the file's footer: the end magic
    follows its 29 bytes, or what the end of the file left of it."""
    with path.open("rb") as handle:
        handle.seek(start + 29)  # opcode, length, summary start, summary offset start, CRC
        after = handle.read(len(_MCAP_MAGIC))
    return after == _MCAP_MAGIC or (
        start + 29 + len(after) == size and _MCAP_MAGIC.startswith(after)
    )


def _chunk_fields(body: bytes) -> tuple[Any, int, int]:
    """(the chunk of a CHUNK record's ``body`` with everything after its fields as its records,
    the byte where they start, the records length its own field says).

    Raises:
        ValueError: the fields do not fit in the body, or the compression name is not UTF-8.
    """
    import struct

    from mcap.records import Chunk

    try:
        start_ns, end_ns, uncompressed_size, crc, name_length = struct.unpack_from("<QQQII", body)
        fields = 32 + name_length + 8
        compression = body[32 : fields - 8].decode("utf-8")
        (declared,) = struct.unpack_from("<Q", body, fields - 8)
    except (struct.error, UnicodeDecodeError) as error:
        raise ValueError(f"chunk fields unreadable: {_error_text(error)}") from None
    chunk = Chunk(
        compression=compression,
        data=body[fields:],
        message_start_time=start_ns,
        message_end_time=end_ns,
        uncompressed_crc=crc,
        uncompressed_size=uncompressed_size,
    )
    return chunk, fields, declared


def _chunk_of_record(body: bytes) -> tuple[Any, tuple[int, int] | None]:
    """The chunk a whole CHUNK record's ``body`` holds, and (the records length its own field
    says, the bytes the record holds after the fields) when the two disagree and the record's
    length was taken; None for the chunk when the field claims more than the record holds and
    the record's records do not check out (the record's length may be the damaged one).

    MCAP's reading comes first: the records as the field gives them, the rest of the record
    padding. When that does not check out (its CRC, or without one its records reading to the
    end) and all that follows the fields does, the field is the damaged one (it cut the data
    short and the CRC failed).

    Raises:
        ValueError: the fields do not fit in the body, or the compression name is not UTF-8.
    """
    import dataclasses

    by_record, fields, declared = _chunk_fields(body)
    if fields + declared == len(body):
        return by_record, None
    if fields + declared > len(body):  # the field, or the record's length, is damaged
        return by_record if _chunk_checks_out(by_record) else None, (declared, len(by_record.data))
    by_field = dataclasses.replace(by_record, data=by_record.data[:declared])
    if not _chunk_checks_out(by_field) and _chunk_checks_out(by_record):
        return by_record, (declared, len(by_record.data))
    return by_field, None


def _chunk_checks_out(chunk: Any) -> bool:
    """Whether a chunk's records match its CRC-32 (when written), or else read to their end."""
    import zlib

    try:
        data = _chunk_data(chunk)
        if chunk.uncompressed_crc:
            return zlib.crc32(data) == chunk.uncompressed_crc
        for _ in _inner_records(data, chunk):
            pass
    except Exception:  # noqa: BLE001 -- damaged records raise anything
        return False
    return True


def _read_mcap(result: SalvageResult, gathered: _Salvaged, keep_unverified: bool = False) -> None:
    """Gather every readable record of ``result.file``; note where and why reading stopped.
    Chunks that the summary's chunk index lists but that were not read (a damaged record header,
    or reading stopped before them) are read through the index afterwards."""
    from mcap.records import Chunk, ChunkIndex, Footer

    footer = False
    indexes: list[Any] = []
    with result.file.open("rb") as handle:
        stream = _StrictStream(handle)
        reader = _salvage_reader(stream, result.size, result.file)
        try:
            for record in reader.records:
                if isinstance(record, Chunk):
                    reader.chunk_starts.add(reader.last_start)
                    try:
                        for inner, verified in _chunk_records(record, keep_unverified):
                            gathered.take(inner, result, verified)
                    except Exception as error:  # noqa: BLE001 -- damaged chunk content
                        result.damaged_chunks.append(
                            f"chunk ending at byte {stream.position}: {_error_text(error)}"
                        )
                else:
                    gathered.take(record, result)
                    if isinstance(record, ChunkIndex):
                        indexes.append(record)
                result.stopped_at = stream.position
                footer = footer or isinstance(record, Footer)
        except Exception as error:  # noqa: BLE001 -- truncation, bit flips: anything
            if result.stopped_at == 0 and stream.position >= len(_MCAP_MAGIC):
                result.stopped_at = _magic_length(result.file)
            result.reason = _stop_reason(error, result, gathered, footer, stream.position)
        else:
            result.stopped_at = stream.position
            result.complete = True
            result.reason = "complete file"
    for start, opcode, length in reader.skipped:
        result.notes.append(
            f"skipped the record at byte {start} ({9 + length} bytes): its opcode 0x{opcode:02x} "
            "is not an MCAP record type (a damaged byte, or a newer writer's record)"
        )
    for start, length in reader.misplaced_footers:
        result.notes.append(
            f"skipped the record at byte {start} ({9 + length} bytes): its opcode says footer, "
            "but a footer ends the file (a damaged byte)"
        )
    for start, said, given in reader.record_lengths:
        result.notes.append(
            f"the chunk at byte {start}: its record says {said} bytes, its fields give "
            f"{given}; read by the fields (the record's length is damaged)"
        )
    for start, declared, actual, unread in reader.chunk_lengths:
        result.notes.append(
            f"the chunk at byte {start}: its records-length field says {declared} bytes, its "
            f"record holds {actual}; "
            + (
                "one of the two lengths is damaged: left to the summary's chunk index"
                if unread
                else "read by the record's length (the field's reading did not check out)"
            )
        )
    if not footer:
        indexes = _summary_chunk_indexes(result, gathered)
    _read_indexed_chunks(result, gathered, indexes, reader.chunk_starts, keep_unverified)


def _summary_chunk_indexes(result: SalvageResult, gathered: _Salvaged) -> list[Any]:
    """The chunk indexes of the summary section that the footer at the end of the file points
    to, for a file whose reading stopped early; its schema and channel records go to
    ``gathered``. Empty when the file has no intact footer or summary."""
    import io

    from mcap.records import ChunkIndex
    from mcap.stream_reader import StreamReader

    footer_start = result.size - len(_MCAP_MAGIC) - 29  # opcode, length, 8 + 8 + 4 bytes
    if footer_start <= len(_MCAP_MAGIC):
        return []
    with result.file.open("rb") as handle:
        handle.seek(footer_start)
        tail = handle.read()
        if tail[:9] != b"\x02" + (20).to_bytes(8, "little") or tail[29:] != _MCAP_MAGIC:
            return []
        summary_start = int.from_bytes(tail[9:17], "little")
        if not len(_MCAP_MAGIC) < summary_start < footer_start:
            return []
        handle.seek(summary_start)
        summary = handle.read()
    indexes: list[Any] = []
    try:
        for record in StreamReader(io.BytesIO(summary), skip_magic=True).records:
            if isinstance(record, ChunkIndex):
                indexes.append(record)
            else:
                gathered.take(record, result)
    except Exception:  # noqa: BLE001, S110 -- a damaged summary: the indexes read so far
        pass
    return indexes


def _read_indexed_chunks(
    result: SalvageResult,
    gathered: _Salvaged,
    indexes: Sequence[Any],
    read: set[int],
    keep_unverified: bool = False,
) -> None:
    """Read each chunk that ``indexes`` list and that was not read as a chunk (``read``: the
    chunk records' starts), at its indexed offset and length."""
    from mcap.records import Message

    for index in sorted(indexes, key=lambda i: i.chunk_start_offset):
        start, length = index.chunk_start_offset, index.chunk_length
        if start in read or not len(_MCAP_MAGIC) <= start < start + 9 < start + length:
            continue
        if start + length > result.size:
            continue  # beyond a truncation: the chunk is not there
        read.add(start)
        with result.file.open("rb") as handle:
            handle.seek(start + 9)  # the index's length stands in for a damaged header's
            body = handle.read(length - 9)
        messages = 0
        try:
            chunk, disagreement = _chunk_of_record(body)
            if chunk is None:
                raise ValueError(
                    f"its records-length field says {disagreement[0]} bytes, more than the "  # type: ignore[index]
                    f"{disagreement[1]} the chunk index gives it"  # type: ignore[index]
                )
            if disagreement is not None:
                result.notes.append(
                    f"the chunk at byte {start}: its records-length field says "
                    f"{disagreement[0]} bytes, the chunk index gives {disagreement[1]}; read by "
                    "the index's length (the field's reading did not check out)"
                )
            for inner, verified in _chunk_records(chunk, keep_unverified):
                gathered.take(inner, result, verified)
                messages += isinstance(inner, Message)
        except Exception as error:  # noqa: BLE001 -- the chunk itself is damaged too
            result.damaged_chunks.append(
                f"chunk at byte {start} (read through the summary's chunk index): "
                f"{_error_text(error)}"
            )
            continue
        result.notes.append(
            f"read the chunk at byte {start} ({messages} messages) through the summary's "
            "chunk index"
        )


def _stop_reason(
    error: Exception, result: SalvageResult, gathered: _Salvaged, footer: bool, position: int
) -> str:
    """Why reading ``result.file`` stopped at ``result.stopped_at``, in words; a chunk cut off by
    the end of the file gives its complete inner records to ``gathered`` first."""
    from mcap.exceptions import EndOfFile, InvalidMagic

    start, size = result.stopped_at, result.size
    if isinstance(error, InvalidMagic):
        if footer:
            return "the 8 bytes after the footer are not the MCAP end magic: the end is damaged"
        return "the file does not start with the MCAP magic: not an MCAP file, or damaged"
    if footer:
        return (
            f"the MCAP end magic after the footer is missing ({size - start} of its 8 bytes "
            "present): the file is cut short after its last record; every record was read"
        )
    if isinstance(error, EOFError | EndOfFile) and position == start:
        if start <= len(_MCAP_MAGIC):
            return "end of file after the MCAP magic: no record (the writer did not finish)"
        return "end of file without footer (the writer did not finish)"
    if size < len(_MCAP_MAGIC):
        with result.file.open("rb") as handle:
            head = handle.read(size)
        if _MCAP_MAGIC.startswith(head):
            return (
                f"the file ends inside the MCAP magic ({size} of its {len(_MCAP_MAGIC)} bytes): "
                "truncated before its first record"
            )
        return "the file does not start with the MCAP magic: not an MCAP file, or damaged"
    header = _record_header(result.file, start)
    if header is None:
        return f"end of file inside the record header at byte {start}: the file is truncated"
    length, name = header
    if start + 9 + length > size:
        if name == "CHUNK":
            partial = _partial_chunk(result, gathered, start, length)
            if partial is not None:
                return partial
        return (
            f"the {name} record at byte {start} claims {length} bytes, past the end of the file "
            f"at byte {size}: the file is truncated there, or the record's length is damaged"
        )
    return f"unreadable {name} record at byte {start}: {_error_text(error)}"


def _error_text(error: BaseException) -> str:
    """An exception's message alone (its class name only when it has none)."""
    text = " ".join(str(error).split()).rstrip(".")
    if len(text) > 200:
        text = text[:200] + "…"
    return text or type(error).__name__


def _record_header(path: Path, start: int) -> tuple[int, str] | None:
    """(length, opcode name) of the record at byte ``start``; None when cut off."""
    from mcap.opcode import Opcode

    with path.open("rb") as handle:
        handle.seek(start)
        head = handle.read(9)
    if len(head) < 9:
        return None
    opcode, length = int(head[0]), int.from_bytes(head[1:], "little")
    try:
        name = Opcode(opcode).name
    except ValueError:
        name = f"unknown (opcode 0x{opcode:02x})"
    return length, name


def _partial_chunk(
    result: SalvageResult, gathered: _Salvaged, start: int, length: int
) -> str | None:
    """Read the complete inner records of the chunk at byte ``start`` that the end of the file
    cuts off. None when the chunk's own fields do not add up to ``length`` (a damaged length
    rather than a truncation)."""
    from mcap.records import Message

    with result.file.open("rb") as handle:
        handle.seek(start + 9)
        body = handle.read(min(length, result.size - start - 9))  # never a damaged length
    try:
        chunk, fields, records_length = _chunk_fields(body)  # its data: the bytes present
    except ValueError:
        return None
    if fields + records_length != length:
        return None
    compression = chunk.compression
    records = messages = 0
    end = 0
    try:
        for end, inner in _inner_records(_chunk_data(chunk, partial=True), chunk):
            gathered.take(inner, result, verified=False)  # cut off: no CRC to check
            records += 1
            messages += isinstance(inner, Message)
    except Exception:  # noqa: BLE001, S110 -- the cut (or damage) ends the readable records
        pass
    # Uncompressed, the last complete inner record ends at a known byte; compressed, every byte
    # up to the end of the file went into the decompressor.
    if records:
        result.stopped_at = start + 9 + fields + end if compression == "" else result.size
    read = (
        f"{records} of its records ({messages} messages) read"
        if records
        else "no complete record in it"
    )
    return (
        f"end of file inside the chunk at byte {start} ({9 + length} bytes, {result.size - start} "
        f"of them present): the file is truncated; {read}"
    )


def _magic_length(path: Path) -> int:
    """8 when the file starts with the MCAP magic (read successfully), else 0."""
    with path.open("rb") as handle:
        return len(_MCAP_MAGIC) if handle.read(len(_MCAP_MAGIC)) == _MCAP_MAGIC else 0


def _chunk_records(chunk: Any, keep_unverified: bool = False) -> Iterator[tuple[object, bool]]:
    """The schema, channel and message records of a chunk, checked as they are read, each with
    whether the chunk's CRC-32 matched (when written: 0 means none, and counts as matched); of a
    chunk whose CRC-32 does not match its records, none of its messages, or with
    ``keep_unverified`` those that read (a changed digit still reads: unverified)."""
    import zlib

    from mcap.records import Message

    data = _chunk_data(chunk)
    if chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc:
        # Its schema and channel records are kept when they read (a later chunk's messages may
        # need them when the file has no summary to repeat them).
        kept = 0
        try:
            for _, record in _inner_records(data, chunk):
                if keep_unverified or not isinstance(record, Message):
                    kept += isinstance(record, Message)
                    yield record, False
        except ValueError:
            pass
        raise ValueError(
            f"its CRC-32 {chunk.uncompressed_crc:#010x} does not match its records "
            f"({zlib.crc32(data):#010x}): damaged, "
            + (
                f"{kept} of its messages kept UNVERIFIED (--keep-unverified; any of them may "
                "hold a changed byte)"
                if keep_unverified
                else "none of its messages kept (--keep-unverified keeps those that read)"
            )
        )
    for _, record in _inner_records(data, chunk):
        yield record, True


def _chunk_data(chunk: Any, *, partial: bool = False) -> bytes:
    """A chunk's records, decompressed; ``partial``: of a chunk cut off by the end of the file
    (as much as the compressed bytes present give)."""
    if chunk.compression == "":
        return bytes(chunk.data)
    if chunk.compression == "zstd":
        import zstandard

        if partial:
            return zstandard.ZstdDecompressor().decompressobj().decompress(chunk.data)
        return zstandard.decompress(chunk.data, chunk.uncompressed_size)
    if chunk.compression == "lz4":  # rosbag2's other MCAP compression (frame format)
        import lz4.frame

        if partial:
            return lz4.frame.LZ4FrameDecompressor().decompress(chunk.data)
        return lz4.frame.decompress(chunk.data)
    raise ValueError(f"chunk compression {chunk.compression!r} is not supported")


def _inner_records(data: bytes, chunk: Any) -> Iterator[tuple[int, object]]:
    """(end offset in ``data``, record) of the schema, channel and message records in a chunk's
    ``data``, checked as they are read; raises ValueError at the first record that does not fit."""
    import struct

    from mcap.data_stream import ReadDataStream
    from mcap.opcode import Opcode
    from mcap.records import Channel, Message, Schema

    offset = 0
    while offset < len(data):
        if offset + 9 > len(data):
            raise ValueError(f"record header cut off at chunk byte {offset}")
        opcode, length = struct.unpack_from("<BQ", data, offset)
        body = data[offset + 9 : offset + 9 + length]
        if len(body) != length:
            raise ValueError(f"record of {length} bytes at chunk byte {offset} overruns the chunk")
        offset += 9 + length
        stream = ReadDataStream(_StrictStream(_Bytes(body)))  # type: ignore[arg-type]
        if opcode == Opcode.MESSAGE:
            if length < 22:
                raise ValueError(f"message record of {length} bytes is too short")
            record = Message.read(stream, length)
            if not chunk.message_start_time <= record.log_time <= chunk.message_end_time:
                raise ValueError(f"message time {record.log_time} outside its chunk's range")
            yield offset, record
        elif opcode in (Opcode.SCHEMA, Opcode.CHANNEL):
            parsed = Schema.read(stream) if opcode == Opcode.SCHEMA else Channel.read(stream)
            if stream.count != length:
                raise ValueError(f"{type(parsed).__name__} record length mismatch")
            yield offset, parsed


class _Bytes:
    def __init__(self, data: bytes) -> None:
        self._data = memoryview(data)
        self._offset = 0

    def read(self, size: int = -1) -> bytes:
        end = len(self._data) if size < 0 else self._offset + size
        piece = bytes(self._data[self._offset : end])
        self._offset += len(piece)
        return piece


def _unusable(channel: Any, schema: Any, data: bytes) -> str | None:
    """Why a salvaged message of ``channel`` cannot be kept (``<topic>: <reason>``), None when it
    deserializes: with the Jazzy typestore, or for a type that lacks with the definition the file
    carries (such messages were dropped, without their topic or the reason being named)."""
    if channel.message_encoding != "cdr":
        return (
            f"{channel.topic}: serialized as {channel.message_encoding!r}, not CDR, which lit "
            "replay does not read (the source keeps them)"
        )
    store = bag.typestore()  # most messages: no copy and hash of their definition
    if schema.name not in store.types:
        try:
            store = _store_for(schema.name, schema.encoding, bytes(schema.data))
        except ValueError as error:
            return f"{channel.topic}: {error}"
    try:
        message = store.deserialize_cdr(data, schema.name)
        if schema.name == bag.STRING_TYPE:
            message.data.encode("utf-8")
    except Exception:  # noqa: BLE001 -- damaged CDR raises anything
        return f"{channel.topic}: bytes that do not deserialize as {schema.name}"
    return None


def _store_for(msgtype: str, encoding: str, definition: bytes) -> Any:
    """The typestore that reads ``msgtype``: rosbags' Jazzy one when it knows the type, else a
    copy of it that also holds ``definition`` (a bag's schema record: ``ros2msg`` or ``ros2idl``
    text, with the types it uses), so another program's messages are kept.

    Raises:
        ValueError: the type is not Jazzy's and the definition does not give it.
    """
    store = _store_or_why(msgtype, encoding, definition)
    if isinstance(store, str):
        raise ValueError(store)  # noqa: TRY004 -- a reason, not a type error
    return store


@cache
def _store_or_why(msgtype: str, encoding: str, definition: bytes) -> Any:
    """:func:`_store_for`'s store, or why there is none (kept too: a definition that does not
    parse was parsed again, and a typestore built, for each of its messages)."""
    if msgtype in bag.typestore().types:
        return bag.typestore()
    from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore

    unknown = f"{msgtype} is not a ROS 2 Jazzy type and"
    parse = {"ros2msg": get_types_from_msg, "ros2idl": get_types_from_idl}.get(encoding)
    if parse is None:
        return f"{unknown} its definition is of encoding {encoding!r}, not ros2msg or ros2idl"
    try:
        text = definition.decode("utf-8")
    except UnicodeDecodeError:
        return f"{unknown} the definition the file carries is not UTF-8 text"
    if not text.strip():  # it parses, as a type without fields, which no message is
        return f"{unknown} the file carries no definition of it"
    try:
        types = parse(text) if encoding == "ros2idl" else parse(text, msgtype)
        store = get_typestore(Stores.ROS2_JAZZY)
        store.register(types)
        store.hash_rihs01(msgtype)  # the definition is whole: every type it uses is known
    except Exception as error:  # noqa: BLE001 -- rosbags' parsers raise many kinds
        return f"{unknown} the definition the file carries does not give it ({_describe(error)})"
    if msgtype not in store.types:
        return f"{unknown} the definition the file carries does not define it"
    return store


def _write_salvaged(
    target: Path, source: Path, kept: list[tuple[Any, Any, int, bytes]], results: list[Any]
) -> None:
    from rosbags.rosbag2.metadata import parse_qos

    run_ids: set[str] = set()
    for channel, schema, _, data in kept:
        if schema.name == bag.STRING_TYPE and split_topic(channel.topic)[1]:
            try:
                text = bag.typestore().deserialize_cdr(data, bag.STRING_TYPE).data
                run_ids.add(str(json.loads(text)["run_id"]))
            except Exception:  # noqa: BLE001, S112 -- not an envelope: no run id from it
                continue
    custom = _salvaged_custom_data(source)
    custom.setdefault(bag.RUN_ID_KEY, ",".join(sorted(run_ids)) or "unknown")
    custom["lit.salvaged_from"] = str(source)
    custom["lit.salvage"] = "; ".join(
        f"{r.file.name}: "
        + (
            f"left out: {r.reason}"
            if r.left_out
            else f"{r.reason}, read {r.stopped_at} of {r.size} bytes"
        )
        + "".join(f"; {note}" for note in r.notes)
        + "".join(f"; {n} messages dropped ({why})" for why, n in r.dropped_why.items())
        + "".join(f"; {n} messages left out as copies of {o.name}'s" for o, n in r.copies.items())
        + "".join(f"; damaged {damage}" for damage in r.damaged_chunks)  # UNVERIFIED kept ones
        for r in results
    )

    def profiles(channel: Any) -> list[Any]:
        qos_text = channel.metadata.get("offered_qos_profiles", "")
        try:
            return parse_qos(qos_text) if qos_text else []
        except Exception:  # noqa: BLE001 -- a damaged profile: the default instead
            return [bag.parse_qos(bag.DEFAULT_QOS)]

    _write_bag(
        bag.ChunkedWriter(target),
        custom,
        (
            # One connection per topic and type, whichever file's channel id it had.
            (
                (channel.topic, schema.name),
                channel.topic,
                schema.name,
                lambda c=channel: profiles(c),
                log_ns,
                data,
                lambda s=schema: _store_for(s.name, s.encoding, bytes(s.data)),
            )
            for channel, schema, log_ns, data in kept
        ),
    )


def _write_bag(
    writer: Any,
    custom: dict[str, str],
    messages: Iterable[
        tuple[Any, str, str, Callable[[], list[Any]], int, bytes, Callable[[], Any]]
    ],
) -> int:
    """Write ``messages`` — (connection key, topic, type, offered QoS profiles (called once per
    connection), log time, serialized data, the typestore that knows the type (called once per
    connection)) — into the unopened ``writer`` with ``custom`` as its ``custom_data``, and close
    it; on a failure the half-written bag folder is removed. Returns the number of messages
    written."""
    # The source's chunk size would misstate the copy's (compact writes 1 MiB chunks).
    custom = {**custom, "lit.chunk_bytes": str(writer.chunk_bytes)}
    for key, value in custom.items():
        writer.set_custom_data(key, value)
    existed = Path(writer.path).exists()
    try:
        writer.open()
    except BaseException as error:  # a signal may land while open() creates the folder
        if not existed:
            shutil.rmtree(writer.path, ignore_errors=True)
        if isinstance(error, Exception):  # rosbags' WriterError, OSError
            raise ReplayError(f"cannot create {writer.path}: {_describe(error)}") from None
        raise
    connections: dict[Any, Any] = {}
    count = 0
    try:
        for key, topic, msgtype, profiles, log_ns, data, store in messages:
            connection = connections.get(key)
            if connection is None:
                connection = writer.add_connection(
                    topic, msgtype, typestore=store(), offered_qos_profiles=profiles()
                )
                connections[key] = connection
            writer.write(connection, log_ns, data)
            count += 1
        writer.close()
    except BaseException as error:
        try:
            writer.abort()  # on a full disk its flush fails again
        except Exception:  # noqa: BLE001, S110 - the folder goes all the same
            pass
        finally:
            shutil.rmtree(writer.path, ignore_errors=True)  # open() created it: no half bag left
        if isinstance(error, OSError):  # a full disk: name what could not be written
            raise ReplayError(
                f"{_io_failure(error, Path(writer.path))}; nothing of {writer.path} was kept"
            ) from None
        raise
    return count


def _connection_store(source: Path, connection: Any) -> Any:
    """The typestore that knows the type of a bag's ``connection``: Jazzy's, else one with the
    definition the bag carries (compact failed on another program's type with "TypesysError:
    Type '...' is unknown", naming neither the bag nor the topic).

    Raises:
        ReplayError: the type is not Jazzy's and the bag's definition does not give it.
    """
    from rosbags.interfaces import MessageDefinitionFormat

    encoding = {MessageDefinitionFormat.IDL: "ros2idl", MessageDefinitionFormat.MSG: "ros2msg"}.get(
        connection.msgdef.format, "none"
    )
    try:
        return _store_for(connection.msgtype, encoding, connection.msgdef.data.encode("utf-8"))
    except ValueError as error:
        raise ReplayError(f"{source}: topic {connection.topic}: {error}") from None


def _salvaged_custom_data(source: Path) -> dict[str, str]:
    """The ``custom_data`` of the bag that ``source`` is or belongs to: its ``metadata.yaml``'s,
    else what its writer left in :data:`bag.UNFINISHED_METADATA` (a writer killed before it
    wrote ``metadata.yaml``); empty when neither reads."""
    folder = source if source.is_dir() else source.parent
    metadata = folder / "metadata.yaml"
    try:
        if metadata.is_file():
            custom = load_metadata(metadata).get("custom_data") or {}
        else:
            custom = json.loads((folder / bag.UNFINISHED_METADATA).read_text())
        return {str(k): str(v) for k, v in custom.items()}
    except (ReplayError, AttributeError, OSError, ValueError):
        return {}


# --- compact ---------------------------------------------------------------------------------


def compact(source: str | Path, out: str | Path) -> dict[str, Any]:
    """Rewrite a complete bag with zstd-compressed 1 MiB MCAP chunks (for bags kept in the
    repository): every connection that has messages with its QoS, the same timestamps and
    message bytes, its ``custom_data`` plus ``lit.compacted_from``.

    Returns:
        ``messages``, ``bytes_before``, ``bytes_after`` and ``compressed_before`` (the source's
        compression as ``lit replay info`` shows it, e.g. "chunks zstd"; None when it had none).
    """
    source, target = _named(Path(source)), Path(out)
    _check_readable(source)
    if target.exists():
        raise ReplayError(f"{target} exists; choose a new folder")
    custom = _salvaged_custom_data(source)
    custom["lit.compacted_from"] = source.name
    # BagReader: a damaged or unfinished bag is the same one-line error (with the salvage hint)
    # as for info and verify, before or while the messages are copied.
    with BagReader(source) as reader:
        compressed_before = reader.facts.compression
        count = _write_bag(
            bag.ChunkedWriter(target, chunk_bytes=bag.MAX_CHUNK_BYTES, compress=True),
            custom,
            (
                (
                    c.id,
                    c.topic,
                    c.msgtype,
                    lambda c=c: c.ext.offered_qos_profiles,
                    stamp,
                    data,
                    lambda c=c: _connection_store(source, c),
                )
                for c, stamp, data in reader.raw_messages()
            ),
        )

    def size(path: Path) -> int:  # the bag's own files (not a replay/ folder inside it)
        if path.is_file():
            return path.stat().st_size
        return sum(f.stat().st_size for f in path.iterdir() if f.is_file())

    return {
        "messages": count,
        "bytes_before": size(source),
        "bytes_after": size(target),
        "compressed_before": compressed_before,
    }


# --- bench -----------------------------------------------------------------------------------


@dataclass
class BenchBag:
    """The BenchConfig and BenchRun envelopes of the bags of one ``lit bench`` run."""

    config: Envelope
    runs: list[Envelope]
    """Each record once (the first bag that holds it)."""
    skipped: Skipped
    missing: int
    """Records missing: gaps in the seq of a publisher (topic, source, run id)."""
    duplicates: list[str] = field(default_factory=list)
    """Records left out because an identical one (same topic, source, run id and seq) was read
    already, each as ``<topic> seq <n> of run <id> in <bag>``."""
    custom_data: dict[str, str] = field(default_factory=dict)
    """The ``custom_data`` of the first bag, which holds the configuration used."""
    warnings: list[str] = field(default_factory=list)
    """What ``replay bench`` read around (a malformed timing in the first bag's metadata)."""


def read_bench(paths: Sequence[str | Path]) -> BenchBag:
    """The recorded config and run records, runs in recording order (bag order, then seq).

    A record read already (same topic, source, run id and seq; e.g. a bag and its salvaged or
    compacted copy) is left out and listed in ``duplicates`` when it is identical, so no run
    counts twice.

    Raises:
        ReplayError: a bag given twice, configs that differ between bags, or two different
            records under the same run id and seq.
        NotBenchBagError: a bag without BenchConfig.
        EmptyBenchBagError: BenchConfig but no usable run record.
    """

    check_distinct_bags(paths)
    skipped = Skipped()
    config: Envelope | None = None
    runs: list[Envelope] = []
    # A record's identity: its run (the stamp of the run's config message: copies of one bag
    # share it, two runs with the same --out name do not), publisher and seq.
    first_seen: dict[tuple[int, str, str, str, int], tuple[Envelope, str | Path]] = {}
    duplicates: list[str] = []
    custom_data: dict[str, str] = {}
    for path in paths:
        bag_config, bag_runs = None, []
        unusable_config = ""  # what became of a config message left out
        with BagReader(path) as reader:
            if config is None:
                custom_data = dict(reader.facts.custom_data)
            for message in reader.messages():
                if message.topic == bag.BENCH_CONFIG_TOPIC:
                    one = Skipped()
                    item = decode(message, one)
                    unusable_config = unusable_config or next(iter(one.examples), "")
                    skipped.merge(one)
                else:
                    item = decode(message, skipped)
                if not isinstance(item, Envelope) or not on_its_topic(item, skipped):
                    continue
                if item.schema == bag.BENCH_CONFIG_SCHEMA:
                    if bag_config is None:
                        bag_config = item
                    elif item.payload != bag_config.payload:
                        # e.g. the bags of two runs salvaged together into one: their records
                        # could not be told apart by run.
                        raise ReplayError(
                            f"{path}: holds the configurations of two lit bench runs (a second "
                            f"{bag.BENCH_CONFIG_TOPIC} message, seq {item.seq} of run "
                            f"{item.run_id}, differs from the first); replay each run's bag "
                            "on its own"
                        )
                elif item.schema == bag.BENCH_RUN_SCHEMA and payload_ok(item, skipped):
                    bag_runs.append(item)
        if bag_config is None and unusable_config:
            raise ReplayError(
                f"{path}: its {bag.BENCH_CONFIG_TOPIC} message is unusable ({unusable_config}): "
                "a lit bench bag whose configuration is damaged or of a newer LIT*"
            )
        if bag_config is None:
            raise NotBenchBagError(
                f"{path}: no {bag.BENCH_CONFIG_TOPIC} message: not a lit bench bag", path
            )
        if not isinstance(bag_config.payload, dict):
            raise ReplayError(f"{path}: the {bag.BENCH_CONFIG_TOPIC} payload is not an object")
        if config is not None and bag_config.payload.get("config") != config.payload.get("config"):
            raise ReplayError(f"{path}: its bench configuration differs from that of {paths[0]}")
        config = config or bag_config
        bag_runs.sort(key=lambda e: e.seq)
        for item in bag_runs:
            key = (bag_config.stamp_ns, item.topic, item.source, item.run_id, item.seq)
            where = f"{item.topic} seq {item.seq} of run {item.run_id}"
            if key not in first_seen:
                first_seen[key] = (item, path)
                runs.append(item)
                continue
            earlier, earlier_path = first_seen[key]
            if earlier.payload != item.payload:
                raise ReplayError(
                    f"{path}: {where} differs from the record with the same run id and seq in "
                    f"{earlier_path}; which one is right cannot be told"
                )
            duplicates.append(f"{where} in {path}")
    assert config is not None
    if not runs:
        raise EmptyBenchBagError(
            f"no usable {bag.BENCH_RUN_TOPIC} record in {', '.join(map(str, paths))}: the "
            "benchmark's configuration is there, none of its records (a run stopped before its "
            f"first scenario finished, or damage; {skipped.total} messages skipped); nothing to "
            "tabulate"
        )
    publishers: dict[tuple[int, str, str, str], list[int]] = {}
    for started, topic, source, run_id, seq in first_seen:
        publishers.setdefault((started, topic, source, run_id), []).append(seq)
    missing = sum(
        b - a - 1 for seqs in publishers.values() for a, b in itertools.pairwise(sorted(seqs))
    )
    return BenchBag(config, runs, skipped, missing, duplicates, custom_data)


def check_distinct_bags(paths: Sequence[str | Path]) -> None:
    """Refuse a bag given twice: the same path, or a bag folder and one of its ``.mcap`` files
    (compared after resolving links and relative paths).

    Raises:
        ReplayError: names both arguments.
    """
    owners: dict[Path, str | Path] = {}
    for path in paths:
        given = Path(path)
        keys = {given.resolve()}
        if given.is_dir():
            keys |= {file.resolve() for file in given.glob("*.mcap")}
        for key in sorted(keys):
            if key in owners:
                same = (
                    "given twice"
                    if Path(owners[key]) == given
                    else f"the same bag as {owners[key]}"
                )
                raise ReplayError(f"{path}: {same}; give each bag once")
        owners.update(dict.fromkeys(keys, path))


def replay_bench(paths: Sequence[str | Path], out: Path) -> tuple[dict[str, Any], BenchBag]:
    """Regenerate summary.json, summary.md and the plots of a recorded ``lit bench`` run.

    Calls the very functions ``lit bench`` uses (:func:`lit_planner.bench.cli.write_outputs`), so
    the same records give the same statistics.
    """
    from lit_msgs_json import codec
    from lit_planner.bench import cli as bench_cli
    from lit_planner.bench import runner

    recorded = read_bench(paths)
    payload = recorded.config.payload
    try:
        settings = payload["config"]
        config = runner.BenchConfig(
            scenarios=tuple(settings["scenarios"]),
            planners=tuple(settings["planners"]),
            runs=int(settings["runs"]),
            first_seed=int(settings["first_seed"]),
            instance=int(settings["instance"]),
            time_scale=float(settings["time_scale"]),
            tensors_dir=Path(settings["tensors_dir"]),
            check_jobs=int(settings["check_jobs"]),
            skipped=tuple(runner.Skip(**skip) for skip in payload["skipped"]),
            t_init_repeats=int(settings.get("t_init_repeats", 1)),  # 1 before it existed
        )
        started = datetime.fromisoformat(payload["started"])
        estimate = payload["estimate"]
        environment = {key: payload[key] for key in ("cwd", "machine", "versions", "planners")}
        requested = list(settings["planners_requested"])
    except (KeyError, TypeError, ValueError) as error:
        raise ReplayError(
            f"{paths[0]}: malformed {bag.BENCH_CONFIG_TOPIC} payload: {_describe(error)}"
        ) from None
    recorded.runs = _runs_in_grid(recorded, config)
    if not recorded.runs:
        raise EmptyBenchBagError(
            f"no {bag.BENCH_RUN_TOPIC} record in {', '.join(map(str, paths))} belongs to its "
            f"benchmark's configuration ({recorded.skipped.line()}); nothing to tabulate"
        )
    last_ns = max(run.stamp_ns for run in recorded.runs)
    finished = datetime.fromtimestamp(last_ns / 1e9, UTC)
    duration = max(0.0, (last_ns - recorded.config.stamp_ns) / 1e9)
    timing = recorded.custom_data
    if bag.BENCH_DURATION_KEY in timing and bag.BENCH_FINISHED_KEY in timing:
        # A finished run recorded its own clock: the same header as `lit bench` printed. (Bags
        # from before 2026-12-05 and interrupted runs: from the configuration's stamp to the
        # last run record's, which leaves out the set-up before the first.)
        try:
            recorded_finished = datetime.fromisoformat(timing[bag.BENCH_FINISHED_KEY])
            recorded_duration = float(timing[bag.BENCH_DURATION_KEY])
            if not (math.isfinite(recorded_duration) and recorded_duration >= 0):
                raise ValueError(f"duration {timing[bag.BENCH_DURATION_KEY]!r}")
            finished, duration = recorded_finished, recorded_duration
        except ValueError as error:
            # It stopped every replay of the bag for good (salvage and compact copy it), and did
            # not name the bag: the span of the records stands in, as for a bag without it.
            recorded.warnings.append(
                f"{paths[0]}: malformed {bag.BENCH_FINISHED_KEY} / {bag.BENCH_DURATION_KEY} in "
                f"its metadata.yaml ({error}); the header's finish time and duration are those "
                "of the configuration's and the last run record's stamps instead"
            )
    planned = config.runs * len(config.scenarios) * len(config.planners)
    incomplete = None
    if len(recorded.runs) < planned:
        # A damaged message, a gap or an interrupted benchmark: say so where the tables are read.
        seen = [
            f"{recorded.missing} seq gaps" if recorded.missing else "",
            recorded.skipped.line() if recorded.skipped.total else "",
        ]
        why = "; ".join(filter(None, seen)) or (
            "none damaged: the benchmark was interrupted, or its bag was cut short and salvaged"
        )
        incomplete = {
            "planned": planned,
            "read": len(recorded.runs),
            "note": (
                f"{planned - len(recorded.runs)} of the {planned} planned run records are missing "
                f"or unreadable ({why}); the statistics cover the {len(recorded.runs)} read, so "
                "the medians compared in a table may come from different runs of each planner "
                "(the query-by-query tables pair only the queries both planners ran). `lit "
                "replay info` shows the bag's gaps and skipped messages"
            ),
        }
    out.mkdir(parents=True, exist_ok=True)
    with (out / bench_cli.RUNS_FILE).open("w", encoding="utf-8") as handle:
        for run in recorded.runs:  # as lit bench writes them
            handle.write(codec.dumps(runner.RUN_SCHEMA, run.payload) + "\n")
    try:
        summary = bench_cli.write_outputs(
            out,
            [run.payload for run in recorded.runs],
            config,
            preset=payload.get("preset"),
            requested=requested,
            started=started,
            finished=finished,
            duration=duration,
            estimate=(float(estimate["planning_s"]), str(estimate["formula"])),
            argv=list(payload["argv"]),
            recorded=environment,
            incomplete=incomplete,
        )
    except LitPlannerError as error:
        raise ReplayError(f"cannot regenerate the outputs: {error}") from None
    return summary, recorded


def _runs_in_grid(recorded: BenchBag, config: Any) -> list[Envelope]:
    """The run records that belong to the benchmark's configuration, one per scenario, planner
    and run; any other is skipped (``recorded.skipped`` says where), so that it cannot stand in
    for a missing one when the records are counted.

    Raises:
        ReplayError: two different records of the same scenario, planner and run.
    """
    grid = {
        (scenario, planner, run)
        for scenario in config.scenarios
        for planner in config.planners
        for run in range(config.runs)
    }
    kept: dict[tuple[str, str, int], Envelope] = {}
    for item in recorded.runs:
        cell = (item.payload["scenario"], item.payload["planner"], item.payload["run"])
        where = f"{item.topic} seq {item.seq} of run {item.run_id}"
        if cell not in grid:
            recorded.skipped.add(
                "run record outside the benchmark's configuration",
                where,
                f"scenario {cell[0]}, planner {cell[1]}, run {cell[2]}",
            )
        elif cell in kept:
            earlier = kept[cell]
            raise ReplayError(
                f"two records of scenario {cell[0]}, planner {cell[1]}, run {cell[2]}: "
                f"{earlier.topic} seq {earlier.seq} of run {earlier.run_id} and {where} (two "
                "runs of the same benchmark?); replay each run's bag on its own"
            )
        else:
            kept[cell] = item
    return list(kept.values())


# --- command line ----------------------------------------------------------------------------


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Subcommands of ``lit replay``."""
    sub = parser.add_subparsers(dest="replay_command", metavar="SUBCOMMAND", required=True)
    info = sub.add_parser("info", help="topics, counts, time span, run metadata, seq accounting")
    info.add_argument("bag", type=argtypes.path, metavar="BAG", help="bag directory or .mcap file")
    info.add_argument("--json", action="store_true", help="print JSON")
    verify = sub.add_parser("verify", help="re-check every recorded path against its world")
    verify.add_argument("bags", type=argtypes.path, nargs="+", metavar="BAG")
    rescue = sub.add_parser(
        "salvage", help="recover the readable messages of a killed or damaged bag into a new bag"
    )
    rescue.add_argument("bag", type=argtypes.path, metavar="BAG")
    rescue.add_argument(
        "-o",
        "--out",
        type=argtypes.path,
        metavar="OUT",
        help=f"new bag (default: BAG{SALVAGED_SUFFIX})",
    )
    rescue.add_argument(
        "--keep-unverified",
        action="store_true",
        help="also keep the messages that read of a chunk whose CRC-32 does not match (any of "
        "them may hold a changed byte: a digit changed in a number still reads)",
    )
    squeeze = sub.add_parser(
        "compact", help="rewrite a bag with zstd-compressed MCAP chunks (smaller, same messages)"
    )
    squeeze.add_argument("bag", type=argtypes.path, metavar="BAG")
    squeeze.add_argument("out", type=argtypes.path, metavar="OUT", help="new bag folder")
    from lit_planner import bag_measure

    tensors = sub.add_parser(
        "tensors", help="train Fuzzy-DDPG offline on the recorded transitions; export tensors"
    )
    _offline().add_arguments(tensors)
    measure = sub.add_parser(
        "measure", help="the recorder's write rate and its loss when the writer is SIGKILLed"
    )
    bag_measure.add_arguments(measure)
    bench = sub.add_parser(
        "bench", help="regenerate lit bench's summary.json, tables and plots from its bag(s)"
    )
    bench.add_argument("bags", type=argtypes.path, nargs="+", metavar="BAG")
    bench.add_argument(
        "--out",
        type=argtypes.path,
        metavar="DIR",
        help=f"output folder, new or empty (default: <first BAG>/{REPLAY_DIR}; for an .mcap "
        "file, <its name without .mcap>-replay beside it)",
    )


def run(args: argparse.Namespace) -> int:
    """Run a ``lit replay`` subcommand: 0 success, 1 invalid paths (verify) or fewer run records
    than planned (bench), 2 bad input."""
    commands = {
        "info": _info,
        "verify": _verify,
        "salvage": _salvage,
        "compact": _compact,
        "bench": _bench,
        "measure": _measure,
        "tensors": _tensors,
    }
    # `kill PID`, or the terminal closing, stops like Ctrl-C: the same clean-up (no half-written
    # bag or output folder).
    try:
        with signals.handling((signal.SIGTERM, signal.SIGHUP), signal.default_int_handler):
            return commands[args.replay_command](args)
    except ReplayError as error:
        print(f"{PROG}: error: {error}", file=sys.stderr)
        return 2
    except (BrokenPipeError, StdoutError):
        raise  # `lit replay info BAG | head -1`, `> /dev/full`: lit's main handles them
    except Exception as error:  # bad input must never end in a traceback
        if os.environ.get("LIT_REPLAY_DEBUG"):
            raise
        print(
            f"{PROG}: error: {_describe(error)} (LIT_REPLAY_DEBUG=1 shows the traceback)",
            file=sys.stderr,
        )
        return 2


def _offline() -> Any:
    """``lit_learner.offline`` (imported only for ``tensors``: it brings torch)."""
    import importlib

    return importlib.import_module("lit_learner.offline")


def _tensors(args: argparse.Namespace) -> int:
    from lit_planner.planning import MAX_SEED

    # Checked before the bags are read (seconds for a large one).
    if not 0 <= args.seed <= MAX_SEED:
        raise ReplayError(f"--seed must be between 0 and {MAX_SEED}, got {args.seed}")
    for label, value, least in (
        ("--warmup", args.warmup, 1),  # 0 is below any batch size
        ("--batch-size", args.batch_size, 1),
        ("--decision-interval", args.decision_interval, 1),
    ):
        if value is not None and value < least:
            raise ReplayError(f"{label} must be {least} or more, got {value}")
    check_distinct_bags(args.bags)
    _check_new_folder(args.out, f"--out {args.out}")
    return int(_offline().run(args))


def _measure(args: argparse.Namespace) -> int:
    from lit_planner import bag_measure

    if args.messages < 1:
        raise ReplayError(
            f"--messages must be 1 or more (write-rate messages), got {args.messages}"
        )
    if args.kills < 0:
        raise ReplayError(f"--kills must be 0 or more (crash trials), got {args.kills}")
    if not 1 <= args.chunk_bytes <= bag.MAX_CHUNK_BYTES:
        raise ReplayError(
            f"--chunk-bytes must be within 1..{bag.MAX_CHUNK_BYTES}, got {args.chunk_bytes}"
        )
    return bag_measure.run(args)


def _check_new_folder(path: Path, label: str, advice: str = "choose a new or empty folder") -> None:
    """Refuse an output folder that is a file or holds files (as ``lit bench --out`` does)."""
    problem = bag.output_folder_problem(path)
    if problem is not None:
        raise ReplayError(f"{label}: {problem}; {advice}")


def _info(args: argparse.Namespace) -> int:
    info = bag_info(args.bag)
    if args.json:
        print(json.dumps(info, indent=1))
    else:
        print(format_info(info))
    return 0


def _verify(args: argparse.Namespace) -> int:
    check_distinct_bags(args.bags)
    report = VerifyReport()
    skipped = Skipped()
    for path in args.bags:
        bag_skipped = verify_bag(path, report)
        skipped.counts.update(bag_skipped.counts)
        skipped.examples.extend(bag_skipped.examples[: skipped.max_examples])
    for line in report.invalid:
        print(f"INVALID  {line}")
    for line in report.disagreements:
        print(f"DIFFERS  {line}")
    print(
        f"{PROG} verify: {report.checked} paths checked: {report.valid} valid, "
        f"{len(report.invalid)} invalid; {report.unsolved} runs without a path (unsolved); "
        f"{report.unchecked.line().replace('skipped', 'not checkable')}; messages "
        f"{skipped.line()}"
    )
    for example in report.unchecked.examples + skipped.examples[: skipped.max_examples]:
        print(f"  {example}")
    damaged = skipped.damaged
    missing = report.missing()
    if not report.invalid and (damaged or report.unchecked.total or missing):
        print(
            f"{PROG} verify: incomplete: {report.unchecked.total} recorded runs could not be "
            f"checked, {damaged} LIT* messages are damaged (see above) and {missing} run records "
            "are missing (their publishers' seq numbers are absent: lost in recording, or "
            "dropped by damage or salvage)"
        )
    return 1 if report.invalid or damaged or report.unchecked.total or missing else 0


def _compact(args: argparse.Namespace) -> int:
    result = compact(args.bag, args.out)
    print(
        f"{PROG} compact: wrote {args.out}: {result['messages']} messages, "
        f"{result['bytes_before'] / 1e6:.2f} MB -> {result['bytes_after'] / 1e6:.2f} MB"
        + (
            f" (the source was compressed already: {result['compressed_before']})"
            if result["compressed_before"]
            else ""
        )
    )
    return 0


def _salvage(args: argparse.Namespace) -> int:
    target, results = salvage(args.bag, args.out, args.keep_unverified)
    total = 0
    for result in results:
        if result.left_out:
            print(f"{PROG} salvage: {result.file}: left out: {result.reason}")
            continue
        print(
            f"{PROG} salvage: {result.file}: read {result.stopped_at} of {result.size} bytes; "
            + (
                "complete file"
                if result.complete
                else f"stopped at byte {result.stopped_at}: {result.reason}"
            )
            + (f"; {result.dropped} unusable messages dropped" if result.dropped else "")
        )
        for damage in result.damaged_chunks:
            print(f"  damaged {damage}")
        for note in result.notes:
            print(f"  {note}")
        for why, count in result.dropped_why.items():
            print(f"  {count} messages dropped: {why}")
        for other, count in result.copies.items():
            print(f"  {count} messages left out: {other} holds the same (a copy of it?)")
        for topic, count in sorted(result.messages.items()):
            print(f"  {topic}: {count} messages recovered")
            total += count
    print(f"{PROG} salvage: wrote {target} ({total} messages)")
    return 0


def read_episode_summaries(
    paths: Sequence[str | Path], skipped: Skipped | None = None
) -> list[dict[str, Any]]:
    """Every EpisodeSummary payload in the bags (a ROS run's queries), in recording order; what
    was left out is counted in ``skipped``."""
    skipped = Skipped() if skipped is None else skipped
    summaries = []
    seen: dict[tuple[str, str, str, int, int], bytes] = {}
    for path in paths:
        with BagReader(path) as reader:
            for message in reader.messages():
                item = decode(message, skipped)
                if (
                    not isinstance(item, Envelope)
                    or item.schema != SCHEMA_PREFIX + "EpisodeSummary"
                    or not payload_ok(item, skipped)
                ):
                    continue
                again = read_before(seen, item, message.data)  # a bag given with its copy: once
                if again == CONFLICTING:  # a copy's are not counted here (the tables' readers do)
                    skipped.counts[again] += 1
                if again is not None:
                    continue
                summaries.append(item.payload)
    return summaries


ENDED_BY = {"cancelled": "a cancel", "shutdown": "the shutdown"}
"""The ``ended by`` cell of :func:`episode_table` for the statuses of queries stopped early;
every other query ended at its limits (``its limits``)."""


def episode_table(summaries: Sequence[Mapping[str, Any]]) -> tuple[list[dict[str, Any]], str]:
    """Per (mode, scenario, planner, policy): queries, solved, medians of t_init, c_init, c_final
    and c_final / optimum (an unsolved query counts as infinite, as in ``lit bench``), fallback
    decisions and independently re-checked paths. Returns the rows and a markdown table.

    Queries of other time budgets (none: ``-``, limited by iterations or batches) and queries
    stopped early (ended by ``a cancel`` or ``the shutdown``, their costs those of that moment) are
    rows of their own: they used to share one, counted as solved.

    Instances of a random family are one group (``rrd4 (458 instances)``): a training run draws a
    new instance for nearly every query, and a row per instance says nothing. Custom worlds
    (``custom2``, every one named by its dimension) are told apart by the world the summary
    carries: three worlds are ``custom2 (3 instances)``."""
    groups: dict[tuple[str, str, str, str, float, str], list[Mapping[str, Any]]] = {}
    for summary in summaries:
        family = str(summary["scenario"]).split("/", 1)[0]
        budget = summary.get("time_budget")
        key = (
            summary["mode"], family, summary["planner"], summary["policy"],
            math.inf if budget is None else float(budget),
            ENDED_BY.get(str(summary.get("status")), "its limits"),
        )  # fmt: skip
        groups.setdefault(key, []).append(summary)

    def median(values: list[float | None]) -> float | None:
        finite = [math.inf if v is None else float(v) for v in values]
        value = float(np.median(finite)) if finite else math.inf
        return value if math.isfinite(value) else None

    def instance(summary: Mapping[str, Any]) -> str:
        world = summary.get("world")  # custom worlds share their name
        if world is None:
            return str(summary["scenario"])
        return f"{summary['scenario']} {json.dumps(world, sort_keys=True)}"

    rows = []
    for (mode, family, planner, policy, budget, ended), group in sorted(groups.items()):
        instances = {instance(s) for s in group}
        scenario = (
            str(group[0]["scenario"])
            if len(instances) == 1
            else f"{family} ({len(instances)} instances)"
        )
        ratios = [
            s["cost"] / s["optimal_cost"] if s["cost"] and s["optimal_cost"] else None
            for s in group
        ]
        rows.append({
            "mode": mode, "scenario": scenario, "planner": planner, "policy": policy,
            "time_budget": budget if math.isfinite(budget) else None, "ended_by": ended,
            "instances": len(instances), "queries": len(group),
            "solved": sum(bool(s["solved"]) for s in group),
            "median_t_init": median([s["t_init"] for s in group]),
            "median_c_init": median([s["c_init"] for s in group]),
            "median_c_final": median([s["cost"] for s in group]),
            "median_ratio": median(ratios) if any(r is not None for r in ratios) else None,
            "fallback_decisions": sum(int(s["fallback_decisions"]) for s in group),
            "paths_rechecked_ok": sum(s.get("path_valid") is True for s in group),
        })  # fmt: skip

    def cell(value: float | None, scale: float = 1.0, unit: str = "") -> str:
        return "-" if value is None else f"{value * scale:.3f}{unit}"

    lines = [
        (
            "| mode | scenario | planner | policy | budget | ended by | queries | solved | "
            "median t_init | median c_init | median c_final | c_final / optimum | fallbacks | "
            "paths re-checked |"
        ),
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        budget = "-" if row["time_budget"] is None else f"{row['time_budget']:g} s"
        lines.append(
            f"| {row['mode']} | {row['scenario']} | {row['planner']} | {row['policy']} | "
            f"{budget} | {row['ended_by']} | {row['queries']} | {row['solved']} | {cell(row['median_t_init'], 1e3, ' ms')} | "
            f"{cell(row['median_c_init'])} | {cell(row['median_c_final'])} | "
            f"{cell(row['median_ratio'])} | {row['fallback_decisions']} | "
            f"{row['paths_rechecked_ok']}/{row['queries']} |"
        )
    return rows, "\n".join(lines) + "\n"


def _has_bench_config(path: str | Path) -> bool:
    """Whether the bag has a connection on the bench configuration topic (from its metadata and
    MCAP summaries; no message is read)."""
    with BagReader(path) as reader:
        return any(c.topic == bag.BENCH_CONFIG_TOPIC for c in reader._reader.connections)


@contextlib.contextmanager
def _removed_on_failure(out: Path) -> Iterator[None]:
    """Remove what the block wrote into ``out`` (new, or empty: checked) when it fails (Ctrl-C, a
    full disk): half-written outputs would look complete and block the rerun. An OSError
    becomes a :class:`ReplayError` naming ``out`` (:func:`_io_failure`). A reader of the output
    that left (BrokenPipeError, from the lines printed once the outputs are written) removes
    nothing, nor does an answer that could not be printed (StdoutError: the outputs are whole)."""
    existed = out.exists()
    try:
        yield
    except (BrokenPipeError, StdoutError):
        raise
    except BaseException as error:
        if existed:
            for child in out.iterdir():
                if child.is_dir():
                    shutil.rmtree(child, ignore_errors=True)
                else:
                    child.unlink(missing_ok=True)
        else:
            shutil.rmtree(out, ignore_errors=True)
        if isinstance(error, OSError):
            raise ReplayError(
                f"{_io_failure(error, out)}; what was written into {out} is removed"
            ) from None
        raise


def _io_failure(error: OSError, out: Path) -> str:
    """An OSError met while writing ``out`` from bags, in words: a file it names outside
    ``out`` was being read (a bag), else it is ``out`` that could not be written (a full disk's
    write names no file)."""
    name = error.filename
    if isinstance(name, str | bytes) and not Path(os.fsdecode(name)).resolve().is_relative_to(
        out.resolve()
    ):
        return f"cannot read {os.fsdecode(name)}: {_describe(error)}"
    return f"cannot write {out}: {_describe(error)}"


def _bench(args: argparse.Namespace) -> int:
    check_distinct_bags(args.bags)
    first = Path(args.bags[0])
    out = args.out
    if out is None:
        out = first / REPLAY_DIR if first.is_dir() else first.with_name(first.stem + "-replay")
        _check_new_folder(
            out,
            f"{out} (the default output folder)",
            "remove it (an earlier replay?) or choose another folder with --out",
        )
    else:
        _check_new_folder(out, f"--out {out}")
    with _removed_on_failure(Path(out)):
        return _bench_into(args, Path(out))


def _bench_into(args: argparse.Namespace, out: Path) -> int:
    """:func:`_bench` once its output folder ``out`` has been checked."""
    try:
        summary, recorded = replay_bench(args.bags, out)
    except EmptyBenchBagError as error:
        print(f"{PROG} bench: warning: {error}", file=sys.stderr)
        return 1
    except NotBenchBagError as error:
        # Not a lit bench bag: summarise the planning queries of a ROS run (lit up, lit demo).
        # A lit bench bag among them would have its records left out without a word.
        benches = [
            str(path) for path in args.bags if Path(path) != error.path and _has_bench_config(path)
        ]
        if benches:
            raise ReplayError(
                f"{error}, while {', '.join(benches)} is a lit bench bag: replay bench tabulates "
                "lit bench bags or the planning queries of ROS runs, not both at once; give "
                "them in separate calls"
            ) from error
        skipped = Skipped()
        summaries = read_episode_summaries(args.bags, skipped)
        damaged = skipped.damaged
        if damaged:
            print(
                f"{PROG} bench: warning: {skipped.line()}; the table leaves them out: "
                + "; ".join(skipped.examples),
                file=sys.stderr,
            )
        newer = skipped.counts["unsupported version"]
        if newer:  # benign, but the table is short of them
            print(
                f"{PROG} bench: {newer} message{'s' if newer > 1 else ''} of a version this LIT* "
                "does not read (a newer one's?) left out; `lit replay info` lists them",
                file=sys.stderr,
            )
        if not summaries:
            raise ReplayError(f"{error}; nor any EpisodeSummary of a ROS run") from error
        rows, table = episode_table(summaries)
        out.mkdir(parents=True, exist_ok=True)
        (out / "episodes.json").write_text(json.dumps(rows, indent=1) + "\n")
        (out / "episodes.md").write_text(table)
        print(table, end="")
        print(
            f"{PROG} bench: {len(summaries)} planning queries -> {out}/episodes.json, episodes.md"
        )
        return 0
    if recorded.skipped.total:
        print(f"{PROG} bench: {recorded.skipped.line()}", file=sys.stderr)
    for warning in recorded.warnings:
        print(f"{PROG} bench: warning: {warning}", file=sys.stderr)
    if recorded.duplicates:
        print(
            f"{PROG} bench: warning: {len(recorded.duplicates)} duplicate run records ignored (an "
            f"identical record with the same run id and seq was read already), e.g. "
            f"{recorded.duplicates[0]}",
            file=sys.stderr,
        )
    if recorded.missing:
        print(
            f"{PROG} bench: warning: {recorded.missing} run records missing (seq gaps); the "
            "statistics cover the recorded ones only",
            file=sys.stderr,
        )
    print(
        f"{PROG} bench: {len(recorded.runs)} run records -> {out}/summary.json, summary.md, runs.jsonl, "
        f"plots ({', '.join(summary['outputs']['plots']) or 'none'})"
    )
    if "incomplete" in summary:
        print(f"{PROG} bench: warning: {summary['incomplete']['note']}", file=sys.stderr)
        return 1
    return 0

"""Bags and ``lit replay``: recording, reading back, seq accounting, salvage after SIGKILL,
damaged files, bad input, path re-checks and the regeneration of ``lit bench``'s summary.

Bags here are written by :class:`lit_planner.bag.BagRecorder`, except the checked-in sample
``bags/samples/bench_np4`` (a real ``lit bench`` run).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pytest
from lit_planner.bag import BagRecorder, envelope

from lit_planner import arena, bag, replay, scenarios

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "bags" / "samples" / "bench_np4"
ENV = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")  # lit test's own domain
OBSERVATION = "lit_msgs_json/Observation"
# The statistics of the live `lit bench` run that recorded SAMPLE (its summary.json).
SAMPLE_STATISTICS = {
    "runs": 2,
    "solved": 2,
    "success_rate": 1.0,
    "invalid_paths": 0,
    "t_init": {"median": 0.0028275515, "ci": None, "min": 0.002539694, "max": 0.003115409},
    "c_init": {
        "median": 1.3915876761360226,
        "ci": None,
        "min": 1.333767928493597,
        "max": 1.4494074237784482,
    },
    "c_final": {
        "median": 0.4978017366028667,
        "ci": None,
        "min": 0.49205873076239326,
        "max": 0.5035447424433401,
    },
    "checks_init": None,  # the sample was recorded before the runs carried it
}


def _replay(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "lit_planner.cli", "replay", *map(str, args)],
        cwd=ROOT,
        env=ENV,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


def _assert_clean_error(result: subprocess.CompletedProcess[str], fragment: str = "") -> None:
    assert result.returncode == 2, result.stdout + result.stderr
    assert "Traceback" not in result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("lit replay: error: "), lines[0]
    assert fragment in lines[0], lines[0]


def _obs(seq: int, source: str = "planner", run_id: str = "r1", **fields: Any) -> str:
    return envelope(OBSERVATION, seq, source, run_id, {"n": seq, **fields}, stamp_ns=seq)


def _summary(**fields: Any) -> dict[str, Any]:
    """A valid EpisodeSummary payload of an np4 query, with ``fields`` changed."""
    return {
        "episode_id": "e/0", "mode": "inference", "scenario": "np4", "instance": 0,
        "dimension": 4, "planner": "litstar", "policy": "fixed", "seed": 1, "status": "exact",
        "solved": True, "cost": 0.5, "t_init": 0.01, "c_init": 0.5, "optimal_cost": None,
        "time": 0.12, "time_budget": 0.12, "improvements": 1, "decisions": {"B": 1, "psi_K": 1},
        "fallback_decisions": 0, "learner_calls": 0, "path_states": 4, "path_valid": None,
        "counters": {}, **fields,
    }  # fmt: skip


def _bench_run(**fields: Any) -> dict[str, Any]:
    """A valid BenchRun payload (the sample bag's first), with ``fields`` changed."""
    return {**_sample_payloads(bag.BENCH_RUN_SCHEMA)[0], **fields}


def _mcap(directory: Path) -> Path:
    return directory / f"{directory.name}.mcap"


def _numbered_bag(path: Path, count: int, *, chunk_bytes: int = 16 * 1024) -> Path:
    """``count`` 1 KB observations with seq 0 … count-1, closed normally."""
    with BagRecorder(path, run_id="numbered", chunk_bytes=chunk_bytes) as recorder:
        recorder.add_topic("/lit/observation", bag.STRING_TYPE)
        for seq in range(count):
            recorder.write_string("/lit/observation", _obs(seq, filler="x" * 900), 10**9 + seq)
    return path


def _recovered(stdout: str) -> int:
    return sum(int(n) for n in re.findall(r"(\d+) messages recovered", stdout))


# --- recording and reading back ------------------------------------------------------------


@pytest.fixture
def mixed_bag(tmp_path: Path) -> Path:
    """Seq gaps and duplicates, a namespaced topic, a path, and three messages to skip."""
    path = tmp_path / "mixed"
    with BagRecorder(path, run_id="r1", metadata={"lit.note": "test"}) as recorder:
        recorder.add_topic("/lit/observation", bag.STRING_TYPE)
        recorder.add_topic("/robot1/lit/decision", bag.STRING_TYPE, qos="reliable-keep-last-10")
        recorder.add_topic("/lit/path", bag.TRAJECTORY_TYPE)
        recorder.add_topic("/chatter", bag.STRING_TYPE)
        for seq in (0, 1, 2, 4):  # one gap, one missing message
            recorder.write_string("/lit/observation", _obs(seq), 100 + seq)
        for seq in (0, 1, 1, 2):  # one duplicate
            text = envelope("lit_msgs_json/Decision", seq, "planner", "r1", {}, stamp_ns=seq)
            recorder.write_string("/robot1/lit/decision", text, 200 + seq)
        recorder.write_trajectory("/lit/path", [[0.0, 0.1], [0.2, 0.3]], 300)
        recorder.write_string("/chatter", "hello", 301)  # foreign topic
        unknown = envelope("lit_msgs_json/NoSuchThing", 0, "planner", "r1", {}, stamp_ns=1)
        recorder.write_string("/lit/observation", unknown, 302)
        newer = json.loads(_obs(5))
        newer["version"] = 2
        recorder.write_string("/lit/observation", json.dumps(newer), 303)
        assert recorder.messages == 12
    return path


def test_info_counts_topics_and_seq_gaps(mixed_bag: Path) -> None:
    result = _replay("info", mixed_bag, "--json")
    assert result.returncode == 0, result.stderr
    info = json.loads(result.stdout)
    counts = {t["topic"]: (t["type"], t["messages"]) for t in info["topics"]}
    assert counts == {
        "/chatter": (bag.STRING_TYPE, 1),
        "/lit/observation": (bag.STRING_TYPE, 6),
        "/lit/path": (bag.TRAJECTORY_TYPE, 1),
        "/robot1/lit/decision": (bag.STRING_TYPE, 4),
    }
    assert info["messages"] == 12
    assert (info["start_ns"], info["end_ns"]) == (100, 303)
    assert info["rosbag2_version"] == 9 and info["storage"] == "mcap"
    assert info["custom_data"]["lit.run_id"] == "r1"
    assert info["custom_data"]["lit.note"] == "test"
    assert {"lit.command", "lit.git_commit"} <= set(info["custom_data"])
    publishers = {p["topic"]: p for p in info["publishers"]}
    observation = publishers["/lit/observation"]
    assert (observation["first_seq"], observation["last_seq"], observation["count"]) == (0, 4, 4)
    assert (observation["gaps"], observation["missing"], observation["duplicates"]) == (1, 1, 0)
    decision = publishers["/robot1/lit/decision"]
    assert (decision["gaps"], decision["missing"], decision["duplicates"]) == (0, 0, 1)
    assert info["schemas"] == {"lit_msgs_json/Decision": 4, OBSERVATION: 4}
    assert info["trajectories"] == 1
    assert info["skipped"]["reasons"] == {
        "foreign topic": 1,
        "unknown schema": 1,
        "unsupported version": 1,
    }
    text = _replay("info", mixed_bag)
    assert text.returncode == 0, text.stderr
    assert "seq 0..4, 4 messages, 1 gaps, 1 missing" in text.stdout
    assert "3 skipped" in text.stdout


def test_info_prints_recorded_names_escaped(tmp_path: Path) -> None:
    """Any process on the graph can publish on /lit/*: a source with a lone surrogate ended
    ``lit replay info`` with a UnicodeEncodeError and nothing else, and one with a terminal
    escape and a newline coloured the terminal and forged a line of the output."""
    path = tmp_path / "poisoned"
    with BagRecorder(path, run_id="r1") as recorder:
        recorder.add_topic("/lit/decision", bag.STRING_TYPE)
        for seq, source in enumerate(("/ev\x1b[31mil\nfake line", "/evil\ud800")):
            text = envelope("lit_msgs_json/Decision", seq, source, "r1", {}, stamp_ns=seq)
            recorder.write_string("/lit/decision", text, 100 + seq)
    result = _replay("info", path)
    assert result.returncode == 0 and "Traceback" not in result.stderr, result.stderr
    assert "from /ev\\x1b[31mil\\x0afake line (run r1)" in result.stdout, result.stdout
    assert "from /evil\\ud800 (run r1)" in result.stdout, result.stdout
    assert "\x1b" not in result.stdout
    assert not any(line.startswith("fake line") for line in result.stdout.splitlines())


def test_info_tells_a_reused_seq_from_a_copy(tmp_path: Path) -> None:
    """A seq recorded again with the same bytes is a duplicate (a copy); under other bytes it is
    reused (two publishers of one name and run id), which was counted as a duplicate too."""
    path = tmp_path / "reused"
    with BagRecorder(path, run_id="r1") as recorder:
        recorder.add_topic("/lit/decision", bag.STRING_TYPE)
        for index, (seq, agent) in enumerate([(0, "b"), (0, "k"), (1, "b"), (1, "b"), (2, "b")]):
            payload = {"agent": agent}
            text = envelope("lit_msgs_json/Decision", seq, "/p", "r1", payload, stamp_ns=seq)
            recorder.write_string("/lit/decision", text, 100 + index)
    (publisher,) = replay.bag_info(path)["publishers"]
    assert (publisher["count"], publisher["duplicates"], publisher["reused"]) == (5, 1, 1)
    text = _replay("info", path)
    assert "seq 0..2, 5 messages, 1 duplicates, 1 reused seqs (two publishers" in text.stdout


def test_info_accounts_a_restarted_publisher_as_a_process_of_its_own(tmp_path: Path) -> None:
    """A node restarted under the same name and run id (lit up passes one) counts from 0 again:
    its second process is accounted apart, so its numbers do not pass for duplicates of the first
    one's, and a gap in either still shows. A copy of a message (same stamp) and a message
    recorded out of order (sent just before the later ones) stay in their process."""
    second = 10_000_000_000  # the second process starts sending 10 s after the first
    sent = [(0, 0), (1, 1_000), (2, 2_000), (2, 2_000), (4, 4_000), (3, 3_000)]  # copy, order
    sent += [(0, second), (1, second + 1_000), (3, second + 3_000)]  # 2 lost
    path = tmp_path / "restarted"
    with BagRecorder(path, run_id="r1") as recorder:
        recorder.add_topic("/lit/decision", bag.STRING_TYPE)
        for index, (seq, stamp) in enumerate(sent):
            text = envelope("lit_msgs_json/Decision", seq, "/lit_planner", "r1", {}, stamp_ns=stamp)
            recorder.write_string("/lit/decision", text, 100 + index)
    info = replay.bag_info(path)
    first, restarted = info["publishers"]
    assert (first["instance"], first["count"], first["last_seq"]) == (1, 6, 4)
    assert (first["duplicates"], first["reordered"], first["missing"]) == (1, 1, 0)
    assert (restarted["instance"], restarted["count"], restarted["first_seq"]) == (2, 3, 0)
    assert (restarted["duplicates"], restarted["gaps"], restarted["missing"]) == (0, 1, 1)
    text = _replay("info", path)
    assert "/lit/decision from /lit_planner (run r1, process 2): seq 0..3, 3 messages, 1 gaps" in (
        text.stdout
    )


def test_an_mcap_file_of_a_bag_folder_has_the_folders_metadata(mixed_bag: Path) -> None:
    """``info`` of a bag's .mcap file said "no metadata" (and ``bench`` of it showed another
    duration than of its folder): a BAG is the folder or one of its files, the same run."""
    folder = replay.bag_info(mixed_bag)
    file = replay.bag_info(_mcap(mixed_bag))
    assert file["custom_data"] == folder["custom_data"] and folder["custom_data"]["lit.note"]
    assert file["rosbag2_version"] == folder["rosbag2_version"] == bag.BAG_VERSION
    alone = mixed_bag.parent / "alone.mcap"  # the same file outside its folder: no metadata
    shutil.copyfile(_mcap(mixed_bag), alone)
    assert replay.bag_info(alone)["rosbag2_version"] is None


def test_bag_reads_with_rosbags_mcap_and_metadata(mixed_bag: Path) -> None:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.rosbag2 import Reader
    from ruamel.yaml import YAML

    store = bag.typestore()
    with Reader(mixed_bag) as reader:
        texts = [
            store.deserialize_cdr(raw, c.msgtype).data
            for c, _, raw in reader.messages()
            if c.topic == "/lit/observation"
        ]
    assert [json.loads(t)["seq"] for t in texts[:4]] == [0, 1, 2, 4]
    with _mcap(mixed_bag).open("rb") as handle:
        decoded = {
            channel.topic: message
            for _, channel, _, message in make_reader(
                handle, decoder_factories=[DecoderFactory()]
            ).iter_decoded_messages()
        }
    assert list(decoded["/lit/path"].points[1].positions) == [0.2, 0.3]
    assert decoded["/lit/path"].joint_names == ["q0", "q1"]
    assert decoded["/chatter"].data == "hello"
    meta = YAML(typ="safe").load((mixed_bag / "metadata.yaml").read_text())
    info = meta["rosbag2_bagfile_information"]
    assert info["version"] == 9 and info["storage_identifier"] == "mcap"
    assert info["compression_mode"] == "" and info["custom_data"]["lit.run_id"] == "r1"
    qos = {
        t["topic_metadata"]["name"]: t["topic_metadata"]["offered_qos_profiles"][0]
        for t in info["topics_with_message_count"]
    }
    assert qos["/lit/observation"]["history"] == "keep_all"
    assert qos["/lit/observation"]["reliability"] == "reliable"
    assert qos["/lit/observation"]["durability"] == "volatile"
    assert (qos["/robot1/lit/decision"]["history"], qos["/robot1/lit/decision"]["depth"]) == (
        "keep_last",
        10,
    )


def test_recorder_rejects_bad_use(tmp_path: Path) -> None:
    with BagRecorder(tmp_path / "b", run_id="r") as recorder:
        with pytest.raises(ValueError, match="not supported"):
            recorder.add_topic("/lit/x", "sensor_msgs/msg/Image")
        with pytest.raises(bag.BagError, match="QoS"):
            recorder.add_topic("/lit/x", bag.STRING_TYPE, qos="sometimes")
        with pytest.raises(bag.BagError, match="not added"):
            recorder.write_string("/lit/y", "{}", 1)
    recorder.close()  # idempotent
    with pytest.raises(bag.BagError, match="exists already"):
        BagRecorder(tmp_path / "b", run_id="r")


def test_recorder_is_thread_safe(tmp_path: Path) -> None:
    import threading

    with BagRecorder(tmp_path / "threads", run_id="t", chunk_bytes=4096) as recorder:
        recorder.add_topic("/lit/observation", bag.STRING_TYPE)

        def publish(source: str) -> None:
            for seq in range(500):
                recorder.write_string("/lit/observation", _obs(seq, source), 10**9 + seq)

        threads = [threading.Thread(target=publish, args=(f"p{i}",)) for i in range(4)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
    assert recorder.messages == 2000
    info = replay.bag_info(tmp_path / "threads")
    assert [(p["source"], p["count"], p["gaps"]) for p in info["publishers"]] == [
        (f"p{i}", 500, 0) for i in range(4)
    ]


# --- crash loss and salvage ----------------------------------------------------------------

WRITER = textwrap.dedent(
    """
    import sys, time
    from lit_planner.bag import BagRecorder, envelope

    recorder = BagRecorder(sys.argv[1], run_id="killed",
                           metadata={"lit.decision_interval": "7", "lit.source": "lit_train"})
    recorder.add_topic("/lit/observation", "std_msgs/msg/String")
    seq = 0
    while True:
        text = envelope("lit_msgs_json/Observation", seq, "planner", "killed", {"f": "x" * 900})
        recorder.write_string("/lit/observation", text, time.time_ns())
        seq += 1
        print(seq, flush=True)  # confirmed: write_string returned
        time.sleep(0.0002)
    """
)


def test_salvage_after_sigkill(tmp_path: Path) -> None:
    confirmed_target = 300
    script = tmp_path / "writer.py"
    script.write_text(WRITER)
    killed = tmp_path / "killed"
    child = subprocess.Popen(
        [sys.executable, str(script), str(killed)],
        stdout=subprocess.PIPE,
        text=True,
        env=ENV,
        cwd=ROOT,
    )
    try:
        confirmed = 0
        assert child.stdout is not None
        for line in child.stdout:
            confirmed = int(line)
            if confirmed >= confirmed_target:
                break
        os.kill(child.pid, signal.SIGKILL)
    finally:
        child.kill()
        child.wait(timeout=30)
    assert confirmed >= confirmed_target
    assert not (killed / "metadata.yaml").exists()
    assert (killed / bag.UNFINISHED_METADATA).is_file()
    _assert_clean_error(_replay("info", killed), "lit replay salvage")

    result = _replay("salvage", killed)
    assert result.returncode == 0, result.stderr
    recovered = _recovered(result.stdout)
    record = len(_obs(0, filler="x" * 900)) + 31  # message record: CDR (about the text) + header
    per_chunk = bag.DEFAULT_CHUNK_BYTES // record + 1
    assert recovered >= confirmed - per_chunk, result.stdout
    assert "the writer did not finish" in result.stdout
    salvaged = tmp_path / "killed-salvaged"
    from rosbags.rosbag2 import Reader

    with Reader(salvaged) as reader:
        assert reader.message_count == recovered
    info = replay.bag_info(salvaged)
    (publisher,) = info["publishers"]
    assert (publisher["first_seq"], publisher["last_seq"]) == (0, recovered - 1)
    assert publisher["gaps"] == 0
    assert info["custom_data"]["lit.run_id"] == "killed"
    assert "lit.salvaged_from" in info["custom_data"]
    # The run's metadata, which only metadata.yaml held before (lit replay tensors needs the
    # decision interval of a training run), comes from the file the writer left.
    assert info["custom_data"]["lit.decision_interval"] == "7"
    assert info["custom_data"]["lit.command"].endswith(f"writer.py {killed}")
    assert not (salvaged / bag.UNFINISHED_METADATA).exists()  # closed normally


def test_salvage_truncated_and_bit_flipped(tmp_path: Path) -> None:
    from mcap.reader import make_reader

    source = _numbered_bag(tmp_path / "source", 300)
    with _mcap(source).open("rb") as handle:
        chunks = sorted(
            c.chunk_start_offset for c in make_reader(handle).get_summary().chunk_indexes
        )
    data = _mcap(source).read_bytes()
    assert len(chunks) >= 5

    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])
    result = _replay("salvage", cut)
    assert result.returncode == 0, result.stderr
    recovered = _recovered(result.stdout)
    assert 0 < recovered < 300
    stopped = int(re.search(r"stopped at byte (\d+)", result.stdout).group(1))  # type: ignore[union-attr]
    assert stopped <= len(data) // 2
    info = replay.bag_info(tmp_path / "cut-salvaged")
    assert info["publishers"][0]["last_seq"] == recovered - 1
    assert info["custom_data"]["lit.chunk_bytes"] == str(bag.DEFAULT_CHUNK_BYTES)  # not 16 KiB

    # A damaged length inside chunk 2: that chunk is lost, reading goes on.
    inner = bytearray(data)
    inner[chunks[1] + 49 + 8] ^= 0x40  # high byte of the first inner record's length
    (tmp_path / "inner.mcap").write_bytes(bytes(inner))
    result = _replay("salvage", tmp_path / "inner.mcap")
    assert result.returncode == 0, result.stderr
    assert "damaged chunk" in result.stdout and "complete file" in result.stdout
    assert 200 < _recovered(result.stdout) < 300

    # A damaged length of chunk 3's record: reading stops there; that chunk and the ones after
    # it are read at the offsets and lengths of the summary's chunk index.
    outer = bytearray(data)
    outer[chunks[2] + 8] ^= 0x01  # high byte of the record length
    (tmp_path / "outer.mcap").write_bytes(bytes(outer))
    result = _replay("salvage", tmp_path / "outer.mcap")
    assert result.returncode == 0, result.stderr
    assert f"stopped at byte {chunks[2]}" in result.stdout
    assert f"read the chunk at byte {chunks[2]} (" in result.stdout
    assert result.stdout.count("through the summary's chunk index") == len(chunks) - 2
    after = replay.bag_info(tmp_path / "outer-salvaged")["publishers"][0]
    assert (after["first_seq"], after["gaps"], after["count"]) == (0, 0, 300)
    # Without the summary (the file cut before it), the chunks before the damage are kept.
    (tmp_path / "outer-cut.mcap").write_bytes(bytes(outer[: chunks[-1]]))
    result = _replay("salvage", tmp_path / "outer-cut.mcap")
    assert result.returncode == 0, result.stderr
    assert "chunk index" not in result.stdout
    before = replay.bag_info(tmp_path / "outer-cut-salvaged")["publishers"][0]
    assert (before["first_seq"], before["gaps"]) == (0, 0)
    assert 0 < before["count"] < 300

    # A damaged opcode of chunk 2 (mcap's reader skips a record of an unknown type without a
    # word): said, and the chunk is read through the chunk index.
    opcode = bytearray(data)
    opcode[chunks[1]] = 0x7E
    (tmp_path / "opcode.mcap").write_bytes(bytes(opcode))
    result = _replay("salvage", tmp_path / "opcode.mcap")
    assert result.returncode == 0, result.stderr
    assert f"skipped the record at byte {chunks[1]}" in result.stdout
    assert "opcode 0x7e is not an MCAP record type" in result.stdout
    assert f"read the chunk at byte {chunks[1]} (" in result.stdout
    assert _recovered(result.stdout) == 300
    custom = replay.bag_info(tmp_path / "opcode-salvaged")["custom_data"]
    assert "through the summary's chunk index" in custom["lit.salvage"]

    # Chunk 2's opcode damaged into a footer's (0x06 -> 0x02): reading took it for the end of
    # the file, and every chunk after it was lost from a "successful" salvage. It is skipped, and
    # the chunk read through the chunk index.
    as_footer = bytearray(data)
    as_footer[chunks[1]] = 0x02
    (tmp_path / "as-footer.mcap").write_bytes(bytes(as_footer))
    result = _replay("salvage", tmp_path / "as-footer.mcap")
    assert result.returncode == 0, result.stderr
    assert "its opcode says footer, but a footer ends the file" in result.stdout, result.stdout
    assert f"read the chunk at byte {chunks[1]} (" in result.stdout
    assert _recovered(result.stdout) == 300

    # Chunk 2's records-length field one less or one more than its record holds (the records and
    # their CRC intact): the chunk was dropped for its CRC, or the reading went out of step.
    records_length = chunks[1] + 9 + 32  # after the times, sizes, CRC and an empty compression
    assert data[records_length - 4 : records_length] == bytes(4)  # the compression name's length
    for name, delta in (("shorter", -1), ("longer", 1)):
        damaged = bytearray(data)
        value = int.from_bytes(damaged[records_length : records_length + 8], "little") + delta
        damaged[records_length : records_length + 8] = value.to_bytes(8, "little")
        (tmp_path / f"{name}.mcap").write_bytes(bytes(damaged))
        result = _replay("salvage", tmp_path / f"{name}.mcap")
        assert result.returncode == 0, result.stderr
        assert f"the chunk at byte {chunks[1]}: its records-length field says {value}" in (
            result.stdout
        ), result.stdout
        assert _recovered(result.stdout) == 300, result.stdout
    # Chunk 2's record length one less or one more (its records-length field intact): read as
    # the field gives it, or the chunk and those after it through the chunk index; the field
    # is not blamed.
    for name, delta in (("record-shorter", -1), ("record-longer", 1)):
        damaged = bytearray(data)
        value = int.from_bytes(damaged[chunks[1] + 1 : chunks[1] + 9], "little") + delta
        damaged[chunks[1] + 1 : chunks[1] + 9] = value.to_bytes(8, "little")
        (tmp_path / f"{name}.mcap").write_bytes(bytes(damaged))
        result = _replay("salvage", tmp_path / f"{name}.mcap")
        assert result.returncode == 0, result.stderr
        assert _recovered(result.stdout) == 300, result.stdout
        assert "records-length field says" not in result.stdout, result.stdout
        if delta < 0:
            assert "complete file" in result.stdout
            assert f"its record says {value} bytes" in result.stdout, result.stdout
    # A flipped bit in the summary's copy of the schema name (the data section's copy intact):
    # the later copy replaced the first, and every message of the schema was dropped.
    name = bag.STRING_TYPE.encode()
    summary_copy = data.rindex(name)
    assert summary_copy > chunks[-1] and data.index(name) < chunks[0] + 100  # one copy each
    renamed = bytearray(data)
    renamed[summary_copy + len(name) - 1] ^= 0x02  # ...String -> ...Strinl
    (tmp_path / "renamed.mcap").write_bytes(bytes(renamed))
    result = _replay("salvage", tmp_path / "renamed.mcap")
    assert result.returncode == 0, result.stderr
    assert _recovered(result.stdout) == 300, result.stdout
    # The data section's copy damaged instead (inside chunk 1, whose CRC then fails): that
    # chunk's messages are lost, the summary's intact copy serves every other chunk.
    renamed = bytearray(data)
    renamed[data.index(name) + len(name) - 1] ^= 0x02
    (tmp_path / "renamed-first.mcap").write_bytes(bytes(renamed))
    result = _replay("salvage", tmp_path / "renamed-first.mcap")
    assert result.returncode == 0, result.stderr
    assert "damaged chunk" in result.stdout and "does not match its records" in result.stdout
    assert 250 < _recovered(result.stdout) < 300, result.stdout
    # Bytes after the end magic: the footer before them is still the file's footer.
    (tmp_path / "trailing.mcap").write_bytes(data + bytes(16))
    result = _replay("salvage", tmp_path / "trailing.mcap")
    assert result.returncode == 0, result.stderr
    assert "footer ends the file" not in result.stdout, result.stdout
    assert _recovered(result.stdout) == 300

    # A damaged MCAP footer: the normal readers fail cleanly, salvage gets everything.
    footer = bytearray(data)
    footer[-8 - 20 + 7] ^= 0x01  # high byte of the footer's summary offset
    (tmp_path / "footer.mcap").write_bytes(bytes(footer))
    assert _replay("info", tmp_path / "footer.mcap").returncode == 2
    result = _replay("salvage", tmp_path / "footer.mcap")
    assert result.returncode == 0 and _recovered(result.stdout) == 300, result.stdout


def test_a_changed_digit_fails_the_chunk_checksum(tmp_path: Path) -> None:
    """The recorder writes each chunk's CRC-32 (rosbags writes 0, "none"): a digit changed inside
    a message, which still decodes, is caught by every reader, and salvage keeps the other
    chunks whole and leaves that one out, saying so."""
    from mcap.records import Chunk
    from mcap.stream_reader import StreamReader

    source = _numbered_bag(tmp_path / "source", 300)
    with _mcap(source).open("rb") as handle:
        crcs = [
            r.uncompressed_crc for r in StreamReader(handle, emit_chunks=True).records
            if isinstance(r, Chunk)
        ]  # fmt: skip
    assert len(crcs) >= 5 and all(crcs)
    data = _mcap(source).read_bytes()
    assert data.count(b'"n": 150,') == 1
    changed = tmp_path / "changed"
    shutil.copytree(source, changed)
    (changed / _mcap(source).name).write_bytes(data.replace(b'"n": 150,', b'"n": 950,'))
    for command in ("info", "verify"):
        _assert_clean_error(_replay(command, changed), "lit replay salvage")
    result = _replay("salvage", changed, "-o", tmp_path / "salvaged")
    assert result.returncode == 0, result.stderr
    assert "does not match its records" in result.stdout, result.stdout
    recovered = _recovered(result.stdout)
    assert 250 < recovered < 300
    info = replay.bag_info(tmp_path / "salvaged")["publishers"][0]
    assert info["count"] == recovered and info["gaps"] == 1
    # Asked for, the messages of that chunk that read are kept too, said to be unverified: the
    # changed one among them.
    result = _replay("salvage", changed, "-o", tmp_path / "unverified", "--keep-unverified")
    assert result.returncode == 0, result.stderr
    assert f"{300 - recovered} of its messages kept UNVERIFIED" in result.stdout, result.stdout
    assert _recovered(result.stdout) == 300
    assert b'"n": 950,' in _mcap(tmp_path / "unverified").read_bytes()
    # ... and the new bag's metadata says so (lit replay info shows it).
    salvage_note = replay.bag_info(tmp_path / "unverified")["custom_data"]["lit.salvage"]
    assert f"{300 - recovered} of its messages kept UNVERIFIED" in salvage_note, salvage_note
    # A bag of one chunk: nothing to salvage, and the error says why and what to do (it gave
    # only "stopped at byte ...: complete file", while info and verify sent the user to salvage).
    small = _numbered_bag(tmp_path / "small", 5)
    _mcap(small).write_bytes(_mcap(small).read_bytes().replace(b'"n": 3,', b'"n": 9,'))
    result = _replay("salvage", small, "-o", tmp_path / "small-salvaged")
    assert result.returncode == 2 and "nothing to salvage" in result.stderr, result.stderr
    assert "does not match its records" in result.stderr and "--keep-unverified" in result.stderr


@pytest.mark.parametrize("command", ["compact", "bench"])
def test_sigterm_leaves_no_half_written_output(command: str, tmp_path: Path) -> None:
    """`kill PID` stops like Ctrl-C (exit 130) and removes what the command had written: a
    SIGTERM used to leave half a compacted bag, and an interrupted bench a plots/ folder that then
    blocked the rerun ("exists and is not empty")."""
    shipped = ROOT / "bags" / "shipped"
    source = shipped / ("train-20261130c" if command == "compact" else "tensor-paper-20261207")
    out = tmp_path / "out"
    args = [source, out] if command == "compact" else [source, "--out", out]
    process = subprocess.Popen(
        [sys.executable, "-m", "lit_planner.cli", "replay", command, *map(str, args)],
        cwd=ROOT, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        while not out.exists() and process.poll() is None:
            time.sleep(0.005)
        process.send_signal(signal.SIGTERM)
        _, stderr = process.communicate(timeout=120)
    finally:
        process.kill()
        process.wait()
    assert process.returncode == 130, stderr
    assert "lit replay: interrupted" in stderr and "Traceback" not in stderr, stderr
    assert not out.exists()


@pytest.mark.parametrize("command", ["compact", "salvage", "bench"])
def test_a_write_failure_leaves_no_half_written_output(command: str, tmp_path: Path) -> None:
    """A full disk in the middle of the output left a half-written bag or a cut runs.jsonl,
    which then blocked the rerun ("exists already"), with an error that named no file."""
    source = _numbered_bag(tmp_path / "source", 300)
    if command == "salvage":
        _mcap(source).write_bytes(_mcap(source).read_bytes()[:200_000])
    elif command == "bench":
        source = SAMPLE
    out = tmp_path / "out"
    args = [source, "--out", out] if command == "bench" else [source, "-o", out]
    if command == "compact":
        args = [source, out]
    from ros_helpers import file_size_limited

    result = subprocess.run(
        [*file_size_limited(8192, sys.executable), "-m", "lit_planner.cli", "replay", command,
         *map(str, args)],
        cwd=ROOT, env=ENV, capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    _assert_clean_error(result, f"cannot write {out}: ")
    assert "File too large" in result.stderr
    assert not out.exists()


def test_ctrl_c_during_measure_prints_no_writers_traceback(tmp_path: Path) -> None:
    """A Ctrl-C (SIGINT to the terminal's process group) during the crash trials reached the
    writer process too, which printed its own KeyboardInterrupt traceback."""
    from lit_planner.testing import handles_signal
    from ros_helpers import children_of

    process = subprocess.Popen(
        [sys.executable, "-m", "lit_planner.cli", "replay", "measure", "--messages", "2000",
         "--kills", "1000"],
        cwd=ROOT, env=dict(ENV, TMPDIR=str(tmp_path)), stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True, start_new_session=True,  # its own process group
    )  # fmt: skip
    try:
        assert process.stdout is not None
        for line in process.stdout:
            if line.startswith("crash 3/"):  # the trials run
                break
        deadline = time.monotonic() + 60.0
        # A writer runs, with Python's own SIGINT handler (before it, a SIGINT ends it quietly).
        while not any(handles_signal(pid, signal.SIGINT) for pid in children_of(process.pid)):
            assert process.poll() is None and time.monotonic() < deadline
            time.sleep(0.001)
        os.killpg(process.pid, signal.SIGINT)  # as a terminal's Ctrl-C: the whole group
        _, stderr = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == 130, stderr
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr, stderr
    assert "lit replay: interrupted" in stderr


def test_measure_counts_a_writer_killed_before_its_first_chunk(tmp_path: Path) -> None:
    """With chunks larger than what the writer wrote before the kill, its .mcap file is empty:
    that used to end the measurement with "is an empty file" (exit 2)."""
    result = _replay("measure", "--messages", "100", "--kills", "1", "--chunk-bytes", "1048576")
    assert result.returncode == 0, result.stdout + result.stderr
    crash = re.search(
        r"SIGKILL after (\d+) confirmed writes, (\d+) recovered, (\d+) lost", result.stdout
    )
    assert crash is not None, result.stdout
    confirmed, recovered, lost = map(int, crash.groups())
    assert recovered == 0 and lost == confirmed > 0


def test_an_mcap_file_of_another_kind_is_named_as_such(tmp_path: Path) -> None:
    """An MCAP file whose profile is not ros2 (another program's) is no bag: it was told to
    "recover it with lit replay salvage", and salvage then found nothing to salvage."""
    from mcap.writer import Writer

    plain = tmp_path / "plain.mcap"
    with plain.open("wb") as handle:
        writer = Writer(handle)
        writer.start(profile="", library="test")
        schema = writer.register_schema(name="text", encoding="jsonschema", data=b"{}")
        channel = writer.register_channel(topic="/x", message_encoding="json", schema_id=schema)
        writer.add_message(channel, log_time=1, data=b"{}", publish_time=1)
        writer.finish()
    folder = tmp_path / "folder"
    folder.mkdir()
    shutil.copy(plain, folder / "plain.mcap")
    for bag_path in (plain, folder):
        _assert_clean_error(_replay("info", bag_path), "not a ROS 2 bag")


def test_a_sqlite3_bag_is_named_as_such(tmp_path: Path) -> None:
    """A rosbag2 bag in sqlite3 storage was said to have a metadata.yaml that does not match its
    MCAP files, with a salvage hint, and salvage then found no .mcap file."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    bag_path = tmp_path / "sqlite"
    with Writer(bag_path, version=8) as writer:
        connection = writer.add_connection("/chatter", "std_msgs/msg/String", typestore=store)
        message = store.types["std_msgs/msg/String"](data="hi")
        writer.write(connection, 1, store.serialize_cdr(message, "std_msgs/msg/String"))
    for verb in ("info", "salvage", "verify"):
        _assert_clean_error(_replay(verb, bag_path), "in 'sqlite3' storage")


# --- bad input -----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def bad_inputs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    base = tmp_path_factory.mktemp("bad")
    good = _numbered_bag(base / "good", 50, chunk_bytes=8 * 1024)
    data = _mcap(good).read_bytes()
    (base / "empty_dir").mkdir()
    (base / "empty.mcap").touch()
    (base / "cut.mcap").write_bytes(data[:20])
    flipped = bytearray(data)
    flipped[15] ^= 0x01  # high byte of the MCAP header record's length
    (base / "flipped.mcap").write_bytes(bytes(flipped))
    (base / "notes.txt").write_text("not a bag")
    gone = base / "file_gone"  # a bag folder whose .mcap file was moved away
    shutil.copytree(good, gone)
    (gone / _mcap(good).name).unlink()
    (base / "killed_early").mkdir()  # a writer killed before it wrote anything
    (base / "killed_early" / "killed_early_0.mcap").touch()
    return {
        "missing": base / "missing",
        "empty directory": base / "empty_dir",
        "empty file": base / "empty.mcap",
        "truncated": base / "cut.mcap",
        "bit flip": base / "flipped.mcap",
        "not a bag": base / "notes.txt",
        "listed file gone": gone,
        "folder of an empty file": base / "killed_early",
    }


@pytest.mark.parametrize("command", ["info", "verify", "bench", "salvage", "tensors"])
def test_bad_input_is_one_line_exit_2(
    command: str, bad_inputs: dict[str, Path], tmp_path: Path
) -> None:
    expected = {
        "missing": "no such file or directory",
        "empty directory": "empty directory",
        "empty file": "empty file",
        "truncated": "truncated",
        "bit flip": "its HEADER record at byte 8 claims",
        "not a bag": "not an MCAP file" if command == "salvage" else "is not a bag",
        "listed file gone": "lists good.mcap, which is not there (no .mcap file is left",
        # It advised salvage, which then refused the empty file.
        "folder of an empty file": (
            "killed_early_0.mcap is an empty file"
            if command == "salvage"
            else "has no metadata.yaml and its .mcap file is empty: nothing was recorded"
        ),
    }
    for case, path in bad_inputs.items():
        out = tmp_path / f"tensors-{case}"
        result = _replay(command, path, *(["--out", out] if command == "tensors" else []))
        if command == "tensors":
            assert not out.exists(), f"{case}: {sorted(out.iterdir())}"  # nothing half-written
        if (command, case) == ("salvage", "bit flip"):
            # The header's damaged length stops the reading at once; the summary's chunk index
            # gives every chunk.
            assert result.returncode == 0, result.stderr
            assert _recovered(result.stdout) == 50, result.stdout
            continue
        try:
            _assert_clean_error(result, expected[case])
        except AssertionError as error:
            raise AssertionError(f"{command} {case}: {error}") from None


def test_an_extra_argument_is_named_with_the_subcommands_usage(tmp_path: Path) -> None:
    """`lit replay salvage BAG OUT` (OUT needs -o) printed lit's top-level usage."""
    result = _replay("salvage", tmp_path / "bag", tmp_path / "out")
    assert result.returncode == 2
    assert result.stderr.startswith(
        "usage: lit replay salvage [-h] [-o OUT] [--keep-unverified] BAG"
    ), result.stderr
    assert f"lit replay salvage: error: unrecognized arguments: {tmp_path / 'out'}" in result.stderr


def test_an_empty_metadata_file_is_named(tmp_path: Path) -> None:
    """rosbags' own words were "'NoneType' object is not subscriptable"."""
    copy = _sample_copy(tmp_path, "blank")
    (copy / "metadata.yaml").write_text("")
    for command in ("info", "verify", "bench"):
        _assert_clean_error(_replay(command, copy), "its metadata.yaml is empty")


def test_a_duration_in_the_metadata_that_is_no_number_is_named(tmp_path: Path) -> None:
    """rosbags' own words were "TypeError: can only concatenate str (not "int") to str"."""
    copy = _sample_copy(tmp_path, "wordy")
    metadata = copy / "metadata.yaml"
    text = metadata.read_text()
    assert text.startswith("rosbag2_bagfile_information:\n") and "\n  duration:\n" in text
    head, tail = text.split("\n  duration:\n    nanoseconds: ", 1)
    metadata.write_text(head + "\n  duration:\n    nanoseconds: abc\n" + tail.split("\n", 1)[1])
    for command in ("info", "verify", "bench"):
        _assert_clean_error(
            _replay(command, copy), "its metadata.yaml's duration.nanoseconds is 'abc', not a whole"
        )


def test_custom_data_that_is_not_a_mapping_is_named(tmp_path: Path) -> None:
    """A list there failed every reader with "dictionary update sequence element #0 ..."."""
    copy = _sample_copy(tmp_path, "listed")
    metadata = copy / "metadata.yaml"
    text = metadata.read_text()
    assert "  custom_data:\n    " in text
    metadata.write_text(
        text.replace("  custom_data:\n    ", "  custom_data:\n    - x\n  was:\n    ", 1)
    )
    for command in ("info", "verify", "bench"):
        _assert_clean_error(_replay(command, copy), "its custom_data is a list, not a mapping")


def test_salvage_of_an_mcap_that_is_no_file_is_named(tmp_path: Path) -> None:
    """IsADirectoryError's and FileNotFoundError's own words before."""
    folder = tmp_path / "odd"
    (folder / "run.mcap").mkdir(parents=True)
    _assert_clean_error(_replay("salvage", folder), "run.mcap is not a file")
    (tmp_path / "linked").mkdir()
    (tmp_path / "linked" / "run.mcap").symlink_to(tmp_path / "nowhere.mcap")
    _assert_clean_error(_replay("salvage", tmp_path / "linked"), "run.mcap is not a file")


def test_killed_bag_without_mcap_or_metadata(tmp_path: Path) -> None:
    (tmp_path / "x").mkdir()
    (tmp_path / "x" / "readme").write_text("hi")
    _assert_clean_error(_replay("info", tmp_path / "x"), "not a bag")
    _assert_clean_error(_replay("salvage", tmp_path / "x"), "no .mcap file")
    (tmp_path / "out").mkdir()
    good = _numbered_bag(tmp_path / "good", 3)
    _assert_clean_error(_replay("salvage", good, "-o", tmp_path / "out"), "exists already")


# --- verify --------------------------------------------------------------------------------


def test_verify_flags_invalid_paths(tmp_path: Path) -> None:
    world = scenarios.get("np4")
    through_wall = [list(world.start), list(world.goal)]  # straight through the wall
    x1 = 0.1  # inside the passage's free x1 interval (0.05, 0.15)
    around = [
        list(world.start),
        [-0.15, x1, 0.0, 0.0],
        [0.15, x1, 0.0, 0.0],
        list(world.goal),
    ]
    assert scenarios.check_path(world, around).ok
    record = _bench_run(scenario="np4", instance=0, solved=True, planner="x", run=0)
    bench_bag = tmp_path / "bench"
    with BagRecorder(bench_bag, run_id="v") as recorder:
        recorder.add_topic(bag.BENCH_RUN_TOPIC, bag.STRING_TYPE)
        for seq, (path, claimed) in enumerate([(through_wall, True), (around, True)]):
            payload = {**record, "path": path, "path_valid": claimed}
            text = envelope(bag.BENCH_RUN_SCHEMA, seq, "lit_bench", "v", payload, stamp_ns=seq)
            recorder.write_string(bag.BENCH_RUN_TOPIC, text, 10 + seq)
    episode_bag = tmp_path / "episodes"
    with BagRecorder(episode_bag, run_id="e") as recorder:
        recorder.add_topic("/robot1/lit/episode", bag.STRING_TYPE)
        recorder.add_topic("/robot1/lit/path", bag.TRAJECTORY_TYPE)
        # As the planner node publishes: the summary, then the path with frame_id = episode_id.
        # Episode 2 is unsolved: its (approximate) path is not a solution to check.
        for seq, (path, solved) in enumerate(
            [(around, True), (through_wall, True), (around, False)]
        ):
            stamp = 1_000_000_000 * (seq + 1)
            payload = _summary(episode_id=f"e/{seq}", solved=solved)
            text = envelope(replay.EPISODE_SCHEMA, seq, "planner", "e", payload, stamp_ns=stamp)
            recorder.write_string("/robot1/lit/episode", text, stamp)
            recorder.write_trajectory("/robot1/lit/path", path, stamp + 1000, frame_id=f"e/{seq}")
    result = _replay("verify", bench_bag, episode_bag)
    assert result.returncode == 1, result.stdout + result.stderr
    assert "4 paths checked: 2 valid, 2 invalid; 1 runs without a path" in result.stdout
    assert result.stdout.count("INVALID") == 2
    assert "/lit/bench/run seq 0 (x run 0): np4: segment 0 leaves the free space" in result.stdout
    assert "/robot1/lit/episode seq 1" in result.stdout
    assert "DIFFERS  /lit/bench/run seq 0" in result.stdout  # recorded path_valid=True was wrong

    sample = _replay("verify", SAMPLE)
    assert sample.returncode == 0, sample.stdout + sample.stderr
    assert "2 paths checked: 2 valid, 0 invalid" in sample.stdout

    # A ROS run's bag with its compacted copy: the copy's paths were "path without an episode"
    # (its episodes were skipped as read twice, its paths were not), and verify said incomplete.
    assert _replay("compact", episode_bag, tmp_path / "episodes-copy").returncode == 0
    both = _replay("verify", episode_bag, tmp_path / "episodes-copy")
    assert "2 paths checked: 1 valid, 1 invalid; 1 runs without a path" in both.stdout, both.stdout
    assert "without an episode" not in both.stdout and "incomplete" not in both.stdout
    # replay bench's table of a ROS run counts each query once (it counted 6)
    assert len(replay.read_episode_summaries([episode_bag, tmp_path / "episodes-copy"])) == 3

    # A bag given with its compacted copy: each path is checked once (it counted 4).
    assert _replay("compact", SAMPLE, tmp_path / "copy").returncode == 0
    both = _replay("verify", SAMPLE, tmp_path / "copy")
    assert both.returncode == 0, both.stdout + both.stderr
    assert "2 paths checked: 2 valid, 0 invalid" in both.stdout
    assert "read twice" in both.stdout


def test_verify_counts_a_returned_path_the_node_found_invalid(tmp_path: Path) -> None:
    """The planner node does not publish a path its own check finds invalid; verify called such
    an episode "not checkable" (exit 1 as incomplete) and hid the invalid path it returned."""
    path = tmp_path / "flagged"
    with BagRecorder(path, run_id="f") as recorder:
        recorder.add_topic("/lit/episode", bag.STRING_TYPE)
        recorder.add_topic("/lit/path", bag.TRAJECTORY_TYPE)
        payload = _summary(episode_id="f/0", path_valid=False)
        text = envelope(replay.EPISODE_SCHEMA, 0, "planner", "f", payload, stamp_ns=1)
        recorder.write_string("/lit/episode", text, 10)
        # A path of no episode (no frame id) recorded next to it: not its path.
        recorder.write_trajectory("/lit/path", [[0.0] * 4, [0.1] * 4], 11)
    result = _replay("verify", path)
    assert result.returncode == 1, result.stdout + result.stderr
    assert "1 paths checked: 0 valid, 1 invalid" in result.stdout, result.stdout
    assert "/lit/episode seq 0: the planner node's own check found the path" in result.stdout
    assert "1 path without an episode" in result.stdout, result.stdout


# --- lit bench: record and replay ----------------------------------------------------------


def test_bench_replay_reproduces_live_summary(tmp_path: Path) -> None:
    out, bags = tmp_path / "live", tmp_path / "bags"
    bench = subprocess.run(
        [sys.executable, "-m", "lit_planner.cli", "bench",
         "--scenarios", "np4", "--planners", "litstar-fixed,rrtconnect", "--runs", "2",
         "--time-scale", "0.1", "--check-jobs", "1", "--out", str(out), "--bag-dir", str(bags)],
        cwd=ROOT, env=ENV, capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    assert bench.returncode == 0, bench.stderr
    recorded = bags / "live"
    assert (recorded / "metadata.yaml").is_file()
    info = replay.bag_info(recorded)
    runs = next(p for p in info["publishers"] if p["topic"] == bag.BENCH_RUN_TOPIC)
    assert (runs["first_seq"], runs["last_seq"], runs["gaps"]) == (0, 3, 0)
    assert info["custom_data"]["lit.run_id"] == "live"

    result = _replay("bench", recorded, "--out", tmp_path / "replayed")
    assert result.returncode == 0, result.stderr
    live = json.loads((out / "summary.json").read_text())
    again = json.loads((tmp_path / "replayed" / "summary.json").read_text())
    # All of it, the finish time and duration too: a finished run records its own clock in the
    # bag's metadata (its messages' stamps leave out the set-up before the first record).
    assert info["custom_data"][bag.BENCH_DURATION_KEY] == repr(live["duration_s"])
    assert again == live
    assert (tmp_path / "replayed" / "plots" / "np4.png").is_file()
    assert (tmp_path / "replayed" / "summary.md").read_text() == (out / "summary.md").read_text()
    # A malformed recorded duration is a warning naming the bag, and the records' own span
    # stands in: it was an error, and salvage and compact copy the value, so no replay of the
    # bag could tabulate its intact records again.
    copy = tmp_path / "bad-timing"
    shutil.copytree(recorded, copy)
    metadata = copy / "metadata.yaml"
    text = metadata.read_text()
    assert text.count(repr(live["duration_s"])) == 1
    metadata.write_text(text.replace(repr(live["duration_s"]), "-1.5"))
    result = _replay("bench", copy, "--out", tmp_path / "bad")
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr
    assert f"warning: {copy}: malformed {bag.BENCH_FINISHED_KEY} / {bag.BENCH_DURATION_KEY}" in (
        result.stderr
    ), result.stderr
    spanned = json.loads((tmp_path / "bad" / "summary.json").read_text())
    assert 0.0 <= spanned["duration_s"] <= live["duration_s"]  # the set-up is left out
    assert spanned["scenarios"] == live["scenarios"]

    # The default folder: <bag>/replay.
    assert _replay("bench", recorded).returncode == 0
    assert (recorded / "replay" / "summary.json").is_file()


def test_sample_bag_info_and_bench_replay(tmp_path: Path) -> None:
    assert sum(f.stat().st_size for f in SAMPLE.iterdir()) < 200_000
    info = replay.bag_info(SAMPLE)
    assert {t["topic"]: t["messages"] for t in info["topics"]} == {
        bag.BENCH_CONFIG_TOPIC: 1,
        bag.BENCH_RUN_TOPIC: 2,
    }
    assert all(p["gaps"] == p["duplicates"] == p["reused"] == 0 for p in info["publishers"])
    assert info["skipped"]["total"] == 0

    result = _replay("bench", SAMPLE, "--out", tmp_path / "out")
    assert result.returncode == 0, result.stderr
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["scenarios"]["np4"]["planners"]["litstar-fixed"] == SAMPLE_STATISTICS


def test_the_readme_table_is_what_replay_regenerates_from_its_bag(tmp_path: Path) -> None:
    """README's "LIT* vs OMPL's AIT*" table says `lit replay bench` of its bag regenerates it;
    it had drifted (a c_final from before c_final became the cost at the budget)."""
    sample = ROOT / "bags" / "samples" / "litstar_vs_aitstar"
    result = _replay("bench", sample, "--out", tmp_path / "out")
    assert result.returncode == 0, result.stderr
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    names = {"LIT* (fixed)": "litstar-fixed", "AIT*": "aitstar"}

    def cell(stat: dict[str, Any], digits: int) -> str:
        ci = stat["ci"]
        return f"{stat['median']:.{digits}f} [{ci['lower']:.{digits}f}, {ci['upper']:.{digits}f}]"

    readme = (ROOT / "README.md").read_text()
    section = readme[readme.index("## LIT* vs OMPL's AIT*") : readme.index("The run's bag is")]
    rows = [line for line in section.splitlines() if re.match(r"\| (np|rrd)\d+ \|", line)]
    assert len(rows) == 4, section
    for row in rows:
        scenario, label, *_ = (part.strip() for part in row.strip("|").split("|"))
        stats = summary["scenarios"][scenario]["planners"][names[label]]
        expected = [
            scenario,
            label,
            f"{round(stats['success_rate'] * 100)}%",
            cell(stats["t_init"], 4),
            cell(stats["c_init"], 3),
            cell(stats["c_final"], 3),
        ]
        assert row == "| " + " | ".join(expected) + " |"


def test_bench_replay_counts_skipped_messages(tmp_path: Path) -> None:
    """A bench bag with a foreign topic, an unknown schema and a newer version: skipped, counted,
    and the statistics stay those of the recorded runs."""
    from rosbags.rosbag2 import Reader

    extended = tmp_path / "extended"
    with Reader(SAMPLE) as reader, BagRecorder(extended, run_id="x") as recorder:
        for connection in reader.connections:
            recorder.add_topic(connection.topic, connection.msgtype)
        recorder.add_topic("/tf", bag.STRING_TYPE)
        for connection, stamp, raw in reader.messages():
            recorder.write_raw(connection.topic, raw, stamp)
        recorder.write_string("/tf", "{}", stamp + 1)
        strange = envelope("lit_msgs_json/Unheard", 9, "lit_bench", "x", {}, stamp_ns=1)
        recorder.write_string(bag.BENCH_RUN_TOPIC, strange, stamp + 2)
        newer = json.loads(envelope(bag.BENCH_RUN_SCHEMA, 2, "lit_bench", "x", {}, stamp_ns=1))
        newer["version"] = 7
        recorder.write_string(bag.BENCH_RUN_TOPIC, json.dumps(newer), stamp + 3)
    result = _replay("bench", extended, "--out", tmp_path / "out")
    assert result.returncode == 0, result.stderr
    assert "3 skipped" in result.stderr and "unsupported version" in result.stderr
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["scenarios"]["np4"]["planners"]["litstar-fixed"] == SAMPLE_STATISTICS
    info = _replay("info", extended)
    assert "3 skipped: " in info.stdout
    verify = _replay("verify", extended)
    assert verify.returncode == 0 and "messages 3 skipped" in verify.stdout

    # Not a bench bag at all.
    plain = _numbered_bag(tmp_path / "plain", 3)
    _assert_clean_error(_replay("bench", plain), "not a lit bench bag")
    # A bench bag with a ROS run's bag: refused (the bench records were left out without a word
    # and the ROS run's queries tabulated).
    mixed = _replay("bench", extended, plain, "--out", tmp_path / "mix")
    _assert_clean_error(mixed, f"while {extended} is a lit bench bag")
    assert not (tmp_path / "mix").exists()
    # A bag with the config topic and no config message is not called a bench bag by its own
    # error.
    with BagRecorder(tmp_path / "config-topic-only", run_id="c") as recorder:
        recorder.add_topic(bag.BENCH_CONFIG_TOPIC, bag.STRING_TYPE)
        recorder.add_topic("/lit/observation", bag.STRING_TYPE)
        recorder.write_string("/lit/observation", _obs(0), 1)
    alone = _replay("bench", tmp_path / "config-topic-only")
    _assert_clean_error(alone, "not a lit bench bag")
    assert "while" not in alone.stderr


def test_killed_bench_bag_is_recoverable(tmp_path: Path) -> None:
    """Bench records are flushed per scenario: a bag never closed still salvages to the records."""
    salvaged = tmp_path / "sample-salvaged"
    copy = tmp_path / SAMPLE.name
    shutil.copytree(SAMPLE, copy)
    (copy / "metadata.yaml").unlink()
    data = _mcap(copy).read_bytes()
    summary_start = int.from_bytes(data[-28:-20], "little")  # the footer's first field
    _mcap(copy).write_bytes(data[: summary_start - 13])  # no DataEnd, summary or footer
    _assert_clean_error(_replay("bench", copy), "lit replay salvage")
    result = _replay("salvage", copy, "-o", salvaged)
    assert result.returncode == 0, result.stderr
    assert _recovered(result.stdout) == 3
    assert "the writer did not finish" in result.stdout
    replayed = _replay("bench", salvaged, "--out", tmp_path / "out")
    assert replayed.returncode == 0, replayed.stderr


def test_bench_replay_of_a_damaged_record_says_the_tables_are_incomplete(tmp_path: Path) -> None:
    """A byte-damaged run record is skipped; replay bench used to exit 0 with a summary.md that
    still read as the whole benchmark."""
    copy = _sample_copy(tmp_path, "damaged")
    mcap_file = next(copy.glob("*.mcap"))
    data = bytearray(mcap_file.read_bytes())
    last = data.rfind(b'{"schema": "lit_msgs_json/BenchRun"')  # the second record's JSON text
    assert last > 0
    data[last] = ord("X")  # no longer JSON; uncompressed chunks carry no checksum here
    mcap_file.write_bytes(bytes(data))
    result = _replay("bench", copy, "--out", tmp_path / "out")
    assert result.returncode == 1, result.stdout + result.stderr
    assert "1 of the 2 planned run records are missing or unreadable" in result.stderr
    assert "Traceback" not in result.stderr
    summary = (tmp_path / "out" / "summary.md").read_text()
    assert summary.startswith("> **Incomplete:** 1 of the 2 planned run records"), summary[:300]
    incomplete = json.loads((tmp_path / "out" / "summary.json").read_text())["incomplete"]
    assert (incomplete["planned"], incomplete["read"]) == (2, 1)
    assert incomplete["note"].startswith("1 of the 2 planned run records")


def _with_records(
    target: Path, records: Sequence[tuple[str, dict[str, Any]]], topics: Sequence[str] = ()
) -> Path:
    """The sample's config message and then ``records`` (schema, payload), as one new bag; on
    their kind's topics, or on ``topics`` (one per record) when given."""
    from rosbags.rosbag2 import Reader

    with Reader(SAMPLE) as reader, BagRecorder(target, run_id="x") as recorder:
        for connection in reader.connections:
            recorder.add_topic(connection.topic, connection.msgtype)
        for topic in set(topics) - {connection.topic for connection in reader.connections}:
            recorder.add_topic(topic, bag.STRING_TYPE)
        for connection, stamp, raw in reader.messages():
            if connection.topic == bag.BENCH_CONFIG_TOPIC:
                recorder.write_raw(connection.topic, raw, stamp)
        for seq, (schema, payload) in enumerate(records):
            topic = (
                topics[seq]
                if topics
                else bag.BENCH_CONFIG_TOPIC
                if schema == bag.BENCH_CONFIG_SCHEMA
                else bag.BENCH_RUN_TOPIC
            )
            text = envelope(schema, seq, "lit_bench", "x", payload, stamp_ns=stamp + 1 + seq)
            recorder.write_string(topic, text, stamp + 1 + seq)
    return target


def _sample_payloads(schema: str) -> list[dict[str, Any]]:
    from rosbags.rosbag2 import Reader

    with Reader(SAMPLE) as reader:
        documents = [
            json.loads(bag.typestore().deserialize_cdr(raw, connection.msgtype).data)
            for connection, _, raw in reader.messages()
        ]
    return [d["payload"] for d in documents if d["schema"] == schema]


def test_bench_replay_counts_only_records_of_its_configuration(tmp_path: Path) -> None:
    """A record of another scenario, planner or run does not stand in for a missing one (a salvage
    of two benchmarks' files used to pass for complete); two benchmarks' configurations in one
    bag and two records of one run are refused."""
    first, second = _sample_payloads(bag.BENCH_RUN_SCHEMA)
    stranger = dict(second, scenario="np8", scenario_key="np8")
    mixed = _with_records(
        tmp_path / "mixed", [(bag.BENCH_RUN_SCHEMA, first), (bag.BENCH_RUN_SCHEMA, stranger)]
    )
    result = _replay("bench", mixed, "--out", tmp_path / "out")
    assert result.returncode == 1, result.stdout + result.stderr
    assert "1 run record outside the benchmark's configuration" in result.stderr, result.stderr
    assert "1 of the 2 planned run records are missing or unreadable" in result.stderr
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["incomplete"]["planned"] == 2 and summary["incomplete"]["read"] == 1
    assert [r["scenario"] for r in summary["runs"]] == ["np4"]
    lines = (tmp_path / "out" / "runs.jsonl").read_text().splitlines()
    assert [json.loads(line)["run"] for line in lines] == [first["run"]]

    # A run record on another topic than its own was tabulated (and its topic's seq showed a
    # gap): left out, as damage.
    astray = _with_records(
        tmp_path / "astray",
        [(bag.BENCH_RUN_SCHEMA, first), (bag.BENCH_RUN_SCHEMA, second)],
        topics=[bag.BENCH_RUN_TOPIC, "/lit/episode"],
    )
    result = _replay("bench", astray, "--out", tmp_path / "astray-out")
    assert result.returncode == 1, result.stdout + result.stderr
    assert replay.WRONG_TOPIC in result.stderr, result.stderr
    lines = (tmp_path / "astray-out" / "runs.jsonl").read_text().splitlines()
    assert [json.loads(line)["run"] for line in lines] == [first["run"]]

    twice = _with_records(
        tmp_path / "twice",
        [(bag.BENCH_RUN_SCHEMA, first), (bag.BENCH_RUN_SCHEMA, dict(first, t_init=1.0))],
    )
    _assert_clean_error(_replay("bench", twice, "--out", tmp_path / "o2"), "two records of")

    (config,) = _sample_payloads(bag.BENCH_CONFIG_SCHEMA)
    other = dict(config, started="2026-12-04T00:00:00+00:00")
    two_configs = _with_records(
        tmp_path / "two", [(bag.BENCH_CONFIG_SCHEMA, other), (bag.BENCH_RUN_SCHEMA, first)]
    )
    _assert_clean_error(
        _replay("bench", two_configs, "--out", tmp_path / "o3"), "two lit bench runs"
    )
    assert not (tmp_path / "o2").exists() and not (tmp_path / "o3").exists()


@pytest.mark.parametrize(
    "lie", ["unlisted topic", "wrong count", "wrong total", "file listed twice"]
)
def test_metadata_that_disagrees_with_the_files_is_refused(lie: str, tmp_path: Path) -> None:
    """rosbags reads the topics metadata.yaml lists: a topic it left out lost its messages
    without a word (info counted 1 message, verify checked 0 paths, compact dropped them); a file
    it lists twice was read twice (info counted every message twice, compact kept both)."""
    copy = _sample_copy(tmp_path, "lying")
    metadata = copy / "metadata.yaml"
    text = metadata.read_text()
    if lie == "file listed twice":
        (name,) = (path.name for path in copy.glob("*.mcap"))
        changed = text.replace(f"- {name}\n", f"- {name}\n  - {name}\n")
        fragment = f"it lists {name} more than once"
    elif lie == "unlisted topic":
        changed = text.replace(f"name: {bag.BENCH_RUN_TOPIC}", "name: /lit/episode")
        fragment = f"2 messages of {bag.BENCH_RUN_TOPIC} in the files, a topic it does not list"
    elif lie == "wrong total":  # every topic's count right, the bag's own wrong
        total = replay.bag_info(copy)["messages"]
        changed = re.sub(
            rf"^  message_count: {total}$", "  message_count: 999", text, flags=re.MULTILINE
        )
        fragment = f"it says 999 messages in all, the files hold {total}"
    else:
        listed = f"- message_count: 2\n    topic_metadata:\n      name: {bag.BENCH_RUN_TOPIC}\n"
        changed = text.replace(listed, listed.replace(": 2", ": 30"))
        fragment = f"it says 30 messages of {bag.BENCH_RUN_TOPIC}, the files hold 2"
    assert changed != text
    metadata.write_text(changed)
    for command in ("info", "verify", "bench"):
        _assert_clean_error(_replay(command, copy), fragment)
    _assert_clean_error(_replay("compact", copy, tmp_path / "compacted"), "lit replay salvage")
    assert not (tmp_path / "compacted").exists()
    salvaged = _replay("salvage", copy, "-o", tmp_path / "salvaged")
    assert salvaged.returncode == 0, salvaged.stderr
    assert _replay("bench", tmp_path / "salvaged", "--out", tmp_path / "out").returncode == 0


def test_a_file_of_another_bag_in_the_folder_is_named_without_the_salvage_advice(
    tmp_path: Path,
) -> None:
    """An .mcap file the folder's metadata.yaml does not list was answered with "rebuild the bag
    from its files with lit replay salvage", which merges a stray file of another bag into it."""
    copy = _sample_copy(tmp_path, "with-stray")
    stray = _numbered_bag(tmp_path / "other", 3)
    shutil.copy(_mcap(stray), copy / "other.mcap")
    _assert_clean_error(
        _replay("info", copy),
        "other.mcap is in the folder, not in the files it lists (a file of another bag? then "
        "move it out rather than salvage",
    )


def test_bench_replay_of_a_bag_without_records_warns_and_writes_nothing(tmp_path: Path) -> None:
    """A bench interrupted before its first scenario finished leaves its configuration and no
    record: that was exit 2 (bad input) with 'nor any EpisodeSummary of a ROS run'."""
    copy = _sample_copy(tmp_path, "no-records")
    mcap_file = next(copy.glob("*.mcap"))
    data = mcap_file.read_bytes().replace(
        b'{"schema": "lit_msgs_json/BenchRun"', b'X"schema": "lit_msgs_json/BenchRun"'
    )
    mcap_file.write_bytes(data)
    result = _replay("bench", copy, "--out", tmp_path / "out")
    assert result.returncode == 1, result.stdout + result.stderr
    assert "the benchmark's configuration is there, none of its records" in result.stderr
    assert "nothing to tabulate" in result.stderr and "Traceback" not in result.stderr
    assert not (tmp_path / "out").exists()


def test_compact_keeps_every_message_and_compresses(mixed_bag: Path, tmp_path: Path) -> None:
    from mcap.reader import make_reader
    from rosbags.rosbag2 import Reader

    out = tmp_path / "compact"
    result = _replay("compact", mixed_bag, out)
    assert result.returncode == 0, result.stderr
    assert "messages" in result.stdout and " MB -> " in result.stdout
    assert "compressed already" not in result.stdout

    def everything(path: Path) -> list[tuple[str, str, int, bytes]]:
        with Reader(path) as reader:
            return [(c.topic, c.msgtype, t, bytes(d)) for c, t, d in reader.messages()]

    assert everything(out) == everything(mixed_bag)
    with Reader(out) as reader, Reader(mixed_bag) as original:
        qos = {c.topic: c.ext.offered_qos_profiles for c in original.connections}
        assert {c.topic: c.ext.offered_qos_profiles for c in reader.connections} == qos
    (mcap_file,) = out.glob("*.mcap")
    with mcap_file.open("rb") as stream:
        chunks = list(make_reader(stream).get_summary().chunk_indexes)
    assert chunks and {c.compression for c in chunks} == {"zstd"}
    info = replay.bag_info(out)
    assert info["custom_data"]["lit.compacted_from"] == mixed_bag.name
    assert info["custom_data"]["lit.chunk_bytes"] == str(bag.MAX_CHUNK_BYTES)  # not the source's
    assert _replay("compact", mixed_bag, out).returncode == 2  # never overwrites
    # Compacting a compacted bag again gains nothing, and says why (it printed only "x MB -> x MB").
    again = _replay("compact", out, tmp_path / "again")
    assert again.returncode == 0, again.stderr
    assert "(the source was compressed already: chunks zstd)" in again.stdout, again.stdout
    assert everything(tmp_path / "again") == everything(mixed_bag)


# --- review fixes: duplicates, damaged files, argument and output checks ---------------------

LITSTAR_SAMPLE = ROOT / "bags" / "samples" / "litstar_vs_aitstar"
EXCEPTION_NAME = re.compile(r"\b[A-Z][A-Za-z]+(Error|Exceeded|Exception)\b")


def _sample_copy(tmp_path: Path, name: str) -> Path:
    copy = tmp_path / name
    shutil.copytree(SAMPLE, copy)
    return copy


def _rerecorded(
    source: Path, target: Path, change: dict[str, Any] | None = None, *, new_run: bool = False
) -> Path:
    """``source``'s messages in a new bag; ``change`` updates the payload of BenchRun seq 0;
    ``new_run``: the config message gets another stamp (another run with the same run id, as two
    `lit bench` runs with the same --out name)."""
    from rosbags.rosbag2 import Reader

    with Reader(source) as reader, BagRecorder(target, run_id="copy") as recorder:
        for connection in reader.connections:
            recorder.add_topic(connection.topic, connection.msgtype)
        for connection, stamp, raw in reader.messages():
            text = bag.typestore().deserialize_cdr(raw, connection.msgtype).data
            document = json.loads(text)
            if change and document["schema"] == bag.BENCH_RUN_SCHEMA and document["seq"] == 0:
                document["payload"].update(change)
            if new_run and document["schema"] == bag.BENCH_CONFIG_SCHEMA:
                document["stamp_ns"] += 1
            recorder.write_string(connection.topic, json.dumps(document), stamp)
    return target


def test_bench_replay_counts_each_bag_and_record_once(tmp_path: Path) -> None:
    """A bag given twice is refused; identical records of two copies count once (warned);
    different records under the same run id and seq are refused."""
    first = _sample_copy(tmp_path, "first")
    _assert_clean_error(_replay("bench", first, first, "--out", tmp_path / "o1"), "given twice")
    _assert_clean_error(
        _replay("bench", first, first / "bench_np4.mcap", "--out", tmp_path / "o1"),
        "the same bag as",
    )
    _assert_clean_error(_replay("bench", first, f"{first}/../first"), "the same bag as")
    _assert_clean_error(_replay("verify", first, first), "given twice")
    assert not (tmp_path / "o1").exists()

    second = _sample_copy(tmp_path, "second")
    result = _replay("bench", first, second, "--out", tmp_path / "o2")
    assert result.returncode == 0, result.stderr
    assert "2 run records" in result.stdout
    assert "2 duplicate run records ignored" in result.stderr
    summary = json.loads((tmp_path / "o2" / "summary.json").read_text())
    assert summary["scenarios"]["np4"]["planners"]["litstar-fixed"] == SAMPLE_STATISTICS
    recorded = replay.read_bench([first, second])
    assert (len(recorded.runs), len(recorded.duplicates), recorded.missing) == (2, 2, 0)

    conflicting = _rerecorded(SAMPLE, tmp_path / "conflicting", {"t_init": 1.0})
    _assert_clean_error(
        _replay("bench", first, conflicting, "--out", tmp_path / "o3"), "differs from the record"
    )
    # Two runs that share a run id (the same --out name) are two runs: both count.
    rerun = _rerecorded(SAMPLE, tmp_path / "rerun", {"t_init": 1.0}, new_run=True)
    both = replay.read_bench([first, rerun])
    assert (len(both.runs), len(both.duplicates), both.missing) == (4, 0, 0)


@pytest.mark.parametrize("command", ["info", "verify", "compact"])
def test_mcap_of_only_its_magic_is_a_clean_error_with_salvage_hint(
    command: str, tmp_path: Path
) -> None:
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(_mcap(SAMPLE).read_bytes()[:8])
    args = (cut, tmp_path / "out") if command == "compact" else (cut,)
    result = _replay(command, *args)
    _assert_clean_error(result, "only the 8-byte MCAP magic")
    assert f"lit replay salvage {cut}" in result.stderr
    assert EXCEPTION_NAME.search(result.stderr) is None, result.stderr


def test_compact_of_damaged_bag_gives_salvage_hint(tmp_path: Path) -> None:
    data = _mcap(SAMPLE).read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) - 100])
    result = _replay("compact", cut, tmp_path / "out")
    _assert_clean_error(result, f"lit replay salvage {cut}")
    assert "does not end with the MCAP magic" in result.stderr
    assert "LIT_REPLAY_DEBUG" not in result.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("command", ["info", "verify", "compact"])
def test_messages_a_damaged_summary_hides_are_an_error(command: str, tmp_path: Path) -> None:
    """One changed byte of a channel's message encoding in the MCAP summary ("cdr" -> "cdv") made
    rosbags leave out that channel's messages without an error: info counted 0, verify checked
    none and compact wrote a bag without them, all with exit 0."""
    path = _numbered_bag(tmp_path / "hidden", 20)
    data = bytearray(_mcap(path).read_bytes())
    at = data.rfind(b"cdr")  # the summary section repeats the channel records at the end
    assert at > len(data) // 2
    data[at + 2] = ord("v")
    _mcap(path).write_bytes(bytes(data))
    out = tmp_path / "out"
    result = _replay(command, path, *([out] if command == "compact" else []))
    _assert_clean_error(result, "0 of the 20 messages of /lit/observation it lists could be read")
    assert f"lit replay salvage {path}" in result.stderr
    assert not out.exists()
    salvaged = _replay("salvage", path, "-o", tmp_path / "salvaged")
    assert salvaged.returncode == 0, salvaged.stderr
    assert _recovered(salvaged.stdout) == 20


def test_salvage_of_a_cut_first_chunk_recovers_its_complete_records(tmp_path: Path) -> None:
    data = (LITSTAR_SAMPLE / "out.mcap").read_bytes()
    for size in (100, 1000):  # inside the first chunk: nothing but schema and channels
        cut = tmp_path / f"cut{size}.mcap"
        cut.write_bytes(data[:size])
        result = _replay("salvage", cut)
        _assert_clean_error(result, "nothing to salvage")
        assert "end of file inside the chunk at byte" in result.stderr
        assert EXCEPTION_NAME.search(result.stderr) is None, result.stderr
    cut = tmp_path / "cut20000.mcap"
    cut.write_bytes(data[:20000])
    result = _replay("salvage", cut)
    assert result.returncode == 0, result.stderr
    assert "end of file inside the chunk at byte" in result.stdout
    assert EXCEPTION_NAME.search(result.stdout) is None, result.stdout
    recovered = _recovered(result.stdout)
    assert 1 < recovered < 81
    runs = next(
        p for p in replay.bag_info(tmp_path / "cut20000-salvaged")["publishers"]
        if p["topic"] == bag.BENCH_RUN_TOPIC
    )  # fmt: skip
    assert (runs["first_seq"], runs["gaps"], runs["count"]) == (0, 0, recovered - 1)

    # zstd chunks (compact): what the compressed bytes present decode to is recovered.
    compacted = tmp_path / "compacted"
    assert _replay("compact", LITSTAR_SAMPLE, compacted).returncode == 0
    zdata = _mcap(compacted).read_bytes()
    zcut = tmp_path / "zcut.mcap"
    zcut.write_bytes(zdata[: len(zdata) * 9 // 10])
    result = _replay("salvage", zcut)
    assert result.returncode == 0, result.stderr
    assert 1 < _recovered(result.stdout) < 81


def test_salvage_reports_a_missing_end_magic(tmp_path: Path) -> None:
    data = _mcap(SAMPLE).read_bytes()
    for missing in (8, 3):
        cut = tmp_path / f"no_magic{missing}.mcap"
        cut.write_bytes(data[:-missing])
        result = _replay("salvage", cut)
        assert result.returncode == 0, result.stderr
        assert "complete file" not in result.stdout
        assert "end magic after the footer is missing" in result.stdout
        assert _recovered(result.stdout) == 3
    result = _replay("salvage", _mcap(SAMPLE), "-o", tmp_path / "whole")
    assert result.returncode == 0 and "complete file" in result.stdout, result.stdout


def test_salvage_of_a_file_shorter_than_the_magic_says_so(tmp_path: Path) -> None:
    """A 5-byte prefix of an MCAP file was "end of file inside the record header at byte 0"."""
    (tmp_path / "five.mcap").write_bytes(_mcap(SAMPLE).read_bytes()[:5])
    (tmp_path / "other.mcap").write_bytes(b"{ ")
    for name, words in (
        (
            "five",
            "ends inside the MCAP magic (5 of its 8 bytes): truncated before its first record",
        ),
        ("other", "does not start with the MCAP magic: not an MCAP file"),
    ):
        result = _replay("salvage", tmp_path / f"{name}.mcap", "-o", tmp_path / f"out-{name}")
        _assert_clean_error(result, words)
        assert not (tmp_path / f"out-{name}").exists()


def test_tensors_and_measure_reject_bad_arguments(tmp_path: Path) -> None:
    (tmp_path / "file").write_text("x")
    _assert_clean_error(_replay("tensors", SAMPLE, "--out", tmp_path / "file"), "not a folder")
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "b_tensor.npy").write_text("old")
    _assert_clean_error(_replay("tensors", SAMPLE, "--out", tmp_path / "full"), "not empty")
    assert (tmp_path / "full" / "b_tensor.npy").read_text() == "old"
    for option, value in (("--seed", "-1"), ("--batch-size", "0"), ("--warmup", "0"),
                          ("--decision-interval", "0")):  # fmt: skip
        out = tmp_path / f"bad{option}"
        _assert_clean_error(_replay("tensors", SAMPLE, "--out", out, option, value), option)
        assert not out.exists()
    # A combination the learner refuses, said before the bags are read (this one is no bag).
    refused = _replay("tensors", tmp_path / "file", "--out", tmp_path / "w", "--warmup", "10")
    _assert_clean_error(refused, "refuses these options: B: warmup 10 must be >= batch_size 64")
    _assert_clean_error(_replay("measure", "--messages", "0"), "--messages")
    _assert_clean_error(_replay("measure", "--kills", "-1"), "--kills")
    _assert_clean_error(_replay("measure", "--chunk-bytes", "0"), "--chunk-bytes")


def test_bench_replay_refuses_a_non_empty_output_folder(tmp_path: Path) -> None:
    stale = tmp_path / "stale"
    (stale / "plots").mkdir(parents=True)
    (stale / "plots" / "old.png").write_bytes(b"png")
    _assert_clean_error(_replay("bench", SAMPLE, "--out", stale), "not empty")
    assert [p.name for p in stale.rglob("*")] == ["plots", "old.png"]
    (tmp_path / "file").write_text("x")
    _assert_clean_error(_replay("bench", SAMPLE, "--out", tmp_path / "file"), "not a folder")
    # A folder that cannot be made is refused before the work, not after it (tensors trained
    # for minutes and then failed on "Not a directory").
    for command in ("bench", "tensors"):
        beneath_a_file = tmp_path / "file" / command
        _assert_clean_error(
            _replay(command, SAMPLE, "--out", beneath_a_file), "file is a file, not a folder"
        )
        assert not beneath_a_file.exists()
    (tmp_path / "empty").mkdir()
    assert _replay("bench", SAMPLE, "--out", tmp_path / "empty").returncode == 0
    # The default folder <bag>/replay: written once, then refused rather than mixed.
    copy = _sample_copy(tmp_path, "copy")
    assert _replay("bench", copy).returncode == 0
    assert (copy / "replay" / "summary.json").is_file()
    _assert_clean_error(_replay("bench", copy), "the default output folder")


def test_replay_outputs_beside_checked_in_bags_are_ignored_by_git() -> None:
    git = shutil.which("git")
    if git is None or not (ROOT / ".git").exists():
        pytest.skip("no git checkout")
    paths = [
        "bags/samples/bench_np4/replay/summary.json",  # lit replay bench <bag>
        "bags/samples/bench_np4/bench_np4-replay/summary.json",  # lit replay bench <bag>.mcap
        "bags/samples/bench_np4-salvaged/metadata.yaml",  # lit replay salvage <bag>
    ]
    for path in paths:
        ignored = subprocess.run([git, "check-ignore", "-q", path], cwd=ROOT, check=False)
        assert ignored.returncode == 0, f"{path} is not ignored"
    tracked = subprocess.run(
        [git, "ls-files", "-ci", "--exclude-standard", "bags"],
        cwd=ROOT, capture_output=True, text=True, check=True,
    )  # fmt: skip
    assert tracked.stdout == ""


def test_verify_of_a_bag_that_lost_run_records_is_incomplete(tmp_path: Path) -> None:
    """A salvage that dropped a damaged chunk (the first runs of a lit bench bag) left a bag
    whose every remaining path was valid, and verify passed it (exit 0) without a word about
    the runs that were gone. Runs missing between a publisher's seqs, and a bench bag's runs
    before its first recorded one, make it incomplete (exit 1); the runs of a ROS recording
    that began late are not counted."""
    world = scenarios.get("np4")
    around = [list(world.start), [-0.15, 0.1, 0.0, 0.0], [0.15, 0.1, 0.0, 0.0], list(world.goal)]
    record = _bench_run(scenario="np4", instance=0, solved=True, planner="x", run=0)
    payload = {**record, "path": around, "path_valid": True}

    def bench_bag(name: str, seqs: Sequence[int]) -> Path:
        with BagRecorder(tmp_path / name, run_id="v") as recorder:
            recorder.add_topic(bag.BENCH_RUN_TOPIC, bag.STRING_TYPE)
            for seq in seqs:
                text = envelope(bag.BENCH_RUN_SCHEMA, seq, "lit_bench", "v", payload, stamp_ns=seq)
                recorder.write_string(bag.BENCH_RUN_TOPIC, text, 10 + seq)
        return tmp_path / name

    whole = _replay("verify", bench_bag("whole", [0, 1, 2, 3]))
    assert whole.returncode == 0, whole.stdout + whole.stderr
    assert "incomplete" not in whole.stdout
    for name, seqs, missing in (("gap", [0, 1, 3], 1), ("head", [3, 4], 3)):
        result = _replay("verify", bench_bag(name, seqs))
        assert result.returncode == 1, result.stdout + result.stderr
        assert f"{len(seqs)} paths checked: {len(seqs)} valid, 0 invalid" in result.stdout
        assert f"and {missing} run records are missing" in result.stdout, result.stdout
    # Both halves of a run given together: nothing is missing.
    together = _replay("verify", bench_bag("first", [0, 1]), bench_bag("second", [2, 3]))
    assert together.returncode == 0, together.stdout + together.stderr


def test_verify_of_a_bag_with_unreadable_lit_messages_is_incomplete(tmp_path: Path) -> None:
    """Valid paths, but one LIT* message that cannot be read and one from another program: the
    unreadable one makes verify exit 1 (not everything was checked); the foreign one does not."""
    world = scenarios.get("np4")
    around = [list(world.start), [-0.15, 0.1, 0.0, 0.0], [0.15, 0.1, 0.0, 0.0], list(world.goal)]
    record = _bench_run(scenario="np4", instance=0, solved=True, planner="x", run=0)
    path = tmp_path / "bench"
    with BagRecorder(path, run_id="v") as recorder:
        recorder.add_topic(bag.BENCH_RUN_TOPIC, bag.STRING_TYPE)
        recorder.add_topic("/other/topic", bag.STRING_TYPE)
        payload = {**record, "path": around, "path_valid": True}
        text = envelope(bag.BENCH_RUN_SCHEMA, 0, "lit_bench", "v", payload, stamp_ns=0)
        recorder.write_string(bag.BENCH_RUN_TOPIC, text, 10)
        recorder.write_string("/other/topic", "hello", 11)
    clean = _replay("verify", path)
    assert clean.returncode == 0, clean.stdout + clean.stderr  # a foreign topic is no damage
    with BagRecorder(tmp_path / "broken", run_id="v") as recorder:
        recorder.add_topic(bag.BENCH_RUN_TOPIC, bag.STRING_TYPE)
        recorder.write_string(bag.BENCH_RUN_TOPIC, text, 10)
        recorder.write_string(bag.BENCH_RUN_TOPIC, "{not json", 11)
    result = _replay("verify", tmp_path / "broken")
    assert result.returncode == 1, result.stdout + result.stderr
    assert "1 paths checked: 1 valid, 0 invalid" in result.stdout
    assert (
        "verify: incomplete: 0 recorded runs could not be checked, 1 LIT* messages are damaged"
        in (result.stdout)
    )
    # A different record under the first one's topic, source, run, seq and stamp is no copy of it
    # (verify filed it as "read twice", harmless, and never checked it): damage.
    with BagRecorder(tmp_path / "conflict", run_id="v") as recorder:
        recorder.add_topic(bag.BENCH_RUN_TOPIC, bag.STRING_TYPE)
        recorder.write_string(bag.BENCH_RUN_TOPIC, text, 10)
        other = envelope(
            bag.BENCH_RUN_SCHEMA, 0, "lit_bench", "v", dict(payload, seed=2), stamp_ns=0
        )
        recorder.write_string(bag.BENCH_RUN_TOPIC, other, 11)
    result = _replay("verify", tmp_path / "conflict")
    assert result.returncode == 1, result.stdout + result.stderr
    assert replay.CONFLICTING in result.stdout + result.stderr, result.stdout
    # A solved run without its path was counted as unsolved (exit 0): it cannot be checked.
    with BagRecorder(tmp_path / "pathless", run_id="v") as recorder:
        recorder.add_topic(bag.BENCH_RUN_TOPIC, bag.STRING_TYPE)
        pathless = dict(payload, path=[])
        text = envelope(bag.BENCH_RUN_SCHEMA, 0, "lit_bench", "v", pathless, stamp_ns=0)
        recorder.write_string(bag.BENCH_RUN_TOPIC, text, 10)
    result = _replay("verify", tmp_path / "pathless")
    assert result.returncode == 1, result.stdout + result.stderr
    assert "0 runs without a path (unsolved); 1 not checkable" in result.stdout, result.stdout


def test_episode_table_groups_the_instances_of_a_random_family() -> None:
    def summary(scenario: str, cost: float | None) -> dict[str, Any]:
        return {
            "mode": "training", "scenario": scenario, "planner": "litstar", "policy": "training",
            "solved": cost is not None, "t_init": 0.01 if cost else None, "c_init": cost,
            "cost": cost, "optimal_cost": None, "fallback_decisions": 1, "path_valid": None,
        }  # fmt: skip

    rows, table = replay.episode_table(
        [summary("rrd4/458", 2.0), summary("rrd4/12", None), summary("np8", 0.5)]
    )
    assert [(r["scenario"], r["instances"], r["queries"], r["solved"]) for r in rows] == [
        ("np8", 1, 1, 1),
        ("rrd4 (2 instances)", 2, 2, 1),
    ]
    assert rows[1]["median_c_final"] is None  # one of two unsolved: the median is infinite
    assert rows[1]["fallback_decisions"] == 2
    assert (
        "| training | rrd4 (2 instances) | litstar | training | - | its limits | 2 | 1 |" in table
    )


def test_episode_table_keeps_budgets_and_stopped_queries_apart() -> None:
    """Plan requests of 0.5 s and 0.2 s, and one cancelled after 1.8 s of a 30 s budget, were one
    row: 3 of 3 solved, a median final cost over runs cut short at different moments."""

    def summary(budget: float | None, cost: float, status: str = "exact_solution") -> dict:
        return {
            "mode": "service", "scenario": "np8", "planner": "litstar", "policy": "tensor",
            "status": status, "time_budget": budget, "solved": True, "t_init": 0.01,
            "c_init": cost, "cost": cost, "optimal_cost": 0.4236, "fallback_decisions": 0,
            "path_valid": True,
        }  # fmt: skip

    rows, table = replay.episode_table([
        summary(0.5, 0.60), summary(0.2, 0.70), summary(0.5, 0.62), summary(30.0, 0.9, "cancelled"),
        summary(None, 0.8), summary(30.0, 0.5, "shutdown"),
    ])  # fmt: skip
    assert [(r["time_budget"], r["ended_by"], r["queries"]) for r in rows] == [
        (0.2, "its limits", 1),
        (0.5, "its limits", 2),
        (30.0, "a cancel", 1),
        (30.0, "the shutdown", 1),
        (None, "its limits", 1),
    ]
    assert rows[1]["median_c_final"] == pytest.approx(0.61)
    assert "| service | np8 | litstar | tensor | 0.5 s | its limits | 2 | 2 |" in table
    assert "| service | np8 | litstar | tensor | 30 s | a cancel | 1 | 1 |" in table
    assert "| service | np8 | litstar | tensor | - | its limits | 1 | 1 |" in table


def test_episode_table_tells_custom_worlds_apart() -> None:
    """Every custom world in R^2 is named custom2; the summaries' worlds tell them apart (they
    were one instance, their medians taken over unrelated problems without a mark)."""

    def summary(boxes: int, cost: float) -> dict[str, Any]:
        world = {
            "lower": [-1, -1],
            "upper": [1, 1],
            "start": [-0.5, 0],
            "goal": [0.5, 0],
            "resolution": 1e-3,
            "boxes": [{"lower": [0, 0], "upper": [0.1, 0.1]}] * boxes,
        }
        return {
            "mode": "service", "scenario": "custom2", "planner": "litstar", "policy": "tensor",
            "solved": True, "t_init": 0.01, "c_init": cost, "cost": cost, "optimal_cost": None,
            "fallback_decisions": 0, "path_valid": True, "world": world,
        }  # fmt: skip

    rows, _ = replay.episode_table([summary(1, 1.0), summary(1, 1.1)])
    assert [(r["scenario"], r["instances"], r["queries"]) for r in rows] == [("custom2", 1, 2)]
    rows, table = replay.episode_table([summary(1, 1.0), summary(2, 1.1), summary(3, 1.2)])
    assert [(r["scenario"], r["instances"], r["queries"]) for r in rows] == [
        ("custom2 (3 instances)", 3, 3)
    ]
    assert "| service | custom2 (3 instances) | litstar | tensor | - | its limits | 3 | 3 |" in (
        table
    )


def test_a_killed_writer_loses_no_more_than_its_open_chunk(tmp_path: Path) -> None:
    """``lit replay measure``'s crash trial: the writer is killed while it writes on; its
    confirmed count is every write it reported (read from its pipe after the kill), so the loss
    is never negative (it was, when the count stopped at the kill point) and at most one chunk."""
    from lit_planner.bag import DEFAULT_CHUNK_BYTES

    from lit_planner import bag_measure

    per_chunk = bag_measure.messages_per_chunk(DEFAULT_CHUNK_BYTES)
    assert per_chunk == 60  # about 1102-byte records in a 64 KiB chunk, as bag.py says
    for trial, target in enumerate((300, 1100)):
        confirmed, recovered = bag_measure.crash_trial(
            tmp_path / f"kill{trial}", target, DEFAULT_CHUNK_BYTES
        )
        assert confirmed >= target
        # -1: a write can return, and close a chunk, just before the kill lands and before the
        # writer reports it (rare).
        assert -1 <= confirmed - recovered <= per_chunk, (confirmed, recovered)


@pytest.mark.parametrize("command", ["info", "bench"])
def test_a_reader_that_left_is_not_an_error(tmp_path: Path, command: str) -> None:
    """`lit replay info BAG | head -1`: the reader gone printed 'lit replay: error:
    BrokenPipeError' with exit 2 (bad input); now exit 141, as a shell reports SIGPIPE. bench
    keeps the outputs it wrote before it printed (they were removed as a failed write's)."""
    read_end, write_end = os.pipe()
    os.close(read_end)  # the first write fails at once
    out = tmp_path / "out"
    try:
        result = subprocess.run(
            [sys.executable, "-m", "lit_planner.cli", "replay", command, str(SAMPLE),
             *(["--out", str(out)] if command == "bench" else [])],
            cwd=ROOT, env=ENV, stdout=write_end, stderr=subprocess.PIPE, text=True,
            timeout=120, check=False,
        )  # fmt: skip
    finally:
        os.close(write_end)
    assert result.returncode == 141, result.stderr
    assert "error" not in result.stderr and "Traceback" not in result.stderr
    if command == "bench":
        assert (out / "summary.json").is_file() and (out / "runs.jsonl").is_file()


@pytest.mark.parametrize("compression", ["lz4", "zstd"])
def test_salvage_reads_the_compressions_rosbag2_writes(compression: str, tmp_path: Path) -> None:
    """An lz4-compressed MCAP file (a rosbag2 storage option) that every other subcommand reads
    was refused by salvage as "damaged" ("chunk compression 'lz4' is not supported"), intact or
    cut off."""
    from mcap.writer import CompressionType, Writer

    string = bag.typestore().types[bag.STRING_TYPE]
    folder = tmp_path / "foreign"
    folder.mkdir()
    with (folder / "foreign.mcap").open("wb") as handle:
        writer = Writer(handle, chunk_size=4096, compression=CompressionType[compression.upper()])
        writer.start(profile="ros2", library="test")
        schema = writer.register_schema(
            name=bag.STRING_TYPE, encoding="ros2msg", data=b"string data"
        )
        channel = writer.register_channel(
            topic="/lit/observation", message_encoding="cdr", schema_id=schema
        )
        for stamp in range(1, 201):
            data = bag.typestore().serialize_cdr(string(data=_obs(stamp)), bag.STRING_TYPE)
            writer.add_message(channel, log_time=stamp, data=bytes(data), publish_time=stamp)
        writer.finish()
    result = _replay("salvage", folder, "-o", tmp_path / "whole")
    assert result.returncode == 0, result.stderr
    assert _recovered(result.stdout) == 200
    data = (folder / "foreign.mcap").read_bytes()
    (folder / "foreign.mcap").write_bytes(data[: len(data) // 2])  # a writer killed midway
    result = _replay("salvage", folder, "-o", tmp_path / "half")
    assert result.returncode == 0, result.stderr
    assert 50 < _recovered(result.stdout) < 200, result.stdout


def test_salvage_keeps_each_files_channels_apart(tmp_path: Path) -> None:
    """MCAP channel ids are unique within one file only: a folder whose two files numbered the
    same two topics the other way round got its messages filed under each other's topic."""
    from mcap.writer import Writer

    string = bag.typestore().types[bag.STRING_TYPE]
    folder = tmp_path / "two"
    folder.mkdir()
    for name, topics in (
        ("a", ["/lit/first", "/lit/second"]),
        ("b", ["/lit/second", "/lit/first"]),
    ):
        with (folder / f"{name}.mcap").open("wb") as handle:
            writer = Writer(handle)
            writer.start(profile="ros2", library="test")
            schema = writer.register_schema(
                name=bag.STRING_TYPE, encoding="ros2msg", data=b"string data"
            )
            ids = {
                topic: writer.register_channel(
                    topic=topic, message_encoding="cdr", schema_id=schema
                )
                for topic in topics
            }
            for stamp, topic in enumerate(topics, start=1):
                data = bag.typestore().serialize_cdr(string(data=topic), bag.STRING_TYPE)
                writer.add_message(ids[topic], log_time=stamp, data=bytes(data), publish_time=stamp)
            writer.finish()
    result = _replay("salvage", folder)
    assert result.returncode == 0, result.stderr
    salvaged = tmp_path / "two-salvaged"
    with replay.BagReader(salvaged) as reader:
        seen = []
        for message in reader.messages():
            seen.append(message.topic)
            text = bag.typestore().deserialize_cdr(message.data, bag.STRING_TYPE).data
            assert text == message.topic, (message.topic, text)
    assert sorted(seen) == ["/lit/first", "/lit/first", "/lit/second", "/lit/second"]


def test_the_demo_names_the_publishers_with_missing_messages(
    mixed_bag: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from lit_planner import demo

    demo._print_bag(mixed_bag)
    out = capsys.readouterr().out
    assert "messages missing" in out and "0 messages missing" not in out, out
    line = r"^    /lit/observation from \S+: 0 before seq 0, 1 in 1 gaps$"
    assert re.search(line, out, re.MULTILINE), out


def test_salvage_and_compact_of_the_current_folder_name_it(tmp_path: Path) -> None:
    """`lit replay salvage .` inside a bag folder failed with "PosixPath('.') has an empty name";
    `compact . OUT` recorded an empty lit.compacted_from."""
    path = _numbered_bag(tmp_path / "here", 3)

    def replay_in(folder: Path, *args: str | Path) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, "-m", "lit_planner.cli", "replay", *map(str, args)],
            cwd=folder, env=ENV, capture_output=True, text=True, timeout=120, check=False,
        )  # fmt: skip

    salvaged = replay_in(path, "salvage", ".")
    assert salvaged.returncode == 0, salvaged.stderr
    assert (tmp_path / f"here{replay.SALVAGED_SUFFIX}" / "metadata.yaml").is_file()
    compacted = replay_in(path, "compact", ".", tmp_path / "small")
    assert compacted.returncode == 0, compacted.stderr
    assert replay.bag_info(tmp_path / "small")["custom_data"]["lit.compacted_from"] == "here"


def test_another_programs_topic_under_lit_is_foreign(tmp_path: Path) -> None:
    """Messages of another program on /lit/foo counted as damaged LIT* messages: verify failed."""
    path = tmp_path / "neighbour"
    with BagRecorder(path, run_id="n") as recorder:
        recorder.add_topic("/lit/observation", bag.STRING_TYPE)
        recorder.add_topic("/lit/foo", bag.STRING_TYPE)
        recorder.add_topic("/robot1/lit/foo/episode", bag.STRING_TYPE)
        recorder.write_string("/lit/observation", _obs(0), 1)
        for stamp in range(2, 5):
            recorder.write_string("/lit/foo", "garbage", stamp)
            recorder.write_string("/robot1/lit/foo/episode", "garbage", stamp)
    result = _replay("verify", path)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "damaged" not in result.stdout, result.stdout
    info = replay.bag_info(path)
    assert info["skipped"]["reasons"] == {"foreign topic": 6}, info["skipped"]


def test_summaries_whose_payload_fails_its_schema_are_damage_not_unsolved_runs(
    tmp_path: Path,
) -> None:
    """EpisodeSummary payloads without ``scenario`` and ``solved``: verify called them runs
    without a path and exited 0, and bench's episode table stopped with "KeyError: 'scenario'".
    Now they are counted as damaged messages (verify exits 1, incomplete) and left out of the
    table with a warning that names them."""
    path = tmp_path / "bad-summaries"
    with BagRecorder(path, run_id="b") as recorder:
        recorder.add_topic("/lit/episode", bag.STRING_TYPE)
        good = _summary(episode_id="b/0", solved=False, status="timeout", path_states=0)
        text = envelope(replay.EPISODE_SCHEMA, 0, "planner", "b", good, stamp_ns=1)
        recorder.write_string("/lit/episode", text, 10)
        for seq in (1, 2, 3):
            bad = {k: v for k, v in _summary(episode_id=f"b/{seq}").items()
                   if k not in ("scenario", "solved")}  # fmt: skip
            text = envelope(replay.EPISODE_SCHEMA, seq, "planner", "b", bad, stamp_ns=1 + seq)
            recorder.write_string("/lit/episode", text, 10 + seq)
    verified = _replay("verify", path)
    assert verified.returncode == 1, verified.stdout + verified.stderr
    assert "1 runs without a path (unsolved)" in verified.stdout, verified.stdout
    assert "3 skipped: 3 payload fails its schema" in verified.stdout, verified.stdout
    assert "/lit/episode seq 1: payload fails its schema (" in verified.stdout
    assert "3 LIT* messages are damaged" in verified.stdout
    table = _replay("bench", path, "--out", tmp_path / "table")
    assert table.returncode == 0, table.stdout + table.stderr
    assert "warning: 3 skipped: 3 payload fails its schema" in table.stderr
    assert "Traceback" not in table.stderr and "KeyError" not in table.stderr
    rows = json.loads((tmp_path / "table" / "episodes.json").read_text(encoding="utf-8"))
    assert sum(row["queries"] for row in rows) == 1, rows


def test_a_message_nested_deeper_than_the_stack_is_one_skipped_message(tmp_path: Path) -> None:
    """JSON nested 100 000 deep raised RecursionError, and info, verify and bench failed for the
    whole bag (exit 2); it is one message that is not JSON."""
    path = tmp_path / "deep"
    with BagRecorder(path, run_id="deep") as recorder:
        recorder.add_topic("/lit/observation", bag.STRING_TYPE)
        recorder.write_string("/lit/observation", _obs(0), 10**9)
        recorder.write_string("/lit/observation", "[" * 100_000, 10**9 + 1)
        recorder.write_string("/lit/observation", _obs(1), 10**9 + 2)
    result = _replay("info", path)
    assert result.returncode == 0, result.stderr
    assert "not JSON" in result.stdout + result.stderr, result.stdout
    assert "RecursionError" not in result.stdout + result.stderr


def test_a_run_record_whose_improvements_are_out_of_time_order_is_one_damaged_record(
    tmp_path: Path,
) -> None:
    """A BenchRun whose improvements were not in time order passed its schema (which only
    describes the order) and stopped `lit replay bench` with "ValueError: improvements must be in
    time order", naming no record; `lit arena` sorted the same record quietly. The codec now
    checks the order: the record is damage, counted and named, and the rest is replayed."""
    sample = replay.read_bench([ROOT / "bags" / "samples" / "bench_np4"])
    runs = [dict(run.payload) for run in sample.runs]
    victim = next(i for i, run in enumerate(runs) if len(run["improvements"]) >= 2)
    swapped = list(runs[victim]["improvements"])
    swapped[0], swapped[1] = swapped[1], swapped[0]
    runs[victim]["improvements"] = swapped
    path = tmp_path / "out-of-order"
    recording = bag.BenchRecording(path, sample.config.run_id, sample.config.payload)
    recording.add_runs(runs)
    recording.finish(datetime.now(UTC), 1.0)
    recording.close()
    table = _replay("bench", path, "--out", tmp_path / "table")
    assert "Traceback" not in table.stderr and "ValueError" not in table.stderr, table.stderr
    assert table.returncode == 1, table.stdout + table.stderr  # incomplete: one record left out
    assert "1 skipped: 1 payload fails its schema" in table.stderr, table.stderr
    verified = _replay("verify", path)  # names it
    assert verified.returncode == 1, verified.stdout + verified.stderr
    assert f"{bag.BENCH_RUN_TOPIC} seq {victim}: payload fails its schema" in verified.stdout
    assert "improvements must be in time order" in verified.stdout, verified.stdout
    kept = [json.loads(line) for line in (tmp_path / "table" / "runs.jsonl").open()]
    assert len(kept) == len(runs) - 1
    # The envelope decoder's one-pass check (codec.valid_envelope) holds it to the same rule.
    from lit_msgs_json import codec

    for index, run in enumerate(runs):
        text = envelope(bag.BENCH_RUN_SCHEMA, index, "lit_bench", "r", run, stamp_ns=1)
        assert codec.valid_envelope("BenchRun", json.loads(text)) == (index != victim)
    # The same record in a runs.jsonl: lit arena refuses it with its line, as other damage.
    lines = [json.dumps({"schema": bag.BENCH_RUN_SCHEMA, **run}) for run in runs]
    (tmp_path / "runs" / "runs.jsonl").parent.mkdir()
    (tmp_path / "runs" / "runs.jsonl").write_text("\n".join(lines) + "\n", encoding="utf-8")
    with pytest.raises(arena.ArenaError, match=f"runs.jsonl:{victim + 1}: not a valid run"):
        arena.read_runs(tmp_path / "runs" / "runs.jsonl")


def test_salvage_of_a_folder_leaves_out_an_empty_file_and_a_copys_messages(tmp_path: Path) -> None:
    """An empty .mcap beside the bag's file (lit replay info sends such a folder to salvage to
    be rebuilt) made salvage refuse the whole folder; a copy of the file beside it wrote every
    message twice."""
    path = _numbered_bag(tmp_path / "folder", 40)
    (path / "empty.mcap").touch()
    result = _replay("salvage", path, "-o", tmp_path / "without-empty")
    assert result.returncode == 0, result.stdout + result.stderr
    assert f"{path / 'empty.mcap'}: left out: an empty file" in result.stdout
    assert _recovered(result.stdout) == 40
    (path / "empty.mcap").unlink()
    shutil.copy(_mcap(path), path / "zz-copy.mcap")
    result = _replay("salvage", path, "-o", tmp_path / "without-copy")
    assert result.returncode == 0, result.stdout + result.stderr
    assert f"40 messages left out: {_mcap(path)} holds the same (a copy of it?)" in result.stdout
    assert _recovered(result.stdout) == 40
    info = replay.bag_info(tmp_path / "without-copy")
    assert info["publishers"][0]["count"] == 40 and info["publishers"][0]["duplicates"] == 0
    # Only empty files: nothing to read, said per file.
    lone = tmp_path / "lone"
    lone.mkdir()
    (lone / "a.mcap").touch()
    result = _replay("salvage", lone)
    assert result.returncode == 2 and f"{lone / 'a.mcap'} is an empty file" in result.stderr


def test_an_episode_summary_of_another_version_is_said_and_a_malformed_version_is_damage(
    tmp_path: Path,
) -> None:
    """`lit replay bench` of a ROS run left out an EpisodeSummary of a newer version without a
    word, and counted a version of "1" (text) or 0, which no LIT* writes, as that benign newer
    version: verify passed such a bag."""
    path = tmp_path / "versions"
    with BagRecorder(path, run_id="v") as recorder:
        recorder.add_topic("/lit/episode", bag.STRING_TYPE)
        for seq, version in enumerate((None, 99, "1", 0)):
            summary = _summary(episode_id=f"v/{seq}", solved=False, status="timeout", path_states=0)
            document = json.loads(
                envelope(replay.EPISODE_SCHEMA, seq, "planner", "v", summary, stamp_ns=1 + seq)
            )
            if version is not None:
                document["version"] = version
            recorder.write_string("/lit/episode", json.dumps(document), 10 + seq)
    table = _replay("bench", path, "--out", tmp_path / "table")
    assert table.returncode == 0, table.stdout + table.stderr
    assert "1 message of a version this LIT* does not read" in table.stderr, table.stderr
    assert "warning: 3 skipped: 2 not an envelope, 1 unsupported version" in table.stderr
    assert "version '1' is not an integer >= 1" in table.stderr
    rows = json.loads((tmp_path / "table" / "episodes.json").read_text(encoding="utf-8"))
    assert sum(row["queries"] for row in rows) == 1, rows
    verified = _replay("verify", path)
    assert verified.returncode == 1, verified.stdout + verified.stderr
    assert "2 LIT* messages are damaged" in verified.stdout, verified.stdout


def test_a_bench_bag_whose_config_message_is_damaged_is_said_to_be_one(tmp_path: Path) -> None:
    """A lit bench bag whose /lit/bench/config message was not JSON (or of a newer version) was
    "not a lit bench bag; nor any EpisodeSummary of a ROS run"."""
    from rosbags.rosbag2 import Reader

    for name, text in (("damaged", "{"), ("newer", None)):
        path = tmp_path / name
        with Reader(SAMPLE) as reader, BagRecorder(path, run_id="x") as recorder:
            for connection in reader.connections:
                recorder.add_topic(connection.topic, connection.msgtype)
            for connection, stamp, raw in reader.messages():
                if connection.topic != bag.BENCH_CONFIG_TOPIC:
                    recorder.write_raw(connection.topic, raw, stamp)
                    continue
                document = json.loads(bag.typestore().deserialize_cdr(raw, bag.STRING_TYPE).data)
                document["version"] = 99
                recorder.write_string(connection.topic, text or json.dumps(document), stamp)
        result = _replay("bench", path, "--out", tmp_path / f"{name}-out")
        assert result.returncode == 2, result.stdout + result.stderr
        reason = "not JSON" if text else "unsupported version"
        assert (
            f"its {bag.BENCH_CONFIG_TOPIC} message is unusable ({bag.BENCH_CONFIG_TOPIC}"
            in result.stderr
        ), result.stderr
        assert reason in result.stderr and "damaged or of a newer LIT*" in result.stderr
        assert "EpisodeSummary" not in result.stderr


def _bag_with_other_programs_topics(path: Path, json_topic: bool) -> list[bytes]:
    """A bag as a robot's own recorder writes it: a LIT* topic, a topic of a message type ROS 2
    Jazzy does not have (its definition, with a nested type, in the file), and with
    ``json_topic`` one serialized as JSON. Returns the custom type's serialized messages."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    definition = "Reading[] readings\nstring frame\n" + "=" * 80 + "\n"
    definition += "MSG: acme_msgs/Reading\nfloat64 value\nint32 sensor\n"
    store.register(get_types_from_msg(definition, "acme_msgs/msg/Readings"))
    readings, reading = store.types["acme_msgs/msg/Readings"], store.types["acme_msgs/msg/Reading"]
    text = store.types[bag.STRING_TYPE]
    custom = [
        store.serialize_cdr(
            readings(readings=[reading(value=0.5 * i, sensor=i)], frame=f"f{i}"),
            "acme_msgs/msg/Readings",
        )
        for i in range(4)
    ]
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        writer.set_custom_data(bag.RUN_ID_KEY, "r1")
        observations = writer.add_connection("/lit/observation", bag.STRING_TYPE, typestore=store)
        acme = writer.add_connection("/acme/readings", "acme_msgs/msg/Readings", typestore=store)
        for seq in range(3):
            writer.write(
                observations, 10 + seq, store.serialize_cdr(text(data=_obs(seq)), bag.STRING_TYPE)
            )
        for stamp, data in enumerate(custom):
            writer.write(acme, 20 + stamp, data)
        if json_topic:
            other = writer.add_connection(
                "/acme/json", bag.STRING_TYPE, typestore=store, serialization_format="json"
            )
            writer.write(other, 30, b'{"data": "hello"}')
    return custom


def test_another_programs_message_types_are_kept_and_what_cannot_be_is_named(
    tmp_path: Path,
) -> None:
    """A topic of a type ROS 2 Jazzy lacks (the file carries its definition): salvage dropped
    its messages, saying only "N unusable messages dropped", and compact failed with "TypesysError:
    Type ... is unknown". A topic serialized as JSON: info, verify and bench called the bag damaged
    and sent the user to salvage."""
    from mcap.reader import make_reader

    def acme(path: Path) -> list[bytes]:
        (file,) = path.glob("*.mcap")
        with file.open("rb") as stream:
            return [m.data for _, _, m in make_reader(stream).iter_messages(["/acme/readings"])]

    source = tmp_path / "robot"
    custom = _bag_with_other_programs_topics(source, json_topic=False)
    salvaged = _replay("salvage", source, "-o", tmp_path / "salvaged")
    assert salvaged.returncode == 0, salvaged.stdout + salvaged.stderr
    assert "dropped" not in salvaged.stdout, salvaged.stdout
    assert "/acme/readings: 4 messages recovered" in salvaged.stdout, salvaged.stdout
    assert acme(tmp_path / "salvaged") == custom
    compacted = _replay("compact", source, tmp_path / "compacted")
    assert compacted.returncode == 0, compacted.stdout + compacted.stderr
    assert acme(tmp_path / "compacted") == custom
    for copy in ("salvaged", "compacted"):  # readable, its definition kept
        info = replay.bag_info(tmp_path / copy)
        assert {t["topic"]: t["type"] for t in info["topics"]}["/acme/readings"] == (
            "acme_msgs/msg/Readings"
        )

    source = tmp_path / "robot-json"
    _bag_with_other_programs_topics(source, json_topic=True)
    for command in ("info", "verify"):
        _assert_clean_error(
            _replay(command, source), "topics not serialized as CDR: /acme/json (json)"
        )
    assert "damaged" not in _replay("info", source).stderr
    salvaged = _replay("salvage", source, "-o", tmp_path / "salvaged-json")
    assert salvaged.returncode == 0, salvaged.stdout + salvaged.stderr
    assert (
        "1 messages dropped: /acme/json: serialized as 'json', not CDR, which lit replay does "
        "not read (the source keeps them)"
    ) in salvaged.stdout, salvaged.stdout
    assert acme(tmp_path / "salvaged-json") == custom
    info = replay.bag_info(tmp_path / "salvaged-json")
    assert "/acme/json: serialized as 'json'" in info["custom_data"]["lit.salvage"]


def test_a_type_without_its_definition_or_with_two_is_not_copied_under_a_wrong_one(
    tmp_path: Path,
) -> None:
    """compact wrote a type whose definition the bag does not carry as a type without fields,
    and salvage wrote the messages of two files with two definitions of one type under the
    first file's."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    def record(path: Path, definition: str, emptied: bool = False) -> None:
        store = get_typestore(Stores.ROS2_JAZZY)
        store.register(get_types_from_msg(definition, "acme_msgs/msg/Level"))
        level = store.types["acme_msgs/msg/Level"]
        with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
            writer.set_custom_data(bag.RUN_ID_KEY, "r1")
            kept = {"msgdef": "", "rihs01": store.hash_rihs01("acme_msgs/msg/Level")}
            acme = writer.add_connection(
                "/acme/level", "acme_msgs/msg/Level", **(kept if emptied else {"typestore": store})
            )
            for stamp in range(3):
                value = stamp + 0.5 if "float64" in definition else stamp
                writer.write(
                    acme, 10 + stamp, store.serialize_cdr(level(value=value), level.__msgtype__)
                )

    record(tmp_path / "bare", "float64 value\n", emptied=True)
    _assert_clean_error(
        _replay("compact", tmp_path / "bare", tmp_path / "bare-compacted"),
        "topic /acme/level: acme_msgs/msg/Level is not a ROS 2 Jazzy type and the file carries "
        "no definition of it",
    )
    _assert_clean_error(  # its only topic: nothing is left, and the error says why
        _replay("salvage", tmp_path / "bare", "-o", tmp_path / "bare-salvaged"),
        "3 messages dropped (/acme/level: acme_msgs/msg/Level is not a ROS 2 Jazzy type and the "
        "file carries no definition of it)",
    )

    record(tmp_path / "two", "float64 value\n")
    record(tmp_path / "other", "int32 value\n")
    (other,) = (tmp_path / "other").glob("*.mcap")
    shutil.copy2(other, tmp_path / "two" / "zz-other.mcap")  # read after the folder's own file
    salvaged = _replay("salvage", tmp_path / "two", "-o", tmp_path / "two-salvaged")
    assert salvaged.returncode == 0, salvaged.stdout + salvaged.stderr
    assert (
        "3 messages dropped: /acme/level: its definition of acme_msgs/msg/Level differs from the "
        "one its earlier messages came with"
    ) in salvaged.stdout, salvaged.stdout
    assert "/acme/level: 3 messages recovered" in salvaged.stdout, salvaged.stdout

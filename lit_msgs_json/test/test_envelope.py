"""Tests of the message schemas and the versioned envelope (Publisher, decode, MessageError)."""

from __future__ import annotations

import copy
import json
import pickle
import random
import threading
from collections.abc import Callable
from typing import Any

import pytest
from jsonschema import Draft202012Validator

import lit_msgs_json
from lit_msgs_json import (
    MAX_MESSAGE_BYTES,
    MESSAGE_VERSIONS,
    OLDER_VERSIONS,
    Message,
    MessageError,
    Publisher,
    accepted_versions,
    decode,
    load_schema,
    schema_names,
    validate,
)
from lit_msgs_json import envelope as envelope_module

FILE_FORMATS = {"TensorSidecar", "BenchRun", "BenchSummary"}
EPISODE = "np8-0-seed42"

# One realistic, valid payload per message schema, written by hand from the brief.
EXAMPLES: dict[str, dict[str, Any]] = {
    "DecideRequest": {
        "agent": "B",
        "episode_id": EPISODE,
        "rho_global": 0.42,
        "rho_local": 0.17,
        "measure": 0.93,
        "planning_time": 0.153,
        "time_budget": 1.0,
        "cost": None,
        "minimum_cost": 1.4142135623730951,
        "improvements": 0,
        "path_states": 0,
        "explore": True,
        "dimension": 8,
    },
    "DecideResponse": {
        "agent": "psi_K",
        "episode_id": EPISODE,
        "value": 6.25,
        "policy_version": 1200,
        "explore": False,
    },
    "EpisodeEnd": {
        "episode_id": EPISODE,
        "planning_time": 1.0004,
        "time_budget": 1.0,
        "cost": 2.031,
        "minimum_cost": 1.4142135623730951,
        "improvements": 4,
        "path_states": 12,
        "truncated": True,
        "fallback_decisions": 1,
        "final_features": {"B": [0.5, 0.2, 0.9], "psi_K": [0.5, 0.31, 0.9]},
    },
    "EpisodeEndResponse": {
        "episode_id": EPISODE,
        "transitions_stored": 37,
        "pending_updates": 3,
        "policy_version": 1201,
        "episodes": 58,
    },
    "PlanRequest": {
        "scenario": "rrd8/3",
        "time": 2.5,
        "planner": "litstar",
        "policy": "tensor",
        "seed": 4294967295,
        "max_iterations": 0,
        "max_batches": 500,
        "request_id": "req-0001",
    },
    "PlanResponse": {
        "request_id": "req-0001",
        "status": "exact",
        "solved": True,
        "message": "",
        "scenario": "rrd8/3",
        "dimension": 2,
        "planner": "litstar",
        "policy": "tensor",
        "seed": 7,
        "cost": 1.52,
        "t_init": 0.012,
        "c_init": 1.9,
        "time": 2.5,
        "checks_init": 40213,
        "iteration_init": 731,
        "improvements": [[0.012, 1.9], [0.4, 1.61], [1.7, 1.52]],
        "path": [[0.1, 0.1], [0.5, 0.62], [0.9, 0.9]],
        "counters": {"iterations": 12034, "batches": 41, "collision_checks": 880213},
        "path_valid": True,
    },
    "CancelRequest": {"request_id": "req-0001"},
    "CancelResponse": {
        "request_id": "req-0001",
        "running": 1,
        "queued": 0,
        "message": "cancelled the running query req-0001",
    },
    "Observation": {
        "episode_id": EPISODE,
        "kind": "psi_K",
        "rho_global": 0.3,
        "rho_local_b": 0.11,
        "rho_local_k": 0.27,
        "measure": 1.0,
        "planning_time": 0.5,
        "iteration": 4410,
        "batches": 12,
        "valid_samples": 1100,
        "invalid_samples": 290,
        "has_solution": True,
        "cost": 1.73,
    },
    "Decision": {
        "episode_id": EPISODE,
        "kind": "psi_K",
        "value": 5.5,
        "neighbours": 23,
        "policy": "training",
        "source": "learner",
        "planning_time": 0.5,
        "latency_ms": 1.8,
    },
    "SolutionUpdate": {
        "episode_id": EPISODE,
        "planning_time": 0.012,
        "cost": 1.9,
        "path_states": 7,
        "improvement": 1,
        "iteration": 310,
    },
    "EpisodeSummary": {
        "episode_id": EPISODE,
        "mode": "training",
        "scenario": "np8",
        "instance": 0,
        "dimension": 8,
        "planner": "litstar",
        "policy": "training",
        "seed": 42,
        "status": "exact",
        "solved": True,
        "cost": 2.031,
        "t_init": 0.2,
        "c_init": 2.9,
        "optimal_cost": None,
        "time": 1.0004,
        "time_budget": 1.0,
        "improvements": 4,
        "decisions": {"B": 41, "psi_K": 41},
        "fallback_decisions": 1,
        "learner_calls": 82,
        "path_states": 12,
        "path_valid": None,
        "counters": {"iterations": 20000},
    },
    "LearnerStats": {
        "episodes": 58,
        "policy_version": 1201,
        "transitions": {"B": 2050, "psi_K": 2049},
        "pending_updates": 0,
        "decisions": 4099,
        "planners": ["planner/host/4711", "planner/host/4712"],
        "metrics": {"critic_loss": 0.0123, "actor_loss": -1.5, "mean_q": -3.25},
        "checkpoint": "/work/main/runs/train-1/checkpoint.pt",
        "uptime": 3600.5,
    },
    "Error": {
        "code": "payload",
        "message": "DecideRequest seq 3 rejected (payload) at $.payload.rho_global: 1.5 is "
        "greater than the maximum of 1 (rule: maximum)",
        "field": "$.payload.rho_global",
        "rule": "maximum",
        "request_schema": "DecideRequest",
        "request_seq": 3,
    },
}

# Other valid shapes: optional fields left out, nulls, the world variant of PlanRequest.
VARIANTS: list[tuple[str, dict[str, Any]]] = [
    (
        "DecideRequest",
        {
            key: value
            for key, value in EXAMPLES["DecideRequest"].items()
            if key not in ("explore", "dimension")
        },
    ),
    ("DecideRequest", {**EXAMPLES["DecideRequest"], "agent": "psi_K", "cost": 3.0}),
    ("EpisodeEnd", {k: v for k, v in EXAMPLES["EpisodeEnd"].items() if k != "final_features"}),
    ("EpisodeEnd", {**EXAMPLES["EpisodeEnd"], "cost": None, "final_features": {"B": [0, 0, 1]}}),
    ("PlanRequest", {"scenario": "np8"}),
    ("PlanRequest", {"scenario": "np8", "start": [0.1] * 8, "goal": [0.9] * 8}),
    (
        "PlanRequest",
        {
            "world": {
                "lower": [0, 0],
                "upper": [1, 1],
                "boxes": [{"lower": [0.4, 0.0], "upper": [0.6, 0.8]}],
                "resolution": 0.1,
            },
            "start": [0.1, 0.1],
            "goal": [0.9, 0.9],
            "planner": "rrtconnect",
        },
    ),
    (
        "PlanResponse",
        {
            **EXAMPLES["PlanResponse"],
            "request_id": None,
            "status": "timeout",
            "solved": False,
            "scenario": "custom2",
            "policy": None,
            "cost": None,
            "t_init": None,
            "c_init": None,
            "improvements": [],
            "path": [],
            "counters": {},
            "path_valid": None,
        },
    ),
    ("Decision", {k: v for k, v in EXAMPLES["Decision"].items() if k != "latency_ms"}),
    ("LearnerStats", {**EXAMPLES["LearnerStats"], "checkpoint": None, "planners": []}),
    (
        "Error",
        {
            "code": "busy",
            "message": "learner busy",
            "field": None,
            "rule": None,
            "request_schema": None,
            "request_seq": None,
        },
    ),
]


def envelope_text(payload: object, name: str = "DecideRequest", /, **fields: object) -> str:
    """A hand-made envelope around ``payload`` (fields override or, as ``...``, delete)."""
    doc: dict[str, object] = {
        "schema": f"lit_msgs_json/{name}",
        "version": MESSAGE_VERSIONS.get(name, 1),
        "seq": 3,
        "stamp_ns": 1_715_240_100_000_000_000,
        "source": "planner/host/4711",
        "run_id": "run-1",
        "payload": payload,
    }
    for key, value in fields.items():
        if value is ...:
            del doc[key]
        else:
            doc[key] = value
    return json.dumps(doc)


def typed(obj: object) -> str:
    """``obj`` as JSON text: equal for documents equal in value *and* number type (1 != 1.0)."""
    return json.dumps(obj, allow_nan=False)


def with_(name: str, **changes: object) -> dict[str, Any]:
    """A copy of ``EXAMPLES[name]`` with ``changes`` applied."""
    return {**copy.deepcopy(EXAMPLES[name]), **changes}


# ---------------------------------------------------------------------------------------------
# The schemas


def test_message_versions_name_every_message_schema() -> None:
    assert set(MESSAGE_VERSIONS) == set(schema_names()) - FILE_FORMATS - {"Envelope"}
    assert set(EXAMPLES) == set(MESSAGE_VERSIONS)
    # version 2 of the two the planner's fallback marks went into (optional fields)
    assert {name: v for name, v in MESSAGE_VERSIONS.items() if v != 1} == {
        "DecideRequest": 3,  # and probe
        "EpisodeEnd": 2,
        "EpisodeSummary": 3,  # the world of a custom scenario; a training query's final features
        "PlanResponse": 2,  # the effort to the first solution
    }
    assert set(OLDER_VERSIONS) <= set(MESSAGE_VERSIONS)
    for name, older in OLDER_VERSIONS.items():
        properties = load_schema(name)["properties"]
        assert all(version < MESSAGE_VERSIONS[name] for version in older)
        assert all(field in properties for fields in older.values() for field in fields)
    assert lit_msgs_json.MAX_MESSAGE_BYTES == MAX_MESSAGE_BYTES == 1_048_576


@pytest.mark.parametrize("name", sorted(set(MESSAGE_VERSIONS) | {"Envelope"}))
def test_message_schemas_are_well_formed_and_described(name: str) -> None:
    schema = load_schema(name)
    Draft202012Validator.check_schema(schema)
    assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    assert schema["$id"] == f"https://lit-planner.invalid/lit_msgs_json/{name}.schema.json"
    assert schema["title"] == name
    assert schema["description"]
    assert schema["type"] == "object"
    assert schema["additionalProperties"] is False
    for key, prop in schema["properties"].items():
        assert prop.get("description"), f"{name}.{key} has no description"
    assert set(schema.get("required", [])) <= set(schema["properties"])


def test_every_shipped_schema_passes_check_schema() -> None:
    for name in schema_names():
        Draft202012Validator.check_schema(load_schema(name))


@pytest.mark.parametrize(
    ("name", "payload"),
    [(name, EXAMPLES[name]) for name in sorted(EXAMPLES)] + VARIANTS,
    ids=[*sorted(EXAMPLES), *(f"{name}-variant{i}" for i, (name, _) in enumerate(VARIANTS))],
)
def test_round_trip_of_every_message(name: str, payload: dict[str, Any]) -> None:
    publisher = Publisher("planner/host/4711", "run-1")
    before = copy.deepcopy(payload)
    text = publisher.encode(name, payload, stamp_ns=123)
    assert payload == before
    message = decode(text)
    version = MESSAGE_VERSIONS[name]
    assert message == Message(name, version, 0, 123, "planner/host/4711", "run-1", payload)
    assert message.schema == f"lit_msgs_json/{name}"
    assert decode(text.encode("utf-8"), accept=name) == message
    assert decode(text, accept=[f"lit_msgs_json/{name}", "Error"]) == message
    # encode() is envelope() as compact JSON, in the envelope's key order
    doc = publisher.envelope(name, payload, stamp_ns=123)
    assert doc["seq"] == 1 and doc["payload"] is payload
    doc["seq"] = 0
    assert typed(json.loads(text)) == typed(doc)
    assert text == json.dumps(json.loads(text), separators=(",", ":"), ensure_ascii=False)
    assert list(doc) == ["schema", "version", "seq", "stamp_ns", "source", "run_id", "payload"]
    validate("Envelope", doc)


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_one_check_of_the_whole_message_agrees_with_the_two_checks(name: str) -> None:
    """decode()'s fast path (codec.valid_envelope) accepts exactly what the reference validator
    accepts for the envelope and the payload separately, on every message and on single-field
    mutations of its envelope and payload."""
    from lit_msgs_json.codec import valid_envelope

    def reference(doc: dict[str, Any]) -> bool:
        shell = {**doc, "payload": {}} if isinstance(doc.get("payload"), dict) else doc
        try:
            validate("Envelope", shell, plain=False)  # plain=False: jsonschema itself
            if isinstance(doc.get("payload"), dict):
                validate(name, doc["payload"], plain=False)
        except lit_msgs_json.SchemaError:
            return False
        return True

    doc = Publisher("p", "r").envelope(name, copy.deepcopy(EXAMPLES[name]), stamp_ns=1)
    assert valid_envelope(name, doc) and reference(doc)
    replacements: list[object] = [None, "x", "", -1, 0, 1, 2.5, 1e300, True, [], {}, [0.5] * 3]
    mutants = [{**doc, "payload": {**doc["payload"], "unexpected": 1}}]
    for key in doc:
        mutants.append({k: v for k, v in doc.items() if k != key})
        mutants += [{**doc, key: value} for value in replacements]
    for key in doc["payload"]:
        payload = doc["payload"]
        mutants.append({**doc, "payload": {k: v for k, v in payload.items() if k != key}})
        mutants += [{**doc, "payload": {**payload, key: value}} for value in replacements]
    assert len(mutants) > 50
    for mutant in mutants:
        assert valid_envelope(name, mutant) == reference(mutant), mutant
    other = "Error" if name != "Error" else "DecideRequest"
    assert not valid_envelope(other, doc)  # the payload is checked against the named schema


def test_encode_with_a_source_and_run_id_json_must_escape() -> None:
    publisher = Publisher('plänner "q" \\ ψ', "rün\t1")
    payload = with_("DecideRequest", episode_id="e")
    for seq in range(2):  # the second text comes from the cached envelope head
        text = publisher.encode("DecideRequest", payload, stamp_ns=7)
        doc = publisher.envelope("DecideRequest", payload, stamp_ns=7)
        doc["seq"] = 2 * seq
        assert json.loads(text) == doc
        assert decode(text).source == 'plänner "q" \\ ψ'


def test_non_ascii_strings_round_trip() -> None:
    payload = with_("DecideRequest", episode_id="épisode-ψ")
    message = decode(Publisher("p", "r").encode("DecideRequest", payload))
    assert message.payload["episode_id"] == "épisode-ψ"


# ---------------------------------------------------------------------------------------------
# orjson (the fast parser and encoder) against the standard json module (the reference)


class _NoOrjson:
    """Stands in for orjson in ``envelope``: every call fails, so decode() and encode() take the
    standard json module's path, the reference the fast path must agree with."""

    JSONDecodeError = ValueError
    JSONEncodeError = TypeError

    @staticmethod
    def loads(text: object) -> object:
        raise ValueError("orjson switched off")

    @staticmethod
    def dumps(obj: object) -> bytes:
        raise TypeError("orjson switched off")


def outcome(text: str | bytes) -> tuple[object, ...]:
    """What decode() makes of ``text``, number types included."""
    try:
        m = decode(text)
    except MessageError as exc:
        return ("error", str(exc), exc.to_payload()["field"])
    return (m.name, m.version, m.seq, m.stamp_ns, m.source, m.run_id, typed(m.payload))


def reference_outcome(text: str | bytes, monkeypatch: pytest.MonkeyPatch) -> tuple[object, ...]:
    with monkeypatch.context() as patch:
        patch.setattr(envelope_module, "orjson", _NoOrjson)
        return outcome(text)


def test_orjson_and_the_standard_parser_decode_alike(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every text decodes to the same message (number types included) or the same error with
    orjson as without it: integers beyond 64 bits (orjson would make them floats), lone
    surrogates (orjson refuses them), overflowing and long numbers, and random mutations."""
    good = EXAMPLES[DR]
    texts = [envelope_text(payload, name) for name, payload in [*EXAMPLES.items(), *VARIANTS]]
    texts += [
        envelope_text(with_(DR, episode_id="\ud800-lone")),  # json.dumps escapes it
        envelope_text(with_(DR, episode_id='épisode ψ " \\ \n \u2028')),
        envelope_text(with_(DR, cost=10**30)),
        envelope_text(with_(DR, cost=2**64 - 1)),
        envelope_text(with_(DR, cost=2**64)),
        envelope_text(with_(DR, cost=-(2**63) - 1)),
        envelope_text(with_(DR, improvements=2**63)),
        envelope_text(good, seq=-(2**63) - 1),
        envelope_text(good, seq=2**64),
        envelope_text(good, seq=3.0),
        envelope_text(good, stamp_ns=99999999999999999999),
        envelope_text(with_(DR, planning_time=1e-7, cost=1.5e300)),
        GOOD.replace("0.42", "1e400"),
        GOOD.replace("0.42", "-1e400"),
        GOOD.replace("0.42", "4.2E-1"),
        GOOD.replace("0.42", "0.4200000000000000000000000000001"),
        GOOD.replace("0.42", "-0.0"),
        GOOD.replace("0.42", "0.42,"),
        GOOD.replace("0.42", "042"),
        "\ufeff" + GOOD,
        " \t\n" + GOOD + " \r\n",
        GOOD + "x",
        GOOD.encode("utf-16"),
        GOOD.encode("utf-8"),
    ]
    rng = random.Random(20261130)
    for _ in range(300):
        text = rng.choice(texts[: len(EXAMPLES)])
        at = rng.randrange(len(text))
        texts.append(text[:at] + rng.choice('0123456789-.eE"{}[],:\\ ') + text[at + 1 :])
    valid = 0
    for text in texts:
        expected = reference_outcome(text, monkeypatch)
        assert outcome(text) == expected, text
        valid += expected[0] != "error"
    assert valid > len(EXAMPLES) + len(VARIANTS)


def test_a_valid_message_takes_the_fast_path(monkeypatch: pytest.MonkeyPatch) -> None:
    """With the standard parser switched off, valid messages still decode (so orjson is really
    what decodes them) and a message orjson cannot take still fails over to it."""

    def refuse(*args: object, **kwargs: object) -> object:
        raise AssertionError("the standard parser was used")

    monkeypatch.setattr(envelope_module.json, "loads", refuse)
    for name, payload in EXAMPLES.items():
        assert decode(envelope_text(payload, name)).payload == payload
    with pytest.raises(MessageError, match="the standard parser was used"):  # code internal
        decode(envelope_text(with_(DR, cost=10**30)))


def test_encode_writes_numbers_and_strings_exactly(monkeypatch: pytest.MonkeyPatch) -> None:
    """encode() (orjson) and decode() give back every finite double bit for bit, every integer
    (beyond 64 bits through the standard encoder), and any string, non-ASCII and lone surrogates
    included; the size limit counts UTF-8 bytes."""
    import math
    import struct

    rng = random.Random(5)
    publisher = Publisher("p", "r")
    values: list[object] = [0.0, -0.0, 5e-324, 1.7976931348623157e308, 1e16, 1e-7, 0.1 + 0.2]
    values += [0, -1, 2**63 - 1, -(2**63), 2**64 - 1, 2**64, -(2**70), 10**30]
    while len(values) < 3000:
        x = struct.unpack("<d", rng.getrandbits(64).to_bytes(8, "little"))[0]
        if math.isfinite(x):
            values.append(x)
    path = [values[i : i + 2] for i in range(0, len(values), 2)]
    payload = with_("PlanResponse", path=path, message='ψ-é\n" \U0001f600')
    decoded = decode(publisher.encode("PlanResponse", payload)).payload
    assert typed(decoded) == typed(payload)
    assert [struct.pack("<d", v) for row in decoded["path"] for v in row if type(v) is float] == [
        struct.pack("<d", v) for v in values if type(v) is float
    ]
    # A lone surrogate is written (escaped), but no receiver takes it: it is not Unicode text
    # (I-JSON), and it stopped the planner node's worker thread in its logger.
    text = publisher.encode("PlanResponse", with_("PlanResponse", message="lone \ud800 surrogate"))
    assert "\\ud800" in text
    with pytest.raises(MessageError, match="lone UTF-16 surrogate") as caught:
        decode(text)
    assert (caught.value.code, caught.value.field) == ("json", "$.payload.message")
    # The first such string in document order is named.
    two = with_("PlanResponse", message="\udc00", path=[[0.0, 1.0], [2.0, "\ud800"]])
    with pytest.raises(MessageError) as caught:
        decode(envelope_text(two, "PlanResponse"))
    assert caught.value.field == "$.payload.message"
    # An Error made from an exception whose text holds one (a file name that is not UTF-8, as
    # os.fsdecode gives it) is escaped: its receivers would refuse it.
    answer = decode(publisher.error(OSError("cannot open caf\udce9.pt")))
    assert answer.payload["message"] == "OSError: cannot open caf\\udce9.pt"
    # the limit is on UTF-8 bytes: each 'ψ' is two
    payload = with_("PlanResponse", message="ψ" * 100)
    text = publisher.encode("PlanResponse", payload)
    assert len(text.encode("utf-8")) == len(text) + 100
    monkeypatch.setattr(envelope_module, "MAX_MESSAGE_BYTES", len(text) + 99)
    with pytest.raises(MessageError, match="max-bytes"):
        publisher.encode("PlanResponse", payload)
    monkeypatch.setattr(envelope_module, "MAX_MESSAGE_BYTES", len(text) + 100)
    assert decode(publisher.encode("PlanResponse", payload)).payload == payload


def test_encoding_a_payload_nested_too_deeply_is_a_message_error() -> None:
    nested: list[object] = []
    for _ in range(5000):
        nested = [nested]
    with pytest.raises(MessageError) as info:
        Publisher("p", "r").encode("PlanResponse", with_("PlanResponse", path=nested))
    assert (info.value.code, info.value.rule) == ("payload", "max-depth")


# ---------------------------------------------------------------------------------------------
# Publisher


def test_seq_rises_by_one_and_failures_take_none(monkeypatch: pytest.MonkeyPatch) -> None:
    publisher = Publisher("learner/host/42", "run-1")
    assert (publisher.source, publisher.run_id, publisher.next_seq) == (
        "learner/host/42",
        "run-1",
        0,
    )
    seqs = [decode(publisher.encode("DecideRequest", EXAMPLES["DecideRequest"])).seq]
    with pytest.raises(MessageError) as info:
        publisher.encode("DecideRequest", with_("DecideRequest", rho_global=1.5))
    assert (info.value.code, info.value.field, info.value.rule) == (
        "payload",
        "$.payload.rho_global",
        "maximum",
    )
    with pytest.raises(MessageError) as info:
        publisher.envelope("DecideRequest", with_("DecideRequest", rho_global=float("nan")))
    assert (info.value.code, info.value.field, info.value.rule) == (
        "payload",
        "$.payload.rho_global",
        "finite",
    )
    with pytest.raises(MessageError) as info:
        publisher.encode("TensorSidecar", {})
    assert (info.value.code, info.value.field, info.value.rule) == (
        "unknown-schema",
        "$.schema",
        "schema",
    )
    with pytest.raises(MessageError) as info:
        publisher.encode("DecideRequest", EXAMPLES["DecideRequest"], stamp_ns=-1)
    assert (info.value.code, info.value.field) == ("envelope", "$.stamp_ns")
    # oversize: the limit is read at call time, so a small one stands in for 1 MiB here
    monkeypatch.setattr(envelope_module, "MAX_MESSAGE_BYTES", 200)
    with pytest.raises(MessageError) as info:
        publisher.encode("DecideRequest", EXAMPLES["DecideRequest"])
    assert (info.value.code, info.value.rule) == ("oversize", "max-bytes")
    assert "200" in str(info.value)
    monkeypatch.undo()
    assert publisher.next_seq == 1
    seqs.append(publisher.envelope("DecideResponse", EXAMPLES["DecideResponse"])["seq"])
    seqs.append(decode(publisher.encode("lit_msgs_json/Error", EXAMPLES["Error"])).seq)
    assert seqs == [0, 1, 2] and publisher.next_seq == 3


def test_real_size_limit_on_encode() -> None:
    publisher = Publisher("p", "r")
    # about 1.1 MB of path: 9000 states of 5 coordinates, 24 characters each
    path = [[-1.2345678901234567e-300] * 5] * 9000
    with pytest.raises(MessageError) as info:
        publisher.encode("PlanResponse", with_("PlanResponse", path=path))
    assert (info.value.code, info.value.request_schema) == ("oversize", "PlanResponse")
    assert f"limit of {MAX_MESSAGE_BYTES} bytes" in str(info.value)
    assert publisher.next_seq == 0


def test_seq_is_thread_safe() -> None:
    publisher = Publisher("p", "r")
    threads, per_thread = 8, 150
    seqs: list[int] = []
    lock = threading.Lock()
    start = threading.Barrier(threads)

    def work() -> None:
        start.wait()
        mine = []
        for i in range(per_thread):
            if i % 3:
                mine.append(decode(publisher.encode("SolutionUpdate", EXAMPLES["SolutionUpdate"])))
            else:
                mine.append(publisher.envelope("Decision", EXAMPLES["Decision"])["seq"])
        with lock:
            seqs.extend(m if isinstance(m, int) else m.seq for m in mine)

    workers = [threading.Thread(target=work) for _ in range(threads)]
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join()
    assert sorted(seqs) == list(range(threads * per_thread))
    assert publisher.next_seq == threads * per_thread


def test_publisher_rejects_bad_source_and_run_id() -> None:
    for source, run_id, field in (("", "r", "$.source"), ("p", "x" * 129, "$.run_id")):
        with pytest.raises(MessageError) as info:
            Publisher(source, run_id)
        assert (info.value.code, info.value.field) == ("envelope", field)


def test_error_messages() -> None:
    publisher = Publisher("learner/host/42", "run-1")
    try:
        decode(envelope_text(with_("DecideRequest", rho_global=1.5)), accept="DecideRequest")
    except MessageError as exc:
        reply = decode(publisher.error(exc), accept="Error")
    assert reply.payload == {
        "code": "payload",
        "message": "DecideRequest seq 3 rejected (payload) at $.payload.rho_global: 1.5 is "
        "greater than the maximum of 1 (rule: maximum)",
        "field": "$.payload.rho_global",
        "rule": "maximum",
        "request_schema": "DecideRequest",
        "request_seq": 3,
    }
    internal = decode(publisher.error(RuntimeError("boom\nagain"))).payload
    assert internal["code"] == "internal"
    assert internal["message"] == "RuntimeError: boom again"
    assert internal["field"] is None and internal["request_seq"] is None
    busy = decode(publisher.error(RuntimeError("x"), code="busy", request_seq=9)).payload
    assert (busy["code"], busy["request_seq"]) == ("busy", 9)
    with pytest.raises(MessageError) as info:
        publisher.error(RuntimeError("x"), code="nope")
    assert (info.value.field, info.value.rule) == ("$.payload.code", "enum")
    long = MessageError("internal", "x" * 10_000, field="$." + "a" * 2000)
    assert len(long.to_payload()["message"]) == 4096
    validate("Error", long.to_payload())
    assert publisher.next_seq == 3
    with pytest.raises(ValueError, match="unknown error code"):
        MessageError("weird", "x")


def test_message_error_pickles() -> None:
    error = MessageError("version", "got 2", field="$.version", rule="version", request_seq=4)
    copy_ = pickle.loads(pickle.dumps(error))
    assert (str(copy_), copy_.to_payload()) == (str(error), error.to_payload())


# ---------------------------------------------------------------------------------------------
# decode failures


def deep(depth: int) -> str:
    return envelope_text({"x": 0}).replace('{"x": 0}', "[" * depth + "]" * depth)


DecodeCase = tuple[str, object, str, str | None, str | None, str | None, int | None]

DR = "DecideRequest"
GOOD = envelope_text(EXAMPLES[DR])
WORLD = {"lower": [0, 0], "upper": [1, 1], "boxes": []}
BOX = {"lower": [0.1, 0.1], "upper": [0.2, 0.2]}
START_GOAL = {"start": [0, 0], "goal": [1, 1]}
MIB = MAX_MESSAGE_BYTES

# (id, text, code, field, rule, request_schema, request_seq)
DECODE_FAILURES: list[DecodeCase] = [
    ("malformed", '{"schema": "lit_msgs_json/DecideRequest",', "json", "$", "json", None, None),
    ("empty", "", "json", "$", "json", None, None),
    ("not-utf8", GOOD.encode().replace(b"B", b"\xff"), "json", "$", "json", None, None),
    ("surrogate", GOOD.replace("np8", "\ud800"), "json", "$", "json", None, None),
    (
        "surrogate-escape",
        GOOD.replace("np8", "\\udfff"),
        "json",
        "$.payload.episode_id",
        "json",
        DR,
        3,
    ),
    ("surrogate-key", GOOD.replace('"explore"', '"\\ud801x"'), "json", "$.payload", "json", DR, 3),
    ("nan", GOOD.replace("0.42", "NaN"), "json", "$", "json", None, None),
    ("infinity", GOOD.replace("0.42", "-Infinity"), "json", "$", "json", None, None),
    ("deep", deep(100), "json", "$", "max-depth", None, None),
    ("very-deep", deep(200_000), "json", "$", "max-depth", None, None),
    ("oversize", GOOD + " " * MIB, "oversize", "$", "max-bytes", None, None),
    (
        "oversize-2-byte",
        GOOD.replace("np8", "é" * (MIB // 2)),
        "oversize",
        "$",
        "max-bytes",
        None,
        None,
    ),
    ("not-object", "[1, 2]", "envelope", "$", "type", None, None),
    ("seq-inf", GOOD.replace('"seq": 3', '"seq": 1e999'), "envelope", "$.seq", "finite", DR, None),
    (
        "rho-overflow",
        GOOD.replace("0.42", "1e999"),
        "payload",
        "$.payload.rho_global",
        "finite",
        DR,
        3,
    ),
    # Overflowing spellings without a 3-digit exponent: json.loads makes them inf as well.
    *(
        (name, GOOD.replace("0.42", spelling), "payload", "$.payload.rho_global", "finite", DR, 3)
        for name, spelling in [
            ("rho-overflow-digits", "1" * 400 + ".0"),
            ("rho-overflow-mixed", "1" + "0" * 250 + "e99"),
        ]
    ),
]

# (id, envelope fields changed (... deletes), code, field, rule, request_schema, request_seq);
# the payload is a valid DecideRequest
ENVELOPE_FAILURES: list[tuple[str, dict[str, object], str, str, str, str | None, int | None]] = [
    ("missing-run-id", {"run_id": ...}, "envelope", "$", "required", DR, 3),
    ("missing-payload", {"payload": ...}, "envelope", "$", "required", DR, 3),
    ("extra-field", {"reply_to": "x"}, "envelope", "$", "additionalProperties", DR, 3),
    ("seq-negative", {"seq": -1}, "envelope", "$.seq", "minimum", DR, None),
    ("seq-string", {"seq": "3"}, "envelope", "$.seq", "type", DR, None),
    ("seq-huge", {"seq": 2**63}, "envelope", "$.seq", "maximum", DR, None),
    ("seq-bool", {"seq": True}, "envelope", "$.seq", "type", DR, None),
    ("stamp-float", {"stamp_ns": 1.5}, "envelope", "$.stamp_ns", "type", DR, 3),
    ("version-zero", {"version": 0}, "envelope", "$.version", "minimum", DR, 3),
    ("schema-no-prefix", {"schema": DR}, "envelope", "$.schema", "pattern", None, 3),
    ("source-empty", {"source": ""}, "envelope", "$.source", "minLength", DR, 3),
    ("payload-list", {"payload": []}, "envelope", "$.payload", "type", DR, 3),
    ("unknown", {"schema": "lit_msgs_json/Foo"}, "unknown-schema", "$.schema", "schema", "Foo", 3),
    (
        "file-format",
        {"schema": "lit_msgs_json/TensorSidecar"},
        "unknown-schema",
        "$.schema",
        "schema",
        "TensorSidecar",
        3,
    ),
    (
        "envelope-as-message",
        {"schema": "lit_msgs_json/Envelope"},
        "unknown-schema",
        "$.schema",
        "schema",
        "Envelope",
        3,
    ),
    ("wrong-version", {"version": 4}, "version", "$.version", "version", DR, 3),
]

# (id, schema, payload, field, rule): the envelope is fine, the payload is not
PAYLOAD_FAILURES: list[tuple[str, str, object, str, str]] = [
    ("rho-out-of-range", DR, with_(DR, rho_global=1.5), "$.payload.rho_global", "maximum"),
    ("agent", DR, with_(DR, agent="C"), "$.payload.agent", "enum"),
    ("cost-zero", DR, with_(DR, cost=0), "$.payload.cost", "exclusiveMinimum"),
    ("budget", DR, with_(DR, time_budget=3601), "$.payload.time_budget", "maximum"),
    ("bool-not-int", DR, with_(DR, improvements=True), "$.payload.improvements", "type"),
    ("dimension-65", DR, with_(DR, dimension=65), "$.payload.dimension", "maximum"),
    ("extra-payload-field", DR, with_(DR, colour="red"), "$.payload", "additionalProperties"),
    (
        "missing-payload-field",
        DR,
        {k: v for k, v in EXAMPLES[DR].items() if k != "episode_id"},
        "$.payload",
        "required",
    ),
    ("episode-id-long", DR, with_(DR, episode_id="e" * 129), "$.payload.episode_id", "maxLength"),
    (
        "final-features",
        "EpisodeEnd",
        with_("EpisodeEnd", final_features={"B": [0.5, 0.5]}),
        "$.payload.final_features.B",
        "minItems",
    ),
    (
        "final-feature-range",
        "EpisodeEnd",
        with_("EpisodeEnd", final_features={"psi_K": [0.5, 0.5, -0.1]}),
        "$.payload.final_features.psi_K[2]",
        "minimum",
    ),
    (
        "plan-both",
        "PlanRequest",
        {"scenario": "np8", "world": WORLD, **START_GOAL},
        "$.payload",
        "oneOf",
    ),
    ("plan-neither", "PlanRequest", {"time": 1.0}, "$.payload", "oneOf"),
    (
        "plan-world-no-start",
        "PlanRequest",
        {"world": WORLD, "goal": [1, 1]},
        "$.payload",
        "required",
    ),
    ("plan-scenario-name", "PlanRequest", {"scenario": "NP8"}, "$.payload.scenario", "pattern"),
    (
        "plan-start-65",
        "PlanRequest",
        {"scenario": "np8", "start": [0.5] * 65},
        "$.payload.start",
        "maxItems",
    ),
    (
        "plan-start-1",
        "PlanRequest",
        {"scenario": "np8", "goal": [0.5]},
        "$.payload.goal",
        "minItems",
    ),
    (
        "plan-world-65",
        "PlanRequest",
        {"world": {**WORLD, "lower": [0] * 65}, **START_GOAL},
        "$.payload.world.lower",
        "maxItems",
    ),
    (
        "plan-box-65",
        "PlanRequest",
        {"world": {**WORLD, "boxes": [BOX, {**BOX, "upper": [1] * 65}]}, **START_GOAL},
        "$.payload.world.boxes[1].upper",
        "maxItems",
    ),
    (
        "plan-10001-boxes",
        "PlanRequest",
        {"world": {**WORLD, "boxes": [BOX] * 10001}, **START_GOAL},
        "$.payload.world.boxes",
        "maxItems",
    ),
    (
        "plan-resolution",
        "PlanRequest",
        {"world": {**WORLD, "resolution": 0}, **START_GOAL},
        "$.payload.world.resolution",
        "minimum",
    ),
    (
        "plan-resolution-too-fine",  # 1e-10 ran the planner node out of memory on one edge
        "PlanRequest",
        {"world": {**WORLD, "resolution": 1e-10}, **START_GOAL},
        "$.payload.world.resolution",
        "minimum",
    ),
    ("plan-seed", "PlanRequest", {"scenario": "np8", "seed": 2**32}, "$.payload.seed", "maximum"),
    (
        "plan-planner",
        "PlanRequest",
        {"scenario": "np8", "planner": "prm"},
        "$.payload.planner",
        "enum",
    ),
    (
        "response-pair",
        "PlanResponse",
        with_("PlanResponse", improvements=[[0.1, 1.0, 2.0]]),
        "$.payload.improvements[0]",
        "maxItems",
    ),
    (
        "counters-negative",
        "PlanResponse",
        with_("PlanResponse", counters={"iterations": -1}),
        "$.payload.counters.iterations",
        "minimum",
    ),
    ("decision-source", "Decision", with_("Decision", source="oracle"), "$.payload.source", "enum"),
    (
        "first-improvement",
        "SolutionUpdate",
        with_("SolutionUpdate", improvement=0),
        "$.payload.improvement",
        "minimum",
    ),
    (
        "summary-mode",
        "EpisodeSummary",
        with_("EpisodeSummary", mode="eval"),
        "$.payload.mode",
        "enum",
    ),
    (
        "stats-transitions",
        "LearnerStats",
        with_("LearnerStats", transitions={"B": 1}),
        "$.payload.transitions",
        "required",
    ),
    ("error-message-empty", "Error", with_("Error", message=""), "$.payload.message", "minLength"),
    ("cancel-no-id", "CancelRequest", {}, "$.payload", "required"),
    ("cancel-empty-id", "CancelRequest", {"request_id": ""}, "$.payload.request_id", "minLength"),
    (
        "cancel-extra",
        "CancelRequest",
        {"request_id": "a", "seq": 3},
        "$.payload",
        "additionalProperties",
    ),
    (
        "cancelled-two-running",
        "CancelResponse",
        with_("CancelResponse", running=2),
        "$.payload.running",
        "maximum",
    ),
]

DECODE_FAILURES += [
    (case_id, envelope_text(EXAMPLES[DR], **fields), code, field, rule, schema, seq)
    for case_id, fields, code, field, rule, schema, seq in ENVELOPE_FAILURES
]
DECODE_FAILURES += [
    (case_id, envelope_text(payload, name), "payload", field, rule, name, 3)
    for case_id, name, payload, field, rule in PAYLOAD_FAILURES
]


@pytest.mark.parametrize(
    ("text", "code", "field", "rule", "request_schema", "request_seq"),
    [case[1:] for case in DECODE_FAILURES],
    ids=[case[0] for case in DECODE_FAILURES],
)
def test_decode_failures_name_code_field_and_rule(
    text: str | bytes,
    code: str,
    field: str | None,
    rule: str | None,
    request_schema: str | None,
    request_seq: int | None,
) -> None:
    with pytest.raises(MessageError) as info:
        decode(text)
    error = info.value
    assert (error.code, error.field, error.rule) == (code, field, rule), str(error)
    assert (error.request_schema, error.request_seq) == (request_schema, request_seq)
    message = str(error)
    assert "\n" not in message and len(message) < 1000
    assert f"({code})" in message
    if field:
        assert f" at {field}: " in message
    if rule:
        assert message.endswith(f"(rule: {rule})")
    payload = error.to_payload()
    validate("Error", payload)
    assert (payload["code"], payload["field"], payload["message"]) == (code, field, message)


def test_decode_failure_messages_explain() -> None:
    def message(text: str | bytes, accept: str | list[str] | None = None) -> str:
        with pytest.raises(MessageError) as info:
            decode(text, accept)
        return str(info.value)

    size = len(GOOD) + MAX_MESSAGE_BYTES
    assert f"message is {size} bytes, more than the limit of {MAX_MESSAGE_BYTES} bytes" in (
        message(GOOD + " " * MAX_MESSAGE_BYTES)
    )
    assert "got version 4 of DecideRequest, expected versions 1, 2, 3" in message(
        envelope_text({}, version=4)
    )
    assert "got version 2 of PlanRequest, expected version 1" in message(
        envelope_text({}, "PlanRequest", version=2)
    )
    assert "known: CancelRequest, CancelResponse, DecideRequest, DecideResponse," in message(
        envelope_text({}, "Foo")
    )
    assert "not valid JSON: NaN is not allowed" in message(GOOD.replace("0.42", "NaN"))
    assert "exactly one of 'scenario', 'world' is required, got 'scenario' and 'world'" in message(
        envelope_text(
            {"scenario": "np8", "world": WORLD, "start": [0, 0], "goal": [1, 1]}, "PlanRequest"
        )
    )
    assert "'start' is a required property" in message(
        envelope_text({"world": WORLD, "goal": [1, 1]}, "PlanRequest")
    )


def test_accept() -> None:
    text = envelope_text(EXAMPLES["EpisodeEnd"], "EpisodeEnd")
    assert decode(text, accept="EpisodeEnd").name == "EpisodeEnd"
    assert decode(text, accept=("DecideRequest", "lit_msgs_json/EpisodeEnd")).seq == 3
    with pytest.raises(MessageError) as info:
        decode(text, accept=["DecideRequest", "PlanRequest"])
    error = info.value
    assert (error.code, error.field, error.rule) == ("unexpected-schema", "$.schema", "schema")
    assert (error.request_schema, error.request_seq) == ("EpisodeEnd", 3)
    assert "EpisodeEnd is not accepted here; accepted: DecideRequest, PlanRequest" in str(error)
    # the order of the checks: unknown before unexpected, version after unexpected
    with pytest.raises(MessageError, match="unknown-schema"):
        decode(envelope_text({}, "Foo"), accept="EpisodeEnd")
    with pytest.raises(MessageError, match="unexpected-schema"):
        decode(envelope_text({}, "PlanRequest", version=7), accept="EpisodeEnd")
    with pytest.raises(ValueError, match="accept names Nope, not message schemas"):
        decode(text, accept=["Nope"])


def test_size_limit_boundary() -> None:
    padded = GOOD + " " * (MAX_MESSAGE_BYTES - len(GOOD))
    assert len(padded.encode("utf-8")) == MAX_MESSAGE_BYTES
    assert decode(padded).payload == EXAMPLES["DecideRequest"]
    with pytest.raises(MessageError, match="max-bytes"):
        decode((padded + " ").encode("utf-8"))


def test_decoded_integers_are_ints() -> None:
    text = GOOD.replace('"seq": 3', '"seq": 3.0').replace('"version": 3', '"version": 3.0')
    assert text != GOOD.replace('"seq": 3', '"seq": 3.0')
    message = decode(text)
    assert (message.seq, message.version) == (3, 3)
    assert type(message.seq) is int and type(message.version) is int


@pytest.mark.parametrize(
    "mutate",
    [
        lambda text, rng: text[: rng.randrange(len(text))],
        lambda text, rng: text.replace(text[rng.randrange(len(text))], chr(rng.randrange(0x2FF))),
        lambda text, rng: bytes(
            b if rng.random() > 0.02 else rng.randrange(256) for b in text.encode("utf-8")
        ),
    ],
    ids=["truncated", "replaced", "bit-noise"],
)
def test_decode_raises_only_message_errors(
    mutate: Callable[[str, random.Random], str | bytes],
) -> None:
    rng = random.Random(20260509)
    texts = [GOOD, envelope_text(EXAMPLES["PlanResponse"], "PlanResponse")]
    for _ in range(150):
        mutated = mutate(rng.choice(texts), rng)
        try:
            message = decode(mutated)
        except MessageError as exc:
            validate("Error", exc.to_payload())
        else:
            validate(message.name, message.payload)
    for weird in (None, 5, {"schema": "x"}):
        with pytest.raises(MessageError, match=r"\(json\)"):
            decode(weird)  # type: ignore[arg-type]


def test_fast_validator_is_never_more_lenient_than_jsonschema() -> None:
    """The compiled validator only short-cuts documents the reference accepts: it accepts every
    example (so the hot path is really taken) and rejects every payload failure case."""
    from lit_msgs_json import codec

    for name, payload in EXAMPLES.items():
        reference = Draft202012Validator(load_schema(name), registry=codec._registry())
        assert reference.is_valid(payload), name
        assert codec._fast_validator(name).is_valid(payload), name
    for case_id, name, payload, _field, _rule in PAYLOAD_FAILURES:
        reference = Draft202012Validator(load_schema(name), registry=codec._registry())
        if not reference.is_valid(payload):  # NaN cases are the finite check's, not the schema's
            assert not codec._fast_validator(name).is_valid(payload), case_id


def test_documents_json_cannot_carry_get_the_reference_answer() -> None:
    """Tuples are no JSON arrays for jsonschema, numpy scalars no JSON numbers: the compiled
    validator (which would take the first and raise ValueError on the second) never sees them."""
    import numpy as np

    payload = copy.deepcopy(EXAMPLES["DecideRequest"])
    payload["improvements"] = np.int64(2)
    with pytest.raises(MessageError) as info:
        Publisher("lit_call", "x").encode("DecideRequest", payload)
    assert info.value.code == "payload"
    plan = {"scenario": "np8", "start": (0.1, 0.1), "goal": [0.9, 0.9]}
    reference = Draft202012Validator(load_schema("PlanRequest"))
    assert not reference.is_valid(plan)
    with pytest.raises(lit_msgs_json.SchemaError, match=r"\$\.start: .* is not of type 'array'"):
        validate("PlanRequest", plan)


# ---------------------------------------------------------------------------------------------
# Older versions


def test_publishers_send_the_current_version() -> None:
    for name in ("DecideRequest", "EpisodeEnd", "PlanRequest"):
        doc = json.loads(Publisher("p", "r").encode(name, EXAMPLES[name]))
        assert doc["version"] == MESSAGE_VERSIONS[name]
    assert accepted_versions("DecideRequest") == (1, 2, 3)
    assert accepted_versions("EpisodeEnd") == (1, 2)
    assert accepted_versions("PlanRequest") == (1,)


def test_decide_request_version_3_adds_probe() -> None:
    """A probe sent to a learner that only knows version 2 is refused as a newer version, and a
    version 2 request that carries probe is a payload error (the field is not in version 2)."""
    payload = dict(EXAMPLES["DecideRequest"])
    assert decode(envelope_text({**payload, "probe": True})).payload["probe"] is True
    assert decode(envelope_text(payload, version=2)).version == 2
    with pytest.raises(MessageError, match="probe is not a field of version 2"):
        decode(envelope_text({**payload, "probe": True}, version=2))


def test_episode_summary_version_3_adds_the_final_features() -> None:
    final = {"B": [0.1, 0.2, 0.3], "psi_K": [0.1, 0.25, 0.3]}
    payload = {key: v for key, v in EXAMPLES["EpisodeSummary"].items() if key != "final_features"}
    assert accepted_versions("EpisodeSummary") == (1, 2, 3)
    for version in (1, 2):  # still read, without them
        assert decode(envelope_text(payload, "EpisodeSummary", version=version)).version == version
        with pytest.raises(
            MessageError, match=f"final_features is not a field of version {version}"
        ):
            decode(
                envelope_text(
                    {**payload, "final_features": final}, "EpisodeSummary", version=version
                )
            )
    message = decode(
        envelope_text({**payload, "final_features": final}, "EpisodeSummary", version=3)
    )
    assert message.payload["final_features"] == final
    with pytest.raises(MessageError) as info:  # features are in [0, 1]
        decode(
            envelope_text(
                {**payload, "final_features": {"B": [0, 0, 2]}}, "EpisodeSummary", version=3
            )
        )
    assert info.value.code == "payload" and info.value.field == "$.payload.final_features.B[2]"


def test_plan_response_version_2_adds_the_effort_to_the_first_solution() -> None:
    effort = {"checks_init": 40213, "iteration_init": 731}
    payload = {key: v for key, v in EXAMPLES["PlanResponse"].items() if key not in effort}
    assert accepted_versions("PlanResponse") == (1, 2)
    assert decode(envelope_text(payload, "PlanResponse", version=1)).version == 1
    for key, value in effort.items():
        with pytest.raises(MessageError, match=f"{key} is not a field of version 1"):
            decode(envelope_text({**payload, key: value}, "PlanResponse", version=1))
    message = decode(envelope_text({**payload, **effort}, "PlanResponse", version=2))
    assert message.payload | effort == message.payload
    unsolved = {**payload, "checks_init": None, "iteration_init": None}
    assert decode(envelope_text(unsolved, "PlanResponse", version=2)).version == 2
    with pytest.raises(MessageError) as info:
        decode(envelope_text({**payload, "checks_init": -1}, "PlanResponse", version=2))
    assert info.value.field == "$.payload.checks_init"


@pytest.mark.parametrize(
    ("name", "field", "value"),
    [
        ("DecideRequest", "after_fallback", True),
        ("EpisodeEnd", "fallback_agents", ["B"]),
        ("EpisodeSummary", "world", WORLD | START_GOAL | {"resolution": 0.01}),
    ],
)
def test_version_1_is_decoded_without_the_fields_version_2_added(
    name: str, field: str, value: object
) -> None:
    payload = {key: v for key, v in EXAMPLES[name].items() if key != field}
    message = decode(envelope_text(payload, name, version=1), accept=name)
    assert (message.name, message.version, message.payload) == (name, 1, payload)
    # the same payload in version 2 is fine too (the field is optional) ...
    assert decode(envelope_text(payload, name, version=2)).version == 2
    # ... the field itself is not part of version 1
    with pytest.raises(MessageError) as info:
        decode(envelope_text({**payload, field: value}, name, version=1))
    error = info.value
    assert (error.code, error.field, error.rule) == ("payload", f"$.payload.{field}", "version")
    assert (error.request_schema, error.request_seq) == (name, 3)
    assert f"{field} is not a field of version 1 of {name}" in str(error)
    assert decode(envelope_text({**payload, field: value}, name, version=2)).payload[field] == value


def test_an_integer_too_large_for_a_double_is_refused_as_1e400_is() -> None:
    """A 401-digit integer passed as a number and overflowed where a node used it (a planner
    node's world: OverflowError, the node down; the learner's reward: an empty answer)."""
    for sign in ("", "-"):
        with pytest.raises(MessageError) as spelled_as_float:
            decode(GOOD.replace("0.42", f"{sign}1e400"))
        with pytest.raises(MessageError) as spelled_as_integer:
            decode(GOOD.replace("0.42", f"{sign}1" + "0" * 400))
        first, second = spelled_as_float.value, spelled_as_integer.value
        assert (second.code, second.field, second.rule) == (first.code, first.field, first.rule)
    assert decode(envelope_text(with_(DR, cost=10**300))).payload["cost"] == 10**300  # a double


def test_a_name_given_twice_in_an_object_is_refused() -> None:
    """I-JSON (RFC 7493) forbids it; both parsers kept the last, so a PlanRequest with two
    request_ids could be logged as one and planned (or cancelled) as the other."""
    world = {
        "lower": [0.0, 0.0],
        "upper": [1.0, 1.0],
        "boxes": [{"lower": [0.4, 0.4], "upper": [0.5, 0.5]}],
    }
    plan = envelope_text({"world": world, "start": [0.1, 0.1], "goal": [0.9, 0.9]}, "PlanRequest")
    assert decode(plan).payload["world"] == world
    twice = [
        ("payload", "$", GOOD.replace('"payload":', '"payload": {}, "payload":', 1)),
        (
            "request_id",
            "$.payload",
            plan.replace('"goal":', '"request_id": "a", "request_id": "b", "goal":'),
        ),
        (
            "request_id",
            "$.payload",
            plan.replace('"goal":', '"request_id": "a", "request_id" \n: "b", "goal":'),
        ),
        (
            "upper",
            "$.payload.world.boxes[0]",
            plan.replace('"upper": [0.5, 0.5]', '"upper": [0.5, 0.5], "upper": [0.6, 0.6]'),
        ),
        # The inner object's duplicate is dropped with it by the outer one's (a review found the
        # message naming "a" at "$").
        ("payload", "$", GOOD.replace('"payload":', '"payload": {"a": 1, "a": 2}, "payload":', 1)),
    ]
    for name, where, text in twice:
        assert text.count(f'"{name}"') >= 2, name
        for sent in (text, text.encode()):
            with pytest.raises(MessageError, match=f"has the name '{name}' twice") as caught:
                decode(sent)
            assert caught.value.code == "json"
            # The object's path (it was "$" for every object, the payload's included).
            assert caught.value.field == where, caught.value.field
            assert f"the object at {where} has" in str(caught.value)
    # A string holding a quote and a colon is no name.
    text = envelope_text(with_(DR, episode_id='run "a": 1 \\":'))
    assert decode(text).payload["episode_id"] == 'run "a": 1 \\":'

"""Tests of schema loading and validation, with the TensorSidecar schema as the subject."""

from __future__ import annotations

import copy
import json
from collections.abc import Callable
from importlib.resources import files
from typing import Any

import pytest

import lit_msgs_json
from lit_msgs_json import SchemaError, UnknownSchemaError, dumps, load_schema, loads, validate

HEX = "0123456789abcdef" * 4


def good_sidecar() -> dict[str, Any]:
    """A sidecar written out by hand from LEARNER.md, independent of the planner's writer."""
    return {
        "schema": "lit_msgs_json/TensorSidecar",
        "version": 1,
        "output": {"name": "B", "range": [20, 200], "rounding": "half_away_from_zero"},
        "axes": [
            {"name": name, "range": [0, 1], "size": 101, "transform": "identity"}
            for name in ("rho_global", "rho_local", "measure")
        ],
        "interpolation": "trilinear",
        "fuzzification": {"centres": [0.0, 0.5, 1.0], "sigma": 0.2123},
        "tsk": {"consequents": [20, 110, 200]},
        "reward": {"w_t": 0.01, "w_c": 1.0, "w_u": 0.05, "w_s": 0.1},
        "training": {"gamma": 0.99, "tau": 0.005, "nested": {"anything": [1, "two"]}},
        "policy_version": 12,
        "data_sha256": HEX,
        "checkpoint_sha256": None,
        "dtype": "<f4",
        "shape": [101, 101, 101],
        "created": "2026-05-09T07:35:00+00:00",
        "provenance": {},
    }


def test_schema_is_packaged_and_loadable() -> None:
    assert (files("lit_msgs_json") / "schemas" / "TensorSidecar.schema.json").is_file()
    assert "TensorSidecar" in lit_msgs_json.schema_names()
    schema = load_schema("TensorSidecar")
    assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    assert load_schema("lit_msgs_json/TensorSidecar") is schema


def test_unknown_schema() -> None:
    with pytest.raises(UnknownSchemaError, match=r"Nope: .*no such schema; known: .*TensorSidecar"):
        load_schema("Nope")
    with pytest.raises(UnknownSchemaError, match=r"\.\./TensorSidecar: .*no such schema"):
        validate("../TensorSidecar", {})
    assert issubclass(UnknownSchemaError, ValueError) and issubclass(
        UnknownSchemaError, LookupError
    )


def test_good_sidecars_pass() -> None:
    validate("TensorSidecar", good_sidecar())
    k = good_sidecar()
    k["output"] = {"name": "psi_K", "range": [3.0, 15.0], "rounding": "none"}
    k["checkpoint_sha256"] = HEX
    k["interpolation"] = "nearest"
    k["created"] = "2026-05-09T07:35:00.123Z"
    validate("lit_msgs_json/TensorSidecar", k)


def setter(path: str, value: object) -> Callable[[dict[str, Any]], None]:
    """Mutation that sets a dotted path (list indices as numbers)."""

    def mutate(doc: dict[str, Any]) -> None:
        *parents, last = [int(p) if p.isdigit() else p for p in path.split(".")]
        for key in parents:
            doc = doc[key]
        doc[last] = value

    return mutate


def deleter(key: str) -> Callable[[dict[str, Any]], None]:
    return lambda doc: doc.pop(key)


BAD = [
    (setter("schema", "lit_msgs_json/Other"), "$.schema", "const"),
    (setter("version", 2), "$.version", "const"),
    (setter("output.name", "C"), "$.output.name", "enum"),
    (setter("output.rounding", "none"), "$.output.rounding", "const"),
    (setter("output.range", [20]), "$.output.range", "minItems"),
    (setter("axes.1.name", "measure"), "$.axes[1].name", "const"),
    (setter("axes.0.size", 100), "$.axes[0].size", "const"),
    (setter("axes.2.transform", "log"), "$.axes[2].transform", "const"),
    (setter("axes.0.range", [0, 2]), "$.axes[0].range", "const"),
    (lambda doc: doc["axes"].append(dict(doc["axes"][0])), "$.axes", "items"),
    (setter("interpolation", "cubic"), "$.interpolation", "enum"),
    (setter("fuzzification.sigma", 0), "$.fuzzification.sigma", "exclusiveMinimum"),
    (setter("fuzzification.sigma", float("nan")), "$.fuzzification.sigma", "finite"),
    (setter("tsk.consequents", [20, 200]), "$.tsk.consequents", "minItems"),
    (setter("reward", []), "$.reward", "type"),
    (setter("policy_version", -1), "$.policy_version", "minimum"),
    (setter("policy_version", 1.5), "$.policy_version", "type"),
    (setter("data_sha256", "abc"), "$.data_sha256", "pattern"),
    (setter("data_sha256", None), "$.data_sha256", "type"),
    (setter("checkpoint_sha256", HEX.upper()), "$.checkpoint_sha256", "pattern"),  # best of oneOf
    (setter("checkpoint_sha256", 7), "$.checkpoint_sha256", "oneOf"),
    (setter("dtype", "<f8"), "$.dtype", "const"),
    (setter("shape", [101, 101, 100]), "$.shape", "const"),
    (setter("created", "yesterday"), "$.created", "pattern"),
    (setter("created", "2026-05-09T07:35:00"), "$.created", "pattern"),
    (setter("unexpected", 1), "$", "additionalProperties"),
    (deleter("policy_version"), "$", "required"),
]


@pytest.mark.parametrize(("mutate", "json_path", "rule"), BAD, ids=[f"{p}:{r}" for _, p, r in BAD])
def test_bad_sidecars_name_field_and_rule(
    mutate: Callable[[dict[str, Any]], None], json_path: str, rule: str
) -> None:
    doc = good_sidecar()
    mutate(doc)
    with pytest.raises(SchemaError) as info:
        validate("TensorSidecar", doc)
    error = info.value
    assert (error.schema, error.json_path, error.rule) == ("TensorSidecar", json_path, rule)
    assert str(error).startswith(f"TensorSidecar: {json_path}: ")
    assert f"(rule: {rule})" in str(error)


def test_a_const_error_names_the_value_found() -> None:
    """'$.version: 1 was expected' did not say which version the file has."""
    doc = good_sidecar()
    doc["version"] = 99
    with pytest.raises(SchemaError, match=r"\$\.version: 1 was expected, got 99 \(rule: const\)"):
        validate("TensorSidecar", doc)


def test_required_error_names_the_missing_field() -> None:
    doc = good_sidecar()
    del doc["data_sha256"]
    with pytest.raises(SchemaError, match="'data_sha256' is a required property"):
        validate("TensorSidecar", doc)


@pytest.mark.parametrize(
    ("request_doc", "got"),
    [({"time": 1.0}, "neither"), ({"scenario": "np4", "world": {}}, "'scenario' and 'world'")],
)
def test_a_plan_request_needs_exactly_one_of_scenario_and_world(
    request_doc: dict, got: str
) -> None:
    """Neither used to read "'scenario' is a required property" (the else branch of the world's
    if), and both "'start' is a required property" (its then branch)."""
    expected = (
        f"PlanRequest: $: exactly one of 'scenario', 'world' is required, got {got} (rule: oneOf)"
    )
    with pytest.raises(SchemaError) as info:
        validate("PlanRequest", request_doc)
    assert str(info.value) == expected
    # The rules inside either choice still speak for themselves.
    with pytest.raises(SchemaError, match=r"'start' is a required property \(rule: required\)"):
        validate("PlanRequest", {"world": {"lower": [0, 0], "upper": [1, 1], "boxes": []}})


def test_validate_does_not_modify_the_document() -> None:
    doc = good_sidecar()
    before = copy.deepcopy(doc)
    validate("TensorSidecar", doc)
    assert doc == before


def test_dumps_and_loads_round_trip_and_reject_nan() -> None:
    text = dumps("TensorSidecar", good_sidecar(), indent=2)
    assert loads("TensorSidecar", text) == json.loads(text)
    with pytest.raises(SchemaError, match=r"\$: not valid JSON: NaN is not allowed") as info:
        loads("TensorSidecar", text.replace("0.2123", "NaN"))
    assert info.value.rule == "json"
    with pytest.raises(SchemaError, match="not valid JSON"):
        loads("TensorSidecar", "{")
    with pytest.raises(SchemaError, match=r"not valid JSON: the integer 1000.* too large"):
        loads("TensorSidecar", text.replace("0.2123", "1" + "0" * 400))
    with pytest.raises(SchemaError, match=r"\$.fuzzification.sigma: inf is not a finite number"):
        dumps(
            "TensorSidecar",
            {**good_sidecar(), "fuzzification": {"centres": [0, 0.5, 1], "sigma": float("inf")}},
        )
    assert issubclass(SchemaError, ValueError)


def test_a_huge_violating_value_is_shortened_in_the_message() -> None:
    """The value is shown short, and a size rule says the size and the limit: a world of 12 000
    boxes was quoted up to 400 characters, and the message never said that 10 000 is the most."""
    from lit_msgs_json.errors import SchemaError

    from lit_msgs_json import codec

    world = {"lower": [0.0] * 2000, "upper": [1.0] * 2000, "boxes": []}
    document = {"world": world, "start": [0.5] * 2000, "goal": [0.6] * 2000}
    with pytest.raises(SchemaError) as caught:
        codec.validate("PlanRequest", document)
    message = str(caught.value)
    assert message == (
        "PlanRequest: $.start: [0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, "
        "0.5, 0.5, 0... is too long (2000 items; at most 64) (rule: maxItems)"
    )
    box = {"lower": [0.1, 0.1], "upper": [0.2, 0.2]}
    world = {"lower": [-0.5, -0.5], "upper": [0.5, 0.5], "boxes": [box] * 10_001}
    with pytest.raises(SchemaError, match=r"^PlanRequest: \$\.world\.boxes: \[\{.{60,80} is too "
                       r"long \(10001 items; at most 10000\) \(rule: maxItems\)$"):  # fmt: skip
        codec.validate("PlanRequest", {"world": world, "start": [0, 0], "goal": [0.3, 0.3]})
    with pytest.raises(SchemaError, match=r"'' should be non-empty \(rule: minLength\)$"):
        codec.validate("PlanRequest", {"scenario": "np4", "request_id": ""})
    with pytest.raises(SchemaError, match=r'^PlanRequest: \$\.request_id: "(empty){15}e\.\.\. is too '
                       r"long \(1000 characters; at most \d+\)"):  # fmt: skip
        codec.validate("PlanRequest", {"scenario": "np4", "request_id": "empty" * 200})
    with pytest.raises(SchemaError, match=r'^PlanRequest: \$\.request_id: "日本日本'):
        codec.validate("PlanRequest", {"scenario": "np4", "request_id": "日本" * 200})
    # A NUL ended the id on /lit/path (header.frame_id), where verify then missed its path.
    for schema, fields in (("PlanRequest", {"scenario": "np4"}), ("CancelRequest", {})):
        for bad in ("\x00\n", "a\x00b", "tab\there", "\x85", "id\n"):  # "id\n": $ before \n
            with pytest.raises(
                SchemaError, match=r"\.request_id: .* holds a control character"
            ) as caught:
                codec.validate(schema, {**fields, "request_id": bad})
            assert str(caught.value).isprintable()  # shown escaped: not carried into logs
        codec.validate(schema, {**fields, "request_id": "ψ_K run #3 é"})
        # A lone surrogate (no control character; the envelopes refuse it as not Unicode text):
        # the compiled validator's regex raised UnicodeEncodeError on it, out of validate().
        codec.validate(schema, {**fields, "request_id": "\ud800"})


def test_prepare_builds_the_validators_ahead_and_names_unknown_schemas() -> None:
    from lit_msgs_json.errors import UnknownSchemaError

    from lit_msgs_json import codec, prepare

    codec._fast_envelope_validator.cache_clear()
    prepare(["DecideRequest", "lit_msgs_json/EpisodeEnd"])
    assert codec._fast_envelope_validator.cache_info().currsize == 2
    with pytest.raises(UnknownSchemaError, match="NoSuchMessage: .*no such schema"):
        prepare(["NoSuchMessage"])


def test_json_nested_too_deeply_is_a_schema_error() -> None:
    """A sidecar of 100 000 nested arrays raised RecursionError (a traceback in lit tensors)."""
    with pytest.raises(SchemaError, match="nested too deeply"):
        loads("lit_msgs_json/TensorSidecar", "[" * 100_000)


def test_a_name_given_twice_is_a_schema_error() -> None:
    """json.loads keeps a repeated name's last value: a sidecar or run record saying two things
    was read as the second (envelopes refuse it)."""
    with pytest.raises(SchemaError, match=r'the name "output" is given twice in one object'):
        loads("lit_msgs_json/TensorSidecar", '{"a": {"output": 1, "output": 2}}')

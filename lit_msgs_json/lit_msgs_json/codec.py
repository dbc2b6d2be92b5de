"""Load the shipped JSON Schemas and validate, encode and decode documents against them.

Schemas live in ``lit_msgs_json/schemas/<Name>.schema.json`` and are found with
``importlib.resources``, so they work from a source tree, a wheel or a ROS install alike.
Validation uses JSON Schema draft 2020-12 and additionally rejects non-finite numbers, which JSON
cannot carry and which numeric bounds do not catch (every comparison with NaN is false). A schema
may ``$ref`` another shipped schema by its ``$id`` (``BenchSummary`` holds ``BenchRun`` records).

Two validators: ``jsonschema_rs`` (compiled, about 2 µs for a decision request) answers "valid?"
on the hot path, for documents made only of JSON's own types (what ``json.loads`` returns); the
reference ``jsonschema`` validator decides everything else and every document the fast one does
not accept, and explains the violation. So errors and the accepted language are jsonschema's: the
fast path can only ever be stricter, never more lenient (tests check both agree).
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterable, Iterator
from functools import cache
from importlib.resources import files
from typing import Any

import jsonschema_rs
from jsonschema import Draft202012Validator
from jsonschema.exceptions import best_match
from referencing import Registry, Resource

from lit_msgs_json.errors import SchemaError, UnknownSchemaError

SCHEMA_SUFFIX = ".schema.json"
"""File-name suffix of every schema."""


def schema_names() -> list[str]:
    """Names of all shipped schemas, sorted (``TensorSidecar``, ...)."""
    directory = files("lit_msgs_json") / "schemas"
    return sorted(
        entry.name.removesuffix(SCHEMA_SUFFIX)
        for entry in directory.iterdir()
        if entry.name.endswith(SCHEMA_SUFFIX)
    )


def load_schema(name: str) -> dict[str, Any]:
    """The schema called ``name`` (``TensorSidecar`` or ``lit_msgs_json/TensorSidecar``) as a dict.

    Raises:
        UnknownSchemaError: no schema of that name ships with the package.
    """
    return _validator(name.removeprefix("lit_msgs_json/")).schema  # type: ignore[no-any-return]


def validate(name: str, obj: object, *, plain: bool | None = None) -> None:
    """Check ``obj`` against schema ``name``.

    Args:
        name: the schema.
        obj: the document.
        plain: True when the caller knows ``obj`` is plain JSON (what ``json.loads`` returns, all
            floats finite), which spares walking it to find out; None: walk it.

    Raises:
        SchemaError: the most relevant violation, naming its JSON path and the broken rule.
        UnknownSchemaError: no schema of that name ships with the package.
    """
    short = name.removeprefix("lit_msgs_json/")
    validator = _validator(short)
    if plain or (plain is None and plain_json(obj)):
        try:
            if _fast_validator(short).is_valid(obj):
                _check_order(short, obj)
                return
        except UnicodeEncodeError:  # a lone surrogate the (Rust) regex of a pattern cannot take
            pass  # the Python validator below can
    else:
        for json_path, value in _non_finite_numbers(obj, "$"):
            raise SchemaError(short, json_path, "finite", f"{value!r} is not a finite number")
    errors = list(validator.iter_errors(obj))
    # A choice of exactly one field (PlanRequest: a scenario or a world) comes first: the rules that
    # depend on the choice would otherwise name a field of one side ('scenario' is required).
    error = next((e for e in errors if _exclusive_fields(e) is not None), None) or best_match(
        errors
    )
    if error is not None:
        message = error.message
        exclusive = _exclusive_fields(error)
        if exclusive is not None:
            given = [name for name in exclusive if name in error.instance]
            message = f"exactly one of {', '.join(map(repr, exclusive))} is required, got " + (
                "neither" if not given else " and ".join(map(repr, given))
            )
        if error.validator == "const":  # jsonschema names the expected value only
            message += f", got {shown(error.instance)}"
        if error.validator == "not" and error.validator_value == {"pattern": CONTROL_CHARACTER}:
            message = f"{shown(error.instance)} holds a control character (NUL, newline, ...)"
        message = _short(message, error.instance)
        # jsonschema names neither the size nor the limit (but for "should be non-empty" and
        # "is expected to be empty", the rules min 1 and max 0)
        at_most = str(error.validator).startswith("max")
        if error.validator in _SIZE_RULES and error.validator_value != (0 if at_most else 1):
            bound = "at most" if at_most else "at least"
            message += (
                f" ({len(error.instance)} {_SIZE_RULES[str(error.validator)]}; {bound} "
                f"{error.validator_value})"
            )
        raise SchemaError(short, error.json_path, str(error.validator), message)
    _check_order(short, obj)


def _check_order(short: str, obj: Any) -> None:
    """The rules JSON Schema cannot say, for a document that passed its schema: a BenchRun's
    improvements in time order (its schema describes them so; the curves and tables of
    ``lit replay bench`` are computed on that order, and one record out of it stopped the
    replay).

    Raises:
        SchemaError: rule ``order``, naming the first item out of order.
    """
    if short != "BenchRun":
        return
    improvements = obj.get("improvements") or []
    for index in range(1, len(improvements)):
        time, before = improvements[index][0], improvements[index - 1][0]
        if time < before:
            raise SchemaError(
                short,
                f"$.improvements[{index}]",
                "order",
                f"time {time!r} is before the previous improvement's {before!r}: improvements "
                "must be in time order",
            )


def _exclusive_fields(error: Any) -> list[str] | None:
    """The field names of a violated ``oneOf`` whose alternatives each require one field (exactly
    one of them must be present), else None."""
    alternatives = error.validator_value if error.validator == "oneOf" else None
    if not isinstance(alternatives, list) or not isinstance(error.instance, dict):
        return None
    names = []
    for alternative in alternatives:
        required = alternative.get("required") if isinstance(alternative, dict) else None
        if not isinstance(required, list) or len(required) != 1 or set(alternative) != {"required"}:
            return None
        names.append(required[0])
    return names


_SIZE_RULES = {
    "maxItems": "items",
    "minItems": "items",
    "maxLength": "characters",
    "minLength": "characters",
    "maxProperties": "fields",
    "minProperties": "fields",
}
"""The size rules, and what they count."""


def _short(message: str, instance: object) -> str:
    """jsonschema's ``message`` with the value it begins with (its Python repr) shown short: a
    world of 12 000 boxes was quoted whole in its "too long" error."""
    text = repr(instance)
    if len(text) > 80 and message.startswith(text):
        return shown(instance) + message[len(text) :]
    return message


CONTROL_ESCAPES = {
    code: f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}"
    for code in (
        *range(0x20),
        *range(0x7F, 0xA0),
        0x2028,
        0x2029,
        *range(0x202A, 0x202F),
        *range(0x2066, 0x206A),
    )
    if code != ord("\t")
}
"""Control characters (C0 but the tab, DEL, C1), the Unicode line and paragraph separators and
the bidirectional overrides as ``\\x0a``, ``\\x1b``, ``\\u202e``, ...: text from a client (a
request id, a source) split one log line into forged ones, coloured them with ANSI escapes,
cut them at a NUL, or could reorder what a terminal shows."""


def shown(value: object) -> str:
    """``value`` as JSON, cut short when long (the message may otherwise quote a whole file)."""
    text = json.dumps(value, default=repr, ensure_ascii=False)  # NaN as NaN (allow_nan)
    # JSON escapes C0 controls only: DEL, C1 controls, separators and lone surrogates are
    # escaped as the nodes' loggers escape them (a message quoting what it refuses carried it
    # into logs).
    from lit_msgs_json.envelope import unicode_text

    text = unicode_text(text).translate(CONTROL_ESCAPES)
    return text if len(text) <= 80 else text[:77] + "..."


def valid_envelope(name: str, obj: object) -> bool:
    """Whether ``obj``, plain JSON, is a valid envelope whose payload satisfies schema ``name``
    (one compiled check of the whole message). False says nothing about why: the caller then
    checks the envelope and the payload separately, which explains the violation.

    Raises:
        UnknownSchemaError: no schema of that name ships with the package.
    """
    short = name.removeprefix("lit_msgs_json/")
    try:
        if not _fast_envelope_validator(short).is_valid(obj):
            return False
    except UnicodeEncodeError:  # a lone surrogate where a pattern applies: not known valid here
        return False
    try:
        _check_order(short, obj["payload"])  # type: ignore[index]
    except SchemaError:
        return False
    return True


def prepare(names: Iterable[str]) -> None:
    """Build the validators of schemas ``names`` now (each is otherwise built at its first use,
    which takes about 10 ms): a node calls this at start-up so that its first request is
    answered as fast as the later ones.

    Raises:
        UnknownSchemaError: no schema of that name ships with the package.
    """
    for name in names:
        short = name.removeprefix("lit_msgs_json/")
        _fast_validator(short)
        _fast_envelope_validator(short)


def dumps(name: str, obj: object, **kwargs: Any) -> str:
    """Validate ``obj`` against schema ``name`` and serialise it as strict JSON (no NaN)."""
    validate(name, obj)
    return json.dumps(obj, allow_nan=False, **kwargs)


def loads(name: str, text: str | bytes) -> Any:
    """Parse strict JSON (``NaN``/``Infinity`` rejected) and validate it against schema ``name``.

    Raises:
        SchemaError: the text is not JSON (rule ``json``) or violates the schema.
    """
    try:
        obj = json.loads(text, parse_constant=reject_constant, parse_int=_double_int)
    except (ValueError, TypeError) as exc:  # JSONDecodeError and UnicodeDecodeError are ValueErrors
        raise SchemaError(
            name.removeprefix("lit_msgs_json/"), "$", "json", f"not valid JSON: {exc}"
        ) from exc
    except RecursionError:  # arrays or objects nested thousands deep
        raise SchemaError(
            name.removeprefix("lit_msgs_json/"), "$", "json", "not usable JSON: nested too deeply"
        ) from None
    # json.loads keeps a repeated name's last value: refused, as envelopes refuse it.
    data = text if isinstance(text, bytes) else text.encode("utf-8", "surrogatepass")
    if len(NAME_END.findall(data)) != names_in(obj):
        twice = name_given_twice(text)
        if twice is not None:
            raise SchemaError(
                name.removeprefix("lit_msgs_json/"),
                twice[1],
                "json",
                f"not usable JSON: the name {shown(twice[0])} is given twice in one object",
            )
    try:
        validate(name, obj)
    except RecursionError:
        raise SchemaError(
            name.removeprefix("lit_msgs_json/"), "$", "json", "not usable JSON: nested too deeply"
        ) from None
    return obj


@cache
def _validator(name: str) -> Draft202012Validator:
    schema = _schema(name)
    Draft202012Validator.check_schema(schema)
    return Draft202012Validator(schema, registry=_registry())


@cache
def _fast_validator(name: str) -> Any:
    """The compiled validator of ``name`` (after :func:`_validator` has checked the schema)."""
    return jsonschema_rs.Draft202012Validator(_schema(name), registry=_fast_registry())


@cache
def _fast_envelope_validator(name: str) -> Any:
    """The compiled validator of an envelope carrying a ``name`` payload."""
    envelope, payload = _validator("Envelope").schema, _validator(name).schema
    schema = {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "allOf": [{"$ref": envelope["$id"]}],
        "properties": {"payload": {"$ref": payload["$id"]}},
    }
    return jsonschema_rs.Draft202012Validator(schema, registry=_fast_registry())


@cache
def _fast_registry() -> Any:
    schemas = [_schema(name) for name in schema_names()]
    return jsonschema_rs.Registry([(s["$id"], s) for s in schemas if "$id" in s])


@cache
def _schema(name: str) -> dict[str, Any]:
    resource = files("lit_msgs_json") / "schemas" / f"{name}{SCHEMA_SUFFIX}"
    if "/" in name or not resource.is_file():
        raise UnknownSchemaError(name, schema_names())
    return json.loads(resource.read_text(encoding="utf-8"))  # type: ignore[no-any-return]


@cache
def _registry() -> Registry:
    """Every shipped schema under its ``$id``, so that schemas can refer to each other."""
    schemas = [_schema(name) for name in schema_names()]
    return Registry().with_resources(
        (schema["$id"], Resource.from_contents(schema)) for schema in schemas if "$id" in schema
    )


def plain_json(obj: object) -> bool:
    """Whether ``obj`` is built only of what ``json.loads`` returns (dict with str keys, list, str,
    int, bool, None) and finite floats, exact types only. Only such documents take the compiled
    validator (it treats a tuple as an array and rejects numpy scalars with a ValueError, where
    jsonschema, the reference, rejects the first and explains the second) and orjson's encoder
    (which writes NaN as null)."""
    kind = type(obj)
    if kind is dict:
        for key, value in obj.items():  # type: ignore[attr-defined]
            if type(key) is not str:
                return False
            kind = type(value)
            if kind is float:
                if value - value != 0.0:  # NaN and the infinities give NaN
                    return False
            elif not (
                kind is str or kind is int or kind is bool or value is None or plain_json(value)
            ):
                return False
        return True
    if kind is list:
        for value in obj:  # type: ignore[attr-defined]
            kind = type(value)
            if kind is float:
                if value - value != 0.0:
                    return False
            elif not (
                kind is str or kind is int or kind is bool or value is None or plain_json(value)
            ):
                return False
        return True
    if kind is float:
        return math.isfinite(obj)  # type: ignore[arg-type]
    return kind is str or kind is int or kind is bool or obj is None


def _non_finite_numbers(obj: object, path: str) -> Iterator[tuple[str, float]]:
    """JSON paths (in jsonschema's ``json_path`` spelling) of NaN and infinite floats in ``obj``."""
    if isinstance(obj, float) and not math.isfinite(obj):
        yield path, obj
    elif isinstance(obj, dict):
        for key, value in obj.items():
            yield from _non_finite_numbers(value, f"{path}.{key}")
    elif isinstance(obj, (list, tuple)):
        for index, value in enumerate(obj):
            yield from _non_finite_numbers(value, f"{path}[{index}]")


CONTROL_CHARACTER = "[\\u0000-\\u001f\\u007f-\\u009f]"
"""A C0 or C1 control character: the schemas refuse one in an id that goes into ROS headers and
log lines (``request_id``: ``"not": {"pattern": ...}``; a NUL ended a ``frame_id`` there). A
pattern of what is allowed, ``^[^...]+$``, let a final newline through: ``$`` matches before it."""


def reject_constant(constant: str) -> float:
    """``json.loads``'s ``parse_constant``: NaN and Infinity are not JSON (RFC 8259)."""
    raise ValueError(f"{constant} is not allowed in JSON")


def beyond_double(spelling: str, value: int) -> bool:
    """Whether a JSON integer (its ``spelling`` and ``value``) is too large for a double, as 1e400
    is (a node that used it as a number ended with OverflowError)."""
    if len(spelling) <= 300:  # below 1e300: a double holds it
        return False
    try:
        float(value)
    except OverflowError:
        return True
    return False


def _double_int(spelling: str) -> int:
    """An integer a double can hold: ``json.loads``'s ``parse_int`` of :func:`loads`."""
    value = int(spelling)
    if beyond_double(spelling, value):
        raise ValueError(f"the integer {spelling[:20]}... is too large for a double")
    return value


NAME_END = re.compile(rb'"[ \t\n\r]*:')
"""The end of an object's name: its closing quote and the colon. Outside strings it occurs once
per name; inside a string (an escaped quote, or a string's opening quote, followed by a colon)
it adds to the count, so the count is at least the number of names in the text."""


def names_in(obj: object) -> int:
    """The names of the objects in ``obj``, at most: an array whose first item is no array or
    object is not searched (an object after a number, which no schema allows, is left out and
    sends the text to :func:`name_given_twice`). A name given twice is kept once."""
    # Exact types (both parsers build plain dicts and lists): three times faster than
    # isinstance with a generator, on the decide path's every message.
    count, pending = 0, [obj]
    while pending:
        item = pending.pop()
        if type(item) is dict:
            count += len(item)
            for value in item.values():
                if type(value) is dict or type(value) is list:
                    pending.append(value)
        elif type(item) is list and item and (type(item[0]) is dict or type(item[0]) is list):
            pending.extend(item)
    return count


def name_given_twice(text: str | bytes) -> tuple[str, str] | None:
    """A name given twice in one object of the JSON ``text`` and that object's JSON path
    (``$.payload.world``); None when there is none. Of the objects with one, the first the
    parser completes (an inner one before the object around it) that the document keeps: an
    object dropped by a name given twice around it is no part of the document."""
    found: list[tuple[str, dict[str, Any]]] = []

    def pairs(items: list[tuple[str, Any]]) -> dict[str, Any]:
        made = dict(items)
        if len(made) < len(items):  # linear: an object of 100 000 names is within 1 MiB
            seen: set[str] = set()
            for name, _ in items:
                if name in seen:
                    found.append((name, made))
                    break
                seen.add(name)
        return made

    document = json.loads(text, object_pairs_hook=pairs, parse_constant=reject_constant)
    if not found:
        return None
    paths: dict[int, str] = {}
    stack: list[tuple[object, str]] = [(document, "$")]
    while stack:  # the objects themselves (by identity), not equal ones elsewhere
        value, where = stack.pop()
        if isinstance(value, dict):
            paths[id(value)] = where
            stack.extend((item, f"{where}.{key}") for key, item in value.items())
        elif isinstance(value, list):
            stack.extend((item, f"{where}[{index}]") for index, item in enumerate(value))
    # The outermost object with a name twice is always kept (the root is), so one is found.
    return next((name, paths[id(made)]) for name, made in found if id(made) in paths)

"""The versioned envelope every LIT* message travels in, and its encoder and decoder.

On the wire a message is one JSON text of at most ``MAX_MESSAGE_BYTES`` UTF-8 bytes::

    {"schema": "lit_msgs_json/DecideRequest", "version": 3, "seq": 7,
     "stamp_ns": 1715240100000000000, "source": "planner/host/4711",
     "run_id": "train-2026-05-09", "payload": {...}}

``payload`` follows the schema named by ``schema`` in the version ``MESSAGE_VERSIONS`` gives.
A sender wraps its payloads with a :class:`Publisher` (one per sender, so that ``seq`` counts that
sender's messages); a receiver calls :func:`decode`, which either returns a validated
:class:`Message` or raises :class:`MessageError`, whose :meth:`MessageError.to_payload` is the
``Error`` payload to answer with. Typical use::

    publisher = Publisher("learner/host/42", run_id)
    try:
        request = decode(text, accept="DecideRequest")
    except MessageError as exc:
        reply = publisher.error(exc)
    else:
        reply = publisher.encode("DecideResponse", answer(request.payload))
"""

from __future__ import annotations

import functools
import json
import math
import re
import threading
import time
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import orjson

from lit_msgs_json.codec import (
    NAME_END,
    beyond_double,
    name_given_twice,
    names_in,
    plain_json,
    reject_constant,
    valid_envelope,
    validate,
)
from lit_msgs_json.errors import SchemaError

MAX_MESSAGE_BYTES = 1_048_576
"""Largest message text in UTF-8 bytes; checked before the text is parsed."""

MAX_NESTING = 64
"""Deepest nesting of arrays and objects a message may have (the schemas need far less)."""

MESSAGE_VERSIONS: dict[str, int] = {
    "DecideRequest": 3,
    "DecideResponse": 1,
    "EpisodeEnd": 2,
    "EpisodeEndResponse": 1,
    "PlanRequest": 1,
    "PlanResponse": 2,
    "CancelRequest": 1,
    "CancelResponse": 1,
    "Observation": 1,
    "Decision": 1,
    "SolutionUpdate": 1,
    "EpisodeSummary": 3,
    "LearnerStats": 1,
    "Error": 1,
}
"""Current version of every message schema, by short name: what a :class:`Publisher` sends.
A message's version rises whenever its payload schema changes, added optional fields included,
so that a receiver built before the change rejects the message with a ``version`` error naming
both versions instead of a ``payload`` error about a field it does not know. File formats
(``TensorSidecar``, ``BenchRun``, ``BenchSummary``) and ``Envelope`` itself are not messages."""

OLDER_VERSIONS: dict[str, dict[int, tuple[str, ...]]] = {
    # version 2 (2026-11-30): the planner's fallback marks, for the learner's pairing; version 3
    # (2026-12-04): probes, answered and never trained on (lit call decide)
    "DecideRequest": {1: ("after_fallback", "probe"), 2: ("probe",)},
    "EpisodeEnd": {1: ("fallback_agents",)},
    # version 2 (2026-12-02): the world of a custom scenario, for lit replay verify; version 3
    # (2026-12-03): a training query's final features, for lit replay tensors
    "EpisodeSummary": {1: ("world", "final_features"), 2: ("final_features",)},
    # version 2 (2026-12-06): the effort to the first solution
    "PlanResponse": {1: ("checks_init", "iteration_init")},
}
"""Older versions a receiver still decodes, by short name: for each, the payload fields that
version did not have. Such a message is checked against the current schema and must not carry
those fields (a ``payload`` error names the field); its :attr:`Message.version` is the version
sent, and the missing fields take their schema defaults."""


def accepted_versions(name: str) -> tuple[int, ...]:
    """The versions of message ``name`` (short name) that :func:`decode` takes, oldest first."""
    return (*sorted(OLDER_VERSIONS.get(name, {})), MESSAGE_VERSIONS[name])


ERROR_CODES: tuple[str, ...] = (
    "json",
    "oversize",
    "envelope",
    "unknown-schema",
    "unexpected-schema",
    "version",
    "payload",
    "invalid-request",
    "busy",
    "unavailable",
    "internal",
)
"""The values of ``Error.code`` (and of :attr:`MessageError.code`)."""

SCHEMA_PREFIX = "lit_msgs_json/"
"""Prefix of the envelope's ``schema`` field."""

_MAX_SEQ = 2**63 - 1
_DIGITS_AS_ZERO = bytes.maketrans(b"123456789", b"000000000")
_UNPARSED = object()
_SCHEMA_PATTERN = re.compile(r"lit_msgs_json/([A-Za-z][A-Za-z0-9]{0,127})")
_MAX_DETAIL = 400
_MAX_MESSAGE = 4096
_MAX_FIELD = 1024
_MAX_RULE = 64


class MessageError(ValueError):
    """One rejected message: why, where in the envelope, and which request it was.

    ``str(error)`` is one line for a human naming the field and the rule, e.g.
    ``DecideRequest seq 7 rejected (payload) at $.payload.rho_global: 1.5 is greater than the
    maximum of 1 (rule: maximum)``.
    """

    def __init__(
        self,
        code: str,
        detail: str,
        *,
        field: str | None = None,
        rule: str | None = None,
        request_schema: str | None = None,
        request_seq: int | None = None,
    ) -> None:
        if code not in ERROR_CODES:
            raise ValueError(f"unknown error code {code!r}; expected one of {ERROR_CODES}")
        self.code = code
        """One of :data:`ERROR_CODES`, e.g. ``payload``."""
        self.detail = _one_line(detail)
        """What is wrong, without the field and rule."""
        self.field = field
        """JSON path relative to the envelope, e.g. ``$.payload.rho_global``; None if none."""
        self.rule = rule
        """Broken rule: a JSON Schema keyword (``minimum``, ``required``, ...) or ``finite``,
        ``json``, ``max-bytes``, ``max-depth``, ``version``, ``schema``, or one of the nodes'
        own (``valid-state``, ``litstar-only``, ``order``: an episode's messages went back);
        None if none."""
        self.request_schema = request_schema
        """Short name of the schema the message claimed, when it was readable."""
        self.request_seq = request_seq
        """``seq`` of the message, when it was readable."""
        subject = request_schema or "message"
        if request_seq is not None:
            subject += f" seq {request_seq}"
        where = f" at {field}" if field else ""
        because = f" (rule: {rule})" if rule else ""
        super().__init__(f"{subject} rejected ({code}){where}: {self.detail}{because}")

    def __reduce__(self) -> tuple[Any, ...]:
        """Pickle support (the keyword-only arguments need it)."""
        return (_rebuild_error, (self.code, self.detail, self._keywords()))

    def to_payload(self) -> dict[str, Any]:
        """The ``Error`` payload describing this rejection (long strings clipped to fit)."""
        return {
            "code": self.code,
            "message": _clip(str(self), _MAX_MESSAGE),
            "field": None if self.field is None else _clip(self.field, _MAX_FIELD),
            "rule": None if self.rule is None else _clip(self.rule, _MAX_RULE),
            "request_schema": self.request_schema,
            "request_seq": self.request_seq,
        }

    def _keywords(self) -> dict[str, Any]:
        return {
            "field": self.field,
            "rule": self.rule,
            "request_schema": self.request_schema,
            "request_seq": self.request_seq,
        }


def _rebuild_error(code: str, detail: str, keywords: dict[str, Any]) -> MessageError:
    return MessageError(code, detail, **keywords)


@dataclass(frozen=True)
class Message:
    """A decoded envelope whose payload satisfies its schema."""

    name: str
    """Short schema name, e.g. ``DecideRequest``."""
    version: int
    """Schema version as sent: ``MESSAGE_VERSIONS[name]`` or one of ``OLDER_VERSIONS[name]``."""
    seq: int
    """The sender's sequence number."""
    stamp_ns: int
    """Send time, ns since the Unix epoch."""
    source: str
    """The sender."""
    run_id: str
    """The sender's run."""
    payload: dict[str, Any]
    """The message itself."""

    @property
    def schema(self) -> str:
        """Full schema name as in the envelope, e.g. ``lit_msgs_json/DecideRequest``."""
        return SCHEMA_PREFIX + self.name


class Publisher:
    """Wraps payloads of one publisher into envelopes; seq starts at 0 and rises by exactly 1 per
    encode() call (thread-safe, use a lock).

    :meth:`envelope` also takes a seq; a call that raises takes none.
    """

    def __init__(self, source: str, run_id: str) -> None:
        """A publisher called ``source`` (1..256 characters) in run ``run_id`` (1..128).

        Raises:
            MessageError: code ``envelope``, ``source`` or ``run_id`` is not allowed.
        """
        _check_envelope(
            {
                "schema": SCHEMA_PREFIX + "Error",
                "version": 1,
                "seq": 0,
                "stamp_ns": 0,
                "source": source,
                "run_id": run_id,
                "payload": {},
            },
            None,
            None,
        )
        self._source = source
        self._run_id = run_id
        self._lock = threading.Lock()
        self._next_seq = 0
        self._heads: dict[str, tuple[str, str]] = {}

    @property
    def source(self) -> str:
        """The envelope's ``source``."""
        return self._source

    @property
    def run_id(self) -> str:
        """The envelope's ``run_id``."""
        return self._run_id

    @property
    def next_seq(self) -> int:
        """The ``seq`` the next successful call will use."""
        with self._lock:
            return self._next_seq

    def envelope(
        self, name: str, payload: dict[str, Any], *, stamp_ns: int | None = None
    ) -> dict[str, Any]:
        """The envelope (a dict holding ``payload`` itself, not a copy) with the next ``seq``.

        ``name`` is a short (``DecideRequest``) or full (``lit_msgs_json/DecideRequest``) name;
        ``stamp_ns`` defaults to now.

        Raises:
            MessageError: ``unknown-schema`` (``name`` is not a message), ``payload`` (the payload
                violates its schema; ``field`` starts with ``$.payload``) or ``envelope`` (a bad
                ``stamp_ns``). No seq is taken then.
        """
        short, stamp, _ = self._check(name, payload, stamp_ns)
        with self._lock:
            seq = self._next_seq
            self._next_seq += 1
        return self._wrap(short, seq, stamp, payload)

    def encode(self, name: str, payload: dict[str, Any], *, stamp_ns: int | None = None) -> str:
        """The envelope as compact strict JSON; like :meth:`envelope`, a seq only on success.

        Raises:
            MessageError: as :meth:`envelope`, or ``oversize`` when the text would be longer than
                ``MAX_MESSAGE_BYTES``.
        """
        short, stamp, plain = self._check(name, payload, stamp_ns)
        payload_text = None
        if plain:  # orjson: the same document, written faster, non-ASCII characters unescaped
            try:
                data = orjson.dumps(payload)
            except orjson.JSONEncodeError:  # a lone surrogate, an integer beyond 64 bits
                pass
            else:
                payload_text = data.decode("utf-8")
                non_ascii_bytes = len(data) - len(payload_text)
        if payload_text is None:  # numpy scalars, tuples, ...: the standard encoder knows them
            payload_text = json.dumps(payload, allow_nan=False, separators=(",", ":"))
            non_ascii_bytes = 0  # json.dumps escapes them
        schema, sender = self._head_parts(short)
        with self._lock:
            seq = self._next_seq
            # json.loads gives the envelope() document back (tested); head and sender from cache.
            text = f'{schema}{seq},"stamp_ns":{int(stamp)}{sender}{payload_text}}}'
            size = len(text) + non_ascii_bytes  # the head is json.dumps's: ASCII only
            if size > MAX_MESSAGE_BYTES:
                raise _oversize(size, short, None)
            self._next_seq += 1
        return text

    def _head_parts(self, short: str) -> tuple[str, str]:
        """The envelope text before ``seq`` and from ``source`` to the payload's colon."""
        parts = self._heads.get(short)
        if parts is None:
            head = json.dumps(self._wrap(short, 0, 0, None), separators=(",", ":"))
            before_seq, after_stamp = head.split(',"seq":0,"stamp_ns":0', 1)
            parts = (before_seq + ',"seq":', after_stamp.removesuffix("null}"))
            self._heads[short] = parts
        return parts

    def error(self, exc: MessageError | Exception, **overrides: Any) -> str:
        """Encode an ``Error`` payload describing ``exc``; ``overrides`` replace its fields.

        An exception other than :class:`MessageError` becomes code ``internal`` with its message.
        """
        if isinstance(exc, MessageError):
            payload = exc.to_payload()
        else:
            payload = {
                "code": "internal",
                "message": _clip(_one_line(f"{type(exc).__name__}: {exc}"), _MAX_MESSAGE),
                "field": None,
                "rule": None,
                "request_schema": None,
                "request_seq": None,
            }
        payload.update(overrides)
        # An exception's text may hold a lone surrogate (a file name that is not UTF-8, as
        # os.fsdecode gives it): escaped, or every receiver would refuse the Error.
        for key in ("message", "field"):
            if isinstance(payload.get(key), str):
                payload[key] = unicode_text(payload[key])
        return self.encode("Error", payload)

    def _check(self, name: str, payload: object, stamp_ns: int | None) -> tuple[str, int, bool]:
        """(short name, stamp, whether the payload is plain JSON) of a valid message."""
        short = name.removeprefix(SCHEMA_PREFIX)
        if short not in MESSAGE_VERSIONS:
            raise _unknown(short, _short_name(SCHEMA_PREFIX + short), None)
        if stamp_ns is None:
            # source and run_id were checked when the publisher was made; seq and a stamp of now
            # are ours and always fit: the envelope needs no check (the hot path of every send).
            stamp = time.time_ns()
        else:
            stamp = stamp_ns
            _check_envelope(self._wrap(short, 0, stamp, {}), short, None)
        try:
            plain = plain_json(payload)
        except RecursionError:  # nested too deeply: the reference explains (max-depth)
            plain = False
        _check_payload(short, payload, None, plain=plain)
        return short, stamp, plain

    def _wrap(self, short: str, seq: int, stamp_ns: int, payload: object) -> dict[str, Any]:
        return {
            "schema": SCHEMA_PREFIX + short,
            "version": MESSAGE_VERSIONS[short],
            "seq": seq,
            "stamp_ns": stamp_ns,
            "source": self._source,
            "run_id": self._run_id,
            "payload": payload,
        }


def decode(text: str | bytes, accept: str | Iterable[str] | None = None) -> Message:
    """Parse and validate one message text.

    ``accept`` names the messages the caller takes (short or full names); None takes all.
    The checks run in this order, the first failure raising :class:`MessageError` with code
    ``oversize``, ``json``, ``envelope``, ``unknown-schema``, ``unexpected-schema``, ``version``,
    ``payload``; ``request_schema`` and ``request_seq`` are set whenever they could be read.
    No other exception escapes for any ``text``.

    Raises:
        MessageError: the message is rejected.
        ValueError: ``accept`` names something that is not a message schema (a caller's bug).
    """
    accepted = _accepted(accept)
    try:
        return _decode(text, accepted)
    except MessageError:
        raise
    except RecursionError:
        raise MessageError(
            "json", "nested too deeply to process", field="$", rule="max-depth"
        ) from None
    except Exception as exc:  # a bug here must still be answerable
        raise MessageError(
            "internal", f"decoding failed: {type(exc).__name__}: {exc}", field=None
        ) from exc


def _decode(text: object, accepted: frozenset[str] | None) -> Message:
    # 1. size, before anything else touches the text
    not_utf8: str | None = None
    data = b""  # the text's UTF-8 bytes (when it is not too long)
    if isinstance(text, (bytes, bytearray, memoryview)):
        data = bytes(text)
        size = len(data)
        if size <= MAX_MESSAGE_BYTES:
            try:
                text = data.decode("utf-8")
            except UnicodeDecodeError as exc:
                not_utf8 = str(exc)
    elif isinstance(text, str):
        if len(text) > MAX_MESSAGE_BYTES:  # UTF-8 needs at least a byte per character
            size = len(text)
        else:
            try:
                data = text.encode("utf-8")
                size = len(data)
            except UnicodeEncodeError as exc:  # lone surrogates
                size = len(text.encode("utf-8", "surrogatepass"))
                not_utf8 = str(exc)
    else:
        raise MessageError(
            "json", f"expected str or bytes, got {type(text).__name__}", field="$", rule="json"
        )
    if size > MAX_MESSAGE_BYTES:
        raise _oversize(size, None, None)

    # 2. strict UTF-8 JSON
    if not_utf8 is not None:
        raise MessageError("json", f"not UTF-8: {not_utf8}", field="$", rule="json")
    # Fewer brackets than the nesting limit cannot nest deeper than it.
    brackets = data.count(b"{") + data.count(b"[")
    # Parsed once: by orjson where it builds the same document as the standard parser (it
    # refuses every text the standard parser refuses here, and some it accepts, such as lone
    # surrogates and numbers too large for a double; the only document it builds differently
    # has an integer outside 64 bits, a float then, which _long_digits keeps off it), else by the
    # standard parser, which explains what is wrong.
    overflowed: list[str] = []
    obj: Any = _UNPARSED
    if brackets <= MAX_NESTING and not _long_digits(data):
        try:
            obj = orjson.loads(data)
        except orjson.JSONDecodeError:
            pass
    by_standard_parser = obj is _UNPARSED
    if by_standard_parser:

        def parse_float(spelling: str) -> float:
            value = float(spelling)
            if math.isinf(value):  # a number too large for a double
                overflowed.append(spelling)
            return value

        def parse_int(spelling: str) -> int | float:
            value = int(spelling)
            if beyond_double(spelling, value):  # then checked as 1e400 is
                overflowed.append(spelling)
                return math.inf if value > 0 else -math.inf
            return value

        try:
            obj = json.loads(
                text,  # type: ignore[arg-type]
                parse_constant=reject_constant,
                parse_float=parse_float,
                parse_int=parse_int,
            )
        except RecursionError:
            raise MessageError(
                "json", "not valid JSON: nested too deeply", field="$", rule="max-depth"
            ) from None
        except ValueError as exc:  # JSONDecodeError
            raise MessageError("json", f"not valid JSON: {exc}", field="$", rule="json") from None
    # A \u escape of a lone UTF-16 surrogate parses to a str that is not Unicode text: I-JSON
    # (RFC 7493) refuses it, and the nodes' loggers could not take it (a request_id of
    # "\ud800" stopped the planner node's worker thread, and its executor when it was busy).
    # orjson refuses such escapes: only the standard parser's documents can hold one, and
    # orjson's encoder (C) tells whether one does before the walk names it.
    if by_standard_parser and b"\\u" in data and _SURROGATE_ESCAPE.search(data):
        try:
            orjson.dumps(obj)
            found = None
        except orjson.JSONEncodeError:  # a lone surrogate, or an integer beyond 64 bits
            found = _lone_surrogate(obj, "$")
        if found is not None:
            where, what = found
            claimed, seq = _claimed(obj)
            raise MessageError(
                "json",
                f"{what} holds a \\u escape of a lone UTF-16 surrogate (D800-DFFF without its "
                "pair), which is not Unicode text",
                field=_clip(where, 1024),
                rule="json",
                request_schema=claimed,
                request_seq=seq,
            )
    # I-JSON (RFC 7493) also forbids an object with a name twice. Both parsers keep the last
    # one, so a message with two request_ids could be logged as one and planned as the other.
    if len(NAME_END.findall(data)) != names_in(obj):
        twice = name_given_twice(text)  # type: ignore[arg-type]
        if twice is not None:
            name, where = twice
            claimed, seq = _claimed(obj)
            raise MessageError(
                "json",
                f"the object at {_clip(where, 200)} has the name {_clip(repr(name), 200)} twice "
                "(I-JSON: names are unique)",
                field=_clip(where, 1024),
                rule="json",
                request_schema=claimed,
                request_seq=seq,
            )
    # The usual case, a valid message: one compiled check of the whole document. Anything else
    # takes the steps below, which find the first problem in the documented order.
    if not overflowed and brackets <= MAX_NESTING:
        message = _valid_message(obj, accepted)
        if message is not None:
            return message
    if brackets > MAX_NESTING and _nesting(obj) > MAX_NESTING:
        raise MessageError(
            "json",
            f"nested deeper than {MAX_NESTING} levels of arrays and objects",
            field="$",
            rule="max-depth",
        )

    # 3. the envelope. What json.loads built is plain JSON (only dict, list, str, int, float,
    # bool, None), with finite floats unless the text spelled one too large for a double; only
    # then do the validators walk the document to find it.
    plain = not overflowed
    claimed, seq = _claimed(obj)
    _check_envelope(obj, claimed, seq, plain=plain)
    assert isinstance(obj, dict)
    short = obj["schema"].removeprefix(SCHEMA_PREFIX)

    # 4. a known message, 5. one the caller takes, 6. in the current version
    if short not in MESSAGE_VERSIONS:
        raise _unknown(short, short, seq)
    if accepted is not None and short not in accepted:
        raise MessageError(
            "unexpected-schema",
            f"{short} is not accepted here; accepted: {', '.join(sorted(accepted)) or 'nothing'}",
            field="$.schema",
            rule="schema",
            request_schema=short,
            request_seq=seq,
        )
    versions = accepted_versions(short)
    version = obj["version"]
    if version not in versions:
        expected = (
            f"version {versions[0]}"
            if len(versions) == 1
            else "versions " + ", ".join(map(str, versions))
        )
        raise MessageError(
            "version",
            f"got version {version} of {short}, expected {expected}",
            field="$.version",
            rule="version",
            request_schema=short,
            request_seq=seq,
        )

    # 7. the payload
    _check_payload(short, obj["payload"], seq, plain=plain)
    for name in OLDER_VERSIONS.get(short, {}).get(version, ()):
        if name in obj["payload"]:
            raise MessageError(
                "payload",
                f"{name} is not a field of version {int(version)} of {short} "
                f"(the current version {MESSAGE_VERSIONS[short]} has it)",
                field=f"$.payload.{name}",
                rule="version",
                request_schema=short,
                request_seq=seq,
            )
    return Message(
        name=short,
        version=int(version),
        seq=int(obj["seq"]),
        stamp_ns=int(obj["stamp_ns"]),
        source=obj["source"],
        run_id=obj["run_id"],
        payload=obj["payload"],
    )


_SURROGATE_ESCAPE = re.compile(rb"\\u[dD][89a-fA-F]")
"""A backslash-u escape of a UTF-16 surrogate (paired or not; :func:`_lone_surrogate` tells)."""


def _lone_surrogate(obj: object, path: str) -> tuple[str, str] | None:
    """Where in ``obj`` a string or object key holds a lone surrogate: its JSON path (the
    object's, for a key) and "the string" or "a key"; None when nothing does."""
    stack = [(obj, path)]
    while stack:
        value, where = stack.pop()
        if isinstance(value, str):
            if not value.isascii() and _SURROGATES.search(value):
                return where, "the string"
        elif isinstance(value, dict):  # children pushed last first: the first is found first
            for key in value:
                if not key.isascii() and _SURROGATES.search(key):
                    return where, "a key of the object"
            stack.extend((value[key], f"{where}.{key}") for key in reversed(value))
        elif isinstance(value, list):
            stack.extend(
                (value[index], f"{where}[{index}]") for index in reversed(range(len(value)))
            )
    return None


_SURROGATES = re.compile("[\ud800-\udfff]")


def _long_digits(data: bytes) -> bool:
    """Whether ``data`` has digits that may spell an integer outside 64 bits, which orjson parses
    as a float (the standard parser as an int): one below -2**63 or above 2**64 - 1 needs 19
    digits after a minus sign or 20 digits. (Three byte scans: a regex takes several times as
    long.)"""
    digits = data.translate(_DIGITS_AS_ZERO)
    return b"00000000000000000000" in digits or b"-0000000000000000000" in digits


def _valid_message(obj: object, accepted: frozenset[str] | None) -> Message | None:
    """``obj`` as a :class:`Message` when it is a valid message the caller takes, in the current
    version (one compiled check of envelope and payload); None says nothing about why."""
    if type(obj) is not dict:
        return None
    short = obj.get("schema")
    short = short.removeprefix(SCHEMA_PREFIX) if type(short) is str else None
    version = obj.get("version")
    if (
        short in MESSAGE_VERSIONS
        and (accepted is None or short in accepted)
        and version == MESSAGE_VERSIONS[short]
        and type(version) is int
        and valid_envelope(short, obj)
    ):
        return Message(
            name=short,
            version=version,
            seq=int(obj["seq"]),  # an integer, perhaps spelt 3.0
            stamp_ns=int(obj["stamp_ns"]),
            source=obj["source"],
            run_id=obj["run_id"],
            payload=obj["payload"],
        )
    return None


def _accepted(accept: str | Iterable[str] | None) -> frozenset[str] | None:
    if accept is None:
        return None
    if isinstance(accept, (str, tuple)):
        return _accepted_names(accept)
    return _accepted_names(tuple(accept))


@functools.lru_cache(maxsize=64)
def _accepted_names(accept: str | tuple[str, ...]) -> frozenset[str]:
    names = [accept] if isinstance(accept, str) else list(accept)
    shorts = frozenset(name.removeprefix(SCHEMA_PREFIX) for name in names)
    unknown = sorted(shorts - MESSAGE_VERSIONS.keys())
    if unknown:
        raise ValueError(
            f"accept names {', '.join(unknown)}, not message schemas; "
            f"known: {', '.join(sorted(MESSAGE_VERSIONS))}"
        )
    return shorts


def _check_envelope(
    obj: object, claimed: str | None, seq: int | None, plain: bool | None = None
) -> None:
    """Validate the envelope without its payload (whose errors are the payload's); ``plain`` as
    for :func:`validate`."""
    shell = obj
    if isinstance(obj, dict) and isinstance(obj.get("payload"), dict):
        shell = {**obj, "payload": {}}
    try:
        validate("Envelope", shell, plain=plain)
    except SchemaError as exc:
        raise MessageError(
            "envelope",
            _detail(exc),
            field=exc.json_path,
            rule=exc.rule,
            request_schema=claimed,
            request_seq=seq,
        ) from None


def _check_payload(short: str, payload: object, seq: int | None, plain: bool | None = None) -> None:
    try:
        validate(short, payload, plain=plain)
    except SchemaError as exc:
        raise MessageError(
            "payload",
            _detail(exc),
            field="$.payload" + exc.json_path.removeprefix("$"),
            rule=exc.rule,
            request_schema=short,
            request_seq=seq,
        ) from None
    except RecursionError:
        raise MessageError(
            "payload",
            "nested too deeply to validate",
            field="$.payload",
            rule="max-depth",
            request_schema=short,
            request_seq=seq,
        ) from None


def _claimed(obj: object) -> tuple[str | None, int | None]:
    """The schema name and seq a parsed message claims, where they are readable."""
    if not isinstance(obj, dict):
        return None, None
    schema = obj.get("schema")
    name = _short_name(schema) if isinstance(schema, str) else None
    seq = obj.get("seq")
    if isinstance(seq, float) and seq.is_integer():
        seq = int(seq)
    if not isinstance(seq, int) or isinstance(seq, bool) or not 0 <= seq <= _MAX_SEQ:
        seq = None
    return name, seq


def _short_name(schema: str) -> str | None:
    match = _SCHEMA_PATTERN.fullmatch(schema)
    return match.group(1) if match else None


def _unknown(short: str, claimed: str | None, seq: int | None) -> MessageError:
    return MessageError(
        "unknown-schema",
        f"{_clip(short, 128)!r} is not a message schema; "
        f"known: {', '.join(sorted(MESSAGE_VERSIONS))}",
        field="$.schema",
        rule="schema",
        request_schema=claimed,
        request_seq=seq,
    )


def _oversize(size: int, claimed: str | None, seq: int | None) -> MessageError:
    return MessageError(
        "oversize",
        f"message is {size} bytes, more than the limit of {MAX_MESSAGE_BYTES} bytes",
        field="$",
        rule="max-bytes",
        request_schema=claimed,
        request_seq=seq,
    )


def _nesting(obj: object) -> int:
    """Deepest nesting of arrays and objects in ``obj``, without recursion."""
    deepest = 0
    stack: list[tuple[object, int]] = [(obj, 1)]
    while stack:
        item, depth = stack.pop()
        if isinstance(item, dict):
            children: Iterable[object] = item.values()
        elif isinstance(item, list):
            children = item
        else:
            continue
        if depth > MAX_NESTING:
            return depth
        deepest = max(deepest, depth)
        stack.extend((child, depth + 1) for child in children)
    return deepest


def _detail(exc: SchemaError) -> str:
    """The jsonschema message of ``exc``, shortened (it may quote a huge instance)."""
    text = str(exc)
    prefix = f"{exc.schema}: {exc.json_path}: "
    suffix = f" (rule: {exc.rule})"
    text = text.removeprefix(prefix).removesuffix(suffix)
    return _shorten(_one_line(text), _MAX_DETAIL)


def _one_line(text: str) -> str:
    return " ".join(text.split())


def _shorten(text: str, limit: int) -> str:
    """``text`` with its middle cut out if longer than ``limit`` (both ends carry meaning)."""
    if len(text) <= limit:
        return text
    marker = " ... "
    keep = (limit - len(marker)) // 2
    return text[:keep] + marker + text[len(text) - keep :]


def unicode_text(text: str) -> str:
    """``text`` with lone surrogates written as backslash escapes (it encodes to UTF-8 then;
    the nodes' loggers and Error texts use it)."""
    if text.isascii() or not _SURROGATES.search(text):
        return text
    return text.encode("utf-8", "backslashreplace").decode("utf-8")


def _clip(text: str, limit: int) -> str:
    return text if len(text) <= limit else text[: limit - 3] + "..."

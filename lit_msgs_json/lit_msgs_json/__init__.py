"""JSON Schemas of every LIT* message and file format, and helpers to validate against them.

The only place where a message shape is defined. Typical use::

    from lit_msgs_json import validate, SchemaError
    validate("TensorSidecar", sidecar_dict)  # raises SchemaError naming the field

Messages travel in a versioned envelope (see ``lit_msgs_json.envelope``)::

    from lit_msgs_json import Publisher, decode, MessageError
    text = Publisher("planner/host/42", "run-1").encode("DecideRequest", payload)
    message = decode(text, accept="DecideRequest")  # or raises MessageError
"""

from __future__ import annotations

from lit_msgs_json.codec import dumps, load_schema, loads, prepare, schema_names, validate
from lit_msgs_json.envelope import (
    MAX_MESSAGE_BYTES,
    MESSAGE_VERSIONS,
    OLDER_VERSIONS,
    Message,
    MessageError,
    Publisher,
    accepted_versions,
    decode,
)
from lit_msgs_json.errors import SchemaError, UnknownSchemaError

__all__ = [
    "MAX_MESSAGE_BYTES",
    "MESSAGE_VERSIONS",
    "OLDER_VERSIONS",
    "Message",
    "MessageError",
    "Publisher",
    "SchemaError",
    "UnknownSchemaError",
    "accepted_versions",
    "decode",
    "dumps",
    "load_schema",
    "loads",
    "prepare",
    "schema_names",
    "validate",
]

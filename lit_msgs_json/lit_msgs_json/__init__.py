"""JSON Schemas of every LIT* message and file format, and helpers to validate against them.

The only place where a message shape is defined. Typical use::

    from lit_msgs_json import validate, SchemaError
    validate("TensorSidecar", sidecar_dict)  # raises SchemaError naming the field
"""

from __future__ import annotations

from lit_msgs_json.codec import dumps, load_schema, loads, schema_names, validate
from lit_msgs_json.errors import SchemaError, UnknownSchemaError

__all__ = [
    "SchemaError",
    "UnknownSchemaError",
    "dumps",
    "load_schema",
    "loads",
    "schema_names",
    "validate",
]

"""Exceptions raised by ``lit_msgs_json``."""

from __future__ import annotations

MAX_DETAIL = 400
"""Characters of a violation's description kept in the message (its start and its end)."""


class SchemaError(ValueError):
    """A document does not satisfy its JSON Schema.

    The message names the schema, the JSON path of the offending field and the rule it broke.
    """

    def __init__(self, schema: str, json_path: str, rule: str, detail: str) -> None:
        if len(detail) > MAX_DETAIL:  # jsonschema quotes the whole value: a 2000-number array
            detail = f"{detail[: MAX_DETAIL // 2]} … {detail[-MAX_DETAIL // 4 :]}"
        super().__init__(f"{schema}: {json_path}: {detail} (rule: {rule})")
        self.schema = schema
        """Name of the schema, e.g. ``TensorSidecar``."""
        self.json_path = json_path
        """JSON path of the offending field, e.g. ``$.axes[1].size``."""
        self.rule = rule
        """Broken rule: a JSON Schema keyword such as ``enum``, or ``finite`` or ``json``."""


class UnknownSchemaError(SchemaError, LookupError):
    """No schema of that name ships with ``lit_msgs_json``."""

    def __init__(self, schema: str, known: list[str]) -> None:
        super().__init__(schema, "$", "known-schema", f"no such schema; known: {', '.join(known)}")

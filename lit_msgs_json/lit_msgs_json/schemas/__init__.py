"""JSON Schemas (draft 2020-12) of every message and file format: ``<Name>.schema.json``."""

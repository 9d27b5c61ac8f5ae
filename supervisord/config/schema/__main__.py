"""``python -m supervisord.config.schema``: print the config's JSON Schema (the committed copy
is ``config/srcsd.schema.json``; a test keeps it fresh)."""

from __future__ import annotations

from supervisord.config.schema import json_schema_text

print(json_schema_text(), end="")

"""``srcsctl log``'s option values (docs/cli.md), apart from the command that reads the record,
so that building ``srcsctl``'s parser loads nothing of the record or the safety core."""

from __future__ import annotations

from typing import Final

FOLLOW_LAST: Final = 10
"""What ``-n`` alone and ``-f`` without ``-n`` show first: the last 10, as journalctl."""
PAGER_END_LAST: Final = 1000
"""What ``-e`` shows without ``-n``: the last 1000, as journalctl's ``-e`` implies ``-n1000``."""
OUTPUTS: Final = ("short", "short-iso", "cat", "verbose", "json", "json-pretty")
"""``-o``'s modes: ``short`` (and ``short-iso``, the same: the time is ISO 8601 already), ``cat``
the line without its time, ``verbose`` as ``--causes``, ``json`` a line per record,
``json-pretty`` each record indented."""

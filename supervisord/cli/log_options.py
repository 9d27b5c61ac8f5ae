"""The options ``srcsctl log`` and ``srcsctl fleet`` share to read stop records
(docs/srcsctl.md): which records (``--since``, ``--until``, ``--cause``, ``--cause-present``),
how they are printed (``--json``, ``-o``, ``-n``, ``-r``, ``--causes``, ``--utc``, ``-q``) and
``-f``. Declared once so that the two commands' options, their help and their man page and
completion (generated from the parsers, ``supervisord/cli/reference.py``) cannot drift apart.
Each command adds its own options between these groups, in the order ``--help`` shows them.

Apart from the commands that read the record, so that building ``srcsctl``'s parser loads
nothing of the record or the safety core.
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, Final

from supervisord.cli.numbers import count

if TYPE_CHECKING:
    from supervisord.cli.cause_names import CauseFilter

FOLLOW_LAST: Final = 10
"""What ``-n`` alone and ``-f`` without ``-n`` show first: the last 10, as journalctl."""
PAGER_END_LAST: Final = 1000
"""What ``-e`` shows without ``-n``: the last 1000, as journalctl's ``-e`` implies ``-n1000``."""
OUTPUTS: Final = ("short", "short-iso", "cat", "verbose", "json", "json-pretty")
"""``-o``'s modes: ``short`` (and ``short-iso``, the same: the time is ISO 8601 already), ``cat``
the line without its time, ``verbose`` as ``--causes``, ``json`` a line per record,
``json-pretty`` each record indented."""


def cause_name(text: str) -> CauseFilter:
    """``--cause``'s type: :func:`supervisord.cli.cause_names.cause_name`, loaded when used."""
    from supervisord.cli.cause_names import cause_name as known  # noqa: PLC0415

    return known(text)


def add_time_range(parser: argparse.ArgumentParser) -> None:
    """``-S``/``--since`` and ``-U``/``--until``: ``log``'s times (docs/srcsctl.md "Times")."""
    parser.add_argument("-S", "--since", metavar="TIME", help="records at or after TIME")
    parser.add_argument("-U", "--until", metavar="TIME", help="records before TIME")


def add_cause_filters(parser: argparse.ArgumentParser) -> None:
    """``--cause`` and ``--cause-present``, each a cause name of the shared vocabulary."""
    parser.add_argument(
        "--cause",
        metavar="NAME",
        type=cause_name,
        help="records that raised, updated, cleared or released this cause (client_lost "
        "matches client_lost:autonomy)",
    )
    parser.add_argument(
        "--cause-present",
        metavar="NAME",
        type=cause_name,
        help="records made while this cause was present, active or latched",
    )


def add_output(parser: argparse.ArgumentParser) -> None:
    """``--json``, ``-o``/``--output`` and ``-n``/``--lines``."""
    parser.add_argument("--json", action="store_true", help="the records as JSON lines")
    parser.add_argument(
        "-o",
        "--output",
        choices=OUTPUTS,
        help="short (the default; short-iso the same), cat (no time), verbose (as --causes), "
        "json (as --json), json-pretty (indented)",
    )
    parser.add_argument(
        "-n",
        "--lines",
        type=count,
        nargs="?",
        const=FOLLOW_LAST,
        metavar="N",
        help=f"only the last N records (alone: {FOLLOW_LAST})",
    )


def add_follow_and_display(parser: argparse.ArgumentParser, *, follows: str) -> None:
    """``-f``/``--follow`` (each new record ``follows``: "as it is written"), then ``-r``,
    ``--causes``, ``--utc``, ``-q`` and ``--no-pager``."""
    parser.add_argument(
        "-f",
        "--follow",
        action="store_true",
        help=f"the last {FOLLOW_LAST} (or -n N), then each new record {follows}",
    )
    parser.add_argument("-r", "--reverse", action="store_true", help="newest first")
    parser.add_argument(
        "--causes", action="store_true", help="also every cause of each record, and its trigger"
    )
    parser.add_argument("--utc", action="store_true", help="times in UTC (default: local time)")
    parser.add_argument(
        "-q", "--quiet", action="store_true", help="no '-- No entries --' when nothing matched"
    )
    parser.add_argument(
        "--no-pager", action="store_true", help="accepted and ignored: there is no pager"
    )

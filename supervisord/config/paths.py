"""Where a robot's daemon is found: the keys of ``[api]`` that name its sockets and the
``[record]`` section, declared once for the schema, the loader and the clients' reader.

``srcsctl``, ``srcs-exporter`` and ``--demo`` need a config's sockets and record path, never
its safety values; they read them with :mod:`supervisord.config.client`, which must not load
the safety core (SR-8.8). So what they share with the daemon's loader lives here, below the
schema (:mod:`supervisord.config.schema`, which imports the core for the safety sections'
choices): the declarations of these keys, the rules each obeys on its own (a relative path
resolved against the config's directory, a socket's path short enough that the name the
daemon binds it under first fits a Unix socket address, the record's files regular files or
nothing yet) and the names of the file's sections and of ``[api]``'s keys, so that a misspelt
section or key is refused by both alike (tests/config/test_client_config.py holds them equal
to the schema's).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Final

from supervisord import strict
from supervisord.api.framing import (
    DEFAULT_SOCKET_PATH,
    PID_MAX_DIGITS,
    SOCKET_ADDRESS_MAX_BYTES,
    SOCKET_PATH_MAX_BYTES,
    operator_socket_path,
)
from supervisord.record.jsonl import (
    DEFAULT_FLIGHT_MAX_BYTES,
    DEFAULT_KEEP,
    DEFAULT_MAX_BYTES,
    FLIGHT_MAX_BYTES_RANGE,
    KEEP_RANGE,
    MAX_BYTES_RANGE,
    not_a_regular_file,
    record_paths,
)

DEFAULT_RECORD_PATH: Final = "/var/lib/srcsd/stops.jsonl"
DEFAULT_SOCKET: Final = str(DEFAULT_SOCKET_PATH)
DEFAULT_OPERATOR_SOCKET: Final = str(operator_socket_path(DEFAULT_SOCKET_PATH))
SOCKET_PATH_LIMIT: Final = (
    f"at most {SOCKET_PATH_MAX_BYTES} bytes (a Unix socket address holds "
    f"{SOCKET_ADDRESS_MAX_BYTES}, and the daemon first binds the socket under a name up to "
    f"{2 + PID_MAX_DIGITS} bytes longer)"
)
"""A socket path's limit and why, as the refusals say it: the check refuses what the start
could not bind (SR-11.2)."""

RENAMED: Final[Mapping[str, str]] = {"log": "record", "class": "role", "rearm_hold_ms": "hold_ms"}
"""Names an integrator may try from older sketches, and the name this file uses instead."""

SECTION_NAMES: Final = (
    "robot",
    "vsc",
    "rearm",
    "clients",
    "outputs",
    "output_bus",
    "record",
    "api",
    "maintenance",
    "realtime",
    "fleet",
)
"""The file's sections, in the schema's order: any other is a mistake."""
API_KEY_NAMES: Final = (
    "socket",
    "group",
    "admin_group",
    "operator_socket",
    "operator_group",
    "max_clients",
    "max_message_bytes",
)
"""``[api]``'s keys, in the schema's order: a misspelt ``socket`` must not send a client to
the default socket, another daemon's."""

API_SOCKET: Final = strict.Text(
    name="socket",
    doc=f"The Unix socket for clients and srcsctl; at most {SOCKET_PATH_MAX_BYTES} bytes "
    "once resolved against the config file's directory (a Unix socket address's "
    f"{SOCKET_ADDRESS_MAX_BYTES}, less room for the name the daemon binds it under first).",
    default=DEFAULT_SOCKET,
    not_dir=True,
    example=DEFAULT_SOCKET,
)
API_OPERATOR_SOCKET: Final = strict.Text(
    name="operator_socket",
    doc="The operators' own socket (SR-8.14: srcsctl tries it first; no robot program can "
    "reach it); at most "
    f"{SOCKET_PATH_MAX_BYTES} bytes once resolved. Default: the socket's path with "
    "-operator before its suffix.",
    default=None,
    not_dir=True,
    example=DEFAULT_OPERATOR_SOCKET,
)

RECORD_PATH: Final = strict.Text(
    name="path",
    doc="The record of stops (docs/record.md); its directory must exist.",
    default=DEFAULT_RECORD_PATH,
    not_dir=True,
    example=DEFAULT_RECORD_PATH,
)
RECORD_MAX_BYTES: Final = strict.Whole(
    name="max_bytes",
    doc="Rotate the record at this size.",
    default=DEFAULT_MAX_BYTES,
    example=DEFAULT_MAX_BYTES,
    low=MAX_BYTES_RANGE[0],
    high=MAX_BYTES_RANGE[1],
)
RECORD_KEEP: Final = strict.Whole(
    name="keep",
    doc="Rotated files kept besides the current one.",
    default=DEFAULT_KEEP,
    example=DEFAULT_KEEP,
    low=KEEP_RANGE[0],
    high=KEEP_RANGE[1],
)
RECORD_JOURNAL: Final = strict.Flag(
    name="journal",
    doc="Also send every record to the systemd journal.",
    default=True,
    example=True,
)
RECORD_FLIGHT_MAX_BYTES: Final = strict.Whole(
    name="flight_max_bytes",
    doc="The flight recorder's windows beside the record take at most this many bytes together.",
    default=DEFAULT_FLIGHT_MAX_BYTES,
    example=DEFAULT_FLIGHT_MAX_BYTES,
    low=FLIGHT_MAX_BYTES_RANGE[0],
    high=FLIGHT_MAX_BYTES_RANGE[1],
)
RECORD: Final = (
    RECORD_PATH,
    RECORD_MAX_BYTES,
    RECORD_KEEP,
    RECORD_JOURNAL,
    RECORD_FLIGHT_MAX_BYTES,
)
"""``[record]``'s keys."""


def file_path(fields: strict.Fields, key: strict.Text, base: Path) -> Path:
    """A file path; a relative one is resolved against ``base``, the config file's
    directory."""
    path = Path(fields.text(key))
    return path if path.is_absolute() else base / path


def api_sockets(fields: strict.Fields, base: Path) -> tuple[Path, Path]:
    """``[api]``'s client socket and operator socket (the one beside the socket when the key
    is absent), each resolved and short enough that the daemon can bind it: its staging name
    too must fit a Unix socket address (SR-8.1, SR-8.14, SR-11.2)."""
    socket = file_path(fields, API_SOCKET, base)
    if len(str(socket).encode()) > SOCKET_PATH_MAX_BYTES:
        raise fields.refuse(
            API_SOCKET.name,
            str(socket),
            f'use a path of {SOCKET_PATH_LIMIT}, e.g. "{API_SOCKET.default}"',
        )
    operator = (
        file_path(fields, API_OPERATOR_SOCKET, base)
        if fields.read(API_OPERATOR_SOCKET) is not None
        else operator_socket_path(socket)
    )
    if len(str(operator).encode()) > SOCKET_PATH_MAX_BYTES:
        raise fields.refuse(
            API_OPERATOR_SOCKET.name,
            str(operator),
            f"use a path of {SOCKET_PATH_LIMIT}; without the key it is the socket's path "
            "with -operator before its suffix",
        )
    return socket, operator


def check_record_files(fields: strict.Fields, path: Path, keep: int) -> None:
    """The record and its rotated files are regular files or nothing yet (SR-7.9): a FIFO
    there would hang the start (its last record is read) and ``srcsctl log``, a symlink
    would be rotated away, a device written to. Looked at, never opened."""
    for file, part in record_paths(path, keep):
        kind = not_a_regular_file(file)
        if kind is not None:
            name = f"its {part} {file}" if part else "it"
            raise fields.refuse(
                RECORD_PATH.name,
                str(path),
                f"{name} is {kind}, not a regular file: remove it, or name another path",
            )

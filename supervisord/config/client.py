"""The clients' reader of a robot's config: where its daemon is, and nothing else.

``srcsctl`` (``--config``, ``--robot``, ``--demo``) and ``srcs-exporter --config`` need the
API sockets and the record's path of the robot's config. They read them here, not with the
daemon's :func:`~supervisord.config.load_config`, which validates every section and builds
the safety core's configuration: a client must load no module of the safety core (SR-8.8,
tests/test_layers.py), and whether the safety values are right is the daemon's to judge,
which refuses to start on a wrong one (SR-11.2).

What is read is read as the daemon reads it (:mod:`supervisord.config.paths`, shared with the
loader): the same file refusals (missing, unreadable, too large, not UTF-8, not TOML), the
same keys with the same defaults, relative paths resolved against the config's directory,
the same limits and the same messages. A section the file should not have and a key of
``[api]`` or ``[record]`` nobody declared are refused too: a misspelt ``[api]`` or
``socket`` would otherwise send the client to the default socket, another daemon's. The other
sections are not looked into (docs/srcsctl.md "Which socket").
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from supervisord import strict
from supervisord.config.paths import (
    API_KEY_NAMES,
    RECORD,
    RECORD_KEEP,
    RECORD_PATH,
    RENAMED,
    SECTION_NAMES,
    api_sockets,
    check_record_files,
    file_path,
)
from supervisord.config.toml_file import read_toml
from supervisord.errors import ConfigError


@dataclasses.dataclass(frozen=True, slots=True)
class ClientConfig:
    """Where a robot's daemon is: its client socket, its operator socket (SR-8.14) and its
    record of stops, each resolved as the daemon resolves it."""

    socket: Path
    operator_socket: Path
    record_path: Path


def load_client_config(path: str | Path) -> ClientConfig:
    """The sockets and the record's path of the robot's config at ``path``. Raises
    :class:`ConfigError` naming the file, the key, the value and the fix, as
    :func:`~supervisord.config.load_config` does for the same mistake in these keys."""
    source = Path(path)
    try:
        root = strict.Fields(read_toml(source), error=ConfigError, renamed=RENAMED)
        root.check_keys(SECTION_NAMES)
        base = source.parent.absolute()
        api = root.table_at("api")
        api.check_keys(API_KEY_NAMES)
        socket, operator = api_sockets(api, base)
        record = root.table_at("record")
        record.check_keys(key.name for key in RECORD)
        record_path = file_path(record, RECORD_PATH, base)
        check_record_files(record, record_path, record.whole(RECORD_KEEP))
    except ConfigError as error:
        raise (error if error.file else error.in_file(str(path))) from None
    return ClientConfig(socket, operator, record_path)

"""Where a running ``srcsctl demo`` is, so that ``srcsctl --demo status`` (or ``watch``, ``log``,
``estop``...) talks to it without being told its socket.

The demo runs in a private directory ``srcs-demo-XXXXXXXX`` under the temporary directory
(``$TMPDIR``, else ``/tmp``), with its config copied in as ``demo.toml`` (whose relative
paths, the socket and the record among them, are read against that directory). A running
demo is such a directory of this user whose config's socket answers a connect; ``--demo`` then
stands for ``--config DIR/demo.toml``. With several, it names them and picks none.
"""

from __future__ import annotations

import contextlib
import os
import socket
import tempfile
from pathlib import Path
from typing import Final

from supervisord.config.client import load_client_config
from supervisord.errors import ConfigError

PREFIX: Final = "srcs-demo-"
"""The demo's run directory's name, before the random part."""
RUN: Final = "srcs-demo"
"""The directory ``demo.toml`` names for its files, inside the run directory."""
CONFIG: Final = "demo.toml"


class NoDemo(LookupError):
    """No running demo, or more than one."""


def _answers(path: Path) -> bool:
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as probe:
        probe.settimeout(2.0)
        with contextlib.suppress(OSError):
            probe.connect(str(path))
            return True
    return False


def _socket(config: Path) -> Path:
    try:
        return load_client_config(config).socket  # no safety core (SR-8.8)
    except ConfigError:
        return config.parent / RUN / "api.sock"  # where the packaged demo.toml puts it


def running_demos(folder: Path | None = None) -> list[Path]:
    """The config of every demo of this user running under ``folder`` (default: the
    temporary directory), newest first."""
    base = Path(folder or tempfile.gettempdir())
    found = []
    for run in base.glob(f"{PREFIX}*"):
        config = run / CONFIG
        try:
            mine = run.stat().st_uid == os.geteuid()
        except OSError:
            continue
        if mine and config.is_file() and _answers(_socket(config)):
            found.append(config)
    return sorted(found, key=lambda config: config.stat().st_mtime, reverse=True)


def demo_config(folder: Path | None = None) -> Path:
    """The config of the one running demo. Raises :class:`NoDemo` saying what was found."""
    found = running_demos(folder)
    if len(found) == 1:
        return found[0]
    if not found:
        raise NoDemo("no demo is running (start one with: srcsctl demo)")
    names = ", ".join(str(config) for config in found)
    raise NoDemo(f"{len(found)} demos are running ({names}); name one with --config")

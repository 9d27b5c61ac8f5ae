"""``srcsd --check-config FILE``: the loader's verdict, printed for a person."""

from __future__ import annotations

import sys
from pathlib import Path

from supervisord.config.loader import load_config
from supervisord.errors import ConfigError


def check_config_main(path: str | Path) -> int:
    """Print ``FILE: OK — ...`` and any warnings and return 0, or print the error (to stderr)
    and return 1."""
    try:
        config = load_config(path)
    except ConfigError as error:
        print(error, file=sys.stderr)
        return 1
    outputs, clients = len(config.outputs), len(config.safety.clients)
    print(
        f"{path}: OK — robot {config.robot.name}, transport {config.vsc.transport.value}, "
        f"{outputs} output{'s' * (outputs != 1)}, {clients} client{'s' * (clients != 1)}"
    )
    for note in config.warnings():
        print(f"{path}: warning: {note}", file=sys.stderr)
    return 0

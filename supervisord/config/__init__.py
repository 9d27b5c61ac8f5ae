"""The robot's configuration: one TOML file, read with ``tomllib`` and validated completely
(SR-11.2, ``docs/configuration.md``).

Three jobs, three modules: :mod:`~supervisord.config.schema` declares every key (type, default,
range, example, documentation) and builds the JSON Schema from the same declarations;
:mod:`~supervisord.config.loader` reads a file into a :class:`DaemonConfig`
(:mod:`~supervisord.config.model`) and applies the rules between keys;
:mod:`~supervisord.config.check` is ``srcsd --check-config``. The clients (``srcsctl``,
``srcs-exporter``) read only where the daemon is with :mod:`~supervisord.config.client`.

The names below are loaded when first asked for: importing one module of this package (the
clients' reader) must not import the loader, which builds the safety core's configuration
(SR-8.8, tests/test_layers.py).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from supervisord.config.check import check_config_main
    from supervisord.config.loader import load_config
    from supervisord.config.model import (
        ApiConfig,
        CanBus,
        CanErrors,
        DaemonConfig,
        HidDevice,
        RecordConfig,
        Reopen,
        RobotConfig,
        SerialPort,
        VscConfig,
    )
    from supervisord.config.schema import (
        DEFAULT_CAN_BITRATE,
        DEFAULT_SERIAL_PORT,
        SERIAL_BAUD,
    )
    from supervisord.config.toml_file import read_toml
    from supervisord.strict import MISSING

_HOMES = {
    "check_config_main": "supervisord.config.check",
    "load_config": "supervisord.config.loader",
    "read_toml": "supervisord.config.toml_file",
    "MISSING": "supervisord.strict",
    **dict.fromkeys(
        ("DEFAULT_CAN_BITRATE", "DEFAULT_SERIAL_PORT", "SERIAL_BAUD"), "supervisord.config.schema"
    ),
    **dict.fromkeys(
        (
            "ApiConfig",
            "CanBus",
            "CanErrors",
            "DaemonConfig",
            "HidDevice",
            "RecordConfig",
            "Reopen",
            "RobotConfig",
            "SerialPort",
            "VscConfig",
        ),
        "supervisord.config.model",
    ),
}
"""Each name of the package's face and the module it lives in."""


def __getattr__(name: str) -> object:
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(home), name)
    globals()[name] = value  # once: later reads find it without this function
    return value


__all__ = [
    "DEFAULT_CAN_BITRATE",
    "DEFAULT_SERIAL_PORT",
    "MISSING",
    "SERIAL_BAUD",
    "ApiConfig",
    "CanBus",
    "CanErrors",
    "DaemonConfig",
    "HidDevice",
    "RecordConfig",
    "Reopen",
    "RobotConfig",
    "SerialPort",
    "VscConfig",
    "check_config_main",
    "load_config",
    "read_toml",
]

"""The robot's configuration: one TOML file, read with ``tomllib`` and validated completely
(SR-11.2, ``docs/configuration.md``).

Three jobs, three modules: :mod:`~supervisord.config.schema` declares every key (type, default,
range, example, documentation) and builds the JSON Schema from the same declarations;
:mod:`~supervisord.config.loader` reads a file into a :class:`DaemonConfig`
(:mod:`~supervisord.config.model`) and applies the rules between keys;
:mod:`~supervisord.config.check` is ``srcsd --check-config``.
"""

from supervisord.config.check import check_config_main
from supervisord.config.loader import load_config, read_toml
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
from supervisord.strict import MISSING

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

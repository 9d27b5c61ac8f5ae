"""Which directories the daemon may count on: those of the record and of its sockets must be
there at its start (it creates neither; SR-11.2), so the check says so before the start does.

The daemon's start asks the machine (:func:`present`). ``srcsd --check-config`` is run before
the service's first start, when the directories that the unit ``srcsd@NAME.service`` makes at
each start do not exist yet (``StateDirectory=srcsd srcsd/%i``, ``RuntimeDirectory=srcsd
srcsd/%i``, ``LogsDirectory=srcsd``): :func:`present_or_made_by_unit` counts those as there,
for the config named ``NAME.toml`` (the unit reads ``/etc/srcs/%i.toml``), so a socket in
``/run/srcsd/OTHER/`` is refused for ``robot-a.toml`` (the unit would make ``robot-a/``, not
``OTHER/``). docs/configuration.md "Checking a config".
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Final

from supervisord.config.loader import NotOnMachine
from supervisord.config.model import DaemonConfig

UNIT_DIRECTORIES: Final = (Path("/var/lib/srcsd"), Path("/run/srcsd"))
"""units/srcsd@.service's StateDirectory= and RuntimeDirectory= (each also with ``/%i``)."""
UNIT_LOGS_DIRECTORY: Final = Path("/var/log/srcsd")
"""units/srcsd@.service's LogsDirectory= (without an instance's own)."""


def present(directory: Path) -> bool:
    """Whether ``directory`` is a directory on this machine now (the daemon's start)."""
    return directory.is_dir()


def made_by_unit(instance: str) -> frozenset[Path]:
    """The directories srcsd@``instance``.service makes at its start."""
    made = {UNIT_LOGS_DIRECTORY}
    for top in UNIT_DIRECTORIES:
        made |= {top, top / instance}
    return frozenset(made)


def present_or_made_by_unit(config: Path) -> Callable[[Path], bool]:
    """For ``srcsd --check-config``: a directory is there, or the unit of the config's name
    makes it at its start."""
    made = made_by_unit(config.stem)
    return lambda directory: directory in made or present(directory)


def missing_directories(
    config: DaemonConfig, there: Callable[[Path], bool]
) -> Iterator[NotOnMachine]:
    """The record's and the sockets' directories that are not ``there``, each as the error
    of the key that names its path. Judged on the loaded config, so that a path left at its
    default (no key written) is judged too; the operator socket only where it is not beside
    the socket (then its key is written)."""
    instance = config.source.stem
    wanted = [
        ("record.path", config.record.path, "the record"),
        ("api.socket", config.api.socket, "the socket"),
    ]
    operator = config.api.operator_path
    if operator.parent != config.api.socket.parent:
        wanted.append(("api.operator_socket", operator, "the operator socket"))
    for key, path, what in wanted:
        if there(path.parent):
            continue
        yield NotOnMachine(
            key,
            str(path),
            f"the directory of {what}, {path.parent}, does not exist on this machine and srcsd "
            f"does not create it: create it (install -d -o srcsd -g srcsd -m 0750 "
            f"{path.parent}), or name a path in /var/lib/srcsd/{instance}/ or "
            f"/run/srcsd/{instance}/, which srcsd@{instance}.service makes at its start",
        )

"""The simulated output: a first-class output kind for the demo, for tests and for bench work.

It models one enable line whose physical level is kept in memory. When the config gives it a
``path``, every change of that level rewrites the file with ``1\\n`` (on) or ``0\\n`` (off),
so a script, a test or an operator can watch it from outside. The file is replaced atomically
(a temporary file in the same directory, then ``os.replace``): an outside reader never sees a
half-written file. A process killed between creating the temporary file and the rename
leaves it behind (``.NAME.PID.tmp``); opening the output removes every such file of a process
that no longer exists, and its own.

Fault injection is a real behaviour of the simulated device, not a test hook: a line can be
*stuck* at a level (``stuck_at = "on"`` or ``"off"`` in the config, or :meth:`SimOutput.stick`
at run time), as a welded relay contact or a shorted driver would be. A stuck line ignores
writes; the read-back then differs from what was written and :meth:`SimOutput.set` reports a
``MISMATCH``, which the daemon turns into ``output_fault:NAME``. A ``path`` that can no longer
be written (its directory removed, a full disk) is reported as ``IO_ERROR``.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, ClassVar, Final

from supervisord import strict
from supervisord.compat import StrEnum
from supervisord.outputs.base import (
    Claim,
    DeviceSpec,
    Output,
    OutputError,
    OutputFault,
    OutputKind,
    ReadBack,
)
from supervisord.safety.config import OutputRole

if TYPE_CHECKING:
    from typing_extensions import Self


class Level(StrEnum):
    """A line level as the config spells it."""

    ON = "on"
    OFF = "off"


PATH: Final = strict.Text(
    name="path",
    doc="The file that mirrors the line's level (1 or 0); its directory must exist. "
    "Relative to the config file's directory. Not set: memory only.",
    default=None,
    not_dir=True,
    example="run/drive",
)
STUCK_AT: Final = strict.Choice(
    name="stuck_at",
    doc="A fault to simulate from the start: the line stays at this level whatever is "
    "written. Not set: a healthy line.",
    values={Level.ON.value: "", Level.OFF.value: ""},
    default=None,
    example="on",
)


@dataclasses.dataclass(frozen=True, kw_only=True)
class SimSpec(DeviceSpec):
    """Options of a ``kind = "sim"`` output.

    ``path``: the file to mirror the level into (``None``: memory only). Its directory must
    exist. ``stuck_at``: a fault to simulate from the start (``None``: a healthy line).
    """

    kind: ClassVar[OutputKind] = OutputKind.SIM
    options: ClassVar[tuple[strict.Key, ...]] = (PATH, STUCK_AT)
    path: Path | None = None
    stuck_at: bool | None = None

    @classmethod
    def from_options(cls, name: str, role: OutputRole, values: Mapping[str, object]) -> Self:
        """The file as a path, the stuck level as a bool."""
        path, stuck = values["path"], values["stuck_at"]
        return cls(
            name=name,
            role=role,
            path=None if path is None else Path(str(path)),
            stuck_at=None if stuck is None else stuck == Level.ON.value,
        )

    def claims(self) -> tuple[Claim, ...]:
        """Its file, if it has one: no other key of the config may name it."""
        if self.path is None:
            return ()
        return (Claim("path", str(self.path), "file", path=self.path),)

    def resolved(self, base: Path) -> Self:
        """A relative ``path`` resolved against ``base``."""
        if self.path is None or self.path.is_absolute():
            return self
        return dataclasses.replace(self, path=base / self.path)


class SimOutput(Output):
    """A simulated enable line (see the module docstring for the file and the stuck fault)."""

    kind: ClassVar[OutputKind] = OutputKind.SIM
    spec_type: ClassVar[type[DeviceSpec]] = SimSpec

    def __init__(self, spec: SimSpec) -> None:
        super().__init__(spec)
        self.spec = spec
        self._stuck = spec.stuck_at
        self._device = False  # the simulated physical level
        self._mirrored: bool | None = None  # the level the file last showed

    @property
    def device_level(self) -> bool:
        """The simulated physical level of the line (what a load wired to it would see)."""
        return self._device

    def stick(self, level: bool | None) -> None:
        """Simulate a line stuck at ``level`` from now on (``None`` heals it). Takes effect at
        once: a stuck line's physical level is the stuck level, whatever was written, and the
        file (if any) shows it. Raises ``OSError`` if the file cannot be rewritten."""
        self._stuck = level
        if level is not None and self.is_open:
            self._device = level
            self._mirror()

    def _open(self, now: int) -> ReadBack:
        self._mirrored = None
        try:
            self._remove_leftovers()
            return self._drive(False, False)
        except OSError as e:
            raise OutputError(self.name, f"cannot write {self.spec.path}: {e}") from e

    def _write(self, on: bool, now: int) -> ReadBack:
        try:
            return self._drive(on, on)
        except OSError as e:
            return ReadBack(self.name, on, on, None, OutputFault.IO_ERROR, str(e))

    def _close(self) -> ReadBack:
        return self._write(False, 0)

    def _drive(self, requested: bool, level: bool) -> ReadBack:
        self._device = level if self._stuck is None else self._stuck
        self._mirror()
        observed = self._device
        if observed != level:
            return ReadBack(
                self.name, requested, level, observed, OutputFault.MISMATCH, "line stuck"
            )
        return ReadBack(self.name, requested, level, observed)

    def _remove_leftovers(self) -> None:
        """Remove temporaries of this output left by a killed writer (its pid is gone) or by
        this process. A live process's temporary is another instance's business."""
        path = self.spec.path
        if path is None:
            return
        pattern = re.compile(r"\." + re.escape(path.name) + r"\.([0-9]+)\.tmp")
        try:
            names = os.listdir(path.parent)
        except FileNotFoundError:
            return  # the directory is missing: the write below reports it
        for name in names:
            match = pattern.fullmatch(name)
            if match is None:
                continue
            pid = int(match.group(1))
            if pid != os.getpid() and _alive(pid):
                continue
            with contextlib.suppress(FileNotFoundError):
                (path.parent / name).unlink()

    def _mirror(self) -> None:
        """Rewrite the file if the level changed since it was last written (atomic replace)."""
        path = self.spec.path
        if path is None or self._mirrored == self._device:
            return
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_CLOEXEC, 0o644)
        try:
            try:
                os.write(fd, b"1\n" if self._device else b"0\n")
            finally:
                os.close(fd)
            os.replace(tmp, path)
        except OSError:
            tmp.unlink(missing_ok=True)
            raise
        self._mirrored = self._device


def _alive(pid: int) -> bool:
    """Whether process ``pid`` exists (one of another user counts as existing)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True

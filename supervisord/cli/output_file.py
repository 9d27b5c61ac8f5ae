"""Every file a command of this project writes at a path its user names (``srcsctl replay --mcap``
and ``--plot``, the man pages and completions of ``supervisord.cli.reference``): written whole
or not at all, and never through a link, whoever runs it and wherever (SR-11.4;
``docs/srcsctl.md`` "Files srcsctl writes").

A shared folder (group- or world-writable, ``/tmp``) lets another user plant a name before root
writes there. So:

- ``-`` is standard output: written there (made whole in memory first), no file and no
  temporary name;
- a target that is a symbolic link is refused (``/dev/stdout`` is one: ``-`` says that), and so
  is one that exists and is not a regular file (a device, a FIFO, a folder): writing would
  replace the link or the device's name, or write into what the link names;
- otherwise the bytes go to a new file of a random name beside the target (``.NAME.RANDOM.tmp``),
  created exclusively without following a link (``O_CREAT | O_EXCL | O_NOFOLLOW``: a name
  someone planted, a link among them, is never opened, another random name is tried), relative
  to the folder opened once; written, fsynced, then renamed onto the target, which replaces
  whatever is at the name (never opening it) and leaves what a planted link pointed to as it
  was; then the folder is fsynced. A failure removes the temporary file.

The file's permissions are the process's umask applied to 0666, as for a plain ``open``.
"""

from __future__ import annotations

import contextlib
import io
import os
import secrets
import stat
from collections.abc import Callable
from pathlib import Path
from typing import IO, BinaryIO, Final

STANDARD_OUTPUT: Final = "-"
ATTEMPTS: Final = 16
"""Random names tried before giving up: each is 64 bits, so more than one means someone is
creating them on purpose."""


class OutputRefused(Exception):
    """A target this module will not write (a link, not a regular file); the message says
    why and what to give instead."""


def is_standard_output(target: Path | str) -> bool:
    """Whether ``target`` is ``-`` (a file named ``-`` is ``./-``)."""
    return str(target) == STANDARD_OUTPUT


def check_target(target: Path | str) -> None:
    """Refuse ``target`` now if it is a link or exists as something else than a regular file
    (:class:`OutputRefused`). :func:`write_output` checks again when it writes."""
    if is_standard_output(target):
        return
    try:
        mode = os.lstat(target).st_mode
    except FileNotFoundError:
        return
    if stat.S_ISLNK(mode):
        raise OutputRefused(
            f"{target} is a symbolic link: name the file itself, or - for standard output; "
            "a link is never written through or replaced"
        )
    if not stat.S_ISREG(mode):
        raise OutputRefused(
            f"{target} exists and is not a regular file (a device, a FIFO or a folder): "
            "name a new or a regular file, or - for standard output"
        )


def write_output(
    target: Path | str, fill: Callable[[IO[bytes]], object], stdout: BinaryIO | None = None
) -> None:
    """Write what ``fill`` writes to its stream at ``target`` (see the module docstring), or
    to ``stdout`` for ``-``. Raises :class:`OutputRefused`, or ``OSError`` as the system
    says (its ``filename`` the target)."""
    if is_standard_output(target):
        if stdout is None:
            raise OutputRefused("- (standard output) is not taken here")
        # Made whole first: a writer that seeks (MCAP's) cannot on a pipe, and a failure
        # midway then writes nothing.
        made = io.BytesIO()
        fill(made)
        stdout.write(made.getbuffer())
        stdout.flush()
        return
    check_target(target)
    path = Path(target)
    folder = os.open(path.parent, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    try:
        temporary, fd = _create(folder, path.name)
        try:
            with os.fdopen(fd, "wb") as file:
                fill(file)
                file.flush()
                os.fsync(file.fileno())
            # A rename replaces whatever is at the name without opening it: a link planted
            # there since the check is replaced, never written through.
            os.replace(temporary, path.name, src_dir_fd=folder, dst_dir_fd=folder)
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(temporary, dir_fd=folder)
            raise
        # The name's durability, where the file system offers it (some refuse a folder's
        # fsync): the file is written and in place either way.
        with contextlib.suppress(OSError):
            os.fsync(folder)
    except OSError as error:
        if error.filename is None:
            error.filename = str(target)
        raise
    finally:
        os.close(folder)


def _create(folder: int, name: str) -> tuple[str, int]:
    """A new file of a random name beside ``name`` in ``folder``, created by this call and
    no one else (``O_EXCL``), never through a link (``O_NOFOLLOW``)."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC
    for _ in range(ATTEMPTS):
        temporary = f".{name}.{secrets.token_hex(8)}.tmp"
        try:
            return temporary, os.open(temporary, flags, 0o666, dir_fd=folder)
        except FileExistsError:
            continue
    raise FileExistsError(0, f"no free temporary name beside {name} after {ATTEMPTS} tries")

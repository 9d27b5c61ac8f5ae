"""What lets the daemon open a VSC's device it was refused (SR-8.18): the device's group and
the command that puts the daemon's user in it, said where the refusal is (the log, ``status``'s
link error, ``wait-ready``).

Read without the name service: the names come from ``/etc/group`` and ``/etc/passwd`` as
files, never through NSS, whose lookup of a uid the files lack can wait for tens of seconds on
a hung userdb service (docs/faults.md; SR-10.3): this runs in the daemon's loop. An id that the
files lack is said as its number.
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path
from typing import Final

GROUP_FILE: Final = Path("/etc/group")
PASSWD_FILE: Final = Path("/etc/passwd")
DEVICE_GROUP: Final = "srcs-dev"
"""The group the package's udev rule (units/60-srcs.rules) gives a VSC's device to, and the
unit adds to the daemon (``SupplementaryGroups=srcs-dev``)."""


def denied_advice(path: str, error: BaseException) -> str:
    """``"; DEVICE is OWNER:GROUP, mode M: FIX"`` when opening ``path`` was refused for want of
    permission (EACCES, EPERM), else ``""``. Never raises."""
    if getattr(error, "errno", None) not in (errno.EACCES, errno.EPERM):
        return ""
    try:
        info = os.stat(path)
    except OSError:
        return ""
    group = _name(GROUP_FILE, info.st_gid)
    user = _name(PASSWD_FILE, os.geteuid())
    owner = (
        f"{path} is {_name(PASSWD_FILE, info.st_uid)}:{group}, mode {stat.S_IMODE(info.st_mode):o}"
    )
    if info.st_gid == 0:
        return (
            f"; {owner}: the udev rule 60-srcs.rules gives a VSC's device to the group "
            f"{DEVICE_GROUP}, and has not matched this one (udevadm info {path}; "
            'docs/install.md "The USB rule on a real USB device")'
        )
    return (
        f"; {owner}, and the daemon's user {user} is not in {group}: sudo usermod -aG {group} "
        f"{user}, then start the daemon again (the unit srcsd@ runs with "
        f"SupplementaryGroups={DEVICE_GROUP})"
    )


def _name(file: Path, number: int) -> str:
    """The name of uid or gid ``number`` in ``file`` (``name:x:id:...``), else the number."""
    try:
        lines = file.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError:
        return str(number)
    for line in lines:
        fields = line.split(":")
        if len(fields) > 2 and fields[2] == str(number) and fields[0]:
            return fields[0]
    return str(number)

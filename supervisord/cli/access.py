"""What to do about a record that cannot be opened for want of permission, in words: whose the
file or folder is and the one command that lets it be read or written (docs/record.md "Who
may read the record")."""

from __future__ import annotations

import errno
import grp
import os
import pwd
import stat
from pathlib import Path


def advice(path: Path, error_number: int | None) -> str:
    """``": it is USER:GROUP, mode M; WHAT TO DO"`` for a permission refused at ``path``, else
    ``""``: root:root's (what a run of srcsd by hand as root leaves) goes back to the service's
    user; one of any other group is read by joining that group, or with sudo."""
    if error_number not in (errno.EACCES, errno.EPERM):
        return ""
    try:
        info = os.stat(path)
    except OSError:  # the folder above is closed to us as well
        return ": read it as root (sudo), or as a member of the record's group"
    owner = f"it is {_user(info.st_uid)}:{_group(info.st_gid)}, mode {stat.S_IMODE(info.st_mode):o}"
    if info.st_uid == 0 and info.st_gid == 0:
        folder = path if stat.S_ISDIR(info.st_mode) else path.parent
        return (
            f": {owner}, left by a run as root, which the service cannot use; give the record "
            f"back to the service's user: sudo chown -R srcsd:srcsd {folder}"
        )
    group = _group(info.st_gid)
    return (
        f": {owner}; join its group (sudo usermod -aG {group} $USER, then log in again) or use sudo"
    )


def _user(uid: int) -> str:
    try:
        return pwd.getpwuid(uid).pw_name
    except KeyError:
        return str(uid)


def _group(gid: int) -> str:
    try:
        return grp.getgrgid(gid).gr_name
    except KeyError:
        return str(gid)

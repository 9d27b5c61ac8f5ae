"""Who is at the other end of a client connection (SR-8).

The kernel tells us the peer's pid, uid and gid as they were when it connected
(``SO_PEERCRED``): a peer cannot forge them. Admin rights (``reset``, ``commission``)
belong to root, the daemon's own user and members of the configured admin group; a peer's
supplementary groups come from ``/proc/PID/status`` (``Groups:``), read once when the
connection is accepted, and count only while that process still runs with the uid the
kernel reported (so a recycled pid cannot lend its groups to another process).
"""

from __future__ import annotations

import grp
import pwd
import socket
import struct
from dataclasses import dataclass
from pathlib import Path

from supervisord.api.names import uid_text
from supervisord.errors import ConfigError
from supervisord.protocol.text import ascii_digits, clean
from supervisord.safety.events import Caller

_UCRED = struct.Struct("3i")  # struct ucred: pid_t pid, uid_t uid, gid_t gid
PROC = Path("/proc")


@dataclass(frozen=True, slots=True)
class PeerCredentials:
    """The peer's process, user and primary group when it connected."""

    pid: int
    uid: int
    gid: int


def peer_credentials(sock: socket.socket) -> PeerCredentials:
    """The credentials of the peer of a connected ``AF_UNIX`` socket.

    Raises ``OSError`` when the socket has no peer (it was closed meanwhile)."""
    raw = sock.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED, _UCRED.size)
    pid, uid, gid = _UCRED.unpack(raw)
    return PeerCredentials(pid, uid, gid)


def _status_fields(pid: int, proc: Path) -> dict[str, str]:
    try:
        text = (proc / str(pid) / "status").read_text(encoding="ascii", errors="replace")
    except OSError:
        return {}
    fields = {}
    for line in text.splitlines():
        key, sep, value = line.partition(":")
        if sep:
            fields[key] = value.strip()
    return fields


def process_groups(credentials: PeerCredentials, proc: Path = PROC) -> frozenset[int]:
    """The peer's groups: its primary gid and, while its process still runs with the same
    effective uid, the supplementary groups of ``/proc/PID/status``. Never raises: what
    cannot be read does not count."""
    groups = {credentials.gid}
    fields = _status_fields(credentials.pid, proc)
    uids = fields.get("Uid", "").split()  # real, effective, saved, file system
    if len(uids) >= 2 and uids[1] == str(credentials.uid):
        groups.update(int(g) for g in fields.get("Groups", "").split() if ascii_digits(g))
    return frozenset(groups)


def group_id(name: str | None, key: str = "api.admin_group") -> int | None:
    """The gid of the group ``name`` (``None`` for ``None``: only root is admin).

    Raises :class:`ConfigError` naming ``key`` when there is no such group."""
    if name is None:
        return None
    try:
        return grp.getgrnam(name).gr_gid
    except KeyError:
        raise ConfigError(key, name, "name a group that exists (see getent group)") from None


def user_name(uid: int) -> str:
    """The login name of ``uid``, or the number as text when it has none. It may wait on
    another process (NSS): call it only off the loop, as :mod:`supervisord.api.names` does.

    A name that is not UTF-8 (the password database holds bytes; Python hands the bad ones on
    as lone surrogates) is escaped here, at its source: ``r\\xe9mi``. Raw, it would reach the
    record and every reply naming the caller, whose encoders cannot write it (SR-8.7: the
    stop record of that user's ``srcsctl estop`` was lost and ``status`` stopped answering
    before it was escaped)."""
    try:
        return clean(pwd.getpwuid(uid).pw_name)
    except KeyError:
        return uid_text(uid)


def is_admin(
    credentials: PeerCredentials,
    groups: frozenset[int],
    admin_gid: int | None,
    own_uid: int | None = None,
) -> bool:
    """Root, the daemon's own user (``own_uid``), or a member of the admin group
    (``admin_gid``; ``None``: no group)."""
    if credentials.uid in (0, own_uid):
        return True
    return admin_gid is not None and admin_gid in groups


def caller(
    credentials: PeerCredentials,
    admin_gid: int | None,
    proc: Path = PROC,
    *,
    own_uid: int | None = None,
    name: str | None = None,
) -> Caller:
    """The safety core's view of the peer: uid, pid, login name (``name``: as looked up off
    the loop; ``None``: not known yet, the uid stands in) and admin flag. Reads only the
    kernel's numbers (``/proc``), never the user database: it cannot wait (SR-10.3).

    ``/proc/PID/status`` is read only when the groups decide (SR-10.8): not for root or the
    daemon's own user, not without an admin group, not when the primary group is it. The loop
    runs SCHED_FIFO, and opening another process's status file can sleep (its memory map's
    lock, which that process holds while it maps its libraries at start): the kernel's rtapp
    monitor saw the loop woken from below in that ``openat`` as a root ``srcsctl`` connected."""
    if credentials.uid in (0, own_uid) or admin_gid in (None, credentials.gid):
        groups = frozenset({credentials.gid})
    else:
        groups = process_groups(credentials, proc)
    admin = is_admin(credentials, groups, admin_gid, own_uid)
    shown = uid_text(credentials.uid) if name is None else name
    return Caller(credentials.uid, credentials.pid, shown, admin)

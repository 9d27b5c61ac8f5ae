"""Where ``srcsctl decode`` gets CAN frames and serial bytes besides text: the capture files
python-can's ``LogReader`` reads, a live CAN interface and a live serial port.

Every source here is read-only: no frame is sent on a bus, no byte is written to a port and
no interface is configured (docs/protocol.md "srcsctl decode").
"""

from __future__ import annotations

import fcntl
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import can
import serial

from supervisord.links.can_link import UDP_MULTICAST_HOP_LIMIT
from supervisord.links.serial_link import BAUD

LOG_SUFFIXES = frozenset({".asc", ".blf", ".csv", ".db", ".mf4", ".trc"})
"""The suffixes whose files python-can's readers decode (each also gzip-compressed, ``.gz``).

candump's ``.log`` is not among them: ``decode``'s own candump reader takes it, which skips a
bad line and goes on where python-can's reader stops at the first (docs/protocol.md)."""
POLL_S = 0.5  # a blocking read returns this often, so Ctrl-C and SIGTERM are seen promptly


class CaptureError(Exception):
    """A capture that cannot be read (on, or from some frame); the message says why."""


def log_suffix(path: str) -> str | None:
    """The python-can format of ``path`` by its suffix (``.asc`` for ``x.ASC.gz``), or None."""
    suffixes = [suffix.lower() for suffix in Path(path).suffixes]
    if suffixes and suffixes[-1] == ".gz":
        suffixes.pop()
    suffix = suffixes[-1] if suffixes else None
    return suffix if suffix in LOG_SUFFIXES else None


def read_log(path: str) -> Iterator[can.Message]:
    """The messages of a capture file in python-can's formats, in file order.

    A reader's failure, on opening or mid-file, is a :class:`CaptureError` (python-can's
    readers stop at the first unreadable record; the messages before it have been yielded).
    ``.asc`` times are read as absolute (from its ``Begin Triggerblock`` date), not relative
    to the start of the file, so that every format gives the capture's own wall-clock time.
    """
    options: dict[str, Any] = {"relative_timestamp": False} if log_suffix(path) == ".asc" else {}
    try:
        reader = can.LogReader(path, **options)
    except OSError:
        raise  # the caller reports a missing or unreadable file as for every format
    except NotImplementedError as error:  # .mf4 without asammdf
        raise CaptureError(
            f"{error} (.mf4 needs python-can's optional dependency asammdf: python-can[mf4])"
        ) from error
    except Exception as error:  # a third-party parser of untrusted input
        raise CaptureError(f"not readable as {log_suffix(path)}: {error!r}") from error
    count = 0
    with reader:
        messages = iter(reader)
        while True:
            try:
                message = next(messages)
            except StopIteration:
                return
            except Exception as error:  # as above: report and stop
                raise CaptureError(f"unreadable after {count} frames: {error!r}") from error
            count += 1
            yield message


def open_bus(interface: str, channel: str) -> can.BusABC:
    """A python-can bus to listen on, opened without configuring it: no ``bitrate`` (that
    would reconfigure a SocketCAN interface, which the supervisor or the system owns), and
    for ``udp_multicast`` the project's hop limit of 0 (docs/testing.md "Network")."""
    options: dict[str, Any] = {}
    if interface == "udp_multicast":
        options["hop_limit"] = UDP_MULTICAST_HOP_LIMIT
    return can.Bus(interface=interface, channel=channel, **options)


def follow_bus(bus: can.BusABC) -> Iterator[can.Message]:
    """Every frame the bus receives, as it comes, until the caller stops iterating.

    Only ``recv`` is ever called: this never sends (docs/protocol.md "srcsctl decode")."""
    while True:
        message = bus.recv(timeout=POLL_S)
        if message is not None:
            yield message


def open_port(path: str) -> serial.Serial:
    """A serial port to listen on at the VSC's 115200 8N1 (manual §8).

    Refused when another process holds the port's lock, as ``srcsd``'s serial link does
    (pyserial's ``exclusive``, an advisory ``flock``): two readers of one line each take
    bytes from the other, and taking the supervisor's would make it stop the robot. The lock
    is only probed, not kept, so that decode never locks the supervisor out of its port
    either (docs/protocol.md "Following a live port or bus")."""
    port = serial.Serial(path, BAUD, timeout=POLL_S, exclusive=False)
    try:
        fcntl.flock(port.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        fcntl.flock(port.fileno(), fcntl.LOCK_UN)
    except OSError as error:
        port.close()
        raise CaptureError(
            "held by another process (srcsd?); on a robot the supervisor owns its port: "
            "follow a tap or tee of the line instead"
        ) from error
    return port


def follow_port(port: serial.Serial) -> Iterator[tuple[float, bytes]]:
    """``(wall-clock time, bytes)`` as the port delivers them; never writes.

    The time is when the read returned, for the ``capture_time`` of the frames the bytes
    complete: like python-can's, a label of the capture, never used for a deadline."""
    while True:
        try:
            chunk = port.read(max(1, port.in_waiting))
        except (serial.SerialException, OSError) as error:
            raise CaptureError(str(error) or "read failed") from error
        if chunk:
            yield time.time(), chunk

"""The serial link: HRI packets over USB CDC or RS-232 at 115200 8N1 (manual §8)."""

from __future__ import annotations

import contextlib
import functools
import os
import threading
from collections.abc import Callable

import serial

from supervisord.links.base import Incoming, Link, LinkBrokenError, LinkError
from supervisord.links.denied import denied_advice
from supervisord.protocol.framing import FrameDecoder, encode_frame
from supervisord.protocol.messages import Message, UserHeartbeat

BAUD = 115200  # manual §8: fixed
READ_LIMIT = 4096  # far more than arrives in a turn: one read takes everything waiting


class SerialLink(Link):
    """A serial port, opened exclusively and read without blocking.

    An unplugged USB device (or a closed pseudo-terminal master) shows as a read that is
    ready but returns nothing, or as an I/O error: both are ``LinkBrokenError``. Every open starts
    a fresh decoder, so no half frame survives a reconnect.
    """

    prepares_open = True
    """A tty's open takes the kernel's global ``tty_mutex``, a USB serial port's sends the
    device its control requests and waits for them (``cdc_acm``), and the emptying of what
    waited (``tcflush``) waits for the tty's buffer lock, which the work that hands received
    bytes to the line discipline holds (``flush_to_ldisc``): each a sleep in which an
    ordinary thread or a softirq wakes the loop, which the judged kernel saw in the
    reopen after a replug (docs/system-tier.md). So the port is opened off the loop
    (:meth:`prepare`, SR-9.8). What arrives between the emptying and the loop's first read
    counts from that read, as every byte does (SR-2.11): once an open, that read may come up to
    the link port's ``PREPARE_POLL_NS`` (10 ms) after it arrived, and a heartbeat in it is taken
    for that much fresher, against a link loss of 50 ms at the shortest (``vsc.timeout_ms``)."""

    def __init__(self, port: str) -> None:
        self._path = port
        self._port: serial.Serial | None = None
        self._fd: int | None = None  # the port's descriptor while open, read once at open
        self._prepared: serial.Serial | LinkError | None = None  # prepare's port or error
        self._prepared_lock = threading.Lock()
        self._decoder = FrameDecoder()
        # The user heartbeat goes out 20 times a second with one of two bytes (SR-5.1): its
        # frames are encoded once (SR-9.4). At most 256 entries, one per byte value.
        self._heartbeats: dict[UserHeartbeat, bytes] = {}

    @property
    def description(self) -> str:
        return f"serial {self._path}"

    @property
    def is_open(self) -> bool:
        return self._port is not None

    def prepare(self) -> None:
        """Open the port, for :meth:`open` to take (on the link port's ``srcsd-open`` thread,
        at ordinary priority)."""
        opened = self._open_port()
        with self._prepared_lock:
            self._prepared = opened

    def open(self) -> None:
        """Take the port :meth:`prepare` opened, or open it here when nothing was prepared."""
        if self._port is not None:
            return
        with self._prepared_lock:
            opened, self._prepared = self._prepared, None
        if opened is None:
            opened = self._open_port()
        if isinstance(opened, LinkError):
            raise opened
        self._port = opened
        self._fd = opened.fileno()
        self._decoder = FrameDecoder()

    def _open_port(self) -> serial.Serial | LinkError:
        """The port opened and emptied, or why it could not be."""
        try:
            port = serial.Serial(self._path, BAUD, timeout=0, write_timeout=0, exclusive=True)
        except (serial.SerialException, OSError, ValueError) as error:
            # A device the daemon may not open names its group and the fix (SR-8.18).
            return _caused(LinkError(_short(error) + denied_advice(self._path, error)), error)
        try:
            # Discard what waited in the port (tcflush TCIFLUSH): a VSC's old heartbeats must
            # never be read as current (SR-2.2, SR-2.11: a heartbeat counts from
            # when it was received). pyserial 3.5 flushes in open too; this does not rely on it.
            port.reset_input_buffer()
        except (serial.SerialException, OSError) as error:
            _close_port(port)
            return _caused(LinkError(_short(error)), error)
        return port

    def fileno(self) -> int | None:
        return self._fd

    def receive(self) -> list[Incoming]:
        fd = self._require_open()
        try:
            data = os.read(fd, READ_LIMIT)
        except BlockingIOError:
            return []
        except OSError as error:
            raise LinkBrokenError(_short(error)) from error
        if not data:  # readable but empty: the device is gone (pyserial's wording, see above)
            raise LinkBrokenError("device reports readiness to read but returned no data")
        # A new list each time, of a narrower type: returned as it is, not copied (SR-9.4).
        return self._decoder.feed(data)  # type: ignore[return-value]

    def send(self, messages: list[Message]) -> None:
        fd = self._require_open()
        if len(messages) == 1:  # the usual: the user heartbeat alone (SR-9.4)
            data = self._encode(messages[0])
        else:
            data = b"".join([self._encode(message) for message in messages])
        try:
            written = os.write(fd, data) if data else 0
        except BlockingIOError:
            written = 0
        except OSError as error:
            raise LinkBrokenError(_short(error)) from error
        if written != len(data):
            # The VSC reads at 115200 baud and our traffic is a few hundred bytes a second:
            # an output buffer that is full means nobody is reading.
            raise LinkBrokenError(f"output buffer full: wrote {written} of {len(data)} bytes")

    def _encode(self, message: Message) -> bytes:
        if type(message) is not UserHeartbeat:
            return encode_frame(message)
        frame = self._heartbeats.get(message)
        if frame is None:
            frame = self._heartbeats[message] = encode_frame(message)
        return frame

    def close(self) -> None:
        port, self._port, self._fd = self._port, None, None
        with self._prepared_lock:  # a prepared port never taken is closed too
            prepared, self._prepared = self._prepared, None
        for each in (port, prepared):
            if isinstance(each, serial.Serial):
                _close_port(each)

    def detach(self) -> Callable[[], None] | None:
        """Closed to the loop at once; the port's close is returned, to run off the loop
        (SR-9.8). A tty's release waits for the tty's lock, which the hang-up of an unplugged
        USB device holds while the hub's work runs (``tty_release`` and ``__tty_hangup``, the
        kernel's drivers/tty/tty_io.c), and for the global ``tty_mutex`` that other ttys'
        closes hold: on the judged kernel the loop was woken from that wait by ordinary
        threads, once 8.5 ms and then 2.3 ms more after the unplug (docs/system-tier.md)."""
        port, self._port, self._fd = self._port, None, None
        return None if port is None else functools.partial(_close_port, port)

    def _require_open(self) -> int:
        if self._fd is None:
            raise LinkBrokenError("not open")
        return self._fd


def _caused(error: LinkError, cause: BaseException) -> LinkError:
    """``error`` as raised ``from cause``, to be raised later (by :meth:`SerialLink.open`)."""
    error.__cause__ = cause
    return error


def _close_port(port: serial.Serial) -> None:
    """Close ``port``: its descriptor is released even when the device is already gone."""
    with contextlib.suppress(serial.SerialException, OSError):
        port.close()


def _short(error: BaseException) -> str:
    if isinstance(error, OSError) and error.strerror:
        return error.strerror
    return str(error) or type(error).__name__

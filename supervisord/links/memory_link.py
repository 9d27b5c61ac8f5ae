"""A link held in memory: the serial protocol's bytes (HRI frames, manual §8) between the
supervisor's side and a far end that a test holds, with no port, bus or thread.

The link encodes with ``protocol.framing.encode_frame`` and decodes with a
``protocol.framing.FrameDecoder``, as the serial link does: what a test writes at the far end
are the bytes a VSC would send, and what it reads there are the bytes the supervisor sent. It
passes the links' conformance suite (docs/protocol.md "Links").
"""

from __future__ import annotations

from supervisord.links.base import Incoming, Link, LinkBrokenError, LinkError
from supervisord.protocol.framing import FrameDecoder, encode_frame
from supervisord.protocol.messages import Message


class MemoryPort:
    """The VSC's end of a :class:`MemoryLink`: bytes each way, and a plug.

    ``unplug`` is the USB cable pulled: what was in flight is lost, an open link finds the
    port gone at its next ``receive`` or ``send``, and none opens until ``replug``.
    """

    def __init__(self, name: str = "memory") -> None:
        self.name = name
        self.plugged = True
        self.plugs = 1
        """How many times the port was plugged in: a link opened on an earlier plug is broken."""
        self.to_host = bytearray()
        self.to_vsc = bytearray()

    def write(self, data: bytes) -> None:
        """Send ``data`` to the supervisor's side, as the VSC's UART would."""
        if self.plugged:
            self.to_host += data

    def send(self, *messages: Message) -> None:
        """Send ``messages`` as the protocol's frames."""
        self.write(b"".join(encode_frame(message) for message in messages))

    def read(self) -> bytes:
        """Everything the supervisor's side wrote since the last read."""
        data = bytes(self.to_vsc)
        self.to_vsc.clear()
        return data

    def unplug(self) -> None:
        self.plugged = False
        self.to_host.clear()
        self.to_vsc.clear()

    def replug(self) -> None:
        if not self.plugged:
            self.plugged = True
            self.plugs += 1


class MemoryLink(Link):
    """The supervisor's end of a :class:`MemoryPort`. It has no descriptor, so a loop polls
    ``receive``; like the serial link, each open discards what waited in the port (a VSC's old
    heartbeats are never current: SR-2.2) and starts a fresh decoder."""

    def __init__(self, port: MemoryPort) -> None:
        self._port = port
        self._plug: int | None = None  # the port's plug this link opened on, while open
        self._decoder = FrameDecoder()

    @property
    def description(self) -> str:
        return f"memory {self._port.name}"

    @property
    def is_open(self) -> bool:
        return self._plug is not None

    def open(self) -> None:
        if self._plug is not None:
            return
        if not self._port.plugged:
            raise LinkError("No such device")
        self._port.to_host.clear()
        self._decoder = FrameDecoder()
        self._plug = self._port.plugs

    def fileno(self) -> int | None:
        return None

    def receive(self) -> list[Incoming]:
        self._require_plugged()
        data = bytes(self._port.to_host)
        self._port.to_host.clear()
        return list(self._decoder.feed(data))

    def send(self, messages: list[Message]) -> None:
        self._require_plugged()
        self._port.to_vsc += b"".join(encode_frame(message) for message in messages)

    def close(self) -> None:
        self._plug = None

    def _require_plugged(self) -> None:
        if self._plug is None:
            raise LinkBrokenError("not open")
        if not self._port.plugged or self._port.plugs != self._plug:
            raise LinkBrokenError("device gone")

"""What the in-memory link promises beyond the links' conformance suite: as the serial link
does, it never reads a VSC's old heartbeats as current (SR-2.2), and a replug between two
reads is still an unplug."""

from __future__ import annotations

import pytest

from supervisord.links.base import LinkBrokenError, LinkError
from supervisord.links.memory_link import MemoryLink, MemoryPort
from supervisord.protocol.messages import VscHeartbeat


def test_what_waited_in_the_port_before_open_is_discarded() -> None:
    """Heartbeats written before the link opened are never read: the first thing read is what
    came after."""
    port = MemoryPort()
    port.send(VscHeartbeat(9), VscHeartbeat(4, 0, 1))
    link = MemoryLink(port)
    link.open()
    port.send(VscHeartbeat(11))
    assert link.receive() == [VscHeartbeat(11)]


def test_an_unplug_and_replug_between_reads_breaks_the_link() -> None:
    """A port unplugged and plugged in again before the link read is a new device: the link
    opened on the old one is broken, a new open works, and nothing is open while unplugged."""
    port = MemoryPort()
    link = MemoryLink(port)
    link.open()
    port.unplug()
    port.replug()
    port.send(VscHeartbeat(9))
    with pytest.raises(LinkBrokenError, match="device gone"):
        link.receive()
    link.close()
    port.unplug()
    with pytest.raises(LinkError):
        link.open()
    port.replug()
    link.open()
    port.send(VscHeartbeat(9))
    assert link.receive() == [VscHeartbeat(9)]

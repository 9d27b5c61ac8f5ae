"""The registry of link kinds: a VSC transport to the link that speaks it.

As ``supervisord.outputs.registry`` does for outputs, each transport (``[vsc] transport``,
:class:`~supervisord.safety.config.Transport`) names the builder of its link, and that builder
imports the link's module only when its transport is chosen: a serial or HID robot never
imports python-can, which costs several MB resident and tens of ms of start-up (SR-9.4;
docs/performance.md "Start-up and memory"). No link imports the registry, and the base class
knows no link.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Final

from supervisord.config.model import CanBus, HidDevice, SerialPort, VscConfig
from supervisord.links.base import Link
from supervisord.safety.config import Transport


def _serial(vsc: VscConfig) -> Link:
    from supervisord.links.serial_link import SerialLink  # noqa: PLC0415 -- chosen transport only

    assert isinstance(vsc.link, SerialPort)  # the loader pairs each transport with its table
    return SerialLink(str(vsc.link.port))


def _can(vsc: VscConfig) -> Link:
    from supervisord.links.can_link import CanLink  # noqa: PLC0415 -- chosen transport only

    assert isinstance(vsc.link, CanBus)
    errors = vsc.can_errors  # docs/safety.md "CAN error frames"
    return CanLink(
        vsc.link.interface,
        str(vsc.link.channel),
        vsc.link.bitrate,
        error_limit=errors.limit,
        error_window_ms=errors.window_ms,
        error_passive_ms=errors.passive_ms,
    )


def _hid(vsc: VscConfig) -> Link:
    from supervisord.links.hid_link import HidLink  # noqa: PLC0415 -- chosen transport only

    assert isinstance(vsc.link, HidDevice)
    return HidLink(str(vsc.link.hidraw))


BUILDERS: Final[Mapping[Transport, Callable[[VscConfig], Link]]] = {
    Transport.SERIAL: _serial,
    Transport.CAN: _can,
    Transport.HID: _hid,
}
"""Each transport's builder: the ``[vsc]`` section to a new link, not yet open."""


def create_link(vsc: VscConfig) -> Link:
    """A new, not yet open link to the VSC as ``vsc`` describes it, built by its transport."""
    return BUILDERS[vsc.transport](vsc)

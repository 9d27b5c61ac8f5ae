"""The CAN error limits as ``[vsc]`` keys (docs/safety.md "CAN error frames"): their
defaults are the link's own, each reaches the real CanLink built from the config (python-can's
virtual interface), and a bad value is refused naming the key."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path

import can
import pytest

from supervisord.config import CanErrors
from supervisord.daemon.assemble import build_link
from supervisord.links.base import LinkBrokenError
from supervisord.links.can_link import (
    ERROR_LIMIT,
    ERROR_PASSIVE_MS,
    ERROR_WINDOW_MS,
    CanLink,
    to_python_can,
)
from supervisord.protocol.j1939 import encode_can
from supervisord.protocol.messages import VscHeartbeat
from tests.config.test_config_rules import CAN_VSC, check, load

CHANNEL = "config-can-errors"
VIRTUAL = {**CAN_VSC, "interface": "virtual", "channel": CHANNEL}


@pytest.fixture
def vsc_bus() -> Iterator[can.BusABC]:
    with can.Bus(interface="virtual", channel=CHANNEL) as bus:
        yield bus


def error_frame(class_bits: int = 0x08, detail: int = 0) -> can.Message:
    """A SocketCAN error frame: the class in the identifier, details in data[1]."""
    return can.Message(
        arbitration_id=class_bits, data=bytes([0, detail, 0, 0, 0, 0, 0, 0]), is_error_frame=True
    )


def drain(link: CanLink) -> list[object]:
    received: list[object] = []
    for _ in range(20):
        received += link.receive()
    return received


def link_from(tmp_path: Path, **keys: object) -> CanLink:
    """The VSC link the daemon would build from a CAN config with ``keys`` in ``[vsc]``."""
    config = load(tmp_path, {"vsc": {**VIRTUAL, **keys}})
    link = build_link(config)
    assert isinstance(link, CanLink)
    link.open()
    return link


def test_can_error_limits_default_to_the_documented_values(tmp_path: Path) -> None:
    """Without the keys a CAN VSC gets more than 16 error frames in 1 s and error-passive for
    1 s, the link's own defaults (one truth for both)."""
    config = load(tmp_path, {"vsc": CAN_VSC})
    assert config.vsc.can_errors == CanErrors(limit=16, window_ms=1000, passive_ms=1000)
    assert config.vsc.can_errors == CanErrors(ERROR_LIMIT, ERROR_WINDOW_MS, ERROR_PASSIVE_MS)


def test_error_limit_and_window_from_the_config_reach_the_link(
    tmp_path: Path, vsc_bus: can.BusABC
) -> None:
    """With ``error_limit = 2``, two error frames in the window are counted and stop nothing;
    a third breaks the link, naming the configured window."""
    link = link_from(tmp_path, error_limit=2, error_window_ms=500)
    try:
        for _ in range(2):
            vsc_bus.send(error_frame())
        vsc_bus.send(to_python_can(encode_can(VscHeartbeat(9))))
        assert drain(link) == [VscHeartbeat(9)]
        assert link.error_frames == 2
        vsc_bus.send(error_frame())
        with pytest.raises(LinkBrokenError, match="3 CAN error frames within 500 ms"):
            drain(link)
    finally:
        link.close()


def test_error_passive_time_from_the_config_reaches_the_link(
    tmp_path: Path, vsc_bus: can.BusABC
) -> None:
    """With ``error_passive_ms = 50``, a controller error-passive for 80 ms breaks the link."""
    link = link_from(tmp_path, error_passive_ms=50)
    try:
        vsc_bus.send(error_frame(0x04, 0x10))  # controller problem: RX error-passive
        drain(link)
        time.sleep(0.08)
        vsc_bus.send(to_python_can(encode_can(VscHeartbeat(9))))
        with pytest.raises(LinkBrokenError, match="error-passive for 50 ms"):
            drain(link)
    finally:
        link.close()


def test_a_zero_limit_makes_every_error_frame_a_fault(tmp_path: Path, vsc_bus: can.BusABC) -> None:
    """``error_limit = 0`` is the strictest policy an integrator may choose: the first error
    frame breaks the link."""
    link = link_from(tmp_path, error_limit=0)
    try:
        vsc_bus.send(error_frame())
        with pytest.raises(LinkBrokenError, match="1 CAN error frames"):
            drain(link)
    finally:
        link.close()


@pytest.mark.parametrize(
    ("key", "value", "fix"),
    [
        ("error_limit", -1, "from 0 to 1000"),
        ("error_limit", 1001, "from 0 to 1000"),
        ("error_limit", "16", "without quotes"),
        ("error_limit", True, "without quotes"),
        ("error_window_ms", 99, "from 100 to 10000"),
        ("error_window_ms", 10_001, "from 100 to 10000"),
        ("error_passive_ms", -1, "from 0 to 10000"),
        ("error_passive_ms", 10_001, "from 0 to 10000"),
        ("error_passive_ms", 1.5, "whole number"),
    ],
)
def test_out_of_range_error_limits_are_refused(
    tmp_path: Path, key: str, value: object, fix: str
) -> None:
    """Each CAN error key outside its range, or not a whole number, is refused by name."""
    check(tmp_path, {"vsc": {**CAN_VSC, key: value}}, f"vsc.{key}", fix)


@pytest.mark.parametrize("key", ["error_limit", "error_window_ms", "error_passive_ms"])
def test_error_limits_on_a_serial_vsc_are_refused(tmp_path: Path, key: str) -> None:
    """A serial VSC has no CAN error frames: the keys are refused, naming the transport."""
    check(tmp_path, {f"vsc.{key}": 16}, f"vsc.{key}", 'applies to transport "can", not "serial"')


def test_error_limits_are_not_output_bus_keys(tmp_path: Path) -> None:
    """``[output_bus]`` only sends enable frames; its errors are not read, so the keys are
    refused there."""
    changes = {
        "vsc": CAN_VSC,
        "outputs[1]": {
            "name": "brake",
            "kind": "can",
            "role": "power",
            "arbitration_id": 0x201,
            "data_on": "01",
            "data_off": "00",
        },
        "output_bus": {"interface": "virtual", "channel": "other", "error_limit": 4},
    }
    check(tmp_path, changes, "output_bus.error_limit", "unknown key")

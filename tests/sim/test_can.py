"""The simulator on CAN (manual §9): python-can's ``virtual`` bus in this process, and
``udp_multicast`` between this process and a real ``srcs-sim``."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path

import can
import pytest

from supervisord.links.can_link import bus_options
from supervisord.protocol.codes import VscMode
from supervisord.protocol.j1939 import (
    CanFrame,
    Hand,
    JoystickBasic,
    JoystickExtended,
    decode_can,
    encode_can,
    feedback_string_frames,
    j1939_value,
)
from supervisord.protocol.messages import Axis, FeedbackSet, Joystick, VscHeartbeat
from supervisord.sim.can_side import CanSide, can_frames
from supervisord.sim.engine import Simulator
from supervisord.sim.model import VscModel
from supervisord.sim.process import SimProcess


def to_can(frame: CanFrame) -> can.Message:
    return can.Message(arbitration_id=frame.arbitration_id, data=frame.data, is_extended_id=True)


def collect(bus: can.BusABC, seconds: float, sim: Simulator | None = None) -> list[can.Message]:
    """Frames received in ``seconds``, stepping the in-process simulator meanwhile."""
    got: list[can.Message] = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if sim is not None:
            sim.step(time.monotonic())
        message = bus.recv(timeout=0.005)
        if message is not None:
            got.append(message)
    return got


def decoded(messages: list[can.Message]) -> list[object]:
    return [
        decode_can(CanFrame(m.arbitration_id, bytes(m.data)))
        for m in messages
        if not m.is_error_frame
    ]


@pytest.fixture
def virtual_sim() -> Iterator[tuple[Simulator, can.BusABC]]:
    channel = f"sim-test-{time.monotonic_ns()}"
    side = CanSide("virtual", channel)
    sim = Simulator(side, VscModel(time.monotonic(), transport="can", link_delay=0.0), log=print)
    host = can.Bus(interface="virtual", channel=channel)
    try:
        yield sim, host
    finally:
        host.shutdown()
        sim.close()


def test_can_traffic_at_the_manual_rates_and_the_joystick_in_four_frames(
    virtual_sim: tuple[Simulator, can.BusABC],
) -> None:
    sim, host = virtual_sim
    now = time.monotonic()
    sim.model.takeover(now)
    sim.model.set_axes({"left_x": 400, "right_z": -90}, now)
    sim.model.set_buttons({"down", "button_2"}, now)
    values = decoded(collect(host, 1.0, sim))
    beats = [v for v in values if isinstance(v, VscHeartbeat)]
    assert 7 <= len(beats) <= 12  # 10 Hz (table 23)
    assert all(b.mode == VscMode.OPERATIONAL for b in beats)
    basics = [v for v in values if isinstance(v, JoystickBasic)]
    extended = [v for v in values if isinstance(v, JoystickExtended)]
    left = [b for b in basics if b.hand is Hand.LEFT]
    assert 10 <= len(left) <= 20  # ~16 Hz
    assert j1939_value(left[-1].x) == 400
    assert left[-1].buttons.pressed == {"down"}
    right = [b for b in basics if b.hand is Hand.RIGHT]
    assert right[-1].buttons.pressed == {"button_2"}
    right_z = [e for e in extended if e.hand is Hand.RIGHT]
    assert j1939_value(right_z[-1].z) == -90


def test_can_frames_never_carry_a_reserved_magnitude_as_a_deflection() -> None:
    """PR-3.2: the simulator's CAN edge sends a full deflection (1022 or 1023 asked) as 1021,
    so the frames never carry the J1939 error or not-available marker as a value."""
    joystick = Joystick(
        left_x=Axis.from_value(1023),
        left_y=Axis.from_value(-1022),
        left_z=Axis.from_value(1021),
        right_x=Axis.from_value(-1023),
        right_y=Axis.from_value(400),
    )
    sent = [decode_can(frame) for frame in can_frames(joystick)]
    axes = [a for m in sent if isinstance(m, JoystickBasic) for a in (m.x, m.y)]
    axes += [m.z for m in sent if isinstance(m, JoystickExtended)]
    assert all(axis.magnitude <= 1021 for axis in axes)
    assert sorted(j1939_value(axis) or 0 for axis in axes) == [-1021, -1021, 0, 400, 1021, 1021]


def test_sim_full_deflection_on_can_reads_as_a_value(
    virtual_sim: tuple[Simulator, can.BusABC],
) -> None:
    """PR-3.2: sticks at -1023 and 1023 in the CAN simulator reach the bus as -1021 and 1021,
    values and not markers."""
    sim, host = virtual_sim
    now = time.monotonic()
    sim.model.takeover(now)
    sim.model.set_axes({"left_x": 1023, "right_z": -1023}, now)
    values = decoded(collect(host, 0.5, sim))
    left = [v for v in values if isinstance(v, JoystickBasic) and v.hand is Hand.LEFT]
    right_z = [v for v in values if isinstance(v, JoystickExtended) and v.hand is Hand.RIGHT]
    assert left
    assert right_z
    assert j1939_value(left[-1].x) == 1021
    assert j1939_value(right_z[-1].z) == -1021


def test_can_feedback_values_and_joined_strings(virtual_sim: tuple[Simulator, can.BusABC]) -> None:
    """manual §9.2.6 values; §9.2.7 the VSC joins three 6-character segments into 18 characters."""
    sim, host = virtual_sim
    host.send(to_can(encode_can(FeedbackSet(4, 321))))
    for frame in feedback_string_frames(4, "Battery voltage V"):
        host.send(to_can(frame))
    host.send(to_can(encode_can(FeedbackSet(12, 1))))
    collect(host, 0.2, sim)
    assert sim.model.values[4] == 321
    assert sim.model.labels[4] == "Battery voltage V"
    assert sim.model.vibration_count == 1


def test_can_estop_and_bus_off(virtual_sim: tuple[Simulator, can.BusABC]) -> None:
    sim, host = virtual_sim
    collect(host, 0.1, sim)
    now = time.monotonic()
    sim.request({"cmd": "estop"}, now)
    beats = [v for v in decoded(collect(host, 0.3, sim)) if isinstance(v, VscHeartbeat)]
    assert beats[-1] == VscHeartbeat(VscMode.LOCAL, 0, 0x01)
    assert sim.request({"cmd": "bus_off", "on": True}, time.monotonic())["bus_off"] is True
    after = collect(host, 0.3, sim)
    assert [m.is_error_frame for m in after] == [True]  # one error frame, then silence
    sim.request({"cmd": "bus_off", "on": False}, time.monotonic())
    assert decoded(collect(host, 0.3, sim))


@pytest.mark.usefixtures("private_network")
def test_srcs_sim_on_udp_multicast(tmp_path: Path) -> None:
    """Between processes on this machine: a real ``srcs-sim --can udp_multicast:...``."""
    group = "239.74.163.77"
    host = can.Bus(interface="udp_multicast", channel=group, **bus_options("udp_multicast", 0))
    try:
        with SimProcess(tmp_path, can=f"udp_multicast:{group}", link_delay=0.0) as sim:
            assert sim.serial_path is None
            sim.control.wait_for(lambda s: s["linked"])
            sim.control.takeover()
            beats = [v for v in decoded(collect(host, 0.5)) if isinstance(v, VscHeartbeat)]
            assert VscHeartbeat(VscMode.OPERATIONAL) in beats
            host.send(to_can(encode_can(FeedbackSet(2, 77))))
            sim.control.wait_for(lambda s: s["values"].get("2") == 77)
            sim.control.bus_off(True)
            frames = collect(host, 0.3)
            assert any(m.is_error_frame for m in frames)
            collect(host, 0.1)
            assert collect(host, 0.3) == []
            state = sim.control.state()
            assert state["transport"] == "can"
            assert state["bus_off"] is True
    finally:
        host.shutdown()

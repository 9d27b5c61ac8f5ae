"""``srcs-sim`` on a device it does not own: ``--tty`` (the device's end of a serial line, a USB
gadget's ``/dev/ttyGS0`` in the system tier) and ``--hid`` (a HID function's end, the gadget's
``/dev/hidg0``). Here a real pseudo-terminal's slave end stands in for the device's end and the
test is the host on its master end; the USB gadget itself runs in the system tier's
``usb_*`` scenarios (docs/system-tier.md)."""

from __future__ import annotations

import os
import select
import time
import tty
from collections.abc import Iterator
from pathlib import Path

import pytest

from supervisord.protocol.codes import VscMode
from supervisord.protocol.framing import Decoded, FrameDecoder, encode_frame
from supervisord.protocol.hid import (
    INPUT_LENGTH,
    DPadDirection,
    HidInput,
    HidOutput,
    decode_hid_input,
    encode_hid_output,
)
from supervisord.protocol.messages import FeedbackGet, FeedbackSet, UserHeartbeat, VscHeartbeat
from supervisord.sim.engine import Simulator
from supervisord.sim.hid_side import HidSide
from supervisord.sim.model import VscModel
from supervisord.sim.process import SimProcess


class Line:
    """A pseudo-terminal: ``device`` is the path of the end the simulator opens, ``host``
    the other end's descriptor."""

    def __init__(self) -> None:
        self.host, slave = os.openpty()
        tty.setraw(self.host)
        os.set_blocking(self.host, False)
        self.device = Path(os.ttyname(slave))
        os.close(slave)  # the simulator opens it by its path, as /dev/ttyGS0

    def read(self, seconds: float) -> bytes:
        data = b""
        end = time.monotonic() + seconds
        while (left := end - time.monotonic()) > 0:
            if select.select([self.host], [], [], left)[0]:
                try:
                    data += os.read(self.host, 65536)
                except (BlockingIOError, OSError):
                    continue
        return data

    def close(self) -> None:
        os.close(self.host)


@pytest.fixture
def line() -> Iterator[Line]:
    made = Line()
    yield made
    made.close()


def test_tty_speaks_the_serial_protocol_on_an_existing_device(tmp_path: Path, line: Line) -> None:
    """PR-2.10: with ``--tty`` the simulator opens a device that already exists and speaks the
    serial protocol on it: heartbeats out, the host's frames in (a Feedback Get answered, user
    heartbeats counted), the e-stop in the next heartbeat; ``state`` names the device and when
    the first frame of the e-stop left (the start of a stop-latency measurement), which the
    host's answer to it does not move, and which is null once the word is 0 again."""
    with SimProcess(tmp_path, tty=line.device, ready_timeout=30) as sim:
        assert sim.serial_path is None
        state = sim.control.wait_for(lambda s: s["linked"])
        assert (state["transport"], state["port"]) == ("serial", str(line.device))
        decoder = FrameDecoder()
        events: list[Decoded] = decoder.feed(line.read(0.5))
        assert any(isinstance(e, VscHeartbeat) and e.mode == VscMode.LOCAL for e in events)
        os.write(line.host, encode_frame(FeedbackGet(85)) + encode_frame(UserHeartbeat(0)))
        answer: list[Decoded] = []
        end = time.monotonic() + 10
        while FeedbackSet(85, 0) not in answer and time.monotonic() < end:
            answer += decoder.feed(line.read(0.1))
        assert FeedbackSet(85, 0) in answer
        assert sim.control.wait_for(lambda s: s["host_frames"] >= 2)["user_heartbeat_age"] >= 0
        before = time.monotonic()
        sim.control.estop()
        stopped = sim.control.wait_for(lambda s: s["estop_sent"] == 0x01)
        assert before <= stopped["estop_sent_at"] <= time.monotonic()
        later = decoder.feed(line.read(0.5))
        assert VscHeartbeat(VscMode.LOCAL, 0, 0x01) in later
        # The host's answer adds its bit (0x40): still the same e-stop, the same first frame.
        os.write(line.host, encode_frame(UserHeartbeat(1)))
        asked = sim.control.wait_for(lambda s: s["estop_sent"] == 0x41)
        assert asked["estop_sent_at"] == stopped["estop_sent_at"]
        sim.control.release()
        os.write(line.host, encode_frame(UserHeartbeat(0)))
        clear = sim.control.wait_for(lambda s: s["estop_sent"] == 0)
        assert clear["estop_sent_at"] is None


def test_tty_lives_through_the_host_going_away(tmp_path: Path) -> None:
    """When the host's end goes away the device's end is hung up: the simulator counts it,
    closes its end, keeps running and answering, and tries the path again."""
    line = Line()
    with SimProcess(tmp_path, tty=line.device, ready_timeout=30) as sim:
        sim.control.wait_for(lambda s: s["linked"])
        line.close()  # the pty's slave end is hung up and its node removed
        state = sim.control.wait_for(lambda s: s["hangups"] >= 1 and not s["plugged"])
        assert state["mode_name"] == "local"
        assert sim.control.takeover()["mode_name"] == "operational"
        assert sim.stop() == 0


def test_hid_mode_sends_the_input_report_and_takes_output_reports(line: Line) -> None:
    """PR-4.1 (manual §10.2): in HID mode the simulator sends the 9-byte input report about 16
    times a second, from the same sticks and buttons as the serial joystick (zero outside
    Operational; -1023..1023 scaled to -127..127), the D-pad's direction, buttons 1-4, the mode
    and the e-stop byte; an output report sets a value or a label as on serial."""
    now = time.monotonic()
    sim = Simulator(HidSide(line.device), VscModel(now, link_delay=0), log=lambda _: None)
    try:

        def reports(seconds: float) -> list[HidInput]:
            found: list[HidInput] = []
            end = time.monotonic() + seconds
            while time.monotonic() < end:
                sim.step(time.monotonic())
                data = line.read(0.01)
                for at in range(0, len(data) - INPUT_LENGTH + 1, INPUT_LENGTH):
                    report = decode_hid_input(data[at : at + INPUT_LENGTH])
                    assert isinstance(report, HidInput)
                    found.append(report)
            return found

        idle = reports(0.6)
        assert 5 <= len(idle) <= 12  # 16 Hz: about 10 in 0.6 s, never a burst
        assert idle[-1] == HidInput(mode=VscMode.LOCAL)
        sim.model.takeover(time.monotonic())
        sim.model.set_axes({"left_x": 1023, "right_y": -512}, time.monotonic())
        sim.model.set_buttons({"up", "right", "button_1", "button_3"}, time.monotonic())
        moving = reports(0.3)[-1]
        assert (moving.left_x, moving.right_y, moving.mode) == (127, -64, VscMode.OPERATIONAL)
        assert moving.dpad_direction is DPadDirection.UP_RIGHT
        assert moving.pressed == {1, 3}
        sim.model.press_estop(time.monotonic())
        stopped = reports(0.3)[-1]
        assert stopped == HidInput(mode=VscMode.LOCAL, estop=1)  # zeroed outside Operational
        assert sim.estop_sent == 0x01
        os.write(line.host, encode_hid_output(HidOutput(0, 0, 2, "Speed")))
        reports(0.1)
        os.write(line.host, encode_hid_output(HidOutput(3, 1234, 0, "")))
        reports(0.1)
        assert sim.model.labels[2] == "Speed"
        assert sim.model.values[3] == 1234
        assert sim.state(time.monotonic())["transport"] == "hid"
    finally:
        sim.close()

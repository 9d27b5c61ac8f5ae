"""``srcs-sim`` as a real process: a real pty, the control socket, signals, the EEPROM file."""

from __future__ import annotations

import errno
import json
import os
import select
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from supervisord.protocol.codes import MessageType, VscMode
from supervisord.protocol.framing import (
    Decoded,
    FrameDecoder,
    Rejection,
    RejectReason,
    encode_frame,
)
from supervisord.protocol.messages import (
    FeedbackGet,
    FeedbackSet,
    Joystick,
    Message,
    MessageControl,
    UserHeartbeat,
    VscHeartbeat,
)
from supervisord.sim.process import SimControl, SimError, SimProcess


class Host:
    """The host's end of the pty, opened as a program opens a serial port."""

    def __init__(self, path: Path) -> None:
        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        self.decoder = FrameDecoder()

    def read(self, seconds: float) -> list[Decoded]:
        events: list[Decoded] = []
        end = time.monotonic() + seconds
        while (left := end - time.monotonic()) > 0:
            ready, _, _ = select.select([self.fd], [], [], left)
            if ready:
                try:
                    events += self.decoder.feed(os.read(self.fd, 65536))
                except BlockingIOError:
                    continue
        return events

    def drain(self) -> list[Decoded]:
        """Everything already waiting in the line, without waiting for more."""
        events: list[Decoded] = []
        while select.select([self.fd], [], [], 0)[0]:
            try:
                events += self.decoder.feed(os.read(self.fd, 65536))
            except BlockingIOError:
                break
        return events

    def until(self, found: Callable[[Decoded], bool], limit: float = 10.0) -> Decoded:
        end = time.monotonic() + limit
        while time.monotonic() < end:
            for event in self.read(0.05):
                if found(event):
                    return event
        raise AssertionError("the expected frame never came")

    def send(self, *messages: Message) -> None:
        for message in messages:
            os.write(self.fd, encode_frame(message))

    def send_raw(self, data: bytes) -> None:
        os.write(self.fd, data)

    def close(self) -> None:
        os.close(self.fd)


def hung_up(fd: int) -> bool:
    """Whether reads of ``fd`` show a hang-up within 2 s: an I/O error or end of file, as
    the host sees a pulled USB device."""
    end = time.monotonic() + 2.0
    while time.monotonic() < end:
        try:
            if os.read(fd, 4096) == b"":
                return True
        except BlockingIOError:
            time.sleep(0.01)
        except OSError as error:
            return error.errno == errno.EIO
    return False


def heartbeats(events: list[Decoded]) -> list[VscHeartbeat]:
    return [e for e in events if isinstance(e, VscHeartbeat)]


def test_serves_the_manual_traffic_and_answers_key_85(tmp_path: Path) -> None:
    """PR-2.10, PR-2.11: the process sends the manual's traffic on the pty, Local with no
    e-stop, and answers key 85. The rates themselves (20 Hz heartbeat, 50 Hz joystick) are
    proven on made-up times in ``test_default_rates_and_message_control``; here, on real
    time, only what no scheduling can change: never more heartbeats than the 20 Hz schedule
    allows in the time they were sent in (from an empty line to an empty line: each
    heartbeat belongs to a point of the 50 ms grid and goes at it or less than a period
    later, since a late simulator drops frames and never bursts, so W seconds hold at most
    20 W + 2; joysticks 50 W + 2), and no fewer joysticks than heartbeats but the one at the
    window's edge (a turn that finds a heartbeat due finds the faster joystick due too, or
    sent it since the last heartbeat). How few frames a starved simulator sends is its
    scheduling, not its schedule."""
    with SimProcess(tmp_path) as sim:
        assert sim.serial_path is not None
        sim.control.wait_for(lambda s: s["mode_name"] == "local")
        host = Host(sim.serial_path)
        try:
            host.read(0.2)
            host.drain()  # what was queued before we opened, however late we came to read
            started = time.monotonic()
            events: list[Decoded] = []
            while len(heartbeats(events)) < 20:
                assert time.monotonic() - started < 30, "no 20 heartbeats in 30 s"
                events += host.read(0.1)
            events += host.drain()
            sent_in = time.monotonic() - started
            beats, sticks = heartbeats(events), [e for e in events if isinstance(e, Joystick)]
            assert len(beats) <= sent_in * 20 + 2
            assert len(beats) - 1 <= len(sticks) <= sent_in * 50 + 2
            assert all(b.mode == VscMode.LOCAL and b.estop == 0 for b in beats)
            assert not [e for e in events if isinstance(e, Rejection)]
            host.send(FeedbackGet(85))
            assert host.until(lambda e: isinstance(e, FeedbackSet)) == FeedbackSet(85, 0)
            host.send(UserHeartbeat(0), UserHeartbeat(0))
            host.send_raw(b"\x10\x01\x21\x01\x00\x00\x00")  # a bad checksum
        finally:
            host.close()
        state = sim.control.wait_for(lambda s: s["host_frames"] >= 3 and s["host_rejections"])
        assert state["user_heartbeat_age"] is not None
        assert sim.stop() == 0


def test_takeover_drive_and_estop_over_the_wire(tmp_path: Path) -> None:
    with SimProcess(tmp_path) as sim:
        assert sim.serial_path is not None
        sim.control.wait_for(lambda s: s["linked"])
        host = Host(sim.serial_path)
        try:
            sim.control.takeover()
            sim.control.axes(left_y=-800)
            sim.control.buttons("left", "button_4")
            # Two control requests: a frame may fall between them (a busy machine), so the
            # first frame after both is the one with the buttons.
            moving = host.until(lambda e: isinstance(e, Joystick) and bool(e.left_buttons.pressed))
            assert isinstance(moving, Joystick)
            assert moving.left_y.value == -800
            assert moving.left_buttons.pressed == {"left"}
            assert moving.right_buttons.pressed == {"button_4"}
            sim.control.estop()
            stopped = host.until(lambda e: isinstance(e, VscHeartbeat) and e.estop != 0)
            assert stopped == VscHeartbeat(VscMode.LOCAL, 0, 0x01)
            assert host.until(lambda e: isinstance(e, Joystick)) == Joystick()  # zeroed
        finally:
            host.close()


def test_bad_requests_get_error_replies_and_the_sim_lives_on(tmp_path: Path) -> None:
    with SimProcess(tmp_path) as sim:
        control = sim.control
        assert "unknown cmd" in control.call("fly")["error"]
        assert control.call("axes", left_x=5000)["ok"] is False
        assert control.call("axes", nose=1)["ok"] is False
        assert control.call("buttons", pressed="up")["ok"] is False
        assert control.call("reboot", delay=-1)["ok"] is False
        assert "bus_off" in control.call("bus_off", on=True)["error"]
        assert "probability" in control.call("fault", plan={"drop": 7})["error"]
        assert control.call("mode", mode="warp")["ok"] is False
        assert control.call("key", key=85, value=7)["ok"] is False
        control.wait_for(lambda s: s["linked"])
        control.estop()
        with pytest.raises(SimError, match="takeover: e-stop active"):
            control.takeover()
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as raw:
            raw.settimeout(10)
            raw.connect(str(sim.control_path))
            raw.sendall(b"this is not json\n[1, 2]\n")
            with raw.makefile() as lines:
                replies = [json.loads(lines.readline()) for _ in range(2)]
        assert replies[0]["ok"] is False
        assert "not JSON" in replies[0]["error"]
        assert "JSON object" in replies[1]["error"]
        assert control.state()["mode_name"] == "local"


def test_sigterm_exits_0_and_removes_the_pty_and_socket(tmp_path: Path) -> None:
    sim = SimProcess(tmp_path).start()
    assert sim.serial_path is not None
    assert sim.serial_path.is_symlink()
    assert sim.process is not None
    sim.control.close()
    sim.process.send_signal(signal.SIGINT)
    assert sim.process.wait(timeout=10) == 0
    assert not sim.serial_path.exists()
    assert not sim.serial_path.is_symlink()
    assert not sim.control_path.exists()
    assert "Traceback" not in sim.log()


def test_prints_the_pty_path_without_a_symlink() -> None:
    with subprocess.Popen(
        [sys.executable, "-m", "supervisord.cli.sim", "--serial"],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        stdin=subprocess.DEVNULL,
        text=True,
    ) as process:
        try:
            assert process.stdout is not None
            first = process.stdout.readline()
            assert first.startswith("srcs-sim: serial ")
            path = Path(first.split()[2])
            assert path.is_symlink()
            assert "(pty /dev/pts/" in first
            assert process.stdout.readline() == "srcs-sim: ready\n"
            process.send_signal(signal.SIGTERM)
            assert process.wait(timeout=10) == 0
            assert not path.exists()
        finally:
            if process.poll() is None:
                process.kill()


def test_eeprom_survives_a_restart(tmp_path: Path) -> None:
    """Message control (manual §8.3.6) and key 85 (table 13) are kept as the VSC keeps them."""
    with SimProcess(tmp_path, eeprom="eeprom.json") as sim:
        assert sim.serial_path is not None
        host = Host(sim.serial_path)
        try:
            host.send(MessageControl(MessageType.REMOTE_STATUS, 1, 250))
            host.send(MessageControl(MessageType.JOYSTICK, 1, 100))
            host.send(FeedbackSet(85, 1))
            sim.control.wait_for(lambda s: s["key85"] == 1)
        finally:
            host.close()
    saved = json.loads((tmp_path / "eeprom.json").read_text())
    assert saved["keys"]["85"] == 1
    assert saved["message_control"]["34"] == {"enabled": True, "interval_ms": 250}
    with SimProcess(tmp_path, eeprom="eeprom.json") as sim:
        state = sim.control.state()
        assert state["key85"] == 1
        rows = {row["name"]: row for row in state["message_control"]}
        assert rows["remote_status"] == {
            "type": 0x22,
            "name": "remote_status",
            "enabled": True,
            "interval_ms": 250,
        }
        assert rows["joystick"]["interval_ms"] == 100
        assert sim.control.key(85) == 1


def test_unreadable_eeprom_refuses_to_start(tmp_path: Path) -> None:
    (tmp_path / "eeprom.json").write_text("{not json")
    with pytest.raises(SimError, match="EEPROM file unreadable"):
        SimProcess(tmp_path, eeprom="eeprom.json").start()


def test_unplug_and_replug(tmp_path: Path) -> None:
    with SimProcess(tmp_path) as sim:
        assert sim.serial_path is not None
        host = Host(sim.serial_path)
        try:
            host.read(0.1)
            sim.control.unplug()
            assert not sim.serial_path.exists()
            assert hung_up(host.fd)
        finally:
            host.close()
        assert sim.control.state()["plugged"] is False
        sim.control.replug()
        host = Host(sim.serial_path)
        try:
            assert heartbeats(host.read(0.5))
        finally:
            host.close()


def test_reboot_is_silent_for_the_bootloader_delay_then_starts_in_searching(tmp_path: Path) -> None:
    """The bootloader's delay is timed from before the reboot command: the simulator counts it
    from when it reads the command, later on the same monotonic clock, so the first heartbeat
    cannot come sooner, however long the test waits to be scheduled meanwhile."""
    with SimProcess(tmp_path, boot_delay=1.0) as sim:
        assert sim.serial_path is not None
        sim.control.wait_for(lambda s: s["linked"])
        sim.control.takeover()
        host = Host(sim.serial_path)
        try:
            before = time.monotonic()
            sim.control.reboot(unplug=False)  # RS-232: the port stays, the line goes quiet
            booting = sim.control.state()["booting"]
            if time.monotonic() - before < 1.0:  # answered within the delay, surely
                assert booting is True
            host.read(0.1)  # frames already on their way
            assert heartbeats(host.read(max(0.0, before + 0.9 - time.monotonic()))) == []
            first = host.until(lambda e: isinstance(e, VscHeartbeat))
            assert time.monotonic() - before >= 1.0
            assert first == VscHeartbeat(VscMode.SEARCHING, 0, 0x02)
            host.until(lambda e: e == VscHeartbeat(VscMode.LOCAL))
        finally:
            host.close()
        sim.control.reboot(delay=0.5)  # USB: the device is gone during the bootloader
        assert not sim.serial_path.exists()
        state = sim.control.wait_for(lambda s: s["plugged"] and not s["booting"])
        assert state["reboots"] == 2
        assert sim.serial_path.exists()


def test_faults_through_the_control_api(tmp_path: Path) -> None:
    with SimProcess(tmp_path, seed=4) as sim:
        assert sim.serial_path is not None
        sim.control.wait_for(lambda s: s["linked"])
        host = Host(sim.serial_path)
        try:
            host.read(0.1)
            sim.control.fault(corrupt=1.0, only_types=[0x20])
            events = host.read(0.5)
            assert heartbeats(events) == []
            assert any(
                isinstance(e, Rejection) and e.reason is RejectReason.BAD_CHECKSUM for e in events
            )
            assert any(isinstance(e, Joystick) for e in events)
            state = sim.control.state()
            assert state["faults"] == {"corrupt": 1.0, "only_types": [32]}
            assert state["fault_counts"]["corrupt"] > 0
            sim.control.fault(chunk_bytes=1, chunk_gap_s=0.002)  # slow, partial writes
            host.read(0.2)
            assert heartbeats(host.read(1.0))  # still whole frames, byte by byte
            sim.control.fault()
            sim.control.silence(True)
            host.read(0.1)
            assert host.read(0.3) == []
            sim.control.silence(False)
            assert heartbeats(host.read(0.3))
        finally:
            host.close()


def test_keys_drive_the_remote_when_stdin_is_a_terminal(tmp_path: Path) -> None:
    """Single keys on a terminal: t takeover, e e-stop, l the LCD, q quit (exit 0)."""
    terminal, stdin = os.openpty()
    control_path = tmp_path / "sim.sock"
    command = [sys.executable, "-m", "supervisord.cli.sim", "--serial", str(tmp_path / "vsc")]
    with subprocess.Popen(
        [*command, "--control", str(control_path), "--link-delay", "0"],
        stdin=stdin,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    ) as process:
        os.close(stdin)
        try:
            assert process.stdout is not None
            while "ready" not in process.stdout.readline():
                pass
            control = SimControl(control_path)
            try:
                os.write(terminal, b"t")
                control.wait_for(lambda s: s["mode_name"] == "operational")
                os.write(terminal, b"e")
                state = control.wait_for(lambda s: s["estop_bits"] == ["remote_button"])
                assert "E-STOP" in state["lcd"]
            finally:
                control.close()
            os.write(terminal, b"q")
            assert process.wait(timeout=10) == 0
            printed = process.stdout.read()
            assert "|E-STOP" in printed  # the LCD printed after the key
        finally:
            os.close(terminal)
            if process.poll() is None:
                process.kill()


def test_quit_request_exits_0(tmp_path: Path) -> None:
    sim = SimProcess(tmp_path).start()
    assert sim.control.request("quit") == {"ok": True}
    assert sim.process is not None
    assert sim.process.wait(timeout=10) == 0
    sim.control.close()

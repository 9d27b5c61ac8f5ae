"""Harnesses for the outputs' conformance suite: one per output kind this machine can run.

Each harness holds an output that is not open yet, a way to see its level from *outside* the
output object (the mirror file, the frames on the bus, gpio-sim's sysfs value), and a way to
break the device for real so that the suite can check that a fault is reported as a fault.
"""

from __future__ import annotations

import glob
import os
import shutil
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

import can
import pytest

from supervisord.outputs import OutputFault, OutputRole
from supervisord.outputs.can_enable import CanEnableOutput, CanEnableSpec
from supervisord.outputs.gpio import GpioOutput, GpioSpec
from supervisord.outputs.sim import SimOutput, SimSpec
from supervisord.testkit.output_conformance import OutputHarness

Harness = OutputHarness
"""The kit's harness (``supervisord.testkit.output_conformance``), by its old name here."""

KINDS = ["sim", "sim-file", "can-virtual", "gpio"]


def _sim(tmp_path: Path) -> Iterator[Harness]:
    out = SimOutput(SimSpec(name="sim"))
    # A line stuck at the opposite level, like a welded relay contact or a shorted driver.
    yield Harness(
        out,
        lambda: out.device_level,
        lambda lv: out.stick(not lv),
        OutputFault.MISMATCH,
        False,
        lambda: out.stick(True),  # stuck on before it is acquired
    )
    out.close()


def _sim_file(tmp_path: Path) -> Iterator[Harness]:
    folder = tmp_path / "lines"
    folder.mkdir()
    path = folder / "enable"
    out = SimOutput(SimSpec(name="sim_file", path=path))

    def outside() -> bool | None:
        text = path.read_text()
        assert text in ("0\n", "1\n"), f"torn or unexpected content {text!r}"
        return text == "1\n"

    def gone(_: object = None) -> None:
        shutil.rmtree(folder)

    yield Harness(out, outside, gone, OutputFault.IO_ERROR, False, gone)
    out.close()


class BusWatcher:
    """Reads the frames an output sends, from a second bus on the same virtual channel."""

    def __init__(self, bus: can.BusABC, spec: CanEnableSpec) -> None:
        self.bus, self.spec = bus, spec
        self.frames: list[can.Message] = []

    def drain(self) -> list[can.Message]:
        """Every frame received since the last drain (the virtual bus delivers at once)."""
        new = []
        while (msg := self.bus.recv(timeout=0)) is not None:
            new.append(msg)
        self.frames.extend(new)
        return new

    def level(self, msg: can.Message) -> bool:
        """Whether ``msg`` is the "on" frame (any counter value)."""
        for on in (True, False):
            if any(bytes(msg.data) == self.spec.frame_data(on, c) for c in range(256)):
                return on
        raise AssertionError(f"frame is neither on nor off: {msg}")

    def outside(self) -> bool | None:
        """The level the last frame on the bus says, or ``None`` before any frame."""
        self.drain()
        return self.level(self.frames[-1]) if self.frames else None


CAN_SPEC = CanEnableSpec(
    name="drive",
    arbitration_id=0x210,
    data_on=bytes.fromhex("01 00 00 00"),
    data_off=bytes.fromhex("00 00 00 00"),
    counter_byte=3,
    counter_mask=0x0F,
)


@pytest.fixture(autouse=True)
def no_bus_left_open() -> Iterator[None]:
    """Fail any test that leaves a virtual CAN channel of its own open."""
    from can.interfaces import virtual  # noqa: PLC0415  (python-can's registry of channels)

    yield
    leaked = [c for c in virtual.channels if str(c).startswith("test-")]
    assert not leaked, f"virtual CAN channels left open: {leaked}"


@pytest.fixture
def virtual_buses() -> Iterator[tuple[can.BusABC, can.BusABC]]:
    """Two buses on a fresh virtual channel: the output's, and an observer's."""
    channel = f"test-{uuid.uuid4()}"
    mine = can.Bus(interface="virtual", channel=channel)
    theirs = can.Bus(interface="virtual", channel=channel)
    yield mine, theirs
    mine.shutdown()
    theirs.shutdown()


def _can(buses: tuple[can.BusABC, can.BusABC]) -> Iterator[Harness]:
    mine, theirs = buses
    out = CanEnableOutput(CAN_SPEC, mine)
    watcher = BusWatcher(theirs, CAN_SPEC)
    yield Harness(
        out,
        watcher.outside,
        lambda _: mine.shutdown(),
        OutputFault.SEND_ERROR,
        True,
        mine.shutdown,
    )
    out.close()


def gpio_sim_chip() -> tuple[str, int] | None:
    """The chip and line the GPIO harness may drive: ``SRCS_TEST_GPIO_CHIP`` (and
    ``SRCS_TEST_GPIO_LINE``, default 0) if set, else the first gpio-sim chip. Never a real
    chip unless named, since driving it could move a real actuator."""
    named = os.environ.get("SRCS_TEST_GPIO_CHIP")
    line = int(os.environ.get("SRCS_TEST_GPIO_LINE", "0"))
    if named:
        return named, line
    import gpiod  # noqa: PLC0415  (only where a chip exists)

    for path in sorted(glob.glob("/dev/gpiochip*")):
        with gpiod.Chip(path) as chip:
            if chip.get_info().label.startswith("gpio-sim"):
                return path, line
    return None


def _gpio_sysfs_value(chip_path: str, offset: int) -> Path | None:
    name = os.path.basename(chip_path)
    found = glob.glob(f"/sys/devices/platform/gpio-sim*/{name}/sim_gpio{offset}/value")
    return Path(found[0]) if found else None


def _gpio() -> Iterator[Harness]:
    if not glob.glob("/dev/gpiochip*"):
        pytest.skip("no /dev/gpiochip*: runs in the VM tier")
    where = gpio_sim_chip()
    if where is None:
        pytest.skip("no gpio-sim chip (set SRCS_TEST_GPIO_CHIP to drive a real one)")
    chip, line = where
    out = GpioOutput(GpioSpec(name="gpio", chip=chip, line=line, role=OutputRole.MOTION))
    sysfs = _gpio_sysfs_value(chip, line)

    def outside() -> bool | None:
        return None if sysfs is None else sysfs.read_text().strip() == "1"

    def break_device(_: bool) -> None:
        # Release the request behind the output's back: the kernel takes the line back and
        # every later write fails, as when the chip goes away.
        line_handle = out._line
        assert line_handle is not None
        line_handle.release()

    yield Harness(out, outside, break_device, OutputFault.IO_ERROR, False)
    out.close()


@pytest.fixture(params=KINDS)
def harness(
    request: pytest.FixtureRequest,
    tmp_path: Path,
    virtual_buses: tuple[can.BusABC, can.BusABC],
) -> Iterator[Harness]:
    """Every output kind this machine can run (gpio is skipped, with its reason, elsewhere)."""
    makers: dict[str, Callable[[], Iterator[Harness]]] = {
        "sim": lambda: _sim(tmp_path),
        "sim-file": lambda: _sim_file(tmp_path),
        "can-virtual": lambda: _can(virtual_buses),
        "gpio": _gpio,
    }
    yield from makers[request.param]()

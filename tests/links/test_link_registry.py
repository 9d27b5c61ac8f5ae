"""The link registry: each transport of ``[vsc]`` to the link that speaks it, its library
imported only when that transport is chosen (SR-9.4)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from supervisord.config.model import CanBus, HidDevice, SerialPort, VscConfig
from supervisord.links.can_link import CanLink
from supervisord.links.hid_link import HidLink
from supervisord.links.registry import BUILDERS, create_link
from supervisord.links.serial_link import SerialLink
from supervisord.safety.config import Transport


def _imported_after(code: str) -> set[str]:
    """The top-level modules imported by a fresh interpreter after running ``code``."""
    probe = f"import sys\n{code}\nprint(' '.join(sorted(m.split('.')[0] for m in sys.modules)))"
    out = subprocess.run([sys.executable, "-c", probe], check=True, capture_output=True, text=True)
    return set(out.stdout.split())


def test_every_transport_has_a_builder() -> None:
    """No transport the config accepts lacks a link."""
    assert set(BUILDERS) == set(Transport)


def test_each_transport_builds_its_link_closed(tmp_path: Path) -> None:
    """Serial, CAN and HID settings build a serial, CAN and HID link to the configured place,
    not yet open (the CAN error limits reaching the link: tests/config/test_can_errors.py)."""
    serial = create_link(VscConfig(Transport.SERIAL, SerialPort(tmp_path / "ttyVSC")))
    can = create_link(VscConfig(Transport.CAN, CanBus("virtual", "registry-test", 500_000)))
    hid = create_link(VscConfig(Transport.HID, HidDevice(tmp_path / "hidraw0")))
    assert isinstance(serial, SerialLink)
    assert isinstance(can, CanLink)
    assert isinstance(hid, HidLink)
    assert serial.description == f"serial {tmp_path / 'ttyVSC'}"
    assert can.description == "CAN virtual:registry-test"
    assert hid.description == f"HID {tmp_path / 'hidraw0'} (no safety channel)"
    assert [serial.is_open, can.is_open, hid.is_open] == [False, False, False]


def test_the_registry_imports_no_link_library() -> None:
    """Importing the registry imports neither python-can nor pyserial; building a serial
    link imports pyserial only, a CAN link python-can."""
    assert not {"can", "serial"} & _imported_after("import supervisord.links.registry")
    serial = _imported_after(
        "from pathlib import Path\n"
        "from supervisord.config.model import SerialPort, VscConfig\n"
        "from supervisord.links.registry import create_link\n"
        "from supervisord.safety.config import Transport\n"
        "create_link(VscConfig(Transport.SERIAL, SerialPort(Path('ttyVSC'))))"
    )
    assert "serial" in serial
    assert "can" not in serial
    can = _imported_after(
        "from supervisord.config.model import CanBus, VscConfig\n"
        "from supervisord.links.registry import create_link\n"
        "from supervisord.safety.config import Transport\n"
        "create_link(VscConfig(Transport.CAN, CanBus('virtual', 'probe', 500_000)))"
    )
    assert "can" in can

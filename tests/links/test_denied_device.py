"""A VSC's device the daemon may not open says its group and the fix (SR-8.18): the real
serial and HID links opening a real pseudo-terminal as the user nobody (``setpriv``), its
group and mode set as udev would, or left root's as when the udev rule did not match."""

from __future__ import annotations

import grp
import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
NOBODY = 65534
OPEN = """
import sys
from supervisord.links.base import LinkError
from supervisord.links.{module} import {cls}
try:
    {cls}(sys.argv[1]).open()
except LinkError as error:
    print(error.reason)
"""

pytestmark = pytest.mark.skipif(
    os.geteuid() != 0 or shutil.which("setpriv") is None, reason="needs root and setpriv"
)


@pytest.fixture
def device() -> Iterator[str]:
    """A pseudo-terminal's device node, as the VSC's ttyACM would be."""
    master, slave = os.openpty()
    try:
        yield os.ttyname(slave)
    finally:
        os.close(slave)
        os.close(master)


def refused(path: str, module: str = "serial_link", cls: str = "SerialLink") -> str:
    """What the link says when nobody opens ``path``."""
    code = OPEN.format(module=module, cls=cls)
    nobody = ["setpriv", f"--reuid={NOBODY}", f"--regid={NOBODY}", "--clear-groups"]
    result = subprocess.run(
        [*nobody, sys.executable, "-c", code, path],
        env={**os.environ, "PYTHONPATH": str(REPO)},
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    return result.stdout.strip()


def test_a_device_of_a_group_names_the_group_and_usermod(device: str) -> None:
    """SR-8.18: a device of group dialout, 0660, refused to nobody: the reason names the
    device's owner, group and mode and ``usermod -aG dialout nobody``."""
    group = grp.getgrnam("dialout").gr_gid
    os.chown(device, 0, group)
    os.chmod(device, 0o660)
    for module, cls in (("serial_link", "SerialLink"), ("hid_link", "HidLink")):
        said = refused(device, module, cls)
        assert f"{device} is root:dialout, mode 660" in said, said
        assert "sudo usermod -aG dialout nobody" in said, said


def test_a_device_left_roots_names_the_udev_rule(device: str) -> None:
    """SR-8.18: a device still root:root (the udev rule did not match it): the reason names the
    rule and the group it gives, not a usermod into root's group."""
    os.chown(device, 0, 0)
    os.chmod(device, 0o600)
    said = refused(device)
    assert "60-srcs.rules" in said, said
    assert "the group srcs-dev" in said, said
    assert "usermod" not in said, said

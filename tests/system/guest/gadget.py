"""A USB VSC in the system tier's guest: a configfs gadget on dummy_hcd (guest only).

dummy_hcd is a USB device controller (a UDC, ``dummy_udc.N``) looped back to a USB host
controller of the same kernel. A gadget bound to it is enumerated by the guest's own host-side
drivers, as a VSC plugged into a vehicle computer is: the ``acm`` function gives the host a
``/dev/ttyACMn`` (cdc_acm) and the gadget's end ``/dev/ttyGS<port>``; the ``hid`` function
gives the host a ``hidraw`` node (usbhid, hid-generic) and the gadget's end ``/dev/hidg<minor>``.
systemd-udevd applies the package's 60-srcs.rules to what the host side sees.

    gadget.py up vsc [--function acm|hid] [--product 0xd002] [--udc dummy_udc.0]
    gadget.py unplug vsc          # an empty write to its UDC file: the cable is pulled
    gadget.py plug vsc [--udc U]  # bound again: plugged in
    gadget.py product vsc 0xb003  # another product ID (unplugged first, then plugged again)
    gadget.py down vsc            # unbound and removed

The kernel command line gives dummy_hcd two controllers (``dummy_hcd.num=2``, vm.py): two
gadgets can be plugged at once, e.g. another serial device that takes ``ttyACM0`` first.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

MARKER = Path("/.srcs-system-tier")
GADGETS = Path("/sys/kernel/config/usb_gadget")
UDCS = Path("/sys/class/udc")
VENDOR = 0x2A99  # the VSC (docs/install.md, 60-srcs.rules)
PRODUCT = 0xD002  # current firmware, serial (CDC ACM)
BOOTLOADER = 0xB003  # the same VSC in its bootloader: another device to the host

# The HID function's report descriptor: a game pad whose one input report (no report ID) is the
# 9 bytes of manual table 38, in the order and sizes supervisord/protocol/hid.py decodes them
# (tests/system/test_gadget.py checks that), and whose output report is the 26 bytes of table
# 39. The manual gives the reports, not the real VSC's descriptor: the usages (X..Rz, a hat
# switch for the D-pad, buttons 1-4, vendor bytes for the mode and the e-stop) are this tier's
# choice of the standard way to say so.
REPORT_DESCRIPTOR = bytes(
    [
        0x05, 0x01,  # Usage Page (Generic Desktop)
        0x09, 0x05,  # Usage (Game Pad)
        0xA1, 0x01,  # Collection (Application)
        0x09, 0x30, 0x09, 0x31, 0x09, 0x32,  # Usage (X), (Y), (Z): the left stick
        0x09, 0x33, 0x09, 0x34, 0x09, 0x35,  # Usage (Rx), (Ry), (Rz): the right stick
        0x15, 0x81,  # Logical Minimum (-127)
        0x25, 0x7F,  # Logical Maximum (127)
        0x75, 0x08,  # Report Size (8)
        0x95, 0x06,  # Report Count (6)
        0x81, 0x02,  # Input (Data, Variable, Absolute): bytes 0-5
        0x09, 0x39,  # Usage (Hat Switch): the D-pad, byte 6 bits 0-3
        0x15, 0x00,  # Logical Minimum (0)
        0x25, 0x07,  # Logical Maximum (7): 8 = not pressed is the null state
        0x35, 0x00,  # Physical Minimum (0)
        0x46, 0x3B, 0x01,  # Physical Maximum (315)
        0x65, 0x14,  # Unit (degrees)
        0x75, 0x04,  # Report Size (4)
        0x95, 0x01,  # Report Count (1)
        0x81, 0x42,  # Input (Data, Variable, Absolute, Null State)
        0x65, 0x00,  # Unit (none)
        0x05, 0x09,  # Usage Page (Button)
        0x19, 0x01,  # Usage Minimum (1)
        0x29, 0x04,  # Usage Maximum (4): buttons 1-4, byte 6 bits 4-7
        0x15, 0x00,  # Logical Minimum (0)
        0x25, 0x01,  # Logical Maximum (1)
        0x75, 0x01,  # Report Size (1)
        0x95, 0x04,  # Report Count (4)
        0x81, 0x02,  # Input (Data, Variable, Absolute)
        0x06, 0x00, 0xFF,  # Usage Page (Vendor Defined 0xFF00)
        0x09, 0x01,  # Usage (1): the SRC mode, byte 7
        0x09, 0x02,  # Usage (2): the e-stop, byte 8
        0x15, 0x00,  # Logical Minimum (0)
        0x26, 0xFF, 0x00,  # Logical Maximum (255)
        0x75, 0x08,  # Report Size (8)
        0x95, 0x02,  # Report Count (2)
        0x81, 0x02,  # Input (Data, Variable, Absolute)
        0x09, 0x03,  # Usage (3): the user feedback report (table 39)
        0x95, 0x1A,  # Report Count (26)
        0x91, 0x02,  # Output (Data, Variable, Absolute)
        0xC0,  # End Collection
    ]
)  # fmt: skip
REPORT_LENGTH = 26  # the longest report: the endpoints' packet size


def _write(path: Path, value: str | bytes) -> None:
    if isinstance(value, bytes):
        path.write_bytes(value)
    else:
        path.write_text(value)


class Gadget:
    """One configfs gadget named ``name``: a VSC (``acm`` or ``hid``) or another device."""

    def __init__(self, name: str) -> None:
        if not MARKER.exists():
            raise SystemExit("gadget: not inside the system tier's guest; refusing")
        self.name = name
        self.root = GADGETS / name

    @property
    def function(self) -> Path:
        found = sorted((self.root / "functions").iterdir())
        if not found:
            raise RuntimeError(f"gadget {self.name} has no function")
        return found[0]

    def create(
        self,
        function: str = "acm",
        vendor: int = VENDOR,
        product: int = PRODUCT,
        serial: str = "SIM0001",
        product_name: str = "VSCSerial",
    ) -> None:
        """Make the gadget with one function and one configuration; not plugged yet."""
        self.root.mkdir()
        _write(self.root / "idVendor", f"{vendor:#06x}")
        _write(self.root / "idProduct", f"{product:#06x}")
        _write(self.root / "bcdDevice", "0x0100")
        _write(self.root / "bcdUSB", "0x0200")
        strings = self.root / "strings/0x409"
        strings.mkdir()
        _write(strings / "manufacturer", "srcs system tier")
        _write(strings / "product", product_name)
        _write(strings / "serialnumber", serial)
        config = self.root / "configs/c.1"
        config.mkdir()
        _write(config / "MaxPower", "100")
        function_dir = self.root / "functions" / f"{function}.usb0"
        function_dir.mkdir()
        if function == "hid":
            _write(function_dir / "protocol", "0")
            _write(function_dir / "subclass", "0")
            _write(function_dir / "report_length", str(REPORT_LENGTH))
            _write(function_dir / "report_desc", REPORT_DESCRIPTOR)
        elif function != "acm":
            raise ValueError(f"unknown function {function!r}: acm or hid")
        (config / function_dir.name).symlink_to(function_dir)

    def device_end(self) -> Path:
        """The gadget's end of its function: /dev/ttyGS<N> (acm) or /dev/hidg<N> (hid)."""
        function = self.function
        if function.name.startswith("acm."):
            return Path(f"/dev/ttyGS{(function / 'port_num').read_text().strip()}")
        minor = (function / "dev").read_text().strip().split(":")[1]
        return Path(f"/dev/hidg{minor}")

    @property
    def udc(self) -> str:
        return (self.root / "UDC").read_text().strip()

    def plug(self, udc: str | None = None) -> str:
        """Bind to ``udc`` (default: the first free dummy UDC): the host enumerates it."""
        chosen = udc or free_udc()
        try:
            _write(self.root / "UDC", chosen)
        except OSError as error:
            raise OSError(
                error.errno,
                f"binding {self.name} to {chosen}: {error.strerror}; {udc_report(chosen)}",
            ) from error
        return chosen

    def unplug(self) -> None:
        """The cable pulled: the host side's devices go away at once."""
        if self.udc:
            _write(self.root / "UDC", "\n")

    def set_product(self, product: int) -> None:
        """Another product ID: the next plug enumerates as another device."""
        udc = self.udc
        self.unplug()
        _write(self.root / "idProduct", f"{product:#06x}")
        if udc:
            self.plug(udc)

    def remove(self) -> None:
        """Unbind and take the gadget apart, in the reverse order of ``create``."""
        if not self.root.exists():
            return
        self.unplug()
        config = self.root / "configs/c.1"
        for link in config.iterdir():
            if link.is_symlink():
                link.unlink()
        config.rmdir()
        for function in (self.root / "functions").iterdir():
            function.rmdir()
        (self.root / "strings/0x409").rmdir()
        self.root.rmdir()


def udc_report(udc: str) -> str:
    """What the UDC and the kernel say, for an error message."""
    found = []
    for name in ("function", "state", "current_speed"):
        try:
            found.append(f"{name}={(UDCS / udc / name).read_text().strip()!r}")
        except OSError as error:
            found.append(f"{name}: {error.strerror}")
    bound = {g.name: (g / "UDC").read_text().strip() for g in GADGETS.iterdir()}
    kernel = subprocess.run(["dmesg"], capture_output=True, text=True, check=False).stdout
    return f"{udc}: {' '.join(found)}; gadgets {bound}; kernel: {kernel[-1500:]}"


def free_udc(keep: str = "") -> str:
    """The first dummy UDC no gadget is bound to, other than ``keep`` (one kept for a gadget
    that is unplugged for now)."""
    taken = {(g / "UDC").read_text().strip() for g in GADGETS.iterdir() if (g / "UDC").exists()}
    taken.add(keep)
    for udc in sorted(os.listdir(UDCS)):
        if udc not in taken:
            return udc
    raise RuntimeError(f"no free UDC (taken: {sorted(taken)})")


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("action", choices=("up", "plug", "unplug", "product", "down"))
    parser.add_argument("name")
    parser.add_argument("value", nargs="?", help="product: the new product ID, e.g. 0xb003")
    parser.add_argument("--function", choices=("acm", "hid"), default="acm")
    parser.add_argument("--product", type=lambda text: int(text, 0), default=PRODUCT)
    parser.add_argument("--udc")
    args = parser.parse_args(argv)
    gadget = Gadget(args.name)
    if args.action == "up":
        gadget.create(args.function, product=args.product)
        print(f"{args.name}: {gadget.plug(args.udc)}, device end {gadget.device_end()}")
    elif args.action == "plug":
        print(f"{args.name}: {gadget.plug(args.udc)}")
    elif args.action == "unplug":
        gadget.unplug()
    elif args.action == "product":
        if args.value is None:
            parser.error("product needs the new product ID")
        gadget.set_product(int(args.value, 0))
    else:
        gadget.remove()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

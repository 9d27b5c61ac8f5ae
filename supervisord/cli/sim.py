"""``srcs-sim``: a simulated VSC with its remote, on a pseudo-terminal, an existing serial
device, a USB HID function or a CAN bus.

    srcs-sim --serial [SYMLINK]          # serial protocol on a pty (path printed)
    srcs-sim --tty /dev/ttyGS0           # on a device's end of a real line (a USB gadget's)
    srcs-sim --hid /dev/hidg0            # HID mode: game-controller reports (a USB gadget's)
    ip netns exec srcs srcs-sim --can udp_multicast:239.74.163.2   # one machine, a namespace
    srcs-sim --control sim.sock --eeprom vsc-eeprom.json --seed 7

It prints ``srcs-sim: serial PATH (pty DEVICE)`` (or ``srcs-sim: tty PATH``, ``hid PATH``,
``can ...``), then
``srcs-sim: control SOCKET`` when it has one, then ``srcs-sim: ready``. Driven by keys when
stdin is a terminal, and by the control socket (``docs/simulator.md``). One thread, one
``select`` loop on monotonic deadlines. SIGTERM or SIGINT: the pty and socket are removed
and it exits 0. Exit 2: bad arguments, an unreadable EEPROM file, a port that cannot be
made.
"""

from __future__ import annotations

import argparse
import contextlib
import select
import signal
import sys
import tempfile
import termios
import time
import tty
from collections.abc import Iterator
from pathlib import Path
from types import FrameType
from typing import Any

import can

from supervisord import __version__
from supervisord.sim.can_side import CanSide
from supervisord.sim.control import ControlServer
from supervisord.sim.engine import DEFAULT_BOOT_DELAY_S, Side, Simulator, load_eeprom
from supervisord.sim.hid_side import HidSide
from supervisord.sim.model import LINK_DELAY_S, REMOTE_OFF_REPORTS, SimTransport, VscModel
from supervisord.sim.serial_side import SerialSide
from supervisord.sim.tty_side import TtySide

POLL_S = 0.05  # the longest wait: state the model changes on its own shows within this
POLL_NO_FD_S = 0.005  # an interface without a descriptor ("virtual") is polled

KEYS: dict[str, tuple[str, str]] = {
    "e": ("e-stop (press the remote's button)", "estop"),
    "r": ("release the e-stop", "release"),
    "t": ("takeover", "takeover"),
    "p": ("pause", "pause"),
    "m": ("menu (enter / leave)", "menu"),
    "o": ("remote power off / on", "power"),
    "w": ("wired e-stop input on / off", "wired_estop"),
    "u": ("unplug / replug", "plug"),
    "b": ("reboot the VSC", "reboot"),
    "s": ("silence on / off", "silence"),
    "l": ("print the LCD", "lcd"),
    "h": ("this help", "help"),
    "q": ("quit", "quit"),
}


def build_parser() -> argparse.ArgumentParser:
    """The argument parser alone, with no side effects: ``main`` and the man page and shell
    completion (``supervisord/cli/reference.py``) share it."""
    parser = argparse.ArgumentParser(
        prog="srcs-sim", description="A simulated SRCS VSC with its remote (docs/simulator.md)."
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    where = parser.add_mutually_exclusive_group()
    where.add_argument(
        "--serial",
        nargs="?",
        const="",
        metavar="SYMLINK",
        help="serve the serial protocol on a pty, linked at SYMLINK (default: a temporary path)",
    )
    where.add_argument(
        "--tty",
        metavar="DEVICE",
        help="serve the serial protocol on an existing serial device, the VSC's end of a real "
        "line: a USB CDC ACM gadget's /dev/ttyGS0, or a port cabled to the host",
    )
    where.add_argument(
        "--hid",
        metavar="DEVICE",
        help="HID mode: input reports to, output reports from a USB HID function's device "
        "end, e.g. a HID gadget's /dev/hidg0 (no serial protocol, no watchdog)",
    )
    where.add_argument(
        "--can",
        metavar="INTERFACE:CHANNEL",
        help="serve J1939 on a python-can interface: socketcan:vcan0, or udp_multicast:GROUP "
        "for processes of one machine only, run inside a private network namespace (its "
        "frames stay on the machine, but joining the group is seen on the network: "
        "docs/simulator.md)",
    )
    parser.add_argument("--bitrate", type=int, default=250_000, help="CAN bitrate (socketcan)")
    parser.add_argument("--control", metavar="SOCKET", help="the control API's Unix socket")
    parser.add_argument(
        "--eeprom", metavar="FILE", help="keep message control and permanent keys in FILE"
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the fault injector")
    parser.add_argument(
        "--boot-delay",
        type=float,
        default=DEFAULT_BOOT_DELAY_S,
        metavar="S",
        help="seconds in the bootloader on a reboot (default %(default)s)",
    )
    parser.add_argument(
        "--link-delay",
        type=float,
        default=LINK_DELAY_S,
        metavar="S",
        help="seconds from power-on to the remote link (default %(default)s)",
    )
    parser.add_argument(
        "--newer-firmware", action="store_true", help="report Remote (0x06) instead of Local"
    )
    parser.add_argument("--remote-off", action="store_true", help="start with the remote off")
    parser.add_argument(
        "--remote-off-reports",
        choices=REMOTE_OFF_REPORTS,
        default="searching",
        help="how the VSC reports a switched-off remote: Searching with bit 0x02, or Local "
        "with the remote's e-stop bit 0x01 as some hardware does (default %(default)s)",
    )
    return parser


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.can is not None and ":" not in args.can:
        parser.error("--can takes INTERFACE:CHANNEL, e.g. udp_multicast:239.74.163.2")
    if not 0 <= args.boot_delay <= 600 or not 0 <= args.link_delay <= 60:
        parser.error("--boot-delay must be 0..600 and --link-delay 0..60 seconds")
    return args


class _Stop:
    requested = False

    def __call__(self, signum: int, frame: FrameType | None) -> None:
        self.requested = True


@contextlib.contextmanager
def _keys_mode(interactive: bool) -> Iterator[None]:
    """Single keys without Enter while running, the terminal restored after."""
    if not interactive:
        yield
        return
    fd = sys.stdin.fileno()
    saved = termios.tcgetattr(fd)
    tty.setcbreak(fd)
    try:
        yield
    finally:
        # At once, not once the output has drained: a terminal that stopped reading would
        # hold the exit for ever.
        termios.tcsetattr(fd, termios.TCSANOW, saved)


def _say(text: str) -> None:
    print(f"srcs-sim: {text}", flush=True)


def _key_request(key: str, sim: Simulator, now: float) -> dict[str, Any] | None:
    """The control request a key stands for (toggles read the current state)."""
    entry = KEYS.get(key.lower())
    if entry is None:
        return None
    command = entry[1]
    if command == "power":
        return {"cmd": "power", "on": not sim.model.remote_on}
    if command == "wired_estop":
        return {"cmd": "wired_estop", "active": not sim.model.wired_estop}
    if command == "plug":
        return {"cmd": "replug" if not sim.side.plugged else "unplug"}
    if command == "silence":
        return {"cmd": "silence", "on": not sim.silenced}
    return {"cmd": command}


def _on_key(key: str, sim: Simulator, now: float) -> None:
    request = _key_request(key, sim, now)
    if request is None:
        return
    if request["cmd"] == "help":
        for letter, (text, _) in KEYS.items():
            print(f"  {letter}  {text}")
        return
    reply = sim.request(request, now)
    if not reply["ok"]:
        _say(f"{request['cmd']}: {reply['error']}")
    print(sim.model.render_lcd(now), flush=True)


def _make_side(args: argparse.Namespace, scratch: Path) -> Side:
    if args.can is not None:
        interface, channel = args.can.split(":", 1)
        return CanSide(interface, channel, args.bitrate)
    if args.tty is not None:
        return TtySide(Path(args.tty))
    if args.hid is not None:
        return HidSide(Path(args.hid))
    path = Path(args.serial) if args.serial else scratch / "vsc"
    return SerialSide(path)


def _describe(side: Side) -> str:
    """The first line's words after ``srcs-sim:`` (docs/simulator.md)."""
    if isinstance(side, SerialSide):
        return f"serial {side.path} (pty {side.device})"
    if isinstance(side, TtySide):
        return f"tty {side.path}"
    if isinstance(side, HidSide):
        return f"hid {side.path}"
    return f"can {side.description}"


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    # HID mode runs the serial model: its sticks, buttons, mode and e-stops make the reports.
    transport: SimTransport = "can" if args.can is not None else "serial"
    eeprom_path = Path(args.eeprom) if args.eeprom else None
    try:
        eeprom = load_eeprom(eeprom_path, transport)
    except ValueError as error:
        print(f"srcs-sim: EEPROM file unreadable: {error}", file=sys.stderr)
        return 2
    stop = _Stop()
    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    with tempfile.TemporaryDirectory(prefix="srcs-sim-") as scratch:
        try:
            side = _make_side(args, Path(scratch))
        except (OSError, ValueError, can.CanError, ImportError) as error:
            print(f"srcs-sim: cannot open the port: {error}", file=sys.stderr)
            return 2
        now = time.monotonic()
        model = VscModel(
            now,
            transport=transport,
            eeprom=eeprom,
            newer_firmware=args.newer_firmware,
            link_delay=args.link_delay,
            remote_on=not args.remote_off,
            remote_off_reports=args.remote_off_reports,
        )
        sim = Simulator(
            side, model, seed=args.seed, eeprom_path=eeprom_path, boot_delay=args.boot_delay
        )
        control: ControlServer | None = None
        try:
            if args.control:
                control = ControlServer(Path(args.control))
            _say(_describe(side))
            if control is not None:
                _say(f"control {control.path}")
            interactive = sys.stdin.isatty()
            with _keys_mode(interactive):  # before "ready": no key may meet a cooked terminal
                _say("ready")
                _run(sim, control, stop, interactive)
        except OSError as error:
            print(f"srcs-sim: {error}", file=sys.stderr)
            return 2
        finally:
            if control is not None:
                control.close()
            sim.close()
    return 0


def _run(sim: Simulator, control: ControlServer | None, stop: _Stop, interactive: bool) -> None:
    stdin_fd = sys.stdin.fileno() if interactive else None
    if interactive:
        _say("keys: " + ", ".join(f"{k} {text}" for k, (text, _) in KEYS.items()))
    while not stop.requested and not sim.quit_requested:
        now = time.monotonic()
        sim.step(now)
        port_fd = sim.fileno()
        longest = POLL_S if port_fd is not None or not sim.side.plugged else POLL_NO_FD_S
        timeout = max(0.0, min(sim.next_deadline(now) - time.monotonic(), longest))
        readers = [fd for fd in (port_fd, stdin_fd) if fd is not None]
        writers: list[int] = []
        if control is not None:
            readers += control.read_fds()
            writers += control.write_fds()
        readable, writable, _ = select.select(readers, writers, [], timeout)
        now = time.monotonic()
        if control is not None:
            ready = set(readable), set(writable)
            control.serve(*ready, lambda request: sim.request(request, time.monotonic()))
        if stdin_fd is not None and stdin_fd in readable:
            for key in sys.stdin.read(1):
                _on_key(key, sim, now)


if __name__ == "__main__":
    sys.exit(main())

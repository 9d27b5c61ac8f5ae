"""srcs-exporter: srcsd's state and counters as Prometheus metrics (docs/fleet.md)."""

from __future__ import annotations

import argparse
import ipaddress
import logging
import signal
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from types import FrameType

from supervisord import __version__
from supervisord.client import DEFAULT_SOCKET_PATH
from supervisord.errors import ConfigError

DEFAULT_LISTEN = "127.0.0.1:9817"
"""Loopback by default: the scrape network is a deliberate choice (docs/fleet.md)."""
EXIT_CONFIG = 78  # sysexits.h EX_CONFIG: systemd's "not configured", not worth a restart
EXIT_BIND = 1
DEFAULT_RV_FILE = Path("/run/srcs-rv/violations.json")
"""supervisord.rv_watch's file (docs/kernel-judge.md), where srcs-rv.service writes it."""


def listen_address(text: str) -> tuple[str, int]:
    """``HOST:PORT``, ``[IPV6]:PORT``: an IP address (no name to resolve) and a port."""
    host, sep, port_text = text.rpartition(":")
    if not sep or not port_text.isdigit() or not 0 <= int(port_text) <= 65535:
        raise argparse.ArgumentTypeError(f"{text!r} is not HOST:PORT (e.g. {DEFAULT_LISTEN})")
    if host.startswith("[") and host.endswith("]"):
        host = host[1:-1]
    try:
        ipaddress.ip_address(host)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{host!r} is not an IP address (e.g. 127.0.0.1, [::1], 0.0.0.0)"
        ) from None
    return host, int(port_text)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="srcs-exporter", description=__doc__)
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--config", metavar="FILE", help="the robot's config (its [api] socket)")
    where.add_argument(
        "--socket",
        metavar="PATH",
        type=Path,
        help=f"the API socket (default {DEFAULT_SOCKET_PATH})",
    )
    parser.add_argument(
        "--listen",
        metavar="HOST:PORT",
        type=listen_address,
        default=DEFAULT_LISTEN,
        help=f"where to serve the metrics over HTTP (default {DEFAULT_LISTEN})",
    )
    parser.add_argument(
        "--poll",
        metavar="SECONDS",
        type=float,
        default=1.0,
        help="how often to ask srcsd for its counters (default 1; state comes as it changes)",
    )
    parser.add_argument(
        "--rv-file",
        metavar="PATH",
        type=Path,
        default=DEFAULT_RV_FILE,
        help="the kernel judge's totals, as srcs-rv.service writes them, read at each scrape "
        f"(default {DEFAULT_RV_FILE}; none there: no srcs_rt_* metrics)",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(
        level=logging.INFO, format="srcs-exporter: %(levelname)s: %(message)s", stream=sys.stderr
    )
    log = logging.getLogger("srcs-exporter")
    if not 0.1 <= args.poll <= 60:
        print("srcs-exporter: --poll must be between 0.1 and 60 seconds", file=sys.stderr)
        return EXIT_CONFIG
    socket_path: Path = args.socket or DEFAULT_SOCKET_PATH
    if args.config:
        # Where the daemon is, and nothing of the safety core (SR-8.8).
        from supervisord.config.client import load_client_config  # noqa: PLC0415

        try:
            socket_path = load_client_config(args.config).socket
        except ConfigError as error:
            print(f"srcs-exporter: {error}", file=sys.stderr)
            return EXIT_CONFIG
    # Imported here: prometheus-client only when the arguments are good.
    from supervisord.exporter.collector import serve  # noqa: PLC0415
    from supervisord.exporter.follower import Follower  # noqa: PLC0415
    from supervisord.exporter.judge import JudgeFile  # noqa: PLC0415
    from supervisord.exporter.model import ExporterModel, Family  # noqa: PLC0415

    model, lock = ExporterModel(), threading.Lock()
    judge_file = JudgeFile(args.rv_file)

    def families() -> list[Family]:
        totals, refused = judge_file.read(time.time())  # at each scrape (SR-9.9)
        with lock:
            model.judge_read(totals, refused)
            return model.families(time.monotonic_ns())

    host, port = args.listen
    try:
        server, _ = serve(families, host, port)
    except OSError as error:
        print(f"srcs-exporter: cannot listen on {host}:{port}: {error}", file=sys.stderr)
        return EXIT_BIND
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    bound = server.server_address
    log.info("serving on %s:%s, following %s", bound[0], bound[1], socket_path)
    follower = Follower(socket_path, model, lock, poll=args.poll)
    thread = threading.Thread(target=follower.run, args=(stop,), name="follower")
    thread.start()
    try:
        while not stop.wait(1.0):
            if not thread.is_alive():  # never expected: it catches everything
                log.error("the follower stopped")
                return 1
    finally:
        stop.set()
        thread.join(5.0)
        server.shutdown()
        server.server_close()
    return 0


if __name__ == "__main__":
    sys.exit(main())

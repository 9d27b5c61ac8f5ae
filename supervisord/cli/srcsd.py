"""srcsd: the safety supervisor service, one per robot configuration."""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
import select
import signal
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Final, TextIO

from supervisord import __version__, threads
from supervisord.api.readiness import srcsctl_for
from supervisord.cli.access import advice
from supervisord.config import check_config_main
from supervisord.config.check import report_lines
from supervisord.config.collect import collect
from supervisord.config.directories import present
from supervisord.config.realtime import LockMode
from supervisord.config.toml_file import MAX_CONFIG_BYTES
from supervisord.daemon import memory_lock, signals
from supervisord.daemon.service_manager_absent import absent, surroundings
from supervisord.errors import SrcsError
from supervisord.record.jsonl import RecordError

EXIT_CONFIG: Final = 78
"""sysexits.h EX_CONFIG, systemd's "not configured": the unit lists it in
RestartPreventExitStatus=, so a bad or missing config fails once instead of restarting five
times (SR-11.2; docs/install.md "Exit status")."""
EXIT_CANNOT_START: Final = 1
"""Valid config, but a resource could not be had (the record's directory, the socket held by
another server): worth a restart, as Restart=on-failure does."""

SYSLOG_PRIORITY: Final = {
    logging.CRITICAL: 2,
    logging.ERROR: 3,
    logging.WARNING: 4,
    logging.INFO: 6,
    logging.DEBUG: 7,
}
"""A Python level as a syslog priority (sd-daemon(3)); levels in between round down."""


def syslog_priority(level: int) -> int:
    """The syslog priority of a log level: the priority of the nearest named level at or
    below it (a custom level 35 is a warning)."""
    named = [lvl for lvl in SYSLOG_PRIORITY if lvl <= level]
    return SYSLOG_PRIORITY[max(named)] if named else SYSLOG_PRIORITY[logging.DEBUG]


class JournalPrefixFormatter(logging.Formatter):
    """``<N>message``, the sd-daemon(3) prefix that journald reads from a service's stderr as
    the entry's PRIORITY. Every line of a multi-line message (a traceback) gets the prefix:
    journald makes each line an entry of its own."""

    def format(self, record: logging.LogRecord) -> str:
        prefix = f"<{syslog_priority(record.levelno)}>"
        return "\n".join(prefix + line for line in super().format(record).split("\n"))


def stderr_is_journal(stream: TextIO = sys.stderr) -> bool:
    """Whether ``stream`` is the journal's stream socket: systemd says so in
    ``JOURNAL_STREAM=DEV:INODE`` (systemd.exec(5)), and the descriptor must still be that
    one (a child whose stderr was redirected inherits the variable, not the socket)."""
    value = os.environ.get("JOURNAL_STREAM", "")
    try:
        device, inode = (int(part) for part in value.split(":"))
        stat = os.fstat(stream.fileno())
    except (ValueError, OSError):
        return False
    return (stat.st_dev, stat.st_ino) == (device, inode)


def setup_logging(verbose: bool, stream: TextIO = sys.stderr) -> logging.Handler:
    """Log lines to ``stream``: with their syslog priority prefix when it is the journal
    (`journalctl -p warning` must see the daemon's warnings), else as
    ``srcsd: LEVEL: message`` for a person at a terminal. The prefixes need nothing but
    stderr: no journal library, no compiler on the robot. The sink's log lane
    (``daemon/sink.py``) later writes every line with this handler's formatter to its stream's
    descriptor (SR-7.7)."""
    handler = logging.StreamHandler(stream)
    if stderr_is_journal(stream):
        handler.setFormatter(JournalPrefixFormatter("%(message)s"))
    else:
        handler.setFormatter(logging.Formatter("srcsd: %(levelname)s: %(message)s"))
    root = logging.getLogger()
    for old in list(root.handlers):
        root.removeHandler(old)
    root.addHandler(handler)
    root.setLevel(logging.DEBUG if verbose else logging.INFO)
    return handler


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="srcsd", description=__doc__)
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--config", metavar="FILE", help="run with this robot configuration")
    group.add_argument(
        "--check-config",
        metavar="FILE",
        help="list every mistake of the configuration, in file order with its line, and exit "
        "(0 = the daemon would start with it): a user, group or directory this machine lacks "
        "is an error, as for the daemon's start",
    )
    machine = parser.add_mutually_exclusive_group()
    machine.add_argument(
        "--portable",
        action="store_true",
        help="with --check-config, for a config written here for another machine: a user, "
        "group or directory this machine lacks is a warning",
    )
    machine.add_argument(
        "--strict",
        action="store_true",
        help="with --check-config: the default (what this machine lacks is an error); kept "
        "for scripts written when it was not",
    )
    parser.add_argument("--verbose", action="store_true", help="log every link event")
    return parser


class Interrupted(BaseException):
    """A stopping signal before the loop runs (a BaseException, as KeyboardInterrupt: no
    ``except Exception`` of a library being imported swallows it)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signals.name(signum))
        self.signum = signum


def _interrupt(signum: int) -> None:
    raise Interrupted(signum)


FLAGS: Final = ("--strict", "--portable", "--verbose")
"""srcsd's options that take no value."""


def flags_first(argv: Sequence[str]) -> list[str]:
    """``argv`` with the options that take no value moved to the front, so that any order
    works: ``--check-config --strict FILE`` as ``--strict --check-config FILE`` (argparse would
    take ``--strict`` for the missing FILE). Nothing after ``--`` moves."""
    end = list(argv).index("--") if "--" in argv else len(argv)
    head = list(argv[:end])
    return [a for a in head if a in FLAGS] + [a for a in head if a not in FLAGS] + list(argv[end:])


INT_DIGITS: Final = 4300
"""The most digits a decimal integer in a request may have (Python's own default). A request's
number is converted in time quadratic in its digits, so this is what keeps that cost bounded
(SR-10.5); ``PYTHONINTMAXSTRDIGITS=0`` in the environment would lift it, so the daemon sets it
itself."""


def pin_int_digits() -> None:
    """Bound the digits Python converts, whatever the environment says (SR-10.5). A Python
    3.10 before 3.10.7 has neither the bound nor this call; the daemon still starts there."""
    pin = getattr(sys, "set_int_max_str_digits", None)
    if pin is not None:
        pin(INT_DIGITS)


def main(argv: Sequence[str] | None = None) -> int:
    pin_int_digits()
    args = build_parser().parse_args(flags_first(sys.argv[1:] if argv is None else argv))
    if args.check_config:
        return check_config_main(args.check_config, portable=args.portable)
    setup_logging(args.verbose)
    log = logging.getLogger("srcsd")
    # Every signal has its meaning from here on (SR-6.6): before the loop runs, nothing is
    # on yet, so a stopping signal ends the start (the socket removed) with the exit status
    # of a stop on that signal; the loop then puts its own handlers in their place.
    signals.install(_interrupt)
    try:
        return _serve(args.config, log)
    except Interrupted as stop:
        log.warning("%s: stopping before the start", stop)
        return signals.exit_status(stop.signum)


def read_until_stopped(path: Path) -> bytes:
    """The bytes of the file at ``path``, read so that a stopping signal always ends the wait
    (SR-6.6). A FIFO or a pipe (``--config <(...)``) can keep a read waiting without end,
    and Python runs a signal's handler only between bytecodes: a signal that lands between
    the ``open`` and the ``read`` system calls would wait with the read (seen: a SIGHUP lost in
    about 4 of 10 starts on a FIFO). So the file is opened without waiting and the wait is a
    poll on it and on the signal wakeup fd, to which the C handler writes every signal. It
    stops one byte beyond the largest config (``MAX_CONFIG_BYTES``): ``/dev/zero`` or an
    endless pipe is refused as too large, not read until memory runs out (SR-11.2)."""
    wake_r, wake_w = os.pipe2(os.O_NONBLOCK | os.O_CLOEXEC)
    previous = signal.set_wakeup_fd(wake_w)
    try:
        # A signal caught before the wakeup fd was set raises at the next call below; one
        # caught after it wakes the poll.
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
        try:
            return _read_polling(fd, wake_r)
        finally:
            os.close(fd)
    finally:
        signal.set_wakeup_fd(previous)
        os.close(wake_r)
        os.close(wake_w)


def _read_polling(fd: int, wake: int) -> bytes:
    poller = select.poll()
    poller.register(fd, select.POLLIN)
    poller.register(wake, select.POLLIN)
    chunks: list[bytes] = []
    size = 0
    while True:  # the loop's jump back runs a handler whose signal woke the poll
        for ready, _ in poller.poll():
            if ready == wake:
                with contextlib.suppress(BlockingIOError):
                    os.read(wake, 64)
                continue
            try:
                chunk = os.read(fd, 1 << 16)
            except BlockingIOError:  # a FIFO whose writer has not written yet
                continue
            if not chunk:
                return b"".join(chunks)
            chunks.append(chunk)
            size += len(chunk)
            if size > MAX_CONFIG_BYTES:
                return b"".join(chunks)


def _serve(path: str, log: logging.Logger) -> int:
    # The directories it does not create are asked of the machine as it is now: a missing one
    # is a config error (exit 78, no restart), not a failed bind restarted five times (SR-11.2).
    report = collect(path, strict_machine=True, read=read_until_stopped, directory_there=present)
    config = report.config
    if config is None:
        # The daemon refuses to start on a bad configuration (docs/configuration.md), with
        # EX_CONFIG so that systemd does not restart it (RestartPreventExitStatus=78). It
        # names every mistake, each with its line, as --check-config does.
        for line in report_lines(path, report):
            log.error("%s", line)
        return EXIT_CONFIG
    # The loop is the main thread: named as the process (SR-9.7); the memory locked before any
    # thread starts and before the parts are built, so that all of it is locked (SR-9.6).
    threads.name_this_thread(threads.LOOP_NAME)
    memory_lock.prepare()
    memory = memory_lock.lock(config.realtime.lock_memory)
    if not memory.locked and memory.mode is LockMode.REQUIRED:
        log.error(
            'cannot start: memory not locked (%s) and [realtime] lock_memory = "required": '
            "raise the unit's LimitMEMLOCK= (units/srcsd@.service)",
            memory.fact(),
        )
        return EXIT_CANNOT_START
    # Imported after the configuration is valid: python-can and gpiod load only when needed.
    from supervisord.daemon import lifecycle  # noqa: PLC0415
    from supervisord.daemon.assemble import build_api, build_supervisor  # noqa: PLC0415

    api = None
    try:
        api = build_api(config)
        supervisor = build_supervisor(config, api)
    except (SrcsError, OSError, Interrupted) as error:
        # A start that fails after the socket was made removes it (a failed start used to
        # leave a stale api.sock; the next start would replace it, but clients saw a path that
        # looked served). close() removes the file only if it is still ours.
        if api is not None:
            api.close()
        if isinstance(error, Interrupted):
            raise
        # A record left root's by a run by hand says whose it is and how to give it back.
        hint = advice(error.path, error.errno) if isinstance(error, RecordError) else ""
        log.error("cannot start: %s%s", error, hint)
        return EXIT_CANNOT_START
    supervisor.srcsctl = srcsctl_for(config=path)  # how its fixes name srcsctl (SR-8.18)
    supervisor.memory_locked = memory.locked  # in status and the exporter (SR-9.6)
    log.info(
        "srcsd %s, robot %s: %s, %d outputs",
        __version__,
        config.robot.name,
        supervisor.link.description,
        len(supervisor.outputs),
    )
    # Once, at the start: what no service manager gives this start, and what to provide
    # instead (SR-0.4, docs/containers.md).
    for finding in absent(surroundings(config, memory)):
        log.warning("%s", finding.line())
    return lifecycle.run(supervisor)


if __name__ == "__main__":
    sys.exit(main())

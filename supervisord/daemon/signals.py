"""What every signal does to ``srcsd`` (SR-6.6; docs/install.md "Signals").

Every signal whose default action would end the process (``Term`` or ``Core`` in signal(7))
and that can be caught has one of three meanings, and no other:

- **a clean stop**, as SIGTERM: every output off, the record drained, then exit. SIGTERM and
  SIGINT are the stop the unit and a terminal ask for: exit 0. Any other (SIGHUP, SIGQUIT,
  SIGUSR1, SIGUSR2, SIGALRM, the real-time signals, ...) stops the same way and exits
  128 + its number, the shell's "ended by a signal", so that systemd's ``Restart=on-failure``
  starts the supervisor again, STOPPED until the operator's takeover (SR-4). srcsd has no
  reload: a changed configuration takes effect at that start. SIGXCPU is one of these
  (SR-6.7): the soft ``LimitRTTIME=`` says the loop has run a second without blocking; where
  the loop still gets to run, the stop is the daemon's own, with its record
  ``shutdown:SIGXCPU`` and exit 152.
- **ignored** (:data:`IGNORED`): the failure they announce is met where it happens.
- **left at the default** (:data:`DEFAULT`): the process ends at once, and the wiring and the
  VSC's watchdog make that safe (SR-6.5). A Python handler would only run later, at the next
  bytecode of the main thread: for the faults it is never (the faulting instruction runs
  again), for SIGABRT it is the hung loop that must not get a say.

Signals whose default does not end the process (SIGCHLD, SIGCONT, SIGURG, SIGWINCH, the stop
signals) and the two that cannot be caught (SIGKILL, SIGSTOP) keep their default.
"""

from __future__ import annotations

import signal
from collections.abc import Callable, Mapping
from types import FrameType
from typing import Any, Final

Handler = Callable[[int], None]
Previous = Callable[[int, FrameType | None], Any] | int | signal.Handlers | None
"""What ``signal.signal`` returns: the handler that was there."""

CLEAN_EXIT: Final = frozenset({signal.SIGTERM, signal.SIGINT})
"""The stops asked for (``systemctl stop``, Ctrl-C): exit status 0."""

IGNORED: Final[Mapping[int, str]] = {
    signal.SIGPIPE: "a client that went away is met by the send (MSG_NOSIGNAL, EPIPE): it is "
    "disconnected",
    signal.SIGXFSZ: "a record file past the file-size limit is met by the write (EFBIG): the "
    "record is counted as not written (SR-7.6)",
}
"""Ignored, with why."""

# SIGXCPU is not left at the default (SR-6.7): the soft LimitRTTIME= (1 s of CPU without
# blocking) is a stop the daemon makes, outputs off and a record, whenever the loop still gets
# to run the handler (a slow turn that ends). A loop that cannot (stuck in one call of C code,
# or spinning inside a turn) is killed by the hard limit (SIGKILL at 2 s): the outputs' release
# on the process's death and the VSC's watchdog stop the robot then (SR-6.5).
DEFAULT: Final[Mapping[int, str]] = {
    signal.SIGABRT: "systemd's watchdog kill of a hung loop (WatchdogSec=)",
    signal.SIGSYS: "the kernel's kill of a forbidden system call (SystemCallFilter=)",
    signal.SIGSEGV: "a fault of the process itself",
    signal.SIGBUS: "a fault of the process itself",
    signal.SIGFPE: "a fault of the process itself",
    signal.SIGILL: "a fault of the process itself",
    signal.SIGTRAP: "a debugger's breakpoint",
}
"""Left at their default (the process ends at once, with a core), with why."""

NOT_ENDING: Final = frozenset(
    {
        signal.SIGKILL,  # cannot be caught
        signal.SIGSTOP,  # cannot be caught
        signal.SIGCHLD,
        signal.SIGCONT,
        signal.SIGURG,
        signal.SIGWINCH,
        signal.SIGTSTP,
        signal.SIGTTIN,
        signal.SIGTTOU,
    }
)
"""Signals whose default does not end the process, or that cannot be caught (signal(7))."""


def stopping() -> tuple[int, ...]:
    """Every other signal of this system, real-time ones included: each ends srcsd as
    SIGTERM does."""
    others = set(NOT_ENDING) | set(IGNORED) | set(DEFAULT)
    return tuple(sorted(int(sig) for sig in signal.valid_signals() if sig not in others))


def name(signum: int) -> str:
    """``SIGHUP``; a real-time signal as ``SIGRTMIN+N`` (Python names only the first and last)."""
    try:
        return signal.Signals(signum).name
    except ValueError:
        return f"SIGRTMIN+{signum - signal.SIGRTMIN}"


def exit_status(signum: int) -> int:
    """The exit status of a clean stop on ``signum``: 0 when asked for, else 128 + N."""
    return 0 if signum in CLEAN_EXIT else 128 + signum


def install(handler: Handler) -> dict[int, Previous]:
    """``handler(signum)`` for every stopping signal, SIG_IGN for :data:`IGNORED` (the
    :data:`DEFAULT` ones are left alone); returns what was there, for :func:`restore`.
    A handler only sets a flag and wakes the loop: Python runs it in the main thread."""
    previous: dict[int, Previous] = {}
    for signum in stopping():
        previous[signum] = signal.signal(signum, lambda got, _frame: handler(got))
    for signum in IGNORED:
        previous[signum] = signal.signal(signum, signal.SIG_IGN)
    return previous


def restore(previous: Mapping[int, Previous]) -> None:
    """Put back what :func:`install` replaced (one not set from Python: the default)."""
    for signum, old in previous.items():
        signal.signal(signum, signal.SIG_DFL if old is None else old)

"""The daemon's threads: each named for the kernel, and every one but the loop at ordinary
priority (SR-9.7, SR-9.8; docs/safety-manual.md "Assumptions of use").

The unit runs srcsd under SCHED_FIFO (``units/srcsd@.service``), and a thread inherits its
creator's policy: without this, the record's fsync, the journal copy, a log line and a user
name's lookup would all run in real time beside the loop, and a trace of the kernel (the
runtime-verification monitors, ``perf``, ``/proc/PID/task``) would name every one of them
``srcsd``. :func:`start` makes such a thread: it gives itself its name (``prctl(PR_SET_NAME)``,
the ``comm`` a trace shows, 15 bytes at most) and SCHED_OTHER (``sched_setscheduler`` with pid
0 acts on the calling thread on Linux) before its work begins, unless it already has it: the
unit starts srcsd with ``CPUSchedulingResetOnFork=yes``, which gives every new thread, a
library's too, SCHED_OTHER (at nice 0), and its seccomp filter denies the call.

The loop is the main thread: it keeps SCHED_FIFO and is named :data:`LOOP_NAME`, ``srcsd``,
the process's own name, so ``ps``, ``pidof srcsd`` and the journal's ``_COMM`` see the daemon
as before and a violation that names ``srcsd`` is the loop's.
"""

from __future__ import annotations

import ctypes
import logging
import os
import threading
from collections.abc import Callable
from typing import Final

LOOP_NAME: Final = "srcsd"
"""The main thread's (the loop's) name: the process's own (SR-9.7)."""
NAME_MAX: Final = 15
"""The kernel's limit on a thread's name (``TASK_COMM_LEN`` 16, with its NUL)."""
PR_SET_NAME: Final = 15
"""prctl(2)'s option that names the calling thread."""

log = logging.getLogger("srcsd")

_libc = ctypes.CDLL(None, use_errno=True)


def kernel_name(name: str) -> bytes:
    """``name`` as the kernel keeps it: ASCII, at most :data:`NAME_MAX` bytes."""
    return name.encode("ascii", "replace")[:NAME_MAX]


def name_this_thread(name: str) -> None:
    """Give the calling thread ``name`` in the kernel (``/proc/PID/task/TID/comm``)."""
    if _libc.prctl(PR_SET_NAME, ctypes.c_char_p(kernel_name(name)), 0, 0, 0) != 0:
        # Never fatal: an unnamed thread is only harder to find in a trace.
        log.warning("thread %s: prctl(PR_SET_NAME): %s", name, os.strerror(ctypes.get_errno()))


ORDINARY: Final = (os.SCHED_OTHER, os.SCHED_BATCH, os.SCHED_IDLE)
"""The policies that are not real time."""


def ordinary_priority() -> None:
    """Put the calling thread (not the process: pid 0 is the calling thread on Linux) at
    SCHED_OTHER, keeping the process's nice value (SR-9.8). Under the unit it is there
    already: ``CPUSchedulingResetOnFork=yes`` starts every new thread at SCHED_OTHER, and the
    unit's seccomp filter denies the call."""
    if (os.sched_getscheduler(0) & ~os.SCHED_RESET_ON_FORK) in ORDINARY:
        return
    try:
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    except OSError as error:  # e.g. an older unit whose seccomp filter denies the call
        log.warning(
            "thread %s stays at the loop's priority (sched_setscheduler: %s): start srcsd with "
            "SCHED_RESET_ON_FORK (CPUSchedulingResetOnFork=yes, as units/srcsd@.service; "
            "chrt -R)",
            threading.current_thread().name,
            error.strerror,
        )


def start(target: Callable[[], object], name: str) -> threading.Thread:
    """A daemon thread named ``name`` (at most :data:`NAME_MAX` bytes) that names itself and
    leaves real time before it runs ``target`` (SR-9.7, SR-9.8); started at once.

    A daemon thread: one stuck in a device (a pipe nobody reads, a lookup that never returns)
    never holds the process's exit."""
    if len(kernel_name(name)) != len(name):
        raise ValueError(f"thread name {name!r} is longer than {NAME_MAX} bytes or not ASCII")

    def run() -> None:
        name_this_thread(name)
        ordinary_priority()
        target()

    thread = threading.Thread(target=run, name=name, daemon=True)
    thread.start()
    return thread

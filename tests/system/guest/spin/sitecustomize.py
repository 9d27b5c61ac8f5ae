"""System tier only: make the running srcsd's loop spin, to prove the unit's LimitRTTIME=.

Nothing in the product knows of this file. The ``rttime`` scenario
(tests/system/guest/scenarios.py) adds a drop-in to srcsd@gpio-a with
``Environment=PYTHONPATH=`` this directory, so that Python imports this module at start-up
(``site`` imports ``sitecustomize``), before the daemon's own code. It replaces
``select.epoll`` with a wrapper whose ``poll`` the loop calls once per turn to wait for its
next input or deadline (the loop waits on epoll itself, SR-9.4; ``select.epoll`` cannot be
subclassed, so the wrapper holds the real one). When the file :data:`TRIGGER` holds this
process's PID, every wait from then on has a timeout of 0: the loop still serves the VSC, its
outputs and systemd's watchdog, but it never blocks again, as a loop whose next deadline is
always in the past would. Only RLIMIT_RTTIME can stop that (SR-9).

The ``judge_sleep`` scenario (the kernel's judge, docs/system-tier.md) uses the same wrapper:
when :data:`SLEEP_TRIGGER` holds this process's PID, every wait first sleeps 2 ms with
``nanosleep`` (libc's relative sleep on CLOCK_REALTIME, the kind of sleep that gives no
real-time guarantee; ``time.sleep`` would not do: since 3.11 it sleeps to an absolute
deadline), which the kernel's ``sleep`` monitor must flag in the real-time loop (SR-9.8).

At start it also asks for a higher SCHED_FIFO priority, once, and prints the answer to
stderr (the journal): the unit's RestrictRealtime=yes must refuse it.
"""

from __future__ import annotations

import ctypes
import os
import select
import sys
from typing import Any

TRIGGER = "/run/srcs-spin"
SLEEP_TRIGGER = "/run/srcs-judge-sleep"
_epoll = select.epoll
_spinning = False
_sleeping = False


class _Timespec(ctypes.Structure):
    _fields_ = (("tv_sec", ctypes.c_long), ("tv_nsec", ctypes.c_long))


_libc = ctypes.CDLL(None, use_errno=True)
_TWO_MS = _Timespec(0, 2_000_000)


def _told(path: str = TRIGGER) -> bool:
    try:
        with open(path) as trigger:
            return trigger.read().strip() == str(os.getpid())
    except OSError:
        return False


def _say(text: str) -> None:
    print(f"srcs-spin: {text}", file=sys.stderr)
    sys.stderr.flush()


class _SpinningEpoll:
    """An epoll whose every wait has timeout 0 once :data:`TRIGGER` names this process."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self._real = _epoll(*args, **kwargs)

    def poll(self, timeout: float | None = None, maxevents: int = -1) -> list[tuple[int, int]]:
        global _spinning, _sleeping  # noqa: PLW0603 -- one flag each for the process
        if not _spinning and _told():
            _spinning = True
            _say("spinning from now on (every wait has timeout 0)")
        if not _sleeping and _told(SLEEP_TRIGGER):
            _sleeping = True
            _say("sleeping 2 ms with nanosleep before every wait from now on")
        if _sleeping:
            _libc.nanosleep(ctypes.byref(_TWO_MS), None)
        return self._real.poll(0 if _spinning else timeout, maxevents)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._real, name)


select.epoll = _SpinningEpoll  # type: ignore[assignment,misc]

try:
    policy = os.sched_getscheduler(0)
    priority = os.sched_getparam(0).sched_priority
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority + 1))
        answer = "allowed"
    except OSError as error:
        answer = f"refused ({error.strerror})"
    print(
        f"srcs-spin: armed; policy {policy} priority {priority}; "
        f"raising the FIFO priority: {answer}",
        file=sys.stderr,
    )
    sys.stderr.flush()
except Exception as error:  # never stop the daemon from starting
    print(f"srcs-spin: {error}", file=sys.stderr)

"""The loop's own failures as the ``internal`` cause's events (``daemon/internal_fault.py``,
SR-2): a late wake says how late, a turn that raised is counted, logged with its trace and
said by its type and text, even when the error cannot say itself. The loop's use of them,
with a real loop whose outputs are switched off: ``tests/daemon/test_loop.py`` and
``tests/faults/test_serial_device.py`` (a hung daemon woken as an internal fault).

Mutants planted and caught here: the count not raised, the trace not logged, the type's name
dropped from the text, the guard for an error that cannot say itself removed, the lateness
in nanoseconds instead of milliseconds.
"""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from supervisord.daemon import lifecycle
from supervisord.daemon.internal_fault import OVERRUN_NS, failed, late
from supervisord.daemon.loop import Supervisor
from supervisord.daemon.loop_status import Counters
from supervisord.links.base import Backoff
from supervisord.links.serial_link import SerialLink
from supervisord.outputs import create_output, parse_output_spec
from supervisord.safety.config import OutputRole, OutputSpec, SafetyConfig
from supervisord.safety.events import InternalFault
from supervisord.sim.pty import PtyPort
from supervisord.timebase import NS_PER_MS
from tests.daemon.test_loop import ManualClock


class Mute(Exception):
    def __str__(self) -> str:
        raise RuntimeError("cannot say itself")


def test_a_late_wake_says_how_late_in_milliseconds() -> None:
    """SR-2: a wake past ``OVERRUN_NS`` after the core's deadline is an internal fault."""
    deadline = 5_000 * NS_PER_MS
    now = deadline + OVERRUN_NS + 3 * NS_PER_MS
    assert late(now, deadline) == InternalFault(now, "loop woke 253 ms late")


def test_a_turn_that_raised_is_counted_logged_and_said(caplog: pytest.LogCaptureFixture) -> None:
    """SR-2: a turn that raised is counted for ``status``, logged with its trace, and said by
    its type and text; an error whose text cannot be made is said by its type."""
    counters = Counters()
    caplog.set_level(logging.ERROR, logger="srcsd")
    try:
        raise ValueError("odd")
    except ValueError as error:
        fault = failed(7, error, counters)
    assert fault == InternalFault(7, "ValueError: odd")
    assert counters.internal_faults == 1
    (line,) = caplog.records
    assert line.getMessage() == "internal fault in the main loop"
    assert line.exc_info is not None
    assert line.exc_info[0] is ValueError
    assert failed(8, Mute(), counters) == InternalFault(8, "Mute")  # fail safe: still a fault
    assert counters.internal_faults == 2


def _started_loop(tmp_path: Path, clock: ManualClock) -> tuple[Supervisor, PtyPort]:
    """A real loop on a pty VSC (silent) and a sim output, started on ``clock``."""
    port = PtyPort(tmp_path / "vsc")
    supervisor = Supervisor(
        SafetyConfig(outputs=(OutputSpec("drive", OutputRole.MOTION),)),
        SerialLink(str(port.path)),
        [create_output(parse_output_spec("drive", {"kind": "sim"}))],
        None,
        backoff=Backoff(first_ms=20, max_ms=100),
        clock=clock,
    )
    lifecycle.start(supervisor)
    return supervisor, port


@pytest.mark.parametrize(("late_ms", "internal"), [(250, False), (251, True)])
def test_the_loop_is_at_fault_only_past_250_ms_after_the_cores_deadline(
    tmp_path: Path, late_ms: int, internal: bool
) -> None:
    """SR-2.9 (docs/safety.md "The loop woke more than 250 ms late"): a loop that wakes
    250 ms after the core's deadline is still on time, one that wakes 251 ms after it has
    overrun and stops for ``internal``. The loop's manual clock puts the wake exactly there."""
    clock = ManualClock()
    supervisor, port = _started_loop(tmp_path, clock)
    try:
        assert supervisor.decision is not None
        assert supervisor.decision.cause("internal") is None
        clock.now = supervisor.decision.next_deadline + late_ms * NS_PER_MS
        supervisor.step()
        assert (supervisor.decision.cause("internal") is not None) is internal
    finally:
        lifecycle.shutdown(supervisor)
        port.close()

"""The outputs' conformance suite, for an integrator's new output kind as for the project's
own (docs/testing.md "The kit for integrators", docs/outputs.md).

An output (``supervisord.outputs.base.Output``) is acquired off (``open``), set to a level and
read back (``set``), keeps its periodic duty (``tick`` at ``next_deadline``), is off when
released (``close``), and reports a device that failed as a faulty ``ReadBack``, never as a
silent pass and never as an exception (SR-6). Out-of-order use is refused with
``OutputUsageError`` and drives nothing.

To run it, subclass ``OutputConformance`` in a test module (the name starting with ``Test``)
and give it a ``harness`` fixture that yields a fresh ``OutputHarness`` per test, its output
not yet open, with a view of the level from *outside* the output object (a mirror file, the
frames on a bus, gpio-sim's sysfs value) and a way to break the device for real::

    class TestMyOutput(OutputConformance):
        @pytest.fixture
        def harness(self, tmp_path): ...

Time is an argument (``T0`` onwards, or a ``clock.FakeClock``'s): no check reads a clock or
imports pytest; each raises ``AssertionError`` when the output breaks the contract.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

from supervisord.outputs import Output, OutputError, OutputFault, OutputUsageError

T0 = 5_000_000_000
"""An arbitrary monotonic start time (ns): the checks never read a clock."""
MS = 1_000_000


@dataclasses.dataclass
class OutputHarness:
    """An output under test and its outside view.

    ``outside()`` is the level an observer outside the output sees, or ``None`` when the kind
    gives no outside view. ``break_device(level)`` makes the device fail for real so that the
    next write of ``level`` cannot succeed; it must then come back with ``fault``.
    ``periodic``: the kind has a periodic duty (``next_deadline`` after open).
    """

    output: Output
    outside: Callable[[], bool | None]
    break_device: Callable[[bool], None]
    fault: OutputFault
    periodic: bool
    break_before_open: Callable[[], None] | None = None
    """Make the device unusable before ``open`` (its file's folder gone, its bus shut); a
    kind that cannot be broken before it is acquired leaves it ``None``."""


def refused(call: Callable[[], object]) -> bool:
    """Whether ``call`` raised ``OutputUsageError`` (and nothing else)."""
    try:
        call()
    except OutputUsageError:
        return True
    return False


class OutputConformance:
    """The contract of ``Output``, one check per method, each on a fresh ``harness``."""

    def test_open_drives_off(self, harness: OutputHarness) -> None:
        """Opening an output drives it off and reads the off state back."""
        rb = harness.output.open(T0)
        assert rb.ok, rb
        assert (rb.requested, rb.written) == (False, False)
        assert rb.observed in (False, None)
        assert harness.output.is_open
        assert harness.output.requested is False
        assert harness.outside() in (False, None)

    def test_set_on_then_off_reads_back(self, harness: OutputHarness) -> None:
        """Setting on and then off is verified by read-back and seen from outside."""
        out = harness.output
        out.open(T0)
        on = out.set(True, T0 + MS)
        assert on.ok, on
        assert (on.requested, on.written, on.observed in (True, None)) == (True, True, True)
        assert harness.outside() in (True, None)
        off = out.set(False, T0 + 2 * MS)
        assert off.ok, off
        assert (off.requested, off.written, off.observed in (False, None)) == (False, False, True)
        assert harness.outside() in (False, None)

    def test_set_same_level_again_is_verified_again(self, harness: OutputHarness) -> None:
        """Re-asserting the current level writes and verifies it again (a stop re-asserts off)."""
        out = harness.output
        out.open(T0)
        assert out.set(False, T0 + MS).ok
        assert out.set(False, T0 + 2 * MS).ok
        assert harness.outside() in (False, None), "set off, and seen on from outside"

    def test_close_leaves_it_off(self, harness: OutputHarness) -> None:
        """Closing an output that is on drives it off, verifies it, and releases it."""
        out = harness.output
        out.open(T0)
        out.set(True, T0 + MS)
        rb = out.close()
        assert rb is not None
        assert rb.ok, rb
        assert (rb.requested, rb.written) == (False, False)
        assert not out.is_open
        assert out.requested is False
        assert harness.outside() in (False, None), "released, and seen on from outside"

    def test_close_is_idempotent_and_final(self, harness: OutputHarness) -> None:
        """A second close does nothing, and the closed output refuses set and tick."""
        out = harness.output
        out.open(T0)
        assert out.close() is not None
        assert out.close() is None
        assert refused(lambda: out.set(True, T0 + MS)), "a closed output was set"
        assert refused(lambda: out.tick(T0 + MS)), "a closed output was ticked"
        assert out.next_deadline() is None

    def test_use_before_open_is_refused(self, harness: OutputHarness) -> None:
        """Set and tick before open raise OutputUsageError and drive nothing."""
        out = harness.output
        assert refused(lambda: out.set(True, T0)), "an output was set before open"
        assert refused(lambda: out.tick(T0)), "an output was ticked before open"
        assert out.next_deadline() is None
        assert out.close() is None
        assert not out.is_open

    def test_open_twice_is_refused(self, harness: OutputHarness) -> None:
        """A second open raises OutputUsageError instead of requesting the line again."""
        harness.output.open(T0)
        assert refused(lambda: harness.output.open(T0 + MS)), "an output was opened twice"

    def test_tick_before_deadline_does_nothing(self, harness: OutputHarness) -> None:
        """A tick before the next deadline performs no duty and keeps the deadline and level."""
        out = harness.output
        out.open(T0)
        out.set(True, T0 + MS)
        deadline = out.next_deadline()
        before = harness.outside()
        early = T0 + MS if deadline is None else deadline - 1
        assert out.tick(early) is None
        assert out.tick(early) is None
        assert out.next_deadline() == deadline
        assert harness.outside() == before

    def test_next_deadline_semantics(self, harness: OutputHarness) -> None:
        """A periodic kind has a deadline after open and moves it forward on each due tick; others
        have none."""
        out = harness.output
        out.open(T0)
        deadline = out.next_deadline()
        if not harness.periodic:
            assert deadline is None
            return
        assert deadline is not None
        assert deadline > T0
        rb = out.tick(deadline)
        assert rb is not None
        assert rb.ok, rb
        assert rb.requested is False
        following = out.next_deadline()
        assert following is not None
        assert following > deadline

    def test_fault_is_reported(self, harness: OutputHarness) -> None:
        """A device that breaks makes the next write come back as a fault, never a silent pass."""
        out = harness.output
        out.open(T0)
        harness.break_device(True)
        rb = out.set(True, T0 + MS)
        assert not rb.ok, f"a write of on to a broken device passed as verified: {rb}"
        assert rb.fault is harness.fault, rb
        assert rb.requested is True
        assert rb.details()["fault"] == harness.fault.value

    def test_fault_on_off_is_reported(self, harness: OutputHarness) -> None:
        """A write of off to a broken device is reported as a fault too (off is not assumed)."""
        out = harness.output
        out.open(T0)
        assert out.set(True, T0 + MS).ok
        harness.break_device(False)
        rb = out.set(False, T0 + 2 * MS)
        assert not rb.ok, f"a write of off to a broken device passed as verified: {rb}"
        assert rb.fault is harness.fault, rb

    def test_a_device_broken_before_open_is_refused(self, harness: OutputHarness) -> None:
        """SR-6: acquiring a device that cannot be driven is refused: ``open`` raises
        ``OutputError`` (nothing held) or returns a faulty read-back (held, so that ``close``
        releases it); never a verified off it did not read."""
        if harness.break_before_open is None:
            return  # the kind cannot be broken before it is acquired
        out = harness.output
        harness.break_before_open()
        try:
            rb = out.open(T0)
        except OutputError:
            assert not out.is_open
            return
        assert not rb.ok, f"opened a broken device as verified off: {rb}"
        assert rb.fault is harness.fault
        out.close()

"""The outputs' conformance suite: the contract of ``supervisord.outputs.base.Output``, run
against every output kind this machine can run (SR-6)."""

from __future__ import annotations

import pytest

from supervisord.outputs import OutputUsageError
from tests.outputs.conftest import T0, Harness

MS = 1_000_000


def test_open_drives_off(harness: Harness) -> None:
    """Opening an output drives it off and reads the off state back."""
    rb = harness.output.open(T0)
    assert rb.ok, rb
    assert (rb.requested, rb.written) == (False, False)
    assert rb.observed in (False, None)
    assert harness.output.is_open
    assert harness.output.requested is False
    assert harness.outside() in (False, None)


def test_set_on_then_off_reads_back(harness: Harness) -> None:
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


def test_set_same_level_again_is_verified_again(harness: Harness) -> None:
    """Re-asserting the current level writes and verifies it again (a stop re-asserts off)."""
    out = harness.output
    out.open(T0)
    assert out.set(False, T0 + MS).ok
    assert out.set(False, T0 + 2 * MS).ok
    assert harness.outside() in (False, None)


def test_close_leaves_it_off(harness: Harness) -> None:
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
    assert harness.outside() in (False, None)


def test_close_is_idempotent_and_final(harness: Harness) -> None:
    """A second close does nothing, and the closed output refuses set and tick."""
    out = harness.output
    out.open(T0)
    assert out.close() is not None
    assert out.close() is None
    with pytest.raises(OutputUsageError):
        out.set(True, T0 + MS)
    with pytest.raises(OutputUsageError):
        out.tick(T0 + MS)
    assert out.next_deadline() is None


def test_use_before_open_is_refused(harness: Harness) -> None:
    """Set and tick before open raise OutputUsageError and drive nothing."""
    out = harness.output
    with pytest.raises(OutputUsageError):
        out.set(True, T0)
    with pytest.raises(OutputUsageError):
        out.tick(T0)
    assert out.next_deadline() is None
    assert out.close() is None
    assert not out.is_open


def test_open_twice_is_refused(harness: Harness) -> None:
    """A second open raises OutputUsageError instead of requesting the line again."""
    harness.output.open(T0)
    with pytest.raises(OutputUsageError):
        harness.output.open(T0 + MS)


def test_tick_before_deadline_does_nothing(harness: Harness) -> None:
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


def test_next_deadline_semantics(harness: Harness) -> None:
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


def test_fault_is_reported(harness: Harness) -> None:
    """A device that breaks makes the next write come back as a fault, never a silent pass."""
    out = harness.output
    out.open(T0)
    harness.break_device(True)
    rb = out.set(True, T0 + MS)
    assert not rb.ok
    assert rb.fault is harness.fault
    assert rb.requested is True
    assert rb.details()["fault"] == harness.fault.value


def test_fault_on_off_is_reported(harness: Harness) -> None:
    """A write of off to a broken device is reported as a fault too (off is not assumed)."""
    out = harness.output
    out.open(T0)
    assert out.set(True, T0 + MS).ok
    harness.break_device(False)
    rb = out.set(False, T0 + 2 * MS)
    assert not rb.ok
    assert rb.fault is harness.fault

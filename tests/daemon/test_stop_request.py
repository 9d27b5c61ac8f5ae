"""The request to end the loop (SR-6.6, SR-7.14): the first signal decides the stop record's
reason and the exit status; asked without a signal, or not asked at all (an exception), each
says so."""

from __future__ import annotations

import logging
import signal

import pytest

from supervisord.daemon.stop_request import StopRequest


def test_the_first_signal_asked_for_decides_the_reason_and_the_exit_status() -> None:
    """SR-6.6, SR-7.14: a second signal during the shutdown changes nothing."""
    stop = StopRequest()
    stop.ask(signal.SIGHUP)
    stop.ask(signal.SIGTERM)
    assert stop.asked
    assert (stop.reason(), stop.exit_status()) == ("SIGHUP", 128 + signal.SIGHUP)


def test_a_signal_after_a_request_without_one_decides() -> None:
    """SR-6.6: asked first without a signal, the signal that follows is the first signal."""
    stop = StopRequest()
    stop.ask()
    assert (stop.reason(), stop.exit_status()) == ("requested", 0)
    stop.ask(signal.SIGUSR2)
    assert (stop.reason(), stop.exit_status()) == ("SIGUSR2", 128 + signal.SIGUSR2)


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_sigterm_and_sigint_exit_cleanly(signum: int) -> None:
    """SR-6.6: the stops asked for exit 0."""
    stop = StopRequest()
    stop.ask(signum)
    assert (stop.reason(), stop.exit_status()) == (signal.Signals(signum).name, 0)


def test_a_run_ended_without_a_request_is_an_error() -> None:
    """SR-7.14: not asked (an exception ended the run): ``shutdown:error``, exit 0 from here
    (the exception itself ends the process)."""
    stop = StopRequest()
    assert not stop.asked
    assert (stop.reason(), stop.exit_status()) == ("error", 0)


def test_the_stop_is_logged_as_a_warning_only_after_a_signal_not_asked_for(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """SR-6.6: SIGTERM and SIGINT are the usual way to stop (info); any other signal that ends
    the daemon is worth a warning; no signal, no line."""
    caplog.set_level(logging.INFO, logger="srcsd")
    quiet = StopRequest()
    quiet.ask()
    quiet.log()
    for signum in (signal.SIGTERM, signal.SIGHUP):
        stop = StopRequest()
        stop.ask(signum)
        stop.log()
    assert [(r.levelno, r.getMessage()) for r in caplog.records if r.name == "srcsd"] == [
        (logging.INFO, "SIGTERM: stopping, every output off"),
        (logging.WARNING, "SIGHUP: stopping, every output off"),
    ]

"""``srcsctl stoptest``: the field stop test (SR-12.1; docs/srcsctl.md "The field stop test").

A dialogue with the operator at the robot: take over (RUN, every output on), press the
remote's e-stop, and with ``--wired`` release it, take over again and press the VSC's wired
e-stop. For each press it waits (at most ``--timeout``) for the stop record, then for the
outputs to be off, and finally asks the daemon to judge and record the presses: the numbers
are the daemon's own (each output's off write, timed from the e-stop frame's read), never
this program's. It says "recorded" only once the daemon pushed the ``stoptest`` record, which
it does when the record lane has finished with it (SR-7.4): then ``srcsctl log`` shows it.
Exit 0 passed, 1 failed (or refused), 3 not done (no press in time, another stop, no daemon,
the record not finished in time).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable, Mapping
from typing import Final, TextIO

from supervisord.api.pushes import RecordPush
from supervisord.cli.numbers import duration
from supervisord.client import SupervisorClient
from supervisord.record.stop import StopTestReport
from supervisord.vocabulary import CauseKind, State

REQUIREMENTS: Final = "/usr/share/doc/srcs-supervisord/docs/requirements.md"
"""Where a robot has the requirements: the package's copy of docs/ (docs/install.md); the
repository's paths are not on a robot."""
EXIT_PASSED: Final = 0
EXIT_FAILED: Final = 1
EXIT_NOT_DONE: Final = 3
DEFAULT_TIMEOUT_S: Final = 60.0
"""Per wait (a takeover, a press): time for an operator to walk to the robot and back."""
OFF_WAIT_S: Final = 5.0
"""After the stop record, how long the outputs get to be off before the daemon judges: far
beyond any output's off delay; one still on by then fails (SR-12.1)."""
RECORD_WAIT_S: Final = 10.0
"""After the verdict, how long its record gets to be finished (written and fsynced, SR-7.5):
the record lane's queue at its longest is about a minute of the worst client traffic, far
beyond a robot's; a record not finished by then is "not done" (exit 3)."""
POLL_S: Final = 0.05

PROMPTS: Final[Mapping[str, str]] = {
    "remote": "press the remote's e-stop now",
    "wired": "press the VSC's wired e-stop now",
}


def add_stoptest(add: Callable[[str, str], argparse.ArgumentParser]) -> None:
    """The command's parser, made by ``control``'s ``add`` (its socket options)."""
    parser = add(
        "stoptest",
        "the field stop test: press the remote's e-stop (and with --wired the VSC's wired "
        "one) in RUN; every output's time to off, judged and recorded (admin); exit 0 passed, "
        "1 failed, 3 not done",
    )
    parser.add_argument(
        "--wired", action="store_true", help="then the VSC's wired e-stop too, after a takeover"
    )
    parser.add_argument(
        "--timeout",
        type=duration,  # nan or inf would never time out (SR-11.3)
        default=DEFAULT_TIMEOUT_S,
        metavar="TIME",
        help="wait at most TIME for each takeover and press: seconds, or a time span such as "
        f"90s, 2min (default {DEFAULT_TIMEOUT_S:g})",
    )
    parser.add_argument(
        "--yes", action="store_true", help="do not ask before starting (scripts, tests)"
    )


def confirmed_stoptest(out: TextIO, stdin: TextIO) -> bool:
    """The operator confirms before the test starts: it needs the robot in RUN and stops it."""
    print(
        "The stop test needs the robot in RUN (you take over on the remote) and stops it with\n"
        "the e-stop you press: stand by the robot in a place where it may move and stop.\n"
        "Type 'yes' to begin: ",
        end="",
        file=out,
        flush=True,
    )
    return stdin.readline().strip().lower() == "yes"


class NotDone(Exception):
    """The test could not be carried out (exit 3); the message says why."""


def run_stoptest(
    client: SupervisorClient,
    out: TextIO,
    *,
    wired: bool,
    timeout_s: float,
    clock: Callable[[], float] = time.monotonic,
) -> int:
    """The dialogue on ``client`` (connected); returns the exit status."""
    client.subscribe("records")
    steps: list[tuple[str, int]] = []
    try:
        for source in ("remote", "wired") if wired else ("remote",):
            _wait_run(client, out, timeout_s, clock, first=not steps)
            # Each line of the dialogue is flushed: piped into a log (tee), a buffered prompt
            # would never show while the test waits for its press.
            print(
                f"stoptest: {PROMPTS[source]} (waiting up to {timeout_s:g} s)", file=out, flush=True
            )
            steps.append((source, _wait_press(client, source, timeout_s, clock)))
            _wait_off(client, clock)
    except NotDone as why:
        print(f"stoptest: not done: {why}", file=out, flush=True)
        return EXIT_NOT_DONE
    result = client.stoptest(tuple(steps)).stoptest
    recorded = _wait_recorded(client, result, clock)
    out.write(report(result, recorded=recorded))
    print(
        "stoptest: release the e-stop"
        + ("s" if wired else "")
        + " and take over on the remote to go on",
        file=out,
        flush=True,
    )
    if not recorded:
        return EXIT_NOT_DONE
    return EXIT_PASSED if result.passed else EXIT_FAILED


def _wait_run(
    client: SupervisorClient,
    out: TextIO,
    timeout_s: float,
    clock: Callable[[], float],
    *,
    first: bool,
) -> None:
    """The test starts in RUN: every output on, so that each one's way to off is measured."""
    if client.status().report.state is State.RUN:
        return
    what = "take over on the remote" if first else "release the remote's e-stop and take over"
    print(f"stoptest: {what} (the supervisor must be in RUN; waiting)", file=out, flush=True)
    deadline = clock() + timeout_s
    while clock() < deadline:
        if client.status().report.state is State.RUN:
            return
        time.sleep(0.1)
    raise NotDone(f"the supervisor did not reach RUN within {timeout_s:g} s")


def _wait_press(
    client: SupervisorClient, source: str, timeout_s: float, clock: Callable[[], float]
) -> int:
    """The ``seq`` of the stop record the press made: the next change into STOPPED, which
    must raise ``vsc_estop`` with ``source`` among its sources."""
    deadline = clock() + timeout_s
    while (left := deadline - clock()) > 0:
        push = client.next_event(timeout=min(left, 0.5))
        if not isinstance(push, RecordPush):
            continue
        record = push.record
        if not record.is_stop:
            continue
        estop = record.cause(CauseKind.VSC_ESTOP)
        sources = (estop.details.get("sources", "") if estop else "").split(",")
        if estop is None or source not in sources:
            names = ", ".join(c.name.name for c in record.causes)
            raise NotDone(f"the robot stopped for something else (#{record.seq}: {names})")
        return record.seq
    raise NotDone(f"no stop within {timeout_s:g} s")


def _wait_off(client: SupervisorClient, clock: Callable[[], float]) -> None:
    """Until every output is asked to be off (their off writes are then timed), at most
    :data:`OFF_WAIT_S`; what is still on then is judged not off by the daemon."""
    deadline = clock() + OFF_WAIT_S
    while clock() < deadline:
        if not any(client.status().report.outputs.values()):
            return
        time.sleep(POLL_S)


def _wait_recorded(
    client: SupervisorClient, result: StopTestReport, clock: Callable[[], float]
) -> bool:
    """Whether the verdict's ``stoptest`` record was pushed within :data:`RECORD_WAIT_S`:
    the daemon pushes a record once its lane has finished with it, so the command's
    "recorded" is what ``srcsctl log`` shows from then on (SR-7.4, SR-12.1)."""
    deadline = clock() + RECORD_WAIT_S
    while (left := deadline - clock()) > 0:
        push = client.next_event(timeout=min(left, 0.5))
        if isinstance(push, RecordPush) and push.record.stoptest == result:
            return True
    return False


def report(result: StopTestReport, *, recorded: bool) -> str:
    """The short report: a line per output and press, then the verdict."""
    lines = []
    limit = result.limit_ms
    for step in result.steps:
        lines.append(f"stoptest: {step.source} e-stop, stop #{step.seq}:")
        for output in step.outputs:
            ms = output.off_ms
            shown = f"{ms:8.3f} ms" if ms is not None else "  not off"
            verdict = "pass" if output.passed else "FAIL"
            lines.append(f"  {output.name:16} {shown}  {verdict}")
    overall = "PASSED" if result.passed else "FAILED"
    lines.append(
        f"stoptest: {overall}: every output off within {limit} ms of the e-stop's frame "
        f"({REQUIREMENTS} SR-12.1); "
        + ("recorded" if recorded else f"its record not finished within {RECORD_WAIT_S:g} s")
    )
    return "\n".join(lines) + "\n"

"""Whatever number or time is typed on ``srcsctl``'s command line, the command runs or refuses
it as a usage error (exit 2, with that command's usage); never a traceback, never a wait
without end (SR-8.10, SR-11.3; docs/srcsctl.md "Exit status")."""

from __future__ import annotations

import argparse
import datetime as dt
import json
import math
import subprocess
from pathlib import Path

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from supervisord.cli import srcsctl
from supervisord.cli.numbers import count, duration
from supervisord.cli.times import BadTime, parse_time
from tests.daemon.test_srcsctl import SRCSCTL

RUN_LIMIT_S = 60.0
"""Far above a refusal's start-up (under a second); an old ``--timeout nan`` never ended."""
NOT_FINITE_OR_POSITIVE = ["nan", "inf", "-inf", "-1", "0", "1e999", "1e-400", "ten"]


def srcsctl_run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [SRCSCTL, *args], capture_output=True, text=True, timeout=RUN_LIMIT_S, check=False
    )


def assert_usage_error(done: subprocess.CompletedProcess[str], command: str, flag: str) -> None:
    assert done.returncode == 2, done
    assert f"usage: srcsctl {command}" in done.stderr, done.stderr
    assert f"srcsctl {command}: error: argument {flag}" in done.stderr, done.stderr
    assert "Traceback" not in done.stderr


@pytest.mark.parametrize("timeout", NOT_FINITE_OR_POSITIVE)
def test_wait_ready_refuses_a_timeout_that_is_not_a_finite_positive_number(
    tmp_path: Path, timeout: str
) -> None:
    """SR-8.10: ``wait-ready --timeout`` nan, inf, 0 or less is a usage error with
    ``wait-ready``'s usage (nan waited without end, -1 gave up at once as "no srcsd")."""
    done = srcsctl_run("wait-ready", "--socket", str(tmp_path / "api.sock"), "--timeout", timeout)
    assert_usage_error(done, "wait-ready", "--timeout")


@pytest.mark.parametrize("value", NOT_FINITE_OR_POSITIVE)
@pytest.mark.parametrize(
    ("command", "flag"),
    [(("stoptest", "--yes"), "--timeout"), (("demo", "--auto"), "--speed")],
    ids=["stoptest", "demo"],
)
def test_every_duration_refuses_what_is_not_a_finite_positive_number(
    tmp_path: Path, command: tuple[str, ...], flag: str, value: str
) -> None:
    """SR-11.3: ``stoptest --timeout`` and ``demo --speed`` refuse nan, inf, 0 or less as a
    usage error of their own command, before anything starts."""
    socket = ["--socket", str(tmp_path / "api.sock")] if command[0] == "stoptest" else []
    done = srcsctl_run(*command, *socket, flag, value)
    assert_usage_error(done, command[0], flag)


@pytest.mark.parametrize("lines", ["-1", "1.5", "nan", "9" * 5000])
def test_log_refuses_a_count_that_is_not_a_whole_number(tmp_path: Path, lines: str) -> None:
    """SR-11.3: ``log -n`` takes a whole number, 0 or more; anything else is ``log``'s usage
    error (5,000 digits used to pass to ``int``, over its own limit)."""
    done = srcsctl_run("log", "--file", str(tmp_path / "stops.jsonl"), "-n", lines)
    assert_usage_error(done, "log", "-n/--lines")


@pytest.mark.parametrize("option", ["--since=-99999999999y", "--until=99999999999999d ago"])
def test_log_refuses_a_time_beyond_the_calendar(tmp_path: Path, option: str) -> None:
    """SR-11.3: a ``--since`` or ``--until`` beyond the years datetime knows is a usage error
    naming the time (it raised OverflowError: a traceback, exit 1)."""
    record = tmp_path / "stops.jsonl"
    record.write_text("")
    done = srcsctl_run("log", "--file", str(record), option)
    assert done.returncode == 2, done
    assert "srcsctl log: not a time:" in done.stderr
    assert "Traceback" not in done.stderr


def test_log_names_a_record_line_nested_too_deep_and_goes_on(tmp_path: Path) -> None:
    """SR-8.7: a record line of 100,000 nested arrays is named as a bad line and the records
    after it are shown (the JSON decoder's RecursionError was a traceback, exit 1)."""
    record = tmp_path / "stops.jsonl"
    good = {
        "seq": 2,
        "mono_ns": 1,
        "utc": "2024-05-01T10:00:00+00:00",
        "from": "RUN",
        "to": "STOPPED",
        "causes": [{"name": "local_estop"}],
        "trigger": "local_estop",
    }
    deep = "[" * 100_000 + "]" * 100_000
    record.write_text(f"{deep}\n{json.dumps(good)}\n")
    done = srcsctl_run("log", "--file", str(record), "--json")
    assert "Traceback" not in done.stderr
    assert f"{record}:1: not_json" in done.stderr, done.stderr
    assert [json.loads(line)["seq"] for line in done.stdout.splitlines()] == [2]
    assert done.returncode == 0


def parses_as_usage_error_or(argv: list[str]) -> argparse.Namespace | None:
    """The namespace ``srcsctl``'s own parser makes of ``argv``, or ``None`` for its usage
    error (exit 2); anything else raised fails the test."""
    try:
        return srcsctl.build_parser().parse_args(argv)
    except SystemExit as exit_:
        code = exit_.code
    assert code == 2
    return None


@settings(max_examples=300, deadline=None)
@given(st.text() | st.floats().map(str))
@example("nan")
@example("0")
@example("1e999")
@example("1m30s")
@example("9" * 400 + "d")
def test_any_timeout_text_is_a_finite_positive_number_or_a_usage_error(text: str) -> None:
    """SR-11.3: whatever text follows ``wait-ready --timeout``, the parser gives a finite
    number above 0 or its usage error; the one type says the same for every duration."""
    args = parses_as_usage_error_or(["wait-ready", f"--timeout={text}"])
    if args is not None:
        assert math.isfinite(args.timeout)
        assert args.timeout > 0
        assert duration(text) == args.timeout


@settings(max_examples=300, deadline=None)
@given(st.text() | st.integers().map(str))
def test_any_count_text_is_a_whole_number_or_a_usage_error(text: str) -> None:
    """SR-11.3: whatever text follows ``log -n``, the parser gives a whole number, 0 or more,
    or its usage error."""
    args = parses_as_usage_error_or(["log", f"--lines={text}"])
    if args is not None:
        assert isinstance(args.lines, int)
        assert args.lines >= 0
        assert count(text) == args.lines


AGES = st.builds(
    lambda sign, amount, unit, ago: f"{sign}{amount}{unit}{ago}",
    st.sampled_from(["", "-", "+"]),
    st.integers(min_value=0, max_value=10**30) | st.floats(min_value=0, allow_infinity=False),
    st.sampled_from(["s", "min", "h", "d", "w", "M", "y", " years", "us", "x"]),
    st.sampled_from(["", " ago"]),
)
ISO = st.from_regex(r"\A[0-9]{1,5}-[0-9]{1,2}-[0-9]{1,2}([T ][0-9]{1,2}:[0-9]{2})?\Z")
NOW = st.datetimes(
    min_value=dt.datetime(1, 1, 2),
    max_value=dt.datetime(9999, 12, 30),
    timezones=st.just(dt.timezone.utc),
)


@settings(max_examples=500, deadline=None)
@given(st.text() | AGES | ISO, NOW, st.booleans())
def test_any_since_text_is_a_time_or_a_bad_time(text: str, now: dt.datetime, utc: bool) -> None:
    """SR-11.3: any ``--since``/``--until`` text, at any moment of the calendar, is an aware
    time or :class:`BadTime` (``log``'s usage error), never another exception."""
    try:
        when = parse_time(text, now, utc=utc)
    except BadTime:
        return
    assert when.tzinfo is not None


def test_a_duration_is_seconds_or_a_systemd_time_span() -> None:
    """SR-11.3: a plain number is seconds; ``2s``, ``500ms``, ``1min``, ``1m30s``, ``1min 30s``
    and ``1h`` are systemd.time(7)'s spans; a unit alone or a number after a span is refused."""
    spans = ("2", "2s", "500ms", "1min", "1m30s", "1min 30s", "1h")
    assert [duration(t) for t in spans] == [2.0, 2.0, 0.5, 60.0, 90.0, 90.0, 3600.0]
    for bad in ("s", "1m 30", "2 fortnights", "0s", "\uff12s"):
        with pytest.raises(argparse.ArgumentTypeError):
            duration(bad)

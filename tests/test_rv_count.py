"""The kernel judge's field counter, pure: kernel-shaped trace lines in, the daemon's
violations by monitor and thread out, bounded and in time linear in the bytes (SR-9.9).

The lines are the kernel's own shape (``TASK-PID [CPU] FLAGS TIMESTAMP: error_MONITOR:
COMM[PID]: violation detected``, the system tier's tests/system/rv.py reads the same). The
linear-time proof follows tests/api/test_worst_case_input.py: the CPU time of this thread,
the least of a few tries, at 16 times the bytes within 64 times the cost (linear: 16;
quadratic: 256).
"""

from __future__ import annotations

import random
from collections.abc import Callable

from hypothesis import given, settings
from hypothesis import strategies as st

from bench.client_input import cpu_ns
from supervisord.rv_count import MAX_KEYS, MAX_LINE, Event, Lost, ViolationCounter, read_line


def kernel_line(running: str, stamp: str, monitor: str, judged: str) -> str:
    """One ``error_*`` event as ftrace prints it: the running task, CPU, flags, timestamp."""
    return f"{running:>20} [000] d..2. {stamp:>12}: error_{monitor}: {judged}: violation detected"


SLEEP = kernel_line("srcsd-415", "123.456789", "sleep", "srcsd[415]")
FAULT = kernel_line("srcsd-415", "130.000001", "pagefault", "srcsd[415]")
WAKE_BY_KWORKER = kernel_line("kworker/0:1-12", "131.5", "wakeup", "srcsd[415]")
LANE = kernel_line("srcsd-record-420", "125.25", "sleep", "srcsd-record[420]")
OTHER = kernel_line("python3-900", "126.0", "sleep", "python3[900]")
STACK = ("<stack trace>", " => trace_event_raw_event_ltl", " => do_nanosleep")


def counted(*lines: str) -> ViolationCounter:
    counter = ViolationCounter()
    counter.feed("".join(f"{line}\n" for line in lines).encode())
    return counter


def test_the_daemons_violations_are_counted_by_monitor_and_thread() -> None:
    """SR-9.9, SR-9.7: the loop's and a lane's violations each under their own thread name,
    a wake of the loop by a kernel worker under the loop (the judged task, not the waker),
    another program's counted apart, a stack trigger's lines read and not counted, the last
    violation's time the trace's."""
    counter = counted(SLEEP, FAULT, *STACK, WAKE_BY_KWORKER, LANE, OTHER, SLEEP, "# tracer: nop")
    assert counter.violations == {
        ("sleep", "srcsd"): 2,
        ("pagefault", "srcsd"): 1,
        ("wakeup", "srcsd"): 1,
        ("sleep", "srcsd-record"): 1,
    }
    assert counter.others == 1
    assert counter.unreadable == 0
    assert counter.last_seconds == 131.5
    assert counter.total() == 5


def test_a_line_is_read_from_the_right_so_no_name_spells_another_threads_violation() -> None:
    """SR-9.9, SR-9.7: the running task may hold spaces, brackets and ``: error_`` in its
    name; the judged task is the one before ``[PID]: violation detected``. A comm (at most
    15 bytes) cannot hold ``: error_sleep: srcsd``."""
    tricky = kernel_line("a: error_sleep: x [y]-7", "1.0", "wakeup", "srcsd[415]")
    assert read_line(tricky) == Event("wakeup", "srcsd", 1.0)
    for comm in (": error_sleep", ": error_sleep: ", "srcsd: error_"):  # 15 bytes at most
        spoof = kernel_line("x-1", "1.0", "wakeup", f"{comm}[9]")
        assert counted(spoof).violations == {}, comm
    assert read_line("CPU:1 [LOST 42 EVENTS]") == Lost(42)


def test_lines_it_cannot_read_are_counted() -> None:
    """SR-9.9: a line of another event, a monitor the rtapp container does not have, a line
    cut short, a pid that is no number: each counted unreadable, none raised."""
    counter = counted(
        "  srcsd-1 [000] d..2. 1.0: sched_switch: prev=srcsd",
        SLEEP.replace("error_sleep", "error_wwnr"),
        SLEEP[:60],
        SLEEP.replace("[415]:", "[41x]:"),
    )
    assert counter.unreadable == 4
    assert counter.violations == {}


def test_a_line_over_the_limit_is_dropped_as_it_comes() -> None:
    """SR-9.9: a line over 512 bytes, fed in pieces, is one unreadable line, its bytes never
    held past the limit; the lines after it are read."""
    counter = ViolationCounter()
    long = (" " * 600 + SLEEP).encode()
    for start in range(0, len(long), 7):
        counter.feed(long[start : start + 7])
        assert len(counter._partial) < MAX_LINE
    counter.feed(b"\n" + SLEEP.encode() + b"\n")
    assert counter.unreadable == 1
    assert counter.violations == {("sleep", "srcsd"): 1}
    exact = b" " * (MAX_LINE - 1 - len(SLEEP)) + SLEEP.encode() + b"\n"  # 512 bytes: read
    assert len(exact) == MAX_LINE
    counter.feed(exact)
    assert counter.violations == {("sleep", "srcsd"): 2}


def test_at_most_64_series_and_the_rest_in_overflow() -> None:
    """SR-9.9: lane names past the 64th (monitor, thread) pair count in the monitor's
    overflow; pairs already kept go on counting."""
    lines = [SLEEP.replace("srcsd[415]", f"srcsd-{n}[415]") for n in range(100)]
    counter = counted(*lines, lines[0])
    assert len(counter.violations) == MAX_KEYS
    assert counter.violations[("sleep", "srcsd-0")] == 2
    assert counter.overflow == {"sleep": 100 - MAX_KEYS}
    assert counter.total() == 101


@settings(max_examples=300, deadline=None)
@given(st.lists(st.binary(max_size=700), max_size=20))
def test_no_bytes_make_it_raise(chunks: list[bytes]) -> None:
    """SR-9.9: any bytes, cut anywhere: counts, never an exception, and never more kept
    than the limit."""
    counter = ViolationCounter()
    for chunk in chunks:
        counter.feed(chunk)
        assert len(counter._partial) < MAX_LINE
    assert counter.unreadable >= 0


# -- linear time -----------------------------------------------------------------------------

SHORT = 64 * 1024
LONG = 16 * SHORT
LINEAR_BOUND = 64


def assert_linear(name: str, make: Callable[[int], list[bytes]]) -> None:
    """Feeding ``make(size)`` costs, at ``LONG`` bytes, within ``LINEAR_BOUND`` times its
    cost at ``SHORT``."""

    def action(size: int) -> Callable[[], object]:
        chunks = make(size)

        def feed() -> None:
            counter = ViolationCounter()
            for chunk in chunks:
                counter.feed(chunk)

        return feed

    short = max(cpu_ns(action(SHORT), tries=9), 1)
    long = cpu_ns(action(LONG), tries=3)
    assert long < LINEAR_BOUND * short, f"{name}: {long / short:.0f} times for 16 times the bytes"


def test_a_huge_line_without_a_newline_costs_linear_time() -> None:
    """SR-9.9: one line that never ends, in 4 KiB reads (trace_pipe's) and in one read:
    dropped as it comes, each byte looked at once."""
    assert_linear("one read", lambda n: [b"x" * n])
    assert_linear("4 KiB reads", lambda n: [b"x" * 4096] * (n // 4096))


def test_random_bytes_cost_linear_time() -> None:
    """SR-9.9: random bytes, newlines among them, in 4 KiB reads."""
    rng = random.Random(9)

    def make(n: int) -> list[bytes]:
        data = rng.randbytes(n)
        return [data[i : i + 4096] for i in range(0, n, 4096)]

    assert_linear("random", make)


def test_many_distinct_thread_names_cost_linear_time() -> None:
    """SR-9.9: every line a violation by a new lane name (the series' cap reached at once),
    and every line one just under the limit: a line's cost is bounded by the limit."""

    def names(n: int) -> list[bytes]:
        lines = b"".join(
            SLEEP.replace("srcsd[415]", f"srcsd-{i}[415]").encode() + b"\n" for i in range(n // 100)
        )
        return [lines]

    assert_linear("distinct names", names)
    near = b" " * (MAX_LINE - 2 - len(SLEEP)) + SLEEP.encode() + b"\n"
    assert_linear("long lines", lambda n: [near * (n // len(near))])

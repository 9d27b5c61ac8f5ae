"""The kernel's judge, read (tests/system/rv.py): the rtapp monitors' events and stacks as the
kernel writes them into the trace, the allow-list as docs/system-tier.md states it, and the
verdict that fails a scenario of the judged tier (SR-9.8)."""

from __future__ import annotations

from pathlib import Path

from tests.system.rv import Allowed, Violation, allow_list, judge, parse

DOCS = Path(__file__).resolve().parents[2] / "docs" / "system-tier.md"
# Lines the judged kernel wrote in the tier's gpio scenario, as it wrote them (guest/judge.py
# keeps each scenario's trace in the result folder): the daemon's start under systemd's name for
# it, a VSC byte's wake from the tty layer's work, and the loop's epoll wait it ended.
KERNELS_OWN = Path(__file__).resolve().parent / "data" / "judge-gpio-excerpt.trace"

# The shape of the kernel's lines: the event's own format ("%s[%d]: violation detected",
# error_ltl_monitor_id in kernel/trace/rv/rv_trace.h) after ftrace's task, CPU, flags and time,
# then the stack trigger's "<stack trace>" and its frames, innermost first.
TRACE = """\
# tracer: nop
#
# entries-in-buffer/entries-written: 4/4   #P:1
#
#           TASK-PID     CPU#  |||||  TIMESTAMP  FUNCTION
#              | |         |   |||||     |         |
     kworker/0:1-19      [000] d..4.   412.093402: error_wakeup: srcsd[415]: violation detected
     kworker/0:1-19      [000] d..4.   412.093447: <stack trace>
 => trace_event_raw_event_error_ltl_monitor_id
 => ltl_validate
 => handle_sched_waking
 => try_to_wake_up
 => ep_poll_callback
 => __wake_up_common
 => n_tty_receive_buf_common
 => flush_to_ldisc
 => process_one_work
 => worker_thread
 => kthread
           srcsd-415     [000] d..2.   413.551020: error_sleep: srcsd[415]: violation detected
           srcsd-415     [000] d..2.   413.551061: <stack trace>
 => trace_event_raw_event_error_ltl_monitor_id
 => ltl_validate
 => handle_sched_set_state
 => do_nanosleep
 => hrtimer_nanosleep
 => __x64_sys_clock_nanosleep
 => do_syscall_64
 => entry_SYSCALL_64_after_hwframe
         python3-880     [000] d..2.   414.000100: error_pagefault: python3[880]: violation detected
"""


def test_each_violation_is_read_with_its_judged_task_its_context_and_its_stack() -> None:
    trace = parse(TRACE)
    assert trace.unreadable == 0
    wake, sleep, fault = trace.violations
    assert (wake.monitor, wake.task, wake.pid, wake.context) == (
        "wakeup",
        "srcsd",
        415,
        "kworker/0:1-19",
    )
    assert wake.stack[0] == "trace_event_raw_event_error_ltl_monitor_id"
    assert wake.stack[-1] == "kthread"
    assert wake.cause == "n_tty_receive_buf_common"  # below the monitor's and the wake's own
    assert sleep.cause == "do_nanosleep"
    assert (fault.monitor, fault.task, fault.stack, fault.cause) == (
        "pagefault",
        "python3",
        (),
        "?",
    )


def test_the_kernels_own_lines_are_read_and_the_pages_rows_explain_them() -> None:
    trace = parse(KERNELS_OWN.read_text())
    assert trace.unreadable == 0
    start, wake, sleep = trace.violations
    assert (start.monitor, start.task, start.cause) == ("pagefault", "(srcsd)", "exc_page_fault")
    assert (wake.monitor, wake.task, wake.context) == ("wakeup", "srcsd", "kworker/u4:1-24")
    assert wake.cause == "n_tty_receive_buf_common"
    assert "flush_to_ldisc" in wake.stack
    assert (sleep.monitor, sleep.cause) == ("sleep", "do_epoll_wait")
    verdict = judge(trace.violations, allow_list(DOCS.read_text()))
    assert verdict.ok
    assert sorted(row.frame for row in verdict.allowed) == [
        "do_epoll_wait",
        "n_tty_receive_buf_common",
    ]
    assert verdict.others == 1  # before the exec, under systemd's name: not judged


def test_a_line_that_is_no_event_no_stack_and_no_comment_is_counted_not_raised() -> None:
    trace = parse(
        TRACE + "garbage\n  <idle>-0 [000] d..2. 1.0: error_other: x[1]: violation detected\n"
    )
    assert len(trace.violations) == 3
    assert trace.unreadable == 2


def test_only_the_daemons_threads_are_judged_and_a_row_explains_by_monitor_and_frame() -> None:
    violations = parse(TRACE).violations
    row = Allowed("wakeup", "flush_to_ldisc", "the tty's flip buffer work")
    verdict = judge(violations, [row, Allowed("pagefault", "do_nanosleep", "wrong monitor")])
    assert verdict.allowed == {row: 1}
    assert [v.monitor for v in verdict.unexplained] == [
        "sleep"
    ]  # do_nanosleep's row is pagefault's
    assert verdict.others == 1  # python3 is not srcsd's
    assert not verdict.ok
    assert "sleep in do_nanosleep (srcsd) x1" in verdict.summary()
    assert judge(violations, []).unexplained == violations[:2]


def test_a_lanes_violation_is_the_daemons() -> None:
    lane = Violation("sleep", "srcsd-record", 416, "srcsd-record-416", ("do_fsync",))
    assert judge([lane], []).unexplained == [lane]
    assert judge([Violation("sleep", "srcsdx", 1, "x-1")], []).others == 1


ALLOWED_PAGE = """\
### The judge's allow-list

Text before the table.

| monitor | frame | what | why it stays | bound |
|---|---|---|---|---|
| wakeup | `flush_to_ldisc` | a serial byte | the tty layer | 3 ms |
| sleep | `` | an empty frame is no row | - | - |
| nosuch | `x` | no monitor | - | - |
| sleep | `unix_stream_sendmsg` | an API client | assumption 11 | 1 ms |

| monitor | frame | what |
|---|---|---|
| sleep | `after_the_table` | not read |
"""


def test_the_allow_list_is_the_table_under_its_heading_and_ends_with_it() -> None:
    assert allow_list(ALLOWED_PAGE) == [
        Allowed("wakeup", "flush_to_ldisc", "a serial byte"),
        Allowed("sleep", "unix_stream_sendmsg", "an API client"),
    ]


def test_the_pages_allow_list_is_read_and_every_row_names_a_frame() -> None:
    page = DOCS.read_text()
    assert "### The judge's allow-list" in page
    rows = allow_list(page)
    table = page.split("### The judge's allow-list", 1)[1].split("\n#", 1)[0]
    written = [line for line in table.splitlines() if line.startswith("| ") and "---" not in line]
    assert len(rows) == len(written) - 1  # every row but the header is read
    assert all(row.frame and " " not in row.frame for row in rows)


# Lines the judged kernel wrote in the tier's rttime scenario: the loop's sleep event, then,
# before that event's stack, a hard interrupt's own event and stack (a 9p reply waking a task),
# then the loop's stack. Each stack is written in the context of its event.
INTERRUPTED = Path(__file__).resolve().parent / "data" / "judge-rttime-interrupted.trace"


def test_an_event_interrupted_before_its_stack_gets_its_own_stack() -> None:
    trace = parse(INTERRUPTED.read_text())
    assert trace.unreadable == 0
    sleep, irq_wake = trace.violations  # in the order of their events
    assert (sleep.monitor, sleep.task, sleep.cause) == ("sleep", "srcsd", "do_epoll_wait")
    assert sleep.stack[-1] == "entry_SYSCALL_64_after_hwframe"
    assert "p9_client_cb" not in sleep.stack
    assert (irq_wake.monitor, irq_wake.task, irq_wake.cause) == ("wakeup", "python", "p9_client_cb")
    assert irq_wake.stack.count("trace_event_raw_event_error_ltl_monitor_id") == 2  # it
    # interrupted the sleep's event on its way to the stack: those frames are its own
    verdict = judge(trace.violations, allow_list(DOCS.read_text()))
    assert verdict.ok, verdict.summary()


def test_a_stack_without_its_event_is_unreadable_and_an_event_without_one_has_none() -> None:
    lines = INTERRUPTED.read_text().splitlines(keepends=True)
    sleep_event = next(i for i, line in enumerate(lines) if "error_sleep" in line)
    trace = parse("".join(lines[:sleep_event] + lines[sleep_event + 1 :]))
    assert trace.unreadable == 1  # the loop's stack, whose event is gone
    (irq_wake,) = trace.violations
    assert irq_wake.cause == "p9_client_cb"

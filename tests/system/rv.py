"""The kernel's judge, read: the rtapp monitors' violations in a trace, and the verdict on them.

The judged kernel (tests/system/judge.config) has the runtime-verification monitors of a
real-time program: ``pagefault`` (a real-time task took a page fault), ``sleep`` (it slept in a
way that gives no real-time guarantee, or was woken by a lower priority or a softirq) and
``wakeup`` (a lower-priority task or a softirq woke it, seen from the waker). The guest
(guest/judge.py) traces each monitor's ``error_*`` event with a stack trigger; this module
reads that text and judges it against the reviewed allow-list in docs/system-tier.md
("The judge's allow-list"), which is the one place a violation may be explained (SR-9.8).

Pure and standard library only: the guest's Python runs it after every scenario, and the host's
tests feed it the kernel's own lines. Its work is linear in the trace's length, and a line it
cannot read is counted, never raised.
"""

from __future__ import annotations

import re
from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, field, replace

MONITORS = ("pagefault", "sleep", "wakeup")
DAEMON_THREADS = re.compile(r"srcsd(-[\w.-]*)?")  # the loop "srcsd", its lanes "srcsd-*" (SR-9.7)

# "  <...>-415  [000] d..2.  123.456789: error_sleep: srcsd[415]: violation detected"
_EVENT = re.compile(
    r"^\s*(?P<context>.+?-\d+)\s+\[(?P<cpu>\d+)\]\s+(?P<flags>\S+)\s.*?:\s+error_(?P<monitor>\w+):\s+"
    r"(?P<task>.*)\[(?P<pid>\d+)\]: violation detected\s*$"
)
# "  <...>-415  [000] d..2.  123.456800: <stack trace>"
# (the flags end at a space: a flags field that could also be the text after it would make a
# line that is neither event nor stack cost the square of its length)
_STACK_HEAD = re.compile(r"^\s*.+?-\d+\s+\[(?P<cpu>\d+)\]\s+(?P<flags>\S+)\s.*<stack trace>\s*$")
_FRAME = re.compile(r"^\s*=> (?P<function>[^\s+]+)")

# Frames of the monitors, the trace machinery and the scheduler's and wait queues' plumbing:
# above the path that says why the thread slept or was woken.
_PLUMBING = re.compile(
    r"^(trace_|__trace|event_triggers_|__traceiter_|__bpf_trace|perf_trace_|ltl_|rv_|"
    r"handle_|__do_trace_|do_trace_|trace_event_|ftrace_|stack_trace_|__ftrace_|"
    r"_*schedule|try_to_wake_up|wake_up_q|_*wake_up|\w*wake_function|ep_poll_callback|"
    r"swake_up)"
)
TABLE_HEADING = "### The judge's allow-list"


@dataclass(frozen=True)
class Violation:
    """One ``error_MONITOR`` event: the judged task (its name and pid when it happened), the
    task that was running (``context``: the waker for ``wakeup``, ``<idle>-0`` or a kernel
    thread for a wake from an interrupt) and the kernel's stack, innermost first."""

    monitor: str
    task: str
    pid: int
    context: str
    stack: tuple[str, ...] = ()

    @property
    def cause(self) -> str:
        """The first frame below the monitor's and the scheduler's own: what slept or woke."""
        return next((f for f in self.stack if not _PLUMBING.match(f)), "?")

    def by_daemon(self) -> bool:
        return DAEMON_THREADS.fullmatch(self.task) is not None

    def text(self) -> str:
        frames = "\n".join(f"    {frame}" for frame in self.stack)
        return f"{self.monitor}: {self.task}[{self.pid}] (running: {self.context})\n{frames}"


@dataclass
class Trace:
    """What one read of the trace held: the violations, and the lines that were neither an
    event, a stack, nor the trace's own comments."""

    violations: list[Violation] = field(default_factory=list)
    unreadable: int = 0


def _where(line: re.Match[str]) -> tuple[str, str]:
    """The CPU and the context (ftrace's hardirq/softirq flag: ``.``, ``s``, ``h``, ``H``,
    ``Z``) a line was written in."""
    flags = line["flags"]
    return line["cpu"], flags[2] if len(flags) > 2 else "?"


def parse(text: str) -> Trace:
    """The violations in ``text``, in the order of their events, each with the stack its
    trigger wrote after it. The stack comes in the event's own context, but an interrupt may
    come in between with an event and a stack of its own (the loop's ``sleep`` event, then a
    hard interrupt's ``wakeup`` and its stack, then the loop's stack): so a stack goes to the
    last event still without one on its CPU and in its context. A stack with no such event is
    an unreadable line; an event that never gets one keeps none (its cause is ``?``)."""
    trace = Trace()
    events: list[Violation] = []
    stacks: dict[int, list[str]] = {}
    waiting: dict[tuple[str, str], int] = {}  # where -> the index of its event without a stack
    frames: list[str] | None = None  # the stack being read, if its event was found
    for line in text.splitlines():
        if not line.strip() or line.startswith("#"):
            continue
        frame = _FRAME.match(line)
        if frame is not None:
            if frames is not None:
                frames.append(frame["function"])
            continue
        head = _STACK_HEAD.match(line)
        if head is not None:
            index = waiting.pop(_where(head), None)
            frames = None if index is None else stacks.setdefault(index, [])
            trace.unreadable += index is None
            continue
        frames = None
        event = _EVENT.match(line)
        if event is None or event["monitor"] not in MONITORS:
            trace.unreadable += 1
            continue
        waiting[_where(event)] = len(events)
        events.append(
            Violation(event["monitor"], event["task"], int(event["pid"]), event["context"])
        )
    trace.violations = [
        replace(event, stack=tuple(stacks.get(index, ()))) for index, event in enumerate(events)
    ]
    return trace


@dataclass(frozen=True)
class Allowed:
    """One reviewed row of the allow-list: a violation of ``monitor`` whose stack passes
    through ``frame`` is explained by ``what``."""

    monitor: str
    frame: str
    what: str

    def covers(self, violation: Violation) -> bool:
        return violation.monitor == self.monitor and self.frame in violation.stack


def allow_list(markdown: str) -> list[Allowed]:
    """The rows of the table under :data:`TABLE_HEADING`: ``| monitor | `frame` | what | why
    it stays | bound |``. Header and rule rows are skipped; the table ends at its first line
    that is not a row."""
    rows: list[Allowed] = []
    inside = False
    for line in markdown.splitlines():
        if line.startswith(TABLE_HEADING):
            inside = True
            continue
        if not inside:
            continue
        if line.startswith("#"):
            break
        cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
        if not line.lstrip().startswith("|") or len(cells) < 3:
            if rows:
                break
            continue
        monitor, frame = cells[0], cells[1].strip("`")
        if monitor in MONITORS and frame:
            rows.append(Allowed(monitor, frame, cells[2]))
    return rows


@dataclass
class Verdict:
    """The daemon's violations split by the allow-list: those a row explains, counted by row,
    and the rest, which fail the scenario."""

    allowed: Counter[Allowed] = field(default_factory=Counter)
    unexplained: list[Violation] = field(default_factory=list)
    others: int = 0  # violations by tasks that are not srcsd's (not judged)

    @property
    def ok(self) -> bool:
        return not self.unexplained

    def summary(self) -> str:
        """One line: the unexplained ones by monitor and cause, then the allowed by row."""
        causes = Counter(f"{v.monitor} in {v.cause} ({v.task})" for v in self.unexplained)
        bad = ", ".join(f"{cause} x{n}" for cause, n in causes.most_common())
        good = ", ".join(f"{row.monitor} via {row.frame} x{n}" for row, n in self.allowed.items())
        return f"unexplained: {bad or 'none'}; allowed: {good or 'none'}; others' {self.others}"


def judge(violations: Iterable[Violation], rows: list[Allowed]) -> Verdict:
    verdict = Verdict()
    for violation in violations:
        if not violation.by_daemon():
            verdict.others += 1
            continue
        row = next((r for r in rows if r.covers(violation)), None)
        if row is None:
            verdict.unexplained.append(violation)
        else:
            verdict.allowed[row] += 1
    return verdict

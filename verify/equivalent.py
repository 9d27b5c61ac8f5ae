"""Mutants of the safety core that no test can tell from the original, each with the
argument why (docs/verification.md "Mutation testing"; ``./dev mutate`` reads this file and
counts them apart). A mutant is named by its file and its line before and after the change,
so an entry outlives edits elsewhere, and ``./dev mutate`` reports an entry whose mutant no
longer exists, or that a test kills after all."""

from __future__ import annotations

from dataclasses import asdict, dataclass


@dataclass(frozen=True)
class Equivalent:
    """A mutant no test can tell from the original, and why."""

    file: str
    where: str  # as Mutant.where
    original: str
    mutated: str
    why: str

    @property
    def key(self) -> tuple[str, str, str, str]:
        return self.file, self.where, self.original.strip(), self.mutated.strip()

    def json(self) -> dict[str, str]:
        return asdict(self)


_INIT = "SafetyCore.__init__"
_INIT_HELD_SINCE = (
    "read only while _held_mode is set, and _hold_mode sets both together when _held_mode is "
    "None, which it is at start: the start value is never read"
)
_STEADY_ESTOP = (
    "read only by the cheap path, which runs only once _steady is true, and every step that "
    "makes _steady true sets _steady_estop first (_finish): the start value is never read"
)

_DEADLINE = "next_deadline"
_LATER_EQUAL = (
    "when the candidate equals earliest, the original keeps earliest and the mutant sets earliest "
    "to the candidate: the same value, and earliest is all the function returns"
)

_ALWAYS = (
    "ALWAYS is read only by Reflex.off (now >= since), and every now the core is given is a "
    "reading of the daemon's clock, time.monotonic_ns(): Linux's CLOCK_MONOTONIC, which is "
    "never negative (a time namespace may not offset it below zero, time_namespaces(7)). "
    "Each mutated ALWAYS (0, -2**61, -2**63) is at most 0, as the original's -2**62 is: "
    "now >= since holds for every such now with each, and the entries are the same outputs"
)

_ONE_UID = "step.charged is a tuple of one (the step's user): its first item is its last"

_DOWN = "VscLink.down"
_VSC_INIT = "VscLink.__init__"
_CLOSED = (
    "read only while the link is open (by the handling of a VSC message, refused while it is "
    "closed, and by the link's frames and deadlines, which a closed link skips), and "
    "LinkOpened sets it again before the link is open: the value a closed link keeps is never "
    "read"
)

_WAITING_CLEARS = (
    "every step into WAITING (__init__, restart, abort, a late try cleared) sets _withheld_from, "
    "_trip_ns and _resumed_ns to None, only a heartbeat while WITHHOLDING sets _trip_ns and only "
    "a heartbeat sent while RESUMED sets _resumed_ns, and WITHHOLDING is entered from WAITING "
    "alone"
)

_WORDS_SINCE = (
    "read only while _words is set (judge's rename test comes after `words is None or`, "
    "canonical reads it under `if self._words is not None`), and judge sets _words and "
    "_words_since together whenever _words leaves None (`words is None` is the first test of "
    "the rename): the start value is never read (a snapshot carries it; a restored core reads "
    "it no more)"
)

_KEPT = (
    "a bound on memory only: exhausted and free_at read the limit newest times of a window, "
    "which every bound of at least one limit keeps (KEPT * limit >= limit)"
)

_VIEW_NOW = (
    "every place that asks the view a question sets its now first (SafetyCore.reflex's "
    "_view.at(now), canonical's at(now, last_stop_raised_ns), the decision's "
    "next_deadline(self._view.at(now)), the cheap path's view.now = now before its first "
    "question): the start value is never read"
)

EQUIVALENT: tuple[Equivalent, ...] = (
    Equivalent(
        "book.py",
        "CauseBook._raise",
        "entry.active, entry.latched = True, entry.latched or stop",
        "entry.active, entry.latched = True, entry.latched and stop",
        "an entry is made with latched = stop (its cause's severity, fixed per cause) and this "
        "line is the only other that writes latched: so an existing entry's latched equals stop, "
        "and latched or stop equals latched and stop",
    ),
    Equivalent(
        "book.py",
        "CauseBook.stops_clear_since",
        "if entry.active or entry.cleared_ns is None:",
        "if entry.active and entry.cleared_ns is None:",
        "active and cleared_ns are written together: _raise sets active with cleared_ns None, "
        "set (to clear) and pulse clear active with cleared_ns now, and nothing else writes "
        "either: so active is true exactly when cleared_ns is None, and the two tests agree",
    ),
    Equivalent("budget.py", "", "KEPT: Final = 4", "KEPT: Final = 3", _KEPT),
    Equivalent("budget.py", "", "KEPT: Final = 4", "KEPT: Final = 5", _KEPT),
    Equivalent(
        "vsc.py",
        "",
        "VSC_SLOWEST_RATE_INTERVAL_NS = 100 * NS_PER_MS",
        "VSC_SLOWEST_RATE_INTERVAL_NS = 99 * NS_PER_MS",
        "its one use is TAKEOVER_MIN_HEARTBEATS = 200 ms // it + 1, which is 3 for 99 ms as for "
        "100 ms (101 ms makes it 2, and is killed)",
    ),
    Equivalent(
        "vsc.py", _VSC_INIT, "self._held_since = 0", "self._held_since = -1", _INIT_HELD_SINCE
    ),
    Equivalent(
        "vsc.py", _VSC_INIT, "self._held_since = 0", "self._held_since = 1", _INIT_HELD_SINCE
    ),
    Equivalent(
        "vsc.py",
        _VSC_INIT,
        "self._remote_linked = False",
        "self._remote_linked = True",
        "the start value (in __init__) is read only by a VSC heartbeat, which is refused until "
        "LinkOpened, and LinkOpened sets it False (VscLink.opened)",
    ),
    Equivalent(
        "core.py",
        "SafetyCore",
        "_steady_estop = 0  # the user heartbeat's byte from the conditions alone (no urgent "
        "raise)",
        "_steady_estop = -1  # the user heartbeat's byte from the conditions alone (no urgent "
        "raise)",
        _STEADY_ESTOP,
    ),
    Equivalent(
        "core.py",
        "SafetyCore",
        "_steady_estop = 0  # the user heartbeat's byte from the conditions alone (no urgent "
        "raise)",
        "_steady_estop = 1  # the user heartbeat's byte from the conditions alone (no urgent "
        "raise)",
        _STEADY_ESTOP,
    ),
    Equivalent(
        "cheap.py",
        "cheap",
        "now = event.now if event.now > last else last",
        "now = event.now if event.now >= last else last",
        "the two differ only when event.now equals last, where both choices are the same number",
    ),
    Equivalent(
        "cheap.py",
        "cheap",
        'raise AssertionError("a heartbeat of an unchanged mode asked a takeover")',
        "pass",
        "unreachable: take_vsc_heartbeat asks a takeover only for a heartbeat that begins one, "
        "and VscLink.unchanged_by, checked just before, passes only a heartbeat of the "
        "last one's mode (no takeover: that needs another mode before Operational), in time "
        "(not silent before) and after a heartbeat since the link opened (which set "
        "remote_linked from that same mode: no relink)",
    ),
    Equivalent(
        "cheap.py",
        "cheap",
        "moved = False  # whether the input moved a fact that a deadline is counted from",
        "moved = True  # whether the input moved a fact that a deadline is counted from",
        "moved True never keeps the previous deadline: the mutant always asks next_deadline "
        "of the machines as the input left them, the computation the full step ends with. The "
        "original keeps previous.next_deadline only for an input that sent nothing and moved "
        "nothing (a Tick, a Joystick, a Gps, a RemoteStatus while the battery is not watched: "
        "no machine changes) and when that deadline fell before previous.now + IDLE_NS. Then "
        "every candidate next_deadline weighs but the idle bound is a time a machine keeps, "
        "the same as at previous.now (the link's timeout, heartbeat and key-85 times, the "
        "clients' timeouts, the battery's stale time, the outputs' off times, the display's "
        "slots, the proof test's limits; the clients' deferred ends, counted from now, decline "
        "the cheap path with clients.pending()), each counted only when later than now, and "
        "none lies in (previous.now, now], since now < previous.next_deadline, the earliest of "
        "them: so the earliest is the same machine time, now + IDLE_NS being later still, and "
        "both give one number (the bounded exploration of takeover, clients, can and "
        "battery_hold gives the digests of the tree on the mutant, decisions included)",
    ),
    Equivalent(
        "core.py",
        "SafetyCore._step",
        "steady, self._steady = self._steady and self.cheap_path, False",
        "steady, self._steady = self._steady and self.cheap_path, True",
        "_steady is read only by handle (before a step) and canonical (between steps), and every "
        "step ends by setting it: True at its normal end, False in handle when it raised; the "
        "value written at a step's start is never read",
    ),
    Equivalent(
        "charging.py",
        "charge_step",
        "step.limited = step.charged is not None and budget.exhausted(step.charged[0], step.now)",
        "step.limited = step.charged is not None and budget.exhausted(step.charged[-1], step.now)",
        _ONE_UID,
    ),
    Equivalent(
        "core.py",
        "SafetyCore._finish",
        "self._budget.charge(step.charged[0], now)",
        "self._budget.charge(step.charged[-1], now)",
        _ONE_UID,
    ),
    Equivalent(
        "vsc.py",
        "VscLink.opened",
        "self._run = None",
        "pass",
        "the same handler forgets the last heartbeat's time, its mode and the mode's hold, so "
        "the first heartbeat after it either starts a new run (it cannot be unbroken) or, "
        "Operational, asks no takeover (no mode before it) and clears the run; _settle reads "
        "the run only while a mode is held: the run kept is never read",
    ),
    Equivalent(
        "vsc.py",
        _DOWN,
        "self.mode = None",
        "pass",
        _CLOSED
        + " (the proof test reads the mode only when it starts, which needs the VSC heard on "
        "an open link)",
    ),
    Equivalent("vsc.py", _DOWN, "self._run = None", "pass", _CLOSED),
    Equivalent("vsc.py", _DOWN, "self._remote_linked = False", "pass", _CLOSED),
    Equivalent(
        "vsc.py", _DOWN, "self._remote_linked = False", "self._remote_linked = True", _CLOSED
    ),
    Equivalent("vsc.py", _DOWN, "self._next_key85_ns = None", "pass", _CLOSED),
    Equivalent("vsc.py", _DOWN, "self.next_heartbeat_ns = None", "pass", _CLOSED),
    Equivalent(
        "clients.py",
        "Clients.next_deadline",
        "if free is not None and now < free and (earliest is None or free < earliest):",
        "if free is not None and now <= free and (earliest is None or free < earliest):",
        "free_at is None unless the user is past its budget at now, and then it is the time the "
        "oldest record that counts is a window old, which is after now (a record exactly a "
        "window old no longer counts): free is never now",
    ),
    Equivalent(
        "clients.py",
        "Clients.next_deadline",
        "if free is not None and now < free and (earliest is None or free < earliest):",
        "if free is not None and now < free and (earliest is None or free <= earliest):",
        _LATER_EQUAL,
    ),
    Equivalent(
        "clients.py",
        "Clients.next_deadline",
        "if now < due and (earliest is None or due < earliest):",
        "if now < due and (earliest is None or due <= earliest):",
        _LATER_EQUAL,
    ),
    Equivalent(
        "vsc.py",
        "VscLink.next_deadline",
        "if due is not None and now < due and (earliest is None or due < earliest):",
        "if due is not None and now < due and (earliest is None or due <= earliest):",
        _LATER_EQUAL,
    ),
    Equivalent(
        "deadline.py",
        _DEADLINE,
        "if later is not None and later < earliest:",
        "if later is not None and later <= earliest:",
        _LATER_EQUAL + " (the same line for the clients', the link's and the outputs' deadlines)",
    ),
    Equivalent(
        "outputs.py",
        "Outputs.next_deadline",
        "if now < due and (earliest is None or due < earliest):",
        "if now < due and (earliest is None or due <= earliest):",
        _LATER_EQUAL,
    ),
    Equivalent(
        "clients.py",
        "Clients.disconnected",
        "self._progress.restart(name)",
        "pass",
        "a client's progress is read only while it is named (lost() reads it for a name in "
        "_by_name, a heartbeat needs a named connection), and the hello that names it again "
        "restarts it first: what a disconnection leaves there is never read",
    ),
    Equivalent(
        "battery.py",
        "RemoteBattery.__init__",
        "self._words_since = 0",
        "self._words_since = -1",
        _WORDS_SINCE,
    ),
    Equivalent(
        "battery.py",
        "RemoteBattery.__init__",
        "self._words_since = 0",
        "self._words_since = 1",
        _WORDS_SINCE,
    ),
    Equivalent(
        "step.py",
        "Step",
        "arriving: bool = False",
        "arriving: bool = True",
        "the default is read only by the battery's judgement in a step whose input is no event "
        "(the full step sets step.arriving for every event); such a step comes at an instant "
        "the core has already judged at the same rule (a report refused on a closed link counts "
        "as no report, SR-8.12), so a report 'arriving' in it finds the battery as the step before "
        "did: no condition differs",
    ),
    Equivalent(
        "step.py",
        "Step",
        "limited: bool = False  # the input's user is past its record budget (SR-8.5)",
        "limited: bool = True  # the input's user is past its record budget (SR-8.5)",
        "read only by the handlers of a local release and of a disconnection, which run only "
        "from SafetyCore._apply, and the full step sets step.limited for every event just "
        "before it decides whether to apply it; a step that applies no event (an input that is "
        "no event, the fail-safe's) never reads it: the default is never read",
    ),
    Equivalent(
        "prooftest.py",
        "ProofTest.__init__",
        "self._was_operational = False",
        "self._was_operational = True",
        "read only by a heartbeat while WITHHOLDING, and advance sets it in the step that enters "
        "WITHHOLDING, the only way in: the start value is never read",
    ),
    Equivalent(
        "prooftest.py",
        "ProofTest.advance",
        "self._trip_ns = None",
        "pass",
        "_trip_ns is already None when WITHHOLDING is entered: " + _WAITING_CLEARS,
    ),
    Equivalent(
        "prooftest.py",
        "ProofTest._resume",
        "self._resumed_ns = None  # set by the first heartbeat that goes out",
        "pass  # set by the first heartbeat that goes out",
        "_resume runs only while WITHHOLDING, where _resumed_ns is None: " + _WAITING_CLEARS,
    ),
    Equivalent(
        "prooftest.py",
        "ProofTest._finish",
        "self._resumed_ns = None",
        "pass",
        "every failure but not_cleared is finished while WAITING (key85_off) or WITHHOLDING "
        "(no_trip, late, stayed_operational), where _resumed_ns is None: " + _WAITING_CLEARS,
    ),
    Equivalent(
        "reflex.py", "", "ALWAYS: Final = -(1 << 62)", "ALWAYS: Final = -(0 << 62)", _ALWAYS
    ),
    Equivalent(
        "reflex.py", "", "ALWAYS: Final = -(1 << 62)", "ALWAYS: Final = -(2 << 62)", _ALWAYS
    ),
    Equivalent(
        "reflex.py", "", "ALWAYS: Final = -(1 << 62)", "ALWAYS: Final = -(1 << 61)", _ALWAYS
    ),
    Equivalent(
        "reflex.py", "", "ALWAYS: Final = -(1 << 62)", "ALWAYS: Final = -(1 << 63)", _ALWAYS
    ),
    Equivalent("view.py", "View.__init__", "self.now = 0", "self.now = 1", _VIEW_NOW),
    Equivalent("view.py", "View.__init__", "self.now = 0", "self.now = -1", _VIEW_NOW),
    Equivalent(
        "daemon/refusal_log.py",
        "RefusalLog.__init__",
        "self._next_log = 0  # the loop's clock at which the next line may go out",
        "self._next_log = -1  # the loop's clock at which the next line may go out",
        "read only by refused's now >= self._next_log, and every now it is given is a reading "
        "of the loop's clock, time.monotonic_ns(), never negative (as for ALWAYS above): now >= "
        "-1 and now >= 0 agree for each such now (0 itself is pinned by "
        "test_the_first_refusal_is_logged_at_once_whatever_the_clock_reads, which kills the 1)",
    ),
    Equivalent(
        "daemon/waiter.py",
        "Waiter.__init__",
        "self.cursor = -1  # the last client descriptor served: the next turn starts after it",
        "self.cursor = -2  # the last client descriptor served: the next turn starts after it",
        "read only by order's item[0] > cursor and item[0] <= cursor, where item[0] is a ready "
        "client's descriptor, never negative (epoll reports only open descriptors, and the loop "
        "sets cursor only to one it served, loop.py): every such descriptor is greater than "
        "-1 and than -2 alike, so both split the ready clients the same (the 0 is killed by "
        "test_descriptor_0_is_a_client_like_any_other_in_the_first_turn)",
    ),
    Equivalent(
        "daemon/waiter.py",
        "Waiter.watch",
        "wanted[api_fd] = select.EPOLLIN | (select.EPOLLOUT if wants_write else 0)",
        "wanted[api_fd] = select.EPOLLIN | (select.EPOLLOUT if wants_write else 1)",
        "EPOLLIN is 1 (the Linux ABI, <sys/epoll.h>: EPOLLIN = 0x001, on every architecture), "
        "so EPOLLIN | 1 is EPOLLIN | 0: the same events are registered and recorded",
    ),
    Equivalent(
        "daemon/output_bank.py",
        "OutputBank.next_deadline",
        "if output.is_open and (due := output.next_deadline()) is not None and due < deadline:",
        "if output.is_open and (due := output.next_deadline()) is not None and due <= deadline:",
        "when due equals deadline, the original keeps deadline and the mutant sets deadline to "
        "due: the same value, and deadline is all the function returns (as _LATER_EQUAL)",
    ),
    Equivalent(
        "daemon/lifecycle.py",
        "start",
        "decision = loop.decision or core.decision  # the last applied (never None here)",
        "decision = loop.decision and core.decision  # the last applied (never None here)",
        "after loop.begin(core) loop.decision is a Decision (begin applies core.decision, and "
        "_finish sets loop.decision to it, None before; a Decision is always true), so the "
        "original gives loop.decision and the mutant core.decision; these are one object: "
        "every decision the loop applies comes from the core, the last applied is the last "
        "the core made (Supervisor._apply applies the read-backs' decisions in the order fed, "
        "to the last), and core.decision is the last it made "
        "(test_the_start_says_ready_only_with_the_outputs_off_and_the_link_open asserts both)",
    ),
    Equivalent(
        "daemon/deadlines.py",
        "next_deadline",
        "if watchdog is not None and watchdog < deadline:",
        "if watchdog is not None and watchdog <= deadline:",
        "when the watchdog's time equals deadline, the original keeps deadline and the mutant "
        "sets deadline to the watchdog's time: the same value, and deadline is all the "
        "function returns (as _LATER_EQUAL)",
    ),
    Equivalent(
        "daemon/deadlines.py",
        "next_deadline",
        "if listener_deadline is not None and listener_deadline < deadline:",
        "if listener_deadline is not None and listener_deadline <= deadline:",
        "when the listener's deadline equals deadline, the original keeps deadline and the "
        "mutant sets deadline to the listener's: the same value, and deadline is all the "
        "function returns (as _LATER_EQUAL)",
    ),
)

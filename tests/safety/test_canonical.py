"""The canonical form the exhaustive exploration compares states by (docs/verification.md "The
time abstraction"): it reads every attribute that can change a later decision, it does not
depend on when the core started, and it tells apart exactly what its guards tell apart."""

from __future__ import annotations

import ast
import dataclasses
import inspect
import textwrap

import pytest

from supervisord.protocol.messages import RemoteStatus
from supervisord.safety import SafetyCore
from supervisord.safety.availability import REMOTE_STATUS_FRESH_NS, Reaction
from supervisord.safety.battery import RemoteBattery
from supervisord.safety.book import CauseBook
from supervisord.safety.budget import RecordBudget
from supervisord.safety.clients import Clients
from supervisord.safety.display import DisplayStore
from supervisord.safety.outputs import Outputs
from supervisord.safety.prooftest import ProofTest
from supervisord.safety.vsc import VscLink
from tests.safety.rig import MS, ROBOT, START_NS, Rig
from verify.explore import UNIT_NS, region

LEFT_OUT: dict[type, frozenset[str]] = {
    SafetyCore: SafetyCore._NOT_CANONICAL,
    # the last clearing is read through stops_clear_since, the last raise by the core against
    # the takeover's run; the changes are empty between steps
    CauseBook: frozenset({"_changes", "last_stop_raised_ns"}),
    RecordBudget: frozenset({"limit", "total"}),  # constants (the window is each clock's limit)
    ProofTest: frozenset({"late_tries"}),  # a constant
    DisplayStore: frozenset(),
    Clients: Clients.NOT_CANONICAL,
    VscLink: VscLink.NOT_CANONICAL,
    RemoteBattery: RemoteBattery.NOT_CANONICAL,
    Outputs: Outputs.NOT_CANONICAL,
}


BUILT_BY = {"_view": "_compose"}
"""An attribute of the core built once from others (the view of its machines), by the method
that builds it: ``canonical`` reading it reads what that method reads."""


def _read(cls: type, method: str = "canonical") -> set[str]:
    """Every ``self.NAME`` (and ``self._proof``-style read through a local) in ``canonical``,
    in the methods of the class it calls, and in the method that builds an attribute it reads
    (:data:`BUILT_BY`: ``self._view``, whose machines it iterates)."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(getattr(cls, method))))
    read = {
        node.attr
        for node in ast.walk(tree)
        if isinstance(node, ast.Attribute)
        and isinstance(node.value, ast.Name)
        and node.value.id == "self"
    }
    for name in list(read):
        if name != method and inspect.isfunction(getattr(cls, name, None)):
            read |= _read(cls, name)
        elif name in BUILT_BY and BUILT_BY[name] != method:
            read |= _read(cls, BUILT_BY[name])
    return read


def _instances() -> dict[type, object]:
    rig = Rig()
    rig.bring_up()
    core = rig.core
    return {
        SafetyCore: core,
        CauseBook: core._book,
        RecordBudget: core._budget,
        ProofTest: core._proof,
        DisplayStore: core._display,
        Clients: core._clients,
        VscLink: core._vsc,
        RemoteBattery: core._battery,
        Outputs: core._outputs,
    }


@pytest.mark.parametrize("cls", list(LEFT_OUT), ids=lambda c: c.__name__)
def test_canonical_reads_every_attribute_but_those_it_names(cls: type) -> None:
    """SR-8.7: a state attribute added later and forgotten in ``canonical`` would merge states
    that differ, and the exploration would stop looking; every attribute of a live instance
    is read by ``canonical`` or named as left out (with the reason beside it)."""
    instance = _instances()[cls]
    names = set(vars(instance)) if hasattr(instance, "__dict__") else set()
    names |= {s for c in cls.__mro__ for s in getattr(c, "__slots__", ())}
    assert names
    missing = names - _read(cls) - LEFT_OUT[cls]
    assert missing == set()
    assert LEFT_OUT[cls] <= names  # nothing named that does not exist


def test_the_form_does_not_depend_on_when_the_core_started() -> None:
    """SR-2.11: the same inputs an hour later give the same form: every time is an age."""
    forms = []
    for shift in (0, 3_600_000 * MS):
        rig = Rig()
        rig.now = START_NS
        rig.core = SafetyCore(ROBOT, START_NS + shift)
        rig.now += shift
        rig.bring_up()
        forms.append(rig.core.canonical())
    assert forms[0] == forms[1]


def test_ages_are_exact_below_their_limit_and_alike_above_it() -> None:
    """SR-2.2: the VSC's last heartbeat is told apart 1 ns before its 200 ms timeout and not
    after it: a guard sees the difference before, none after."""
    rig = Rig()
    rig.bring_up()
    last = rig.now

    def age(at: int) -> int:
        (found,) = [a for n, a, _ in rig.core.canonical(at)[1] if n == "vsc:last"]
        return found

    assert age(last + 200 * MS - 2) != age(last + 200 * MS - 1)
    assert age(last + 200 * MS) == age(last + 200 * MS + 1) == age(last + 900 * MS)


def test_the_battery_clocks_limits_are_whole_units_of_the_exploration() -> None:
    """SR-8.12, SR-3.4: the clocks of a watched battery (the report's age, the reason's and the
    good run's) have every limit a whole number of the exploration's 10 ms units, so that its
    regions keep the report's age exact at the 3.5 s limit and one past it (a report arriving
    then refreshes it, a step after it finds it stale) and the battery models can run at all
    (``region`` refuses any other limit)."""
    rig = Rig(dataclasses.replace(ROBOT, on_estop_unavailable=Reaction.HOLD))
    rig.open_link()
    rig.from_vsc(RemoteStatus(10))
    rig.advance(10)
    rig.from_vsc(RemoteStatus(80))  # held, a good run begun
    clocks = {name: limits for name, _, limits in rig.core.canonical(rig.now + 10 * MS)[1]}
    battery = {n: limits for n, limits in clocks.items() if n.startswith("battery:")}
    assert set(battery) == {"battery:seen", "battery:words_since", "battery:good_since"}
    assert max(battery["battery:seen"]) > REMOTE_STATUS_FRESH_NS
    for name, limits in battery.items():
        assert all(limit % UNIT_NS == 0 for limit in limits), (name, limits)
    region(list(rig.core.canonical(rig.now + 10 * MS)[1]))  # raises for a limit not whole


def test_the_view_asked_for_the_form_carries_the_latest_stop_raised() -> None:
    """SR-4.3, SR-2.11: the view the canonical form is asked about carries when the latest stop
    was raised (the link's form orders the takeover's run against it); a view asked at a time
    alone carries none, so that no step's question reads a stale one."""
    view = SafetyCore(ROBOT, START_NS)._view
    at = view.at(START_NS + 5 * MS, START_NS + 2 * MS)
    assert (at.now, at.last_stop_raised_ns) == (START_NS + 5 * MS, START_NS + 2 * MS)
    at = view.at(START_NS + 6 * MS)
    assert (at.now, at.last_stop_raised_ns) == (START_NS + 6 * MS, None)

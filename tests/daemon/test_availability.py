"""Is the remote e-stop available (SR-8.11): the pure function, one part at a time.

Time is passed in (ns); nothing here waits.
"""

from __future__ import annotations

from collections.abc import Iterable

import pytest

from supervisord.api.status import EstopAvailable
from supervisord.daemon.availability import estop_available
from supervisord.protocol.codes import VscMode
from supervisord.protocol.messages import RemoteStatus, VscHeartbeat
from supervisord.safety.availability import REMOTE_STATUS_FRESH_NS
from supervisord.safety.prooftest import Phase, ProofStatus, ProofTestPolicy
from supervisord.vocabulary import Cause

NOW = 1_000 * 1_000_000_000
LINKED = VscHeartbeat(VscMode.OPERATIONAL)
PASSED = ProofStatus(ProofTestPolicy.BLOCK, Phase.PASSED, None)


def _check(
    *,
    active: Iterable[str] = (),
    heartbeat: VscHeartbeat | None = LINKED,
    battery: int | None = 80,
    age_ns: int = 0,
    prooftest: ProofStatus | None = PASSED,
    min_battery: int = 20,
) -> EstopAvailable:
    remote = RemoteStatus(battery) if battery is not None else None
    return estop_available(
        NOW,
        active=[Cause.from_text(name) for name in active],
        heartbeat=heartbeat,
        remote=remote,
        remote_seen=NOW - age_ns if remote is not None else None,
        prooftest=prooftest,
        min_battery=min_battery,
    )


def test_everything_in_place_is_available() -> None:
    """VSC heard, remote linked, battery fresh and above the minimum, watchdog proven:
    available, nothing missing; the status object says so."""
    result = _check()
    assert result.available
    assert result.json() == {"available": True, "missing": []}


@pytest.mark.parametrize(
    ("cause", "words"),
    [
        ("vsc_link_lost", "the VSC is not heard"),
        ("transport_fault", "the link to the VSC has failed"),
        ("vsc_watchdog_off", "the VSC's key-85 watchdog is off"),
    ],
)
def test_a_lost_vsc_or_watchdog_is_missing(cause: str, words: str) -> None:
    """An active link-loss, transport fault or watchdog-off cause makes the e-stop not
    available, named in words; other causes (a client lost) are not the e-stop's."""
    result = _check(active=[cause, "client_lost:autonomy"])
    assert result.missing == (words,)


def test_the_mode_of_a_vsc_not_heard_is_not_read() -> None:
    """The VSC not heard: its last heartbeat's mode is stale, so only the loss is named."""
    result = _check(active=["vsc_link_lost"], heartbeat=VscHeartbeat(VscMode.SEARCHING))
    assert result.missing == ("the VSC is not heard",)


def test_no_heartbeat_yet_is_missing() -> None:
    """Before the first VSC heartbeat, the e-stop is not available."""
    result = _check(heartbeat=None)
    assert result.missing == ("no heartbeat from the VSC yet",)


@pytest.mark.parametrize(("mode", "name"), [(VscMode.SEARCHING, "searching"), (0x42, "0x42")])
def test_a_remote_not_linked_is_missing(mode: int, name: str) -> None:
    """A VSC in Searching (or a mode without a name) has no remote linked: not available."""
    result = _check(heartbeat=VscHeartbeat(mode))
    assert result.missing == (f"no remote is linked to the VSC (its mode is {name})",)


@pytest.mark.parametrize("mode", [VscMode.LOCAL, VscMode.REMOTE, VscMode.MENU, VscMode.PAUSE])
def test_every_linked_mode_counts_as_linked(mode: VscMode) -> None:
    """Local, Remote, Menu and Pause have a remote linked as much as Operational."""
    assert _check(heartbeat=VscHeartbeat(mode)).available


def test_the_battery_minimum_is_inclusive() -> None:
    """At the minimum is available; one percent below is not, with both numbers said."""
    assert _check(battery=20, min_battery=20).available
    result = _check(battery=19, min_battery=20)
    assert result.missing == ("the remote's battery is 19 %, below 20 %",)
    assert _check(battery=3).missing == ("the remote's battery is 3 %, below 20 %",)


def test_a_battery_report_as_old_as_the_limit_is_missing() -> None:
    """A report one nanosecond younger than REMOTE_STATUS_FRESH_NS still counts; one exactly
    that old does not (the core's rule, SR-8.12)."""
    assert _check(age_ns=REMOTE_STATUS_FRESH_NS - 1).available
    result = _check(age_ns=REMOTE_STATUS_FRESH_NS)
    assert result.missing == ("the remote's battery has not been reported for 3.5 s",)


def test_no_battery_report_is_missing() -> None:
    """A VSC that never sent remote status (not commissioned): not available, and the words
    say how to turn it on."""
    (text,) = _check(battery=None).missing
    assert text.startswith("the remote's battery is not reported")
    assert "srcsctl commission" in text


def test_min_battery_zero_turns_the_battery_check_off() -> None:
    """``vsc.min_remote_battery = 0``: neither the level nor the report's age is checked."""
    assert _check(battery=None, min_battery=0).available
    assert _check(battery=0, min_battery=0).available
    assert _check(age_ns=REMOTE_STATUS_FRESH_NS * 10, min_battery=0).available


@pytest.mark.parametrize("phase", [Phase.WAITING, Phase.WITHHOLDING, Phase.RESUMED, Phase.FAILED])
@pytest.mark.parametrize("policy", [ProofTestPolicy.BLOCK, ProofTestPolicy.RECORD])
def test_an_unproven_watchdog_is_missing(policy: ProofTestPolicy, phase: Phase) -> None:
    """Under a proof-test policy, anything but a passed proof test is missing."""
    result = _check(prooftest=ProofStatus(policy, phase, None))
    assert result.missing == (
        f"the VSC's key-85 watchdog is not proven (proof test {phase.value})",
    )


@pytest.mark.parametrize("prooftest", [None, ProofStatus(ProofTestPolicy.OFF, Phase.OFF, None)])
def test_no_proof_test_in_the_config_is_not_missing(prooftest: ProofStatus | None) -> None:
    """CAN, HID and ``vsc.prooftest = "off"``: there is no proof test to pass."""
    assert _check(prooftest=prooftest).available


def test_every_missing_part_is_named_at_once() -> None:
    """Several parts missing: each is named, in a fixed order (VSC, remote, battery, proof)."""
    result = _check(
        heartbeat=VscHeartbeat(VscMode.SEARCHING),
        battery=10,
        prooftest=ProofStatus(ProofTestPolicy.BLOCK, Phase.WAITING, None),
    )
    assert result.missing == (
        "no remote is linked to the VSC (its mode is searching)",
        "the remote's battery is 10 %, below 20 %",
        "the VSC's key-85 watchdog is not proven (proof test waiting)",
    )

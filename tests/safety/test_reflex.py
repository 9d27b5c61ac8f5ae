"""The reflex (SR-9.5): what a stopping VSC heartbeat switches off at once, given by the core
from its state before the full step, equals what the full step switches off at once."""

from __future__ import annotations

import pytest

from supervisord.safety import Decision, State
from supervisord.safety.prooftest import Phase
from supervisord.safety.reflex import NOTHING
from tests.safety.rig import LOCAL, MS, OPERATIONAL, PAUSE, Rig
from tests.safety.test_prooftest import Vsc
from tests.safety.test_stop_category import BRAKES_MS, CATEGORY_1, FANS_MS

REMOTE_ESTOP = 0x01


def _switched_off(before: Decision, after: Decision) -> list[str]:
    return sorted(n for n, on in before.outputs.items() if on and not after.outputs[n])


def _early_and_full(rig: Rig, mode: int, estop: int) -> tuple[list[str], list[str]]:
    """The reflex's outputs for the heartbeat, and the full step's, fed it."""
    reflex = rig.core.reflex(rig.now)
    assert reflex is not None, "time decides nothing else here: the reflex holds"
    early = reflex.off(mode, estop, rig.now)
    before = rig.last
    return sorted(early), _switched_off(before, rig.vsc(mode, estop))


@pytest.mark.parametrize(
    ("mode", "estop", "off"),
    [
        (PAUSE, 0, ["drive"]),
        (LOCAL, 0, ["drive"]),
        (OPERATIONAL, REMOTE_ESTOP, ["drive", "lights"]),
        (PAUSE, REMOTE_ESTOP, ["drive", "lights"]),
        (OPERATIONAL, 0, []),
    ],
)
def test_in_run_the_reflex_is_the_full_steps_first_switching(
    mode: int, estop: int, off: list[str]
) -> None:
    """SR-9.5, SR-1.4: in RUN a mode that leaves Operational switches the motion output off, an
    e-stop word every output but the category-1 ones, an Operational heartbeat nothing; the
    reflex says so before the step, and the full step does exactly that."""
    rig = Rig(CATEGORY_1)
    rig.bring_up()
    rig.advance(20)
    assert _early_and_full(rig, mode, estop) == (off, off)


@pytest.mark.parametrize(
    ("after_ms", "off"),
    [
        (BRAKES_MS - 1, ["lights"]),
        (BRAKES_MS, ["brakes", "lights"]),
        (FANS_MS - 1, ["brakes", "lights"]),
        (FANS_MS, ["brakes", "fans", "lights"]),
    ],
)
def test_in_hold_a_stop_keeps_a_category_1_output_on_through_its_delay(
    after_ms: int, off: list[str]
) -> None:
    """SR-9.5, SR-1.4: in HOLD, an e-stop word switches off at once each power output whose
    delay since RUN was left has passed (a nanosecond before it, not yet), as the full step
    does, no more and no fewer."""
    rig = Rig(CATEGORY_1)
    rig.bring_up()
    rig.advance(20)
    assert rig.vsc(PAUSE).state is State.HOLD
    for _ in range(after_ms // 40):  # the link and the client kept alive meanwhile
        rig.advance(40)
        rig.vsc(PAUSE)
        rig.beat()
    rig.advance(after_ms - 40 * (after_ms // 40))
    assert _early_and_full(rig, PAUSE, REMOTE_ESTOP) == (off, off)


def test_in_stopped_the_reflex_switches_nothing_off() -> None:
    """SR-9.5: STOPPED has no reflex: every output is off, or a category-1 output goes off with
    time, never with a heartbeat; asking for it changes nothing the core keeps."""
    rig = Rig(CATEGORY_1)
    rig.bring_up()
    rig.advance(20)
    rig.vsc(OPERATIONAL, REMOTE_ESTOP)
    before = rig.core.canonical()
    assert rig.core.reflex(rig.now) is NOTHING
    assert rig.core.canonical() == before


def test_the_reflex_holds_when_the_user_heartbeat_alone_is_due() -> None:
    """SR-9.5: a stopping heartbeat read just as the user heartbeat falls due (the VSC's
    heartbeats and the user heartbeat keep one cadence, so a stop often comes then) still has
    its outputs switched off by the reflex, exactly as the full step does; the beat's deadline
    is not a time at which anything else moves."""
    rig = Rig(CATEGORY_1)
    rig.bring_up()
    rig.advance(20)
    rig.vsc(OPERATIONAL, 0)
    rig.now = rig.last.next_deadline  # the user heartbeat's, nothing else due (RUN, in time)
    assert _early_and_full(rig, OPERATIONAL, REMOTE_ESTOP) == (["drive", "lights"],) * 2
    assert any(type(frame).__name__ == "UserHeartbeat" for frame in rig.last.frames)


def test_the_reflex_steps_aside_when_a_timeout_is_due() -> None:
    """SR-9.5, SR-2.2: at a time when the VSC's timeout has expired too, the core gives no
    reflex (``None``): time decides as well, and the full step alone switches the outputs."""
    rig = Rig(CATEGORY_1)
    rig.bring_up()
    rig.advance(20)
    rig.vsc(OPERATIONAL, 0)
    rig.advance(10_000)  # far past the VSC's timeout, no heartbeat meanwhile
    assert rig.core.reflex(rig.now) is None


def test_the_reflex_steps_aside_at_the_nanosecond_the_vscs_timeout_falls_due() -> None:
    """SR-9.5, SR-2.2: at the very nanosecond the VSC's 200 ms timeout falls due, the core's
    next deadline, the core gives no reflex (``None``): the timeout decides too, and the full
    step alone switches the outputs."""
    rig = Rig(CATEGORY_1)
    rig.bring_up()
    rig.advance(20)
    rig.vsc(OPERATIONAL, 0)
    timeout = rig.now + 200 * MS  # the VSC's last heartbeat, none after it
    while rig.last.next_deadline < timeout:  # the user heartbeat's ticks meanwhile
        rig.now = rig.last.next_deadline
        rig.tick()
    assert rig.last.next_deadline == timeout
    rig.now = timeout
    assert rig.core.reflex(rig.now) is None


def test_the_reflex_steps_aside_at_the_user_heartbeat_while_a_proof_test_runs() -> None:
    """SR-9.5, SR-5.3: at the user heartbeat's deadline while the proof test waits for the
    VSC's bits to clear (RESUMED: time moves it between its deadlines, none of which has
    come), the core gives no reflex (``None``): the full step alone decides at such a time."""
    vsc = Vsc()
    for _ in range(300):  # 3 s of VSC heartbeats, 10 ms apart: the withholding, the trip
        vsc.beat(10)
        if vsc.core._proof.phase is Phase.RESUMED:
            break
    assert vsc.core._proof.phase is Phase.RESUMED
    now = vsc.proof.next_deadline
    assert not vsc.core._proof.due_by(vsc.core._view.at(now))  # the beat's deadline alone
    assert vsc.core.reflex(now) is None

"""Step 2 for a message of the VSC: what each kind of message tells the machines.

One of the parts :class:`~supervisord.safety.core.SafetyCore` composes: its handler of
``VscReceived`` hands :func:`take_vsc_message` the message with the machines it tells (the
link, the proof test, the remote's display and battery) and takes back the takeover it asks
for, if any, for step 4 to check (SR-4). A message on a link that is not open is refused: the
link's facts are those of an open link only (SR-2.3).
"""

from __future__ import annotations

from supervisord.protocol.codes import FeedbackKey
from supervisord.protocol.messages import FeedbackSet, RemoteStatus, VscHeartbeat
from supervisord.safety.battery import RemoteBattery
from supervisord.safety.decision import RearmKind, RefusalReason
from supervisord.safety.display import DisplayStore
from supervisord.safety.events import VscReceived
from supervisord.safety.prooftest import ProofTest
from supervisord.safety.rearm import RearmRequest
from supervisord.safety.step import Step
from supervisord.safety.vsc import VscLink


def take_vsc_message(
    event: VscReceived,
    step: Step,
    *,
    vsc: VscLink,
    proof: ProofTest,
    display: DisplayStore,
    battery: RemoteBattery,
) -> RearmRequest | None:
    """Apply the VSC's message of ``event`` at ``step.now``: a heartbeat to the link and the
    proof test (a takeover it completes is returned), a remote status to the battery when it
    is watched (SR-8.12), key 85's answer to the link (SR-5.3), any other value to the
    display."""
    message = event.message
    if not vsc.open:
        step.refuse(RefusalReason.LINK_NOT_OPEN, type(message).__name__, event)
        return None
    if isinstance(message, VscHeartbeat):
        return take_vsc_heartbeat(message, step.now, vsc, proof, display)
    if isinstance(message, RemoteStatus):
        if battery.cause is not None:
            battery.report(message.battery_level, step.now)
            step.taken_in = True
    elif isinstance(message, FeedbackSet):
        if message.key == FeedbackKey.USER_ESTOP_TIMEOUT:
            vsc.key85_read(message.value)
        else:
            display.edited_on_remote(message)
    return None


def take_vsc_heartbeat(
    message: VscHeartbeat, now: int, vsc: VscLink, proof: ProofTest, display: DisplayStore
) -> RearmRequest | None:
    """Apply a VSC heartbeat at ``now`` on an open link: to the link and the proof test (a
    takeover it completes is returned). The one handler of a heartbeat: the full step's
    (:func:`take_vsc_message`) and the cheap path's (SR-2.2, SR-5.3, SR-9.4); positional
    and without the step, which a heartbeat neither refuses nor notes in."""
    heard = vsc.heartbeat(message, now)
    if heard.silent_before:
        # The VSC was silent: it may have rebooted (a firmware update can reset key
        # 85), so its watchdog is proven again (docs/safety.md "The proof test").
        proof.restart()
    proof.heartbeat(message.mode, message.estop, now)
    if heard.relinked:
        display.relink()
    if heard.takeover:
        return RearmRequest(RearmKind.TAKEOVER, None, heard.run)
    return None

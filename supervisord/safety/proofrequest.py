"""``srcsctl prooftest``: a proof test asked for on demand, begun or refused (SR-5.3).

One of the parts :class:`~supervisord.safety.core.SafetyCore` composes: step 2 hands
:func:`request_prooftest` the request with the proof test (:mod:`~supervisord.safety.prooftest`)
and the core's state, and takes back its refusal as a value, as the other machines' handlers
give theirs (docs/safety.md "The proof test"). A function of its own, not a method of
:class:`~supervisord.safety.prooftest.ProofTest`: the decision's module imports the proof
test's (for its outcome and status), so the proof test cannot import the refusal.
"""

from __future__ import annotations

from supervisord.safety.config import Transport
from supervisord.safety.decision import Refusal, RefusalReason
from supervisord.safety.events import ProofTestRequest
from supervisord.safety.prooftest import ProofTest, ProofTestPolicy
from supervisord.safety.transitions import State


def request_prooftest(
    event: ProofTestRequest, proof: ProofTest, state: State, transport: Transport
) -> Refusal | None:
    """Begin a new proof test (``proof.restart``), or the refusal: admins only, only while
    STOPPED, one at a time, and none under the policy ``off`` (the refusal names the
    transport: CAN and HID have no user heartbeat to withhold)."""
    if proof.policy is ProofTestPolicy.OFF:
        return Refusal(RefusalReason.PROOFTEST_NOT_POSSIBLE, transport.value, event)
    if not event.caller.admin:
        return Refusal(RefusalReason.NOT_ADMIN, event.caller.name[:60], event)
    if state is not State.STOPPED:
        return Refusal(RefusalReason.PROOFTEST_NOT_STOPPED, state.name, event)
    if proof.running:
        return Refusal(RefusalReason.PROOFTEST_RUNNING, proof.phase.value, event)
    proof.restart()
    return None

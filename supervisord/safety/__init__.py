"""The safety core: a pure state machine deciding STOPPED, HOLD or RUN (``docs/safety.md``).

No module of this package opens a file or port, reads a clock, sleeps or starts a thread
(``tests/safety/test_purity.py`` proves it); the one exception is the documentation tool
:mod:`supervisord.safety.diagram`, which only its command line runs and nothing imports.
"""

from __future__ import annotations

from supervisord.safety.causes import Cause, CauseKind, CauseState, Details, Severity
from supervisord.safety.config import (
    ClientSpec,
    OutputRole,
    OutputSpec,
    SafetyConfig,
    Transport,
)
from supervisord.safety.core import SafetyCore
from supervisord.safety.decision import (
    CauseChange,
    ChangeKind,
    Decision,
    Rearm,
    RearmKind,
    Record,
    RecordNote,
    Refusal,
    RefusalReason,
)
from supervisord.safety.events import (
    Caller,
    ClientCommand,
    ClientConnected,
    ClientDisconnected,
    ClientEstop,
    ClientHeartbeat,
    ClientHello,
    ClientHold,
    ClientRelease,
    Commissioned,
    DisplayUpdate,
    Event,
    InternalFault,
    LinkBroken,
    LinkClosed,
    LinkOpened,
    LocalEstop,
    LocalRelease,
    OutputReadback,
    Request,
    ResetRequest,
    Shutdown,
    Tick,
    VscReceived,
)
from supervisord.safety.transitions import TABLE, IllegalTransition, Situation, State, Transition

__all__ = [
    "TABLE",
    "Caller",
    "Cause",
    "CauseChange",
    "CauseKind",
    "CauseState",
    "ChangeKind",
    "ClientCommand",
    "ClientConnected",
    "ClientDisconnected",
    "ClientEstop",
    "ClientHeartbeat",
    "ClientHello",
    "ClientHold",
    "ClientRelease",
    "ClientSpec",
    "Commissioned",
    "Decision",
    "Details",
    "DisplayUpdate",
    "Event",
    "IllegalTransition",
    "InternalFault",
    "LinkBroken",
    "LinkClosed",
    "LinkOpened",
    "LocalEstop",
    "LocalRelease",
    "OutputReadback",
    "OutputRole",
    "OutputSpec",
    "Rearm",
    "RearmKind",
    "Record",
    "RecordNote",
    "Refusal",
    "RefusalReason",
    "Request",
    "ResetRequest",
    "SafetyConfig",
    "SafetyCore",
    "Severity",
    "Shutdown",
    "Situation",
    "State",
    "Tick",
    "Transition",
    "Transport",
    "VscReceived",
]

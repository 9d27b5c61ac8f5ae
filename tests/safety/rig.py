"""A test rig for the safety core: a fake monotonic clock that only moves forward on request,
and short names for the inputs a daemon would feed. Nothing here sleeps."""

from __future__ import annotations

from supervisord.protocol.codes import VscMode
from supervisord.protocol.messages import FeedbackSet, Message, UserHeartbeat, VscHeartbeat
from supervisord.safety import (
    Caller,
    ClientCommand,
    ClientConnected,
    ClientDisconnected,
    ClientEstop,
    ClientHeartbeat,
    ClientHello,
    ClientHold,
    ClientRelease,
    ClientSpec,
    Decision,
    Event,
    LinkOpened,
    OutputRole,
    OutputSpec,
    Request,
    ResetRequest,
    SafetyConfig,
    SafetyCore,
    State,
    Tick,
    VscReceived,
)
from supervisord.safety.step import Step

MS = 1_000_000
START_NS = 5_000 * MS  # an arbitrary monotonic origin, far from zero
LOCAL = VscMode.LOCAL.value
OPERATIONAL = VscMode.OPERATIONAL.value
PAUSE = VscMode.PAUSE.value
SEARCHING = VscMode.SEARCHING.value
ADMIN = Caller(uid=1000, pid=42, name="alice", admin=True)
NOBODY = Caller(uid=1001, pid=43, name="bob", admin=False)

MACHINES = ("vsc", "clients", "budget", "outputs", "battery", "display", "proof")
"""The core's machines, by the names its view of them gives them (``face.View``)."""


def composed_of_its_own(core: SafetyCore) -> bool:
    """Whether the core's view of its machines (``face.View``) holds the core's own machines,
    each once, by name and in the tuple it iterates (SR-9.4)."""
    view = core._view
    own = tuple(getattr(core, f"_{name}") for name in MACHINES)
    named = tuple(getattr(view, name) for name in MACHINES)
    return all(a is b for a, b in zip(named + view.machines, own + own, strict=True))


ROBOT = SafetyConfig(
    clients=(ClientSpec("planner"),),
    outputs=(OutputSpec("drive", OutputRole.MOTION), OutputSpec("lights", OutputRole.POWER)),
)
"""A serial robot with one required client, a motion output and a power output."""


class Rig:
    """A core, its fake clock and every decision so far."""

    def __init__(self, config: SafetyConfig = ROBOT) -> None:
        self.now = START_NS
        self.core = SafetyCore(config, self.now)
        self.decisions: list[Decision] = [self.core.decision]

    @property
    def last(self) -> Decision:
        return self.decisions[-1]

    @property
    def state(self) -> State:
        return self.last.state

    def advance(self, ms: float) -> Rig:
        """Move the fake clock forward (never back) by ``ms`` milliseconds."""
        step = round(ms * MS)
        assert step >= 0
        self.now += step
        return self

    def feed(self, event: Event) -> Decision:
        decision = self.core.handle(event)
        self.decisions.append(decision)
        assert decision.next_deadline > decision.now
        return decision

    def tick(self) -> Decision:
        return self.feed(Tick(self.now))

    def vsc(self, mode: int = OPERATIONAL, estop: int = 0) -> Decision:
        return self.feed(VscReceived(self.now, VscHeartbeat(mode, 0, estop)))

    def from_vsc(self, message: Message) -> Decision:
        return self.feed(VscReceived(self.now, message))

    def open_link(self) -> Decision:
        return self.feed(LinkOpened(self.now))

    def key85(self, value: int = 1) -> Decision:
        return self.from_vsc(FeedbackSet(85, value))

    def connect(
        self, connection: int = 1, name: str | None = "planner", uid: int | None = None
    ) -> Decision:
        decision = self.feed(ClientConnected(self.now, connection, uid))
        if name is not None:
            decision = self.feed(ClientHello(self.now, connection, name))
        return decision

    def beat(self, connection: int = 1) -> Decision:
        return self.feed(ClientHeartbeat(self.now, connection))

    def command(self, nonzero: bool = False, connection: int = 1) -> Decision:
        """The client's declaration of its commanded motion (SR-4.6): zero changes nothing in
        RUN, and still takes the full step (a client's heartbeat in time is cheap)."""
        return self.feed(ClientCommand(self.now, connection, nonzero))

    def estop(self, connection: int = 1) -> Decision:
        return self.feed(ClientEstop(self.now, connection))

    def hold(self, connection: int = 1) -> Decision:
        return self.feed(ClientHold(self.now, connection))

    def release(self, connection: int = 1, request: Request = Request.ESTOP) -> Decision:
        return self.feed(ClientRelease(self.now, connection, request))

    def disconnect(self, connection: int = 1) -> Decision:
        return self.feed(ClientDisconnected(self.now, connection))

    def reset(self, caller: Caller = ADMIN) -> Decision:
        return self.feed(ResetRequest(self.now, caller))

    def run_for(
        self, ms: int, mode: int = LOCAL, clients: tuple[int, ...] = (1,), step_ms: int = 50
    ) -> Decision:
        """Let ``ms`` pass with a healthy VSC in ``mode`` and the clients beating, every step."""
        for _ in range(ms // step_ms):
            self.advance(step_ms)
            self.vsc(mode)
            for connection in clients:
                self.beat(connection)
        return self.last

    def take_over(self, local_ms: int, clients: tuple[int, ...] = (1,)) -> Decision:
        """The remote's takeover: ``local_ms`` in Local with the clients beating, then
        Operational 50 ms later (SR-4.2)."""
        self.run_for(local_ms, LOCAL, clients)
        self.advance(50)
        return self.vsc(OPERATIONAL)

    def bring_up(self) -> Decision:
        """From startup to RUN the normal way: link, key 85, client, clear hold, takeover."""
        self.open_link()
        self.key85(1)
        self.connect()
        decision = self.take_over(600)
        assert decision.state is State.RUN, decision.causes
        return decision

    def stopped_and_cleared(self) -> Decision:
        """RUN, then the client's e-stop and its release: STOPPED, every condition clear."""
        self.bring_up()
        self.advance(10)
        self.estop()
        self.advance(10)
        return self.release()

    def count_refreshes(self) -> list[int]:
        """A spy on the full path's recomputation: the times it runs from now on (it still
        runs for real)."""
        refreshes: list[int] = []
        real = SafetyCore._refresh

        def counting(core: SafetyCore, step: Step) -> None:
            refreshes.append(step.now)
            real(core, step)

        self.core._refresh = counting.__get__(self.core)  # type: ignore[method-assign]
        return refreshes

    def frames(self) -> list[Message]:
        """Every frame the core asked to send so far."""
        return [f for d in self.decisions for f in d.frames]

    def heartbeats(self) -> list[UserHeartbeat]:
        return [f for f in self.frames() if isinstance(f, UserHeartbeat)]

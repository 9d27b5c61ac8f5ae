"""Fault injection on the VSC's outgoing stream, pure and seeded.

A ``FaultPlan`` says what goes wrong and how often; a ``FaultInjector`` applies it with its
own ``random.Random(seed)``, so a seed replays the same faults for the same input. Time is
passed in (monotonic seconds); nothing here reads a clock or does I/O. The simulator uses
it, and tests can use it directly on frames they build.

Three stages, in the order the simulator applies them:

0. ``watchdog``: faults of the VSC's key-85 watchdog, applied by the model (``VscModel.
   watchdog``): one that ignores the missing user heartbeat, one that trips late
   (``watchdog_late_s``), one that never clears its user-timeout bit, even after a takeover;
   and ``held``, no fault but the other reading of the manual: a bit held until the
   operator's takeover (docs/safety.md "The proof test").
1. ``message``: faults of the VSC's logic, on messages before encoding: a frozen heartbeat
   (the same content forever, whatever the VSC's state), mode flapping (the heartbeat's
   mode alternates with ``flap_mode``; with ``flap_heartbeats`` every change of the flapping
   mode also sends a heartbeat of its own, ``flap_due``, as a VSC whose mode logic chatters
   faster than its heartbeat schedule).
2. ``push`` / ``push_can`` then ``due``: faults of the line, per frame: drop, delay,
   duplicate, reorder, corrupt, wrong length, and inserted garbage or unknown-type frames.
3. ``Pacer``: slow and partial writes: the serial bytes go out in chunks of
   ``chunk_bytes`` with ``chunk_gap_s`` between them (frames split across writes).

Serial corruption XORs a non-zero value into one byte after the length byte, so the
Fletcher-16 checksum always catches it (every single-byte error changes sum1): the receiver
must reject it as ``bad_checksum``. ``corrupt_bytes`` > 1 hits several bytes; that can pass
the checksum about once in 65,536 (``docs/protocol.md``). A CAN controller drops a frame
whose CRC fails and signals an error frame: on CAN, corruption sends a ``CanErrorFrame``
instead of the frame.
"""

from __future__ import annotations

import heapq
import math
import random
from dataclasses import asdict, dataclass, fields, replace
from typing import Any

from supervisord.protocol.codes import MessageType
from supervisord.protocol.framing import HEADER_SIZE, build_frame
from supervisord.protocol.j1939 import CanFrame
from supervisord.protocol.messages import Message, VscHeartbeat

# Types seen from the VSC but outside the manual (PR-2.13): the decoder
# must count and skip them.
UNKNOWN_TYPES = (0x25, 0x26, 0x33, 0x40, 0x50, 0x90, 0xA5, 0xB1, 0xD3, 0xF7)
UNKNOWN_CAN_ID = 0x0CFDFF42  # priority 3, a PGN the SRCS does not use
WATCHDOG_BEHAVIOURS = ("healthy", "ignores", "late", "held", "never_clears")
"""How the simulated VSC's key-85 watchdog behaves (``VscModel.watchdog``)."""


@dataclass(frozen=True, slots=True)
class CanErrorFrame:
    """What a CAN receiver sees instead of a frame whose CRC failed: a SocketCAN error frame
    whose identifier holds its classes (linux/can/error.h: 0x08 protocol violation, the
    default; 0x40 bus-off). The daemon's policy tells them apart (docs/safety.md "CAN error
    frames")."""

    classes: int = 0x08


Item = bytes | CanFrame | CanErrorFrame

_PROBABILITIES = (
    "drop",
    "delay",
    "duplicate",
    "reorder",
    "corrupt",
    "garbage",
    "wrong_length",
    "unknown_type",
)


@dataclass(frozen=True, slots=True)
class FaultPlan:
    """What goes wrong. Probabilities are per outgoing frame, 0..1; 0 everywhere (the
    default) is a healthy VSC. ``only_types`` limits the per-frame faults to those message
    types (serial type bytes; on CAN, 0x20 heartbeat and 0x10 joystick); empty means all."""

    drop: float = 0.0
    delay: float = 0.0  # probability a frame is held back ``delay_s``
    delay_s: float = 0.1
    duplicate: float = 0.0
    reorder: float = 0.0  # probability a frame is sent after the next one
    corrupt: float = 0.0
    corrupt_bytes: int = 1
    garbage: float = 0.0  # probability of a burst of random bytes before a frame
    garbage_max: int = 16
    wrong_length: float = 0.0  # a known type with an impossible length, checksum correct
    unknown_type: float = 0.0  # probability of a valid frame of an unknown type before it
    freeze_heartbeat: bool = False
    flap_mode: int | None = None  # the heartbeat's mode alternates with this one
    flap_period_s: float = 0.1
    flap_heartbeats: bool = False  # a heartbeat at every change of the flapping mode
    chunk_bytes: int = 0  # 0: whole writes
    chunk_gap_s: float = 0.0
    only_types: frozenset[int] = frozenset()
    watchdog: str = "healthy"  # one of WATCHDOG_BEHAVIOURS
    watchdog_late_s: float = 1.0  # with watchdog "late": the trip comes after this

    def __post_init__(self) -> None:
        for name in _PROBABILITIES:
            value = getattr(self, name)
            if not _number(value) or not 0.0 <= value <= 1.0:
                raise ValueError(f"{name} must be a probability 0..1, not {value!r}")
        for name, low, high in (("delay_s", 0.0, 60.0), ("chunk_gap_s", 0.0, 10.0)):
            value = getattr(self, name)
            if not _number(value) or not low <= value <= high:
                raise ValueError(f"{name} must be {low}..{high} seconds, not {value!r}")
        self._check_flapping()
        for name, low, high in (("corrupt_bytes", 1, 8), ("garbage_max", 1, 1024)):
            value = getattr(self, name)
            if not _integer(value) or not low <= value <= high:
                raise ValueError(f"{name} must be an integer {low}..{high}, not {value!r}")
        if not _integer(self.chunk_bytes) or not 0 <= self.chunk_bytes <= 4096:
            raise ValueError("chunk_bytes must be an integer 0..4096")
        if self.watchdog not in WATCHDOG_BEHAVIOURS:
            raise ValueError(f"watchdog must be one of {list(WATCHDOG_BEHAVIOURS)}")
        if not _number(self.watchdog_late_s) or not 0.5 <= self.watchdog_late_s <= 60.0:
            raise ValueError("watchdog_late_s must be 0.5..60 seconds")
        if not isinstance(self.freeze_heartbeat, bool):
            raise ValueError("freeze_heartbeat must be true or false")
        if not all(_integer(kind) and 0 <= kind <= 0xFF for kind in self.only_types):
            raise ValueError("only_types must be message type bytes")

    def _check_flapping(self) -> None:
        if not _number(self.flap_period_s) or not 0.01 <= self.flap_period_s <= 60.0:
            raise ValueError("flap_period_s must be 0.01..60 seconds")
        if self.flap_mode is not None and (
            not _integer(self.flap_mode) or not 0 <= self.flap_mode <= 0xFF
        ):
            raise ValueError("flap_mode must be a mode byte 0..255 or null")
        if not isinstance(self.flap_heartbeats, bool):
            raise ValueError("flap_heartbeats must be true or false")
        if self.flap_heartbeats and self.flap_mode is None:
            raise ValueError("flap_heartbeats needs flap_mode")

    @property
    def active(self) -> bool:
        return self != FaultPlan()

    @classmethod
    def from_json(cls, data: object) -> FaultPlan:
        """A plan from a JSON object of the field names; ``ValueError`` names what is wrong."""
        if not isinstance(data, dict):
            raise ValueError("a fault plan is a JSON object")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ValueError(f"unknown fault field(s) {unknown}; known: {sorted(known)}")
        values = dict(data)
        if "only_types" in values:
            kinds = values["only_types"]
            if not isinstance(kinds, list):
                raise ValueError("only_types must be a list of type bytes")
            values["only_types"] = frozenset(kinds)
        return cls(**values)

    def to_json(self) -> dict[str, Any]:
        """The fields that differ from a healthy VSC."""
        healthy = asdict(FaultPlan())
        out = {k: v for k, v in asdict(self).items() if v != healthy[k]}
        if "only_types" in out:
            out["only_types"] = sorted(self.only_types)
        return out


def _number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _integer(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


class FaultInjector:
    """Applies a ``FaultPlan`` to messages and frames; ``counts`` says what it did."""

    def __init__(self, plan: FaultPlan | None = None, seed: int = 0) -> None:
        self.rng = random.Random(seed)  # noqa: S311 (simulated faults, replayable by seed)
        self.counts: dict[str, int] = {}
        self._queue: list[tuple[float, int, Item]] = []
        self._held: list[Item] = []
        self._held_since = 0.0
        self._seq = 0
        self._frozen: VscHeartbeat | None = None
        self._plan_start = 0.0
        self._flips = 0  # the flaps whose extra heartbeat has been asked for (flap_due)
        self.plan = FaultPlan()
        self.set_plan(plan or FaultPlan(), 0.0)

    def set_plan(self, plan: FaultPlan, now: float) -> None:
        """Switch to ``plan``. Frames already delayed still go out when due."""
        self.plan = plan
        self._plan_start = now
        self._frozen = None
        self._flips = 0

    def _count(self, kind: str) -> None:
        self.counts[kind] = self.counts.get(kind, 0) + 1

    def _roll(self, probability: float) -> bool:
        return probability > 0.0 and self.rng.random() < probability

    # -- stage 1: the VSC's logic --------------------------------------------------------------

    def message(self, message: Message, now: float) -> Message:
        if not isinstance(message, VscHeartbeat):
            return message
        plan = self.plan
        if plan.freeze_heartbeat:
            if self._frozen is None:
                self._frozen = message
            self._count("freeze_heartbeat")
            return self._frozen
        if plan.flap_mode is not None and int((now - self._plan_start) / plan.flap_period_s) % 2:
            self._count("flap_mode")
            return replace(message, mode=plan.flap_mode)
        return message

    def flap_due(self, now: float) -> bool:
        """With ``flap_heartbeats``: whether the flapping mode has changed since the last
        extra heartbeat (the caller then sends one, through ``message``); once per change."""
        plan = self.plan
        if plan.flap_mode is None or not plan.flap_heartbeats:
            return False
        flips = int((now - self._plan_start) / plan.flap_period_s) + 1
        if flips <= self._flips:
            return False
        self._flips = flips
        return True

    def _next_flip(self) -> float | None:
        plan = self.plan
        if plan.flap_mode is None or not plan.flap_heartbeats:
            return None
        return self._plan_start + self._flips * plan.flap_period_s

    # -- stage 2: the line ---------------------------------------------------------------------

    def push(self, frame: bytes, message_type: int, now: float) -> None:
        """One serial frame of ``message_type`` to send at ``now``, faults applied."""
        self._push(frame, message_type, now)

    def push_can(self, frame: CanFrame, message_type: int, now: float) -> None:
        """One CAN frame carrying (part of) a message of serial ``message_type``."""
        self._push(frame, message_type, now)

    def _push(self, item: Item, message_type: int, now: float) -> None:
        plan = self.plan
        if plan.only_types and message_type not in plan.only_types:
            self._schedule(now, item)
            self._release_held(now)
            return
        if self._roll(plan.drop):
            self._count("drop")
            return
        if self._roll(plan.garbage):
            self._count("garbage")
            self._schedule(now, self._garbage(item))
        if self._roll(plan.unknown_type):
            self._count("unknown_type")
            self._schedule(now, self._unknown(item))
        if self._roll(plan.corrupt):
            self._count("corrupt")
            item = self._corrupt(item)
        elif self._roll(plan.wrong_length):
            self._count("wrong_length")
            item = self._wrong_length(item, message_type)
        copies = 1
        if self._roll(plan.duplicate):
            self._count("duplicate")
            copies = 2
        due = now
        if self._roll(plan.delay):
            self._count("delay")
            due = now + plan.delay_s
        if self._roll(plan.reorder):
            self._count("reorder")
            if not self._held:
                self._held_since = now
            self._held += [item] * copies
            return
        for _ in range(copies):
            self._schedule(due, item)
        self._release_held(now)

    def _release_held(self, now: float) -> None:
        """Held frames go out right after the frame that overtook them."""
        for item in self._held:
            self._schedule(now, item)
        self._held = []

    def _schedule(self, due: float, item: Item) -> None:
        self._seq += 1
        heapq.heappush(self._queue, (due, self._seq, item))

    def due(self, now: float) -> list[Item]:
        """What is to be sent by ``now``, in order. A frame held for reordering goes out
        after at most 0.5 s even when no frame overtakes it."""
        if self._held and now - self._held_since >= 0.5:
            self._release_held(now)
        out: list[Item] = []
        while self._queue and self._queue[0][0] <= now:
            out.append(heapq.heappop(self._queue)[2])
        return out

    def next_deadline(self) -> float | None:
        deadlines = [self._queue[0][0]] if self._queue else []
        if self._held:
            deadlines.append(self._held_since + 0.5)
        flip = self._next_flip()
        if flip is not None:
            deadlines.append(flip)
        return min(deadlines, default=None)

    def clear(self) -> None:
        """Forget frames not yet sent (a VSC that reboots or is unplugged)."""
        self._queue.clear()
        self._held.clear()

    # -- frame mutations ----------------------------------------------------------------------

    def _corrupt(self, item: Item) -> Item:
        if not isinstance(item, bytes):
            return CanErrorFrame()
        data = bytearray(item)
        count = min(self.plan.corrupt_bytes, len(data) - HEADER_SIZE)
        for position in self.rng.sample(range(HEADER_SIZE, len(data)), count):
            data[position] ^= self.rng.randint(1, 255)
        return bytes(data)

    def _wrong_length(self, item: Item, message_type: int) -> Item:
        if isinstance(item, CanFrame):
            return CanFrame(item.arbitration_id, item.data[:1])  # fewer bytes than needed
        if not isinstance(item, bytes):
            return item
        payload = item[HEADER_SIZE:-2]
        if message_type == MessageType.GPS:
            return build_frame(message_type, b"")  # GPS needs at least its source byte
        return build_frame(message_type, payload + bytes((self.rng.randint(0, 255),)))

    def _garbage(self, item: Item) -> Item:
        size = self.rng.randint(1, self.plan.garbage_max)
        if isinstance(item, bytes):
            return self.rng.randbytes(size)
        return CanFrame(self.rng.randint(0, 0x1FFF_FFFF), self.rng.randbytes(min(size, 8)))

    def _unknown(self, item: Item) -> Item:
        if isinstance(item, bytes):
            payload = self.rng.randbytes(self.rng.randint(0, 8))
            return build_frame(self.rng.choice(UNKNOWN_TYPES), payload)
        return CanFrame(UNKNOWN_CAN_ID, self.rng.randbytes(8))


class Pacer:
    """Slow and partial writes: bytes leave in chunks of ``chunk_bytes`` (0 = all at once),
    one chunk per ``gap_s``."""

    def __init__(self, chunk_bytes: int = 0, gap_s: float = 0.0) -> None:
        self.chunk_bytes, self.gap_s = chunk_bytes, gap_s
        self._pending = bytearray()
        self._next = 0.0

    def configure(self, chunk_bytes: int, gap_s: float) -> None:
        self.chunk_bytes, self.gap_s = chunk_bytes, gap_s

    def push(self, data: bytes) -> None:
        self._pending += data

    @property
    def pending(self) -> int:
        return len(self._pending)

    def pop(self, now: float) -> bytes:
        """The bytes to write at ``now`` (empty if the next chunk is not due)."""
        if not self._pending or now < self._next:
            return b""
        size = self.chunk_bytes or len(self._pending)
        chunk = bytes(self._pending[:size])
        del self._pending[:size]
        if self.chunk_bytes:
            self._next = now + self.gap_s
        return chunk

    def next_deadline(self) -> float | None:
        return self._next if self._pending else None

    def clear(self) -> None:
        self._pending.clear()

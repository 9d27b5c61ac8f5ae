"""The simulated VSC and its remote as a pure state machine (manual §6, §8.3, PR-2).

No I/O and no clock: every method that depends on time takes ``now``, monotonic seconds.
The host's messages go in through ``handle``; ``tick`` returns what the VSC sends at
``now``; the remote's buttons are methods (``press_estop``, ``takeover``, ...). What the VSC
keeps in EEPROM (message control, the permanent keys) is the ``eeprom`` value: the I/O edge
saves it when ``eeprom_version`` changes.

Where the manual is silent the choices are written down here and in ``docs/simulator.md``:

- E-stop word bits (PR-2 only name the pairs): 0x01 the remote's e-stop button, 0x02 no
  remote link (remote off, out of range, or the VSC still searching), 0x04 the wired input,
  0x40 the host's heartbeat asked for an e-stop, 0x80 the key-85 watchdog timed out.
- A switched-off remote is reported as Searching with 0x02 (``remote_off_reports="searching"``,
  the default) or, as some hardware reports it, as Local (Remote on newer firmware) with the
  remote's e-stop bit 0x01 (``"local"``); both are a stop (PR-2.6). A remote that is on and
  still linking is Searching with 0x02 either way.
- The key-85 watchdog trips when the last user heartbeat is 500 ms old or older (age >= 0.5 s,
  inclusive). Its age is counted from the VSC's boot when no heartbeat has arrived since.
  On CAN there is no user heartbeat (PR-3), so the watchdog never runs there.
- The takeover (manual §2 "protocol enforced remote takeover sequence") is refused while
  any e-stop bit is set, while a stick is deflected, outside Local/Remote/Pause, or in Menu.
- The watchdog's behaviour is ``watchdog`` (set through the fault plan, docs/simulator.md):
  ``healthy`` as above; ``ignores`` never trips; ``late`` trips at ``watchdog_late_s``;
  ``held`` keeps the bit, once it tripped after a user heartbeat, until the operator's
  takeover gesture, which clears it and leaves the remote in Local (a second takeover enters
  Operational); ``never_clears`` keeps it until a reboot, the takeover refused. The manual
  does not say whether the real VSC clears the bit by itself or holds it.
- Newer firmware reports Remote (0x06) wherever older firmware reports Local (0x04).
"""

from __future__ import annotations

import enum
from collections import deque
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace
from typing import Any, Literal

from supervisord.errors import SrcsError
from supervisord.protocol.codes import (
    USER_VALUE_KEYS,
    DisplayMode,
    FieldStatus,
    MessageType,
    VscMode,
)
from supervisord.protocol.hid import DPadDirection, HidInput
from supervisord.protocol.j1939 import SEGMENT_COUNT, FeedbackStringSegment
from supervisord.protocol.messages import (
    AXIS_MAGNITUDE_MAX,
    Axis,
    DPad,
    FeedbackGet,
    FeedbackName,
    FeedbackSet,
    Gps,
    Joystick,
    Message,
    MessageControl,
    NumberedButtons,
    RemoteStatus,
    UserHeartbeat,
    VscHeartbeat,
)
from supervisord.protocol.nmea import parse_nmea

SimTransport = Literal["serial", "can"]
RemoteOffReport = Literal["searching", "local"]
REMOTE_OFF_REPORTS: tuple[RemoteOffReport, ...] = ("searching", "local")

WATCHDOG_S = 0.5  # manual §8.3.5: "after a 500ms timeout"
VIBRATION_S = 0.75  # manual table 13: keys 10-12 drive a motor for 750 ms
LINK_DELAY_S = 0.3  # the radio link forming after power-on: a sim choice, short for tests
AUTO_OFF_S = 120.0  # manual §6.4: power off 2 minutes after an inactivity pause
MIN_INTERVAL_MS = 20  # manual §8.3.6: 20 -> UINT16_MAX
VALUE_RATE_LIMIT = 20  # manual table 5: feedback values at most 20 Hz
STRING_RATE_LIMIT = 4  # manual table 5: name strings at most 4 Hz
LCD_WIDTH = 20  # manual §6.5: four 20-character lines


class EstopBit(enum.IntFlag):
    """The bits this simulator sets in the heartbeat's e-stop word (see the module doc)."""

    REMOTE_BUTTON = 0x01
    REMOTE_LINK = 0x02
    WIRED = 0x04
    USER_REQUEST = 0x40
    USER_TIMEOUT = 0x80


class SimRefused(SrcsError):
    """A remote action the real remote would not do in the current state (e.g. a takeover
    during an e-stop). Nothing changed."""


@dataclass(frozen=True, slots=True)
class Schedule:
    """One row of the message-control table (manual §8.3.6)."""

    enabled: bool
    interval_ms: int


# Manual table 5 (serial) and table 23 (CAN: heartbeat 10 Hz, joystick ~16 Hz).
SERIAL_SCHEDULE: dict[int, Schedule] = {
    MessageType.JOYSTICK: Schedule(True, 20),
    MessageType.GPS: Schedule(True, 1000),
    MessageType.VSC_HEARTBEAT: Schedule(True, 50),
    MessageType.REMOTE_STATUS: Schedule(False, 1000),
}
CAN_SCHEDULE: dict[int, Schedule] = {
    MessageType.JOYSTICK: Schedule(True, 62),
    MessageType.VSC_HEARTBEAT: Schedule(True, 100),
    MessageType.REMOTE_STATUS: Schedule(False, 1000),
}
# Heartbeat first: a receiver that sees both in one read learns the mode before the sticks.
EMIT_ORDER = (
    MessageType.VSC_HEARTBEAT,
    MessageType.JOYSTICK,
    MessageType.GPS,
    MessageType.REMOTE_STATUS,
)

# Settings the VSC or remote keep across power cycles (manual table 13; 85 "is persistent").
KEY_DEFAULTS: dict[int, int] = {80: 4, 81: 1, 82: 1, 83: 1, 84: 1, 85: 0}
KEY_RANGES: dict[int, tuple[int, int]] = {80: (0, 10), 81: (0, 1), 82: (0, 1), 83: (0, 1)}
KEY_RANGES |= {84: (0, 1), 85: (0, 1)}
VIBRATION_KEYS = {10: "left", 11: "right", 12: "both"}
DISPLAY_KEY = 99
TEXT_ROW_KEYS = (90, 91, 92, 93)
PAUSE_REASONS = {"button": None, "orientation": 82, "free_fall": 83, "inactivity": 84}
BUTTON_NAMES = ("down", "right", "up", "left", "button_1", "button_2", "button_3", "button_4")
START_UTC_S = 12 * 3600  # the generated GPS clock starts at 12:00:00 UTC
DEFAULT_POSITION = (48.1173, 11.5167)
HID_AXIS_MAX = 127  # manual table 38: an axis is -127..127 in the HID report
# The D-pad's direction (manual table 38) by (right minus left, down minus up).
HID_DPAD: dict[tuple[int, int], int] = {
    (0, -1): DPadDirection.UP,
    (1, -1): DPadDirection.UP_RIGHT,
    (1, 0): DPadDirection.RIGHT,
    (1, 1): DPadDirection.DOWN_RIGHT,
    (0, 1): DPadDirection.DOWN,
    (-1, 1): DPadDirection.DOWN_LEFT,
    (-1, 0): DPadDirection.LEFT,
    (-1, -1): DPadDirection.UP_LEFT,
    (0, 0): DPadDirection.NONE,
}


@dataclass(frozen=True, slots=True)
class Eeprom:
    """What the VSC keeps in EEPROM: the message-control table and the permanent keys."""

    message_control: dict[int, Schedule]
    keys: dict[int, int]

    @classmethod
    def defaults(cls, transport: SimTransport) -> Eeprom:
        table = SERIAL_SCHEDULE if transport == "serial" else CAN_SCHEDULE
        return cls(dict(table), dict(KEY_DEFAULTS))

    def to_json(self) -> dict[str, Any]:
        return {
            "message_control": {
                str(kind): {"enabled": row.enabled, "interval_ms": row.interval_ms}
                for kind, row in sorted(self.message_control.items())
            },
            "keys": {str(key): value for key, value in sorted(self.keys.items())},
        }

    @classmethod
    def from_json(cls, data: object, transport: SimTransport) -> Eeprom:
        """Read what ``to_json`` wrote; raise ``ValueError`` naming the bad field. Rows and
        keys missing from ``data`` keep their factory defaults."""
        if not isinstance(data, dict):
            raise ValueError("EEPROM file must hold a JSON object")
        base = cls.defaults(transport)
        table, keys = dict(base.message_control), dict(base.keys)
        for kind_text, row in dict(data.get("message_control", {})).items():
            kind = _int_field(f"message_control key {kind_text!r}", kind_text)
            if kind not in table:
                raise ValueError(f"message_control: type {kind:#04x} has no schedule")
            if not isinstance(row, dict) or not isinstance(row.get("enabled"), bool):
                raise ValueError(f"message_control {kind:#04x}: needs enabled true/false")
            interval = row.get("interval_ms")
            if not isinstance(interval, int) or not MIN_INTERVAL_MS <= interval <= 0xFFFF:
                raise ValueError(f"message_control {kind:#04x}: interval_ms must be 20..65535")
            table[kind] = Schedule(row["enabled"], interval)
        for key_text, value in dict(data.get("keys", {})).items():
            key = _int_field(f"keys key {key_text!r}", key_text)
            if key not in KEY_RANGES:
                raise ValueError(f"keys: {key} is not a permanent key (80-85)")
            low, high = KEY_RANGES[key]
            if not isinstance(value, int) or isinstance(value, bool) or not low <= value <= high:
                raise ValueError(f"keys: key {key} must be {low}..{high}, not {value!r}")
            keys[key] = value
        return cls(table, keys)


def _int_field(name: str, text: object) -> int:
    try:
        return int(str(text), 0)
    except ValueError:
        raise ValueError(f"{name} is not a number") from None


def gga_sentence(seconds: float, latitude: float, longitude: float) -> str:
    """A GGA sentence (fix quality 1, 8 satellites) at ``seconds`` after 12:00:00 UTC."""
    day = (START_UTC_S + seconds) % 86400
    hours, rest = divmod(day, 3600)
    minutes, secs = divmod(rest, 60)

    def angle(value: float, width: int, hemispheres: str) -> str:
        degrees = int(abs(value))
        return f"{degrees:0{width}d}{(abs(value) - degrees) * 60:07.4f},{hemispheres[value < 0]}"

    body = (
        f"GPGGA,{int(hours):02d}{int(minutes):02d}{secs:05.2f},"
        f"{angle(latitude, 2, 'NS')},{angle(longitude, 3, 'EW')},1,08,0.9,545.4,M,46.9,M,,"
    )
    checksum = 0
    for ch in body:
        checksum ^= ord(ch)
    return f"${body}*{checksum:02X}"


class VscModel:
    """The VSC with its remote. ``now`` is monotonic seconds throughout."""

    def __init__(
        self,
        now: float,
        *,
        transport: SimTransport = "serial",
        eeprom: Eeprom | None = None,
        newer_firmware: bool = False,
        link_delay: float = LINK_DELAY_S,
        remote_on: bool = True,
        remote_off_reports: RemoteOffReport = "searching",
    ) -> None:
        if remote_off_reports not in REMOTE_OFF_REPORTS:
            raise ValueError(f"remote_off_reports must be one of {REMOTE_OFF_REPORTS}")
        self.transport: SimTransport = transport
        self.remote_off_reports = remote_off_reports
        self.eeprom = eeprom or Eeprom.defaults(transport)
        self.eeprom_version = 0  # bumped on every change the edge must save
        self.idle_mode = VscMode.REMOTE if newer_firmware else VscMode.LOCAL
        self.link_delay = link_delay
        # The remote's own state survives a VSC reboot.
        self.remote_on = remote_on
        self.remote_estop = False
        self.wired_estop = False
        self.axes: dict[str, int] = dict.fromkeys(Joystick.AXES, 0)
        self.buttons: frozenset[str] = frozenset()
        self.remote_status = RemoteStatus(80, 0, 2, 2)
        self.gps_override: str | None = None
        self.position = DEFAULT_POSITION
        self.autonomy = 0
        # Counters for the control API.
        self.host_frames = 0
        self.host_rejections = 0
        self.ignored_messages = 0
        self.rate_violations = 0
        self.vibration_count = 0
        self.reboots = 0
        self.watchdog = "healthy"  # faults.WATCHDOG_BEHAVIOURS
        self.watchdog_late_s = 1.0
        self._created = now
        self._value_times: deque[float] = deque()
        self._string_times: deque[float] = deque()
        self._boot(now, until=now)

    # -- power-on ----------------------------------------------------------------------------

    def _boot(self, start: float, *, until: float) -> None:
        """The VSC's state right after power-on (manual §6.1: Searching until it links)."""
        self._boot_until = until
        self._link_at: float | None = start + self.link_delay if self.remote_on else None
        self._linked = False
        self._mode: int = self.idle_mode
        self._forced_mode: int | None = None
        self._menu_return: int = self.idle_mode
        self._pause_reason = ""
        self._estop = int(EstopBit.REMOTE_LINK)
        self._last_user_heartbeat = start  # the watchdog counts from boot until one arrives
        self._user_heartbeat_seen = False
        self._timeout_held = False  # watchdog "held" or "never_clears": the bit is kept
        self._user_request = 0
        self._due = dict.fromkeys(self.eeprom.message_control, start)
        self._outbox: list[Message] = []
        self.values: dict[int, int] = {}
        self.display_mode = DisplayMode.GPS.value
        self.labels: dict[int, str] = {}
        self._segments: dict[int, list[str | None]] = {}
        self._vibrate_until = start
        self._vibrate_side = ""
        self._last_activity = start
        self._inactivity_paused_at: float | None = None

    def reboot(self, now: float, delay: float) -> None:
        """Restart the VSC: silent and deaf for ``delay`` (its bootloader), then a fresh start
        in Searching, linking to the remote ``link_delay`` later (manual §6.7, PR-5.1)."""
        self.reboots += 1
        self._boot(now + delay, until=now + delay)

    def booting(self, now: float) -> bool:
        return now < self._boot_until

    # -- the host's side ---------------------------------------------------------------------

    def handle(self, message: Message | FeedbackStringSegment, now: float) -> None:
        """A valid message from the host. Replies (Feedback Get answers) come out of the next
        ``tick``. A booting VSC hears nothing."""
        if self.booting(now):
            return
        self._update(now)
        self.host_frames += 1
        match message:
            case UserHeartbeat(estop=estop) if self.transport == "serial":
                self._last_user_heartbeat = now
                self._user_heartbeat_seen = True
                self._user_request = estop
            case MessageControl() if self.transport == "serial":
                self._message_control(message, now)
            case FeedbackSet(key=key, value=value):
                self._count_rate(self._value_times, VALUE_RATE_LIMIT, now)
                if not self.set_key(key, value, now):
                    self.ignored_messages += 1
            case FeedbackName(key=key, text=text):
                self._count_rate(self._string_times, STRING_RATE_LIMIT, now)
                self._set_label(key, text)
            case FeedbackStringSegment(key=key, segment=segment, text=text):
                self._count_rate(self._string_times, STRING_RATE_LIMIT * SEGMENT_COUNT, now)
                parts = self._segments.setdefault(key, [None] * SEGMENT_COUNT)
                parts[segment] = text
                if segment == SEGMENT_COUNT - 1:  # manual §9.2.7: joined once the third arrives
                    self._set_label(key, "".join(part or "" for part in parts))
                    del self._segments[key]
            case FeedbackGet(key=key):
                answer = self.key_value(key)
                if answer is None:
                    self.ignored_messages += 1  # manual §8.3.8 answers only a valid key
                else:
                    self._outbox.append(FeedbackSet(key, answer))
            case _:
                self.ignored_messages += 1  # a VSC-bound message the VSC does not take
        self._update(now)

    def host_rejection(self) -> None:
        """The host sent bytes that did not decode (counted for the control API)."""
        self.host_rejections += 1

    def _count_rate(self, times: deque[float], limit: int, now: float) -> None:
        times.append(now)
        while times and times[0] <= now - 1.0:
            times.popleft()
        if len(times) > limit:
            self.rate_violations += 1

    def _message_control(self, message: MessageControl, now: float) -> None:
        table = self.eeprom.message_control
        if message.message_type not in table or message.interval < MIN_INTERVAL_MS:
            self.ignored_messages += 1
            return
        row = Schedule(bool(message.enabled), message.interval)
        if table[message.message_type] != row:
            self.eeprom.message_control[message.message_type] = row
            self.eeprom_version += 1
        self._due[message.message_type] = now

    def set_key(self, key: int, value: int, now: float) -> bool:
        """A Feedback Set of ``key``; ``False`` (nothing changed) for a key or value the
        manual does not define (table 13)."""
        if key in USER_VALUE_KEYS:
            self.values[key] = value
        elif key in VIBRATION_KEYS:
            if value != 1:
                return False
            self.vibration_count += 1
            self._vibrate_side = VIBRATION_KEYS[key]
            self._vibrate_until = now + VIBRATION_S
        elif key in KEY_RANGES:
            low, high = KEY_RANGES[key]
            if not low <= value <= high:
                return False
            if self.eeprom.keys.get(key) != value:
                self.eeprom.keys[key] = value
                self.eeprom_version += 1
        elif key == DISPLAY_KEY and DisplayMode.parse(value) is not None:
            self.display_mode = value
        else:
            return False
        return True

    def _set_label(self, key: int, text: str) -> None:
        if key in USER_VALUE_KEYS or key in TEXT_ROW_KEYS:
            self.labels[key] = text
        else:
            self.ignored_messages += 1

    def key_value(self, key: int) -> int | None:
        """What a Feedback Get of ``key`` answers, or ``None`` for a key with no value."""
        if key in USER_VALUE_KEYS:
            return self.values.get(key, 0)
        if key in KEY_RANGES:
            return self.eeprom.keys[key]
        if key == DISPLAY_KEY:
            return self.display_mode
        return None

    # -- what the VSC sends ------------------------------------------------------------------

    def tick(self, now: float) -> list[Message]:
        """Everything the VSC sends at ``now``: queued replies, then each enabled message
        whose interval has come round (heartbeat first)."""
        if self.booting(now):
            return []
        self._update(now)
        out, self._outbox = self._outbox, []
        for kind in EMIT_ORDER:
            row = self.eeprom.message_control.get(kind)
            if row is None or not row.enabled:
                continue
            due = self._due.setdefault(kind, now)
            if now < due:
                continue
            interval = row.interval_ms / 1000
            # Fell behind (a stalled loop): no burst of catch-up frames, as a real timer.
            self._due[kind] = due + interval if due + interval > now else now + interval
            message = self._build(kind, now)
            if message is not None:
                out.append(message)
        return out

    def next_deadline(self, now: float) -> float:
        """When ``tick`` next has something to send."""
        if self.booting(now):
            return self._boot_until
        if self._outbox:
            return now
        dues = [
            self._due.get(kind, now)
            for kind, row in self.eeprom.message_control.items()
            if row.enabled
        ]
        return min(dues, default=now + 0.1)

    def _build(self, kind: int, now: float) -> Message | None:
        if kind == MessageType.VSC_HEARTBEAT:
            return self.heartbeat(now)
        if kind == MessageType.JOYSTICK:
            return self.joystick(now)
        if kind == MessageType.GPS:
            if not self._linked:
                return None  # the position comes from the remote's GPS (manual §8.3.2)
            return Gps(Gps.SOURCE_REMOTE, self.gps_sentence(now))
        if kind == MessageType.REMOTE_STATUS:
            return self.remote_status  # manual §8.3.4: not cleared when the link drops
        return None

    def heartbeat(self, now: float) -> VscHeartbeat:
        self._update(now)
        return VscHeartbeat(self.mode(now), self.autonomy, self._estop)

    def joystick(self, now: float) -> Joystick:
        """The sticks and buttons, zeroed outside Operational (manual §6 table 1)."""
        if self.mode(now) != VscMode.OPERATIONAL:
            return Joystick()
        on, off = FieldStatus.SET, FieldStatus.NOT_SET

        def status(name: str) -> FieldStatus:
            return on if name in self.buttons else off

        x, y, z = (Axis.from_value(self.axes[f"left_{a}"]) for a in "xyz")
        rx, ry, rz = (Axis.from_value(self.axes[f"right_{a}"]) for a in "xyz")
        return Joystick(
            x,
            y,
            z,
            rx,
            ry,
            rz,
            DPad(*(status(n) for n in BUTTON_NAMES[:4])),
            NumberedButtons(*(status(n) for n in BUTTON_NAMES[4:])),
        )

    def hid_report(self, now: float) -> HidInput:
        """The HID input report (manual §10.2.1, table 38) of the same sticks and buttons as
        ``joystick``, zeroed outside Operational alike. *sim*: a stick's -1023..1023 is scaled
        to -127..127; the D-pad's four buttons become its direction (opposite buttons cancel);
        the e-stop byte is 1 while any e-stop bit is set (the manual: "Actuated")."""
        stick = self.joystick(now)
        lx, ly, lz, rx, ry, rz = (
            round((axis.value or 0) * HID_AXIS_MAX / AXIS_MAGNITUDE_MAX) for axis in stick.axes
        )
        pressed = self.buttons if self.mode(now) == VscMode.OPERATIONAL else frozenset()
        across = ("right" in pressed) - ("left" in pressed)
        along = ("down" in pressed) - ("up" in pressed)
        numbered = sum(1 << i for i, name in enumerate(BUTTON_NAMES[4:]) if name in pressed)
        return HidInput(
            lx,
            ly,
            lz,
            rx,
            ry,
            rz,
            dpad=HID_DPAD[(across, along)],
            buttons=numbered,
            mode=self.mode(now),
            estop=1 if self.estop_word(now) else 0,
        )

    def gps_sentence(self, now: float) -> str:
        if self.gps_override is not None:
            return self.gps_override
        return gga_sentence(now - self._created, *self.position)

    # -- state -------------------------------------------------------------------------------

    def _update(self, now: float) -> None:
        """Bring every time-driven part of the state up to ``now``."""
        if self.booting(now):
            return
        linked = self.remote_on and self._link_at is not None and now >= self._link_at
        if linked != self._linked:
            self._linked = linked
            # Labels and display mode are lost when the remote re-links (PR-2).
            self.labels.clear()
            self.display_mode = DisplayMode.GPS.value
            self._mode = self.idle_mode  # manual §6.2: a new link starts in Local
            self._forced_mode = None
        keys = self.eeprom.keys
        if (
            self._linked
            and self._mode == VscMode.OPERATIONAL
            and keys[84]
            and now - self._last_activity >= (keys[80] + 1) * 60.0
        ):
            self._mode, self._pause_reason = VscMode.PAUSE, "inactivity"  # manual §6.3, §6.4
            self._inactivity_paused_at = now
        if (
            self._inactivity_paused_at is not None
            and keys[81]
            and now - self._inactivity_paused_at >= AUTO_OFF_S
        ):
            self._inactivity_paused_at = None
            self.power(False, now)  # manual §6.4 AutoOffEnable: the remote switches itself off
            return
        word = 0
        if self._off_as_local:
            word |= EstopBit.REMOTE_BUTTON  # PR-2.6: the remote's bits, as some hardware does
        elif not self._linked:
            word |= EstopBit.REMOTE_LINK
        elif self.remote_estop:
            word |= EstopBit.REMOTE_BUTTON
        if self.wired_estop:
            word |= EstopBit.WIRED
        if self._user_request:
            word |= EstopBit.USER_REQUEST
        if self._watchdog_tripped(now) or self._timeout_held:
            word |= EstopBit.USER_TIMEOUT
        self._estop = int(word)
        if word and self._linked and self._mode != self.idle_mode:
            # manual §6.6: "The system will always revert to Local Mode after an E-Stop".
            self._mode, self._forced_mode = self.idle_mode, None

    def _watchdog_tripped(self, now: float) -> bool:
        if not self.watchdog_enabled or self.watchdog == "ignores":
            return False
        limit = self.watchdog_late_s if self.watchdog == "late" else WATCHDOG_S
        tripped = now - self._last_user_heartbeat >= limit
        if tripped and self._user_heartbeat_seen and self.watchdog in ("held", "never_clears"):
            self._timeout_held = True  # a trip after heartbeats were seen is kept
        return tripped

    def set_watchdog(self, behaviour: str, late_s: float, now: float) -> None:
        """How the key-85 watchdog behaves from now on (faults.WATCHDOG_BEHAVIOURS)."""
        self.watchdog, self.watchdog_late_s = behaviour, late_s
        if behaviour not in ("held", "never_clears"):
            self._timeout_held = False
        self._update(now)

    @property
    def watchdog_enabled(self) -> bool:
        """Key 85 is on and the link has a user heartbeat (serial only, PR-3)."""
        return self.transport == "serial" and self.eeprom.keys[85] == 1

    @property
    def _off_as_local(self) -> bool:
        """The remote is off and this VSC reports that as Local with bit 0x01 (PR-2.6)."""
        return not self.remote_on and self.remote_off_reports == "local"

    def mode(self, now: float) -> int:
        """The mode the heartbeat reports."""
        self._update(now)
        if self._off_as_local and not self.booting(now):
            return self.idle_mode
        if not self._linked:
            return VscMode.SEARCHING
        return self._forced_mode if self._forced_mode is not None else self._mode

    def estop_word(self, now: float) -> int:
        self._update(now)
        return self._estop

    def linked(self, now: float) -> bool:
        self._update(now)
        return self._linked

    def user_heartbeat_age(self, now: float) -> float | None:
        """Seconds since the last user heartbeat, ``None`` if none since boot."""
        return now - self._last_user_heartbeat if self._user_heartbeat_seen else None

    def vibrating(self, now: float) -> str:
        """ "left", "right", "both" while a motor runs, else ""."""
        return self._vibrate_side if now < self._vibrate_until else ""

    @property
    def pause_reason(self) -> str:
        return self._pause_reason

    def consume_eeprom(self) -> Eeprom:
        """A copy of the EEPROM for the edge to save."""
        return Eeprom(dict(self.eeprom.message_control), dict(self.eeprom.keys))

    # -- the remote's side -------------------------------------------------------------------

    def _activity(self, now: float) -> None:
        self._last_activity = now
        self._inactivity_paused_at = None
        self._forced_mode = None

    def _require_link(self, now: float, action: str) -> None:
        if self.booting(now) or not self.linked(now):
            raise SimRefused(f"{action}: the remote has no link to the VSC (Searching)")

    def press_estop(self, now: float) -> None:
        """The remote's e-stop button (manual §4.4, §6.6): held down until ``release_estop``."""
        self.remote_estop = True
        self._activity(now)
        self._update(now)

    def release_estop(self, now: float) -> None:
        """Release the button. The VSC stays in Local until a takeover (manual §6.6)."""
        self.remote_estop = False
        self._activity(now)
        self._update(now)

    def set_wired_estop(self, active: bool, now: float) -> None:
        """The VSC's wired e-stop input (manual §6, §6.6 condition 2)."""
        self.wired_estop = active
        self._update(now)

    def takeover(self, now: float) -> None:
        """The takeover sequence: Local (or Remote, or Pause) to Operational (manual §6.5).

        Refused while any e-stop bit is set (manual §6.6: enables return only once the condition is
        corrected), while a stick is deflected (no jump into motion), and from Menu."""
        self._require_link(now, "takeover")
        if (
            self.watchdog == "held"
            and self._estop == EstopBit.USER_TIMEOUT
            and self._timeout_held
            and not self._watchdog_tripped(now)
        ):
            # The held bit: the gesture acknowledges it; the remote stays in Local (manual §6.6).
            self._timeout_held = False
            self._activity(now)
            self._update(now)
            return
        if self._estop:
            names = ", ".join(bit.name or "" for bit in EstopBit if self._estop & bit).lower()
            raise SimRefused(f"takeover: e-stop active ({names}); clear it first")
        deflected = [name for name, value in self.axes.items() if value]
        if deflected:
            raise SimRefused(f"takeover: sticks must be neutral ({', '.join(deflected)})")
        mode = self.mode(now)
        if mode == VscMode.OPERATIONAL:
            return
        if mode not in (self.idle_mode, VscMode.PAUSE):
            raise SimRefused(
                f"takeover: not from mode {mode:#04x} (only Local or Pause, manual §6.5)"
            )
        self._activity(now)
        self._mode, self._pause_reason = VscMode.OPERATIONAL, ""

    def pause(self, now: float, reason: str = "button") -> None:
        """The pause button, or a SafetySense trigger: orientation, free_fall, inactivity
        (manual §6.3). A trigger whose enable key (82, 83, 84) is 0 is refused."""
        if reason not in PAUSE_REASONS:
            raise SimRefused(f"pause: reason must be one of {', '.join(PAUSE_REASONS)}")
        enable_key = PAUSE_REASONS[reason]
        if enable_key is not None and not self.eeprom.keys[enable_key]:
            raise SimRefused(f"pause: {reason} pause is disabled by key {enable_key}")
        self._require_link(now, "pause")
        mode = self.mode(now)
        if mode == VscMode.PAUSE:
            return
        if mode != VscMode.OPERATIONAL:
            raise SimRefused(f"pause: only from Operational (mode is {mode:#04x}, manual §6.2-6.3)")
        self._activity(now)
        self._mode, self._pause_reason = VscMode.PAUSE, reason

    def menu(self, now: float) -> None:
        """The menu button: enter Menu, or leave it (manual §6.4). Leaving returns to Pause
        when the menu was entered from Operational or Pause (motion needs a new takeover),
        else to the mode it was entered from."""
        self._require_link(now, "menu")
        if self._estop:
            raise SimRefused("menu: not during an e-stop")
        self._activity(now)
        if self._mode == VscMode.MENU:
            self._mode = self._menu_return
            return
        entered_from = self._mode
        pausing = entered_from in (VscMode.OPERATIONAL, VscMode.PAUSE)
        self._menu_return = VscMode.PAUSE if pausing else entered_from
        if pausing:
            self._pause_reason = "menu"
        self._mode = VscMode.MENU

    def power(self, on: bool, now: float) -> None:
        """Switch the remote on (it links ``link_delay`` later) or off (the VSC searches and
        raises the remote e-stop bits, manual §6.1)."""
        if on == self.remote_on:
            return
        self.remote_on = on
        self._link_at = now + self.link_delay if on else None
        self._activity(now)
        self._update(now)

    def set_axes(self, values: Mapping[str, int], now: float) -> None:
        """Move sticks: ``{"left_x": 512, ...}``, each -1023..1023; others stay."""
        for name, value in values.items():
            if name not in self.axes:
                raise SimRefused(f"axes: unknown axis {name!r} (one of {', '.join(self.axes)})")
            if isinstance(value, bool) or not isinstance(value, int) or abs(value) > 1023:
                raise SimRefused(f"axes: {name} must be an integer in -1023..1023")
        self.axes.update(values)
        self._activity(now)

    def set_buttons(self, pressed: Iterable[str], now: float) -> None:
        """The buttons held down now (all others released)."""
        names = frozenset(pressed)
        unknown = sorted(names - set(BUTTON_NAMES))
        if unknown:
            raise SimRefused(f"buttons: unknown {unknown} (one of {', '.join(BUTTON_NAMES)})")
        self.buttons = names
        self._activity(now)

    def edit_value(self, key: int, value: int, now: float) -> None:
        """Edit user value ``key`` (1-9) in the remote's menu: the VSC tells the host with a
        Feedback Set (manual §8.3.9)."""
        if self.mode(now) != VscMode.MENU:
            raise SimRefused("edit: values are edited in Menu mode only (manual §8.3.9)")
        if key not in USER_VALUE_KEYS or not -32768 <= value <= 32767:
            raise SimRefused("edit: key must be 1-9 and value a 16-bit integer")
        self.values[key] = value
        self._outbox.append(FeedbackSet(key, value))
        self._activity(now)

    def force_mode(self, mode: int, now: float) -> None:
        """A test lever: report ``mode`` (any byte, named or not) regardless of the rules
        until the next remote action or e-stop. Sticks are live only if it is Operational."""
        if isinstance(mode, bool) or not isinstance(mode, int) or not 0 <= mode <= 0xFF:
            raise SimRefused("mode: must be a mode name or a byte 0..255")
        self._require_link(now, "mode")
        self._forced_mode = mode

    def set_autonomy(self, autonomy: int) -> None:
        if isinstance(autonomy, bool) or not isinstance(autonomy, int) or not 0 <= autonomy <= 255:
            raise SimRefused("autonomy: must be a byte (0 user, 1 shared, 2 autonomous)")
        self.autonomy = autonomy

    def set_remote_status(self, **fields: int) -> None:
        try:
            self.remote_status = replace(self.remote_status, **fields)
        except (TypeError, ValueError) as error:
            raise SimRefused(f"remote_status: {error}") from None

    def set_gps(self, sentence: str | None) -> None:
        """Send ``sentence`` as the remote's GPS, or ``None`` for the generated GGA."""
        if sentence is not None:
            try:
                Gps(Gps.SOURCE_REMOTE, sentence)
            except ValueError as error:
                raise SimRefused(f"gps: {error}") from None
        self.gps_override = sentence

    # -- the LCD -----------------------------------------------------------------------------

    def render_lcd(self, now: float) -> str:
        """The remote's screen as text: a status row and four 20-character rows, framed."""
        rows = self._lcd_rows(now)
        body = [row[:LCD_WIDTH].ljust(LCD_WIDTH) for row in (*rows, "", "", "", "", "")[:5]]
        edge = "+" + "-" * LCD_WIDTH + "+"
        return "\n".join([edge, *(f"|{row}|" for row in body), edge])

    def _lcd_rows(self, now: float) -> list[str]:
        if not self.remote_on:
            return ["", "   (remote is off)"]
        battery = f"BAT{self.remote_status.battery_level:3d}%"
        vibration = {"left": "<< ", "right": " >>", "both": "<>>"}.get(self.vibrating(now), "")
        mode = self.mode(now) if not self.booting(now) else VscMode.SEARCHING

        def status(name: str) -> str:
            right = vibration + battery
            return name[: LCD_WIDTH - len(right) - 1].ljust(LCD_WIDTH - len(right)) + right

        if mode == VscMode.SEARCHING:
            return [status("SEARCHING"), "Looking for the VSC", "", "Check VSC power", "and range"]
        if self._estop:
            sources = [
                text
                for bit, text in (
                    (EstopBit.REMOTE_BUTTON, "Remote e-stop"),
                    (EstopBit.WIRED, "Wired e-stop input"),
                    (EstopBit.USER_REQUEST, "Computer e-stop"),
                    (EstopBit.USER_TIMEOUT, "Computer timeout"),
                )
                if self._estop & bit
            ]
            return [status("E-STOP"), *sources[:3], "Clear it, take over"]
        if mode == self.idle_mode:
            name = "LOCAL" if mode == VscMode.LOCAL else "REMOTE"
            return [status(name), "Linked to VSC", "", "Take over to drive"]
        if mode == VscMode.PAUSE:
            reason = f"Reason: {self._pause_reason or 'button'}"
            return [status("PAUSED"), reason, "", "Take over to resume"]
        if mode == VscMode.MENU:
            return [status("MENU"), "Vehicle Remote Info", *self._value_rows(3, labelled=True)]
        if mode != VscMode.OPERATIONAL:
            return [status(f"MODE {mode:#04x}"), "Unknown mode"]
        header = status("OPERATIONAL")
        match self.display_mode:
            case DisplayMode.TEXT_ROWS:
                return [header, *(self.labels.get(key, "") for key in TEXT_ROW_KEYS)]
            case DisplayMode.LABELLED_VALUES:
                return [header, *self._value_rows(4, labelled=True)]
            case DisplayMode.VALUES:
                return [
                    header,
                    *(
                        f"{k}:{self._shown(k):>6}   {k + 4}:{self._shown(k + 4):>6}"
                        for k in range(1, 5)
                    ),
                ]
        fix = parse_nmea(self.gps_sentence(now)) if self._linked else None
        if fix is None or fix.latitude is None or fix.longitude is None:
            return [header, "GPS: no fix"]
        utc = fix.utc_time.strftime("%H:%M:%S") if fix.utc_time else "--:--:--"
        return [header, f"UTC {utc}", f"LAT {fix.latitude:10.5f}", f"LON {fix.longitude:10.5f}"]

    def _shown(self, key: int) -> str:
        """A user value as the remote shows it: 6 characters, "XXXXXX" outside 16 bits."""
        value = self.values.get(key, 0)
        return str(value) if -32768 <= value <= 32767 else "XXXXXX"

    def _value_rows(self, count: int, *, labelled: bool) -> list[str]:
        rows = []
        for key in range(1, count + 1):
            label = self.labels.get(key, f"Value {key}") if labelled else ""
            rows.append(f"{label[:13]:<13} {self._shown(key):>6}")
        return rows

"""The simulator's engine: the model, the fault injector and one transport edge, stepped by
the caller's loop, and the control requests (``docs/simulator.md`` lists them).

``step(now)`` does one round: read the host's frames, let the model answer, send what is
due through the faults. ``request(obj, now)`` runs one control request and returns its
reply; a bad request is an ``{"ok": false, "error": ...}`` reply, never an exception.
The EEPROM file is written (atomically) whenever the model's EEPROM changes.
"""

from __future__ import annotations

import json
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from supervisord.protocol.codes import MessageType, VscMode
from supervisord.protocol.framing import Rejection, encode_frame
from supervisord.protocol.hid import HidOutput
from supervisord.protocol.j1939 import CanRejection
from supervisord.protocol.messages import FeedbackName, FeedbackSet, VscHeartbeat
from supervisord.sim.can_side import CanSide, can_frames
from supervisord.sim.faults import FaultInjector, FaultPlan, Pacer
from supervisord.sim.hid_side import HID_PERIOD_S, HidSide
from supervisord.sim.model import (
    BUTTON_NAMES,
    Eeprom,
    EstopBit,
    SimRefused,
    SimTransport,
    VscModel,
)
from supervisord.sim.serial_side import SerialSide
from supervisord.sim.tty_side import TtySide

DEFAULT_BOOT_DELAY_S = 2.0  # the real bootloader waits one to two minutes (PR-5)
MAX_DELAY_S = 600.0
Side = SerialSide | TtySide | CanSide | HidSide
ByteSide = SerialSide | TtySide  # the serial protocol's bytes (manual §8)
Reply = dict[str, Any]


class RequestError(Exception):
    """A control request that cannot be done as asked; its text is the error reply."""


def load_eeprom(path: Path | None, transport: SimTransport) -> Eeprom:
    """The EEPROM saved at ``path``, factory defaults if there is no file yet. A file that
    cannot be read raises ``ValueError`` naming it: the simulator refuses to start rather
    than silently forget a test's settings."""
    if path is None or not path.exists():
        return Eeprom.defaults(transport)
    try:
        return Eeprom.from_json(json.loads(path.read_text()), transport)
    except (OSError, ValueError, RecursionError) as error:  # Recursion: nested thousands deep
        raise ValueError(f"{path}: {error}") from error


def save_eeprom(path: Path, eeprom: Eeprom) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(eeprom.to_json(), indent=2) + "\n")
    os.replace(tmp, path)


def _mode_name(mode: int) -> str:
    known = VscMode.parse(mode)
    return known.name.lower() if known is not None else "unknown"


class Simulator:
    """One simulated VSC on one transport."""

    def __init__(
        self,
        side: Side,
        model: VscModel,
        *,
        seed: int = 0,
        eeprom_path: Path | None = None,
        boot_delay: float = DEFAULT_BOOT_DELAY_S,
        log: Callable[[str], None] | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.side = side
        self.model = model
        self.faults = FaultInjector(seed=seed)
        self.pacer = Pacer()
        self.eeprom_path = eeprom_path
        self.boot_delay = boot_delay
        self.silenced = False
        self.frames_sent = 0
        self.quit_requested = False
        self._log = log or (lambda text: print(f"srcs-sim: {text}", file=sys.stderr, flush=True))
        self._saved_version = model.eeprom_version
        self._replug_after_boot = False
        self._last_seen: tuple[int, int] | None = None
        self._clock = clock
        self._next_report = 0.0  # HID: when the next input report is due
        # The e-stop word on the wire (the last one sent), and while it is not 0, when
        # (``clock``) the first frame or report of this e-stop was written: where a stop's
        # latency starts, whatever bits the host's answer adds to the word afterwards.
        self.estop_sent: int | None = None
        self.estop_sent_at: float | None = None

    # -- the loop's side ---------------------------------------------------------------------

    def fileno(self) -> int | None:
        return self.side.fileno()

    def step(self, now: float) -> None:
        """One round: the host's frames in, the VSC's frames out, the EEPROM saved."""
        self._receive(now)
        if self._replug_after_boot and not self.model.booting(now):
            self._replug_after_boot = False
            self.side.replug()
            self._log(f"replugged after reboot at {self.side.description}")
        self._send(now)
        self._save_eeprom()
        self._report(now)

    def _receive(self, now: float) -> None:
        if isinstance(self.side, HidSide):
            for report in self.side.receive():
                if isinstance(report, HidOutput):
                    for message in _hid_messages(report):
                        self.model.handle(message, now)
                else:
                    self.model.host_rejection()
            return
        for event in self.side.receive():
            if isinstance(event, Rejection | CanRejection):
                self.model.host_rejection()
            else:
                self.model.handle(event, now)

    def _send(self, now: float) -> None:
        # The model ticks even while nothing is sent, so its clocks keep running.
        sending = not self.silenced and self.side.plugged
        messages = self.model.tick(now)
        if isinstance(self.side, HidSide):
            self._send_report(now, sending)  # HID mode speaks none of the serial messages
            return
        if self.faults.flap_due(now) and not self.model.booting(now):
            # A chattering VSC: each change of the flapping mode is a heartbeat of its own.
            messages.insert(0, self.model.heartbeat(now))
        word: int | None = None  # a heartbeat with another e-stop word goes out this round
        for produced in messages if sending else []:
            message = self.faults.message(produced, now)
            if type(message) is VscHeartbeat and message.estop != self.estop_sent:
                word = message.estop
            if isinstance(self.side, ByteSide):
                self.faults.push(encode_frame(message), message.TYPE, now)
            else:
                for frame in can_frames(message):
                    self.faults.push_can(frame, message.TYPE, now)
        self._sent_word(word, self._write_due(now, sending))

    def _write_due(self, now: float, sending: bool) -> float:
        """What the faults let through now goes out (through the pacer on serial); the clock
        just before the write."""
        began = self._clock()
        for item in self.faults.due(now):
            if not sending:
                continue
            self.frames_sent += 1
            if isinstance(self.side, CanSide):
                self.side.send(item)
            elif isinstance(item, bytes):
                self.pacer.push(item)
        if isinstance(self.side, ByteSide):
            self.pacer.configure(self.faults.plan.chunk_bytes, self.faults.plan.chunk_gap_s)
            data = self.pacer.pop(now)
            if data:
                began = self._clock()
                self.side.write(data)
        return began

    def _send_report(self, now: float, sending: bool) -> None:
        """HID: the input report every ``HID_PERIOD_S`` (not while booting or silenced)."""
        assert isinstance(self.side, HidSide)
        if now < self._next_report:
            return
        # Fell behind (a stalled loop): the next report a period from now, no burst.
        due = self._next_report + HID_PERIOD_S
        self._next_report = due if due > now else now + HID_PERIOD_S
        if not sending or self.model.booting(now):
            return
        word = self.model.estop_word(now)
        report = self.model.hid_report(now)
        began = self._clock()
        self.side.send(report)
        self.frames_sent += 1
        self._sent_word(word if word != self.estop_sent else None, began)

    def _sent_word(self, word: int | None, began: float) -> None:
        """A heartbeat (or report) with another e-stop word ``word`` was written by a write
        that began at ``began`` (with no fault plan that holds frames back; with one, it was
        handed to the faults, which may delay it). The time is taken before the write: on one
        CPU the host may read the frame and act before the write call returns."""
        if word is None:
            return
        if not word:
            self.estop_sent_at = None
        elif not self.estop_sent:
            self.estop_sent_at = began
        self.estop_sent = word

    def next_deadline(self, now: float) -> float:
        deadlines = [self.model.next_deadline(now)]
        if isinstance(self.side, HidSide):
            deadlines.append(self._next_report)
        for extra in (self.faults.next_deadline(), self.pacer.next_deadline()):
            if extra is not None:
                deadlines.append(extra)
        return min(deadlines)

    def _save_eeprom(self) -> None:
        if self.model.eeprom_version == self._saved_version:
            return
        self._saved_version = self.model.eeprom_version
        if self.eeprom_path is not None:
            save_eeprom(self.eeprom_path, self.model.consume_eeprom())

    def _report(self, now: float) -> None:
        """Log each change of mode or e-stop word once."""
        if self.model.booting(now):
            return
        seen = (self.model.mode(now), self.model.estop_word(now))
        if seen != self._last_seen:
            self._last_seen = seen
            self._log(f"mode {_mode_name(seen[0])} ({seen[0]:#04x}), e-stop word {seen[1]:#x}")

    def close(self) -> None:
        self._save_eeprom()
        self.side.close()

    # -- control requests --------------------------------------------------------------------

    def request(self, request: object, now: float) -> Reply:
        """Run one control request (a JSON object with ``cmd``) and return the reply."""
        try:
            if not isinstance(request, dict):
                raise RequestError('a request is a JSON object like {"cmd": "state"}')
            command = request.get("cmd")
            handler = self._handlers().get(command) if isinstance(command, str) else None
            if handler is None:
                known = ", ".join(sorted(self._handlers()))
                raise RequestError(f"unknown cmd {command!r}; known: {known}")
            reply = handler(request, now)
        except (RequestError, SimRefused, ValueError) as error:
            return {"ok": False, "error": str(error)}
        return {"ok": True, **reply}

    def _handlers(self) -> dict[str, Callable[[dict[str, Any], float], Reply]]:
        return {
            "state": lambda r, now: self.state(now),
            "lcd": lambda r, now: {"lcd": self.model.render_lcd(now)},
            "estop": self._estop,
            "release": self._release,
            "pause": self._pause,
            "takeover": self._takeover,
            "menu": self._menu,
            "mode": self._mode,
            "power": self._power,
            "wired_estop": self._wired,
            "axes": self._axes,
            "buttons": self._buttons,
            "edit": self._edit,
            "key": self._key,
            "autonomy": self._autonomy,
            "remote_status": self._remote_status,
            "gps": self._gps,
            "unplug": self._unplug,
            "replug": self._replug,
            "reboot": self._reboot,
            "fault": self._fault,
            "silence": self._silence,
            "bus_off": self._bus_off,
            "quit": self._quit,
        }

    def _summary(self, now: float) -> Reply:
        mode = self.model.mode(now)
        return {"mode": mode, "mode_name": _mode_name(mode), "estop": self.model.estop_word(now)}

    def _estop(self, request: dict[str, Any], now: float) -> Reply:
        self.model.press_estop(now)
        return self._summary(now)

    def _release(self, request: dict[str, Any], now: float) -> Reply:
        self.model.release_estop(now)
        return self._summary(now)

    def _pause(self, request: dict[str, Any], now: float) -> Reply:
        self.model.pause(now, _arg(request, "reason", str, "button"))
        return self._summary(now)

    def _takeover(self, request: dict[str, Any], now: float) -> Reply:
        self.model.takeover(now)
        return self._summary(now)

    def _menu(self, request: dict[str, Any], now: float) -> Reply:
        self.model.menu(now)
        return self._summary(now)

    def _mode(self, request: dict[str, Any], now: float) -> Reply:
        value = request.get("mode")
        if isinstance(value, str):
            named = VscMode.__members__.get(value.upper())
            if named is None:
                names = ", ".join(m.name.lower() for m in VscMode)
                raise RequestError(f"mode: unknown name {value!r}; names: {names}, or a byte")
            value = int(named)
        if isinstance(value, bool) or not isinstance(value, int):
            raise RequestError("mode: give a mode name or a byte 0..255")
        self.model.force_mode(value, now)
        return self._summary(now)

    def _power(self, request: dict[str, Any], now: float) -> Reply:
        self.model.power(_arg(request, "on", bool), now)
        return self._summary(now)

    def _wired(self, request: dict[str, Any], now: float) -> Reply:
        self.model.set_wired_estop(_arg(request, "active", bool), now)
        return self._summary(now)

    def _axes(self, request: dict[str, Any], now: float) -> Reply:
        values = {k: v for k, v in request.items() if k != "cmd"}
        self.model.set_axes(values, now)
        return {"axes": dict(self.model.axes)}

    def _buttons(self, request: dict[str, Any], now: float) -> Reply:
        pressed = _arg(request, "pressed", list)
        if not all(isinstance(name, str) for name in pressed):
            raise RequestError(f"buttons: pressed is a list of names: {', '.join(BUTTON_NAMES)}")
        self.model.set_buttons(pressed, now)
        return {"buttons": sorted(self.model.buttons)}

    def _edit(self, request: dict[str, Any], now: float) -> Reply:
        self.model.edit_value(_arg(request, "key", int), _arg(request, "value", int), now)
        return {}

    def _key(self, request: dict[str, Any], now: float) -> Reply:
        """Read a feedback key, or set it as the host's Feedback Set would (85 is saved)."""
        key = _arg(request, "key", int)
        if "value" in request:
            if not self.model.set_key(key, _arg(request, "value", int), now):
                raise RequestError(f"key: {key} does not take that value (manual table 13)")
            self._save_eeprom()
        value = self.model.key_value(key)
        if value is None:
            raise RequestError(f"key: {key} has no readable value")
        return {"key": key, "value": value}

    def _autonomy(self, request: dict[str, Any], now: float) -> Reply:
        self.model.set_autonomy(_arg(request, "autonomy", int))
        return {"autonomy": self.model.autonomy}

    def _remote_status(self, request: dict[str, Any], now: float) -> Reply:
        fields = {k: v for k, v in request.items() if k != "cmd"}
        self.model.set_remote_status(**fields)
        return {"remote_status": _remote_status_json(self.model)}

    def _gps(self, request: dict[str, Any], now: float) -> Reply:
        sentence = request.get("sentence")
        if sentence is not None and not isinstance(sentence, str):
            raise RequestError("gps: sentence is text, or null for the generated GGA")
        if "latitude" in request or "longitude" in request:
            latitude = _arg(request, "latitude", float, self.model.position[0])
            longitude = _arg(request, "longitude", float, self.model.position[1])
            if not (-90 <= latitude <= 90 and -180 <= longitude <= 180):
                raise RequestError("gps: latitude -90..90 and longitude -180..180")
            self.model.position = (latitude, longitude)
        self.model.set_gps(sentence)
        return {"sentence": self.model.gps_sentence(now)}

    def _unplug(self, request: dict[str, Any], now: float) -> Reply:
        self.side.unplug()
        self.faults.clear()
        self.pacer.clear()
        self._log("unplugged")
        return {"plugged": False}

    def _replug(self, request: dict[str, Any], now: float) -> Reply:
        self.side.replug()
        self._log(f"replugged at {self.side.description}")
        return {"plugged": True}

    def _reboot(self, request: dict[str, Any], now: float) -> Reply:
        delay = _arg(request, "delay", float, self.boot_delay)
        if not 0 <= delay <= MAX_DELAY_S:
            raise RequestError(f"reboot: delay must be 0..{MAX_DELAY_S:g} seconds")
        # On USB the VSC leaves the bus while its bootloader runs (PR-5); on RS-232 or
        # CAN the line only falls silent. A device the simulator does not own (--tty, --hid)
        # cannot leave the bus by its doing: it falls silent too.
        unplug = _arg(request, "unplug", bool, isinstance(self.side, SerialSide))
        self.model.reboot(now, delay)
        self.faults.clear()
        self.pacer.clear()
        if unplug and self.side.plugged:
            self.side.unplug()
            self._replug_after_boot = True
        self._log(f"rebooting: {delay:g} s in the bootloader")
        return {"booting_until_s": delay}

    def _fault(self, request: dict[str, Any], now: float) -> Reply:
        if request.get("clear") is True:
            plan = FaultPlan()
        else:
            plan = FaultPlan.from_json(_arg(request, "plan", dict))
        self.faults.set_plan(plan, now)
        self.model.set_watchdog(plan.watchdog, plan.watchdog_late_s, now)
        self._log(f"fault plan: {plan.to_json() or 'none'}")
        return {"faults": plan.to_json()}

    def _silence(self, request: dict[str, Any], now: float) -> Reply:
        self.silenced = _arg(request, "on", bool)
        return {"silenced": self.silenced}

    def _bus_off(self, request: dict[str, Any], now: float) -> Reply:
        if not isinstance(self.side, CanSide):
            raise RequestError("bus_off: only on CAN (start with --can)")
        self.side.bus_off(_arg(request, "on", bool))
        return {"bus_off": self.side.is_bus_off}

    def _quit(self, request: dict[str, Any], now: float) -> Reply:
        self.quit_requested = True
        return {}

    # -- the state -----------------------------------------------------------------------------

    def state(self, now: float) -> Reply:
        model = self.model
        mode = model.mode(now)
        word = model.estop_word(now)
        age = model.user_heartbeat_age(now)
        return {
            "transport": self.side.kind,
            "port": self.side.description,
            "device": self.side.device if not isinstance(self.side, CanSide) else "",
            "plugged": self.side.plugged,
            "hangups": self.side.hangups if isinstance(self.side, TtySide) else 0,
            "hid_reports": _hid_counts(self.side),
            "estop_sent": self.estop_sent,
            "estop_sent_at": self.estop_sent_at,
            "booting": model.booting(now),
            "silenced": self.silenced,
            "bus_off": isinstance(self.side, CanSide) and self.side.is_bus_off,
            "mode": mode,
            "mode_name": _mode_name(mode),
            "autonomy": model.autonomy,
            "estop": word,
            "estop_bits": [bit.name.lower() for bit in EstopBit if word & bit and bit.name],
            "remote_on": model.remote_on,
            "remote_off_reports": model.remote_off_reports,
            "linked": model.linked(now),
            "remote_estop": model.remote_estop,
            "wired_estop": model.wired_estop,
            "pause_reason": model.pause_reason,
            "axes": dict(model.axes),
            "buttons": sorted(model.buttons),
            "key85": model.eeprom.keys[85],
            "watchdog_enabled": model.watchdog_enabled,
            "user_heartbeat_age": None if age is None else round(age, 4),
            "keys": {str(k): v for k, v in sorted(model.eeprom.keys.items())},
            "values": {str(k): v for k, v in sorted(model.values.items())},
            "labels": {str(k): v for k, v in sorted(model.labels.items())},
            "display_mode": model.display_mode,
            "message_control": [
                {
                    "type": kind,
                    "name": MessageType(kind).name.lower(),
                    "enabled": row.enabled,
                    "interval_ms": row.interval_ms,
                }
                for kind, row in sorted(model.eeprom.message_control.items())
            ],
            "remote_status": _remote_status_json(model),
            "lcd": model.render_lcd(now),
            "vibration_count": model.vibration_count,
            "vibrating": model.vibrating(now),
            "host_frames": model.host_frames,
            "host_rejections": model.host_rejections,
            "ignored_messages": model.ignored_messages,
            "rate_violations": model.rate_violations,
            "frames_sent": self.frames_sent,
            "reboots": model.reboots,
            "faults": self.faults.plan.to_json(),
            "fault_counts": dict(sorted(self.faults.counts.items())),
        }


def _hid_messages(report: HidOutput) -> list[FeedbackSet | FeedbackName]:
    """What an output report asks (manual §10.2.2): a value where its key is not 0, a label
    or text row where its string key is not 0; as the same messages on serial would."""
    messages: list[FeedbackSet | FeedbackName] = []
    if report.key:
        messages.append(FeedbackSet(report.key, report.value))
    if report.string_key:
        messages.append(FeedbackName(report.string_key, report.text))
    return messages


def _hid_counts(side: Side) -> dict[str, int] | None:
    """Input reports written and dropped (HID only)."""
    if not isinstance(side, HidSide):
        return None
    return {"sent": side.reports_sent, "dropped": side.reports_dropped}


def _remote_status_json(model: VscModel) -> dict[str, int]:
    status = model.remote_status
    return {
        "battery_level": status.battery_level,
        "battery_charging": status.battery_charging,
        "connection_strength_vsc": status.connection_strength_vsc,
        "connection_strength_src": status.connection_strength_src,
    }


def _arg(request: dict[str, Any], name: str, kind: type, default: Any = None) -> Any:
    """``request[name]`` checked to be a ``kind`` (an int is accepted as a float); without
    a default the field is required."""
    value = request.get(name, default)
    cmd = request.get("cmd")
    if value is None:
        raise RequestError(f"{cmd}: missing field {name!r}")
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
        raise RequestError(f"{cmd}: {name} must be {kind.__name__}, not {value!r}")
    return value

"""A CAN enable frame: a generic template that fits common motor controllers.

Many motor controllers enable their power stage only while a periodic command frame says so,
and check a rolling counter in it to detect a sender that hangs. This output sends such a
frame, built from a template (``docs/outputs.md`` has a worked example):

- ``arbitration_id`` (11-bit, or 29-bit with ``extended = true``);
- ``data_on`` and ``data_off``: the payload for "enabled" and "disabled" (hex, 0-8 bytes);
- optionally a rolling counter: ``counter_byte`` (its index in the payload) and
  ``counter_mask`` (the bits of that byte it occupies, contiguous; default ``0xFF``). The
  counter goes up by one with every frame sent and wraps within its mask; the other bits of
  that byte come from the template;
- ``period_ms`` (default 20): the frame goes out every period, from the daemon's main loop
  calling :meth:`CanEnableOutput.tick`.

On :meth:`CanEnableOutput.set` the new frame goes out at once, inside the call, and the period
restarts from there; so on a stop the "off" frame leaves at once and keeps going out every
period (SR-6). A frame the bus refuses (bus closed, transmit buffer full) is a
``SEND_ERROR`` read-back, i.e. ``output_fault:NAME``. The bus belongs to the daemon: this
output never shuts it down. Sends never block: a full transmit queue is a fault, not a wait.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar, Final

import can

from supervisord.errors import ConfigError
from supervisord.outputs.base import (
    NS_PER_MS,
    ConfigTable,
    Output,
    OutputFault,
    OutputKind,
    OutputSpec,
    Periodic,
    ReadBack,
)

PERIOD_MS_RANGE: Final = (5, 1000)
"""Allowed ``period_ms``."""
MAX_STANDARD_ID: Final = 0x7FF
MAX_EXTENDED_ID: Final = 0x1FFF_FFFF
MAX_DATA: Final = 8  # classic CAN; CAN FD frames are not supported
SEND_TIMEOUT_S: Final = 0.0  # never wait for the transmit queue: a full queue is a fault


def parse_hex(text: str) -> bytes:
    """Bytes from hex text such as ``"01 00 ff"``, ``"0100ff"`` or ``"01:00:ff"``.

    Raises ``ValueError`` for anything else."""
    return bytes.fromhex(text.replace(":", " "))


@dataclasses.dataclass(frozen=True, kw_only=True)
class CanEnableSpec(OutputSpec):
    """Options of a ``kind = "can"`` output (see the module docstring; all validated here)."""

    kind: ClassVar[OutputKind] = OutputKind.CAN
    arbitration_id: int
    extended: bool = False
    data_on: bytes
    data_off: bytes
    counter_byte: int | None = None
    counter_mask: int = 0xFF
    period_ms: int = 20

    def __post_init__(self) -> None:
        super().__post_init__()
        p = f"outputs.{self.name}"
        top = MAX_EXTENDED_ID if self.extended else MAX_STANDARD_ID
        if not 0 <= self.arbitration_id <= top:
            fix = f"give 0 to {top:#x}" + ("" if self.extended else ", or set extended = true")
            raise ConfigError(f"{p}.arbitration_id", self.arbitration_id, fix)
        for key, data in (("data_on", self.data_on), ("data_off", self.data_off)):
            if len(data) > MAX_DATA:
                raise ConfigError(f"{p}.{key}", data.hex(" "), f"give at most {MAX_DATA} bytes")
        low, high = PERIOD_MS_RANGE
        if not low <= self.period_ms <= high:
            raise ConfigError(f"{p}.period_ms", self.period_ms, f"give {low} to {high} ms")
        mask = self.counter_mask
        if not 0 < mask <= 0xFF or not _contiguous(mask):
            raise ConfigError(
                f"{p}.counter_mask", mask, "give contiguous bits within one byte, e.g. 0x0F"
            )
        if self.counter_byte is not None:
            shortest = min(len(self.data_on), len(self.data_off))
            if not 0 <= self.counter_byte < shortest:
                raise ConfigError(
                    f"{p}.counter_byte",
                    self.counter_byte,
                    f"give a byte index below {shortest}, the length of data_on and data_off",
                )
        if self.frame_data(True, 0) == self.frame_data(False, 0):
            raise ConfigError(f"{p}.data_on", self.data_on.hex(" "), "make it differ from data_off")

    @property
    def counter_modulo(self) -> int:
        """How many counter values there are before it wraps (1 without a counter)."""
        if self.counter_byte is None:
            return 1
        return (self.counter_mask >> _shift(self.counter_mask)) + 1

    def frame_data(self, on: bool, counter: int) -> bytes:
        """The payload for ``on`` with the rolling counter at ``counter`` (modulo its range)."""
        data = bytearray(self.data_on if on else self.data_off)
        if self.counter_byte is not None:
            mask = self.counter_mask
            value = ((counter % self.counter_modulo) << _shift(mask)) & mask
            data[self.counter_byte] = (data[self.counter_byte] & ~mask & 0xFF) | value
        return bytes(data)

    @classmethod
    def _read(cls, t: ConfigTable) -> dict[str, Any]:
        options: dict[str, Any] = {
            "arbitration_id": t.integer("arbitration_id", None, 0, MAX_EXTENDED_ID),
            "extended": t.boolean("extended", False),
            "counter_byte": t.optional_integer("counter_byte", 0, MAX_DATA - 1),
            "counter_mask": t.integer("counter_mask", 0xFF, 1, 0xFF),
            "period_ms": t.integer("period_ms", 20, *PERIOD_MS_RANGE),
        }
        for key in ("data_on", "data_off"):
            text = t.raw(key)
            try:
                options[key] = parse_hex(text) if isinstance(text, str) else None
            except ValueError:
                options[key] = None
            if options[key] is None:
                raise ConfigError(t.key(key), text, 'give hex bytes, e.g. "01 00 00 00"')
        return options


def _shift(mask: int) -> int:
    return (mask & -mask).bit_length() - 1


def _contiguous(mask: int) -> bool:
    m = mask >> _shift(mask)
    return m & (m + 1) == 0


class CanEnableOutput(Output):
    """Sends the enable frame of ``spec`` on ``bus`` (see the module docstring)."""

    kind: ClassVar[OutputKind] = OutputKind.CAN
    spec_type: ClassVar[type[OutputSpec]] = CanEnableSpec

    def __init__(self, spec: CanEnableSpec, bus: can.BusABC) -> None:
        super().__init__(spec)
        self.spec = spec
        self._bus = bus
        self._period = Periodic(spec.period_ms * NS_PER_MS)
        self._counter = 0
        self._on = False

    @property
    def counter(self) -> int:
        """The rolling counter value the next frame will carry."""
        return self._counter

    def _open(self, now: int) -> ReadBack:
        return self._send(False, now)

    def _write(self, on: bool, now: int) -> ReadBack:
        return self._send(on, now)

    def tick(self, now: int) -> ReadBack | None:
        """Send the periodic frame when it is due (see :meth:`Output.tick`)."""
        super().tick(now)
        if not self._period.due(now):
            return None
        self._period.advance(now)
        return self._transmit(self._on)

    def next_deadline(self) -> int | None:
        """The next periodic frame, or ``None`` when closed."""
        return self._period.deadline if self.is_open else None

    def _close(self) -> ReadBack:
        self._period.stop()
        return self._transmit(False)

    def _send(self, on: bool, now: int) -> ReadBack:
        """Send the frame for ``on`` now and restart the period from ``now``."""
        self._on = on
        self._period.start(now)
        return self._transmit(on)

    def _transmit(self, on: bool) -> ReadBack:
        self._on = on
        msg = can.Message(
            arbitration_id=self.spec.arbitration_id,
            is_extended_id=self.spec.extended,
            data=self.spec.frame_data(on, self._counter),
        )
        try:
            self._bus.send(msg, timeout=SEND_TIMEOUT_S)
        except can.CanError as e:
            return ReadBack(self.name, on, on, None, OutputFault.SEND_ERROR, str(e))
        self._counter = (self._counter + 1) % self.spec.counter_modulo
        return ReadBack(self.name, on, on, None)

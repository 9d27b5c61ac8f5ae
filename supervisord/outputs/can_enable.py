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
import re
from collections.abc import Mapping
from typing import TYPE_CHECKING, ClassVar, Final

import can

from supervisord import strict
from supervisord.errors import ConfigError
from supervisord.outputs.base import (
    Claim,
    DeviceSpec,
    Output,
    OutputFault,
    OutputKind,
    OutputUsageError,
    Periodic,
    ReadBack,
    Resources,
)
from supervisord.safety.config import OutputRole
from supervisord.timebase import NS_PER_MS

if TYPE_CHECKING:
    from typing_extensions import Self

PERIOD_MS_RANGE: Final = (5, 1000)
"""Allowed ``period_ms``."""
MAX_STANDARD_ID: Final = 0x7FF
MAX_EXTENDED_ID: Final = 0x1FFF_FFFF
MAX_DATA: Final = 8  # classic CAN; CAN FD frames are not supported
SEND_TIMEOUT_S: Final = 0.0  # never wait for the transmit queue: a full queue is a fault


HEX_PATTERN: Final = (
    f"^[ \\t\\n\\r\\f\\v:]*(?:[0-9A-Fa-f]{{2}}[ \\t\\n\\r\\f\\v:]*){{0,{MAX_DATA}}}$"
)
"""A payload as hex text: at most 8 bytes of two digits, spaces or colons between them."""


def parse_hex(text: str) -> bytes:
    """Bytes from hex text such as ``"01 00 ff"``, ``"0100ff"`` or ``"01:00:ff"``.

    Raises ``ValueError`` for anything else."""
    return bytes.fromhex(text.replace(":", " "))


def _shift(mask: int) -> int:
    return (mask & -mask).bit_length() - 1


def _contiguous(mask: int) -> bool:
    m = mask >> _shift(mask)
    return m & (m + 1) == 0


CONTIGUOUS_MASKS: Final = tuple(m for m in range(1, 0x100) if _contiguous(m))
"""Every counter mask of contiguous bits within one byte."""


@dataclasses.dataclass(frozen=True, kw_only=True, eq=False)
class HexBytes(strict.Key):
    """A payload written as hex text (:data:`HEX_PATTERN`)."""

    def fits(self, raw: object) -> bool:
        return isinstance(raw, str) and re.fullmatch(HEX_PATTERN, raw) is not None

    def wording(self, raw: object) -> str:
        return f'use at most {MAX_DATA} hex bytes in double quotes, e.g. "01 00 00 00"'

    def type_schema(self) -> dict[str, object]:
        return {"type": "string", "pattern": HEX_PATTERN}


@dataclasses.dataclass(frozen=True, kw_only=True, eq=False)
class CounterMask(strict.Whole):
    """A rolling counter's bits: contiguous, within one byte."""

    def fits(self, raw: object) -> bool:
        return type(raw) is int and raw in CONTIGUOUS_MASKS

    def wording(self, raw: object) -> str:
        return "use contiguous bits within one byte, e.g. 0x0F (15)"

    def type_schema(self) -> dict[str, object]:
        return {"type": "integer", "enum": list(CONTIGUOUS_MASKS)}


ARBITRATION_ID: Final = strict.Whole(
    name="arbitration_id",
    doc="The frame's CAN identifier: 11-bit (up to 0x7FF), or 29-bit with extended = true.",
    low=0,
    high=MAX_EXTENDED_ID,
    example=0x201,
)
EXTENDED: Final = strict.Flag(
    name="extended", doc="The identifier is 29-bit (J1939 style).", default=False, example=False
)
DATA_ON: Final = HexBytes(
    name="data_on", doc="The payload that enables (0 to 8 bytes of hex).", example="01 00"
)
DATA_OFF: Final = HexBytes(
    name="data_off",
    doc="The payload that disables; it must differ from data_on.",
    example="00 00",
)
COUNTER_BYTE: Final = strict.Whole(
    name="counter_byte",
    doc="The index in the payload of a rolling counter, below the payloads' length. "
    "Not set: no counter.",
    low=0,
    high=MAX_DATA - 1,
    default=None,
    example=7,
)
COUNTER_MASK: Final = CounterMask(
    name="counter_mask",
    doc="The counter's bits in that byte: contiguous; the other bits come from the payload.",
    low=1,
    high=0xFF,
    default=0xFF,
    example=0x0F,
)
PERIOD_MS: Final = strict.Whole(
    name="period_ms",
    doc="The frame goes out every this many ms, from the main loop.",
    low=PERIOD_MS_RANGE[0],
    high=PERIOD_MS_RANGE[1],
    default=20,
    example=20,
)


@dataclasses.dataclass(frozen=True, kw_only=True)
class CanEnableSpec(DeviceSpec):
    """Options of a ``kind = "can"`` output (see the module docstring; all validated here)."""

    kind: ClassVar[OutputKind] = OutputKind.CAN
    options: ClassVar[tuple[strict.Key, ...]] = (
        ARBITRATION_ID,
        EXTENDED,
        DATA_ON,
        DATA_OFF,
        COUNTER_BYTE,
        COUNTER_MASK,
        PERIOD_MS,
    )
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
        strict.check_value(ARBITRATION_ID, self.arbitration_id, f"{p}.arbitration_id", ConfigError)
        if not self.extended and self.arbitration_id > MAX_STANDARD_ID:
            raise ConfigError(
                f"{p}.arbitration_id",
                self.arbitration_id,
                f"use a whole number from 0 to {MAX_STANDARD_ID} (0x7ff), or set extended = true",
            )
        for key, data in (("data_on", self.data_on), ("data_off", self.data_off)):
            if len(data) > MAX_DATA:
                raise ConfigError(f"{p}.{key}", data.hex(" "), DATA_ON.wording(data))
        strict.check_value(PERIOD_MS, self.period_ms, f"{p}.period_ms", ConfigError)
        strict.check_value(COUNTER_MASK, self.counter_mask, f"{p}.counter_mask", ConfigError)
        if self.counter_byte is not None:
            strict.check_value(COUNTER_BYTE, self.counter_byte, f"{p}.counter_byte", ConfigError)
        if self.counter_byte is not None:
            shortest = min(len(self.data_on), len(self.data_off))
            if not 0 <= self.counter_byte < shortest:
                raise ConfigError(
                    f"{p}.counter_byte",
                    self.counter_byte,
                    f"use a byte index below {shortest}, the length of data_on and data_off",
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
    def from_options(cls, name: str, role: OutputRole, values: Mapping[str, object]) -> Self:
        """The payloads from hex text to bytes."""
        options = dict(values)
        for key in (DATA_ON.name, DATA_OFF.name):
            options[key] = parse_hex(str(options[key]))
        return cls(name=name, role=role, **options)  # type: ignore[arg-type]

    @classmethod
    def schema_rules(cls) -> tuple[dict[str, object], ...]:
        """An 11-bit identifier unless ``extended = true``."""
        standard = {"not": {"required": ["extended"], "properties": {"extended": {"const": True}}}}
        return (
            {
                "if": standard,
                "then": {"properties": {"arbitration_id": {"maximum": MAX_STANDARD_ID}}},
            },
        )

    def claims(self) -> tuple[Claim, ...]:
        """Its identifier on the CAN outputs' bus (one bus for every CAN output of a robot)."""
        return (
            Claim(
                "arbitration_id",
                self.arbitration_id,
                "id",
                identity=("can", self.arbitration_id, self.extended),
            ),
        )


class CanEnableOutput(Output):
    """Sends the enable frame of ``spec`` on ``bus`` (see the module docstring)."""

    kind: ClassVar[OutputKind] = OutputKind.CAN
    spec_type: ClassVar[type[DeviceSpec]] = CanEnableSpec

    @classmethod
    def build(cls, spec: DeviceSpec, resources: Resources) -> Output:
        """The output on the daemon's CAN bus; refused without one."""
        if resources.can_bus is None:
            raise ConfigError(f"outputs.{spec.name}.kind", "can", "configure a CAN bus for it")
        if not isinstance(spec, CanEnableSpec):
            raise OutputUsageError(f"a can output needs a CanEnableSpec, not {spec!r}")
        return cls(spec, resources.can_bus)

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

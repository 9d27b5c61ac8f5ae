"""A GPIO enable line through the Linux GPIO character device (libgpiod v2 bindings).

- The chip is named by path (``/dev/gpiochip2``), by kernel name (``gpiochip2``) or by label
  (``"pinctrl-bcm2711"``; a label that matches more than one chip is refused). The line is named
  by its name (a string) or its offset (an integer).
- The line is requested as an output whose initial value is *inactive*: the kernel drives it
  off in the same call that grants it, so it is never on before the supervisor says so
  (SR-6). ``active_low`` makes "on" a low level; on/off below are always logical.
- Every write is read back with ``get_value``; a different value is a ``MISMATCH`` and an
  OS error (line released, chip gone) an ``IO_ERROR``. Either becomes ``output_fault:NAME``.
- Optional pulsed enable (``pulse_period_ms``): while on, the line toggles every period from
  :meth:`GpioOutput.tick`, for safety relays that need a living signal; while off it is steady
  off. If the main loop stops calling ``tick``, the pulses stop and such a relay drops out.

Only the daemon's main loop drives the line; this module starts no thread.
"""

from __future__ import annotations

import contextlib
import dataclasses
import glob
import os
import re
from collections.abc import Callable
from typing import ClassVar, Final, Protocol

import gpiod
from gpiod.line import Direction, Value

from supervisord import strict
from supervisord.errors import ConfigError
from supervisord.outputs.base import (
    Claim,
    DeviceSpec,
    Output,
    OutputError,
    OutputFault,
    OutputKind,
    Periodic,
    ReadBack,
)
from supervisord.timebase import NS_PER_MS

PULSE_PERIOD_MS_RANGE = (2, 1000)
"""Allowed ``pulse_period_ms`` (the time between two toggles; the pulse frequency is half its
inverse)."""

_MAX_OFFSET = 65535
KERNEL_CHIP_NAME: Final = re.compile(r"gpiochip[0-9]+")
"""A GPIO chip's kernel name: the device ``/dev/NAME``."""

LINE_NAME_PATTERN: Final = (
    "^(?![0-9]+$)[^\\u0000-\\u001f\\u007f-\\u009f]*[^ \\u0000-\\u001f\\u007f-\\u009f]"
    "[^\\u0000-\\u001f\\u007f-\\u009f]*$"
)
"""A line's name: text as :data:`supervisord.strict.TEXT_PATTERN`, but not only digits (an
offset is written as a number)."""

CHIP: Final = strict.Text(
    name="chip",
    doc='The GPIO chip: a device path ("/dev/gpiochip2"), a kernel name ("gpiochip2") or a '
    "label; a label that matches more than one chip is refused when the line is requested.",
    example="gpiochip0",
)
LINE: Final = strict.Either(
    name="line",
    doc="The line: its name, or its offset on the chip as a number.",
    options=(
        strict.Text(
            name="line",
            doc="",
            pattern=LINE_NAME_PATTERN,
            rule="a line name in double quotes",
            example="MOTOR_EN",
        ),
        strict.Whole(name="line", doc="", low=0, high=_MAX_OFFSET),
    ),
    example=17,
)
ACTIVE_LOW: Final = strict.Flag(
    name="active_low", doc="On is a low level on the wire.", default=False, example=False
)
PULSE_PERIOD_MS: Final = strict.Whole(
    name="pulse_period_ms",
    doc="A pulsed enable: while on, the line toggles every this many ms (for safety relays "
    "that need a living signal). Not set: a steady level.",
    low=PULSE_PERIOD_MS_RANGE[0],
    high=PULSE_PERIOD_MS_RANGE[1],
    default=None,
    example=10,
)


@dataclasses.dataclass(frozen=True, kw_only=True)
class GpioSpec(DeviceSpec):
    """Options of a ``kind = "gpio"`` output.

    ``chip``: path, kernel name or label. ``line``: name (str) or offset (int, 0-65535).
    ``active_low``: on is a low level (default ``False``). ``pulse_period_ms``: toggle period
    of a pulsed enable, 2-1000 ms (default ``None``: a steady level).
    """

    kind: ClassVar[OutputKind] = OutputKind.GPIO
    options: ClassVar[tuple[strict.Key, ...]] = (CHIP, LINE, ACTIVE_LOW, PULSE_PERIOD_MS)
    chip: str
    line: str | int
    active_low: bool = False
    pulse_period_ms: int | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        prefix = f"outputs.{self.name}"
        for key, value in ((CHIP, self.chip), (LINE, self.line)):
            strict.check_value(key, value, f"{prefix}.{key.name}", ConfigError)
        if self.pulse_period_ms is not None:
            strict.check_value(
                PULSE_PERIOD_MS, self.pulse_period_ms, f"{prefix}.pulse_period_ms", ConfigError
            )

    @property
    def consumer(self) -> str:
        """The consumer label the line is requested under (shown by ``gpioinfo``)."""
        return f"srcsd-{self.name}"[:31]

    def claims(self) -> tuple[Claim, ...]:
        """Its line on its chip. What the config alone can tell of a chip (docs/configuration.md
        "One owner per path"): a device path, with symlinks resolved, and a kernel name
        (``gpiochip2``) are the same device (``/dev/gpiochip2``); a label is only known to the
        hardware, so it stays a label, and a line named by name stays a name."""
        if "/" in self.chip:
            chip = ("device", os.path.realpath(self.chip))
        elif KERNEL_CHIP_NAME.fullmatch(self.chip):
            chip = ("device", os.path.realpath(f"/dev/{self.chip}"))
        else:
            chip = ("label", self.chip)
        return (Claim("line", self.line, "line", identity=("gpio", chip, self.line)),)


class LineHandle(Protocol):
    """One requested output line, in logical levels (``True`` = active = on).

    Each method raises ``OSError`` (or a gpiod error) when the kernel refuses."""

    def set(self, active: bool) -> None:
        """Drive the line."""

    def get(self) -> bool:
        """Read the line's value back."""

    def release(self) -> None:
        """Give the line back to the kernel."""


class GpiodLine:
    """A :class:`LineHandle` over a libgpiod v2 line request."""

    def __init__(self, request: gpiod.LineRequest, offset: int) -> None:
        self._request, self._offset = request, offset

    def set(self, active: bool) -> None:
        """Drive the line (logical level)."""
        self._request.set_value(self._offset, Value.ACTIVE if active else Value.INACTIVE)

    def get(self) -> bool:
        """Read the line's value back (logical level)."""
        return self._request.get_value(self._offset) is Value.ACTIVE

    def release(self) -> None:
        """Release the request."""
        self._request.release()


GPIO_ERRORS = (OSError, ValueError, gpiod.RequestReleasedError, gpiod.ChipClosedError)
"""What the gpiod bindings raise when the kernel refuses or the request is gone."""


def find_chip(chip: str) -> str:
    """The device path of ``chip`` (a path, a kernel name like ``gpiochip0``, or a label).

    Raises :class:`LookupError` when no chip, or more than one chip, matches.
    """
    if "/" in chip:
        if not gpiod.is_gpiochip_device(chip):
            raise LookupError(f"{chip} is not a GPIO chip device")
        return chip
    matches = []
    for path in sorted(glob.glob("/dev/gpiochip*")):
        if not gpiod.is_gpiochip_device(path):
            continue
        with gpiod.Chip(path) as c:
            info = c.get_info()
        if chip in (info.name, info.label):
            matches.append(path)
    if len(matches) != 1:
        found = "no chip" if not matches else f"{len(matches)} chips ({', '.join(matches)})"
        raise LookupError(f"{found} named or labelled {chip!r}")
    return matches[0]


def request_line(spec: GpioSpec) -> LineHandle:
    """Request ``spec``'s line as an output that starts inactive (off).

    Raises :class:`LookupError` for an unknown chip or line, the gpiod errors for a refusal
    (line busy, no permission)."""
    path = find_chip(spec.chip)
    with gpiod.Chip(path) as chip:
        try:
            offset = chip.line_offset_from_id(spec.line)
        except (OSError, ValueError) as e:
            raise LookupError(f"no line {spec.line!r} on {path}: {e}") from e
        settings = gpiod.LineSettings(
            direction=Direction.OUTPUT, output_value=Value.INACTIVE, active_low=spec.active_low
        )
        request = chip.request_lines(config={offset: settings}, consumer=spec.consumer)
    return GpiodLine(request, offset)


class GpioOutput(Output):
    """A GPIO enable line (see the module docstring).

    ``opener`` requests the line; it defaults to :func:`request_line` (the real chip). Tests of
    the pulse logic on a machine without a chip may pass another :class:`LineHandle` maker.
    """

    kind: ClassVar[OutputKind] = OutputKind.GPIO
    spec_type: ClassVar[type[DeviceSpec]] = GpioSpec

    def __init__(
        self, spec: GpioSpec, opener: Callable[[GpioSpec], LineHandle] = request_line
    ) -> None:
        super().__init__(spec)
        self.spec = spec
        self._opener = opener
        self._line: LineHandle | None = None
        self._pulse = Periodic(spec.pulse_period_ms * NS_PER_MS) if spec.pulse_period_ms else None
        self._phase = False  # the level driven in the current pulse phase

    def _open(self, now: int) -> ReadBack:
        try:
            self._line = self._opener(self.spec)
        except (LookupError, *GPIO_ERRORS) as e:
            raise OutputError(self.name, f"cannot request GPIO line: {e}") from e
        return self._drive(False, False, write=False)

    def _write(self, on: bool, now: int) -> ReadBack:
        if self._pulse is None:
            return self._drive(on, on)
        if not on:
            self._pulse.stop()
            self._phase = False
            return self._drive(False, False)
        if self._pulse.deadline is None:  # off -> on: start a pulse train, high first
            self._phase = True
            self._pulse.start(now)
        # Already pulsing: re-assert the current phase without restarting the train, so a loop
        # that re-asserts "on" often does not stop the pulses.
        return self._drive(True, self._phase)

    def tick(self, now: int) -> ReadBack | None:
        """Toggle a pulsed enable when its edge is due (see :meth:`Output.tick`)."""
        super().tick(now)
        if self._pulse is None or not self._pulse.due(now):
            return None
        self._pulse.advance(now)
        self._phase = not self._phase
        return self._drive(True, self._phase)

    def next_deadline(self) -> int | None:
        """The next pulse edge, or ``None`` when not pulsing (steady line, off, or closed)."""
        if self._pulse is None or not self.is_open:
            return None
        return self._pulse.deadline

    def _close(self) -> ReadBack:
        if self._pulse is not None:
            self._pulse.stop()
        self._phase = False
        result = self._drive(False, False)
        line, self._line = self._line, None
        if line is not None:
            # A request already gone has given the line back to the kernel either way.
            with contextlib.suppress(*GPIO_ERRORS):
                line.release()
        return result

    def _drive(self, requested: bool, level: bool, *, write: bool = True) -> ReadBack:
        """Write ``level`` (unless ``write`` is false) and read it back."""
        assert self._line is not None
        try:
            if write:
                self._line.set(level)
            observed = self._line.get()
        except GPIO_ERRORS as e:
            return ReadBack(self.name, requested, level, None, OutputFault.IO_ERROR, str(e))
        if observed != level:
            return ReadBack(self.name, requested, level, observed, OutputFault.MISMATCH)
        return ReadBack(self.name, requested, level, observed)

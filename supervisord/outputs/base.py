"""The output interface: what every enable-line driver promises, and what every kind's spec
declares (its options, what it holds exclusively). The registry of kinds is
:mod:`supervisord.outputs.registry`.

An output gates one enable line of a motion controller (``docs/outputs.md``). The rules it
serves are SR-6:

- it is requested in the **off** state before anything else happens (:meth:`Output.open`);
- it is set off first on every stop, so :meth:`Output.set` is fast and synchronous, and it
  *reads back* what it wrote: a mismatch or an OS error comes back as a :class:`ReadBack` with
  a :class:`OutputFault`, which the daemon turns into the stop cause ``output_fault:NAME``;
- periodic duties (a CAN enable frame every period, a pulsed GPIO enable) run only when the
  daemon's main loop calls :meth:`Output.tick` at :meth:`Output.next_deadline`. An output owns
  no thread and no timer: if the loop hangs, the living signal stops.

Time is an argument: ``now`` is the daemon's monotonic clock in integer nanoseconds. Outputs
never read a clock themselves.

Kinds are plugins picked by name (``"sim"``, ``"gpio"``, ``"can"``) in the registry, which
imports a kind's module only when that kind is chosen, so a robot without GPIO never imports
``gpiod`` and one without CAN never imports ``can``. This module imports no plugin.
"""

from __future__ import annotations

import abc
import dataclasses
from collections.abc import Hashable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, ClassVar

from supervisord import strict
from supervisord.compat import StrEnum
from supervisord.errors import SrcsError
from supervisord.safety.config import OutputRole, OutputSpec  # one vocabulary with the core
from supervisord.timebase import next_due

if TYPE_CHECKING:
    from can import BusABC
    from typing_extensions import Self


class OutputKind(StrEnum):
    """The output plugins, by the name the config uses in ``kind = ...``."""

    SIM = "sim"
    GPIO = "gpio"
    CAN = "can"


class OutputFault(StrEnum):
    """Why a write did not leave the output where it was asked to be (SR-6)."""

    MISMATCH = "mismatch"
    """The level read back differs from the level written."""
    IO_ERROR = "io_error"
    """The operating system refused the write or the read-back (line released, file gone...)."""
    SEND_ERROR = "send_error"
    """A CAN enable frame could not be queued on the bus (bus closed, transmit buffer full)."""


@dataclasses.dataclass(frozen=True)
class ReadBack:
    """The outcome of one write to an output, checked by reading back.

    ``requested`` is the state the supervisor asked for; ``written`` the level actually driven
    by this write (it differs from ``requested`` only in the low phase of a pulsed enable);
    ``observed`` the level read back, or ``None`` for a kind that cannot read back (CAN, where
    a frame accepted by the bus is the read-back). ``fault`` is ``None`` when the write is
    verified; otherwise the daemon raises ``output_fault:NAME``.
    """

    name: str
    requested: bool
    written: bool
    observed: bool | None
    fault: OutputFault | None = None
    detail: str = ""

    def __post_init__(self) -> None:
        if self.fault is None and self.observed is not None and self.observed != self.written:
            raise ValueError("a read-back that differs from the written level is a MISMATCH")
        if self.fault is OutputFault.MISMATCH and (
            self.observed is None or self.observed == self.written
        ):
            raise ValueError("MISMATCH needs an observed level that differs from the written one")

    @property
    def ok(self) -> bool:
        """True when the write is verified."""
        return self.fault is None

    def details(self) -> dict[str, object]:
        """The read-back as plain JSON values, for a stop record's cause details."""
        return {
            "output": self.name,
            "requested": self.requested,
            "written": self.written,
            "observed": self.observed,
            "fault": None if self.fault is None else self.fault.value,
            "detail": self.detail,
        }


class OutputError(SrcsError):
    """An output could not be acquired at all (no such chip or line, line busy, file not
    writable). Raised only by :meth:`Output.open`; nothing is driven. The daemon treats it as
    ``output_fault:NAME``."""

    def __init__(self, name: str, detail: str) -> None:
        self.name, self.detail = name, detail
        super().__init__(f"output {name!r}: {detail}")


class OutputUsageError(SrcsError, RuntimeError):
    """Our own code used an output out of order (``set`` before ``open`` or after ``close``).
    Nothing was driven."""


# ---------------------------------------------------------------------------------------------
# Specs: each kind's declared options, what it holds exclusively


@dataclasses.dataclass(frozen=True)
class Claim:
    """Something an output holds exclusively (SR-11.1, docs/configuration.md "One owner per
    path"): no two outputs may hold the same device, and a file no other key of the config.

    ``option`` is the spec's option that names it (``line``, ``arbitration_id``, ``path``) and
    ``value`` its value as written, for the message; ``what`` is how the fix names it ("line",
    "id"). A device is compared by ``identity`` (a hashable value); a file by ``path``, with
    every other path of the config once symlinks are resolved.
    """

    option: str
    value: object
    what: str
    identity: Hashable = None
    path: Path | None = None


@dataclasses.dataclass(frozen=True, kw_only=True)
class DeviceSpec(OutputSpec):
    """An output the daemon drives: its name and role (what the safety core knows of it,
    :class:`~supervisord.safety.config.OutputSpec`) and its kind's own validated options.

    Every kind declares its options the same way: :attr:`options`, the keys of its config
    table as :class:`~supervisord.strict.Key` (type, default, range, documentation: the
    single source of the loader and of the JSON Schema), :meth:`from_options` to build the
    spec from the values read, and :meth:`claims`, what it holds exclusively.
    """

    kind: ClassVar[OutputKind]
    options: ClassVar[tuple[strict.Key, ...]]

    @classmethod
    def from_options(cls, name: str, role: OutputRole, values: Mapping[str, object]) -> Self:
        """The spec of output ``name`` from its options' values, as read by :attr:`options`
        (a kind that converts a value, such as hex text to bytes, overrides this)."""
        return cls(name=name, role=role, **values)  # type: ignore[arg-type]

    @classmethod
    def schema_rules(cls) -> tuple[dict[str, object], ...]:
        """JSON Schema rules between this kind's options (e.g. a CAN id's range that depends
        on ``extended``), for the config's published schema; none unless the kind says so."""
        return ()

    def claims(self) -> tuple[Claim, ...]:
        """What this output holds exclusively (nothing, unless the kind says so)."""
        return ()

    def resolved(self, base: Path) -> Self:
        """This spec with its relative file paths resolved against ``base`` (the config
        file's directory); a kind without files returns itself."""
        return self


@dataclasses.dataclass(frozen=True)
class Resources:
    """What the daemon lends an output to drive it: ``can_bus``, the python-can bus a
    ``can`` output sends on (the daemon owns and closes it)."""

    can_bus: BusABC | None = None


# ---------------------------------------------------------------------------------------------
# The output interface


class Periodic:
    """A deadline that repeats every ``period_ns``, for outputs' periodic duties.

    After a duty at ``now``, the next deadline is one period after the previous one; if the
    loop was late by a whole period or more, it restarts from ``now`` instead of bursting to
    catch up (a burst of enable frames would not make a late loop any safer).
    """

    def __init__(self, period_ns: int) -> None:
        if period_ns <= 0:
            raise ValueError("period must be positive")
        self.period_ns = period_ns
        self.deadline: int | None = None

    def start(self, now: int) -> None:
        """Arm: the next duty is one period after ``now``."""
        self.deadline = now + self.period_ns

    def stop(self) -> None:
        """Disarm: no duty is due."""
        self.deadline = None

    def due(self, now: int) -> bool:
        """Whether a duty is due at ``now``."""
        return self.deadline is not None and now >= self.deadline

    def advance(self, now: int) -> None:
        """Schedule the next duty after the one performed at ``now``."""
        assert self.deadline is not None
        self.deadline = next_due(self.deadline, now, self.period_ns)


class Output(abc.ABC):
    """One enable line. Subclasses implement the ``_open``/``_write``/``_close`` hooks; this
    class enforces the life cycle: ``open`` once, then ``set``/``tick`` any number of times,
    then ``close`` (idempotent). Out-of-order calls raise :class:`OutputUsageError`.

    Not thread-safe: only the daemon's main loop calls an output.
    """

    kind: ClassVar[OutputKind]
    spec_type: ClassVar[type[DeviceSpec]]

    @classmethod
    def build(cls, spec: DeviceSpec, resources: Resources) -> Output:
        """A new, not yet open output for ``spec`` with what it needs from ``resources``: how
        the registry builds every kind. Raises :class:`ConfigError` when a resource the kind
        needs is missing, :class:`OutputUsageError` for another kind's spec."""
        return cls(spec)

    def __init__(self, spec: DeviceSpec) -> None:
        if spec.kind is not self.kind:
            raise OutputUsageError(f"{type(self).__name__} cannot drive a {spec.kind} spec")
        self._spec = spec
        self._opened = False
        self._closed = False
        self._requested = False

    @property
    def name(self) -> str:
        """The output's configured name."""
        return self._spec.name

    @property
    def role(self) -> OutputRole:
        """Motion or power (SR-1)."""
        return self._spec.role

    @property
    def is_open(self) -> bool:
        """True between a successful :meth:`open` and :meth:`close`."""
        return self._opened and not self._closed

    @property
    def requested(self) -> bool:
        """The state last asked for by :meth:`set` (``False`` before open and after close)."""
        return self._requested

    def open(self, now: int) -> ReadBack:
        """Acquire the line in the **off** state, before it could ever be driven on, and read
        the off state back. Raises :class:`OutputError` when the line cannot be acquired at all
        (nothing is then held); a line acquired but not reading back off is returned as a
        faulty :class:`ReadBack` and stays open, so that :meth:`close` can release it.
        """
        if self._opened:
            raise OutputUsageError(f"output {self.name!r} is already open (or closed)")
        result = self._open(now)
        self._opened = True
        self._requested = False
        return result

    def set(self, on: bool, now: int) -> ReadBack:
        """Drive the output on or off at once and read it back. Fast and synchronous: this is
        the first thing the daemon does on a stop. Never raises for a device fault: the fault
        is in the returned :class:`ReadBack`. Setting the level it already has writes again
        and reads back again (a stop re-asserts off)."""
        self._check_open("set")
        self._requested = on
        return self._write(on, now)

    def tick(self, now: int) -> ReadBack | None:
        """Perform the periodic duty due at ``now`` (an enable frame, a pulse edge), if any.
        Returns its read-back, or ``None`` when nothing was due. Calling it early, or often,
        is harmless."""
        self._check_open("tick")
        return None

    def next_deadline(self) -> int | None:
        """When :meth:`tick` next has a duty (monotonic ns), or ``None`` when it has none
        (closed, or a kind with no periodic duty in its current state)."""
        return None

    def close(self) -> ReadBack | None:
        """Drive off, read back, release the line. Idempotent; after it the output cannot be
        used again. Returns the off read-back, or ``None`` if the output was never open or was
        already closed. Never raises for a device fault."""
        if not self.is_open:
            self._closed = True
            return None
        self._requested = False
        try:
            return self._close()
        finally:
            self._closed = True

    def _check_open(self, what: str) -> None:
        if not self.is_open:
            state = "closed" if self._closed else "not open yet"
            raise OutputUsageError(f"{what} on output {self.name!r}, which is {state}")

    @abc.abstractmethod
    def _open(self, now: int) -> ReadBack:
        """Acquire the line off; raise :class:`OutputError` if it cannot be acquired."""

    @abc.abstractmethod
    def _write(self, on: bool, now: int) -> ReadBack:
        """Drive ``on`` and read back."""

    @abc.abstractmethod
    def _close(self) -> ReadBack:
        """Drive off, read back, release."""

    def __repr__(self) -> str:
        state = "open" if self.is_open else ("closed" if self._closed else "new")
        return f"<{type(self).__name__} {self.name!r} {state} requested={self._requested}>"

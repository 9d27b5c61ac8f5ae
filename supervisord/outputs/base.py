"""The output interface: what every enable-line driver promises, and the registry of kinds.

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

Kinds are plugins picked by name (``"sim"``, ``"gpio"``, ``"can"``); :func:`output_class`
imports a kind's module only when that kind is chosen, so a robot without GPIO never imports
``gpiod`` and one without CAN never imports ``can``.
"""

from __future__ import annotations

import abc
import dataclasses
import importlib
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, ClassVar, Final, Self, TypeVar

from supervisord.compat import StrEnum
from supervisord.errors import ConfigError, SrcsError
from supervisord.safety.config import NAME_PATTERN, OutputRole  # one vocabulary with the core

if TYPE_CHECKING:
    from can import BusABC

NS_PER_MS: Final = 1_000_000

_E = TypeVar("_E", bound=StrEnum)


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
# Specs and their validation


class ConfigTable:
    """Reads one output's config table, raising :class:`ConfigError` that names the full key.

    Every key must be consumed: :meth:`finish` rejects unknown keys, because a misspelt option
    in a safety config must not be silently ignored.
    """

    def __init__(self, prefix: str, table: Mapping[str, object]) -> None:
        self.prefix = prefix
        self._table = table
        self._seen: set[str] = set()

    def key(self, key: str) -> str:
        """The full dotted name of ``key``, as error messages show it."""
        return f"{self.prefix}.{key}"

    def has(self, key: str) -> bool:
        """Whether the table sets ``key``."""
        return key in self._table

    def raw(self, key: str) -> object:
        """The value of ``key`` as given (``None`` when absent), marking it consumed."""
        self._seen.add(key)
        return self._table.get(key)

    def string(self, key: str, default: str | None = None) -> str:
        """A non-empty string; absent means ``default`` (absent and no default is an error)."""
        value = self.raw(key)
        if value is None and default is not None:
            return default
        if not isinstance(value, str) or not value:
            raise ConfigError(self.key(key), value, "give a non-empty string")
        return value

    def integer(self, key: str, default: int | None, low: int, high: int) -> int:
        """An integer in ``[low, high]``; absent means ``default``."""
        value = self.raw(key)
        if value is None and default is not None:
            return default
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
            raise ConfigError(self.key(key), value, f"give an integer from {low} to {high}")
        return value

    def optional_integer(self, key: str, low: int, high: int) -> int | None:
        """An integer in ``[low, high]``, or ``None`` when the key is absent."""
        if not self.has(key):
            self._seen.add(key)
            return None
        return self.integer(key, None, low, high)

    def boolean(self, key: str, default: bool) -> bool:
        """``true`` or ``false``; absent means ``default``."""
        value = self.raw(key)
        if value is None:
            return default
        if not isinstance(value, bool):
            raise ConfigError(self.key(key), value, "give true or false")
        return value

    def choice(self, key: str, enum_type: type[_E], default: _E | None) -> _E:
        """One of ``enum_type``'s values; absent means ``default``."""
        value = self.raw(key)
        if value is None and default is not None:
            return default
        allowed = ", ".join(repr(m.value) for m in enum_type)
        if not isinstance(value, str):
            raise ConfigError(self.key(key), value, f"give one of {allowed}")
        try:
            return enum_type(value)
        except ValueError:
            raise ConfigError(self.key(key), value, f"give one of {allowed}") from None

    def finish(self) -> None:
        """Reject any key that no reader consumed."""
        unknown = sorted(set(self._table) - self._seen)
        if unknown:
            raise ConfigError(self.key(unknown[0]), self._table[unknown[0]], "unknown option")


@dataclasses.dataclass(frozen=True, kw_only=True)
class OutputSpec:
    """What every output kind's spec has: the output's ``name`` (used in ``output_fault:NAME``)
    and its ``role``. Each kind subclasses it with its own validated options."""

    kind: ClassVar[OutputKind]
    name: str
    role: OutputRole = OutputRole.MOTION

    def __post_init__(self) -> None:
        if NAME_PATTERN.fullmatch(self.name) is None:
            raise ConfigError(
                "outputs",
                self.name,
                "name outputs with 1-32 letters, digits, '_', '.' or '-' (as clients)",
            )

    @classmethod
    def from_table(cls, name: str, table: Mapping[str, object], prefix: str = "") -> Self:
        """Build and validate a spec from one config table (``[outputs.NAME]``).

        ``kind`` and ``role`` are read here, the kind's own options by :meth:`_read`; unknown
        keys are rejected. Raises :class:`ConfigError` naming ``prefix.key`` (default
        ``outputs.NAME``).
        """
        t = ConfigTable(prefix or f"outputs.{name}", table)
        kind = t.choice("kind", OutputKind, None)
        if kind is not cls.kind:
            raise ConfigError(t.key("kind"), kind.value, f"this spec reads kind {cls.kind.value!r}")
        role = t.choice("role", OutputRole, OutputRole.MOTION)
        options = cls._read(t)
        t.finish()
        try:
            return cls(name=name, role=role, **options)
        except ConfigError as e:  # the spec's own checks name outputs.NAME.key: use the prefix
            default = f"outputs.{name}."
            if e.key.startswith(default):
                raise ConfigError(t.key(e.key.removeprefix(default)), e.value, e.fix) from None
            raise

    @classmethod
    @abc.abstractmethod
    def _read(cls, t: ConfigTable) -> dict[str, Any]:
        """The kind's own options from ``t``, as keyword arguments of the spec."""


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
        following = self.deadline + self.period_ns
        self.deadline = following if following > now else now + self.period_ns


class Output(abc.ABC):
    """One enable line. Subclasses implement the ``_open``/``_write``/``_close`` hooks; this
    class enforces the life cycle: ``open`` once, then ``set``/``tick`` any number of times,
    then ``close`` (idempotent). Out-of-order calls raise :class:`OutputUsageError`.

    Not thread-safe: only the daemon's main loop calls an output.
    """

    kind: ClassVar[OutputKind]
    spec_type: ClassVar[type[OutputSpec]]

    def __init__(self, spec: OutputSpec) -> None:
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


# ---------------------------------------------------------------------------------------------
# The registry

_MODULES: Final[Mapping[OutputKind, tuple[str, str]]] = {
    OutputKind.SIM: ("supervisord.outputs.sim", "SimOutput"),
    OutputKind.GPIO: ("supervisord.outputs.gpio", "GpioOutput"),
    OutputKind.CAN: ("supervisord.outputs.can_enable", "CanEnableOutput"),
}


def output_class(kind: OutputKind | str) -> type[Output]:
    """The output class for ``kind``, importing its module now (and only now).

    Raises :class:`ConfigError` for an unknown kind.
    """
    try:
        kind = OutputKind(kind)
    except ValueError:
        allowed = ", ".join(repr(k.value) for k in OutputKind)
        raise ConfigError("kind", kind, f"give one of {allowed}") from None
    module_name, class_name = _MODULES[kind]
    cls = getattr(importlib.import_module(module_name), class_name)
    assert isinstance(cls, type)
    assert issubclass(cls, Output)
    return cls


def spec_class(kind: OutputKind | str) -> type[OutputSpec]:
    """The spec class for ``kind`` (importing its module, as :func:`output_class` does)."""
    return output_class(kind).spec_type


def parse_output_spec(name: str, table: Mapping[str, object], prefix: str = "") -> OutputSpec:
    """Validate one ``[outputs.NAME]`` table into the spec of its ``kind``.

    Raises :class:`ConfigError` naming the key (``outputs.NAME.key`` unless ``prefix`` says
    otherwise) for a missing or unknown kind, a bad value or an unknown option.
    """
    prefix = prefix or f"outputs.{name}"
    kind = table.get("kind")
    if not isinstance(kind, str) or kind not in {k.value for k in OutputKind}:
        allowed = ", ".join(repr(k.value) for k in OutputKind)
        raise ConfigError(f"{prefix}.kind", kind, f"give one of {allowed}")
    return spec_class(kind).from_table(name, table, prefix)


def create_output(spec: OutputSpec, *, can_bus: BusABC | None = None) -> Output:
    """A new, not yet open output for ``spec``.

    ``can_bus`` is the python-can bus a ``can`` output sends on; the daemon owns and closes
    it. Raises :class:`ConfigError` when a ``can`` output gets no bus.
    """
    if spec.kind is OutputKind.CAN:
        if can_bus is None:
            raise ConfigError(f"outputs.{spec.name}.kind", "can", "configure a CAN bus for it")
        # Imported here, not at the top: a plugin is imported only when chosen.
        from supervisord.outputs.can_enable import CanEnableOutput, CanEnableSpec  # noqa: PLC0415

        if not isinstance(spec, CanEnableSpec):
            raise OutputUsageError(f"a can output needs a CanEnableSpec, not {spec!r}")
        return CanEnableOutput(spec, can_bus)
    return output_class(spec.kind)(spec)

"""The registry of output kinds: a kind's name to its spec and its output class.

Every kind is a plugin module holding a :class:`~supervisord.outputs.base.DeviceSpec`
subclass (its declared options, what it holds exclusively) and an
:class:`~supervisord.outputs.base.Output` subclass (built by ``Output.build`` from the spec
and the :class:`~supervisord.outputs.base.Resources` the daemon lends). The registry imports a
kind's module only when that kind is chosen (:func:`output_class`), so a robot without GPIO
never imports ``gpiod`` and one without CAN never imports ``can``; no plugin imports the
registry, and the base class knows no plugin.
"""

from __future__ import annotations

import dataclasses
import importlib
from collections.abc import Mapping
from typing import TYPE_CHECKING, Final

from supervisord import strict
from supervisord.errors import ConfigError
from supervisord.outputs.base import DeviceSpec, Output, OutputKind, Resources
from supervisord.safety.config import OFF_DELAY_RANGE_MS, OutputRole

if TYPE_CHECKING:
    from can import BusABC

PLUGINS: Final[Mapping[OutputKind, tuple[str, str]]] = {
    OutputKind.SIM: ("supervisord.outputs.sim", "SimOutput"),
    OutputKind.GPIO: ("supervisord.outputs.gpio", "GpioOutput"),
    OutputKind.CAN: ("supervisord.outputs.can_enable", "CanEnableOutput"),
}
"""Each kind's module and output class (its spec is the class's ``spec_type``)."""

KIND: Final = strict.Choice(
    name="kind",
    doc="The output plugin that drives the line (docs/outputs.md).",
    values={
        OutputKind.SIM.value: "simulated",
        OutputKind.GPIO.value: "a GPIO line",
        OutputKind.CAN.value: "a CAN enable frame",
    },
    example="gpio",
)
ROLE: Final = strict.Choice(
    name="role",
    doc='What the output enables (SR-1.2): "motion" is on only in RUN, "power" in HOLD and RUN.',
    values={role.value: "" for role in OutputRole},
    default=OutputRole.MOTION.value,
    example="motion",
)

OFF_DELAY: Final = strict.Whole(
    name="off_delay_ms",
    doc="A power output's stop category (SR-1.4): 0 switches it off at once with every stop; "
    "more keeps it on that long after the motion outputs went off, so that drives brake under "
    "power (category 1).",
    default=0,
    example=500,
    low=OFF_DELAY_RANGE_MS[0],
    high=OFF_DELAY_RANGE_MS[1],
)


def output_class(kind: OutputKind | str) -> type[Output]:
    """The output class for ``kind``, importing its module now (and only now).

    Raises :class:`ConfigError` for an unknown kind.
    """
    checked = KIND.read(kind.value if isinstance(kind, OutputKind) else kind, "kind", ConfigError)
    module_name, class_name = PLUGINS[OutputKind(checked)]
    cls = getattr(importlib.import_module(module_name), class_name)
    assert isinstance(cls, type)
    assert issubclass(cls, Output)
    return cls


def spec_class(kind: OutputKind | str) -> type[DeviceSpec]:
    """The spec class for ``kind`` (importing its module, as :func:`output_class` does)."""
    return output_class(kind).spec_type


def option_names(kind: OutputKind | str) -> tuple[str, ...]:
    """Every key an output table of ``kind`` may hold."""
    return (
        "name",
        KIND.name,
        ROLE.name,
        OFF_DELAY.name,
        *(key.name for key in spec_class(kind).options),
    )


def read_spec(name: str, fields: strict.Fields) -> DeviceSpec:
    """The spec of output ``name`` from its table's ``fields`` (``kind``, ``role`` and the
    kind's options; a key no one reads is refused). Raises the fields' error naming the key.
    The caller has read ``name`` (or given it from elsewhere)."""
    fields.used.setdefault("name", None)
    kind = OutputKind(str(fields.read(KIND)))
    cls = spec_class(kind)
    role = OutputRole(str(fields.read(ROLE)))
    off_delay = fields.whole(OFF_DELAY)
    values = {key.name: fields.read(key) for key in cls.options}
    fields.finish()
    try:
        spec = cls.from_options(name, role, values)
        return dataclasses.replace(spec, off_delay_ms=off_delay) if off_delay else spec
    except ConfigError as error:  # the spec names outputs.NAME.key: name the table's key
        default = f"outputs.{name}."
        if error.key.startswith(default):
            key = fields.key(error.key.removeprefix(default))
            raise ConfigError(key, error.value, error.fix) from None
        raise


def parse_output_spec(name: str, table: Mapping[str, object], prefix: str = "") -> DeviceSpec:
    """Validate one output's table (``kind`` and its options, without ``name``) into the spec
    of its kind. Raises :class:`ConfigError` naming the key (``outputs.NAME.key`` unless
    ``prefix`` says otherwise) for a missing or unknown kind, a bad value or an unknown key.
    """
    fields = strict.Fields(
        {k: v for k, v in table.items() if k != "name"},
        prefix or f"outputs.{name}",
        error=ConfigError,
    )
    return read_spec(name, fields)


def create_output(spec: DeviceSpec, *, can_bus: BusABC | None = None) -> Output:
    """A new, not yet open output for ``spec``, built by its kind as every kind is.

    ``can_bus`` is the python-can bus a ``can`` output sends on; the daemon owns and closes
    it. Raises :class:`ConfigError` when the kind needs a resource it is not given.
    """
    return output_class(spec.kind).build(spec, Resources(can_bus=can_bus))

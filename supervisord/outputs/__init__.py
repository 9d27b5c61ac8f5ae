"""Outputs: the enable lines of the motion controllers (SR-6, ``docs/outputs.md``).

This package imports no plugin: ``sim``, ``gpio`` (``gpiod``) and ``can`` (``python-can``) are
imported by the registry (:func:`output_class`) only when a config names them.
"""

from supervisord.outputs.base import (
    Claim,
    DeviceSpec,
    Output,
    OutputError,
    OutputFault,
    OutputKind,
    OutputUsageError,
    Periodic,
    ReadBack,
    Resources,
)
from supervisord.outputs.registry import (
    create_output,
    option_names,
    output_class,
    parse_output_spec,
    read_spec,
    spec_class,
)
from supervisord.safety.config import OutputRole, OutputSpec

__all__ = [
    "Claim",
    "DeviceSpec",
    "Output",
    "OutputError",
    "OutputFault",
    "OutputKind",
    "OutputRole",
    "OutputSpec",
    "OutputUsageError",
    "Periodic",
    "ReadBack",
    "Resources",
    "create_output",
    "option_names",
    "output_class",
    "parse_output_spec",
    "read_spec",
    "spec_class",
]

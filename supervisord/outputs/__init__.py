"""Outputs: the enable lines of the motion controllers (SR-6, ``docs/outputs.md``).

This package imports no plugin: ``sim``, ``gpio`` (``gpiod``) and ``can`` (``python-can``) are
imported by :func:`output_class` only when a config names them.
"""

from supervisord.outputs.base import (
    NS_PER_MS,
    ConfigTable,
    Output,
    OutputError,
    OutputFault,
    OutputKind,
    OutputSpec,
    OutputUsageError,
    Periodic,
    ReadBack,
    create_output,
    output_class,
    parse_output_spec,
    spec_class,
)
from supervisord.safety.config import OutputRole

__all__ = [
    "NS_PER_MS",
    "ConfigTable",
    "Output",
    "OutputError",
    "OutputFault",
    "OutputKind",
    "OutputRole",
    "OutputSpec",
    "OutputUsageError",
    "Periodic",
    "ReadBack",
    "create_output",
    "output_class",
    "parse_output_spec",
    "spec_class",
]

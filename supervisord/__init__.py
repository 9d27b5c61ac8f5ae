"""SRCS safety supervisor: protocol codecs, safety core, daemon, simulator and tools."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__: str = version("srcs-supervisord")
    """The installed distribution's version: in ``--version``, the start log line,
    ``status`` and the first record of every start (docs/record.md)."""
except PackageNotFoundError:  # run from a source tree that was never installed
    __version__ = "0+unknown"

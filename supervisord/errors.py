"""The one tree of errors this package raises on purpose.

A peer's bad bytes are never an exception: decoders turn them into ``Rejection`` events that
the safety logic reacts to. Exceptions are for our own side's mistakes, and each class says
whose mistake it is.
"""

from __future__ import annotations

from supervisord.strict import Invalid


class SrcsError(Exception):
    """Base of every error raised on purpose by this package."""


class UnsafeCommandError(SrcsError, ValueError):
    """Our own code asked to send something the protocol requirements forbid (e.g. switching
    off the VSC heartbeat, PR-2.11). Nothing was sent."""


class ConfigError(SrcsError, Invalid):
    """A configuration value is missing, of the wrong kind or out of range.

    The message names the file (when known), the key, the value (shown bounded, see
    :func:`supervisord.strict.shown`) and the fix; the daemon prints it and refuses to start.
    The one strict reader (``supervisord.strict``) raises it for configuration tables.
    """

    def __init__(self, key: str, value: object, fix: str, file: str | None = None) -> None:
        self.file = file
        super().__init__(key, value, fix, where=f"{file}: " if file else "")

    def in_file(self, file: str) -> ConfigError:
        """The same error, naming ``file``."""
        return ConfigError(self.key, self.value, self.fix, file)

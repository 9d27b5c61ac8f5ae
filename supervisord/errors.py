"""The one tree of errors this package raises on purpose.

A peer's bad bytes are never an exception: decoders turn them into ``Rejection`` events that
the safety logic reacts to. Exceptions are for our own side's mistakes, and each class says
whose mistake it is.
"""

from __future__ import annotations


class SrcsError(Exception):
    """Base of every error raised on purpose by this package."""


class UnsafeCommandError(SrcsError, ValueError):
    """Our own code asked to send something the protocol notes forbid (e.g. switching off the
    VSC heartbeat, notes §2 "Other messages"). Nothing was sent."""

"""Broken implementations planted to show that the kit's conformance suites fail them: a
suite that passes everything proves nothing (tests/testkit/test_suites_catch_planted.py)."""

from __future__ import annotations

from supervisord.links.base import Incoming
from supervisord.links.memory_link import MemoryLink
from supervisord.outputs import ReadBack
from supervisord.outputs.sim import SimOutput


class RaisingLink(MemoryLink):
    """A link whose decoder raises on a byte that starts no frame, as a hand-written decoder
    that indexes a table with what arrived would: an exception into the daemon's loop."""

    def receive(self) -> list[Incoming]:
        if b"\xff\xff" in self._port.to_host:
            raise ValueError("no frame starts with 0xff")
        return super().receive()


class OffDoesNothingOutput(SimOutput):
    """An output whose release reports a verified off and leaves the line as it was."""

    def _close(self) -> ReadBack:
        return ReadBack(self.name, False, False, False)


class SilentFaultOutput(SimOutput):
    """An output that reports every write verified without reading the line back."""

    def _write(self, on: bool, now: int) -> ReadBack:
        super()._write(on, now)
        return ReadBack(self.name, on, on, on)

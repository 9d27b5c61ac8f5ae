"""The outputs' conformance suite (``supervisord.testkit.output_conformance``, the one the
kit ships to integrators), run against every output kind the project ships that this machine
can run (SR-6; tests/outputs/conftest.py)."""

from __future__ import annotations

from supervisord.testkit.output_conformance import OutputConformance


class TestEveryOutput(OutputConformance):
    """Every check of the suite, for each harness of ``conftest.KINDS`` (the ``harness``
    fixture: sim in memory and mirrored to a file, CAN on a virtual bus, gpio on gpio-sim)."""

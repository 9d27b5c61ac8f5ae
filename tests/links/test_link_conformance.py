"""The links' conformance suite (``supervisord.testkit.link_conformance``, the one the kit
ships to integrators), run against every link kind the project ships, each on a real medium
(tests/links/conftest.py; docs/protocol.md "Links")."""

from __future__ import annotations

from supervisord.testkit.link_conformance import LinkConformance


class TestEveryLink(LinkConformance):
    """Every check of the suite, for each harness of ``conftest.KINDS`` (the ``harness``
    fixture: serial and HID on pseudo-terminals, CAN on a virtual bus, the memory link)."""

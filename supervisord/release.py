"""What a client's ``release`` ends: its own e-stop or its own hold (SR-2, SR-3).

One vocabulary of the client API (:class:`supervisord.api.ops.Release` carries it) and the
safety core (:class:`supervisord.safety.events.ClientRelease`), in a module of its own so that
the client library names it without loading the safety core (docs/ros2.md "The client
library"). Pure: the core imports it (``tests/safety/test_purity.py``).
"""

from __future__ import annotations

import enum


class Request(enum.Enum):
    """What a client's release ends."""

    ESTOP = "estop"
    HOLD = "hold"

"""``srcsctl status``'s human form says a daemon that runs without its memory lock (SR-9.6),
from the ``status`` reply's ``daemon.memory_locked``."""

from __future__ import annotations

import dataclasses

from supervisord.cli.control import MEMORY_NOT_LOCKED, format_status
from tests.api.samples import LOOP, status_reply


def test_an_unlocked_daemon_is_said_and_a_locked_or_older_one_is_not() -> None:
    """SR-9.6: ``memory   NOT LOCKED: ...`` when the reply says false; nothing when it says
    true, or nothing at all (a daemon older than the lock)."""
    unlocked = format_status(status_reply(loop=dataclasses.replace(LOOP, memory_locked=False)))
    assert f"  memory   {MEMORY_NOT_LOCKED}\n" in unlocked
    for said in (True, None):
        text = format_status(status_reply(loop=dataclasses.replace(LOOP, memory_locked=said)))
        assert "memory" not in text

"""The heap after start-up: what the garbage collector still scans while the loop runs.

CPython's cyclic garbage collector now and then scans every object it tracks: after start-up
that is about 30,000 of them (the modules, their functions and classes, the config), and one
such full collection held the loop 10-14 ms on the bench machine (docs/performance.md "The
heap"), five times SR-9.1's 2 ms, at whatever moment the loop's allocations set it off, a
stop's decoding included. Objects that live as long as the process never become garbage, so
:func:`settle` collects start-up's garbage once and then freezes what is left (``gc.freeze``:
the collector ignores it from then on); what the loop allocates later is still collected as
before. A full collection then scans only the loop's own live objects (the flight recorder's
ring, the clients'): about 0.4 ms. The price: an object of start-up's that the loop drops
later (a port closed and opened again) is freed by its reference count as always, but not if
it sits in a reference cycle; each can be kept once at most, so the heap stays bounded by
start-up's.
"""

from __future__ import annotations

import gc


def settle() -> int:
    """Collect start-up's garbage and freeze the survivors; the number frozen so far. Called
    once, between the start and the first turn of the loop (``lifecycle.run``), never in a
    process that goes on to allocate long-lived objects it will drop (a test runner)."""
    gc.collect()
    gc.freeze()
    return gc.get_freeze_count()

"""The heap after start-up (``supervisord/daemon/heap.py``; SR-9.1, SR-9.4).

Each test runs in a process of its own: freezing the heap of the test runner would keep its
garbage for good.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

_SETTLE = textwrap.dedent(
    """
    import gc, json, weakref
    from supervisord.daemon import heap

    class Node:
        pass

    cycle = Node()
    cycle.itself = cycle  # start-up's garbage: only the cyclic collector frees it
    gone = weakref.ref(cycle)
    del cycle
    kept = [Node() for _ in range(1000)]  # start-up's lasting objects
    frozen = heap.settle()
    later = [Node() for _ in range(10)]  # the loop's own
    print(json.dumps({
        "frozen": frozen,
        "collected": gone() is None,
        "scanned": len(gc.get_objects()),
        "kept_scanned": any(o is kept[0] for o in gc.get_objects()),
        "later_scanned": any(o is later[0] for o in gc.get_objects()),
    }))
    """
)


def test_settle_collects_start_ups_garbage_and_freezes_what_lasts() -> None:
    """SR-9.1, SR-9.4: after ``settle`` a full collection no longer scans what start-up
    left (frozen), start-up's cyclic garbage is freed rather than frozen, and what is
    allocated afterwards is scanned (and collected) as before."""
    result = subprocess.run(
        [sys.executable, "-c", _SETTLE], capture_output=True, text=True, check=True
    )
    said = json.loads(result.stdout)
    assert said["collected"]
    assert said["frozen"] >= 1000
    assert not said["kept_scanned"]
    assert said["later_scanned"]
    assert said["scanned"] < said["frozen"] // 10

"""A bench that needs a network of its own runs itself again in a new network namespace, its
loopback up, so nothing it sends leaves the machine (docs/testing.md, docs/fleet.md)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
INSIDE = "SRCS_BENCH_NETNS"
"""Set in the bench's environment once it runs inside its namespace."""


def in_namespace(module: str) -> None:
    """Run ``python -m module`` with this process's arguments again in a network namespace of
    its own and exit with its status; inside it, bring the loopback up and return."""
    if os.environ.get(INSIDE):
        subprocess.run(["ip", "link", "set", "lo", "up"], check=True)
        return
    if os.geteuid() != 0 or shutil.which("unshare") is None:
        raise SystemExit("needs root and unshare(1): it runs in a network namespace of its own")
    done = subprocess.run(
        ["unshare", "--net", sys.executable, "-m", module, *sys.argv[1:]],
        env={**os.environ, INSIDE: "1"},
        cwd=REPO,
        check=False,
    )
    raise SystemExit(done.returncode)

"""The fleet's console in the fleet tier: the installed package's ``srcsctl fleet stop``, its
own code (``supervisord.cli.srcsctl``), run again and again in one process so that the rounds
measure the stop and not a Python start (docs/fleet.md "The fleet tier").

Run by tests/fleet/fleet_stop.py with the robot package's own interpreter, never imported by
the tier (whose Python has no MQTT client):

    PYTHON tests/fleet/console.py ROUNDS RELEASE -- ARGS...

Each round is ``srcsctl fleet stop --json ARGS`` and, when RELEASE is 1, ``srcsctl fleet stop
--release --stop-id ID --json ARGS`` of that round's stop; a JSON line per round,
``{"status": N, "rows": [...], "release": [...]}`` (``rows``: the console's own JSON lines,
a line per robot and its summary last).
"""

from __future__ import annotations

import contextlib
import io
import json
import sys

from supervisord.cli import srcsctl


def console(argv: list[str]) -> tuple[int, list[dict[str, object]]]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        status = srcsctl.main(["fleet", "stop", "--json", *argv])
    return status, [json.loads(line) for line in out.getvalue().splitlines() if line.strip()]


def main() -> int:
    rounds, release = int(sys.argv[1]), sys.argv[2] == "1"
    argv = sys.argv[sys.argv.index("--") + 1 :]
    for _ in range(rounds):
        status, rows = console(argv)
        answer: dict[str, object] = {"status": status, "rows": rows, "release": None}
        stop_id = rows[-1].get("stop_id") if rows else None
        if release and isinstance(stop_id, str):
            answer["release"] = console(["--release", "--stop-id", stop_id, *argv])[1]
        print(json.dumps(answer), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

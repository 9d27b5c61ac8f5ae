"""The picture of a remote e-stop that docs/record.md shows, drawn by ``srcsctl replay --plot``
from the tests' window of that stop kind (``tests/record/stop_kinds.py``).

    .venv/bin/python -m tests.record.example_picture     # rewrites docs/pictures/stop-vsc-estop.svg
"""

from __future__ import annotations

import io
import tempfile
from pathlib import Path

from supervisord.cli.replay import run_replay
from tests.record.stop_kinds import KINDS, RECORD

DOCUMENTED = Path(__file__).resolve().parents[2] / "docs" / "pictures" / "stop-vsc-estop.svg"
KIND = "remote_estop"


def example_picture() -> str:
    """The SVG the replay draws of the remote e-stop's window today."""
    with tempfile.TemporaryDirectory() as folder:
        where = Path(folder)
        story = KINDS[KIND]()
        story.write(where)
        said = io.StringIO()
        code = run_replay(
            str(story.stop["seq"]), where / RECORD, said, said, plot=where / "stop.svg"
        )
        if code != 0:
            raise RuntimeError(f"the replay of {KIND} said exit {code}: {said.getvalue()}")
        return (where / "stop.svg").read_text()


if __name__ == "__main__":
    DOCUMENTED.write_text(example_picture())
    print(f"wrote {DOCUMENTED.name}")

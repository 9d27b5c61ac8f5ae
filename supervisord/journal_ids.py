"""The stable journal ``MESSAGE_ID`` of each record kind, by the kind's name (SR-7.3,
docs/record.md "The systemd journal").

Their own module, importing nothing: the robot's journal sink
(:mod:`supervisord.record.journal`) writes them and ``srcsctl fleet`` selects by them on a
collector, which loads no module of the safety core (SR-13.6). Never change them: operators'
queries and alerting depend on them."""

from __future__ import annotations

import uuid
from collections.abc import Mapping
from typing import Final

MESSAGE_IDS_BY_KIND: Final[Mapping[str, uuid.UUID]] = {
    "state_change": uuid.UUID("26c2f33dae3d4a6c8996fc9bc658ad32"),
    "cause_raised": uuid.UUID("820501387c1a46049b855bcae8bc9ba2"),
    "cause_cleared": uuid.UUID("fd9e4e6d79c643eb9a534d2f8228aa89"),
    "rearm_refused": uuid.UUID("2be6051d1b7c43d0a0bfd08ad06caac8"),
    "commissioned": uuid.UUID("bdd0782d2f2b45a3bdc4e9984db1024d"),
    "prooftest": uuid.UUID("af4347b3c6a741d6a06ce07e58cea85a"),
    "hello_refused": uuid.UUID("31b39d5239c64c748a02ea76dd76a97f"),
    "stoptest": uuid.UUID("55afb9fa858e45458a44937c4062ca84"),
}

FLIGHT_WINDOW_MESSAGE_ID: Final = uuid.UUID("75233db4b0b14222b4593748065a0c40")
"""A stop's flight recorder window, sent after its file as a journal entry of its own
(``supervisord/record/flight_journal.py``, docs/fleet.md "A stop's evidence at the
collector"). Not a record kind: ``srcsctl fleet``'s record lines never select it."""

"""The record of stops (SR-7, ``docs/record.md``): the typed record every reader shares
(:mod:`.stop`), its making from the safety core's record (:mod:`.format`), an
append-only JSON Lines file with fsync per record and crash-safe rotation (:mod:`.jsonl`), and
the systemd journal (:mod:`.journal`)."""

"""How often a random multi-byte corruption of a frame passes the checksum.

Run: ``.venv/bin/python -m bench.checksum_escape [trials]``. Prints, per number of corrupted
bytes, how many corrupted frames the decoder accepted as a message. docs/protocol.md records
the result and what it means for safety.
"""

from __future__ import annotations

import random
import sys

from supervisord.protocol.framing import FrameDecoder, Rejection, encode_frame
from supervisord.protocol.messages import Joystick, Message, VscHeartbeat


def escapes(frame: bytes, corrupted_bytes: int, trials: int, seed: int = 1) -> int:
    """Corrupt ``corrupted_bytes`` random bytes after the header (so the frame keeps its
    boundaries) ``trials`` times; count the corrupted frames accepted as a message."""
    rng = random.Random(seed)
    accepted = 0
    for _ in range(trials):
        corrupt = bytearray(frame)
        for at in rng.sample(range(4, len(frame)), corrupted_bytes):
            corrupt[at] ^= rng.randint(1, 255)
        events = FrameDecoder().feed(bytes(corrupt))
        accepted += bool(events) and not isinstance(events[0], Rejection)
    return accepted


def main() -> None:
    trials = int(sys.argv[1]) if len(sys.argv) > 1 else 200_000
    frames: dict[str, Message] = {"heartbeat": VscHeartbeat(9), "joystick": Joystick()}
    print(f"trials per row: {trials}; Fletcher-16 ideal: 1/65536 = {1 / 65536:.2e}")
    for name, message in frames.items():
        frame = encode_frame(message)
        for count in (1, 2, 3, 4):
            accepted = escapes(frame, count, trials)
            print(
                f"{name:9} {count} bytes corrupted: {accepted:6} accepted = {accepted / trials:.2e}"
            )


if __name__ == "__main__":
    main()

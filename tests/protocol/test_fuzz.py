"""A mutation fuzz run of the serial decoder: realistic streams, randomly broken.

Bounded for the everyday run (``SRCS_FUZZ_EXAMPLES`` streams, default 300); ``./dev fuzz N``
runs N. Each case checks the decoder's contract: no exception, bounded memory, every byte
accounted for, and the same events whatever the chunking.
"""

from __future__ import annotations

import os
import random

import pytest

from supervisord.protocol.framing import FrameDecoder, Rejection, encode_frame
from supervisord.protocol.messages import UserHeartbeat
from supervisord.testkit.traffic import vsc_stream
from tests.protocol.test_properties import consumed, feed_in_chunks, merge_noise

EXAMPLES = int(os.environ.get("SRCS_FUZZ_EXAMPLES", "300"))
SEED_STREAM = vsc_stream(0.3, garbage=0.0, seed=3)


def mutate(rng: random.Random, data: bytes) -> bytes:
    """Flip, insert, delete, duplicate or splice a few spots of ``data``."""
    out = bytearray(data)
    for _ in range(rng.randint(1, 8)):
        at = rng.randrange(len(out) or 1)
        match rng.randrange(6):
            case 0:
                out[at : at + 1] = bytes((rng.randrange(256),))
            case 1:
                out[at:at] = rng.randbytes(rng.randint(1, 300))
            case 2:
                del out[at : at + rng.randint(1, 40)]
            case 3:
                out[at:at] = out[at : at + rng.randint(1, 60)]
            case 4:
                out[at:at] = b"\x10\x01" + bytes((rng.randrange(256), rng.randrange(256)))
            case _:
                out[at : at + 1] = bytes((0x10,))
    return bytes(out)


@pytest.mark.fuzz
def test_fuzz_decoder_contract() -> None:
    """Mutated realistic streams never break the decoder's contract."""
    rng = random.Random(int(os.environ.get("SRCS_FUZZ_SEED", "20261122")))
    messages = 0
    for _ in range(EXAMPLES):
        start = rng.randrange(len(SEED_STREAM))
        data = mutate(rng, SEED_STREAM[start : start + rng.randint(0, 2000)])
        cuts = [rng.randrange(len(data) + 1) for _ in range(rng.randint(0, 40))]
        events = feed_in_chunks(data, cuts)
        assert merge_noise(events) == merge_noise(feed_in_chunks(data, []))
        assert sum(consumed(event) for event in events) == len(data)
        messages += sum(1 for event in events if not isinstance(event, Rejection))
    assert messages > EXAMPLES  # the mutations leave most frames intact: the run is not vacuous
    print(f"fuzz: {EXAMPLES} streams, {messages} messages decoded")


@pytest.mark.fuzz
def test_fuzz_a_heartbeat_after_any_broken_frame_is_recovered() -> None:
    """Whatever type, length byte and bytes precede it, the heartbeat behind a broken frame is
    decoded: the one-byte resync never loses it (PR-1)."""
    rng = random.Random(5)
    heartbeat = UserHeartbeat(0)
    for _ in range(EXAMPLES * 10):
        kind, length = rng.randrange(256), rng.randrange(256)
        junk = bytes((0x10, 0x01, kind, length)) + rng.randbytes(rng.randrange(260))
        decoder = FrameDecoder()
        events = [*decoder.feed(junk), *decoder.feed(encode_frame(heartbeat)), *decoder.end()]
        assert heartbeat in events, junk.hex()

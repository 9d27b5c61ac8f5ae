"""The checksum against a line-by-line transcription of the manual's algorithm (figure 11)."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from supervisord.protocol.checksum import fletcher16


def manual_checksum16(data: bytes) -> int:
    """Figure 11 of the manual, statement by statement."""
    sum1 = 0
    sum2 = 0
    for index in range(len(data)):
        sum1 = (sum1 + data[index]) & 255
        sum2 = (sum2 + sum1) & 255
    return (sum2 << 8) | sum1


@given(st.binary(max_size=300))
def test_equals_the_manuals_loop(data: bytes) -> None:
    """For any bytes, the checksum equals the manual's own loop."""
    assert fletcher16(data) == manual_checksum16(data)


def test_known_values() -> None:
    """Empty input sums to 0; the user heartbeat's header and payload give 0xB933."""
    assert fletcher16(b"") == 0
    assert fletcher16(bytes.fromhex("10 01 21 01 00")) == 0xB933
    assert fletcher16(b"\xff" * 300) == manual_checksum16(b"\xff" * 300)

"""The HRI packet checksum (manual §8.6, figure 11)."""

from __future__ import annotations


def fletcher16(data: bytes | bytearray | memoryview) -> int:
    """The manual's Fletcher-16 variant: both sums start at 0 and are kept mod 256.

    Returns ``sum2 << 8 | sum1``; on the wire sum1 goes first (notes §1). Over a frame it
    covers the header, type, length and payload.
    """
    sum1 = sum2 = 0
    for byte in data:
        sum1 = (sum1 + byte) & 0xFF
        sum2 = (sum2 + sum1) & 0xFF
    return sum2 << 8 | sum1

"""A picture as a browser shows it: headless Chromium renders an SVG file to PNG, and the PNG's
pixels are read with the standard library (zlib), for tests that look at what a person sees.

Chromium (the Debian package ``chromium``, which ``./dev`` installs) runs in a network namespace
of its own (``unshare --net``): it reaches nothing, loopback included, whatever it tries at its
start. Run as root, it needs ``--no-sandbox``."""

from __future__ import annotations

import dataclasses
import os
import shutil
import struct
import subprocess
import zlib
from pathlib import Path

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@dataclasses.dataclass(frozen=True)
class Image:
    """Pixels as (red, green, blue) rows."""

    width: int
    height: int
    rows: list[list[tuple[int, int, int]]]

    def at(self, x: float, y: float) -> tuple[int, int, int]:
        return self.rows[round(y)][round(x)]


def _paeth(a: int, b: int, c: int) -> int:
    p = a + b - c
    pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
    if pa <= pb and pa <= pc:
        return a
    return b if pb <= pc else c


def read_png(data: bytes) -> Image:
    """An 8-bit RGB or RGBA, non-interlaced PNG (what Chromium writes), decoded."""
    assert data.startswith(PNG_SIGNATURE), "not a PNG"
    offset, idat = len(PNG_SIGNATURE), b""
    width = height = colour = 0
    while offset < len(data):
        (length,) = struct.unpack(">I", data[offset : offset + 4])
        kind = data[offset + 4 : offset + 8]
        body = data[offset + 8 : offset + 8 + length]
        offset += 12 + length
        if kind == b"IHDR":
            width, height, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            assert (depth, interlace) == (8, 0), (depth, interlace)
            assert colour in (2, 6), colour
        elif kind == b"IDAT":
            idat += body
        elif kind == b"IEND":
            break
    channels = 4 if colour == 6 else 3
    raw = zlib.decompress(idat)
    stride = width * channels
    previous = bytearray(stride)
    rows = []
    for y in range(height):
        start = y * (stride + 1)
        method, line = raw[start], bytearray(raw[start + 1 : start + 1 + stride])
        for i in range(stride):
            a = line[i - channels] if i >= channels else 0
            b = previous[i]
            c = previous[i - channels] if i >= channels else 0
            if method == 1:
                line[i] = (line[i] + a) & 0xFF
            elif method == 2:
                line[i] = (line[i] + b) & 0xFF
            elif method == 3:
                line[i] = (line[i] + (a + b) // 2) & 0xFF
            elif method == 4:
                line[i] = (line[i] + _paeth(a, b, c)) & 0xFF
        rows.append([(line[x], line[x + 1], line[x + 2]) for x in range(0, stride, channels)])
        previous = line
    return Image(width, height, rows)


def render_svg(svg: Path, width: int, height: int) -> Image:
    """``svg`` as headless Chromium draws it in a window of ``width`` x ``height``."""
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    assert chromium is not None, "chromium is missing: ./dev installs it (apt-get install chromium)"
    png = svg.with_suffix(".png")
    command = [
        chromium,
        "--headless",
        "--disable-gpu",
        "--hide-scrollbars",
        "--force-device-scale-factor=1",
        "--no-first-run",
        "--disable-background-networking",
        f"--user-data-dir={svg.parent / 'chromium-profile'}",
        f"--screenshot={png}",
        f"--window-size={width},{height}",
        svg.as_uri(),
    ]
    if os.geteuid() == 0:
        command[1:1] = ["--no-sandbox"]
        command[:0] = ["unshare", "--net"]  # a network of its own: nothing leaves the machine
    done = subprocess.run(command, capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    assert png.exists(), done.stderr[-2000:]
    return read_png(png.read_bytes())

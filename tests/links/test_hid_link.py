"""The USB HID link's bytes (PR-4.1): what it reads as input reports and what it writes to a
hidraw node. There is no hidraw node on a host without HID devices, so a named pipe stands in
for the node's file here: it keeps the bytes each write() gave it, so a test sees exactly what
the link would hand to the kernel. What the kernel then does with them (the USB HID driver
drops the report number 0, the VSC receives the 26-byte report) is proven on the real driver
path by the system tier's ``usb_hid`` scenario (docs/system-tier.md).
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from supervisord.links.base import LinkError
from supervisord.links.hid_link import HidLink
from supervisord.protocol.hid import (
    OUTPUT_LENGTH,
    HidInput,
    HidOutput,
    HidRejection,
    decode_hid_output,
    encode_hid_input,
)
from supervisord.protocol.messages import FeedbackName, FeedbackSet, UserHeartbeat


@pytest.fixture
def node(tmp_path: Path) -> Path:
    path = tmp_path / "hidraw0"
    os.mkfifo(path)
    return path


def written(path: Path) -> bytes:
    """Everything waiting in the pipe, read without blocking."""
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    try:
        chunks = []
        while True:
            try:
                chunk = os.read(fd, 4096)
            except BlockingIOError:
                break
            if not chunk:
                break
            chunks.append(chunk)
        return b"".join(chunks)
    finally:
        os.close(fd)


def test_output_reports_go_to_hidraw_behind_report_number_zero(node: Path) -> None:
    """PR-4.1: hidraw's write() takes the report number first (0: the VSC numbers none of its
    reports), then the report. A label's report starts with its key byte 0: written bare, the
    USB HID driver took that 0 for the report number and sent the VSC 25 bytes (seen in the
    system tier: the VSC's end rejected it as 25 of 26 bytes). Each report here is 0 and the
    26 bytes of manual table 39, whatever its first byte."""
    link = HidLink(str(node))
    link.open()
    try:
        link.send([FeedbackSet(1, 1234), FeedbackName(2, "Speed"), UserHeartbeat(0)])
        data = written(node)
    finally:
        link.close()
    size = 1 + OUTPUT_LENGTH
    assert len(data) == 2 * size, "one report for the value, one for the label, no heartbeat"
    value, label = data[:size], data[size:]
    assert value[0] == 0, "the value's report behind the report number 0"
    assert label[0] == 0, "the label's report behind the report number 0"
    assert decode_hid_output(value[1:]) == HidOutput(1, 1234, 0, "")
    assert decode_hid_output(label[1:]) == HidOutput(0, 0, 2, "Speed")


def test_each_read_is_one_input_report_and_a_wrong_length_is_rejected(node: Path) -> None:
    """PR-4.1: a read of the node is one 9-byte input report (no report number: hidraw gives a
    device's unnumbered reports bare), decoded; any other length is a rejection, not a report."""
    link = HidLink(str(node))
    link.open()
    feeder = os.open(node, os.O_WRONLY)
    report = HidInput(12, -34, 0, -127, 127, 5, dpad=2, buttons=0b1001, mode=9, estop=1)
    try:
        os.write(feeder, encode_hid_input(report))
        assert link.receive() == [report]
        os.write(feeder, encode_hid_input(report)[:8])
        assert link.receive() == [HidRejection(8, 9)]
        assert link.receive() == []
    finally:
        os.close(feeder)
        link.close()
    assert not link.is_open


def test_a_readable_node_is_read_once_and_never_to_find_it_empty(
    node: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """SR-9.8: the loop receives when the node is readable; the link reads the one report and
    makes no read that finds the queue empty (hidraw marks its reader sleeping before it tests
    O_NONBLOCK, which the kernel's rtapp monitor judges a real-time thread's sleep)."""
    link = HidLink(str(node))
    link.open()
    feeder = os.open(node, os.O_WRONLY)
    reads: list[int] = []
    real_read = os.read

    def read(fd: int, size: int) -> bytes:
        reads.append(fd)
        return real_read(fd, size)

    report = HidInput(1, 2, 3, 4, 5, 6, dpad=0, buttons=0, mode=1, estop=0)
    try:
        os.write(feeder, encode_hid_input(report))
        monkeypatch.setattr(os, "read", read)
        assert link.receive() == [report]
        assert len(reads) == 1
    finally:
        monkeypatch.undo()
        os.close(feeder)
        link.close()


def test_a_missing_node_is_a_link_error_naming_why(tmp_path: Path) -> None:
    """PR-4.1: a VSC not plugged in (no hidraw node at the configured path) cannot be opened:
    ``LinkError`` with the reason, which the daemon retries with its backoff."""
    link = HidLink(str(tmp_path / "hidraw9"))
    with pytest.raises(LinkError, match="No such file"):
        link.open()
    assert not link.is_open


def test_a_prepared_node_is_taken_by_the_open_and_closed_if_never_taken(node: Path) -> None:
    """SR-9.8: ``prepare`` (run off the loop by the link port) opens the node, and ``open``
    takes that descriptor without opening the node again: here the node is gone by the time
    of the open, which still succeeds. A prepared descriptor that no open takes is closed by
    ``close``; a prepare that met an error hands it to the open."""
    link = HidLink(str(node))
    assert link.prepares_open
    link.prepare()
    node.unlink()
    link.open()
    fd = link.fileno()
    assert fd is not None
    assert stat.S_ISFIFO(os.fstat(fd).st_mode)  # the node's descriptor, opened before it went
    link.close()
    os.mkfifo(node)
    unused = HidLink(str(node))
    unused.prepare()
    before = set(os.listdir("/proc/self/fd"))
    unused.close()
    assert len(before - set(os.listdir("/proc/self/fd"))) == 1
    missing = HidLink(str(node) + "-absent")
    missing.prepare()
    with pytest.raises(LinkError, match="No such file"):
        missing.open()
    assert not missing.is_open

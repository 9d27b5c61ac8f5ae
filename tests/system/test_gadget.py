"""The system tier's HID gadget presents the reports the project's HID link decodes (PR-4.1).

The manual gives the VSC's HID reports (table 38: 9 bytes in, table 39: 26 bytes out), not its
report descriptor, so the tier writes one (``REPORT_DESCRIPTOR`` in ``guest/gadget.py``). Here
its items are parsed as a host's HID parser reads them, and every field of the input report is
taken out of reports that ``supervisord/protocol/hid.py`` encodes: each must be the value the
codec put there. In the guest, the kernel reads the same descriptor as a game pad with six axes
and a hat switch (docs/system-tier.md, ``usb_hid``).
"""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from supervisord.protocol.hid import (
    HID_AXES,
    INPUT_LENGTH,
    OUTPUT_LENGTH,
    HidInput,
    encode_hid_input,
)
from tests.system.guest.gadget import REPORT_DESCRIPTOR

MAIN_INPUT, MAIN_OUTPUT = 0x8, 0x9  # main item tags (HID 1.11, 6.2.2.4)
GLOBAL_USAGE_PAGE, GLOBAL_LOGICAL_MIN, GLOBAL_LOGICAL_MAX = 0x0, 0x1, 0x2
GLOBAL_REPORT_SIZE, GLOBAL_REPORT_ID, GLOBAL_REPORT_COUNT = 0x7, 0x8, 0x9
LOCAL_USAGE, LOCAL_USAGE_MIN, LOCAL_USAGE_MAX = 0x0, 0x1, 0x2
NULL_STATE = 0x40  # main item flag: values outside the logical range mean "no value"
GENERIC_DESKTOP, BUTTON, VENDOR = 0x01, 0x09, 0xFF00
AXIS_USAGES = (0x30, 0x31, 0x32, 0x33, 0x34, 0x35)  # X, Y, Z, Rx, Ry, Rz: left x, y, z, right
HAT_SWITCH = 0x39


@dataclass(frozen=True)
class Field:
    """One value of a report: where it is (bits from the report's start) and what it is."""

    offset: int
    size: int
    logical_min: int
    flags: int
    page: int
    usage: int

    def read(self, report: bytes) -> int:
        raw = int.from_bytes(report, "little") >> self.offset & ((1 << self.size) - 1)
        if self.logical_min < 0 and raw >> (self.size - 1):
            raw -= 1 << self.size  # a signed field
        return raw


def parse(descriptor: bytes) -> tuple[list[Field], int, int, bool]:
    """The input fields, the input and output report lengths in bits, and whether any report
    ID is declared. Short items only (the descriptor has no long item)."""
    fields: list[Field] = []
    bits = {MAIN_INPUT: 0, MAIN_OUTPUT: 0}
    page = size = count = logical_min = 0
    usages: list[int] = []
    usage_range: list[int] = []
    numbered = False
    at = 0
    while at < len(descriptor):
        prefix = descriptor[at]
        length = (0, 1, 2, 4)[prefix & 0x3]
        kind, tag = prefix >> 2 & 0x3, prefix >> 4
        data = descriptor[at + 1 : at + 1 + length]
        value = int.from_bytes(data, "little")
        signed = int.from_bytes(data, "little", signed=True)
        at += 1 + length
        if kind == 1:  # global
            page = value if tag == GLOBAL_USAGE_PAGE else page
            logical_min = signed if tag == GLOBAL_LOGICAL_MIN else logical_min
            size = value if tag == GLOBAL_REPORT_SIZE else size
            count = value if tag == GLOBAL_REPORT_COUNT else count
            numbered = numbered or tag == GLOBAL_REPORT_ID
        elif kind == 2:  # local
            if tag == LOCAL_USAGE:
                usages.append(value)
            elif tag in (LOCAL_USAGE_MIN, LOCAL_USAGE_MAX):
                usage_range.append(value)
        elif kind == 0 and tag in bits:  # a main item that makes report fields
            if usage_range:
                usages += range(usage_range[0], usage_range[1] + 1)
            for index in range(count):
                if tag == MAIN_INPUT:
                    usage = usages[min(index, len(usages) - 1)]
                    fields.append(Field(bits[tag], size, logical_min, value, page, usage))
                bits[tag] += size
            usages, usage_range = [], []
        elif kind == 0:  # collections: locals end here too
            usages, usage_range = [], []
    return fields, bits[MAIN_INPUT], bits[MAIN_OUTPUT], numbered


REPORTS = [
    HidInput(),
    HidInput(-127, 127, -1, 1, 0, 100, dpad=2, buttons=0b1010, mode=9, estop=1),
    HidInput(127, -127, 127, -127, 127, -127, dpad=7, buttons=0b0101, mode=255, estop=0),
    HidInput(0, 0, 0, 0, 0, 0, dpad=8, buttons=0b1111, mode=4, estop=1),
]


def test_the_reports_have_the_lengths_the_codec_takes_and_no_report_number() -> None:
    """PR-4.1: one unnumbered input report of 9 bytes and one output report of 26: hidraw
    then hands the input report over bare, as ``decode_hid_input`` expects it, and takes the
    output report behind the report number 0 (``HidLink``)."""
    _, input_bits, output_bits, numbered = parse(REPORT_DESCRIPTOR)
    assert not numbered
    assert input_bits == INPUT_LENGTH * 8
    assert output_bits == OUTPUT_LENGTH * 8


@pytest.mark.parametrize("report", REPORTS)
def test_every_input_field_holds_what_the_codec_put_there(report: HidInput) -> None:
    """PR-4.1 (manual table 38): in the descriptor's order, the six axes (X, Y, Z, Rx, Ry, Rz
    for left x, y, z and right x, y, z, signed -127..127), the hat switch (the D-pad: 0-7 and 8
    as its null state), buttons 1-4, then the mode and the e-stop (vendor bytes); read out of
    the codec's bytes they are the report's values."""
    fields, *_ = parse(REPORT_DESCRIPTOR)
    data = encode_hid_input(report)
    axes = [f for f in fields if f.page == GENERIC_DESKTOP and f.usage in AXIS_USAGES]
    assert [f.usage for f in axes] == list(AXIS_USAGES)
    assert all(f.logical_min == -127 and f.size == 8 for f in axes)
    assert [f.read(data) for f in axes] == [getattr(report, name) for name in HID_AXES]
    (hat,) = [f for f in fields if f.page == GENERIC_DESKTOP and f.usage == HAT_SWITCH]
    assert hat.flags & NULL_STATE
    assert hat.read(data) == report.dpad
    buttons = [f for f in fields if f.page == BUTTON]
    assert [f.usage for f in buttons] == [1, 2, 3, 4]
    assert {f.usage for f in buttons if f.read(data)} == report.pressed
    mode, estop = (f for f in fields if f.page == VENDOR)
    assert (mode.read(data), estop.read(data)) == (report.mode, report.estop)
    assert len(fields) == 6 + 1 + 4 + 2

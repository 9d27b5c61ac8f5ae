"""The USB HID reports of manual §10."""

from __future__ import annotations

from supervisord.protocol.hid import (
    DPadDirection,
    HidInput,
    HidOutput,
    HidRejection,
    decode_hid_input,
    decode_hid_output,
    encode_hid_output,
)


def test_input_report_fields() -> None:
    """PR-4.1: six signed axes, D-pad low nibble, buttons high nibble, mode, e-stop (table 38)."""
    report = decode_hid_input(bytes([0x7F, 0x81, 0, 0, 0, 0, 0x32, 0x09, 0x01]))
    assert report == HidInput(127, -127, 0, 0, 0, 0, dpad=2, buttons=3, mode=9, estop=1)
    assert isinstance(report, HidInput)
    assert report.dpad_direction is DPadDirection.RIGHT
    assert report.pressed == {1, 2}


def test_undefined_dpad_value_has_no_direction() -> None:
    """D-pad values 9-15 are kept but have no direction."""
    report = decode_hid_input(bytes([0] * 6 + [0x0C, 4, 0]))
    assert isinstance(report, HidInput)
    assert report.dpad == 12
    assert report.dpad_direction is None


def test_output_report_layout() -> None:
    """Key, i32 value, string key, 20 NUL-padded characters: 26 bytes (table 39)."""
    data = encode_hid_output(HidOutput(1, -2, 90, "Hi"))
    assert data == bytes([1]) + (-2).to_bytes(4, "little", signed=True) + bytes(
        [90]
    ) + b"Hi" + bytes(18)
    assert decode_hid_output(data) == HidOutput(1, -2, 90, "Hi")


def test_wrong_lengths_are_rejected() -> None:
    """A report of the wrong size for its direction is a typed rejection."""
    assert decode_hid_input(bytes(10)) == HidRejection(10, 9)
    assert decode_hid_output(bytes(25)) == HidRejection(25, 26)

"""The CAN enable frame over python-can's virtual bus (supervisord.outputs.can_enable)."""

from __future__ import annotations

import can
import pytest

from supervisord.errors import ConfigError
from supervisord.outputs import OutputFault, create_output, parse_output_spec
from supervisord.outputs.can_enable import CanEnableOutput, CanEnableSpec, parse_hex
from supervisord.testkit.output_conformance import T0
from tests.outputs.conftest import CAN_SPEC, BusWatcher

MS = 1_000_000

Buses = tuple[can.BusABC, can.BusABC]


def test_open_sends_off_at_once(virtual_buses: Buses) -> None:
    """Opening sends the off frame inside the call, with the configured id."""
    mine, theirs = virtual_buses
    watch = BusWatcher(theirs, CAN_SPEC)
    out = CanEnableOutput(CAN_SPEC, mine)
    out.open(T0)
    [frame] = watch.drain()
    assert frame.arbitration_id == 0x210
    assert not frame.is_extended_id
    assert bytes(frame.data) == bytes.fromhex("00 00 00 00")
    closed = out.close()
    assert closed is not None
    assert (closed.ok, closed.requested) == (True, False)
    [last] = watch.drain()
    assert watch.level(last) is False


def test_stop_sends_off_at_once_and_keeps_sending(virtual_buses: Buses) -> None:
    """SR-6.3: set(False) sends the off frame immediately, and every due tick sends it again."""
    mine, theirs = virtual_buses
    watch = BusWatcher(theirs, CAN_SPEC)
    out = CanEnableOutput(CAN_SPEC, mine)
    out.open(T0)
    out.set(True, T0 + 5 * MS)
    watch.drain()
    out.set(False, T0 + 7 * MS)
    [stop] = watch.drain()
    assert watch.level(stop) is False
    for _ in range(5):
        deadline = out.next_deadline()
        assert deadline is not None
        rb = out.tick(deadline)
        assert rb is not None
        assert rb.ok
        [again] = watch.drain()
        assert watch.level(again) is False
    out.close()


def test_period_restarts_at_each_set(virtual_buses: Buses) -> None:
    """After a set, the next periodic frame is one period (20 ms by default) later."""
    mine, _ = virtual_buses
    out = CanEnableOutput(CAN_SPEC, mine)
    out.open(T0)
    assert out.next_deadline() == T0 + 20 * MS
    out.set(True, T0 + 13 * MS)
    assert out.next_deadline() == T0 + 33 * MS
    out.close()


def test_periodic_frames_follow_the_period(virtual_buses: Buses) -> None:
    """SR-6.3: ticks at each deadline send one frame each, spaced exactly one period apart."""
    mine, theirs = virtual_buses
    watch = BusWatcher(theirs, CAN_SPEC)
    out = CanEnableOutput(CAN_SPEC, mine)
    out.open(T0)
    out.set(True, T0)
    deadlines = []
    for _ in range(4):
        deadline = out.next_deadline()
        assert deadline is not None
        deadlines.append(deadline)
        out.tick(deadline + 2 * MS)  # a little late: the schedule does not drift
    assert deadlines == [T0 + k * 20 * MS for k in (1, 2, 3, 4)]
    assert [watch.level(f) for f in watch.drain()] == [False, True, True, True, True, True]
    out.close()


def test_late_loop_sends_one_frame_not_a_burst(virtual_buses: Buses) -> None:
    """A tick several periods late sends one frame and schedules the next from now."""
    mine, theirs = virtual_buses
    watch = BusWatcher(theirs, CAN_SPEC)
    out = CanEnableOutput(CAN_SPEC, mine)
    out.open(T0)
    watch.drain()
    late = T0 + 95 * MS
    assert out.tick(late) is not None
    assert out.tick(late) is None
    assert len(watch.drain()) == 1
    assert out.next_deadline() == late + 20 * MS
    out.close()


def test_rolling_counter_keeps_template_bits_and_wraps(virtual_buses: Buses) -> None:
    """SR-6.3: the counter rises by one per frame within its mask, keeps the other bits, and
    wraps."""
    spec = CanEnableSpec(
        name="m",
        arbitration_id=0x18FF1234,
        extended=True,
        data_on=bytes.fromhex("01 a5"),
        data_off=bytes.fromhex("00 a5"),
        counter_byte=1,
        counter_mask=0x30,
    )
    mine, theirs = virtual_buses
    out = CanEnableOutput(spec, mine)
    out.open(T0)
    out.set(True, T0)
    for k in range(6):
        out.tick(T0 + (k + 1) * 20 * MS)
    frames = BusWatcher(theirs, spec).drain()
    assert all(f.is_extended_id and f.arbitration_id == 0x18FF1234 for f in frames)
    counters = [(f.data[1] & 0x30) >> 4 for f in frames]
    assert counters == [0, 1, 2, 3, 0, 1, 2, 3]
    assert all(f.data[1] & 0xCF == 0x85 for f in frames)
    assert [f.data[0] for f in frames] == [0, 1, 1, 1, 1, 1, 1, 1]
    out.close()


def test_close_sends_off_and_leaves_the_bus_open(virtual_buses: Buses) -> None:
    """Closing sends one last off frame, stops the schedule and does not shut the bus down."""
    mine, theirs = virtual_buses
    watch = BusWatcher(theirs, CAN_SPEC)
    out = CanEnableOutput(CAN_SPEC, mine)
    out.open(T0)
    out.set(True, T0)
    watch.drain()
    out.close()
    [last] = watch.drain()
    assert watch.level(last) is False
    assert out.next_deadline() is None
    mine.send(can.Message(arbitration_id=1, data=b""))  # still usable by its owner
    assert len(watch.drain()) == 1


def test_send_error_on_tick_is_a_fault(virtual_buses: Buses) -> None:
    """A periodic frame the bus refuses comes back from tick as SEND_ERROR."""
    mine, _ = virtual_buses
    out = CanEnableOutput(CAN_SPEC, mine)
    out.open(T0)
    mine.shutdown()
    rb = out.tick(T0 + 20 * MS)
    assert rb is not None
    assert rb.fault is OutputFault.SEND_ERROR
    closing = out.close()
    assert closing is not None
    assert closing.fault is OutputFault.SEND_ERROR


def test_worked_example_from_the_docs(virtual_buses: Buses) -> None:
    """The configuration example in docs/outputs.md parses and sends what the docs say."""
    table = {
        "kind": "can",
        "role": "motion",
        "arbitration_id": 0x201,
        "data_on": "0F 00 00 00 00 00 00 00",
        "data_off": "06 00 00 00 00 00 00 00",
        "counter_byte": 7,
        "counter_mask": 0x0F,
        "period_ms": 20,
    }
    spec = parse_output_spec("traction", table)
    mine, theirs = virtual_buses
    out = create_output(spec, can_bus=mine)
    out.open(T0)
    out.set(True, T0 + MS)
    assert out.tick(T0 + 21 * MS) is not None
    out.set(False, T0 + 30 * MS)
    assert out.tick(T0 + 50 * MS) is not None
    frames = BusWatcher(theirs, CAN_SPEC).drain()
    assert {(f.arbitration_id, f.is_extended_id, f.dlc) for f in frames} == {(0x201, False, 8)}
    assert [bytes(f.data).hex(" ").upper() for f in frames] == [
        "06 00 00 00 00 00 00 00",
        "0F 00 00 00 00 00 00 01",
        "0F 00 00 00 00 00 00 02",
        "06 00 00 00 00 00 00 03",
        "06 00 00 00 00 00 00 04",
    ]
    out.close()


def test_parse_hex_accepts_common_spellings() -> None:
    """Hex payloads may be written with spaces, colons or nothing between the bytes."""
    assert parse_hex("01 0a FF") == parse_hex("010aff") == parse_hex("01:0a:ff") == b"\x01\x0a\xff"
    assert parse_hex("") == b""


@pytest.mark.parametrize(
    ("change", "key"),
    [
        ({"arbitration_id": 0x800}, "arbitration_id"),
        ({"arbitration_id": -1}, "arbitration_id"),
        ({"arbitration_id": "0x10"}, "arbitration_id"),
        ({"data_on": "01 02 03 04 05 06 07 08 09"}, "data_on"),
        ({"data_on": "0x01"}, "data_on"),
        ({"data_off": 1}, "data_off"),
        ({"data_on": "00 00 00 00"}, "data_on"),
        ({"counter_byte": 4}, "counter_byte"),
        ({"counter_byte": 3, "counter_mask": 0x05}, "counter_mask"),
        ({"counter_mask": 0x100}, "counter_mask"),
        ({"period_ms": 4}, "period_ms"),
        ({"period_ms": 1001}, "period_ms"),
        ({"extended": "yes"}, "extended"),
        ({"period": 20}, "period"),
    ],
)
def test_spec_rejects_bad_options(change: dict[str, object], key: str) -> None:
    """Each bad or unknown CAN option raises ConfigError naming its full key."""
    table: dict[str, object] = {
        "kind": "can",
        "arbitration_id": 0x210,
        "data_on": "01 00 00 00",
        "data_off": "00 00 00 00",
    } | change
    with pytest.raises(ConfigError) as e:
        parse_output_spec("drive", table)
    assert e.value.key == f"outputs.drive.{key}"


def test_spec_defaults() -> None:
    """Without options, a CAN spec is 11-bit, counter-less and sends every 20 ms."""
    spec = parse_output_spec(
        "drive", {"kind": "can", "arbitration_id": 0x7FF, "data_on": "01", "data_off": "00"}
    )
    assert isinstance(spec, CanEnableSpec)
    assert (spec.extended, spec.counter_byte, spec.period_ms) == (False, None, 20)
    assert spec.counter_modulo == 1
    assert spec.frame_data(True, 5) == b"\x01"


def test_extended_id_range() -> None:
    """A 29-bit id is accepted only with extended = true."""
    with pytest.raises(ConfigError, match="extended"):
        CanEnableSpec(name="x", arbitration_id=0x800, data_on=b"\x01", data_off=b"\x00")
    spec = CanEnableSpec(
        name="x", arbitration_id=0x1FFFFFFF, extended=True, data_on=b"\x01", data_off=b"\x00"
    )
    assert spec.arbitration_id == 0x1FFFFFFF

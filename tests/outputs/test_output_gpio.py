"""The GPIO output on a machine without a GPIO chip: its spec, its refusal to open, and its
pulse schedule over an in-memory line handle. The real line runs in the conformance suite
where a gpio-sim chip exists (the VM tier)."""

from __future__ import annotations

import glob

import pytest

from supervisord.errors import ConfigError
from supervisord.outputs import OutputError, OutputFault, parse_output_spec
from supervisord.outputs.gpio import GpioOutput, GpioSpec, find_chip
from supervisord.testkit.output_conformance import T0

MS = 1_000_000

no_chip = pytest.mark.skipif(
    bool(glob.glob("/dev/gpiochip*")), reason="this machine has a GPIO chip"
)


class MemoryLine:
    """A line handle that keeps its level in memory and can be told to ignore writes."""

    def __init__(self) -> None:
        self.level = False
        self.history: list[bool] = []
        self.stuck: bool | None = None
        self.released = False

    def set(self, active: bool) -> None:
        """Drive the line (ignored while stuck)."""
        if self.released:
            raise OSError(9, "request released")
        self.level = active if self.stuck is None else self.stuck
        self.history.append(active)

    def get(self) -> bool:
        """Read the line back."""
        if self.released:
            raise OSError(9, "request released")
        return self.level

    def release(self) -> None:
        """Give the line back."""
        self.released = True


def pulsed(line: MemoryLine, period_ms: int = 10) -> GpioOutput:
    """A pulsed GPIO output over ``line``."""
    spec = GpioSpec(name="relay", chip="gpiochip0", line=4, pulse_period_ms=period_ms)
    return GpioOutput(spec, opener=lambda _: line)


def test_spec_from_config() -> None:
    """A gpio table with a label, a line name, active_low and a pulse parses into a GpioSpec."""
    spec = parse_output_spec(
        "relay",
        {
            "kind": "gpio",
            "chip": "pinctrl-rp1",
            "line": "MOTOR_EN",
            "active_low": True,
            "pulse_period_ms": 10,
        },
    )
    assert isinstance(spec, GpioSpec)
    assert (spec.chip, spec.line, spec.active_low, spec.pulse_period_ms) == (
        "pinctrl-rp1",
        "MOTOR_EN",
        True,
        10,
    )
    assert spec.consumer == "srcsd-relay"


def test_spec_defaults() -> None:
    """A gpio line is active-high and steady unless configured otherwise."""
    spec = parse_output_spec("e", {"kind": "gpio", "chip": "/dev/gpiochip0", "line": 17})
    assert isinstance(spec, GpioSpec)
    assert (spec.line, spec.active_low, spec.pulse_period_ms) == (17, False, None)


@pytest.mark.parametrize(
    ("change", "key"),
    [
        ({"chip": ""}, "chip"),
        ({"chip": None}, "chip"),
        ({"line": "17"}, "line"),
        ({"line": ""}, "line"),
        ({"line": -1}, "line"),
        ({"line": True}, "line"),
        ({"line": 1.5}, "line"),
        ({"active_low": 1}, "active_low"),
        ({"pulse_period_ms": 1}, "pulse_period_ms"),
        ({"pulse_period_ms": 1001}, "pulse_period_ms"),
        ({"bias": "pull-down"}, "bias"),
    ],
)
def test_spec_rejects_bad_options(change: dict[str, object], key: str) -> None:
    """Each bad or unknown gpio option raises ConfigError naming its full key."""
    table: dict[str, object] = {"kind": "gpio", "chip": "gpiochip0", "line": 4} | change
    with pytest.raises(ConfigError) as e:
        parse_output_spec("relay", table)
    assert e.value.key == f"outputs.relay.{key}"


@no_chip
@pytest.mark.parametrize("chip", ["/dev/gpiochip0", "gpiochip0", "pinctrl-bcm2711"])
def test_open_without_a_chip_raises(chip: str) -> None:
    """Opening a line on a chip that does not exist raises OutputError and holds nothing."""
    out = GpioOutput(GpioSpec(name="relay", chip=chip, line=4))
    with pytest.raises(OutputError, match="cannot request GPIO line"):
        out.open(T0)
    assert not out.is_open
    assert out.close() is None


@no_chip
def test_find_chip_reports_no_match() -> None:
    """A label no chip carries is a LookupError that says so."""
    with pytest.raises(LookupError, match="no chip named or labelled 'nothing'"):
        find_chip("nothing")


def test_steady_line_reads_back_through_the_handle() -> None:
    """A steady line writes each level once and reads it back; it has no deadline."""
    line = MemoryLine()
    out = GpioOutput(GpioSpec(name="e", chip="c", line=0), opener=lambda _: line)
    assert out.open(T0).ok
    assert line.history == []  # requested inactive by the kernel: open only reads back
    assert out.set(True, T0).ok
    assert out.next_deadline() is None
    assert out.tick(T0 + 1000 * MS) is None
    assert out.close() is not None
    assert (line.history, line.level, line.released) == ([True, False], False, True)


def test_mismatch_and_io_error_are_faults() -> None:
    """SR-6.2: a line that ignores a write is MISMATCH; one whose request is gone is IO_ERROR."""
    line = MemoryLine()
    out = GpioOutput(GpioSpec(name="e", chip="c", line=0), opener=lambda _: line)
    out.open(T0)
    line.stuck = True
    rb = out.set(False, T0)
    assert rb.fault is OutputFault.MISMATCH
    assert rb.observed is True
    line.released = True
    assert out.set(False, T0).fault is OutputFault.IO_ERROR
    closing = out.close()
    assert closing is not None
    assert closing.fault is OutputFault.IO_ERROR


def test_pulse_toggles_only_while_on() -> None:
    """SR-6.4: a pulsed enable toggles at each due tick while on, and is steady off after set
    off."""
    line = MemoryLine()
    out = pulsed(line)
    out.open(T0)
    assert out.next_deadline() is None
    out.set(True, T0)
    levels = [line.level]
    for k in range(1, 5):
        assert out.next_deadline() == T0 + k * 10 * MS
        rb = out.tick(T0 + k * 10 * MS)
        assert rb is not None
        assert rb.ok
        assert rb.requested is True
        levels.append(line.level)
    assert levels == [True, False, True, False, True]
    off = out.set(False, T0 + 45 * MS)
    assert (off.ok, line.level) == (True, False)
    assert out.next_deadline() is None
    assert out.tick(T0 + 1000 * MS) is None
    assert line.level is False
    out.close()


def test_pulse_is_not_restarted_by_reasserting_on() -> None:
    """Re-asserting on keeps the pulse train's phase and schedule."""
    line = MemoryLine()
    out = pulsed(line)
    out.open(T0)
    out.set(True, T0)
    out.tick(T0 + 10 * MS)
    assert line.level is False
    rb = out.set(True, T0 + 12 * MS)
    assert (rb.ok, rb.written, line.level) == (True, False, False)
    assert out.next_deadline() == T0 + 20 * MS
    out.close()


def test_pulse_before_deadline_does_nothing() -> None:
    """A tick before the next edge writes nothing."""
    line = MemoryLine()
    out = pulsed(line)
    out.open(T0)
    out.set(True, T0)
    writes = len(line.history)
    assert out.tick(T0 + 10 * MS - 1) is None
    assert len(line.history) == writes
    out.close()


def test_pulse_mismatch_is_reported_by_tick() -> None:
    """A pulse edge that does not read back is a MISMATCH from tick."""
    line = MemoryLine()
    out = pulsed(line)
    out.open(T0)
    out.set(True, T0)
    line.stuck = True
    rb = out.tick(T0 + 10 * MS)
    assert rb is not None
    assert rb.fault is OutputFault.MISMATCH
    assert (rb.written, rb.observed) == (False, True)
    out.close()

"""The safety configuration validates itself and names key, value and fix on error."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from supervisord.config import load_config
from supervisord.errors import ConfigError
from supervisord.safety import ClientSpec, OutputRole, OutputSpec, SafetyConfig, Transport
from supervisord.safety.availability import Reaction
from supervisord.safety.prooftest import ProofTestPolicy
from supervisord.timebase import NS_PER_MS as MS


def test_defaults_follow_the_rules() -> None:
    """Defaults: serial, 200 ms VSC timeout, 20 Hz, 500 ms hold, no local reset, watchdog
    required, a 500 ms client timeout, a proof test's clear wait of 10 s (docs/safety.md
    "The proof test", SR-5.3), and the remote's battery at 20 % only warned of (SR-8.12)."""
    config = SafetyConfig()
    assert config.transport is Transport.SERIAL
    assert config.vsc_timeout_ns == 200 * MS
    assert config.heartbeat_hz == 20
    assert config.rearm_hold_ms == 500
    assert config.local_reset is False
    assert config.require_watchdog is True
    assert config.prooftest_clear_ms == 10_000
    assert config.min_remote_battery == 20
    assert config.on_estop_unavailable is Reaction.WARN
    assert ClientSpec("planner").timeout_ms == 500


@pytest.mark.parametrize(
    ("transport", "timeout_ms"),
    [(Transport.SERIAL, 200), (Transport.CAN, 300), (Transport.HID, 200)],
)
def test_each_transport_has_its_vsc_timeout(transport: Transport, timeout_ms: int) -> None:
    """SR-2.2, docs/configuration.md: ``vsc_link_lost`` after 200 ms of silence on serial and
    HID and 300 ms on CAN, unless ``vsc_timeout_ms`` says otherwise."""
    config = SafetyConfig(transport=transport, require_watchdog=transport is Transport.SERIAL)
    assert config.vsc_timeout_ns == timeout_ms * MS
    assert config.vsc_timeout_ns == timeout_ms * 1_000_000


@pytest.mark.parametrize("policy", list(ProofTestPolicy))
def test_serial_takes_every_proof_test_policy(policy: ProofTestPolicy) -> None:
    """SR-5.3, docs/configuration.md: on serial every policy of ``vsc.prooftest`` is accepted
    (only CAN and HID are limited to ``off``)."""
    assert SafetyConfig(prooftest=policy).prooftest is policy


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"heartbeat_hz": 19}, "vsc.heartbeat_hz"),
        ({"heartbeat_hz": 51}, "vsc.heartbeat_hz"),
        ({"heartbeat_hz": True}, "vsc.heartbeat_hz"),
        ({"vsc_timeout_ms": 0}, "vsc.timeout_ms"),
        ({"vsc_timeout_ms": True}, "vsc.timeout_ms"),
        ({"rearm_hold_ms": 10}, "rearm.hold_ms"),
        ({"local_reset": 1}, "rearm.local_reset"),
        ({"transport": "serial"}, "vsc.transport"),
        ({"transport": Transport.CAN}, "vsc.require_watchdog"),
        ({"clients": (ClientSpec("a"), ClientSpec("a"))}, "clients.name"),
        ({"outputs": [OutputSpec("x", OutputRole.POWER)]}, "outputs"),
        ({"outputs": ("drive",)}, "outputs"),
        ({"outputs": (OutputSpec("a"), OutputSpec("a", OutputRole.POWER))}, "outputs.name"),
        ({"clients": [ClientSpec("a")]}, "clients"),
        ({"clients": ("a",)}, "clients"),
        ({"require_watchdog": 1}, "vsc.require_watchdog"),
        ({"prooftest": "block"}, "vsc.prooftest"),
        ({"on_estop_unavailable": "hold"}, "vsc.on_estop_unavailable"),
        ({"transport": Transport.HID, "prooftest": ProofTestPolicy.BLOCK}, "vsc.prooftest"),
        (
            {
                "transport": Transport.CAN,
                "require_watchdog": False,
                "prooftest": ProofTestPolicy.RECORD,
            },
            "vsc.prooftest",
        ),
    ],
)
def test_bad_values_are_refused(kwargs: dict[str, object], key: str) -> None:
    """Each bad value raises ConfigError naming its key as the robot's file spells it, and a
    fix."""
    with pytest.raises(ConfigError) as caught:
        SafetyConfig(**kwargs)  # type: ignore[arg-type]
    assert caught.value.key == key
    assert caught.value.fix


def test_can_needs_the_watchdog_switched_off_explicitly() -> None:
    """On CAN ``require_watchdog = false`` must be written out; then the timeout is 300 ms."""
    config = SafetyConfig(transport=Transport.CAN, require_watchdog=False)
    assert config.vsc_timeout_ns == 300 * MS


def test_bad_client_and_output_specs_are_refused() -> None:
    """Names must fit the name pattern and timeouts their range; a bad output name is refused
    naming its key."""
    with pytest.raises(ConfigError):
        ClientSpec("has space")
    with pytest.raises(ConfigError):
        ClientSpec("#1")
    with pytest.raises(ConfigError):
        ClientSpec("ok", timeout_ms=5)
    with pytest.raises(ConfigError):
        OutputSpec("drive", "motion")  # type: ignore[arg-type]
    for name in ("has space", "#1", "", "x" * 33):
        with pytest.raises(ConfigError) as caught:
            OutputSpec(name)
        assert caught.value.key == "outputs.name"


ROBOT_FILE = """\
[robot]
name = "bot"

[vsc]
transport = "can"
require_watchdog = false

[[clients]]
name = "planner"
timeout_ms = 300

[[outputs]]
name = "drive"
kind = "sim"
role = "motion"

[[outputs]]
name = "lamp"
kind = "sim"
role = "power"
"""


def test_the_loader_builds_the_safety_config_from_a_file(tmp_path: Path) -> None:
    """SR-11.2: the robot's file becomes a SafetyConfig with typed clients and outputs."""
    file = tmp_path / "robot.toml"
    file.write_text(ROBOT_FILE)
    config = load_config(file).safety
    assert config.transport is Transport.CAN
    assert config.clients == (ClientSpec("planner", 300),)
    assert [(o.name, o.role) for o in config.outputs] == [
        ("drive", OutputRole.MOTION),
        ("lamp", OutputRole.POWER),
    ]


@pytest.mark.parametrize(
    ("old", "new", "key"),
    [
        ("require_watchdog = false", "require_watchdog = false\nheartbeat = 20", "vsc.heartbeat"),
        ('transport = "can"', 'transport = "usb"', "vsc.transport"),
        ("require_watchdog = false", "", "vsc.require_watchdog"),
        ("timeout_ms = 300", "timeout = 3", "clients[0].timeout"),
        ('role = "power"', 'role = "laser"', "outputs[1].role"),
        (
            '[[clients]]\nname = "planner"\ntimeout_ms = 300',
            '[clients]\nname = "planner"',
            "clients",
        ),
    ],
)
def test_the_loader_names_the_file_and_key(tmp_path: Path, old: str, new: str, key: str) -> None:
    """SR-11.2: unknown keys and bad safety values in a file are errors naming the file and
    the key as the file spells it."""
    file = tmp_path / "robot.toml"
    assert old in ROBOT_FILE
    file.write_text(ROBOT_FILE.replace(old, new, 1))
    with pytest.raises(ConfigError) as caught:
        load_config(file)
    assert caught.value.key == key
    assert caught.value.file == str(file)


@pytest.mark.parametrize(
    ("field", "key", "lowest", "highest"),
    [
        ("vsc_timeout_ms", "vsc.timeout_ms", 50, 1000),
        ("heartbeat_hz", "vsc.heartbeat_hz", 20, 50),
        ("rearm_hold_ms", "rearm.hold_ms", 100, 60_000),
        ("prooftest_clear_ms", "vsc.prooftest_clear_ms", 1_000, 600_000),
        ("min_remote_battery", "vsc.min_remote_battery", 0, 100),
    ],
)
def test_each_range_takes_its_ends_and_refuses_one_past_them(
    field: str, key: str, lowest: int, highest: int
) -> None:
    """SR-11.2, SR-2.2, SR-5.1: every range is inclusive at both ends, as docs/configuration.md
    gives it, and one past either end is refused naming the key."""
    for value in (lowest, highest):
        SafetyConfig(**{field: value})  # type: ignore[arg-type]
    for value in (lowest - 1, highest + 1):
        with pytest.raises(ConfigError) as caught:
            SafetyConfig(**{field: value})  # type: ignore[arg-type]
        assert caught.value.key == key


def test_a_client_timeout_and_uid_take_their_ends_and_refuse_one_past_them() -> None:
    """SR-11.2, SR-2.4, SR-8.6: a client's timeout is 20 to 10000 ms and its uid 0 to 2^32 - 2
    ((uid_t) -1 means "no user"), both inclusive."""
    for timeout in (20, 10_000):
        ClientSpec("a", timeout_ms=timeout)
    for uid in (0, (1 << 32) - 2):
        ClientSpec("a", uid=uid)
    wrong: tuple[dict[str, Any], ...] = (
        {"timeout_ms": 19},
        {"timeout_ms": 10_001},
        {"uid": -1},
        {"uid": (1 << 32) - 1},
    )
    for kwargs in wrong:
        with pytest.raises(ConfigError):
            ClientSpec("a", **kwargs)

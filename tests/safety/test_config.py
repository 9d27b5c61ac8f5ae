"""The safety configuration validates itself and names key, value and fix on error."""

from __future__ import annotations

import pytest

from supervisord.errors import ConfigError
from supervisord.safety import ClientSpec, OutputRole, OutputSpec, SafetyConfig, Transport


def test_defaults_follow_the_rules() -> None:
    """Defaults: serial, 200 ms VSC timeout, 20 Hz, 500 ms hold, no local reset, watchdog
    required, and a 500 ms client timeout."""
    config = SafetyConfig()
    assert config.transport is Transport.SERIAL
    assert config.effective_vsc_timeout_ms == 200
    assert config.heartbeat_hz == 20
    assert config.rearm_hold_ms == 500
    assert config.local_reset is False
    assert config.require_watchdog is True
    assert ClientSpec("planner").timeout_ms == 500


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"heartbeat_hz": 19}, "heartbeat_hz"),
        ({"heartbeat_hz": 51}, "heartbeat_hz"),
        ({"heartbeat_hz": True}, "heartbeat_hz"),
        ({"vsc_timeout_ms": 0}, "vsc_timeout_ms"),
        ({"rearm_hold_ms": 10}, "rearm_hold_ms"),
        ({"local_reset": 1}, "local_reset"),
        ({"transport": "serial"}, "transport"),
        ({"transport": Transport.CAN}, "require_watchdog"),
        ({"clients": (ClientSpec("a"), ClientSpec("a"))}, "clients.name"),
        ({"outputs": [OutputSpec("x", OutputRole.POWER)]}, "outputs"),
    ],
)
def test_bad_values_are_refused(kwargs: dict[str, object], key: str) -> None:
    """Each bad value raises ConfigError naming its key and a fix."""
    with pytest.raises(ConfigError) as caught:
        SafetyConfig(**kwargs)  # type: ignore[arg-type]
    assert caught.value.key == key
    assert caught.value.fix


def test_can_needs_the_watchdog_switched_off_explicitly() -> None:
    """On CAN ``require_watchdog = false`` must be written out; then the timeout is 300 ms."""
    config = SafetyConfig(transport=Transport.CAN, require_watchdog=False)
    assert config.effective_vsc_timeout_ms == 300


def test_bad_client_and_output_specs_are_refused() -> None:
    """Names must fit the name pattern and timeouts their range."""
    with pytest.raises(ConfigError):
        ClientSpec("has space")
    with pytest.raises(ConfigError):
        ClientSpec("#1")
    with pytest.raises(ConfigError):
        ClientSpec("ok", timeout_ms=5)
    with pytest.raises(ConfigError):
        OutputSpec("drive", "motion")  # type: ignore[arg-type]


def test_from_mapping_reads_a_parsed_file() -> None:
    """A parsed TOML-like mapping becomes a config with typed clients and outputs."""
    config = SafetyConfig.from_mapping(
        {
            "transport": "can",
            "require_watchdog": False,
            "clients": [{"name": "planner", "timeout_ms": 300}],
            "outputs": [{"name": "drive", "role": "motion"}, {"name": "lamp", "role": "power"}],
        }
    )
    assert config.transport is Transport.CAN
    assert config.clients == (ClientSpec("planner", 300),)
    assert config.outputs[1] == OutputSpec("lamp", OutputRole.POWER)


@pytest.mark.parametrize(
    ("data", "key"),
    [
        ({"heartbeat": 20}, "heartbeat"),
        ({"transport": "usb"}, "transport"),
        ({"transport": "can"}, "require_watchdog"),
        ({"clients": [{"name": "a", "timeout": 3}]}, "clients.timeout"),
        ({"outputs": [{"name": "a", "role": "laser"}]}, "outputs.a.role"),
        ({"clients": "planner"}, "clients"),
    ],
)
def test_from_mapping_names_the_file_and_key(data: dict[str, object], key: str) -> None:
    """Unknown keys and bad values in a file are errors naming the file and the key."""
    with pytest.raises(ConfigError) as caught:
        SafetyConfig.from_mapping(data, file="robot.toml")
    assert caught.value.key == key
    assert caught.value.file == "robot.toml"

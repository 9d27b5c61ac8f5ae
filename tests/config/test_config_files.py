"""Reading the file: the shipped examples, unreadable files, TOML syntax errors with their
position, what ``srcsd --check-config`` prints, and what every error message names."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import supervisord
from supervisord.cli.demo import DEMO_CONFIG
from supervisord.config import (
    CanBus,
    DaemonConfig,
    SerialPort,
    check_config_main,
    load_config,
    read_toml,
)
from supervisord.config.collect import collect
from supervisord.config.loader import NotOnMachine
from supervisord.errors import ConfigError
from supervisord.outputs import OutputKind, OutputRole
from supervisord.safety.config import Transport

CONFIG_DIR = Path(__file__).resolve().parents[2] / "config"
EXAMPLES = [*sorted(CONFIG_DIR.glob("*.toml")), DEMO_CONFIG]
ROBOT_USER = "robot"
"""The user the examples' clients run as: the administrator creates it on the robot."""

VALID = """\
[robot]
name = "bot"

[vsc]
transport = "serial"

[[outputs]]
name = "drive"
kind = "sim"
"""


def write(tmp_path: Path, text: str | bytes) -> Path:
    """``text`` as the file robot.toml in ``tmp_path``."""
    file = tmp_path / "robot.toml"
    if isinstance(text, bytes):
        file.write_bytes(text)
    else:
        file.write_text(text)
    return file


def srcs_admin_exists(name: str) -> bool:
    """A group lookup in which only the examples' admin and operator groups exist."""
    return name in ("srcs-admin", "srcs-operator")


def test_the_three_examples_are_shipped() -> None:
    """config/ holds the serial-GPIO and CAN examples; the demo's config is package data."""
    assert [p.name for p in EXAMPLES] == [
        "example-can.toml",
        "example-serial-gpio.toml",
        "demo.toml",
    ]
    assert DEMO_CONFIG.is_relative_to(Path(supervisord.__file__).parent)


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_every_example_loads(path: Path) -> None:
    """Each shipped example passes the whole validator, but for the users its clients are bound
    to, which this machine may lack (a warning, SR-11.2)."""
    report = collect(path, group_exists=srcs_admin_exists)
    assert report.config is not None, report.findings
    assert report.config.outputs
    assert report.config.source == path
    for finding in report.findings:
        assert finding.warning, finding
        if isinstance(finding.error, NotOnMachine):
            assert finding.error.key.endswith(".user")
            assert finding.error.value == ROBOT_USER


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_every_example_binds_its_clients(path: Path) -> None:
    """SR-8.6: each shipped example binds every required client to a user (docs/safety.md
    "Clients bound to a user"), so none is warned about as unbound."""
    clients = read_toml(path).get("clients", [])
    assert isinstance(clients, list)
    assert all("user" in client or "uid" in client for client in clients), path
    report = collect(path, group_exists=srcs_admin_exists)
    assert not any("unbound" in finding.error.fix for finding in report.findings)


def example(name: str) -> DaemonConfig:
    """The shipped example ``name``, loaded as on a robot with its user and group (the user's
    lookup on this machine set aside)."""
    config = collect(CONFIG_DIR / name, group_exists=srcs_admin_exists).config
    assert config is not None
    return config


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_every_example_line_is_commented(path: Path) -> None:
    """Every key of an example carries a comment, on its line or on the line just above."""
    lines = path.read_text().splitlines()
    for number, line in enumerate(lines):
        if "=" not in line or line.lstrip().startswith("#"):
            continue
        above = lines[number - 1].lstrip() if number else ""
        assert "#" in line or above.startswith("#"), f"{path.name}:{number + 1}: {line}"


def test_serial_gpio_example(tmp_path: Path) -> None:
    """The serial example: a serial VSC, two GPIO outputs (motion, pulsed power), two clients."""
    config = example("example-serial-gpio.toml")
    assert config.vsc.transport is Transport.SERIAL
    assert isinstance(config.vsc.link, SerialPort)
    assert [(o.kind, o.role) for o in config.outputs] == [
        (OutputKind.GPIO, OutputRole.MOTION),
        (OutputKind.GPIO, OutputRole.POWER),
    ]
    assert [c.name for c in config.safety.clients] == ["autonomy", "localization"]
    assert config.api.admin_group == "srcs-admin"


def test_can_example_is_the_docs_worked_example() -> None:
    """The CAN example's traction output is the worked example, on the VSC's bus."""
    config = example("example-can.toml")
    assert config.vsc.transport is Transport.CAN
    assert config.can_output_bus == CanBus("socketcan", "can0", 250_000)
    traction = config.outputs[0]
    assert traction.kind is OutputKind.CAN
    assert getattr(traction, "arbitration_id", None) == 0x201
    assert getattr(traction, "data_on", None) == bytes.fromhex("0F 00 00 00 00 00 00 00")
    assert getattr(traction, "data_off", None) == bytes.fromhex("06 00 00 00 00 00 00 00")
    assert (getattr(traction, "counter_byte", None), getattr(traction, "counter_mask", None)) == (
        7,
        0x0F,
    )
    assert config.safety.require_watchdog is False


def test_demo_config_runs_without_hardware_or_clients(tmp_path: Path) -> None:
    """The demo: serial to a path under the run folder, sim outputs, local reset, no clients."""
    config = load_config(DEMO_CONFIG, base_dir=tmp_path)
    assert config.vsc.link == SerialPort(tmp_path / "srcs-demo/vsc", 115_200)
    assert {o.kind for o in config.outputs} == {OutputKind.SIM}
    assert [getattr(o, "path", None) for o in config.outputs] == [
        tmp_path / "srcs-demo/drive",
        tmp_path / "srcs-demo/power",
    ]
    assert config.record.path == tmp_path / "srcs-demo/stops.jsonl"
    assert config.record.journal is False
    assert config.api.socket == tmp_path / "srcs-demo/api.sock"
    assert config.api.admin_group is None
    assert config.safety.local_reset is True
    assert config.safety.clients == ()


def test_missing_file(tmp_path: Path) -> None:
    """A file that cannot be read is an error naming it and the reason."""
    missing = tmp_path / "nope.toml"
    with pytest.raises(ConfigError) as caught:
        load_config(missing)
    assert caught.value.file == str(missing)
    assert caught.value.key == "file"
    assert "No such file" in caught.value.fix


def test_not_utf8(tmp_path: Path) -> None:
    """Bytes that are not UTF-8 are reported at their line and column."""
    file = write(tmp_path, b'[robot]\nname = "b\xffot"\n')
    with pytest.raises(ConfigError) as caught:
        load_config(file)
    assert caught.value.key == "line 2, column 10"
    assert "UTF-8" in caught.value.fix


@pytest.mark.parametrize(
    ("text", "key", "shown", "reason"),
    [
        ("[robot]\nname = bot\n", "line 2, column 8", "name = bot", "invalid value"),
        ('[robot]\nname = "bot\n', "line 2, column 12", 'name = "bot', "illegal character"),
        ("[robot\n", "line 1, column 7", "[robot", "expected ']'"),
        ('[robot]\nname = "a"\nname = "b"\n', "line 3, column 11", 'name = "b"', "overwrite"),
        ("[robot]\nname =", "line 2, column 7", "name =", "invalid value"),
    ],
)
def test_toml_syntax_error_names_the_position(
    tmp_path: Path, text: str, key: str, shown: str, reason: str
) -> None:
    """A TOML syntax error names the file, the line and column, the line's text and the cause."""
    file = write(tmp_path, text)
    with pytest.raises(ConfigError) as caught:
        load_config(file)
    error = caught.value
    assert error.file == str(file)
    assert error.key == key
    assert error.value == shown
    assert reason in error.fix.lower()
    assert str(error).startswith(f"{file}: {key} = {shown!r}: correct the TOML syntax there (")


def test_error_message_names_file_key_value_and_fix(tmp_path: Path) -> None:
    """The printed message holds the file, the dotted key, the value and the fix, in order."""
    file = write(
        tmp_path, VALID.replace('transport = "serial"', 'timeout_ms = 5000\ntransport = "serial"')
    )
    with pytest.raises(ConfigError) as caught:
        load_config(file)
    assert str(caught.value) == f"{file}: vsc.timeout_ms = 5000: use a whole number from 50 to 1000"


def test_check_config_ok(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--check-config prints one OK line with the robot, transport and counts, and returns 0."""
    file = write(tmp_path, VALID + '\n[[clients]]\nname = "nav"\n')
    assert check_config_main(file) == 0
    out, err = capsys.readouterr()
    assert out == f"{file}: OK — robot bot, transport serial, 1 output, 1 client\n"
    line = 1 + VALID.splitlines().index('kind = "sim"')
    assert err.splitlines() == [
        f'{file}:{line}: warning: outputs[0].kind = "sim": drive is simulated: it drives no '
        "hardware",
        f"{file}:{line + 2}: warning: clients[0].user = (not set): unbound: any program that can "
        'reach the socket may say hello as "nav" and keep it alive after it died: bind it to the '
        'user it runs as (user = "NAME", or uid = N)',
    ]


def test_check_config_counts_in_plural(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The OK line counts several outputs and no clients in the plural."""
    file = write(tmp_path, VALID + '\n[[outputs]]\nname = "power"\nkind = "sim"\n')
    assert check_config_main(file) == 0
    assert "2 outputs, 0 clients" in capsys.readouterr().out


def test_check_config_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--check-config prints the error to stderr with its line and the value as TOML writes
    it, nothing to stdout, and returns 1."""
    file = write(tmp_path, VALID.replace('"serial"', '"serail"'))
    assert check_config_main(file) == 1
    out, err = capsys.readouterr()
    assert out == ""
    line = 1 + VALID.splitlines().index('transport = "serial"')
    assert err.startswith(
        f"{file}:{line}: error: vsc.transport = \"serail\": did you mean 'serial'? use one of "
        '"serial"'
    )


def test_loading_imports_no_unused_plugin(tmp_path: Path) -> None:
    """A serial config with sim outputs loads without importing gpiod or python-can."""
    file = write(tmp_path, VALID)
    probe = (
        "import sys\nfrom supervisord.config import load_config\n"
        f"load_config({str(file)!r})\n"
        "print(' '.join(sorted(m.split('.')[0] for m in sys.modules)))"
    )
    out = subprocess.run([sys.executable, "-c", probe], check=True, capture_output=True, text=True)
    loaded = set(out.stdout.split())
    assert "gpiod" not in loaded
    assert "can" not in loaded


def test_a_huge_value_is_shown_cut(tmp_path: Path) -> None:
    """SR-11.2: an error names a megabyte-long value by its first characters, not whole: the
    message stays one short line."""
    file = write(tmp_path, VALID.replace('name = "bot"', f'name = "{"x" * 1_000_000}"'))
    with pytest.raises(ConfigError) as caught:
        load_config(file)
    message = str(caught.value)
    assert message.startswith(f"{file}: robot.name = 'xxxx")
    assert len(message) < len(str(file)) + 200


def test_a_client_may_demand_progress(tmp_path: Path) -> None:
    """SR-8.16: ``progress = true`` in a ``[[clients]]`` entry reaches the core's client spec;
    it defaults to false, and a value that is not true or false is refused with its key."""
    both = '\n[[clients]]\nname = "nav"\nprogress = true\n[[clients]]\nname = "map"\n'
    config = load_config(write(tmp_path, VALID + both))
    assert [(c.name, c.progress) for c in config.safety.clients] == [("nav", True), ("map", False)]
    wrong = write(tmp_path, VALID + '\n[[clients]]\nname = "nav"\nprogress = 1\n')
    with pytest.raises(ConfigError, match=r"clients\[0\]\.progress = 1"):
        load_config(wrong)

"""The clients' reader of a robot's config (``supervisord/config/client.py``): it finds the
daemon where the daemon's own loader puts it, for every shipped config, refuses a mistake in
what it reads with the loader's very words, and leaves the safety sections to the daemon."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import pytest

from supervisord.cli.demo import DEMO_CONFIG
from supervisord.config import load_config
from supervisord.config.client import ClientConfig, load_client_config
from supervisord.config.paths import API_KEY_NAMES, RECORD, RENAMED, SECTION_NAMES
from supervisord.config.schema import API, SECTION, SECTIONS
from supervisord.config.toml_file import MAX_CONFIG_BYTES
from supervisord.errors import ConfigError

CONFIG_DIR = Path(__file__).resolve().parents[2] / "config"
SHIPPED = [*sorted(CONFIG_DIR.glob("*.toml")), DEMO_CONFIG]
"""Every config the package ships: the examples (installed beside the docs) and the demo's."""

VALID = """\
[robot]
name = "bot"

[vsc]
transport = "serial"

[[outputs]]
name = "drive"
kind = "sim"
"""


def on_the_robot(path: Path) -> ClientConfig:
    """What the daemon's loader makes of ``path``'s sockets and record, on a robot where the
    config's users and groups exist (this machine may lack them)."""
    config = load_config(path, group_exists=lambda _: True, user_uid=lambda _: 1000)
    return ClientConfig(config.api.socket, config.api.operator_path, config.record.path)


def test_every_shipped_config_is_found() -> None:
    """SR-8.8: the comparison below runs on the two examples and the demo's config."""
    assert [path.name for path in SHIPPED] == [
        "example-can.toml",
        "example-serial-gpio.toml",
        "demo.toml",
    ]


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.name)
def test_the_client_finds_the_daemon_where_the_loader_puts_it(path: Path) -> None:
    """SR-8.8: for every shipped config, the clients' reader gives the client socket, the
    operator socket and the record's path the daemon's loader gives (relative paths resolved
    against the config's directory, as for the demo's)."""
    assert load_client_config(path) == on_the_robot(path)


def test_the_defaults_are_the_loaders(tmp_path: Path) -> None:
    """SR-8.8: a config without ``[api]`` and ``[record]`` is read with the loader's defaults,
    and an ``operator_socket`` given relative is resolved as the loader resolves it."""
    bare = tmp_path / "bare.toml"
    bare.write_text(VALID)
    assert load_client_config(bare) == on_the_robot(bare)
    assert load_client_config(bare).socket == Path("/run/srcsd/api.sock")
    moved = tmp_path / "moved.toml"
    moved.write_text(
        VALID + '[api]\nsocket = "run/api.sock"\noperator_socket = "op.sock"\n'
        '[record]\npath = "stops.jsonl"\nkeep = 2\n'
    )
    assert load_client_config(moved) == on_the_robot(moved)
    assert load_client_config(moved).operator_socket == tmp_path / "op.sock"


def test_the_names_the_client_checks_are_the_schemas() -> None:
    """SR-11.2: the sections and ``[api]``'s keys the client accepts are the schema's, and
    ``[record]``'s declarations are the schema's own, so a misspelling is refused alike."""
    assert tuple(section.name for section in SECTIONS) == SECTION_NAMES
    assert tuple(key.name for key in API) == API_KEY_NAMES
    assert SECTION["record"].keys == RECORD
    assert RENAMED["log"] == "record"


def test_the_client_reads_a_config_with_every_section(tmp_path: Path) -> None:
    """SR-11.2, SR-9.6: a config that sets ``[realtime]`` (the daemon's memory lock) is read
    by srcsctl as by the daemon: no section the daemon takes is an unknown one to it."""
    path = tmp_path / "robot.toml"
    path.write_text(VALID + '[realtime]\nlock_memory = "required"\n')
    assert load_client_config(path) == on_the_robot(path)


def _fifo(tmp_path: Path) -> str:
    os.mkfifo(tmp_path / "fifo.jsonl")
    return '[record]\npath = "fifo.jsonl"\n'


MISTAKES: dict[str, Callable[[Path], str | bytes]] = {
    "socket not text": lambda _: VALID + "[api]\nsocket = 5\n",
    "socket a directory": lambda _: VALID + '[api]\nsocket = "run/"\n',
    "socket too long": lambda _: VALID + f'[api]\nsocket = "{"a" * 120}.sock"\n',
    "operator socket too long": lambda _: VALID + f'[api]\noperator_socket = "{"a" * 120}"\n',
    "a key of [api] misspelt": lambda _: VALID + '[api]\nsockte = "x.sock"\n',
    "a section misspelt": lambda _: VALID + '[apii]\nsocket = "x.sock"\n',
    "an old section name": lambda _: VALID + '[log]\npath = "x.jsonl"\n',
    "api not a table": lambda _: 'api = "x.sock"\n' + VALID,
    "record a directory": lambda _: VALID + '[record]\npath = "dir/"\n',
    "record keep out of range": lambda _: VALID + "[record]\nkeep = -1\n",
    "a key of [record] misspelt": lambda _: VALID + '[record]\npaht = "x.jsonl"\n',
    "record a FIFO": lambda tmp_path: VALID + _fifo(tmp_path),
    "TOML syntax": lambda _: "[robot\nname = 1\n",
    "not UTF-8": lambda _: b"\xff\xfe",
    "too large": lambda _: b"# padding\n" * (MAX_CONFIG_BYTES // 10 + 1),
}


@pytest.mark.parametrize("mistake", MISTAKES)
def test_a_mistake_in_what_the_client_reads_is_refused_as_the_loader_refuses_it(
    tmp_path: Path, mistake: str
) -> None:
    """SR-11.2: a file or a value the client reads that the loader refuses, the client
    refuses too, with the same :class:`ConfigError` (file, key, value and fix): the same
    message on stderr and the same exit status as before."""
    path = tmp_path / "robot.toml"
    text = MISTAKES[mistake](tmp_path)
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text)
    with pytest.raises(ConfigError) as daemon:
        on_the_robot(path)
    with pytest.raises(ConfigError) as client:
        load_client_config(path)
    assert str(client.value) == str(daemon.value)
    assert client.value.file == str(path)


def test_a_missing_file_is_refused_as_the_loader_refuses_it(tmp_path: Path) -> None:
    """SR-11.2: a config that is not there is refused with the loader's words."""
    path = tmp_path / "absent.toml"
    with pytest.raises(ConfigError) as daemon:
        on_the_robot(path)
    with pytest.raises(ConfigError) as client:
        load_client_config(path)
    assert str(client.value) == str(daemon.value)
    assert "No such file or directory" in str(client.value)


SAFETY_MISTAKES = {
    "a safety value": VALID.replace('"serial"', '"serial"\ntimeout_ms = -5'),
    "an unknown key in [vsc]": VALID.replace('"serial"', '"serial"\ntimeout = 100'),
    "no output": VALID.split("[[outputs]]", maxsplit=1)[0],
    "a client's user missing": VALID + '[[clients]]\nname = "planner"\nuser = "nobody-here-x"\n',
}


@pytest.mark.parametrize("mistake", SAFETY_MISTAKES)
def test_the_safety_sections_are_the_daemons_to_judge(tmp_path: Path, mistake: str) -> None:
    """SR-8.8: a mistake outside what the client reads (a safety value, an output, a user of
    this machine) is the daemon's to refuse, which then does not start; the client still
    finds where the daemon would be."""
    path = tmp_path / "robot.toml"
    path.write_text(SAFETY_MISTAKES[mistake] + '[api]\nsocket = "robot.sock"\n')
    with pytest.raises(ConfigError):
        load_config(path, group_exists=lambda _: True)
    assert load_client_config(path).socket == tmp_path / "robot.sock"

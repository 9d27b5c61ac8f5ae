"""Every path in the config has one owner (SR-11.1; docs/configuration.md "One owner
per path"): the VSC's port, every output's file or GPIO line, the record and its rotated
files, the API socket, compared after resolving relative paths and symlinks, across all
sections. A clash is a ConfigError naming both keys, and ``srcsd --check-config`` fails."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Mapping
from pathlib import Path

import pytest

from supervisord.errors import ConfigError
from tests.config.test_config_rules import GPIO, changed, dump, load, refused


def _sim(name: str, path: str) -> dict[str, object]:
    return {"name": name, "kind": "sim", "role": "motion", "path": path}


def _clash(tmp_path: Path, changes: Mapping[str, object], key: str, other: str) -> ConfigError:
    """Loading is refused at ``key``, and the message names ``other`` too."""
    error = refused(tmp_path, changes)
    assert error.key == key, str(error)
    assert other in error.fix, str(error)
    assert "one owner" in error.fix, str(error)
    return error


def test_record_path_that_is_an_outputs_file_is_refused(tmp_path: Path) -> None:
    """``record.path`` equal to a sim output's ``path``: each write of the output would
    replace the record. Refused naming both keys."""
    _clash(
        tmp_path,
        {"outputs[0].path": "state/drive", "record": {"path": "state/drive"}},
        "record.path",
        "outputs[0].path",
    )


def test_api_socket_that_is_an_outputs_file_is_refused(tmp_path: Path) -> None:
    """``api.socket`` equal to a sim output's ``path`` (the output's write destroys the
    socket, or the socket the output): refused naming both keys."""
    _clash(
        tmp_path,
        {"outputs[0].path": str(tmp_path / "api.sock"), "api": {"socket": "api.sock"}},
        "api.socket",
        "outputs[0].path",
    )


def test_record_path_that_is_the_socket_is_refused(tmp_path: Path) -> None:
    """The record and the socket at one path (the socket's start removes the record):
    refused naming both keys."""
    _clash(
        tmp_path,
        {"outputs[0].path": "out/drive", "record": {"path": "run/x"}, "api": {"socket": "run/x"}},
        "api.socket",
        "record.path",
    )


def test_a_rotated_record_file_is_owned_by_the_record(tmp_path: Path) -> None:
    """The record's rotated files (``path.1`` ... ``path.keep``) are the record's too: an
    output writing ``stops.jsonl.2`` with ``keep = 3`` is refused."""
    error = _clash(
        tmp_path,
        {"outputs[0].path": "stops.jsonl.2", "record": {"path": "stops.jsonl", "keep": 3}},
        "record.path",
        "outputs[0].path",
    )
    assert "rotated file 2" in error.fix


@pytest.mark.parametrize(
    "spelling",
    [
        pytest.param("{tmp}/run/x", id="absolute"),
        pytest.param("run/./x", id="dot"),
        pytest.param("run/../run/x", id="dotdot"),
        pytest.param("alias/x", id="symlink"),
    ],
)
def test_the_same_sim_file_spelled_two_ways_is_refused(tmp_path: Path, spelling: str) -> None:
    """Two sim outputs writing one file, the second spelling it otherwise: absolute against
    relative, with ``.`` or ``..``, or through a symlink to the directory. Refused."""
    (tmp_path / "run").mkdir()
    (tmp_path / "alias").symlink_to(tmp_path / "run")
    second = spelling.format(tmp=tmp_path)
    _clash(
        tmp_path,
        {"outputs[0].path": "run/x", "outputs[1]": _sim("brake", second)},
        "outputs[1].path",
        "outputs[0].path",
    )


def test_a_symlink_to_the_record_is_refused(tmp_path: Path) -> None:
    """An output whose path is a symlink to the record file: one file, two owners."""
    (tmp_path / "stops.jsonl").write_text("")
    (tmp_path / "lamp").symlink_to(tmp_path / "stops.jsonl")
    _clash(
        tmp_path,
        {"outputs[0].path": "lamp", "record": {"path": "stops.jsonl"}},
        "record.path",
        "outputs[0].path",
    )


def test_an_output_writing_the_vscs_port_is_refused(tmp_path: Path) -> None:
    """A sim output at the VSC's serial port path would replace the device: refused."""
    _clash(
        tmp_path,
        {"vsc.port": str(tmp_path / "vsc"), "outputs[0].path": "vsc"},
        "outputs[0].path",
        "vsc.port",
    )


@pytest.mark.parametrize(
    ("first", "second"),
    [
        pytest.param("gpiochip0", "/dev/gpiochip0", id="name_and_path"),
        pytest.param("/dev/gpiochip0", "/dev/../dev/gpiochip0", id="two_paths"),
    ],
)
def test_one_gpio_line_named_twice_is_refused(tmp_path: Path, first: str, second: str) -> None:
    """One GPIO line named by the chip's kernel name and by its device path (or two
    spellings of the path), with the same offset: refused naming both outputs."""
    error = refused(
        tmp_path,
        {
            "outputs[0]": {"name": "a", **GPIO, "chip": first},
            "outputs[1]": {"name": "b", **GPIO, "chip": second},
        },
    )
    assert error.key == "outputs[1].line", str(error)
    assert "outputs[0] (a) has it" in error.fix


def test_what_the_config_alone_cannot_decide_is_left_to_the_kernel(tmp_path: Path) -> None:
    """A chip named by label and by path, or a line named by name and by offset, may be one
    line or two: only the hardware knows. The config passes; at start the kernel refuses the
    second request of a line (busy), an ``output_fault`` that keeps the robot STOPPED."""
    config = load(
        tmp_path,
        {
            "outputs[0]": {"name": "a", **GPIO, "chip": "pinctrl-bcm2711"},
            "outputs[1]": {"name": "b", **GPIO, "chip": "/dev/gpiochip0"},
            "outputs[2]": {"name": "c", **GPIO, "chip": "/dev/gpiochip0", "line": "RELAY"},
        },
    )
    assert [o.name for o in config.outputs] == ["a", "b", "c"]


def test_distinct_paths_pass(tmp_path: Path) -> None:
    """Different files in one directory, and one line offset on two chips, are no clash."""
    config = load(
        tmp_path,
        {
            "outputs[0].path": "run/drive",
            "outputs[1]": _sim("brake", "run/brake"),
            "outputs[2]": {"name": "a", **GPIO, "chip": "gpiochip0"},
            "outputs[3]": {"name": "b", **GPIO, "chip": "gpiochip1"},
            "record": {"path": "run/stops.jsonl"},
            "api": {"socket": "run/api.sock"},
        },
    )
    assert config.record.path == tmp_path / "run" / "stops.jsonl"


def test_check_config_reports_a_clash_with_both_keys(tmp_path: Path) -> None:
    """``srcsd --check-config`` exits non-zero and prints both keys of a clash."""
    file = tmp_path / "robot.toml"
    file.write_text(dump(changed({"outputs[0].path": "x", "record": {"path": "x"}})))
    result = subprocess.run(
        [sys.executable, "-m", "supervisord.cli.srcsd", "--check-config", str(file)],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert result.returncode != 0
    assert "record.path" in result.stderr
    assert "outputs[0].path" in result.stderr

"""What ``--help`` says is plain text, and every ``srcsctl`` command names its robot the same
way (docs/srcsctl.md "Which daemon")."""

from __future__ import annotations

import re
import subprocess

import pytest

from supervisord.cli import control, reference, srcsctl
from supervisord.cli.reference import COMMANDS
from tests.daemon.test_srcsctl import SRCSCTL

MARKUP = re.compile(r"`|:(func|class|mod|data|meth|attr):")
"""reStructuredText that docstrings use and a terminal shows as it is."""


@pytest.mark.parametrize("command", COMMANDS, ids=[command.name for command in COMMANDS])
def test_help_texts_have_no_markup(command: reference.Command) -> None:
    """Every help text of every command and subcommand (the very parsers the programs parse
    with) is plain text: no ``rst`` literals or roles, which a terminal shows as they are."""
    for path, parser in reference.walk(command.build()):
        text = parser.format_help()
        assert MARKUP.search(text) is None, (path, MARKUP.search(text), text)


def test_the_real_help_is_plain() -> None:
    """The installed ``srcsctl --help`` starts with its plain description."""
    shown = subprocess.run(
        [SRCSCTL, "--help"], capture_output=True, text=True, timeout=60, check=True
    ).stdout
    assert "srcsctl: the operator's and integrator's tool" in shown
    assert "`" not in shown


def test_every_command_names_its_robot_the_same_way() -> None:
    """Each ``srcsctl`` command that talks to a daemon or reads its record takes ``--robot
    NAME`` (``-R``), ``--demo`` and ``--config``, before the command or after it."""
    parser = srcsctl.build_parser()
    commands = [*sorted(control.COMMANDS - {"display"}), "log"]
    for command in commands:
        args = [command, *(["row", "1", "x"] if command == "display" else [])]
        assert parser.parse_args([*args, "-R", "robot-a"]).robot == "robot-a", command
        assert parser.parse_args(["--robot", "robot-a", *args]).robot == "robot-a", command
        assert parser.parse_args([*args, "--demo"]).demo is True, command
    shown = parser.parse_args(["display", "row", "1", "x", "-R", "robot-a"])
    assert shown.robot == "robot-a"

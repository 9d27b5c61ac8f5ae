"""``srcsd --check-config`` lists every mistake at once: in file order, each with its line, the
key, the value as TOML writes it and the fix; a user or group this machine lacks is a warning
unless ``--strict`` (docs/configuration.md "Checking a config")."""

from __future__ import annotations

import grp
import pwd
import subprocess
import sys
from pathlib import Path

import pytest

from supervisord.config import load_config
from supervisord.config.collect import collect
from supervisord.config.lines import key_path, key_positions, position
from supervisord.errors import ConfigError

ROOT = Path(__file__).parents[2]
MISSING_GROUP = "srcs-test-no-such-group"
MISSING_USER = "srcs-test-no-such-user"

MISTAKES = """\
# a config with one mistake in nearly every section
[robot]
name = "mower-3"

[vsc]
transport = "serial"
port = "vsc"
timeout_ms = 5000
heartbeat_hz = "20"

[rearm]
hold_ms = 500
local-reset = true

[[clients]]
name = "autonomy"
user = "srcs-test-no-such-user"

[[outputs]]
name = "traction"
kind = "sim"
role = "motion"
path = "drive"
colour = "red"

[api]
socket = "api.sock"
admin_group = "srcs-test-no-such-group"
max_clients = 0
"""


def _srcsd(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "supervisord.cli.srcsd", *args],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
        cwd=ROOT,
    )


@pytest.fixture(autouse=True)
def _names_are_missing() -> None:
    for lookup, name in ((grp.getgrnam, MISSING_GROUP), (pwd.getpwnam, MISSING_USER)):
        with pytest.raises(KeyError):
            lookup(name)  # the machine really lacks them: the warnings below are real


def test_every_mistake_at_once_in_file_order_with_its_line(tmp_path: Path) -> None:
    """SR-11.2: the real ``srcsd --check-config`` names every mistake of the file, not only
    the first, in the order of the file, each as FILE:LINE with the key, the value as TOML
    writes it (``true``, ``"20"``) and the fix; the user and group this machine lacks are
    warnings there; the verdict counts them; exit 1, nothing on stdout."""
    config = tmp_path / "robot.toml"
    config.write_text(MISTAKES)
    checked = _srcsd("--check-config", str(config))
    assert checked.returncode == 1, checked.stderr
    assert checked.stdout == ""
    f = str(config)
    assert checked.stderr.splitlines() == [
        f"{f}:8: error: vsc.timeout_ms = 5000: use a whole number from 50 to 1000",
        f'{f}:9: error: vsc.heartbeat_hz = "20": use a whole number from 20 to 50, without quotes',
        f"{f}:13: error: rearm.local-reset = true: unknown key: did you mean 'local_reset'? "
        "(known: hold_ms, local_reset)",
        f'{f}:17: warning: clients[0].user = "{MISSING_USER}": no such user on this machine: '
        f"create it (useradd --system {MISSING_USER}) or name the user the client runs as (an "
        "error with --strict, and for the daemon's start)",
        f'{f}:24: error: outputs[0].colour = "red": unknown key: remove it (known: name, kind, '
        "role, off_delay_ms, path, stuck_at)",
        f'{f}:28: warning: api.admin_group = "{MISSING_GROUP}": no such group on this machine: '
        f"create it (groupadd --system {MISSING_GROUP}) and add the users to it, or name an "
        "existing group (an error with --strict, and for the daemon's start)",
        f"{f}:29: error: api.max_clients = 0: use a whole number from 1 to 256",
        f"{f}: not valid: 5 errors, 2 warnings",
    ]


def test_the_daemon_names_every_mistake_too(tmp_path: Path) -> None:
    """SR-11.2: ``srcsd --config`` refuses the same file with exit 78, logging each mistake
    with its line; for the daemon the missing group is an error (it cannot run without it)."""
    config = tmp_path / "robot.toml"
    config.write_text(MISTAKES)
    started = _srcsd("--config", str(config))
    assert started.returncode == 78
    assert f"{config}:8: error: vsc.timeout_ms = 5000" in started.stderr
    assert f"{config}:28: error: api.admin_group" in started.stderr
    assert f"{config}:29: error: api.max_clients = 0" in started.stderr


def test_a_missing_group_is_a_warning_unless_strict(tmp_path: Path) -> None:
    """SR-11.2: a valid config naming a group this machine lacks passes ``--check-config``
    (exit 0, the OK line, the warning with its line); with ``--strict`` it is an error
    (exit 1), as the daemon's start refuses it."""
    good = MISTAKES.replace("timeout_ms = 5000", "timeout_ms = 200")
    good = good.replace('heartbeat_hz = "20"', "heartbeat_hz = 20")
    good = good.replace("local-reset", "local_reset").replace('colour = "red"\n', "")
    good = good.replace("max_clients = 0", "max_clients = 4")
    good = good.replace(f'user = "{MISSING_USER}"\n', "")
    config = tmp_path / "robot.toml"
    config.write_text(good)
    line = 1 + good.splitlines().index(f'admin_group = "{MISSING_GROUP}"')
    checked = _srcsd("--check-config", str(config))
    assert checked.returncode == 0, checked.stderr
    assert checked.stdout.startswith(f"{config}: OK — robot mower-3, transport serial")
    assert f"{config}:{line}: warning: api.admin_group = " in checked.stderr
    strict = _srcsd("--check-config", str(config), "--strict")
    assert strict.returncode == 1
    assert f"{config}:{line}: error: api.admin_group = " in strict.stderr
    assert strict.stderr.splitlines()[-1] == f"{config}: not valid: 1 error"


@pytest.mark.parametrize("example", ["config/example-serial-gpio.toml", "config/example-can.toml"])
def test_the_readme_examples_pass_on_a_developers_machine(example: str) -> None:
    """SR-11.2: the README's ``srcsd --check-config config/example-...toml`` passes on a
    machine without the package's ``srcs-admin`` group (exit 0); the group is named as a
    warning when it is missing."""
    checked = _srcsd("--check-config", example)
    assert checked.returncode == 0, checked.stderr
    assert checked.stdout.startswith(f"{example}: OK — ")
    if not _group("srcs-admin"):
        assert 'warning: api.admin_group = "srcs-admin"' in checked.stderr


def _group(name: str) -> bool:
    try:
        grp.getgrnam(name)
    except KeyError:
        return False
    return True


def test_a_syntax_error_has_its_line_and_column(tmp_path: Path) -> None:
    """SR-11.2: a TOML syntax error is FILE:LINE:COLUMN, the one place TOML gives a column,
    with the line as written and the parser's reason; nothing after it can be judged."""
    config = tmp_path / "robot.toml"
    config.write_text('[robot]\nname = mower\n[vsc]\ntransport = "x"\n')
    checked = _srcsd("--check-config", str(config))
    assert checked.returncode == 1
    assert checked.stderr.splitlines() == [
        f'{config}:2:8: error: line 2, column 8 = "name = mower": correct the TOML syntax there '
        "(invalid value)",
        f"{config}: not valid: 1 error",
    ]


def test_a_wrong_transport_does_not_judge_the_keys_it_decides(tmp_path: Path) -> None:
    """SR-11.2: with ``transport`` misspelt, the CAN keys are not called wrong for a transport
    nobody chose (a note says they were not judged), while a key every transport has still
    is; a rule between sections ends the list with a note that the checks after it did not
    run."""
    config = tmp_path / "robot.toml"
    config.write_text(
        '[robot]\nname = "m"\n[vsc]\ntransport = "cann"\nchannel = "can0"\ntimeout_ms = 3\n'
        '[[outputs]]\nname = "d"\nkind = "sim"\nrole = "power"\npath = "d"\n'
    )
    report = collect(config)
    keys = [finding.error.key for finding in report.findings]
    assert keys == ["vsc.transport", "vsc.timeout_ms", "outputs"]
    assert [finding.where for finding in report.findings] == [(4, 1), (6, 1), (7, 1)]
    assert any("that vsc.transport decides were not judged" in note for note in report.notes)
    assert any("the checks after outputs did not run" in note for note in report.notes)


VARIANTS = [
    ("", ""),
    ("timeout_ms = 5000", "timeout_ms = 200"),
    ('heartbeat_hz = "20"', "heartbeat_hz = 20"),
    ("local-reset", "local_reset"),
    ('colour = "red"\n', ""),
    ("max_clients = 0", "max_clients = 4"),
    (f'admin_group = "{MISSING_GROUP}"\n', ""),
    (f'user = "{MISSING_USER}"\n', ""),
    ('role = "motion"', 'role = "power"'),
    ('name = "mower-3"', "name = 3"),
    ('transport = "serial"', 'transport = "can"'),
]


def test_collecting_never_changes_what_is_valid(tmp_path: Path) -> None:
    """SR-11.2: the list is the loader's verdict, not a second opinion: for the file with
    mistakes taken away one by one (and some added), ``collect`` (strict) finds no error
    exactly when ``load_config`` accepts it, and its first error in loading order is
    the loader's."""
    text = MISTAKES
    for index, (old, new) in enumerate(VARIANTS):
        text = text.replace(old, new)
        for variant in (text, text.replace("[rearm]", "[rearm]\nhold_ms_x = 1")):
            config = tmp_path / f"robot-{index}.toml"
            config.write_text(variant)
            report = collect(config, strict_machine=True)
            refused = _refusal(config)
            if refused is None:
                assert report.errors == 0, (variant, report.findings)
                assert report.config is not None
            else:
                assert report.errors >= 1, (variant, refused)
                assert refused in {str(f.error) for f in report.findings}, (variant, refused)


def _refusal(config: Path) -> str | None:
    """The loader's message for ``config``, or ``None`` when it takes it."""
    try:
        load_config(config)
    except ConfigError as error:
        return str(error)
    return None


TEXT = """\
top.dotted = 1
list = [
  "[not_a_table]",  # a comment
  'x = 2',
]
long = \"\"\"
[also_not]
y = 3
\"\"\"
[vsc]
inline = { timeout_ms = 200, "q.k" = 1 }
[[outputs]]
name = 'a'
[outputs.extra]
k = 1
[[outputs]]
"name" = "b"
"""


def test_each_key_is_found_on_its_line() -> None:
    """SR-11.2: the scan that places keys (the parser gives no positions) finds dotted keys,
    inline tables, the second ``[[outputs]]`` as ``outputs[1]``, a sub-table of an array's
    latest table and quoted keys, and never takes text inside a string or an array for a key;
    a key not written is placed at its table, one in no written table nowhere."""
    positions = key_positions(TEXT)
    wanted = {
        "top.dotted": (1, 1),
        "list": (2, 1),
        "long": (6, 1),
        "vsc": (10, 1),
        "vsc.inline.timeout_ms": (11, 12),
        "outputs[0].name": (13, 1),
        "outputs[0].extra.k": (15, 1),
        "outputs[1]": (16, 1),
        "outputs[1].name": (17, 1),
        "vsc.not_written": (10, 1),
    }
    for key, where in wanted.items():
        path = key_path(key)
        assert path is not None
        assert position(positions, path) == where, key
    assert position(positions, ("vsc", "inline", "q.k")) == (11, 30)
    assert ("not_a_table",) not in positions
    assert ("also_not",) not in positions
    assert ("y",) not in positions
    assert position(positions, ("api", "socket")) is None
    assert key_path("line 3, column 5") is None

"""``srcsd --check-config`` lists every mistake at once: in file order, each with its line, the
key, the value as TOML writes it and the fix; a user or group this machine lacks is an error,
as for the daemon's start, and a warning with ``--portable`` (docs/configuration.md "Checking
a config")."""

from __future__ import annotations

import grp
import pwd
import subprocess
import sys
import threading
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
    writes it (``true``, ``"20"``) and the fix; with ``--portable`` the user and group this
    machine lacks are warnings there; the verdict counts them; exit 1, nothing on stdout."""
    config = tmp_path / "robot.toml"
    config.write_text(MISTAKES)
    checked = _srcsd("--check-config", str(config), "--portable")
    assert checked.returncode == 1, checked.stderr
    assert checked.stdout == ""
    f = str(config)
    assert checked.stderr.splitlines() == [
        f"{f}:8: error: vsc.timeout_ms = 5000: use a whole number from 50 to 1000",
        f'{f}:9: error: vsc.heartbeat_hz = "20": use a whole number from 20 to 50, without quotes',
        f"{f}:13: error: rearm.local-reset = true: unknown key: did you mean 'local_reset'? "
        "(known: hold_ms, local_reset)",
        f'{f}:17: warning: clients[0].user = "{MISSING_USER}": no such user on this machine: '
        f"create it (useradd --system {MISSING_USER}) or name the user the client runs as (a "
        "warning only with --portable: the daemon's start refuses it)",
        f'{f}:24: error: outputs[0].colour = "red": unknown key: remove it (known: name, kind, '
        "role, off_delay_ms, path, stuck_at)",
        f'{f}:28: warning: api.admin_group = "{MISSING_GROUP}": no such group on this machine: '
        f"create it (groupadd --system {MISSING_GROUP}) and add the users to it, or name an "
        "existing group (a warning only with --portable: the daemon's start refuses it)",
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


def test_a_missing_group_is_an_error_unless_portable(tmp_path: Path) -> None:
    """SR-11.2: a valid config naming a group this machine lacks passes ``--check-config
    --portable`` (exit 0, the OK line, the warning with its line); without it, and with the
    ``--strict`` of older scripts, it is an error (exit 1), as the daemon's start refuses it."""
    good = MISTAKES.replace("timeout_ms = 5000", "timeout_ms = 200")
    good = good.replace('heartbeat_hz = "20"', "heartbeat_hz = 20")
    good = good.replace("local-reset", "local_reset").replace('colour = "red"\n', "")
    good = good.replace("max_clients = 0", "max_clients = 4")
    good = good.replace(f'user = "{MISSING_USER}"\n', "")
    config = tmp_path / "robot.toml"
    config.write_text(good)
    line = 1 + good.splitlines().index(f'admin_group = "{MISSING_GROUP}"')
    checked = _srcsd("--check-config", str(config), "--portable")
    assert checked.returncode == 0, checked.stderr
    assert checked.stdout.startswith(f"{config}: OK — robot mower-3, transport serial")
    assert f"{config}:{line}: warning: api.admin_group = " in checked.stderr
    for flags in ((), ("--strict",)):
        strict = _srcsd("--check-config", str(config), *flags)
        assert strict.returncode == 1
        assert f"{config}:{line}: error: api.admin_group = " in strict.stderr
        assert strict.stderr.splitlines()[-1] == f"{config}: not valid: 1 error"


@pytest.mark.parametrize("example", ["config/example-serial-gpio.toml", "config/example-can.toml"])
def test_the_readme_examples_pass_on_a_developers_machine(example: str) -> None:
    """SR-11.2, SR-8.6: the README's ``srcsd --check-config --portable config/example-...toml``
    passes on a machine without the package's ``srcs-admin`` group or the clients' user
    ``robot`` (exit 0), each named as a warning when it is missing; no client is unbound."""
    checked = _srcsd("--check-config", "--portable", example)
    assert checked.returncode == 0, checked.stderr
    assert checked.stdout.startswith(f"{example}: OK — ")
    if not _group("srcs-admin"):
        assert 'warning: api.admin_group = "srcs-admin"' in checked.stderr
    if not _user("robot"):
        assert 'warning: clients[0].user = "robot": no such user' in checked.stderr
    assert "unbound" not in checked.stderr


def _user(name: str) -> bool:
    try:
        pwd.getpwnam(name)
    except KeyError:
        return False
    return True


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
    is; a rule between sections (no motion output) is listed with the rest, and no check is
    left unrun."""
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
    assert not any("did not run" in note for note in report.notes)


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


SIX_MISTAKES = """\
[robot]
name = "mower-3"

[vsc]
transport = "serial"
port = "/dev/srcs-vsc"
timeout_ms = 200
reopen_min_ms = 100
heartbeat_hz = 10
require_watchdog = true

[rearm]
local_reset = "yes"
hold_ms = 500

[[clients]]
name = "autonomy"
timeout_ms = 5

[[outputs]]
name = "traction"
kind = "gpio"
role = "motion"
chip = "/dev/gpiochip0"
line = 17

[[outputs]]
name = "safety_relay"
kind = "gpio"
role = "power"
chip = "/dev/gpiochip0"
line = 17
pulse_period_ms = 1

[record]
path = "/var/lib/srcsd/stops.jsonl"
keep = 0
"""


def test_a_clash_between_outputs_hides_no_other_mistake(tmp_path: Path) -> None:
    """SR-11.2: the real ``srcsd --check-config`` lists all six mistakes of a file in one run,
    each at its line: the rule between outputs (one GPIO line twice, line 32) is judged after
    every section's own keys and stops nothing, neither the keys above it in loading order
    (``heartbeat_hz``, ``local_reset``) nor the sections after it (``record.keep``)."""
    config = tmp_path / "robot.toml"
    config.write_text(SIX_MISTAKES)
    checked = _srcsd("--check-config", str(config))
    assert checked.returncode == 1, checked.stderr
    f = str(config)
    assert checked.stderr.splitlines() == [
        f"{f}:9: error: vsc.heartbeat_hz = 10: use a whole number from 20 to 50",
        f'{f}:13: error: rearm.local_reset = "yes": use true or false, without quotes',
        f"{f}:18: error: clients[0].timeout_ms = 5: use a whole number from 20 to 10000",
        f"{f}:32: error: outputs[1].line = 17: give each output its own line: outputs[0] "
        "(traction) has it",
        f"{f}:33: error: outputs[1].pulse_period_ms = 1: use a whole number from 2 to 1000",
        f"{f}:37: error: record.keep = 0: use a whole number from 1 to 99",
        f"{f}: not valid: 6 errors",
    ]


def test_every_rule_between_sections_is_listed(tmp_path: Path) -> None:
    """SR-11.2, SR-11.1: two broken rules between sections (one GPIO line twice, the record
    and an output one file) are both listed, each at the later key; the daemon, which stops
    at the first, is refused by the same first one."""
    text = SIX_MISTAKES.replace("heartbeat_hz = 10", "heartbeat_hz = 20")
    text = text.replace('"yes"', "false").replace("timeout_ms = 5\n", "")
    text = text.replace("pulse_period_ms = 1", "pulse_period_ms = 10")
    text = text.replace("keep = 0", "keep = 2")
    text += '\n[[outputs]]\nname = "mirror"\nkind = "sim"\npath = "/var/lib/srcsd/stops.jsonl"\n'
    config = tmp_path / "robot.toml"
    config.write_text(text)
    checked = _srcsd("--check-config", str(config))
    f = str(config)
    lines = checked.stderr.splitlines()
    assert lines[0].startswith(f"{f}:31: error: outputs[1].line = 17: give each output its own")
    assert lines[1].startswith(f"{f}:35: error: record.path = ")
    assert "outputs[2].path = '/var/lib/srcsd/stops.jsonl'" in lines[1]
    assert lines[2:] == [f"{f}: not valid: 2 errors"]
    first = _refusal(config)
    assert first is not None
    assert first.startswith(f"{f}: outputs[1].line = 17: give each output its own line")


def test_a_wrongly_shaped_outputs_table_hides_no_other_section(tmp_path: Path) -> None:
    """SR-11.2: ``[outputs.drive]`` for ``[[outputs]]`` is listed once, its keys are not
    judged (a note says so), and the sections after it still are: a wrong ``record.path``
    is listed; the hint of an unknown ``[vsc]`` key of a serial VSC lists only the keys a
    serial VSC takes."""
    config = tmp_path / "robot.toml"
    config.write_text(
        '[robot]\nname = "m"\n\n[vsc]\ntransport = "serial"\ncolour = 1\n\n[outputs.drive]\n'
        'kind = "gpio"\nchip = "gpiochip0"\nline = 3\n\n[record]\npath = "/var/lib/srcsd/"\n'
    )
    checked = _srcsd("--check-config", str(config))
    assert checked.returncode == 1
    f = str(config)
    assert checked.stderr.splitlines() == [
        f"{f}:6: error: vsc.colour = 1: unknown key: remove it (known: transport, timeout_ms, "
        "require_watchdog, prooftest, prooftest_clear_ms, min_remote_battery, "
        "on_estop_unavailable, reopen_min_ms, reopen_max_ms, port, baud, heartbeat_hz)",
        f'{f}:8: error: outputs.drive = {{ kind = "gpio", chip = "gpiochip0", line = 3 }}: write '
        '[[outputs]] with name = "drive" instead of [outputs.drive]',
        f"{f}:14: error: record.path = \"/var/lib/srcsd/\": use a file's path, not a directory's, "
        'e.g. "/var/lib/srcsd/stops.jsonl"',
        f"{f}: note: the [[outputs]] tables were not judged, as outputs.drive is not one: "
        "correct it and check again",
        f"{f}: not valid: 3 errors",
    ]


def test_the_vsc_hint_follows_the_transport(tmp_path: Path) -> None:
    """SR-11.2: an unknown ``[vsc]`` key's hint lists the keys of the transport written (CAN
    keys for CAN, never the serial or HID ones), and every key when the transport is itself
    unknown (a note then says the transport's keys were not judged)."""
    for transport, listed, absent in (
        ("can", "channel", "hidraw"),
        ("serial", "heartbeat_hz", "channel"),
        ("hid", "hidraw", "port"),
    ):
        config = tmp_path / f"{transport}.toml"
        config.write_text(f'[robot]\nname = "m"\n[vsc]\ntransport = "{transport}"\nchanel = 1\n')
        report = collect(config)
        hint = next(f.error.fix for f in report.findings if f.error.key == "vsc.chanel")
        known = hint.split("(known: ")[1].rstrip(")").split(", ")
        assert listed in known, (transport, hint)
        assert absent not in known, (transport, hint)
    config = tmp_path / "unknown.toml"
    config.write_text('[robot]\nname = "m"\n[vsc]\ntransport = "cann"\nchanel = 1\n')
    hint = next(f.error.fix for f in collect(config).findings if f.error.key == "vsc.chanel")
    assert "did you mean 'channel'?" in hint
    assert {"port", "channel", "hidraw"} <= set(hint.split("(known: ")[1].rstrip(")").split(", "))


WARNED = """\
[robot]
name = "bench"

[vsc]
transport = "serial"
require_watchdog = false

[[clients]]
name = "autonomy"

[[clients]]
name = "mapper"
uid = 4000

[[outputs]]
name = "drive"
kind = "sim"
"""


def test_every_warning_carries_its_line_and_strict_keeps_them_warnings(tmp_path: Path) -> None:
    """SR-11.2, SR-8.6: a valid config's warnings are printed each at its key's line (an
    unbound required client at its table, saying the hazard and how to bind it; a bound one
    is not named); ``--strict``, which is what the daemon's start refuses, keeps them
    warnings (exit 0), as the daemon starts with them."""
    config = tmp_path / "robot.toml"
    config.write_text(WARNED)
    f = str(config)
    wanted = [
        f"{f}:6: warning: vsc.require_watchdog = false: the VSC's own user watchdog (key 85) "
        "is not checked, so the VSC does not stop when the supervisor falls silent",
        f"{f}:8: warning: clients[0].user = (not set): unbound: any program that can reach the "
        'socket may say hello as "autonomy" and keep it alive after it died: bind it to the '
        'user it runs as (user = "NAME", or uid = N)',
        f'{f}:17: warning: outputs[0].kind = "sim": drive is simulated: it drives no hardware',
    ]
    for strict_flag in ((), ("--strict",)):
        checked = _srcsd("--check-config", str(config), *strict_flag)
        assert checked.returncode == 0, checked.stderr
        assert checked.stdout.startswith(f"{f}: OK — robot bench")
        assert checked.stderr.splitlines() == wanted


def test_the_daemon_logs_an_unbound_client_at_start(tmp_path: Path) -> None:
    """SR-8.6: the real daemon's start logs the unbound required client's warning (the hazard
    and how to bind it) before its start line; it is stopped with SIGTERM once started."""
    text = WARNED.replace('transport = "serial"', 'transport = "serial"\nport = "no-vsc"')
    text += '\n[record]\npath = "stops.jsonl"\njournal = false\n[api]\nsocket = "api.sock"\n'
    config = tmp_path / "robot.toml"
    config.write_text(text)
    daemon = subprocess.Popen(
        [sys.executable, "-m", "supervisord.cli.srcsd", "--config", str(config)],
        stderr=subprocess.PIPE,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        text=True,
        cwd=ROOT,
    )
    bound = threading.Timer(120, daemon.kill)  # a failure's bound, never waited for
    bound.start()
    logged = []
    try:
        assert daemon.stderr is not None
        for line in daemon.stderr:
            logged.append(line)
            if "robot bench:" in line:  # the start line: every warning is logged before it
                break
    finally:
        daemon.terminate()
        daemon.communicate()  # reads the rest and closes the pipe
        bound.cancel()
    unbound = "clients[0].user = (not set): unbound: any program that can reach the socket"
    assert any(unbound in line and "WARNING" in line for line in logged), logged
    assert not any("clients[1].user" in line for line in logged), logged

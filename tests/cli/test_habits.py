"""What users of journalctl, systemctl and apt type, on the real programs as subprocesses:
``srcsctl log``'s journalctl options and its ``--cause`` (SR-7), durations as systemd writes
them and usage errors with the command's own usage (SR-11.3, SR-8.10), ``srcsd``'s options in
any order (SR-11.2), completion of robots and causes in a real bash, ``replay`` of a record that
has no window (SR-7.13) and ``srcs-ros2 --help`` (docs/srcsctl.md "log: journalctl's habits")."""

from __future__ import annotations

import datetime as dt
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from supervisord import __version__
from supervisord.safety.causes import CauseKind
from tests.daemon.test_srcsctl import SRCSCTL

REPO = Path(__file__).resolve().parents[2]
SRCSD = str(Path(SRCSCTL).with_name("srcsd"))
BASH = shutil.which("bash") or "/bin/bash"
RUN_LIMIT_S = 60.0
"""Far above a start-up of the interpreter (under a second) on a busy machine."""
CAUSE_NAMES = sorted(kind.value for kind in CauseKind)


def boot_time() -> dt.datetime:
    """The machine's boot, as the kernel says it: ``btime`` in /proc/stat."""
    for line in Path("/proc/stat").read_text().splitlines():
        if line.startswith("btime "):
            return dt.datetime.fromtimestamp(int(line.split()[1]), dt.timezone.utc)
    raise AssertionError("no btime in /proc/stat")


def run(*command: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        list(command),
        capture_output=True,
        text=True,
        timeout=RUN_LIMIT_S,
        check=False,
        cwd=REPO,
        env=env,
    )


def _cause(name: str, *, active: bool) -> dict[str, Any]:
    return {
        "name": name,
        "severity": "stop",
        "active": active,
        "latched": True,
        "raised_ns": 1,
        "cleared_ns": None if active else 2,
        "details": {},
    }


def _record(
    seq: int,
    when: dt.datetime,
    move: tuple[str, str],
    causes: list[dict[str, Any]],
    changes: list[tuple[str, str]],
) -> dict[str, Any]:
    return {
        "seq": seq,
        "mono_ns": seq,
        "utc": when.isoformat(),
        "kind": "state_change" if move[0] != move[1] else "cause_raised",
        "from": move[0],
        "to": move[1],
        "causes": causes,
        "changes": [{"name": name, "change": change} for change, name in changes],
        "trigger": {"event": "vsc_received"},
    }


def link_story(path: Path, first: dt.datetime) -> Path:
    """Six records as the daemon writes them: the link lost (#1, a stop), an e-stop while it is
    lost (#2), the link back (#3, cleared: latched), another e-stop (#4, the link latched),
    the re-arm that releases both (#5), a stop by a client (#6). ``first`` is #1's time; the
    others follow a second apart."""
    at = [first + dt.timedelta(seconds=i) for i in range(6)]
    link, estop = "vsc_link_lost", "vsc_estop"
    records = [
        _record(1, at[0], ("RUN", "STOPPED"), [_cause(link, active=True)], [("raised", link)]),
        _record(
            2,
            at[1],
            ("STOPPED", "STOPPED"),
            [_cause(link, active=True), _cause(estop, active=True)],
            [("raised", estop)],
        ),
        _record(
            3,
            at[2],
            ("STOPPED", "STOPPED"),
            [_cause(link, active=False), _cause(estop, active=True)],
            [("cleared", link)],
        ),
        _record(
            4,
            at[3],
            ("STOPPED", "STOPPED"),
            [_cause(link, active=False), _cause(estop, active=False)],
            [("cleared", estop)],
        ),
        _record(5, at[4], ("STOPPED", "RUN"), [], [("released", link), ("released", estop)]),
        _record(
            6,
            at[5],
            ("RUN", "STOPPED"),
            [_cause("client_lost:autonomy", active=True)],
            [("raised", "client_lost:autonomy")],
        ),
    ]
    path.write_text("".join(json.dumps(r) + "\n" for r in records))
    return path


def seqs(done: subprocess.CompletedProcess[str]) -> list[str]:
    assert done.returncode == 0, done.stderr
    return [line.split()[1] for line in done.stdout.splitlines()]


def test_log_takes_journalctls_options(tmp_path: Path) -> None:
    """SR-7: ``log --no-pager``, ``-x``, ``-e`` (the last 1000), ``-o cat``, ``-o verbose`` and
    ``-o json-pretty`` (indented JSON) work as a journalctl user expects, and ``-b`` shows only
    the records since the machine booted (its btime in /proc/stat)."""
    booted = boot_time()
    path = link_story(tmp_path / "stops.jsonl", booted - dt.timedelta(seconds=3))
    log = (SRCSCTL, "log", "--file", str(path))
    plain = run(*log)
    assert seqs(plain) == [f"#{n}" for n in range(1, 7)]
    assert run(*log, "--no-pager", "-x").stdout == plain.stdout
    assert run(*log, "-e").stdout == plain.stdout  # six records: all of the last 1000
    assert seqs(run(*log, "-e", "-n", "2")) == ["#5", "#6"]
    assert seqs(run(*log, "-b")) == ["#4", "#5", "#6"]  # #1-#3 came before the boot
    assert seqs(run(*log, "-b", "0", "--no-pager", "-e")) == ["#4", "#5", "#6"]
    cat = run(*log, "-o", "cat", "-n", "1")
    assert cat.returncode == 0, cat.stderr
    assert cat.stdout.startswith("#6 ")  # no time
    assert "[causes: " in run(*log, "-o", "verbose", "-n", "1").stdout
    pretty = run(*log, "-o", "json-pretty")
    assert pretty.returncode == 0, pretty.stderr
    decoder, text, objects = json.JSONDecoder(), pretty.stdout, []
    while text.strip():
        obj, end = decoder.raw_decode(text.lstrip())
        objects.append(obj)
        text = text.lstrip()[end:]
    assert [o["seq"] for o in objects] == [1, 2, 3, 4, 5, 6]
    assert pretty.stdout.startswith("{\n  ")


def test_log_refuses_with_its_own_usage(tmp_path: Path) -> None:
    """SR-11.3: an option ``log`` does not have, an ``-o`` it does not know, an earlier boot
    and an unknown cause name are usage errors (exit 2) said with ``log``'s usage, never the
    top level's; the unknown cause lists the cause names."""
    path = link_story(tmp_path / "stops.jsonl", dt.datetime.now(dt.timezone.utc))
    for extra in (["--bogus"], ["-o", "export"], ["--cause", "nosuch"]):
        done = run(SRCSCTL, "log", "--file", str(path), *extra)
        assert done.returncode == 2, (extra, done)
        assert done.stderr.startswith("usage: srcsctl log "), (extra, done.stderr)
        assert "srcsctl log: error: " in done.stderr, (extra, done.stderr)
    unknown = run(SRCSCTL, "log", "--file", str(path), "--cause", "nosuch")
    assert all(name in unknown.stderr for name in CAUSE_NAMES)
    earlier = run(SRCSCTL, "log", "--file", str(path), "-b", "-1")
    assert earlier.returncode == 2
    assert "only this boot" in earlier.stderr
    assert earlier.stdout == ""


def test_log_cause_means_the_records_about_it(tmp_path: Path) -> None:
    """SR-7: ``--cause`` selects the records that raised, cleared or released the cause (its
    changes), not those where it was merely latched; ``--cause-present`` those that hold it;
    a subject narrows (``client_lost:autonomy``), a kind matches its subjects."""
    path = link_story(tmp_path / "stops.jsonl", dt.datetime.now(dt.timezone.utc))
    log = (SRCSCTL, "log", "--file", str(path))
    assert seqs(run(*log, "--cause", "vsc_link_lost")) == ["#1", "#3", "#5"]
    assert seqs(run(*log, "--cause-present", "vsc_link_lost")) == ["#1", "#2", "#3", "#4"]
    assert seqs(run(*log, "--cause", "client_lost")) == ["#6"]
    assert seqs(run(*log, "--cause", "client_lost:autonomy")) == ["#6"]
    as_json = run(*log, "--cause", "vsc_estop", "--json")
    assert [json.loads(line)["seq"] for line in as_json.stdout.splitlines()] == [2, 4, 5]


def test_log_says_no_entries_as_journalctl(tmp_path: Path) -> None:
    """SR-7: a filter that matches nothing prints ``-- No entries --`` on stdout (exit 0), as
    journalctl does; nothing in a JSON mode or with ``-q``."""
    path = link_story(tmp_path / "stops.jsonl", dt.datetime.now(dt.timezone.utc))
    log = (SRCSCTL, "log", "--file", str(path), "--cause", "local_estop")
    done = run(*log)
    assert (done.returncode, done.stdout, done.stderr) == (0, "-- No entries --\n", "")
    for quiet in (["--json"], ["-o", "json-pretty"], ["-q"]):
        done = run(*log, *quiet)
        assert (done.returncode, done.stdout) == (0, ""), quiet


def test_durations_take_systemds_time_spans(tmp_path: Path) -> None:
    """SR-11.3, SR-8.10: ``wait-ready --timeout 500ms`` and ``stoptest --timeout 1min`` are
    taken (no daemon answers: exit 3), a plain number is seconds, and a span that is not one is
    a usage error with the command's usage (the values: tests/cli/test_hostile_arguments.py)."""
    sock = str(tmp_path / "api.sock")
    started = time.monotonic()
    ready = run(SRCSCTL, "wait-ready", "--timeout", "500ms", "--socket", sock)
    assert ready.returncode == 3, ready.stderr
    assert time.monotonic() - started < RUN_LIMIT_S
    tested = run(SRCSCTL, "stoptest", "--yes", "--timeout", "1min", "--socket", sock)
    assert tested.returncode == 3, tested.stderr
    bad = run(SRCSCTL, "wait-ready", "--timeout", "2 fortnights", "--socket", sock)
    assert bad.returncode == 2
    assert bad.stderr.startswith("usage: srcsctl wait-ready")


def test_display_out_of_range_is_a_usage_error(tmp_path: Path) -> None:
    """SR-11.3: ``display row 5 x`` (rows are 1-4) and ``display value 10 1`` (keys 1-9) are
    usage errors of their command (exit 2, its usage), before any daemon is asked."""
    sock = str(tmp_path / "api.sock")
    for args, usage in (
        (["display", "row", "5", "x"], "usage: srcsctl display row"),
        (["display", "value", "10", "1"], "usage: srcsctl display value"),
        (["display", "label", "0", "x"], "usage: srcsctl display label"),
    ):
        done = run(SRCSCTL, *args, "--socket", sock)
        assert done.returncode == 2, (args, done)
        assert done.stderr.startswith(usage), done.stderr


def test_srcsd_takes_its_options_in_any_order(tmp_path: Path) -> None:
    """SR-11.2: ``srcsd --check-config --strict FILE`` checks as ``--strict --check-config
    FILE`` does, not a usage error."""
    config = tmp_path / "robot.toml"
    config.write_text((REPO / "config" / "example-serial-gpio.toml").read_text())
    first = run(SRCSD, "--strict", "--check-config", str(config))
    assert first.returncode in (0, 1), first.stderr
    for order in (["--check-config", "--strict", str(config)], ["--check-config", str(config)]):
        done = run(SRCSD, *order, *([] if "--strict" in order else ["--strict"]))
        assert (done.returncode, done.stdout, done.stderr) == (
            first.returncode,
            first.stdout,
            first.stderr,
        ), order


def test_replay_of_a_record_without_a_window_says_what_it_is(tmp_path: Path) -> None:
    """SR-7.13: ``replay 5`` of a re-arm says that record 5 is a re-arm, that windows are kept
    for stops only, and names the nearest stops with windows, not only a missing file."""
    path = link_story(tmp_path / "stops.jsonl", dt.datetime.now(dt.timezone.utc))
    flight = tmp_path / "stops.jsonl.flight"
    flight.mkdir()
    for seq in (1, 6):  # the two stops of the story
        (flight / f"{seq}.jsonl").write_text("{}\n")
    done = run(SRCSCTL, "replay", "5", "--file", str(path))
    assert done.returncode == 2
    assert "record 5 is a re-arm (STOPPED -> RUN)" in done.stderr, done.stderr
    assert "windows are kept for stops only" in done.stderr
    assert "the nearest stops with windows: #1, #6" in done.stderr


def test_srcs_ros2_help_and_version_need_no_rclpy() -> None:
    """SR-8.8: ``srcs-ros2 --help`` prints a usage and its parameters, ``--version`` the
    version, both without loading rclpy (a robot where ROS is not sourced)."""
    no_ros = {**os.environ, "PYTHONPATH": str(REPO), "PYTHONNOUSERSITE": "1"}
    bridge = (sys.executable, "-c", "import sys; from supervisord.cli.ros2 import main; main()")
    helped = run(*bridge, "--help", env=no_ros)
    assert helped.returncode == 0, helped.stderr
    assert helped.stdout.startswith("usage: srcs-ros2 ")
    assert "client_name" in helped.stdout
    version = run(*bridge, "--version", env=no_ros)
    assert (version.returncode, version.stdout) == (0, f"srcs-ros2 {__version__}\n")


def test_texts_cite_what_a_robot_has() -> None:
    """SR-8.8: no ``--help`` of srcsctl's commands cites a repository path (``docs/...``)
    that a robot does not have: they name the man page or the installed docs."""
    commands = ["log", "replay", "decode", "stoptest", "wait-ready", "status"]
    for command in commands:
        done = run(SRCSCTL, command, "--help", env={**os.environ, "COLUMNS": "1000"})
        assert done.returncode == 0, done.stderr
        text = done.stdout.replace("/usr/share/doc/srcs-supervisord/docs", "")
        assert "docs/" not in text, (command, done.stdout)
        assert "tests/" not in text, (command, done.stdout)


COMPLETE = r"""
source "$1"
fn=$(complete -p srcsctl | sed -E 's/.* -F ([^ ]+) .*/\1/')
shift
read -ra COMP_WORDS <<< "$*"
COMP_WORDS+=("")
COMP_CWORD=$(( ${#COMP_WORDS[@]} - 1 ))
COMP_LINE="$* "
COMP_POINT=${#COMP_LINE}
COMPREPLY=()
"$fn" srcsctl "" "${COMP_WORDS[COMP_CWORD-1]}"
printf '%s\n' "${COMPREPLY[@]}"
"""


@pytest.mark.skipif(
    os.geteuid() != 0 or shutil.which("unshare") is None,
    reason="needs root and unshare (/etc/srcs shown in a private mount namespace)",
)
def test_bash_completes_robot_names_and_causes(tmp_path: Path) -> None:
    """SR-11.3: in a real bash, ``srcsctl -R <TAB>`` offers the robots of /etc/srcs (two
    configs laid over /etc in a private mount namespace, the machine's /etc left alone) and
    ``srcsctl log --cause <TAB>`` the cause names."""
    out = tmp_path / "completion"
    built = run(sys.executable, "-m", "supervisord.cli.reference", "completion", str(out))
    assert built.returncode == 0, built.stderr
    layer = tmp_path / "layer"
    (layer / "srcs").mkdir(parents=True)
    for robot in ("mower", "robot-a"):
        (layer / "srcs" / f"{robot}.toml").write_text("")
    overlay = f'mount -t overlay overlay -o "lowerdir={layer}:/etc" /etc && exec "$@"'
    script = str(out / "srcsctl")

    def offered(*line: str) -> list[str]:
        bash = [BASH, "--norc", "--noprofile", "-c", COMPLETE, "-", script, *line]
        done = run("unshare", "-m", "sh", "-c", overlay, "-", *bash)
        assert done.returncode == 0, done.stderr
        return sorted(done.stdout.split())

    assert offered("srcsctl", "-R") == ["mower", "robot-a"]
    assert offered("srcsctl", "log", "--robot") == ["mower", "robot-a"]
    assert offered("srcsctl", "log", "--cause") == sorted(CAUSE_NAMES)

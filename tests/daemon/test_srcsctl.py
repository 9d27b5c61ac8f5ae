"""``srcsctl``'s daemon commands, run as real processes against the real ``srcsd``."""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import os
import re
import shutil
import signal
import subprocess
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from supervisord.api.pushes import StatePush
from supervisord.api.status import Cause
from supervisord.protocol.codes import VscMode
from supervisord.protocol.messages import FeedbackName, FeedbackSet
from supervisord.sim.pty import PtyPort
from supervisord.testkit.daemon import SrcsdProcess
from supervisord.testkit.wait import wait_until
from supervisord.vocabulary import Cause as Named
from supervisord.vocabulary import CauseKind, Severity
from tests.api.samples import STOPPED
from tests.daemon.peer import VscPeer
from tests.daemon.test_srcsd import CONFIG

SRCSCTL = shutil.which("srcsctl") or str(Path(__file__).parents[2] / ".venv/bin/srcsctl")


class Robot:
    """A running ``srcsd`` with its VSC peer served from a thread."""

    def __init__(self, tmp_path: Path, peer: VscPeer) -> None:
        self.dir = tmp_path
        self.peer = peer
        self.config = tmp_path / "robot.toml"

    def ctl(self, *args: str, stdin: str = "") -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [SRCSCTL, *args[:1], "--config", str(self.config), *args[1:]],
            input=stdin,
            capture_output=True,
            text=True,
            timeout=30,
            check=False,
        )

    def status(self) -> dict[str, object]:
        result = self.ctl("status", "--json")
        assert result.returncode == 0, result.stderr
        status = json.loads(result.stdout)
        assert isinstance(status, dict)
        return status

    def active(self) -> set[str]:
        causes = self.status()["causes"]
        assert isinstance(causes, list)
        return {c["name"] for c in causes if c["active"]}


@pytest.fixture
def robot(tmp_path: Path) -> Iterator[Robot]:
    (tmp_path / "robot.toml").write_text(CONFIG)
    with PtyPort(tmp_path / "vsc") as port:
        peer = VscPeer(port)
        with (
            SrcsdProcess(tmp_path / "robot.toml").start(serve=peer.serve) as daemon,
            peer.serving(),
        ):
            yield Robot(tmp_path, peer)
    assert daemon.exit_status == 0


def test_status_in_both_forms(robot: Robot) -> None:
    """The human form names the robot, the state, each cause (the startup stop cleared, held
    by its latch: marked ``*`` as everywhere, with the marker's meaning once) and each output;
    --json is the API's reply with the daemon's own part (link, counters)."""
    status = robot.status()
    assert status["state"] == "STOPPED"
    daemon = status["daemon"]
    assert isinstance(daemon, dict)
    assert daemon["robot"] == "test-robot"
    assert daemon["pid"] > 0
    human = robot.ctl("status")
    assert human.returncode == 0
    assert human.stdout.startswith("robot test-robot: STOPPED for ")
    assert "outputs  drive=off" in human.stdout
    assert "startup* (stop)" in human.stdout
    assert human.stdout.count("* cleared; its latch holds the stop until a re-arm") == 1
    assert f"link     serial {robot.dir / 'vsc'}" in human.stdout


def test_estop_release_hold_and_a_refused_reset(robot: Robot) -> None:
    """A local e-stop and its release; a named hold that outlives the srcsctl process until
    the same name releases it; a reset refused with the core's reason and exit status 1."""
    done = robot.ctl("estop")
    assert done.returncode == 0, done.stderr
    assert "estop (local): done; the supervisor is STOPPED" in done.stdout
    assert "local_estop" in robot.active()
    assert robot.ctl("release").returncode == 0
    assert "local_estop" not in robot.active()

    assert robot.ctl("hold").returncode == 0
    assert "client_hold:srcsctl" in robot.active()  # the process has exited; the hold stays
    assert robot.ctl("release", "hold").returncode == 0
    assert "client_hold:srcsctl" not in robot.active()

    refused = robot.ctl("reset")
    assert refused.returncode == 1
    assert "refused: local reset is not allowed" in refused.stderr
    records = (robot.dir / "stops.jsonl").read_text().splitlines()
    assert any(json.loads(line)["kind"] == "rearm_refused" for line in records)


def test_display_and_vibrate_reach_the_vsc(robot: Robot) -> None:
    """Text rows, labelled values, the page and vibration go out as the manual's frames."""
    for args in (
        ("display", "row", "1", "HELLO"),
        ("display", "value", "3", "42", "--label", "SPEED"),
        ("display", "mode", "labelled"),
        ("vibrate", "left"),
    ):
        result = robot.ctl(*args)
        assert result.returncode == 0, (args, result.stderr)
    wanted = [FeedbackSet(3, 42), FeedbackSet(99, 2), FeedbackSet(10, 1)]
    deadline = time.monotonic() + 5
    while not all(m in robot.peer.received for m in wanted):
        assert time.monotonic() < deadline, robot.peer.received
        time.sleep(0.02)
    names = [m for m in robot.peer.received if isinstance(m, FeedbackName)]
    assert any(m.text.startswith("HELLO") for m in names)
    assert any(m.text.startswith("SPEED") for m in names)
    bad = robot.ctl("display", "row", "7", "X")  # a usage error, found before the daemon is asked
    assert bad.returncode == 2
    assert "'7' is not a whole number from 1 to 4" in bad.stderr


def test_commission_asks_for_confirmation_then_writes_and_reads_back(robot: Robot) -> None:
    """Without --yes it asks; anything but 'yes' writes nothing. With --yes it commissions."""
    robot.peer.key85 = 0
    declined = robot.ctl("commission", stdin="no\n")
    assert declined.returncode == 1
    assert "Type 'yes'" in declined.stdout
    assert robot.peer.key85 == 0
    done = robot.ctl("commission", stdin="yes\n")
    assert done.returncode == 0, done.stderr
    assert "commissioned: key 85 reads 1; remote status on" in done.stdout
    assert robot.peer.key85 == 1


def test_watch_follows_a_stop_live(robot: Robot) -> None:
    """``watch`` prints the state at once, then each change and record as it happens."""
    with subprocess.Popen(
        [SRCSCTL, "watch", "--config", str(robot.config)],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    ) as watcher:
        try:
            assert watcher.stdout is not None
            assert watcher.stdout.readline().startswith("# srcsd ")  # the daemon's line
            first = watcher.stdout.readline()
            assert " STOPPED " in first
            assert robot.ctl("estop").returncode == 0
            lines: list[str] = []
            while not any("raised local_estop" in line for line in lines):
                lines.append(watcher.stdout.readline())
                assert lines[-1], "watch ended early"
            (record,) = [line for line in lines if "raised local_estop" in line]
            assert re.search(r"#\d+ +STOPPED +cause_raised +raised local_estop", record), record
            watcher.send_signal(signal.SIGINT)
            assert watcher.wait(timeout=10) == 0
        finally:
            if watcher.poll() is None:
                watcher.kill()


def test_no_daemon_and_bad_config_have_their_own_exit_status(tmp_path: Path) -> None:
    """SR-8.8: 3: nobody listens at the socket; 2: what the client reads of the config is
    invalid (the message names the key); a wrong safety value is the daemon's to refuse, and
    the client finds no daemon at that config's socket (3)."""
    missing = subprocess.run(
        [SRCSCTL, "status", "--socket", str(tmp_path / "none.sock")],
        capture_output=True,
        text=True,
        check=False,
    )
    assert missing.returncode == 3
    assert "is srcsd running?" in missing.stderr
    (tmp_path / "bad.toml").write_text(CONFIG.replace('socket = "api.sock"', "socket = 5"))
    bad = subprocess.run(
        [SRCSCTL, "status", "--config", str(tmp_path / "bad.toml")],
        capture_output=True,
        text=True,
        check=False,
        env={**os.environ, "SRCS_SOCKET": ""},
    )
    assert bad.returncode == 2
    assert "api.socket = 5" in bad.stderr
    (tmp_path / "unsafe.toml").write_text(CONFIG.replace('"serial"', '"x"'))
    unsafe = subprocess.run(
        [SRCSCTL, "status", "--config", str(tmp_path / "unsafe.toml")],
        capture_output=True,
        text=True,
        check=False,
        env={**os.environ, "SRCS_SOCKET": ""},
    )
    assert unsafe.returncode == 3
    assert f"cannot connect to {tmp_path / 'api.sock'}" in unsafe.stderr


# -- status in full, and srcsctl without sharp edges ----------------------------------------


class _Output:
    """What a running command prints, read without blocking, kept whole lines at a time."""

    def __init__(self, proc: subprocess.Popen[str]) -> None:
        assert proc.stdout is not None
        self.fd = proc.stdout.fileno()
        os.set_blocking(self.fd, False)
        self.data = b""

    @property
    def lines(self) -> list[str]:
        return self.data.decode().split("\n")[:-1]  # whole lines only

    def until(self, done: Callable[[list[str]], bool], limit: float = 10.0) -> list[str]:
        """Every line so far, once ``done`` holds for them; fails after ``limit`` seconds, a
        coarse deadline (the command's interpreter may take a while to start on a busy
        machine)."""
        end = time.monotonic() + limit
        while not done(lines := self.lines):
            assert time.monotonic() < end, lines
            try:
                self.data += os.read(self.fd, 65536)
            except BlockingIOError:
                time.sleep(0.05)
        return lines


def _settled(robot: Robot) -> None:
    """Wait until the link is open and the state stops changing (the startup transients)."""
    deadline = time.monotonic() + 10
    while "vsc_link_lost" in robot.active() or "transport_fault" in robot.active():
        assert time.monotonic() < deadline
        time.sleep(0.05)
    time.sleep(0.3)


@pytest.mark.parametrize("as_json", [False, True])
def test_watch_prints_the_first_state_once(robot: Robot, as_json: bool) -> None:
    """``watch`` shows the state it starts in once, not once from ``status`` and again from
    the subscription's push; with --json every line is a push (``event``), never a reply.
    The human form shows a state again only when the state or an output changes: a hold in
    STOPPED is its record's line alone (what was raised), not the whole state once more.

    No window of time: a hold taken once the first state is shown makes a new state push and
    a record, which the ordered stream delivers after any second copy of the first."""
    _settled(robot)
    args = [SRCSCTL, "watch", "--config", str(robot.config), *(["--json"] if as_json else [])]
    with subprocess.Popen(args, stdout=subprocess.PIPE, text=True) as watcher:
        try:
            output = _Output(watcher)
            output.until(lambda lines: len(_states(lines, as_json)) >= 1)
            assert robot.ctl("hold").returncode == 0
            if as_json:
                lines = output.until(lambda lines: len(set(_states(lines, as_json))) >= 2)
            else:
                lines = output.until(lambda lines: any("raised client_hold" in x for x in lines))
        finally:
            watcher.send_signal(signal.SIGINT)
            watcher.wait(timeout=10)
    if as_json:
        objects = [json.loads(line) for line in lines]
        assert all("event" in o and "ok" not in o for o in objects), lines
        # A state the daemon decided once (one mono_ns) is shown once.
        decided = _states(lines, as_json)
        assert len(decided) == len(set(decided)), lines
    else:
        # The daemon's own line, then the state, from the subscription's push alone, once.
        assert lines[0].startswith("# srcsd "), lines  # the daemon's own line first
        assert _states(lines, as_json) == [lines[1]], lines
        (hold,) = [line for line in lines if "client_hold" in line]
        assert re.search(r"#\d+ +STOPPED +cause_raised +raised client_hold:srcsctl$", hold), hold


def _states(lines: list[str], as_json: bool) -> list[str]:
    """The states ``watch`` showed: each push's decision time (--json), or each state line
    (the time of day, then the state; a record's line has its ``#N`` there)."""
    if as_json:
        pushes = [json.loads(line) for line in lines]
        return [str(p["mono_ns"]) for p in pushes if p.get("event") == "state"]
    return [line for line in lines if re.match(r"\S+ STOPPED ", line)]


def test_watch_ends_on_sigint_even_when_started_with_sigint_ignored(robot: Robot) -> None:
    """SR-8.9: Ctrl-C (SIGINT) ends ``watch`` with status 0 also when it was started from a script
    in the background, which starts it with SIGINT ignored (the cause of a timed-out
    test_watch_follows_a_stop_live); SIGTERM ends it too."""
    for sig in (signal.SIGINT, signal.SIGTERM):
        with subprocess.Popen(
            [SRCSCTL, "watch", "--config", str(robot.config)],
            stdout=subprocess.PIPE,
            text=True,
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN),  # noqa: PLW1509
        ) as watcher:
            try:
                assert watcher.stdout is not None
                assert watcher.stdout.readline()
                watcher.send_signal(sig)
                assert watcher.wait(timeout=10) == 0
            finally:
                if watcher.poll() is None:
                    watcher.kill()


def test_options_are_taken_after_the_arguments_and_before_the_command(robot: Robot) -> None:
    """``--config``/``--socket`` work after a subcommand's arguments (``display row 1 X``)
    and before the command (``srcsctl --socket S status``)."""
    after = robot.ctl("display", "row", "1", "HI", "--config", str(robot.config))
    assert after.returncode == 0, after.stderr
    mode = subprocess.run(
        [SRCSCTL, "display", "mode", "gps", "--socket", str(robot.dir / "api.sock")],
        capture_output=True,
        text=True,
        timeout=30,
        check=False,
    )
    assert mode.returncode == 0, mode.stderr
    before = subprocess.run(
        [SRCSCTL, "--socket", str(robot.dir / "api.sock"), "status"],
        capture_output=True,
        text=True,
        timeout=30,
        check=False,
    )
    assert before.returncode == 0, before.stderr
    assert before.stdout.startswith("robot test-robot: ")


@pytest.mark.skipif(os.geteuid() != 0, reason="needs root to run srcsctl as another user")
def test_permission_denied_is_reported_as_such(robot: Robot) -> None:
    """A user who may not open the socket is told so (exit 4), not asked whether srcsd runs."""
    os.chmod(robot.dir, 0o755)  # noqa: S103 -- the directory is traversable, the socket 0660
    denied = subprocess.run(
        ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups", SRCSCTL, "status"],
        capture_output=True,
        text=True,
        timeout=30,
        check=False,
        env={**os.environ, "SRCS_SOCKET": str(robot.dir / "api.sock")},
    )
    assert denied.returncode == 4, denied.stderr
    assert "permission denied" in denied.stderr.lower()
    assert "is srcsd running" not in denied.stderr


def test_status_in_full(robot: Robot) -> None:
    """``status`` names the clients (required or not, heartbeat age), the remote's battery,
    link strength and RSSI, the version, the time in the state, the uptime and the link."""
    from supervisord.client import SupervisorClient  # noqa: PLC0415

    robot.peer.remote_status_ms = 100
    with SupervisorClient.connect(robot.dir / "api.sock", name="nav") as nav:
        nav.heartbeat()
        deadline = time.monotonic() + 10
        while robot.status()["daemon"]["remote"] is None:  # type: ignore[index]
            assert time.monotonic() < deadline
            time.sleep(0.05)
        status = robot.status()
        human = robot.ctl("status").stdout
    daemon = status["daemon"]
    assert isinstance(daemon, dict)
    (client,) = daemon["clients"]
    assert client["name"] == "nav"
    assert client["required"] is False
    assert client["connected"]
    assert 0 <= client["heartbeat_age_s"] < 10
    assert daemon["remote"]["battery_level"] == 80
    assert {"rssi_vsc", "connection_strength_vsc", "battery_charging"} <= set(daemon["remote"])
    assert daemon["version"]
    assert daemon["uptime_s"] >= daemon["in_state_s"] >= 0
    assert daemon["link"]["open"]
    assert daemon["link"]["since_s"] >= 0
    assert "  clients  nav (optional): heartbeat " in human
    assert "  remote   battery 80 %" in human
    assert "  daemon   srcsd " in human
    assert " up " in human
    assert "STOPPED for " in human


def _records(tmp_path: Path) -> Path:
    """A record file of three entries: yesterday, two hours ago and now; the last with one
    active and one latched-cleared cause."""
    import datetime as dt  # noqa: PLC0415

    now = dt.datetime.now(dt.timezone.utc)
    base = {
        "mono_ns": 1,
        "kind": "state_change",
        "from": "RUN",
        "to": "STOPPED",
        "changes": [],
        "trigger": {"event": "tick"},
    }
    cause = {"severity": "stop", "latched": True, "raised_ns": 1, "cleared_ns": None}
    times = [now - dt.timedelta(days=1, hours=1), now - dt.timedelta(hours=2), now]
    path = tmp_path / "stops.jsonl"
    with path.open("w") as out:
        for seq, when in enumerate(times, 1):
            causes = [
                {**cause, "name": "local_estop", "active": True, "details": {}},
                {**cause, "name": "vsc_estop", "active": False, "details": {}},
            ]
            entry = {**base, "seq": seq, "utc": when.isoformat(), "causes": causes}
            out.write(json.dumps(entry) + "\n")
    return path


def _log(*args: str, tz: str = "UTC") -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [SRCSCTL, "log", *args],
        capture_output=True,
        text=True,
        timeout=30,
        check=False,
        env={**os.environ, "TZ": tz},
    )


def test_log_marks_and_time_zone_agree_with_watch(tmp_path: Path) -> None:
    """In ``log`` as in ``watch``, ``*`` marks a latched cause whose condition has cleared;
    times are local unless ``--utc``. A record that names no change shows its causes; the
    whole set is ``--causes`` away for every record."""
    path = _records(tmp_path)
    local = _log("--file", str(path), tz="Asia/Kolkata")
    assert local.returncode == 0, local.stderr
    assert "causes local_estop, vsc_estop*" in local.stdout
    full = _log("--file", str(path), "--causes")
    assert "[causes: local_estop, vsc_estop*; trigger tick]" in full.stdout
    assert "+05:30" in local.stdout.splitlines()[0]
    utc = _log("--file", str(path), "--utc", tz="Asia/Kolkata")
    assert "+00:00" in utc.stdout.splitlines()[0]
    assert "+05:30" not in utc.stdout

    from supervisord.cli.control import format_push  # noqa: PLC0415

    cleared = Cause(
        name=Named(CauseKind.VSC_ESTOP),
        severity=Severity.STOP,
        active=False,
        latched=True,
        raised_ns=1,
        cleared_ns=2,
    )
    line = format_push(StatePush(dataclasses.replace(STOPPED, causes=(cleared,))))
    assert "vsc_estop*" in line


def test_log_prints_a_cause_kind_it_does_not_know_as_written(tmp_path: Path) -> None:
    """SR-7.1, SR-8.7: a record line naming a cause kind this version does not know (a newer
    daemon's, or an old record's) is printed by ``log`` as written, never refused: raised, in
    the cause set, and selected by its name (docs/api.md "Cause kinds a client does not
    know")."""
    from tests.record.test_unknown_cause import LINE  # noqa: PLC0415

    path = tmp_path / "stops.jsonl"
    path.write_text(json.dumps(LINE) + "\n")
    done = _log("--file", str(path), "--causes")
    assert done.returncode == 0, done.stderr
    assert done.stderr == ""
    assert "raised lidar_blind:front (dazzled)" in done.stdout, done.stdout
    assert "[causes: lidar_blind:front, vsc_estop:odd*; trigger tick]" in done.stdout


def test_log_since_today_yesterday_an_age_and_n(tmp_path: Path) -> None:
    """``--since`` takes today, yesterday and ``-1h``; ``-n N`` shows the last N records."""
    path = _records(tmp_path)

    def seqs(*args: str) -> list[str]:
        result = _log("--file", str(path), *args)
        assert result.returncode == 0, result.stderr
        return [line.split()[1] for line in result.stdout.splitlines()]

    assert seqs("--since", "-1h") == ["#3"]
    assert seqs("--since", "3h") == ["#2", "#3"]
    assert seqs("--since", "yesterday")[-2:] == ["#2", "#3"]
    assert "#3" in seqs("--since", "today")
    assert "#1" not in seqs("--since", "today")
    assert seqs("-n", "2") == ["#2", "#3"]
    assert seqs("-n", "1", "--since", "yesterday") == ["#3"]
    bad = _log("--file", str(path), "--since", "last tuesday")
    assert bad.returncode == 2
    assert "not a time" in bad.stderr


def test_log_follow_prints_records_as_they_are_appended(tmp_path: Path) -> None:
    """``log -f`` prints the last records, then each new one as it is written."""
    path = _records(tmp_path)
    with subprocess.Popen(
        [SRCSCTL, "log", "--file", str(path), "-f", "-n", "1"], stdout=subprocess.PIPE, text=True
    ) as follower:
        try:
            assert follower.stdout is not None
            assert " #3 " in follower.stdout.readline()
            last = json.loads(path.read_text().splitlines()[-1])
            with path.open("a") as out:
                out.write(json.dumps({**last, "seq": 4}) + "\n")
            assert " #4 " in follower.stdout.readline()
            follower.send_signal(signal.SIGINT)
            assert follower.wait(timeout=10) == 0
        finally:
            if follower.poll() is None:
                follower.kill()


def test_log_without_a_config_names_the_choices(tmp_path: Path) -> None:
    """Without --config or --file, ``log`` uses the one config in the config directory, and
    with none or several says so and names them, instead of a file nobody made."""
    from supervisord.cli.srcsctl import default_config  # noqa: PLC0415

    with pytest.raises(LookupError, match="no config"):
        default_config(tmp_path)
    (tmp_path / "robot-a.toml").write_text("")
    assert default_config(tmp_path) == tmp_path / "robot-a.toml"
    (tmp_path / "robot-b.toml").write_text("")
    with pytest.raises(LookupError, match=r"robot-a\.toml, .*robot-b\.toml"):
        default_config(tmp_path)


# -- records in words, and journalctl's habits ------------------------------------------------


def _lines(result: subprocess.CompletedProcess[str]) -> list[str]:
    assert result.returncode == 0, result.stderr
    return result.stdout.splitlines()


def test_log_says_what_each_record_did(robot: Robot) -> None:
    """SR-7.1, SR-4: with the real ``srcsd``, ``log`` shows each record as one line: the state
    change if any, the record's kind, which cause was raised (with its details: who asked) or
    cleared (not the whole set again) and, for a refused reset, the core's reason; a cause
    that cleared and stays latched is marked ``*``, in ``log`` as in ``status``; ``-o json``
    is ``--json``."""
    _settled(robot)
    for command in ("estop", "release"):
        assert robot.ctl(command).returncode == 0
    assert robot.ctl("reset").returncode == 1
    log = _lines(robot.ctl("log", "-n", "3"))
    caller = r"\(caller=\w+; pid=\d+; uid=\d+\)"  # who pressed it: the cause's details
    assert re.search(rf"#\d+ +STOPPED +cause_raised +raised local_estop {caller}$", log[0]), log
    assert re.search(r"#\d+ +STOPPED +cause_cleared +cleared local_estop\*$", log[1]), log
    assert re.search(
        r"#\d+ +STOPPED +rearm_refused +reset refused: local reset is not allowed by the "
        r"config \(local_reset = false\)$",
        log[2],
    ), log
    assert "startup" not in log[0]  # the causes that did not change are not repeated
    full = _lines(robot.ctl("log", "-n", "1", "--causes"))
    assert re.search(r"\[causes: .*local_estop\*.*; trigger reset_request\]$", full[0]), full
    assert "local_estop* (stop)" in robot.ctl("status").stdout
    as_json = robot.ctl("log", "-n", "3", "--json").stdout
    assert robot.ctl("log", "-n", "3", "-o", "json").stdout == as_json
    assert [json.loads(line)["kind"] for line in as_json.splitlines()] == [
        "cause_raised",
        "cause_cleared",
        "rearm_refused",
    ]


def _timed_records(tmp_path: Path, ages_min: list[int]) -> Path:
    """A record file with one record per age (minutes before now), seq 1, 2, ..."""
    now = dt.datetime.now(dt.timezone.utc)
    path = tmp_path / "stops.jsonl"
    with path.open("w") as out:
        for seq, age in enumerate(ages_min, 1):
            cause = {"name": f"client_hold:n{seq}", "severity": "hold", "active": True}
            entry = {
                "seq": seq,
                "mono_ns": seq,
                "utc": (now - dt.timedelta(minutes=age)).isoformat(),
                "kind": "cause_raised",
                "from": "STOPPED",
                "to": "STOPPED",
                "causes": [{**cause, "latched": False, "details": {}}],
                "changes": [{"name": f"client_hold:n{seq}", "change": "raised"}],
                "trigger": {"event": "client_hold"},
            }
            out.write(json.dumps(entry) + "\n")
    return path


def _seqs(result: subprocess.CompletedProcess[str]) -> list[int]:
    return [int(line.split()[1].lstrip("#")) for line in _lines(result)]


def test_log_takes_journalctls_habits(tmp_path: Path) -> None:
    """``-n`` alone is the last 10, ``-r`` newest first, and ``--since``/``-S`` take
    journalctl's relative times ("5 min ago", -5min, "2 hours ago", yesterday, today)."""
    ages = [60 * 30, 300, 130, 90, 50, 40, 30, 20, 12, 8, 4, 1]  # minutes ago, oldest first
    path = _timed_records(tmp_path, ages)
    file = ["--file", str(path)]
    assert _seqs(_log(*file, "-n")) == list(range(3, 13))
    assert _seqs(_log(*file, "-n", "3", "-r")) == [12, 11, 10]
    assert _seqs(_log(*file, "--since", "5 min ago")) == [11, 12]
    assert _seqs(_log(*file, "-S", "-5min")) == [11, 12]
    assert _seqs(_log(*file, "--since", "2 hours ago")) == list(range(4, 13))
    assert _seqs(_log(*file, "--since", "1h 40min ago", "--until", "-10min")) == list(range(4, 10))
    assert _seqs(_log(*file, "-S", "yesterday"))[-11:] == list(range(2, 13))
    # The record of 30 hours ago is never today's; in the minute after midnight no record is,
    # and log says so in a line of its own, so only the lines of records are read.
    today = _lines(_log(*file, "-S", "today"))
    assert not [line for line in today if line.split()[1:2] == ["#1"]], today
    both = _log(*file, "-r", "-f")
    assert both.returncode == 2
    assert "-r and -f do not go together" in both.stderr


def test_log_follow_prints_the_last_10_then_watches_the_file(tmp_path: Path) -> None:
    """SR-8.9, SR-7.2: ``log -f`` prints the last 10 records (not the whole history), then
    each record as it is appended, through rotation (the file renamed to ``.1``, a new one
    made), watching the file with inotify rather than reading it again and again; SIGINT ends
    it with exit 0."""
    path = _timed_records(tmp_path, list(range(24, 0, -2)))
    with subprocess.Popen(
        [SRCSCTL, "log", "--file", str(path), "-f"], stdout=subprocess.PIPE, text=True
    ) as follower:
        try:
            output = _Output(follower)
            first = output.until(lambda lines: len(lines) >= 10)
            assert [int(line.split()[1].lstrip("#")) for line in first] == list(range(3, 13))
            fds = Path(f"/proc/{follower.pid}/fdinfo")
            assert any("inotify wd:" in info.read_text() for info in fds.iterdir())
            last = json.loads(path.read_text().splitlines()[-1])
            with path.open("a") as out:
                out.write(json.dumps({**last, "seq": 13, "mono_ns": 13}) + "\n")
            output.until(lambda lines: any(" #13 " in line for line in lines))
            path.rename(tmp_path / "stops.jsonl.1")  # rotation, as the writer does it
            path.write_text(json.dumps({**last, "seq": 14, "mono_ns": 14}) + "\n")
            lines = output.until(lambda lines: any(" #14 " in line for line in lines))
            assert [int(line.split()[1].lstrip("#")) for line in lines] == list(range(3, 15))
            follower.send_signal(signal.SIGINT)
            assert follower.wait(timeout=10) == 0
        finally:
            if follower.poll() is None:
                follower.kill()


def test_a_robot_is_chosen_by_its_name(tmp_path: Path) -> None:
    """``--robot NAME`` (``-R``, also ``srcsd@NAME``) stands for ``/etc/srcs/NAME.toml`` in
    every command, before or after it; a robot that is not there is a usage error (exit 2)
    naming the file and the robots that are."""
    from supervisord.cli.srcsctl import robot_config  # noqa: PLC0415

    (tmp_path / "robot-a.toml").write_text("")
    assert robot_config("robot-a", tmp_path) == tmp_path / "robot-a.toml"
    assert robot_config("srcsd@robot-a.service", tmp_path) == tmp_path / "robot-a.toml"
    with pytest.raises(LookupError, match=r"robot-b\.toml does not exist \(robots here: robot-a\)"):
        robot_config("robot-b", tmp_path)
    for args in (["-R", "srcs-test-none", "status"], ["log", "--robot", "srcsd@srcs-test-none"]):
        missing = subprocess.run([SRCSCTL, *args], capture_output=True, text=True, check=False)
        assert missing.returncode == 2, missing.stderr
        assert "/etc/srcs/srcs-test-none.toml does not exist" in missing.stderr


def test_wait_ready_passes_once_the_stop_path_works(robot: Robot) -> None:
    """SR-8.10: ``wait-ready`` exits 0 once the VSC is heard, its watchdog proven and the
    outputs held; the supervisor is still STOPPED (ready is not armed). The proof test's last
    result is asked for, not its phase: the peer is a thread of this test, and when it is late
    by the VSC timeout the watchdog is proven again (SR-5.6), its phase then not yet passed."""
    done = robot.ctl("wait-ready", "--timeout", "30")
    assert done.returncode == 0, done.stderr
    assert "ready" in done.stdout
    status = robot.status()
    assert status["state"] == "STOPPED"
    assert status["prooftest"]["last"]["result"] == "passed"  # type: ignore[index]


def test_wait_ready_names_what_is_missing(tmp_path: Path) -> None:
    """SR-8.10: with no VSC answering, ``wait-ready`` gives up at its timeout with exit 1,
    naming what is missing; with no supervisor at all, exit 3."""
    config = tmp_path / "robot.toml"
    config.write_text(CONFIG)
    nobody = subprocess.run(
        [SRCSCTL, "wait-ready", "--config", str(config), "--timeout", "0.5"],
        capture_output=True,
        text=True,
        timeout=30,
        check=False,
    )
    assert nobody.returncode == 3, nobody.stderr
    assert "no supervisor answers" in nobody.stderr
    with PtyPort(tmp_path / "vsc"), SrcsdProcess(config).start():
        silent = subprocess.run(
            [SRCSCTL, "wait-ready", "--config", str(config), "--timeout", "1"],
            capture_output=True,
            text=True,
            timeout=30,
            check=False,
        )
    assert silent.returncode == 1, silent.stderr
    assert "not ready after 1 s" in silent.stderr
    assert "the VSC is not heard" in silent.stderr


def _available_when(robot: Robot, done: Callable[[dict[str, object]], bool]) -> dict[str, Any]:
    """The ``estop_available`` object of the first ``status`` for which ``done`` holds (the
    peer's thread changes what the VSC sends; the daemon reads it within a few turns)."""
    deadline = time.monotonic() + 20
    while True:
        available = robot.status()["estop_available"]
        assert isinstance(available, dict)
        if done(available):
            return available
        assert time.monotonic() < deadline, available
        time.sleep(0.05)


def _shown_when(robot: Robot, line: str) -> None:
    """Wait until ``srcsctl status`` shows ``line``."""
    wait_until(lambda: line in robot.ctl("status").stdout, what=repr(line))


def test_status_says_whether_the_remote_estop_is_available(robot: Robot) -> None:
    """SR-8.11: ``status`` and ``srcsctl status`` say whether the remote e-stop is available
    and name each part missing: no battery report before remote status is on, a battery
    below ``vsc.min_remote_battery`` (20 %), no remote linked (Searching); available once the
    VSC is heard, a remote linked, its battery reported and high enough and the watchdog
    proven. The state is not asked for: it is STOPPED throughout. Each step waits for the
    list it names, whole: the peer is a thread of this test, and when it is late by the VSC
    timeout the daemon proves the watchdog again (SR-5), a part missing for a while."""
    done = robot.ctl("wait-ready", "--timeout", "30")
    assert done.returncode == 0, done.stderr
    unreported = "the remote's battery is not reported"
    first = _available_when(robot, lambda a: [m[:36] for m in a["missing"]] == [unreported])  # type: ignore[attr-defined]
    assert first["available"] is False

    robot.peer.battery = 10
    robot.peer.remote_status_ms = 100
    low = "the remote's battery is 10 %, below 20 %"
    _available_when(robot, lambda a: a["missing"] == [low])
    _shown_when(robot, f"  e-stop   NOT AVAILABLE: {low}\n")

    robot.peer.battery = 20
    assert _available_when(robot, lambda a: a["available"] is True)["missing"] == []
    _shown_when(robot, "  e-stop   available\n")

    robot.peer.mode = VscMode.SEARCHING
    unlinked = "no remote is linked to the VSC (its mode is searching)"
    _available_when(robot, lambda a: a["missing"] == [unlinked])
    assert robot.status()["state"] == "STOPPED"


def test_a_vsc_with_its_watchdog_off_names_the_command_that_commissions_it(
    tmp_path: Path,
) -> None:
    """SR-8.18: a VSC fresh from the box (key 85 = 0): ``wait-ready`` at its timeout,
    ``status`` and the daemon's log each name ``srcsctl ... commission`` with the way this
    daemon is reached, and who may run it; once commissioned the gate opens."""
    config = tmp_path / "robot.toml"
    config.write_text(CONFIG)
    log = tmp_path / "srcsd.log"
    fix = f"commission the VSC once: srcsctl --config {config} commission"
    with PtyPort(tmp_path / "vsc") as port:
        peer = VscPeer(port, key85=0)
        with (
            SrcsdProcess(config, log=log).start(serve=peer.serve),
            peer.serving(),
        ):
            robot = Robot(tmp_path, peer)
            wait_until(lambda: "vsc_watchdog_off" in robot.active(), what="vsc_watchdog_off")
            gate = robot.ctl("wait-ready", "--timeout", "1")
            assert gate.returncode == 1, gate.stderr
            assert f"the VSC's key-85 watchdog is off: {fix}" in gate.stderr
            assert "api.admin_group" in gate.stderr
            shown = robot.ctl("status")
            assert f"  ready    no: the VSC's key-85 watchdog is off: {fix}" in shown.stdout
            wait_until(lambda: fix in log.read_text(), what="the fix in the daemon's log")
            done = robot.ctl("commission", "--yes")
            assert done.returncode == 0, done.stderr
            opened = robot.ctl("wait-ready", "--timeout", "30")
            assert opened.returncode == 0, opened.stderr
            assert "  ready    " not in robot.ctl("status").stdout

"""``srcsctl``'s daemon commands, run as real processes against the real ``srcsd``."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from supervisord.protocol.messages import FeedbackName, FeedbackSet
from supervisord.sim.pty import PtyPort
from supervisord.testkit.daemon import SrcsdProcess
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
    """The human form names the robot, the state, each cause and each output; --json is the
    API's reply with the daemon's own part (link, counters)."""
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
    assert "startup (stop, " in human.stdout
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
    bad = robot.ctl("display", "row", "7", "X")
    assert bad.returncode == 1
    assert "bad_request" in bad.stderr


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
            while not any("local_estop" in line and "record #" in line for line in lines):
                lines.append(watcher.stdout.readline())
                assert lines[-1], "watch ended early"
            watcher.send_signal(signal.SIGINT)
            assert watcher.wait(timeout=10) == 0
        finally:
            if watcher.poll() is None:
                watcher.kill()


def test_no_daemon_and_bad_config_have_their_own_exit_status(tmp_path: Path) -> None:
    """3: nobody listens at the socket; 2: the config is invalid (the message names the key)."""
    missing = subprocess.run(
        [SRCSCTL, "status", "--socket", str(tmp_path / "none.sock")],
        capture_output=True,
        text=True,
        check=False,
    )
    assert missing.returncode == 3
    assert "is srcsd running?" in missing.stderr
    (tmp_path / "bad.toml").write_text(CONFIG.replace('transport = "serial"', 'transport = "x"'))
    bad = subprocess.run(
        [SRCSCTL, "status", "--config", str(tmp_path / "bad.toml")],
        capture_output=True,
        text=True,
        check=False,
        env={**os.environ, "SRCS_SOCKET": ""},
    )
    assert bad.returncode == 2
    assert "vsc.transport" in bad.stderr


# -- issue 13: status in full, and srcsctl without sharp edges ------------------------------


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

    No window of time: a hold taken once the first state is shown makes a new state push,
    which the ordered stream delivers after any second copy of the first."""
    _settled(robot)
    args = [SRCSCTL, "watch", "--config", str(robot.config), *(["--json"] if as_json else [])]
    with subprocess.Popen(args, stdout=subprocess.PIPE, text=True) as watcher:
        try:
            output = _Output(watcher)
            output.until(lambda lines: len(_states(lines, as_json)) >= 1)
            assert robot.ctl("hold").returncode == 0
            lines = output.until(lambda lines: len(set(_states(lines, as_json))) >= 2)
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
        # The daemon's own line, then the state, from the subscription's push alone (the
        # human and the JSON form share that path; the JSON form pins the duplicate down).
        assert len(lines) >= 2, lines
        assert " STOPPED " in lines[1], lines
        assert lines[0].startswith("# srcsd "), lines  # the daemon's own line first


def _states(lines: list[str], as_json: bool) -> list[str]:
    """The states ``watch`` showed: each push's decision time (--json), or each line."""
    if as_json:
        pushes = [json.loads(line) for line in lines]
        return [str(p["mono_ns"]) for p in pushes if p.get("event") == "state"]
    return [line for line in lines if " STOPPED " in line]


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
    times are local unless ``--utc``."""
    path = _records(tmp_path)
    local = _log("--file", str(path), tz="Asia/Kolkata")
    assert local.returncode == 0, local.stderr
    assert "[local_estop, vsc_estop*]" in local.stdout
    assert "+05:30" in local.stdout.splitlines()[0]
    utc = _log("--file", str(path), "--utc", tz="Asia/Kolkata")
    assert "+00:00" in utc.stdout.splitlines()[0]
    assert "+05:30" not in utc.stdout

    from supervisord.cli.control import format_push  # noqa: PLC0415

    cleared = {"name": "vsc_estop", "active": False, "latched": True}
    line = format_push("state", {"state": "STOPPED", "causes": [cleared], "outputs": {}})
    assert "vsc_estop*" in line


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

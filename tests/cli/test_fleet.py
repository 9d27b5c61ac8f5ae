"""``srcsctl fleet`` on a collector made of real parts: real srcsd runs, each as a robot with a
host name of its own beside a private journald (tests/journald.py), their entries exported in
journal export format and written into one collector directory by the real
systemd-journal-remote, read back by the real journalctl (SR-13.4 to SR-13.6)."""

from __future__ import annotations

import contextlib
import json
import os
import select
import shutil
import subprocess
import sys
import time
import unicodedata
from collections.abc import Iterator, Mapping
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from supervisord.testkit.daemon import MINIMAL_CONFIG
from tests.journald import clock_behind, collect, robot_export

SRCSCTL = str(Path(sys.executable).with_name("srcsctl"))
BEHIND_S = 3600
"""robot-b's second run: its clock an hour behind the collector's."""
ADDRESSES = {"robot-a": "127.0.1.1", "robot-b": "127.0.1.2", "robot-c": "127.0.1.3"}
"""Where each robot uploads from: the collector names its file by it (SR-13.8)."""
FOLLOW_SEEN_S = 15.0
"""How long ``-f`` may take to show an entry the collector wrote: journalctl wakes on the
file's inotify event at once; the margin is the loaded two-core machine's start of a Python
process and journalctl (seen at 1 to 3 s), five times over."""

# One srcsd run: its start (seq 1 and 2: startup, the VSC port that cannot open), an e-stop
# from srcsctl (local_estop), its SIGTERM (shutdown:SIGTERM). The socket's appearance is
# awaited as every journald test here awaits its sockets.
_RUN = """
cd "$DIR"
$CLOCK "$SRCSD" --config robot.toml 2>/dev/null &
daemon=$!
for _ in $(seq 400); do [ -S api.sock ] && break; sleep 0.05; done
"$SRCSCTL" --socket api.sock estop >/dev/null
kill -TERM "$daemon"
wait "$daemon" || true
"""
ONE_RUN = 'start_journald ""\nCLOCK=""\n' + _RUN
SET_BACK = ONE_RUN + 'stop_journald\nstart_journald "$BEHIND"\nCLOCK="$BEHIND"\n' + _RUN
"""Two runs; before the second, journald and srcsd restart with the clock an hour back: the
record's numbering goes on (5 to 8) while its times go back."""


def _robot(name: str, body: str, base: Path) -> bytes:
    folder = base / name
    folder.mkdir()
    (folder / "robot.toml").write_text(MINIMAL_CONFIG.replace("journal = false", "journal = true"))
    bin_dir = Path(sys.executable).parent
    env = {
        "DIR": str(folder),
        "SRCSD": str(bin_dir / "srcsd"),
        "SRCSCTL": SRCSCTL,
        "BEHIND": clock_behind(BEHIND_S),
    }
    return robot_export(name, body, env)


@pytest.fixture(scope="module")
def exports(tmp_path_factory: pytest.TempPathFactory) -> dict[str, bytes]:
    """robot-a (one run), robot-b (a run, then one with its clock an hour back) and robot-c
    (one run, collected only by the follow test), made side by side."""
    base = tmp_path_factory.mktemp("robots")
    plan = {"robot-a": ONE_RUN, "robot-b": SET_BACK, "robot-c": ONE_RUN}
    with ThreadPoolExecutor(len(plan)) as pool:
        made = {name: pool.submit(_robot, name, body, base) for name, body in plan.items()}
        return {name: future.result() for name, future in made.items()}


@pytest.fixture
def collector(exports: dict[str, bytes], tmp_path: Path) -> Path:
    """A collector directory holding robot-a's and robot-b's entries."""
    directory = tmp_path / "remote"
    directory.mkdir()
    for name in ("robot-a", "robot-b"):
        collect(exports[name], directory / remote(name))
    return directory


def remote(robot: str) -> str:
    """The robot's file at the collector, named as systemd-journal-remote names it: by the
    sender's address."""
    return f"remote-{ADDRESSES[robot]}.journal"


def shown(robot: str) -> str:
    """How a line names the robot: its host name and its address (SR-13.8)."""
    return f"{robot}@{ADDRESSES[robot]}"


def fleet(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [SRCSCTL, "fleet", *args],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
        env={**os.environ, **(env or {})},
    )


def seqs(lines: list[str], robot: str) -> list[int]:
    """The ``seq`` of each line of ``robot`` (a label, ``HOST@ADDRESS``, or a host name of
    :data:`ADDRESSES`)."""
    label = robot if "@" in robot else shown(robot)
    return [int(line.split()[2].lstrip("#")) for line in lines if line.split()[0] == label]


def test_every_robot_named_filtered_as_log_filters(collector: Path) -> None:
    """SR-13.4: each line starts with the robot's host name and says what the record changed
    as ``log`` does; --robot, --cause, -n, -o json and --summary select and answer per robot."""
    every = fleet("-D", str(collector))
    assert every.returncode == 0, every.stderr
    lines = every.stdout.splitlines()
    assert sorted(seqs(lines, "robot-a")) == [1, 2, 3, 4]
    assert sorted(seqs(lines, "robot-b")) == list(range(1, 9))
    assert len(lines) == 12
    assert all("raised" in line or "updated" in line for line in lines)

    only_a = fleet("-D", str(collector), "--robot", "robot-a").stdout.splitlines()
    assert [line.split()[0] for line in only_a] == ["robot-a@127.0.1.1"] * 4

    estops = fleet("-D", str(collector), "--cause", "local_estop").stdout.splitlines()
    assert sorted((line.split()[0], line.split()[2]) for line in estops) == [
        ("robot-a@127.0.1.1", "#3"),
        ("robot-b@127.0.1.2", "#3"),
        ("robot-b@127.0.1.2", "#7"),
    ]
    assert all("raised local_estop" in line for line in estops)

    as_json = fleet("-D", str(collector), "-o", "json", "-n", "2", "--robot", "robot-b")
    records = [json.loads(line) for line in as_json.stdout.splitlines()]
    assert [(r["robot"], r["seq"], r["kind"]) for r in records] == [
        ("robot-b", 7, "cause_raised"),
        ("robot-b", 8, "cause_raised"),
    ]
    assert records[0]["changes"] == [{"name": "local_estop", "change": "raised"}]

    # An e-stop while STOPPED (the daemon never left it: no VSC) is no stop (SR-13.9); each
    # run's first record is a start-up.
    summary = fleet("-D", str(collector), "--summary").stdout
    a_line, b_line = summary.splitlines()
    assert a_line == (
        "robot-a@127.0.1.1  0 stops, 1 start-up, proof tests 0 passed, 0 re-arms, 4 records"
    )
    assert b_line == (
        "robot-b@127.0.1.2  0 stops, 2 start-ups, proof tests 0 passed, 0 re-arms, 8 records"
    )
    b_estops = fleet("-D", str(collector), "--summary", "--cause", "local_estop").stdout
    assert b_estops.splitlines()[1].startswith("robot-b@127.0.1.2  0 stops, 0 start-ups, ")
    assert b_estops.splitlines()[1].endswith(", 2 records")
    nothing = fleet("-D", str(collector), "--robot", "robot-z")
    assert (nothing.returncode, nothing.stdout) == (0, "-- No entries --\n")


def test_each_robot_in_its_own_order_and_since_on_its_own_clock(collector: Path) -> None:
    """SR-13.5: robot-b's records 5 to 8, stamped an hour before its 1 to 4 (its clock set
    back), come after them, in its own order; --since compares with each robot's own stamp, so
    "30 min ago" leaves out robot-b's hour-behind records."""
    lines = fleet("-D", str(collector), "--utc").stdout.splitlines()
    assert seqs(lines, "robot-b") == list(range(1, 9))
    assert seqs(lines, "robot-a") == [1, 2, 3, 4]
    stamps = [line.split()[1] for line in lines if line.startswith("robot-b")]
    assert stamps[4] < stamps[3]  # the clock went back: the order is not the clock's
    recent = fleet("-D", str(collector), "--since", "30 min ago").stdout.splitlines()
    assert seqs(recent, "robot-b") == [1, 2, 3, 4]
    assert seqs(recent, "robot-a") == [1, 2, 3, 4]


class _Lines:
    """The lines a following process prints, read from its pipe as they come (no buffered
    reader in between, so that select sees what is not read yet)."""

    def __init__(self, process: subprocess.Popen[bytes]) -> None:
        assert process.stdout is not None
        self.fd, self.pending = process.stdout.fileno(), b""

    def take(self, count: int, within_s: float) -> list[str]:
        deadline = time.monotonic() + within_s
        while self.pending.count(b"\n") < count:
            left = deadline - time.monotonic()
            ready, _, _ = select.select([self.fd], [], [], max(0.0, left))
            assert ready, f"srcsctl fleet -f showed nothing in time: {self.pending!r}"
            chunk = os.read(self.fd, 65536)
            assert chunk, f"srcsctl fleet -f ended: {self.pending!r}"
            self.pending += chunk
        *lines, self.pending = self.pending.split(b"\n", count)
        return [line.decode() for line in lines]


@contextlib.contextmanager
def _following(collector: Path, last: int = 2) -> Iterator[_Lines]:
    """``srcsctl fleet -f -n LAST`` on ``collector``, its lines as they come; at the end it is
    stopped with SIGTERM and must exit 0 (SR-13.4)."""
    follow = subprocess.Popen(
        [SRCSCTL, "fleet", "-D", str(collector), "-f", "-n", str(last)],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
    )
    try:
        yield _Lines(follow)
    finally:
        follow.terminate()
        follow.wait(timeout=30)
        assert follow.stdout is not None
        follow.stdout.close()
    assert follow.returncode == 0


def test_follow_shows_a_robot_that_reports_after_it_started(
    collector: Path, exports: dict[str, bytes]
) -> None:
    """SR-13.4: ``fleet -f`` prints the last records, then robot-c's records, which the
    collector takes in after it started."""
    with _following(collector) as lines:
        first = lines.take(2, FOLLOW_SEEN_S)
        assert [line.split()[0] for line in first] == [shown("robot-b")] * 2
        collect(exports["robot-c"], collector / remote("robot-c"))
        later = lines.take(4, FOLLOW_SEEN_S)
        assert seqs(later, "robot-c") == [1, 2, 3, 4]


def _stamped_around(export: bytes, first_late: int, early_us: int, late_us: int) -> bytes:
    """``export`` with every entry before the record ``first_late`` stamped ``early_us`` and
    every entry from it on ``late_us`` (journal export format: entries apart by a blank line,
    ``__REALTIME_TIMESTAMP`` in microseconds)."""
    entries, late = [], False
    for entry in export.split(b"\n\n"):
        late = late or f"\nSRCS_SEQ={first_late}\n".encode() in b"\n" + entry + b"\n"
        lines = [
            f"__REALTIME_TIMESTAMP={late_us if late else early_us}".encode()
            if line.startswith(b"__REALTIME_TIMESTAMP=")
            else line
            for line in entry.split(b"\n")
        ]
        entries.append(b"\n".join(lines))
    return b"\n\n".join(entries)


def test_follow_keeps_a_new_files_records_in_order_when_they_straddle_the_shown_ones(
    collector: Path, exports: dict[str, bytes]
) -> None:
    """SR-13.5: a robot's first upload whose records 1-2 are stamped before the newest shown
    and 3-4 after it is shown as 1, 2, 3, 4: the follower starts over on the new file before
    it shows any of it, rather than showing what journalctl placed after its position first."""
    with _following(collector) as lines:
        lines.take(2, FOLLOW_SEEN_S)
        year_2001_us, year_2100_us = 978_307_200_000_000, 4_102_444_800_000_000
        late = _stamped_around(exports["robot-c"], 3, year_2001_us, year_2100_us)
        collect(late, collector / remote("robot-c"))
        later = lines.take(4, FOLLOW_SEEN_S)
        assert seqs(later, "robot-c") == [1, 2, 3, 4]


@pytest.mark.parametrize(
    ("args", "status", "said"),
    [
        (["-D", "{tmp}/nowhere"], 2, "no such directory"),
        (["-D", "{tmp}/plain"], 2, "not a directory"),
        (["--file", "{tmp}/nowhere.journal"], 2, "no such file"),
        (["--robot", "robot-a; rm"], 2, "is not a robot's host name"),
        (["--robot", "_HOSTNAME=x"], 2, "is not a robot's host name"),
        (["--since", "the day before"], 2, "not a time"),
        (["--cause", "nosuch"], 2, "is not a cause"),
        (["-f", "-r"], 2, "do not go together"),
        (["-n", "-1"], 2, "not a whole number"),
    ],
)
def test_bad_input_is_refused_in_words(
    tmp_path: Path, args: list[str], status: int, said: str
) -> None:
    """SR-13.4: every bad input is a typed refusal with srcsctl's exit status, no traceback."""
    (tmp_path / "plain").write_text("")
    given = [a.format(tmp=tmp_path) for a in args]
    if "-D" not in given and "--file" not in given:
        given += ["-D", str(tmp_path)]
    refused = fleet(*given)
    assert refused.returncode == status, refused.stderr
    assert said in refused.stderr
    assert "Traceback" not in refused.stderr


def test_without_journalctl_it_says_so(tmp_path: Path) -> None:
    """SR-13.4: a machine without journalctl (not a collector) is told so, exit 1."""
    bare = tmp_path / "bin"
    bare.mkdir()
    refused = fleet("-D", str(tmp_path), env={"PATH": str(bare)})
    assert refused.returncode == 1
    assert "journalctl not found" in refused.stderr
    assert "Traceback" not in refused.stderr


def test_fleet_loads_no_module_of_the_safety_core(collector: Path) -> None:
    """SR-13.6: the fleet command, its lines, JSON and summary, loads no module of the safety
    core (supervisord.safety), nor of the record package but the typed stop record."""
    script = (
        "import sys\n"
        "from supervisord.cli.fleet import main\n"
        f"for args in (['-D', {str(collector)!r}], ['-D', {str(collector)!r}, '-o', 'json'],"
        f" ['-D', {str(collector)!r}, '--summary', '--since=-1d', '--robot', 'robot-b']):\n"
        "    assert main(args) == 0\n"
        "typed = {'supervisord.record', 'supervisord.record.stop', 'supervisord.record.counted'}\n"
        "loaded = sorted(m for m in sys.modules if m.startswith(('supervisord.safety',"
        " 'supervisord.record')) and m not in typed)\n"
        "print('LOADED', loaded, file=sys.stderr)\n"
    )
    run = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=60, check=False
    )
    assert run.returncode == 0, run.stderr
    assert "robot-b" in run.stdout
    assert "LOADED []" in run.stderr, run.stderr


def test_the_collector_tools_are_there() -> None:
    """SR-13.4: the collector's own tools the command and its tests run are installed (./dev
    installs systemd-journal-remote)."""
    assert shutil.which("journalctl") is not None
    assert Path("/lib/systemd/systemd-journal-remote").exists() or shutil.which(
        "systemd-journal-remote"
    )


def test_a_record_sent_twice_is_shown_once(collector: Path) -> None:
    """SR-13.1: an entry systemd-journal-remote took in twice (robot-a's e-stop record sent
    again, as systemd-journal-upload resends the entry in flight when the collector went away)
    is one record in ``fleet``'s lines, JSON and summary; a record with the same ``seq`` but
    other stamps of the robot (a new record file) is still shown."""
    journal = collector / remote("robot-a")
    again = subprocess.run(
        ["journalctl", f"--directory={collector}", "-o", "export", "_HOSTNAME=robot-a",
         "SRCS_SEQ=3"],
        capture_output=True,
        check=True,
        timeout=60,
    ).stdout  # fmt: skip
    assert again.count(b"\nSRCS_SEQ=3\n") == 1
    collect(again, journal)
    held = subprocess.run(
        ["journalctl", f"--directory={collector}", "-o", "json", "_HOSTNAME=robot-a",
         "SRCS_SEQ=3"],
        capture_output=True,
        text=True,
        check=True,
        timeout=60,
    ).stdout.splitlines()  # fmt: skip
    assert len(held) == 2  # the collector's journal holds it twice

    lines = fleet("-D", str(collector), "--robot", "robot-a").stdout.splitlines()
    assert seqs(lines, "robot-a") == [1, 2, 3, 4]
    as_json = fleet("-D", str(collector), "-o", "json", "--robot", "robot-a").stdout
    assert [json.loads(line)["seq"] for line in as_json.splitlines()] == [1, 2, 3, 4]
    summary = fleet("-D", str(collector), "--summary", "--robot", "robot-a").stdout
    assert summary.startswith("robot-a@127.0.1.1  ")
    assert summary.rstrip().endswith(", 4 records")

    other = again.replace(b"\n__MONOTONIC_TIMESTAMP=", b"\n__MONOTONIC_TIMESTAMP=1")
    assert other != again
    collect(other, journal)
    lines = fleet("-D", str(collector), "--robot", "robot-a").stdout.splitlines()
    assert seqs(lines, "robot-a") == [1, 2, 3, 4, 3]


HOSTILE = (
    "\x1b]0;owned\x07\x1b[2J\x1b[H\x1b[31m\rrobot-a@127.0.1.1  forged\n\x9b2J\x7f"
    "\u202e\u2066\u2069\u2028\u2029\u200b\ufeff\x00\\"
)
"""What a hostile or broken uploader puts in a record's text: an OSC that retitles the
terminal, CSIs that clear it and recolour it, a CR and a newline that would forge another
robot's line, the C1 CSI, DEL, the bidi overrides and isolates, the line and paragraph
separators, zero-width and byte-order marks, NUL and a backslash (SR-13.4)."""
_RAW = frozenset({"Cc", "Cf", "Zl", "Zp", "Cs", "Co", "Cn"})


def raw_controls(text: str) -> list[str]:
    """Every character of ``text`` a terminal would act on or hide, but the lines' ends."""
    return [c for c in text if c != "\n" and unicodedata.category(c) in _RAW]


def _binary(name: str, value: str) -> bytes:
    """A field in journal export format's binary form, which carries any bytes."""
    data = value.encode()
    return name.encode() + b"\n" + len(data).to_bytes(8, "little") + data


def _rewritten(export: bytes, seq: int, change: Mapping[str, object]) -> bytes:
    """``export`` with the fields of record ``seq``'s entry set as ``change`` says: a text as
    it is, anything else as JSON."""
    entries = []
    for entry in export.split(b"\n\n"):
        lines = entry.split(b"\n")
        if f"SRCS_SEQ={seq}".encode() in lines:
            names = {name.encode() for name in change}
            lines = [line for line in lines if line.partition(b"=")[0] not in names]
            lines += [
                _binary(name, value if isinstance(value, str) else json.dumps(value))
                for name, value in change.items()
            ]
        entries.append(b"\n".join(lines))
    return b"\n\n".join(entries)


def _fields(export: bytes, seq: int) -> dict[str, str]:
    for entry in export.split(b"\n\n"):
        lines = entry.split(b"\n")
        if f"SRCS_SEQ={seq}".encode() in lines:
            return dict(line.decode().partition("=")[::2] for line in lines if b"=" in line)
    raise AssertionError(f"no record {seq}")


def _hostile(export: bytes) -> bytes:
    """robot-a's upload as robot-x whose record #3, a stop, raises a stop cause named with
    :data:`HOSTILE`, its details, reason and trigger :data:`HOSTILE` too, and whose record #4
    comes from a state so named (a line that is no typed record)."""
    renamed = export.replace(b"\n_HOSTNAME=robot-a\n", b"\n_HOSTNAME=robot-x\n")
    fields = _fields(renamed, 3)
    evil = {
        "name": "evil" + HOSTILE,
        "severity": "stop",
        "active": True,
        "latched": True,
        "details": {"reason": HOSTILE, "where": HOSTILE},
    }
    causes = [*json.loads(fields["SRCS_CAUSES"]), evil]
    changes = [*json.loads(fields["SRCS_CHANGES"]), {"name": evil["name"], "change": "raised"}]
    third = {
        "SRCS_CAUSES": causes,
        "SRCS_CHANGES": changes,
        "SRCS_REASON": HOSTILE,
        "SRCS_TRIGGER": HOSTILE,
        "SRCS_FROM": "RUN",  # a stop (SR-13.9): the summary names its trigger
    }
    return _rewritten(_rewritten(renamed, 3, third), 4, {"SRCS_FROM": "RUN" + HOSTILE})


@pytest.mark.parametrize(
    "mode",
    [
        [],
        ["--causes"],
        ["-o", "cat"],
        ["-o", "verbose"],
        ["-r"],
        ["--summary"],
        ["-o", "json"],
        ["-o", "json-pretty"],
        ["--summary", "-o", "json"],
    ],
)
def test_a_robots_text_reaches_no_terminal_raw(
    exports: dict[str, bytes], tmp_path: Path, mode: list[str]
) -> None:
    """SR-13.7: a record whose cause names, details, reason, trigger and from-state hold
    escape sequences, CR and newline, C1 controls, bidi overrides and separators is shown with
    each of them escaped (``\\x1b``, ``\\u202e``), in every output mode and on stderr: no
    raw control reaches the terminal, and no line is forged."""
    directory = tmp_path / "remote"
    directory.mkdir()
    collect(_hostile(exports["robot-a"]), directory / "remote-127.0.1.9.journal")
    shown = fleet("-D", str(directory), *mode)
    assert shown.returncode == 0, shown.stderr
    assert raw_controls(shown.stdout) == []
    assert raw_controls(shown.stderr) == []
    lines = shown.stdout.splitlines()
    if "-o" in mode and mode[mode.index("-o") + 1].startswith("json"):
        assert "--summary" in mode or "evil" in shown.stdout
        return
    assert all(line.startswith("robot-x") for line in lines), lines
    assert len(lines) == (1 if "--summary" in mode else 4)
    assert "\\x1b]0;owned\\x07" in shown.stdout  # shown, escaped, not dropped
    if "--summary" not in mode:
        assert "\\u202e" in shown.stdout
        assert "RUN\\x1b" in shown.stdout  # the from-state of #4


def test_a_robots_text_followed_reaches_no_terminal_raw(
    exports: dict[str, bytes], tmp_path: Path
) -> None:
    """SR-13.7: ``-f`` shows a hostile record escaped, as the other modes do."""
    directory = tmp_path / "remote"
    directory.mkdir()
    collect(exports["robot-b"], directory / remote("robot-b"))
    with _following(directory, last=1) as lines:
        lines.take(1, FOLLOW_SEEN_S)
        collect(_hostile(exports["robot-a"]), directory / "remote-127.0.1.9.journal")
        later = lines.take(4, FOLLOW_SEEN_S)
    text = "\n".join(later)
    assert raw_controls(text) == []
    assert all(line.startswith("robot-x") for line in later), later
    assert "\\x1b[2J" in text


def test_one_host_name_from_two_senders_is_two_robots_and_said(
    exports: dict[str, bytes], tmp_path: Path
) -> None:
    """SR-13.1, SR-13.8: records uploaded from another address under robot-b's host name
    (robot-a's run, renamed) are not shown as robot-b's own: each robot is its host name and
    the sender's address (the collector's file, ``remote-ADDRESS.journal``), in lines, JSON and
    the summary, and a warning says that robot-b came from two addresses."""
    directory = tmp_path / "remote"
    directory.mkdir()
    collect(exports["robot-b"], directory / remote("robot-b"))
    forged = exports["robot-a"].replace(b"\n_HOSTNAME=robot-a\n", b"\n_HOSTNAME=robot-b\n")
    collect(forged, directory / "remote-127.0.1.66.journal")

    every = fleet("-D", str(directory))
    assert every.returncode == 0, every.stderr
    lines = every.stdout.splitlines()
    assert seqs(lines, "robot-b@127.0.1.2") == list(range(1, 9))
    assert sorted(seqs(lines, "robot-b@127.0.1.66")) == [1, 2, 3, 4]
    warning = [line for line in every.stderr.splitlines() if "robot-b" in line]
    assert len(warning) == 1, every.stderr
    assert "127.0.1.2" in warning[0]
    assert "127.0.1.66" in warning[0]

    summary = fleet("-D", str(directory), "--summary").stdout.splitlines()
    assert [line.split()[0] for line in summary] == ["robot-b@127.0.1.2", "robot-b@127.0.1.66"]
    as_json = fleet("-D", str(directory), "-o", "json").stdout.splitlines()
    senders = {(r["robot"], r["sender"]) for r in map(json.loads, as_json)}
    assert senders == {("robot-b", "127.0.1.2"), ("robot-b", "127.0.1.66")}

    alone = fleet("-D", str(directory), "--robot", "robot-b", "-n", "1")
    assert "127.0.1.66" in alone.stderr  # said whichever records are shown


@pytest.mark.parametrize(
    ("name", "sender"),
    [
        ("remote-192.0.2.17.journal", "192.0.2.17"),
        ("remote-192.0.2.17@" + "a" * 32 + "-" + "1" * 16 + "-" + "2" * 16 + ".journal",
         "192.0.2.17"),
        ("remote-192.0.2.17@" + "1" * 16 + "-" + "2" * 16 + ".journal~", "192.0.2.17"),
        ("remote-fe80::1.journal", "fe80::1"),
        ("remote-CN=robot-a.journal", "CN=robot-a"),
        ("system.journal", None),
        ("remote.journal", None),
    ],
)  # fmt: skip
def test_a_collectors_file_names_its_sender(name: str, sender: str | None) -> None:
    """SR-13.8: the sender as systemd-journal-remote names its files (systemd-journal-remote(8):
    ``remote-HOST.journal``, set aside on rotation with ``@ID-SEQNUM-TIME`` or as
    ``@SEQNUM-TIME.journal~``); a file no collector named has none."""
    from supervisord.cli.fleet_senders import sender_of_file  # noqa: PLC0415

    assert sender_of_file(f"/var/log/journal/remote/{name}") == sender


STOP_ROBOT = 'start_journald ""\n"$PYTHON" -m tests.cli.fleet_stop_robot "$DIR" "$JOURNAL"\n'
"""robot-d: the real srcsd and srcs-sim, two remote e-stops in RUN (tests/cli/fleet_stop_robot)."""
STOPPING = "127.0.1.4"


@pytest.fixture(scope="module")
def stopped(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, bytes]:
    """robot-d's folder (its record, windows and own replays) and its journal's export."""
    base = tmp_path_factory.mktemp("stopping")
    folder = base / "robot-d"
    folder.mkdir()
    env = {"DIR": str(folder), "PYTHON": sys.executable}
    return folder, robot_export("robot-d", STOP_ROBOT, env)


def test_a_stops_window_is_replayed_at_the_collector_as_on_the_robot(
    stopped: tuple[Path, bytes], tmp_path: Path
) -> None:
    """SR-13.12: a real srcsd beside a private journald stops twice in RUN; its journal, sent
    through the real systemd-journal-remote, holds each stop's window as an entry of its own,
    byte for byte the robot's file. ``srcsctl fleet replay robot-d@ADDRESS SEQ --plot`` at the
    collector says what the robot's own ``srcsctl replay --file RECORD SEQ --plot`` says, line
    for line (the files named as the collector's copy), with the same exit status (0: the
    replay matches the record) and the same picture. A record with no window, and a robot name
    that is no host name, are refused in words (exit 2)."""
    folder, export = stopped
    directory = tmp_path / "remote"
    directory.mkdir()
    collect(export, directory / f"remote-{STOPPING}.journal")
    made = json.loads((folder / "stops.json").read_text())
    record = Path(made["record"])
    assert len(made["seqs"]) == 2
    for seq in made["seqs"]:
        own_status, own = (folder / f"robot-{seq}.txt").read_text().split("\n", 1)
        assert own_status == "0", own
        assert "replay matches the record" in own, own
        plot = tmp_path / f"collector-{seq}.svg"
        there = fleet("replay", f"robot-d@{STOPPING}", str(seq), "-D", str(directory),
                      "--plot", str(plot))  # fmt: skip
        assert there.returncode == 0, there.stdout + there.stderr
        named = f"robot-d@{STOPPING}'s window of #{seq} at the collector"
        expected = own.replace(str(record) + f".flight/{seq}.jsonl", named).replace(
            str(folder / f"robot-{seq}.svg"), str(plot)
        )
        assert there.stdout == expected
        assert plot.read_bytes() == (folder / f"robot-{seq}.svg").read_bytes()
        window = (Path(str(record) + ".flight") / f"{seq}.jsonl").read_bytes()
        assert json.loads(window.splitlines()[0])["seq"] == seq
    alone = fleet("replay", "robot-d", str(made["seqs"][0]), "-D", str(directory))
    assert alone.returncode == 0, alone.stderr
    missing = fleet("replay", f"robot-d@{STOPPING}", "1", "-D", str(directory))
    assert missing.returncode == 2
    assert "no window of record 1 from robot-d@127.0.1.4" in missing.stderr, missing.stderr
    assert f"#{made['seqs'][0]}" in missing.stderr
    assert "Traceback" not in missing.stderr
    bad = fleet("replay", "robot-d;rm", "3", "-D", str(directory))
    assert bad.returncode == 2
    assert "not a robot's host name" in bad.stderr, bad.stderr

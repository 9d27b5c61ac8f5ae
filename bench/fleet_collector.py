"""A fleet's collector under load: the real systemd-journal-remote taking stop records over
HTTPS from N robots, and how long until ``srcsctl fleet`` answers with one (SR-13.4,
docs/fleet.md "Scale").

Run: ``.venv/bin/python -m bench.fleet_collector [--robots 5,100,1000] [--records 10]``
(root: it runs in a network namespace of its own, loopback only); ``--robots 100,1000,10000``
for the fleet sizes of docs/fleet.md "Scale" (10,000 robots: about 2 minutes here).

- **The receiver**: ``systemd-journal-remote --listen-https=127.0.0.1:19532`` with a key and
  certificate the bench makes with openssl, ``--split-mode=host`` (a file per robot, as
  shipped) up to ``--split-robots`` robots and ``--split-mode=none`` (one file) above: each
  file starts at 8 MiB on disk, so 1,000 robots would take 8 GB of this machine for the
  floor alone (the figure per file is measured and multiplied, docs/fleet.md "Scale").
  Debian 12's build has no client-certificate check (``--trust`` is not available), so the
  robot's file is named by its address: each robot connects from an address of its own,
  ``127.x.y.z``.
- **The entries**: the records of a real ``srcsd`` run (started, an e-stop, SIGTERM), as
  ``supervisord/record/journal.py`` maps them to journal fields, with the fields journald
  adds on a robot (``_HOSTNAME``, ``_MACHINE_ID``, ``_BOOT_ID``, ``_PID``, the timestamps);
  each robot its own ``_HOSTNAME``, ``_MACHINE_ID`` and ``SRCS_SEQ``.
- **The senders**: as systemd-journal-upload does, an HTTPS POST to ``/upload`` with
  ``Content-Type: application/vnd.fdo.journal`` and the entries in journal export format.
  1,000 robots are not 1,000 processes: ``--senders`` threads take the robots in turn, each
  robot one connection that sends its burst (``--records`` entries: the backlog a robot
  sends after an outage) and closes.
- **Measured**: records per second taken in (from the first connection to the last 202
  answer), the receiver's CPU time (``/proc/PID/stat``) per robot and per record, its disk
  (allocated blocks) per robot and per record, the number of journal files, and the delay
  from one more record's send to its line in ``srcsctl fleet --robot``, and the time of
  ``srcsctl fleet --summary --since "1 hour ago"`` over every robot's records.
"""

from __future__ import annotations

import argparse
import http.client
import json
import os
import shutil
import socket
import ssl
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from collections.abc import Sequence
from pathlib import Path

from bench.netns import in_namespace
from bench.rig import load, machine, table
from supervisord.record.journal import journal_fields
from supervisord.testkit.daemon import MINIMAL_CONFIG

PORT = 19532
RECEIVER = "/lib/systemd/systemd-journal-remote"
TICKS = os.sysconf("SC_CLK_TCK")
ANSWER_LIMIT_S = 60.0
"""A coarse bound on the delay measured: only a record that never shows fails it."""


def _export(fields: Sequence[tuple[str, str]]) -> bytes:
    """One entry in journal export format (systemd.io/JOURNAL_EXPORT_FORMATS)."""
    out = bytearray()
    for key, value in fields:
        data = value.encode()
        if b"\n" in data:
            out += key.encode() + b"\n" + len(data).to_bytes(8, "little") + data + b"\n"
        else:
            out += key.encode() + b"=" + data + b"\n"
    return bytes(out + b"\n")


def real_records(folder: Path) -> list[dict[str, object]]:
    """The records of a real srcsd run: its start, an e-stop from srcsctl, its SIGTERM."""
    (folder / "robot.toml").write_text(MINIMAL_CONFIG)
    bin_dir = Path(sys.executable).parent
    daemon = subprocess.Popen(
        [str(bin_dir / "srcsd"), "--config", "robot.toml"], cwd=folder, stderr=subprocess.DEVNULL
    )
    try:
        deadline = time.monotonic() + 60
        while not (folder / "api.sock").exists():
            if time.monotonic() > deadline:
                raise SystemExit("srcsd did not start")
            time.sleep(0.05)
        subprocess.run(
            [str(bin_dir / "srcsctl"), "--socket", str(folder / "api.sock"), "estop"],
            check=True,
            capture_output=True,
        )
    finally:
        daemon.terminate()
        daemon.wait()
    lines = (folder / "stops.jsonl").read_text().splitlines()
    return [json.loads(line) for line in lines]


class Robot:
    """One robot's entries: the real records' fields under its own names and numbering."""

    def __init__(self, index: int, records: list[dict[str, object]]) -> None:
        self.index = index
        self.name = f"robot-{index:05d}"
        self.address = f"127.{1 + index // 65536}.{index // 256 % 256}.{index % 256}"
        self.machine = uuid.uuid4().hex
        self.boot = uuid.uuid4().hex
        self.records = records
        self.seq = 0

    def entries(self, count: int) -> bytes:
        body = bytearray()
        for _ in range(count):
            record = dict(self.records[self.seq % len(self.records)])
            self.seq += 1
            record["seq"] = self.seq
            now_us = time.time_ns() // 1000
            trusted = [
                ("__REALTIME_TIMESTAMP", str(now_us)),
                ("__MONOTONIC_TIMESTAMP", str(time.monotonic_ns() // 1000)),
                ("_BOOT_ID", self.boot),
                ("_MACHINE_ID", self.machine),
                ("_HOSTNAME", self.name),
                ("_TRANSPORT", "journal"),
                ("_PID", "812"),
                ("_UID", "998"),
                ("_GID", "998"),
                ("_COMM", "srcsd"),
                ("_SYSTEMD_UNIT", "srcsd@robot.service"),
            ]
            body += _export(trusted + journal_fields(record))
        return bytes(body)


def send(robot: Robot, count: int, context: ssl.SSLContext) -> None:
    """One upload as systemd-journal-upload makes it: POST /upload, the export format."""
    connection = http.client.HTTPSConnection(
        "127.0.0.1", PORT, context=context, source_address=(robot.address, 0), timeout=60
    )
    try:
        connection.request(
            "POST",
            "/upload",
            body=robot.entries(count),
            headers={"Content-Type": "application/vnd.fdo.journal"},
        )
        answer = connection.getresponse()
        answer.read()
        if answer.status != 202:
            raise RuntimeError(f"{robot.name}: {answer.status} {answer.reason}")
    finally:
        connection.close()


def cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS


def disk(folder: Path) -> tuple[int, int]:
    """Allocated bytes and journal files under ``folder``."""
    files = [p for p in folder.iterdir() if p.name.endswith(".journal")]
    return sum(p.stat().st_blocks * 512 for p in files), len(files)


def certificate(folder: Path) -> tuple[Path, Path]:
    key, cert = folder / "key.pem", folder / "cert.pem"
    subprocess.run(
        [
            "openssl", "req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:P-256",
            "-nodes", "-keyout", str(key), "-out", str(cert), "-days", "1",
            "-subj", "/CN=collector", "-addext", "subjectAltName=IP:127.0.0.1",
        ],
        check=True,
        capture_output=True,
    )  # fmt: skip
    return key, cert


def wait_listening(deadline_s: float = 30.0) -> None:
    end = time.monotonic() + deadline_s
    while True:
        try:
            socket.create_connection(("127.0.0.1", PORT), timeout=1).close()
            return
        except OSError:
            if time.monotonic() > end:
                raise SystemExit("systemd-journal-remote did not listen") from None
            time.sleep(0.05)


def run_one(
    robots: int,
    records: int,
    *,
    senders: int,
    split: str,
    base: Path,
    template: list[dict[str, object]],
) -> list[object]:
    out = base / f"remote-{robots}"
    out.mkdir()
    key, cert = certificate(base)
    receiver = subprocess.Popen(
        [
            RECEIVER, f"--listen-https=127.0.0.1:{PORT}", f"--key={key}", f"--cert={cert}",
            # One file: a file's name (a directory takes a file per sender).
            f"--output={out}/" if split == "host" else f"--output={out}/remote-all.journal",
            f"--split-mode={split}",
        ],
        stderr=subprocess.DEVNULL,
    )  # fmt: skip
    try:
        wait_listening()
        context = ssl.create_default_context(cafile=str(cert))
        fleet = [Robot(i, template) for i in range(robots)]
        turn, lock = iter(fleet), threading.Lock()

        def worker() -> None:
            while True:
                with lock:
                    robot = next(turn, None)
                if robot is None:
                    return
                send(robot, records, context)

        cpu_before, started = cpu_s(receiver.pid), time.monotonic()
        threads = [threading.Thread(target=worker) for _ in range(senders)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        took = time.monotonic() - started
        cpu = cpu_s(receiver.pid) - cpu_before
        total = robots * records
        delay = answered(fleet[0], context, out)
        summary = summarized(out, robots)
        used, files = disk(out)
    finally:
        receiver.terminate()
        receiver.wait()
    shutil.rmtree(out)
    return [
        robots,
        split,
        total,
        f"{total / took:.0f}",
        f"{cpu / robots * 1000:.2f}",
        f"{cpu / total * 1e6:.0f}",
        f"{used / robots / 1024:.0f}",
        f"{used / total:.0f}",
        files,
        f"{delay[0] * 1000:.0f}",
        f"{delay[1] * 1000:.0f}",
        f"{summary:.1f}",
    ]


def summarized(out: Path, robots: int) -> float:
    """Seconds ``srcsctl fleet --summary --since "1 hour ago"`` takes over the collector's
    directory, every robot's records in the window (SR-13.9: the fleet's stop counts)."""
    srcsctl = str(Path(sys.executable).with_name("srcsctl"))
    line = [srcsctl, "fleet", "-D", str(out), "--summary", "--since", "1 hour ago"]
    started = time.monotonic()
    done = subprocess.run(line, capture_output=True, text=True, check=False)
    took = time.monotonic() - started
    if done.returncode != 0 or len(done.stdout.splitlines()) != robots:
        raise SystemExit(f"fleet --summary: exit {done.returncode}: {done.stderr[-500:]}")
    return took


def answered(robot: Robot, context: ssl.SSLContext, out: Path) -> tuple[float, float]:
    """From one more record's send to its entry in journalctl's answer, and from another
    one's send to its line in ``srcsctl fleet --robot`` (which adds starting srcsctl)."""
    srcsctl = str(Path(sys.executable).with_name("srcsctl"))
    journalctl = [
        "journalctl", "-D", str(out), "-o", "cat", "--no-pager", f"_HOSTNAME={robot.name}",
    ]  # fmt: skip
    fleet = [srcsctl, "fleet", "-D", str(out), "--robot", robot.name, "-n", "1"]
    delays = []
    for line, field in ((journalctl, "SRCS_SEQ={}"), (fleet, None)):
        started = time.monotonic()
        send(robot, 1, context)
        asked = [*line, field.format(robot.seq)] if field else line
        wanted = f"#{robot.seq} " if field is None else ""
        while True:
            shown = subprocess.run(asked, capture_output=True, text=True, check=False).stdout
            if shown.strip() and wanted in shown:
                delays.append(time.monotonic() - started)
                break
            if time.monotonic() - started > ANSWER_LIMIT_S:
                raise SystemExit(f"{robot.name}'s record #{robot.seq} never showed")
    return delays[0], delays[1]


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default="5,100,1000", help="fleet sizes, comma-separated")
    parser.add_argument("--records", type=int, default=10, help="records per robot (a burst)")
    parser.add_argument("--senders", type=int, default=8, help="sending threads")
    parser.add_argument(
        "--split-robots",
        type=int,
        default=100,
        help="a file per robot (split-mode=host) up to this many robots, one file above",
    )
    args = parser.parse_args(argv)
    if not Path(RECEIVER).exists():
        raise SystemExit("needs systemd-journal-remote (Debian package systemd-journal-remote)")
    in_namespace("bench.fleet_collector")
    print(f"machine: {machine()}; {load()}")
    rows = []
    with tempfile.TemporaryDirectory(prefix="srcs-fleet-") as tmp:
        base = Path(tmp)
        srcsd_dir = base / "srcsd"
        srcsd_dir.mkdir()
        template = real_records(srcsd_dir)
        for robots in (int(n) for n in args.robots.split(",")):
            split = "host" if robots <= args.split_robots else "none"
            rows.append(
                run_one(
                    robots,
                    args.records,
                    senders=args.senders,
                    split=split,
                    base=base,
                    template=template,
                )
            )
            print(f"  {robots} robots done; {load()}", flush=True)
    print(
        table(
            [
                "robots", "split", "records", "records/s in", "CPU ms/robot", "CPU µs/record",
                "disk KiB/robot", "disk B/record", "files", "to journalctl ms",
                "to srcsctl fleet ms", "--summary 1 h s",
            ],
            rows,
        )
    )  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())

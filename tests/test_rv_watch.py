"""``python3 -m supervisord.rv_watch``, the kernel judge's counter, as a process against a
directory laid out as tracefs (tests/fake_tracefs.py: the host's kernel has no monitors) fed
the kernel's lines (SR-9.9)."""

from __future__ import annotations

import shutil
import stat
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from supervisord.rv_watch import EXIT_NO_MONITORS, EXIT_NO_TRACEFS, EXIT_NOT_ARMED
from supervisord.tooling.children import terminate
from tests.fake_tracefs import FakeTracefs, Watch, kernel_line


@pytest.fixture
def tracefs(tmp_path: Path) -> Iterator[FakeTracefs]:
    fake = FakeTracefs(tmp_path / "tracing")
    yield fake
    fake.close()


def run_refused(root: Path, output: Path) -> tuple[int, str]:
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "supervisord.rv_watch",
            "--tracing",
            str(root),
            "--output",
            str(output),
        ],
        check=False,
        capture_output=True,
        text=True,
        timeout=60,
    )
    return result.returncode, result.stderr


def test_the_watch_arms_the_judge_counts_the_daemons_violations_and_says_when_it_stops(
    tracefs: FakeTracefs, tmp_path: Path
) -> None:
    """SR-9.9, SR-9.7: armed in its own instance (the events on, the clock monotonic), the
    three monitors added to what was enabled and judging on; the kernel's lines, cut across
    writes, counted by monitor and thread, another program's apart; the totals in a file of
    mode 0644 written whole; the ring's overrun as lost events; on SIGTERM a last write with
    the judge off, exit 0."""
    output = tmp_path / "run" / "violations.json"
    output.parent.mkdir()
    watch = Watch(tracefs.root, output)
    try:
        first = watch.wait_for("the first totals", lambda t: t["judge_on"])
        assert first["violations"] == {
            name: {"srcsd": 0} for name in ("pagefault", "sleep", "wakeup")
        }
        assert tracefs.read("rv/enabled_monitors").split() == [
            "wwnr",
            "pagefault",
            "sleep",
            "wakeup",
        ]
        assert tracefs.read("rv/monitoring_on").strip() == "1"
        for name in ("pagefault", "sleep", "wakeup"):
            assert tracefs.read(f"instances/srcs-rv/events/rv/error_{name}/enable") == "1"
        assert tracefs.read("instances/srcs-rv/trace_clock") == "mono"

        stamp = time.monotonic() - 2.0  # the instance's clock: CLOCK_MONOTONIC
        text = (
            kernel_line("srcsd-415", stamp - 1, "pagefault", "srcsd[415]")
            + kernel_line("kworker/0:1-12", stamp - 1, "wakeup", "srcsd[415]")
            + kernel_line("srcsd-log-420", stamp - 1, "sleep", "srcsd-log[420]")
            + kernel_line("python3-900", stamp, "sleep", "python3[900]")
            + "garbage that is no event\n"
            + kernel_line("srcsd-415", stamp, "pagefault", "srcsd[415]")
        )
        tracefs.emit(text[:50])
        tracefs.emit(text[50:])
        tracefs.set_overrun(3)
        totals = watch.wait_for(
            "two page faults",
            lambda t: t["violations"]["pagefault"]["srcsd"] == 2 and t["lost_events"] == 3,
        )
        assert totals["violations"] == {
            "pagefault": {"srcsd": 2},
            "sleep": {"srcsd": 0, "srcsd-log": 1},
            "wakeup": {"srcsd": 1},
        }
        assert totals["others"] == 1
        assert totals["unreadable_lines"] == 1
        assert totals["lost_events"] == 3
        assert abs(totals["last_violation_unix"] - (time.time() - 2.0)) < 1.0
        assert stat.S_IMODE(output.stat().st_mode) == 0o644
        assert not list(output.parent.glob(".*")), "a temporary file left"
    finally:
        status = terminate(watch.process)
    assert status == 0, watch.log.read_text()
    last = watch.totals()
    assert last is not None
    assert last["judge_on"] is False
    assert last["violations"]["pagefault"]["srcsd"] == 2


def test_the_judge_turned_off_by_another_hand_is_said(tracefs: FakeTracefs, tmp_path: Path) -> None:
    """SR-9.9: ``monitoring_on`` 0, or one monitor's event off in the instance, while the
    watch runs: its next totals say the judge is off; back on, on, also as Linux 7.3 reads
    ``monitoring_on`` back (a NUL byte after its newline, seen on the judged kernel)."""
    watch = Watch(tracefs.root, tmp_path / "violations.json")
    try:
        watch.wait_for("the judge on", lambda t: t["judge_on"])
        tracefs.write("rv/monitoring_on", "0\n")
        watch.wait_for("the judge off", lambda t: not t["judge_on"])
        tracefs.write("rv/monitoring_on", "1\n\0")
        watch.wait_for("the judge on again", lambda t: t["judge_on"])
        tracefs.write("instances/srcs-rv/events/rv/error_sleep/enable", "0\n")
        watch.wait_for("the judge off", lambda t: not t["judge_on"])
    finally:
        assert terminate(watch.process) == 0


def test_no_tracefs_is_a_refusal_with_its_own_status(tmp_path: Path) -> None:
    """SR-9.9: tracefs not mounted (no ``instances/``): one line, exit 3, no file."""
    (tmp_path / "tracing").mkdir()
    status, said = run_refused(tmp_path / "tracing", tmp_path / "out.json")
    assert status == EXIT_NO_TRACEFS
    assert said.count("\n") == 1, said
    assert "tracefs is not mounted" in said, said
    assert not (tmp_path / "out.json").exists()


def test_a_kernel_without_the_monitors_is_a_refusal_with_its_own_status(tmp_path: Path) -> None:
    """SR-9.9: a kernel whose rv has none of the rtapp monitors (or no rv at all): one line,
    exit 4, nothing armed."""
    fake = FakeTracefs(tmp_path / "tracing", monitors=())
    status, said = run_refused(fake.root, tmp_path / "out.json")
    assert status == EXIT_NO_MONITORS
    assert said.count("\n") == 1, said
    assert "has no rtapp monitor" in said, said
    assert fake.read("rv/monitoring_on") == "0\n"
    assert fake.read("rv/enabled_monitors") == "wwnr\n"
    (fake.root / "rv/available_monitors").unlink()
    status, said = run_refused(fake.root, tmp_path / "out.json")
    assert status == EXIT_NO_MONITORS, said


def test_a_kernel_without_the_pagefault_monitor_is_judged_by_the_others(tmp_path: Path) -> None:
    """SR-9.9: arm64's kernel has no ``pagefault`` monitor (x86 and RISC-V only): the watch
    arms ``sleep`` and ``wakeup``, its totals name only those, and its judge is on."""
    fake = FakeTracefs(tmp_path / "tracing", monitors=("sleep", "wakeup"))
    watch = Watch(fake.root, tmp_path / "violations.json")
    try:
        totals = watch.wait_for("the judge on", lambda t: t["judge_on"])
        assert totals["monitors"] == ["sleep", "wakeup"]
        assert totals["violations"] == {"sleep": {"srcsd": 0}, "wakeup": {"srcsd": 0}}
        assert fake.read("rv/enabled_monitors").split() == ["wwnr", "sleep", "wakeup"]
        assert fake.read("instances/srcs-rv/events/rv/error_pagefault/enable") == "0\n"
    finally:
        fake.close()
        assert terminate(watch.process) == 0


def test_a_tracefs_file_that_refuses_the_arming_is_a_refusal(tmp_path: Path) -> None:
    """SR-9.9: a write that arms the judge refused (here an ``enable`` that cannot be
    written): one line naming the file, exit 5."""
    fake = FakeTracefs(tmp_path / "tracing")
    enable = fake.instance / "events/rv/error_sleep/enable"
    enable.unlink()
    enable.mkdir()
    status, said = run_refused(fake.root, tmp_path / "out.json")
    assert status == EXIT_NOT_ARMED
    assert said.count("\n") == 1, said
    assert "error_sleep/enable" in said, said


@pytest.mark.skipif(shutil.which("systemd-analyze") is None, reason="needs systemd-analyze")
def test_the_unit_passes_systemd_analyze_verify(tmp_path: Path) -> None:
    """SR-9.9: systemd-analyze verify accepts srcs-rv.service (its ExecStart pointed at this
    checkout's Python, since /opt/srcsd is the installed location); it runs as root without
    capabilities, and is enabled by nothing but its own [Install]."""
    unit = Path(__file__).resolve().parents[1] / "units" / "srcs-rv.service"
    text = unit.read_text()
    assert "CapabilityBoundingSet=\n" in text
    assert "ReadWritePaths=/sys/kernel/tracing\n" in text
    (tmp_path / unit.name).write_text(text.replace("/opt/srcsd/bin/python3", sys.executable))
    result = subprocess.run(
        ["systemd-analyze", "verify", str(tmp_path / unit.name)],
        check=False,
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr
    assert result.stderr.strip() == "", result.stderr

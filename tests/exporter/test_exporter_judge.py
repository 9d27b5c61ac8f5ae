"""The kernel judge's totals in the exporter (SR-9.9): the file ``srcs-rv`` writes, read at
each scrape; hostile files refused and counted, never raised; and end to end, the real watch
against a directory laid out as tracefs (tests/fake_tracefs.py), the real exporter, and a real
Prometheus whose alert fires on the loop's page fault."""

from __future__ import annotations

import json
import shutil
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from prometheus_client.openmetrics.parser import text_string_to_metric_families

from supervisord.exporter.judge import (
    MAX_FILE_BYTES,
    STALE_S,
    JudgeFile,
    JudgeFileRefused,
    parse,
    read_judge_file,
)
from supervisord.exporter.model import ExporterModel
from supervisord.rv_watch import DEFAULT_OUTPUT
from supervisord.testkit.wait import wait_until
from supervisord.tooling.children import terminate
from tests.exporter.stack import PROMETHEUS, Exporter, Prometheus, http_get
from tests.fake_tracefs import FakeTracefs, Watch, kernel_line

GOOD: dict[str, Any] = {
    "format": 1,
    "judge_on": True,
    "violations": {
        "pagefault": {"srcsd": 1},
        "sleep": {"srcsd": 0, "srcsd-log": 4},
        "wakeup": {"srcsd": 2},
    },
    "overflow": {"sleep": 7},
    "others": 3,
    "unreadable_lines": 5,
    "lost_events": 6,
    "last_violation_unix": 1_765_000_000.25,
}


def samples(model: ExporterModel) -> dict[tuple[str, tuple[tuple[str, str], ...]], float]:
    return {
        (f.name, s.labels): s.value for f in model.families(0) for s in f.samples if "rt_" in f.name
    }


def test_the_totals_become_the_judges_metrics() -> None:
    """SR-9.9: the judge on, each (monitor, thread) a counter, the series past the watch's
    cap under ``other``, the last violation's time, lost events, unreadable lines."""
    model = ExporterModel()
    model.judge_read(parse(json.dumps(GOOD).encode(), age_s=1.0))
    got = samples(model)
    assert got[("srcs_rt_judge_on", ())] == 1
    v = "srcs_rt_violations"
    assert got[(v, (("monitor", "pagefault"), ("thread", "srcsd")))] == 1
    assert got[(v, (("monitor", "sleep"), ("thread", "srcsd-log")))] == 4
    assert got[(v, (("monitor", "sleep"), ("thread", "other")))] == 7
    assert got[("srcs_rt_last_violation_timestamp_seconds", ())] == 1_765_000_000.25
    assert got[("srcs_rt_lost_events", ())] == 6
    assert got[("srcs_rt_unreadable_lines", ())] == 5


def test_no_file_is_no_judge_and_no_metric(tmp_path: Path) -> None:
    """SR-9.9: most robots run without the judge: no file, no ``srcs_rt_*`` series at all,
    and nothing refused."""
    assert read_judge_file(tmp_path / "none.json", time.time()) is None
    model = ExporterModel()
    model.judge_read(None)
    assert samples(model) == {}


def test_a_file_not_rewritten_says_the_judge_is_off() -> None:
    """SR-9.9: a watch that died leaves its last file; older than 30 s its judge is off, and
    its totals still served."""
    assert parse(json.dumps(GOOD).encode(), age_s=STALE_S).judge_on
    stale = parse(json.dumps(GOOD).encode(), age_s=STALE_S + 1)
    assert not stale.judge_on
    assert stale.violations


def _with(**changes: Any) -> bytes:
    return json.dumps({**GOOD, **changes}).encode()


HOSTILE = {
    "too_big": b" " * (MAX_FILE_BYTES + 1),
    "not_json": b'{"format": 1, ',
    "not utf-8": b'{"format": 1, "x": "\xff"}',
    "deep": b"[" * 100_000,
    "a list": b"[1, 2]",
    "another format": _with(format=2),
    "true for 1": _with(format=True),
    "judge_on a number": _with(judge_on=1),
    "a count a string": _with(lost_events="6"),
    "a negative count": _with(unreadable_lines=-1),
    "a count a float": _with(unreadable_lines=1.5),
    "a huge count": _with(lost_events=2**64),
    "a thread not srcsd's": _with(violations={"sleep": {"python3": 1}}),
    "a long thread name": _with(violations={"sleep": {"srcsd-" + "x" * 20: 1}}),
    "a label with a quote": _with(violations={"sleep": {'srcsd-"x': 1}}),
    "a monitor not rtapp's": _with(violations={"wwnr": {"srcsd": 1}}),
    "threads a list": _with(violations={"sleep": ["srcsd"]}),
    "too many series": _with(violations={"sleep": {f"srcsd-{n}": 1 for n in range(80)}}),
    "overflow of no monitor": _with(overflow={"x": 1}),
    "a time that is nan": b'{"format": 1, "last_violation_unix": NaN}',
    "a time a string": _with(last_violation_unix="now"),
    "violations missing": _with(violations=None),
}


@pytest.mark.parametrize("name", list(HOSTILE))
def test_a_hostile_file_is_a_typed_refusal(name: str) -> None:
    """SR-9.9: a file too big, not JSON, of another format, with a value of the wrong type, a
    thread not srcsd's or too many series is refused with a fixed reason, never raised as
    anything else; the model then counts it and serves none of the judge's series."""
    with pytest.raises(JudgeFileRefused) as refused:
        parse(HOSTILE[name], age_s=0.0)
    assert refused.value.reason in {"too_big", "not_json", "format", "bad_value"}
    model = ExporterModel()
    model.judge_read(None, refused.value.reason)
    assert samples(model) == {("srcs_rt_file_refusals", (("reason", refused.value.reason),)): 1}


def test_a_hostile_file_on_disk_is_read_bounded_and_said_once(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """SR-9.9: a file of 100 MiB is refused by its size without being read; a directory or a
    link in its place is refused; the same refusal at every scrape is said once."""
    path = tmp_path / "violations.json"
    with path.open("wb") as f:
        f.truncate(100 << 20)
    reader = JudgeFile(path)
    for _ in range(3):
        assert reader.read(time.time()) == (None, "too_big")
    assert len([r for r in caplog.records if "refused" in r.getMessage()]) == 1
    path.unlink()
    (tmp_path / "elsewhere.json").write_text(json.dumps(GOOD))
    path.symlink_to(tmp_path / "elsewhere.json")
    assert reader.read(time.time()) == (None, "unreadable")
    path.unlink()
    path.mkdir()
    assert reader.read(time.time()) == (None, "unreadable")


def test_the_exporters_default_file_is_the_watchs() -> None:
    """SR-9.9: the exporter reads, by default, where the watch writes by default."""
    from supervisord.cli.exporter import DEFAULT_RV_FILE  # noqa: PLC0415

    assert DEFAULT_RV_FILE == DEFAULT_OUTPUT


# -- end to end: the watch, the exporter, Prometheus ---------------------------------------


def scrape(exporter: Exporter) -> dict[tuple[str, tuple[tuple[str, str], ...]], float]:
    body, _ = http_get(exporter.url, accept="application/openmetrics-text; version=1.0.0")
    families = text_string_to_metric_families(body)  # type: ignore[no-untyped-call]
    return {
        (s.name, tuple(sorted(s.labels.items()))): s.value
        for f in families
        for s in f.samples
        if s.name.startswith("srcs_rt_")
    }


@pytest.fixture
def judged(tmp_path: Path) -> Iterator[tuple[FakeTracefs, Path]]:
    """A fake tracefs with the watch running on it; the totals' path."""
    tracefs = FakeTracefs(tmp_path / "tracing")
    output = tmp_path / "run" / "violations.json"
    output.parent.mkdir()
    watch = Watch(tracefs.root, output)
    watch.wait_for("the watch's first totals", lambda totals: True)
    try:
        yield tracefs, output
    finally:
        tracefs.close()
        assert terminate(watch.process) == 0, watch.log.read_text()


def test_the_exporter_serves_what_the_watch_counted(
    judged: tuple[FakeTracefs, Path], tmp_path: Path
) -> None:
    """SR-9.9: the kernel's lines into the watch, the watch's file into the real exporter: a
    scrape shows the loop's page fault and a lane's sleep, the judge on; the file broken
    under it, the scrape still answers and counts the refusal."""
    tracefs, output = judged
    exporter = Exporter(tmp_path / "api.sock", tmp_path / "exporter.log", rv_file=output)
    try:
        tracefs.emit(
            kernel_line("srcsd-415", time.monotonic(), "pagefault", "srcsd[415]")
            + kernel_line("srcsd-log-420", time.monotonic(), "sleep", "srcsd-log[420]")
        )
        fault = ("srcs_rt_violations_total", (("monitor", "pagefault"), ("thread", "srcsd")))
        got = wait_until(lambda: (m := scrape(exporter)).get(fault) == 1 and m, what="the fault")
        assert got[("srcs_rt_judge_on", ())] == 1
        assert (
            got[("srcs_rt_violations_total", (("monitor", "sleep"), ("thread", "srcsd-log")))] == 1
        )
        assert got[("srcs_rt_violations_total", (("monitor", "wakeup"), ("thread", "srcsd")))] == 0
        assert abs(got[("srcs_rt_last_violation_timestamp_seconds", ())] - time.time()) < 5
    finally:
        assert exporter.stop() == 0
    # A hostile file in the watch's place (the watch stopped writing: a link would follow).
    broken = tmp_path / "broken.json"
    broken.write_bytes(b"{" * 5000)
    exporter = Exporter(tmp_path / "api.sock", tmp_path / "exporter2.log", rv_file=broken)
    try:
        refusals = ("srcs_rt_file_refusals_total", (("reason", "not_json"),))
        first = scrape(exporter)
        assert set(first) == {refusals}  # no series of the judge's, the refusal counted
        assert scrape(exporter)[refusals] == first[refusals] + 1  # each scrape reads it
    finally:
        assert exporter.stop() == 0
    log = (tmp_path / "exporter2.log").read_text()
    assert log.count("refused") == 1, log
    assert "Traceback" not in log


@pytest.mark.skipif(
    shutil.which("prometheus") is None and not Path(PROMETHEUS).exists(),
    reason="needs Debian's prometheus package (./dev installs it)",
)
def test_prometheus_sees_the_loops_page_fault_and_alerts(
    private_network: None, judged: tuple[FakeTracefs, Path], tmp_path: Path
) -> None:
    """SR-9.9: a real Prometheus scraping the real exporter of the watch's file: the loop's
    page-fault series at 0, then 1 after the kernel's line, and SrcsRtLoopPageFault fires;
    the watch stopped, the judge reads off."""
    from tests.conftest import NO_PRIVATE_NETWORK  # noqa: PLC0415 - set when the session starts

    if NO_PRIVATE_NETWORK is not None:
        pytest.skip(
            f"Prometheus listens on TCP: only in a private namespace ({NO_PRIVATE_NETWORK})"
        )
    tracefs, output = judged
    exporter = Exporter(tmp_path / "api.sock", tmp_path / "exporter.log", rv_file=output)
    prometheus = None
    try:
        prometheus = Prometheus(tmp_path / "prometheus", [f"127.0.0.1:{exporter.port}"], "robot-a")
        fault = 'srcs_rt_violations_total{monitor="pagefault", thread="srcsd"}'
        prometheus.wait_value(fault, 0, timeout=30)
        prometheus.wait_value("srcs_rt_judge_on", 1)
        tracefs.emit(kernel_line("srcsd-415", time.monotonic(), "pagefault", "srcsd[415]"))
        prometheus.wait_value(fault, 1)
        prometheus.wait_value('ALERTS{alertname="SrcsRtLoopPageFault", alertstate="firing"}', 1)
        tracefs.write("rv/monitoring_on", "0\n")
        prometheus.wait_value("srcs_rt_judge_on", 0)
    finally:
        if prometheus is not None:
            prometheus.stop()
        assert exporter.stop() == 0


def test_the_watch_writes_where_the_unit_gives_it_a_directory() -> None:
    """SR-9.9: the unit's runtime directory is the default file's, 0755 so that the
    exporter, another user, reads the file (its mode 0644 is the watch's)."""
    unit = (Path(__file__).resolve().parents[2] / "units/srcs-rv.service").read_text()
    assert f"RuntimeDirectory={DEFAULT_OUTPUT.parent.name}\n" in unit
    assert DEFAULT_OUTPUT.parent.parent == Path("/run")
    assert "RuntimeDirectoryMode=0755\n" in unit

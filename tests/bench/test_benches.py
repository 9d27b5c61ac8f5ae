"""Each bench, run small: it must keep working and produce sane numbers.

No timing thresholds here (CI machines are shared and slow); only what holds by construction:
an output goes off after the frame that stopped it was written, a link-loss stop never comes
before the timeout, every stop asked for is measured, the daemon uses some CPU and memory.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from bench import heartbeat_jitter, idle_cost, link_loss, stop_latency
from bench.rig import NS_PER_MS, percentile


def test_percentile_is_a_nearest_rank_measured_value() -> None:
    values = list(range(1, 101))
    assert percentile(values, 0.5) == 50
    assert percentile(values, 0.99) == 99
    assert percentile(values, 1.0) == 100
    assert percentile([7], 0.99) == 7


def test_stop_latency_measures_every_stop_of_both_kinds(tmp_path: Path) -> None:
    measured = stop_latency.run(tmp_path, stops=6, estop_every=3)
    assert [stop.kind for stop in measured] == ["hold", "hold", "estop"] * 2
    for stop in measured:
        assert stop.edge.on is False
        assert stop.sent < stop.edge.started <= stop.edge.finished  # causality
        assert 0 < stop.to_write <= stop.latency
    records = (tmp_path / "stops.jsonl").read_text().splitlines()
    assert len(records) >= 12  # the real loop recorded every stop and every re-arm


def test_stop_latency_back_to_back_and_the_two_models(tmp_path: Path) -> None:
    for model in ("supervisor", "poll50", "event"):
        directory = tmp_path / model
        directory.mkdir()
        measured = stop_latency.run(directory, 4, 2, model, back_to_back=True, mirror=True)
        assert len(measured) == 4
        assert all(stop.latency > 0 for stop in measured)
        assert (directory / "drive").read_text() in {"0\n", "1\n"}


def test_stop_latency_prints_its_table_and_verdict(capsys: pytest.CaptureFixture[str]) -> None:
    stop_latency.main(["--stops", "3", "--estop-every", "3"])
    out = capsys.readouterr().out
    assert "| all stops | 3 |" in out
    assert "| e-stop (VSC e-stop word) | 1 |" in out
    assert "safety-rules §9 target: p99 under 2 ms" in out
    assert out.rstrip().endswith(("PASS", "FAIL"))


def test_link_loss_never_stops_before_the_timeout(tmp_path: Path) -> None:
    measured = link_loss.run(tmp_path, trials=2, timeout_ms=100)
    assert len(measured) == 2
    assert all(value >= 100 * NS_PER_MS for value in measured)  # the deadline counts from receipt
    assert all(value < 1100 * NS_PER_MS for value in measured)  # else run() would have raised


def test_link_loss_prints_its_table(capsys: pytest.CaptureFixture[str]) -> None:
    link_loss.main(["--trials", "1", "--timeout-ms", "100"])
    out = capsys.readouterr().out
    assert "| silence to off | 1 |" in out
    assert "stopped before the timeout: 0 of 1" in out


def test_heartbeat_jitter_hears_a_steady_heartbeat(capsys: pytest.CaptureFixture[str]) -> None:
    heartbeat_jitter.main(["--seconds", "1"])
    out = capsys.readouterr().out
    assert "| period |" in out
    assert "| deviation from 50 ms |" in out


def test_heartbeat_jitter_periods(tmp_path: Path) -> None:
    periods, stops = heartbeat_jitter.run(tmp_path, seconds=1.0, spin=1, pin=False)
    assert stops >= 0
    assert len(periods) >= 10  # 20 Hz for a second, whatever the scheduling
    # Two heartbeats read in one chunk share a timestamp: a period may be 0, never negative.
    assert all(period >= 0 for period in periods)
    assert sum(periods) > 0


def test_idle_cost_of_the_real_daemon(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    result = idle_cost.run(tmp_path, seconds=1.0)
    assert result["frames"] > 0
    assert result["wall"] >= 1.0
    assert result["cpu"] >= 0
    assert 0 < result["rss_max_kb"] <= result["hwm_kb"]
    assert result["heartbeats"] > 0  # the daemon was in service, feeding the VSC
    idle_cost.main(["--seconds", "1"])
    out = capsys.readouterr().out
    assert "| CPU time / wall time |" in out
    assert "under 40 MB resident" in out

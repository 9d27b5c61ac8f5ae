"""Each bench, run small: it must keep working and produce sane numbers.

No timing thresholds here (CI machines are shared and slow); only what holds by construction:
an output goes off after the frame that stopped it was written, a link-loss stop never comes
before the timeout, every stop asked for is measured, the daemon uses some CPU and memory.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from bench import (
    client_input,
    core_input_cost,
    fleet_ack,
    heartbeat_cost,
    heartbeat_jitter,
    idle_cost,
    input_instructions,
    link_loss,
    rt_budget,
    stop_latency,
)
from bench.bare import BareLoop, open_port
from bench.rig import percentile
from bench.unit import Scheduling, read_unit, span_us
from supervisord.outputs.sim import SimOutput, SimSpec
from supervisord.protocol.framing import FrameDecoder
from supervisord.protocol.messages import UserHeartbeat
from supervisord.sim.pty import PtyPort
from supervisord.testkit.wait import wait_until
from supervisord.testkit.worst_input import LINES
from supervisord.timebase import NS_PER_MS


def test_percentile_is_a_nearest_rank_measured_value() -> None:
    """The percentile the benches print is the nearest-rank one: always a measured value."""
    values = list(range(1, 101))
    assert percentile(values, 0.5) == 50
    assert percentile(values, 0.99) == 99
    assert percentile(values, 1.0) == 100
    assert percentile([7], 0.99) == 7


def test_fleet_ack_measures_every_stop(tmp_path: Path) -> None:
    """SR-8.20: every fleet stop asked for is acknowledged with the outputs read back off and
    measured: a time from arrival to off within the agent's own round trip."""
    measured = fleet_ack.run(tmp_path, stops=2)
    assert len(measured) == 2
    for arrival, trip in measured:
        assert 0 < arrival < trip


def test_stop_latency_measures_every_stop_of_both_kinds(tmp_path: Path) -> None:
    """SR-9.1: every stop asked for is measured, holds and e-stops in order, each output edge
    after its frame, and the real loop records each."""
    measured = stop_latency.run(tmp_path, stops=6, estop_every=3)
    assert [stop.kind for stop in measured] == ["hold", "hold", "estop"] * 2
    for stop in measured:
        assert stop.edge.on is False
        assert stop.sent < stop.edge.started <= stop.edge.finished  # causality
        assert 0 < stop.to_write <= stop.latency
    records = (tmp_path / "stops.jsonl").read_text().splitlines()
    assert len(records) >= 12  # the real loop recorded every stop and every re-arm


def test_stop_latency_back_to_back_and_the_two_models(tmp_path: Path) -> None:
    """SR-9.1: back-to-back stops with the mirrored level file work for srcsd, the polling model
    and the bare loop alike."""
    for model in ("supervisor", "poll50", "event"):
        directory = tmp_path / model
        directory.mkdir()
        measured = stop_latency.run(directory, 4, 2, model, back_to_back=True, mirror=True)
        assert len(measured) == 4
        assert all(stop.latency > 0 for stop in measured)
        assert (directory / "drive").read_text() in {"0\n", "1\n"}


def test_stop_latency_prints_its_table_and_verdict(capsys: pytest.CaptureFixture[str]) -> None:
    """SR-9.1: one loop alone prints its table, the e-stop row and the SR-9 verdict."""
    stop_latency.main(["--stops", "3", "--estop-every", "3"])
    out = capsys.readouterr().out
    assert "| all stops | 3 |" in out
    assert "| e-stop (VSC e-stop word) | 1 |" in out
    assert "SR-9 target: p99 under 2 ms" in out
    assert out.rstrip().endswith(("PASS", "FAIL"))


def test_side_by_side_interleaves_the_three_loops_in_blocks(tmp_path: Path) -> None:
    """Side by side: one run measures srcsd, the bare loop and the polling model, each in every
    block on a fresh rig, with the stop kinds continuing across blocks and srcsd's heartbeat
    periods taken within blocks (never across the gap between two)."""
    periods: list[int] = []
    measured = stop_latency.side_by_side(tmp_path, 4, 2, blocks=2, periods=periods)
    assert set(measured) == {"supervisor", "event", "poll50"}
    for stops in measured.values():
        assert [stop.kind for stop in stops] == ["hold", "estop"] * 2
        assert all(stop.latency > 0 for stop in stops)
    for name in ("srcsd", "bare", "poll50"):
        for block in (0, 1):
            assert (tmp_path / f"{name}-{block}").is_dir()
    assert (tmp_path / "srcsd-1" / "stops.jsonl").read_text().count("\n") >= 4
    assert periods
    assert all(0 <= period < 1000 * NS_PER_MS for period in periods)


def test_side_by_side_prints_the_ratios_load_and_steal(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """The default run prints every loop's table, the ratios of the run, the steal time and
    the side-by-side ratio targets with a verdict."""
    stop_latency.main(["--stops", "2", "--blocks", "2", "--estop-every", "0"])
    out = capsys.readouterr().out
    assert out.count("| all stops | 2 |") == 3
    assert "| srcsd / bare |" in out
    assert "| poll50 / srcsd |" in out
    assert "host steal during the run:" in out
    assert "load average" in out
    assert "side-by-side target: srcsd p50 within 1.15 x bare ->" in out
    assert "side-by-side target: srcsd p99 within 1.3 x bare ->" in out


def test_loaded_mode_runs_busy_processes_and_stops_them(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """``--loaded`` runs two busy processes per core meanwhile, says so, and ends them."""
    with stop_latency.busy(2) as count:
        assert count == 2 * (os.cpu_count() or 1)
        # A child shows its program once it has exec'd; until then /proc shows ours.
        wait_until(
            lambda: len([p for p in children_commands() if "while True" in p]) == count,
            what=f"{count} busy processes",
        )
    assert not [p for p in children_commands() if "while True" in p]
    stop_latency.main(["--stops", "2", "--model", "srcsd", "--loaded"])
    out = capsys.readouterr().out
    assert f"loaded: {2 * (os.cpu_count() or 1)} busy processes, unpinned" in out
    assert "| all stops | 2 |" in out
    if os.geteuid() == 0:  # the unit's policy and its RTTIME budget, as systemd applies them
        unit = read_unit()
        assert f"SCHED_FIFO {unit.priority}" in out
        assert unit.soft_us is not None
        assert f"RLIMIT_RTTIME soft {unit.soft_us / 1e6:g} s (the unit's)" in out


def children_commands() -> list[str]:
    """The command lines of this process's live children (from /proc, no extra package)."""
    me = str(os.getpid())
    lines = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
            if fields[1] == me and fields[0] != "Z":
                lines.append((stat.parent / "cmdline").read_bytes().replace(b"\0", b" ").decode())
        except (OSError, IndexError):
            continue
    return lines


def test_steal_share_and_the_units_scheduling(tmp_path: Path) -> None:
    """Steal is the steal ticks' share of all ticks between two readings; the unit's
    ``Nice=`` is read, and a FIFO priority only with ``CPUSchedulingPolicy=fifo``."""
    before = stop_latency.CpuTimes(total=1000, steal=10)
    after = stop_latency.CpuTimes(total=3000, steal=190)
    assert stop_latency.steal_share(before, after) == pytest.approx(0.09)
    assert stop_latency.steal_share(before, before) is None
    assert stop_latency.CpuTimes.read().total > 0
    unit = tmp_path / "srcsd@.service"
    unit.write_text("[Service]\nNice=-5\nCPUSchedulingPriority=10\n")
    assert stop_latency.unit_scheduling(unit) == (-5, 0)
    unit.write_text("[Service]\nNice=-5\nCPUSchedulingPolicy=fifo\nCPUSchedulingPriority=10\n")
    assert stop_latency.unit_scheduling(unit) == (-5, 10)


def test_core_input_cost_times_a_steady_vsc_and_client_heartbeat(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """SR-9.4: the per-input bench of the pure core brings a core to RUN in a fresh
    interpreter of this tree, feeds both heartbeats without a record and prints both medians."""
    core_input_cost.main(["--rounds", "1", "--inputs", "50"])
    out = capsys.readouterr().out
    assert "round 1 after" in out
    assert "after  median of rounds: VSC heartbeat" in out
    assert out.count("load average") == 2


def test_heartbeat_cost_serves_each_kind_of_turn() -> None:
    """SR-9.4: the heartbeat bench drives srcsd's loop through its three kinds of turn (a VSC
    frame alone, with named clients connected, a client's heartbeat answered ok: the bench
    checks the hellos' replies and reads each heartbeat's) and gives each a CPU time."""
    times = heartbeat_cost.measure(turns=20, clients=2)
    assert len(times) == 3
    assert all(time > 0 for time in times)


@pytest.mark.parametrize("model", input_instructions.MODELS)
def test_input_instructions_drives_each_loop_on_its_virtual_clock(
    model: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """SR-9.4: the instruction bench's child (here without valgrind) drives srcsd into RUN and
    through the VSC's full traffic turn by turn, a turn per frame and one per user heartbeat
    due between two frames (10 a second: the others fall on a joystick frame's time), sends
    every user heartbeat, and its replayed core decides as the loop's did; the bare loop
    switches its output on and sends its user heartbeats."""
    assert input_instructions.child(model, warm_up=1.0, seconds=2.0, seed=1) == 0
    said = dict(part.split("=") for part in capsys.readouterr().out.split())
    assert int(said["frames"]) == 142  # 50 + 20 + 1 frames a second, for 2 s
    if model == "srcsd":
        assert said["state"] == "run"
        assert int(said["turns"]) == 142 + 20  # and the user heartbeats' own turns
        assert int(said["heartbeats"]) == 40
        assert int(said["core_inputs"]) >= 142
    elif model == "bare":
        assert said["state"] == "on"
        assert int(said["heartbeats"]) == 40


def test_link_loss_never_stops_before_the_timeout(tmp_path: Path) -> None:
    """SR-9.2: a link loss stops at or after the timeout, never before it, and within a second."""
    measured = link_loss.run(tmp_path, trials=2, timeout_ms=100)
    assert len(measured) == 2
    assert all(value >= 100 * NS_PER_MS for value in measured)  # the deadline counts from receipt
    assert all(value < 1100 * NS_PER_MS for value in measured)  # else run() would have raised


def test_link_loss_prints_its_table(capsys: pytest.CaptureFixture[str]) -> None:
    """SR-9.2: the link-loss bench prints its table, its early-stop count and the load with the
    host's steal."""
    link_loss.main(["--trials", "1", "--timeout-ms", "100"])
    out = capsys.readouterr().out
    assert "| silence to off | 1 |" in out
    assert "stopped before the timeout: 0 of 1" in out
    assert "host steal during the run:" in out


def test_heartbeat_jitter_hears_a_steady_heartbeat(capsys: pytest.CaptureFixture[str]) -> None:
    """SR-9.3: the heartbeat bench prints the periods and their deviation from 50 ms, with the
    steal."""
    heartbeat_jitter.main(["--seconds", "1"])
    out = capsys.readouterr().out
    assert "| period |" in out
    assert "| deviation from 50 ms |" in out
    assert "host steal during the run:" in out


def test_heartbeat_jitter_periods(tmp_path: Path) -> None:
    """SR-9.3: over a second in RUN the VSC side hears about twenty heartbeats, never a negative
    period."""
    periods, stops = heartbeat_jitter.run(tmp_path, seconds=1.0, spin=1, pin=False)
    assert stops >= 0
    assert len(periods) >= 10  # 20 Hz for a second, whatever the scheduling
    # Two heartbeats read in one chunk share a timestamp: a period may be 0, never negative.
    assert all(period >= 0 for period in periods)
    assert sum(periods) > 0


def test_idle_cost_measures_srcsd_the_bare_loop_and_clients_side_by_side(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """SR-9.4: one round runs the real daemon, the bare loop and the daemon with a client, each
    in service at the VSC's full traffic and writing it user heartbeats; the client beats;
    every run prints its load and steal, and the ratios and targets follow (no time asserted)."""
    idle_cost.main(["--seconds", "1", "--rounds", "1", "--clients", "2", "--warm-up", "0.5"])
    out = capsys.readouterr().out
    rows = [line.split(" | ") for line in out.splitlines() if line.startswith("| 1 | ")]
    runs = {row[1]: row for row in rows if len(row) == 11}  # the table of every run
    for loop in ("srcsd", "bare", "srcsd+2"):
        row = runs[loop]
        assert float(row[6]) > 0  # the VSC's frames went in
        beats, frames_out = (float(part) for part in row[7].split(" / "))
        assert 0 < beats <= frames_out  # it fed the VSC: in service
    assert float(runs["srcsd+2"][8]) > 0  # the clients' heartbeats went out
    assert "host steal during the run:" in out
    assert "| CPU share |" in out
    assert "| VmHWM |" in out
    assert "| 2 |" in out  # what a client adds
    assert "target: srcsd's share at most 1.5 x the bare loop's ->" in out
    assert "SR-9.4 target: under 40 MB resident" in out


def test_idle_cost_pairs_the_runs_of_one_round() -> None:
    """The ratios and a client's share are taken between the runs of one round, never across
    rounds; a round without its partner gives none."""

    def run(loop: str, round_: int, cpu: float, clients: int = 0) -> idle_cost.Run:
        return idle_cost.Run(
            loop, clients, round_, 10.0, cpu, 710, 13000, 200, 200, 0.0, 1024, 2048, 1536, 0.5, 0.0
        )

    runs = [
        run("srcsd", 0, 0.2),
        run("bare", 0, 0.1),
        run("srcsd+10", 0, 0.3, 10),
        run("bare", 1, 0.5),
        run("srcsd", 1, 0.6),
        run("srcsd", 2, 0.9),
    ]
    assert idle_cost.ratios(runs, "srcsd", "bare", lambda r: r.share) == pytest.approx([2.0, 1.2])
    assert idle_cost.per_client(runs, 10) == pytest.approx([0.001])
    assert idle_cost.per_client(runs, 50) == []
    assert idle_cost.spread([1.0, 3.0, 2.0], str) == "2.0 (1.0 to 3.0)"
    assert idle_cost.client_counts("1, 10,50") == [1, 10, 50]
    assert idle_cost.client_counts("") == []


def test_the_unit_file_is_read_as_systemd_reads_its_scheduling(tmp_path: Path) -> None:
    """SR-9: ``LimitRTTIME=`` is read as systemd reads it (soft:hard, time units, one value
    for both, infinity), the FIFO priority only with the FIFO policy; the real unit sets a
    FIFO priority and a finite budget."""
    assert span_us("1s") == 1_000_000
    assert span_us("300ms") == 300_000
    assert span_us("250000") == 250_000
    assert span_us("infinity") is None
    with pytest.raises(ValueError, match="time span"):
        span_us("1min")
    unit = tmp_path / "srcsd@.service"
    unit.write_text("[Service]\nNice=-5\nLimitRTTIME=300ms\nCPUSchedulingPriority=7\n")
    assert read_unit(unit) == Scheduling(-5, 0, 300_000, 300_000)
    unit.write_text("[Service]\nCPUSchedulingPolicy=fifo\nLimitRTTIME=1s:infinity\n")
    assert read_unit(unit) == Scheduling(0, 1, 1_000_000, None)
    real = read_unit()
    assert real.priority > 0
    assert real.soft_us is not None


TIMEHIST = """\
           time    cpu  task name                       wait time  sch delay   run time  state
                        [tid/pid]                          (msec)     (msec)     (msec)
--------------- ------  ------------------------------  ---------  ---------  ---------  -----
   100.000000 [0000]  python[500]                         0.000      0.100    150.000      D
   100.500000 [0001]  python[500]                         0.000      0.000      3.000      R
   100.510000 [0001]  python[500]                         0.000      0.000      4.000      S
   100.520000 [0000]  python[501/500]                     0.000      0.000      1.000      S
   100.600000 [0000]  python[500]                         0.000      0.000      2.000      S
"""


def test_rt_budget_adds_up_runs_until_the_thread_sleeps() -> None:
    """SR-9: a run that ended in a preemption (R) counts on into the next, as the kernel's
    RLIMIT_RTTIME count does; a sleep (S, D) ends it; READY=1 splits start-up from service."""
    found = rt_budget.bursts(TIMEHIST, ready=100.2, pid=500)
    assert found.startup == {"main": 150.0}
    assert found.running == {"main": 7.0, "thread 501": 1.0}
    assert found.long == [(100.0, "main", 150.0), (100.51, "main", 7.0)]
    assert found.longest == 150.0
    assert found.switches == 5


def test_rt_budget_runs_the_daemon_under_the_units_settings(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """SR-9: the real srcsd, under the unit's FIFO policy and RTTIME budget as root, starts,
    takes the stops and leaves cleanly (never killed), and its page faults are counted."""
    rt_budget.main(["--stops", "3", "--no-perf"])
    out = capsys.readouterr().out
    assert "3 stops; exit status 0 after SIGTERM" in out
    assert "| after the last stop |" in out
    assert "host steal during the run:" in out


def test_slow_disk_runs_srcsd_with_and_without_it_side_by_side(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """SR-7.5: ``--slow-disk`` measures srcsd with every record fsync 50 ms slower beside
    srcsd as it is, in the same blocks, prints both tables and their ratio, and how many
    records had reached the disk when each block's stops were done."""
    stop_latency.main(["--stops", "4", "--blocks", "2", "--model", "srcsd", "--slow-disk"])
    out = capsys.readouterr().out
    assert out.count("| all stops | 4 |") == 2
    assert "srcsd-slow: the srcsd loop, every record fsync 50 ms slower" in out
    assert "| srcsd slow disk / srcsd |" in out
    assert out.count("slow disk (50 ms more per fsync):") == 2


def test_client_input_measures_every_family_and_the_heartbeat_under_its_flood(
    tmp_path: Path,
) -> None:
    """SR-10.5: the bench gives a cost for every worst-case family and the framing at each
    size, and the real loop keeps sending the user heartbeat while every client slot floods
    one of them (the flood never dropped); no time asserted."""
    rows = client_input.costs([1, 2])
    assert set(rows) == {*LINES, client_input.FRAMING}
    assert all(len(values) == 2 and min(values) > 0 for values in rows.values())
    periods, turns, status = client_input.heartbeat_under_flood(tmp_path, 1.0, "commas")
    assert len(periods) >= 5
    assert turns["turns"] > 0
    assert status is None


def test_the_bare_loop_sends_the_user_heartbeat_on_srcsds_cadence(tmp_path: Path) -> None:
    """SR-5.1, SR-9.4: the floor writes the user heartbeat as srcsd does, every 50 ms on a
    schedule that a late turn does not move, and waits no longer than its next one: at the
    same rate as srcsd, so that the idle bench compares the same I/O. Real pty, driven clock."""
    vsc = PtyPort(tmp_path / "vsc")
    port = open_port(str(tmp_path / "vsc"))
    now = [1_000 * NS_PER_MS]
    output = SimOutput(SimSpec(name="drive", path=None))
    output.open(now[0])
    loop = BareLoop(port, output, True, lambda: now[0])
    heard = FrameDecoder()
    beats = []
    try:
        for late_ms in (0, 60, 100, 120, 150):  # a turn 10 ms late, then on time
            now[0] = 1_000 * NS_PER_MS + late_ms * NS_PER_MS
            loop.turn()
            written = heard.feed(vsc.read(timeout=0.5 if late_ms != 120 else 0.0))
            beats += [late_ms for event in written if isinstance(event, UserHeartbeat)]
        assert beats == [0, 60, 100, 150]  # due at 0, 50, 100, 150: the late one kept the rest
        assert loop.wait_s() == pytest.approx(0.05)  # until the heartbeat due at 200 ms
    finally:
        output.close()
        os.close(port)
        vsc.close()

"""Stop categories (SR-1.4; docs/outputs.md "Stop categories"): the real ``srcsd`` against
``srcs-sim``, a remote e-stop in RUN, and the times the outputs' files went off."""

from __future__ import annotations

from pathlib import Path

from supervisord.record.stop import StopRecord
from supervisord.testkit.robot import ALLOWANCE_S, OutputDef, Robot
from supervisord.testkit.wait import wait_until
from supervisord.vocabulary import CauseKind, State

DELAY_MS = 400
OUTPUTS = (
    OutputDef("drive", "motion"),
    OutputDef("brakes", "power", off_delay_ms=DELAY_MS),
    OutputDef("lights", "power"),
)


def test_a_category_1_output_goes_off_its_delay_after_the_motion_output(tmp_path: Path) -> None:
    """SR-1.4: a remote e-stop in RUN switches the motion output and the category-0 power
    output off by the next heartbeat; the category-1 output stays on, and goes off no
    earlier than its delay after the stop's decision (the record's ``mono_ns``, the instant
    the motion output went off: a file is seen after it was written, so this bound is exact)
    and no later than that plus the harness's scheduling allowance. ``status`` shows the
    delay."""
    with Robot(tmp_path, outputs=OUTPUTS) as robot:
        watcher = robot.watcher
        assert watcher is not None
        assert robot.counters().outputs_off_delay_ms == {"brakes": DELAY_MS}
        robot.arm()
        t = robot.now()
        robot.vsc.estop()
        drive = watcher.wait("drive", False, t)
        lights = watcher.wait("lights", False, t)
        for level in (drive, lights):
            assert level.t - t <= robot.beat_s + ALLOWANCE_S
        record: StopRecord = wait_until(
            lambda: robot.record_raising(CauseKind.VSC_ESTOP, t), what="the stop's record"
        )
        assert record.to_state is State.STOPPED, record
        stopped = record.mono_ns / 1e9
        brakes = watcher.wait("brakes", False, t)
        assert brakes.t >= stopped + DELAY_MS / 1000, (
            f"brakes off {(brakes.t - stopped) * 1000:.0f} ms after the stop"
        )
        assert brakes.t - stopped <= DELAY_MS / 1000 + ALLOWANCE_S
        assert watcher.level_at("brakes", drive.t) is True  # on while the drives brake
        assert robot.status().report.outputs == {"brakes": False, "drive": False, "lights": False}

"""A real stop looked at (SR-7.15, SR-7.16; docs/record.md "Looking at a stop"): the real
``srcsd`` against ``srcs-sim`` stops on the remote's e-stop, and ``srcsctl replay --mcap --plot``
exports its window: the MCAP file's stop record is the record file's, and the picture, drawn by
headless Chromium, shows the marker at the stop."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from mcap.reader import make_reader

from supervisord.protocol.messages import VscHeartbeat
from supervisord.record.flight import read_window
from supervisord.record.replay import replay
from supervisord.record.stop import read_record
from supervisord.record.stop_picture import MARKER, STATE_COLOURS, stop_picture
from supervisord.record.timeline import timeline
from supervisord.safety.events import VscReceived
from supervisord.testkit.robot import Robot
from tests.faults.test_flight import _window_of, srcsctl
from tests.record.browser import render_svg


def test_a_real_stop_exported_as_mcap_and_as_a_picture(tmp_path: Path) -> None:
    """SR-7.15, SR-7.16: a remote e-stop of the real daemon; ``srcsctl replay SEQ --config
    --mcap --plot`` replays it (exit 0) and writes both files: the MCAP file's last record is
    the stop record of the record file (every field) at its ``utc``, its VSC heartbeats are the
    window's; the SVG renders in Chromium with the stop marker at the stop's x and RUN before
    it in the state band."""
    with Robot(tmp_path) as robot:
        robot.arm()
        stop = robot.remote_estop()
        path = _window_of(robot, stop.record)
        mcap, svg = tmp_path / "stop.mcap", tmp_path / "stop.svg"
        done = srcsctl(
            "replay",
            str(stop.record.seq),
            "--config",
            str(robot.config_path),
            "--mcap",
            str(mcap),
            "--plot",
            str(svg),
        )
        assert done.returncode == 0, done.stdout + done.stderr
        robot.vsc.release()
        robot.recover(stop)
    window = read_window(path)
    with mcap.open("rb") as file:
        messages = [
            (channel.topic, message.log_time, json.loads(message.data))
            for _, channel, message in make_reader(file).iter_messages()
        ]
    records = [value for topic, _, value in messages if topic == "/core/record"]
    last = records[-1]["record"]
    assert dataclasses.replace(read_record(last), utc=stop.record.utc) == stop.record
    beats = [value for topic, _, value in messages if topic == "/vsc/heartbeat"]
    heard = [
        e.now
        for e in window.inputs
        if isinstance(e, VscReceived) and isinstance(e.message, VscHeartbeat)
    ]
    assert [b["mono_ns"] for b in beats] == heard
    assert beats[-1]["e_stop_remote"] is True
    picture = stop_picture(timeline(window, replay(window, {})))
    assert picture.svg == svg.read_text()
    image = render_svg(svg, picture.width, picture.height)
    state = picture.rows["state"]
    row = image.rows[round(state.y + state.height / 2)]
    marked = [
        x
        for x, p in enumerate(row)
        if all(abs(a - b) <= 20 for a, b in zip(p, bytes.fromhex(MARKER[1:]), strict=True))
    ]
    assert marked, "no stop marker"
    assert abs(sum(marked) / len(marked) - picture.stop_x) <= 3, (marked, picture.stop_x)
    before = image.at(picture.stop_x - 6, state.y + state.height / 2)
    run = bytes.fromhex(STATE_COLOURS["RUN"][1:])
    assert all(abs(a - b) <= 6 for a, b in zip(before, run, strict=True)), before

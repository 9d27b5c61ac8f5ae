"""A stop you can look at (SR-7.15, SR-7.16; docs/record.md "Looking at a stop"): ``srcsctl replay
--mcap`` writes every stop kind's window as an MCAP file whose channels, read back with the
mcap library's reader, hold exactly the window's inputs and the replay's decisions; ``--plot``
draws it as a self-contained SVG that a real browser (headless Chromium) renders with the state
band's colours in their spans and the stop marker where the stop was decided."""

from __future__ import annotations

import datetime as dt
import io
import itertools
import json
import subprocess
import sys
import xml.etree.ElementTree as ET
from collections import defaultdict
from pathlib import Path
from typing import Any

import jsonschema  # type: ignore[import-untyped]  # no stubs in the dev extra
import pytest
from mcap.reader import make_reader

from supervisord.cli.replay import EXIT_BAD_INPUT, run_replay
from supervisord.protocol.messages import Joystick, UserHeartbeat, VscHeartbeat
from supervisord.record.flight import LoadedWindow, read_window
from supervisord.record.mcap_export import METADATA
from supervisord.record.replay import Replay, replay
from supervisord.record.stop_picture import (
    ESTOP_SET,
    MARKER,
    OUTPUT_ON,
    PHASE_COLOURS,
    STATE_COLOURS,
    Picture,
    stop_picture,
)
from supervisord.record.timeline import timeline
from supervisord.safety.events import (
    ClientConnected,
    ClientDisconnected,
    ClientEstop,
    ClientHeartbeat,
    ClientHello,
    ClientHold,
    ClientRelease,
    LinkBroken,
    LinkClosed,
    LinkOpened,
    VscReceived,
)
from tests.record.browser import Image, render_svg
from tests.record.example_picture import DOCUMENTED, example_picture
from tests.record.stop_kinds import CAUSES, KINDS, RECORD, Story

EPOCH = dt.datetime(1970, 1, 1, tzinfo=dt.timezone.utc)


def _ns(when: dt.datetime) -> int:
    delta = when - EPOCH
    return (delta.days * 86_400 + delta.seconds) * 1_000_000_000 + delta.microseconds * 1000


def _colour(hex_colour: str) -> tuple[int, int, int]:
    value = int(hex_colour[1:], 16)
    return (value >> 16, (value >> 8) & 0xFF, value & 0xFF)


def _close(a: tuple[int, int, int], b: tuple[int, int, int], tolerance: int = 6) -> bool:
    return all(abs(x - y) <= tolerance for x, y in zip(a, b, strict=True))


def _exported(tmp_path: Path, story: Story) -> tuple[int, str, LoadedWindow, Replay]:
    story.write(tmp_path)
    out, errors = io.StringIO(), io.StringIO()
    code = run_replay(
        str(story.stop["seq"]),
        tmp_path / RECORD,
        out,
        errors,
        mcap=tmp_path / "stop.mcap",
        plot=tmp_path / "stop.svg",
    )
    window = read_window(next((tmp_path / f"{RECORD}.flight").glob("*.jsonl")))
    result = replay(window, {r["seq"]: r for r in story.records})
    return code, out.getvalue() + errors.getvalue(), window, result


def _messages(
    path: Path,
) -> tuple[dict[str, list[tuple[int, dict[str, Any]]]], Any, dict[str, str]]:
    """The file's messages by topic (log time, decoded JSON), its summary and its metadata,
    every message checked against its channel's JSON Schema."""
    with path.open("rb") as file:
        reader = make_reader(file)
        summary = reader.get_summary()
        assert summary is not None
        by_topic: dict[str, list[tuple[int, dict[str, Any]]]] = defaultdict(list)
        for schema, channel, message in reader.iter_messages():
            assert schema is not None
            assert schema.encoding == "jsonschema", schema.encoding
            assert channel.message_encoding == "json", channel.message_encoding
            value = json.loads(message.data)
            jsonschema.validate(value, json.loads(schema.data))
            assert message.publish_time == message.log_time
            by_topic[channel.topic].append((message.log_time, value))
        metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
    return by_topic, summary, metadata[METADATA]


def _check_channel(
    by_topic: dict[str, list[tuple[int, dict[str, Any]]]],
    topic: str,
    expected: list[tuple[int, dict[str, Any]]],
    utc: Any,
) -> None:
    """The channel holds one message per expected (monotonic time, fields), in order, at the
    mapped wall-clock time, with those fields."""
    got = by_topic.get(topic, [])
    assert len(got) == len(expected), (topic, len(got), len(expected))
    for (log_time, value), (mono_ns, fields) in zip(got, expected, strict=True):
        assert value["mono_ns"] == mono_ns, topic
        assert log_time == utc(mono_ns), topic
        for key, wanted in fields.items():
            assert value[key] == wanted, (topic, key, value, wanted)


@pytest.mark.parametrize("kind", list(KINDS))
def test_every_channel_of_the_mcap_file_is_the_window(tmp_path: Path, kind: str) -> None:
    """SR-7.15: for each stop kind, ``srcsctl replay --mcap`` writes a file the mcap reader
    reads whole: JSON messages with a JSON Schema per channel; each channel holds exactly the
    window's inputs of its kind (VSC heartbeats with each e-stop source, sticks, link, the
    client's heartbeats and requests, output read-backs) or the replay's decisions (state and
    causes, every record, each output's commanded level, each user heartbeat sent, the proof
    test's phase), the counts, first and last times and values checked; times are the
    monotonic stamps mapped to the wall clock by the stop record's ``utc``."""
    story = KINDS[kind]()
    code, said, window, result = _exported(tmp_path, story)
    assert code == 0, said
    assert "mcap: wrote" in said, said
    by_topic, summary, metadata = _messages(tmp_path / "stop.mcap")
    stop_ns: int = story.stop["mono_ns"]
    stop_utc = _ns(dt.datetime.fromisoformat(story.stop["utc"]))

    def utc(mono_ns: int) -> int:
        return stop_utc + mono_ns - stop_ns

    inputs = window.inputs
    beats = [
        (e.now, e.message)
        for e in inputs
        if isinstance(e, VscReceived) and isinstance(e.message, VscHeartbeat)
    ]
    _check_channel(
        by_topic,
        "/vsc/heartbeat",
        [
            (
                now,
                {
                    "vsc_mode": beat.mode,
                    "e_stop_word": beat.estop,
                    "e_stop_remote": bool(beat.estop & 0b11),
                    "e_stop_wired": bool(beat.estop & 0b1100),
                    "e_stop_user": bool(beat.estop & 0b1100_0000),
                },
            )
            for now, beat in beats
        ],
        utc,
    )
    sticks = [e for e in inputs if isinstance(e, VscReceived) and isinstance(e.message, Joystick)]
    _check_channel(by_topic, "/remote/sticks", [(e.now, {"left_x": 0}) for e in sticks], utc)
    links = {LinkOpened: "opened", LinkBroken: "broken", LinkClosed: "closed"}
    _check_channel(
        by_topic,
        "/vsc/link",
        [(e.now, {"event": links[type(e)]}) for e in inputs if type(e) in links],
        utc,
    )
    heartbeats = [e for e in inputs if isinstance(e, ClientHeartbeat)]
    requests = {
        ClientConnected: "connected",
        ClientHello: "hello",
        ClientEstop: "estop",
        ClientHold: "hold",
        ClientRelease: "release",
        ClientDisconnected: "disconnected",
    }
    asked = [e for e in inputs if type(e) in requests]
    if kind == "client_lost":
        assert heartbeats
        assert [requests[type(e)] for e in asked] == ["connected", "hello", "hold", "release"]
        _check_channel(
            by_topic,
            "/client/nav/heartbeat",
            [(e.now, {"connection": 1, "accepted": True, "timeout_ms": 300}) for e in heartbeats],
            utc,
        )
        # Connected before its hello named it: that request is the connection's own.
        _check_channel(by_topic, "/client/connection-1/request", [(asked[0].now, {})], utc)
        _check_channel(
            by_topic,
            "/client/nav/request",
            [(e.now, {"request": requests[type(e)]}) for e in asked[1:]],
            utc,
        )
    else:
        assert not heartbeats
        assert not asked
        assert not [t for t in by_topic if t.startswith("/client/")]
    # The decisions: the replay's own, step by step.
    steps = result.steps
    states = [(s.decision.now, s.decision.state.name) for s in steps]
    changes = [states[0], *(b for a, b in itertools.pairwise(states) if a[1] != b[1])]
    got_states = [(v["mono_ns"], v["state"]) for _, v in by_topic["/core/state"]]
    # Every change of state, in order, at its input's time (a sample between them: a cause).
    got_changes = [got_states[0], *(b for a, b in itertools.pairwise(got_states) if a[1] != b[1])]
    assert got_changes == changes
    last_state = by_topic["/core/state"][-1][1]
    assert last_state["state"] == "STOPPED"
    assert last_state["mono_ns"] == stop_ns
    assert CAUSES[kind] in last_state["latched"]
    records = [(s.decision.now, r) for s in steps for r, _ in s.records]
    _check_channel(
        by_topic,
        "/core/record",
        [
            (now, {"record": json.loads(json.dumps(r)), "verdict": "as recorded"})
            for now, r in records
        ],
        utc,
    )
    assert by_topic["/core/record"][-1][1]["record"]["seq"] == story.stop["seq"]
    assert by_topic["/core/record"][-1][0] == stop_utc  # the stop at its record's utc
    for spec in window.config.outputs:
        levels = [(s.decision.now, s.decision.outputs[spec.name]) for s in steps]
        flips = [levels[0], *(b for a, b in itertools.pairwise(levels) if a[1] != b[1])]
        _check_channel(
            by_topic, f"/output/{spec.name}/commanded", [(t, {"on": on}) for t, on in flips], utc
        )
    sent = [
        (s.decision.now, {"e_stop_indication": f.estop})
        for s in steps
        for f in s.decision.frames
        if isinstance(f, UserHeartbeat)
    ]
    _check_channel(by_topic, "/vsc/user_heartbeat", sent, utc)
    phases = [m["phase"] for _, m in by_topic.get("/core/prooftest", [])]
    if kind == "prooftest_failed":
        assert phases[-2:] == ["withholding", "failed"], phases
    else:
        assert phases == ["off"], phases
    # The file as a whole: every channel has a schema, the stop's metadata says how time is made.
    assert summary.statistics.message_count == sum(len(m) for m in by_topic.values())
    assert set(by_topic) == {c.topic for c in summary.channels.values()}
    assert metadata["seq"] == str(story.stop["seq"])
    assert metadata["replay"] == "matches the record"
    assert "utc" in metadata["clock"]
    assert json.loads(metadata["stop"]) == story.stop


def _spans(result: Replay, end_ns: int) -> list[tuple[int, int, str]]:
    states = [(s.decision.now, s.decision.state.name) for s in result.steps]
    changes = [states[0], *(b for a, b in itertools.pairwise(states) if a[1] != b[1])]
    ends = [t for t, _ in changes[1:]] + [end_ns]
    return [(t, until, state) for (t, state), until in zip(changes, ends, strict=True)]


def _marker_columns(image: Image, y: float) -> list[int]:
    row = image.rows[round(y)]
    return [x for x, pixel in enumerate(row) if _close(pixel, _colour(MARKER), 20)]


def _check_picture(picture: Picture, image: Image, result: Replay, kind: str) -> None:
    """What a person sees: the marker at the stop, the state band's colours in their spans."""
    state = picture.rows["state"]
    stop_x = picture.stop_x
    # The stop marker: a vertical line of its own colour at the stop, from above the band.
    for y in (state.y - 3, state.y + state.height / 2, picture.rows["vsc_mode"].y + 4):
        columns = _marker_columns(image, y)
        assert columns, (kind, y)
        assert min(columns) >= stop_x - 3, (kind, columns, stop_x)
        assert max(columns) <= stop_x + 3, (kind, columns, stop_x)
    # The state band: each span's colour at its middle (spans wider than a few pixels).
    seen = set()
    for start, until, name in _spans(result, picture.end_ns):
        x0, x1 = picture.x(start), picture.x(until)
        middle = (x0 + x1) / 2
        if x1 - x0 < 8 or abs(middle - stop_x) < 6:
            continue
        pixel = image.at(middle, state.y + state.height / 2)
        assert _close(pixel, _colour(STATE_COLOURS[name])), (kind, name, pixel)
        seen.add(name)
    assert {"RUN", "STOPPED"} <= seen, (kind, seen)
    if kind == "client_lost":
        assert "HOLD" in seen
    after = stop_x + 12
    remote = picture.rows["estop_remote"]
    estop = image.at(after, remote.y + remote.height / 2)
    assert _close(estop, _colour(ESTOP_SET)) == (
        kind in {"remote_estop", "category_1", "prooftest_failed"}
    )
    if kind == "category_1":
        # The brake stays on for its 400 ms off delay after the stop, the drive goes at once.
        brake, drive = picture.rows["output_brake"], picture.rows["output_drive"]
        during = picture.x(picture.timeline.stop_ns + 200_000_000)
        later = picture.x(picture.timeline.stop_ns + 450_000_000)
        assert _close(image.at(during, brake.y + 6), _colour(OUTPUT_ON))
        assert not _close(image.at(later, brake.y + 6), _colour(OUTPUT_ON))
        assert not _close(image.at(during, drive.y + 6), _colour(OUTPUT_ON))
    if kind == "prooftest_failed":
        proof = picture.rows["prooftest"]
        pixel = image.at(stop_x - 20, proof.y + 3)
        assert _close(pixel, _colour(PHASE_COLOURS["failed"])), pixel


def _check_svg(text: str, causes: list[str]) -> None:
    """Self-contained: no script, link, image, style sheet or font of its own; the causes are
    named at the marker."""
    for banned in ("<script", "href", "<image", "url(", "@font-face", "<style", "<foreignObject"):
        assert banned not in text, banned
    root = ET.fromstring(text)  # noqa: S314 - the picture this test made
    labels = [
        "".join(t.itertext())
        for t in root.iter("{http://www.w3.org/2000/svg}text")
        if t.get("fill") == MARKER
    ]
    assert len(labels) == 1, labels
    for cause in causes:
        assert cause in labels[0], (cause, labels)


@pytest.mark.parametrize("kind", list(KINDS))
def test_the_picture_of_every_stop_kind_in_a_browser(tmp_path: Path, kind: str) -> None:
    """SR-7.16: ``srcsctl replay --plot`` draws each stop kind's window as a self-contained SVG;
    headless Chromium renders it, and its pixels show the stop marker's colour at the stop's x
    (only there) and each span of the replayed states in its colour (RUN, HOLD, STOPPED), the
    remote's e-stop bit set after a remote e-stop, a category-1 output on through its off
    delay, a failed proof test's phase; the marker names the stop's causes."""
    story = KINDS[kind]()
    code, said, window, result = _exported(tmp_path, story)
    assert code == 0, said
    svg = (tmp_path / "stop.svg").read_text()
    picture = stop_picture(timeline(window, result))
    assert picture.svg == svg  # the file is the picture whose geometry is checked
    _check_svg(svg, [c["name"] for c in story.stop["causes"]])
    image = render_svg(tmp_path / "stop.svg", picture.width, picture.height)
    _check_picture(picture, image, result, kind)


def test_without_the_mcap_library_the_export_says_what_to_install(tmp_path: Path) -> None:
    """SR-7.15: in an installation that lost the mcap library, ``--mcap`` is refused before
    anything is written, with what to do (exit 2), never a traceback; ``--plot`` alone needs
    nothing and writes its picture."""
    story = KINDS["remote_estop"]()
    story.write(tmp_path)
    script = (
        "import sys, io\n"
        "sys.modules['mcap'] = None\n"  # the package is not installed
        "from pathlib import Path\n"
        "from supervisord.cli.replay import run_replay\n"
        "out, err = io.StringIO(), io.StringIO()\n"
        f"code = run_replay({str(story.stop['seq'])!r}, Path({str(tmp_path / RECORD)!r}), out, err,"
        f" mcap=Path({str(tmp_path / 'x.mcap')!r}))\n"
        "print(code, err.getvalue())\n"
        f"code = run_replay({str(story.stop['seq'])!r}, Path({str(tmp_path / RECORD)!r}), out, err,"
        f" plot=Path({str(tmp_path / 'x.svg')!r}))\n"
        "print(code)\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120, check=False
    )
    lines = done.stdout.splitlines()
    assert lines[0].startswith(f"{EXIT_BAD_INPUT} srcsctl replay: --mcap: the mcap package"), done
    assert "install its package again" in lines[0]
    assert "pip install" not in lines[0]  # the project is on no index; /opt/srcsd has no pip
    assert lines[-1] == "0", done
    assert not (tmp_path / "x.mcap").exists()
    assert (tmp_path / "x.svg").read_text().startswith("<svg")


def test_the_daemon_never_loads_the_export(tmp_path: Path) -> None:
    """SR-7.15, SR-7.16: the export is a desk's tool: starting ``srcsd``'s program (its whole
    import graph: the loop, the sink, the flight recorder) loads neither the MCAP library nor
    the export's modules."""
    script = (
        "import sys\n"
        "import supervisord.cli.srcsd, supervisord.daemon.loop, supervisord.daemon.sink\n"
        "names = ('mcap', 'supervisord.record.mcap_export', 'supervisord.record.stop_picture',"
        " 'supervisord.record.timeline', 'supervisord.cli.replay_export')\n"
        "print(sorted(n for n in names if n in sys.modules))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120, check=True
    )
    assert done.stdout.strip() == "[]", done.stdout


def test_the_documented_picture_is_the_one_the_replay_draws() -> None:
    """SR-7.16: the picture docs/record.md shows is what ``srcsctl replay --plot`` draws today of
    the tests' remote e-stop, so the manual never shows a picture the tool no longer makes
    (``python -m tests.record.example_picture`` draws it again)."""
    assert example_picture() == DOCUMENTED.read_text(), (
        "the picture is stale: run `.venv/bin/python -m tests.record.example_picture`"
    )

"""A stop's window as a picture: one self-contained SVG on one time axis, for the incident report
(SR-7.16; ``docs/record.md`` "Looking at a stop").

From top to bottom: the stop marker with the causes' names where the stop was decided; the
state band (RUN, HOLD, STOPPED, each its colour); the VSC's mode and each e-stop source of its
heartbeats; the time since the last VSC heartbeat against the VSC timeout, and since each
client's last accepted heartbeat against its own, with its holds and e-stops marked; each
output's commanded level (a category-1 output's off delay drawn after the stop) and read-backs;
the proof test's phase; each user heartbeat sent. The axis is in seconds before the stop; a
legend says what each colour is.

Plain SVG 1.1: rectangles, lines, polylines and text in the generic ``sans-serif`` family; no
script, no style sheet, no link, no image, no font of its own: it reads the same offline, in a
browser, an editor or a printed report. Pure: the caller writes the file.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Iterable, Sequence
from typing import Final
from xml.sax.saxutils import escape

from supervisord.record.timeline import Sample, Timeline

WIDTH: Final = 1200
LEFT: Final = 200  # the labels' column
RIGHT: Final = 24
TOP: Final = 78  # the title, and the stop marker's label
BAND: Final = 20
GAUGE: Final = 44
SPACE: Final = 6
STATE_COLOURS: Final = {"RUN": "#2ca02c", "HOLD": "#ffb000", "STOPPED": "#d62728"}
MARKER: Final = "#7b2fbe"
"""The stop marker's colour: used by nothing else in the picture."""
MODE_COLOURS: Final = {
    "operational": "#9ecae1",
    "local": "#d9d9d9",
    "pause": "#fdd0a2",
    "searching": "#bcbddc",
    "menu": "#c7e9c0",
    "remote": "#fdae6b",
}
PHASE_COLOURS: Final = {
    "waiting": "#dadaeb",
    "withholding": "#fdae6b",
    "resumed": "#c6dbef",
    "passed": "#a1d99b",
    "failed": "#a50f15",
    "off": "#f0f0f0",
}
ESTOP_SET: Final = "#8c1b1b"
OUTPUT_ON: Final = "#1f77b4"
AGE: Final = "#1f77b4"
TIMEOUT: Final = "#d62728"
EMPTY: Final = "#f4f4f4"
INK: Final = "#222222"
GRID: Final = "#cccccc"
FONT: Final = 'font-family="sans-serif"'


@dataclasses.dataclass(frozen=True)
class Row:
    """One row of the picture: its label and where it is (``y``, ``height``, pixels)."""

    key: str
    label: str
    y: int
    height: int


@dataclasses.dataclass
class Picture:
    """The SVG and its geometry: where a moment is (:meth:`x`) and where each row is."""

    timeline: Timeline
    start_ns: int
    end_ns: int
    rows: dict[str, Row] = dataclasses.field(default_factory=dict)
    height: int = 0
    parts: list[str] = dataclasses.field(default_factory=list)

    @property
    def width(self) -> int:
        return WIDTH

    def x(self, mono_ns: int) -> float:
        """The horizontal position of a moment on the monotonic clock."""
        span = max(self.end_ns - self.start_ns, 1)
        return LEFT + (WIDTH - LEFT - RIGHT) * (mono_ns - self.start_ns) / span

    @property
    def stop_x(self) -> float:
        return self.x(self.timeline.stop_ns)

    @property
    def svg(self) -> str:
        head = (
            f'<svg xmlns="http://www.w3.org/2000/svg" version="1.1" width="{WIDTH}" '
            f'height="{self.height}" viewBox="0 0 {WIDTH} {self.height}">\n'
        )
        return head + "\n".join(self.parts) + "\n</svg>\n"

    # Drawing.

    def rect(self, x0: float, x1: float, y: float, h: float, fill: str, *, title: str = "") -> None:
        if x1 - x0 <= 0:
            return
        tip = f"<title>{escape(title)}</title>" if title else ""
        self.parts.append(
            f'<rect x="{x0:.1f}" y="{y:.1f}" width="{x1 - x0:.1f}" height="{h:.1f}" '
            f'fill="{fill}">{tip}</rect>'
        )

    def line(
        self,
        x0: float,
        y0: float,
        x1: float,
        y1: float,
        colour: str,
        *,
        width: float = 1,
        dash: str = "",
    ) -> None:
        dashed = f' stroke-dasharray="{dash}"' if dash else ""
        self.parts.append(
            f'<line x1="{x0:.1f}" y1="{y0:.1f}" x2="{x1:.1f}" y2="{y1:.1f}" stroke="{colour}" '
            f'stroke-width="{width}"{dashed}/>'
        )

    def text(
        self,
        x: float,
        y: float,
        words: str,
        *,
        size: int = 11,
        anchor: str = "start",
        colour: str = INK,
        bold: bool = False,
    ) -> None:
        weight = ' font-weight="bold"' if bold else ""
        self.parts.append(
            f'<text x="{x:.1f}" y="{y:.1f}" {FONT} font-size="{size}" text-anchor="{anchor}" '
            f'fill="{colour}"{weight}>{escape(words)}</text>'
        )

    def add_row(self, key: str, label: str, height: int = BAND) -> Row:
        row = Row(key, label, self.height, height)
        self.rows[key] = row
        self.height += height + SPACE
        self.rect(LEFT, WIDTH - RIGHT, row.y, height, EMPTY)
        self.text(LEFT - 8, row.y + height / 2 + 4, label, anchor="end")
        return row


def _spans(samples: Sequence[Sample], key: str, end_ns: int) -> Iterable[tuple[int, int, object]]:
    """Each value of ``key`` from the sample that set it to the next that changed it (the last
    to ``end_ns``): one shape per span, never one per sample."""
    changes = [
        s
        for i, s in enumerate(samples)
        if i == 0 or s.value.get(key) != samples[i - 1].value.get(key)
    ]
    for index, sample in enumerate(changes):
        until = changes[index + 1].mono_ns if index + 1 < len(changes) else end_ns
        yield sample.mono_ns, until, sample.value.get(key)


def _step(span_s: float) -> float:
    """The axis' step: at most 12 ticks over ``span_s``, however long the window says it is
    (a damaged one may say 2**63 ns: a fixed largest step drew a tick per 2 minutes, tens of
    millions of them, until memory ran out; SR-7.13, SR-7.16)."""
    for step in (0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1, 2, 5, 10, 20, 30, 60):
        if span_s / step <= 12:
            return step
    step = 120.0
    while span_s / step > 12:
        step *= 10
    return step


def _seconds(value: float, step: float) -> str:
    decimals = 0 if step >= 1 else 1 if step >= 0.1 else 2
    return f"{value:+.{decimals}f} s" if value else "0 s"


class _Painter:
    def __init__(self, timeline: Timeline) -> None:
        self.t = timeline
        config = timeline.window.config
        self.delays = {o.name: o.off_delay_ms for o in config.outputs}
        span = max(timeline.stop_ns - timeline.start_ns, 100_000_000)
        after = max([span // 12, *(d * 1_200_000 for d in self.delays.values())])
        self.p = Picture(timeline, timeline.stop_ns - span, timeline.stop_ns + after)
        self.p.height = TOP

    def samples(self, topic: str) -> list[Sample]:
        signal = self.t.signals.get(topic)
        return signal.samples if signal is not None else []

    def paint(self) -> Picture:
        self.title()
        self.state()
        self.vsc()
        self.clients()
        self.outputs()
        self.prooftest()
        self.user_heartbeats()
        self.axis()
        self.marker()
        self.legend()
        # A background for viewers that show none, under everything.
        self.p.parts.insert(
            0, f'<rect x="0" y="0" width="{WIDTH}" height="{self.p.height}" fill="#ffffff"/>'
        )
        return self.p

    def title(self) -> None:
        t, p = self.t, self.p
        causes = ", ".join(t.cause_names()) or "no cause"
        p.text(
            12,
            22,
            f"Stop #{t.seq}: {t.stop.get('from')} -> {t.stop.get('to')}, causes {causes}",
            size=15,
            bold=True,
        )
        when = t.stop_utc.isoformat() if t.stop_utc else "no utc in the record"
        verdict = "replay matches the record" if t.matches else "REPLAY MISMATCH"
        base = t.window.base.get("kind")
        p.text(
            12,
            40,
            f"{when}; window of {len(t.window.inputs)} inputs from {base}; {verdict}; "
            f"srcsd {t.window.header.get('srcsd')}",
            size=11,
        )

    def state(self) -> None:
        p = self.p
        row = p.add_row("state", "state", BAND + 6)
        for start, until, state in _spans(self.samples("/core/state"), "state", p.end_ns):
            colour = STATE_COLOURS.get(str(state), "#888888")
            p.rect(p.x(start), p.x(until), row.y, row.height, colour, title=str(state))

    def vsc(self) -> None:
        p = self.p
        beats = self.samples("/vsc/heartbeat")
        row = p.add_row("vsc_mode", "VSC mode")
        for start, until, mode in _spans(beats, "vsc_mode_name", p.end_ns):
            x0, x1 = p.x(start), p.x(until)
            p.rect(
                x0, x1, row.y, row.height, MODE_COLOURS.get(str(mode), "#ffffff"), title=str(mode)
            )
        self._mode_names(beats, row)
        for source in ("remote", "wired", "user"):
            bits = p.add_row(f"estop_{source}", f"e-stop {source}")
            for start, until, on in _spans(beats, f"e_stop_{source}", p.end_ns):
                if on:
                    p.rect(p.x(start), p.x(until), bits.y, bits.height, ESTOP_SET, title="set")
        timeout = self.t.window.config.vsc_timeout_ns
        self._gauge("vsc_age", "VSC heartbeat age", [s.mono_ns for s in beats], timeout)

    def _mode_names(self, beats: list[Sample], row: Row) -> None:
        p, shown = self.p, -1000.0
        for start, until, mode in _spans(beats, "vsc_mode_name", p.end_ns):
            x0, x1 = p.x(start), p.x(until)
            if x1 - x0 > 60 and x0 > shown:
                p.text(x0 + 4, row.y + row.height - 6, str(mode), size=10)
                shown = x0 + 70

    def _gauge(self, key: str, label: str, beats: list[int], timeout_ns: int | None) -> Row:
        """The time since the last heartbeat, a saw tooth, against the timeout (dashed)."""
        p = self.p
        row = p.add_row(key, label, GAUGE)
        top = (
            3 * timeout_ns
            if timeout_ns
            else max([b - a for a, b in itertools.pairwise(beats)] or [1])
        )
        scale = (row.height - 4) / max(top, 1)

        def y(age: int) -> float:
            return row.y + row.height - min(age, top) * scale

        if timeout_ns:
            p.line(LEFT, y(timeout_ns), WIDTH - RIGHT, y(timeout_ns), TIMEOUT, dash="5,3")
            p.text(
                WIDTH - RIGHT - 4,
                y(timeout_ns) - 3,
                f"timeout {timeout_ns // 1_000_000} ms",
                size=9,
                anchor="end",
                colour=TIMEOUT,
            )
        if beats:
            points = []
            ends = [*beats[1:], self.t.stop_ns]
            for beat, until in zip(beats, ends, strict=True):
                points += [(p.x(beat), y(0)), (p.x(until), y(until - beat))]
            drawn = " ".join(f"{px:.1f},{py:.1f}" for px, py in points)
            self.p.parts.append(
                f'<polyline points="{drawn}" fill="none" stroke="{AGE}" stroke-width="1.2"/>'
            )
        return row

    def clients(self) -> None:
        timeouts = {c.name: c.timeout_ms for c in self.t.window.config.clients}
        names = sorted(
            {
                topic.split("/")[2]
                for topic in self.t.signals
                if topic.startswith("/client/") and topic.endswith("/heartbeat")
            }
            | set(timeouts)
        )
        for name in names:
            beats = [
                s.mono_ns
                for s in self.samples(f"/client/{name}/heartbeat")
                if s.value.get("accepted")
            ]
            timeout = timeouts.get(name)
            row = self._gauge(
                f"client_{name}",
                f"client {name}",
                beats,
                None if timeout is None else timeout * 1_000_000,
            )
            for sample in self.samples(f"/client/{name}/request"):
                request = sample.value.get("request")
                colour = {"hold": STATE_COLOURS["HOLD"], "estop": ESTOP_SET}.get(str(request))
                if colour is not None:
                    x = self.p.x(sample.mono_ns)
                    self.p.rect(x - 2, x + 2, row.y, 8, colour, title=str(request))

    def outputs(self) -> None:
        p = self.p
        for spec in self.t.window.config.outputs:
            name = spec.name
            row = p.add_row(f"output_{name}", f"output {name} ({spec.role.value})")
            levels = self.samples(f"/output/{name}/commanded")
            delay_ns = spec.off_delay_ms * 1_000_000
            last_on = bool(levels) and bool(levels[-1].value.get("on"))
            for start, until, on in _spans(levels, "on", p.end_ns):
                off = until
                if on and until == p.end_ns and delay_ns and start <= self.t.stop_ns:
                    # Category 1 (SR-1.4): on at the stop, off once its delay has run.
                    off = self.t.stop_ns + delay_ns
                if on:
                    p.rect(p.x(start), p.x(off), row.y, row.height - 6, OUTPUT_ON, title="on")
            if last_on and delay_ns:
                x0, x1 = p.stop_x, p.x(self.t.stop_ns + delay_ns)
                p.line(x0, row.y + row.height - 2, x1, row.y + row.height - 2, INK)
                p.text(x1 + 4, row.y + row.height - 5, f"off delay {spec.off_delay_ms} ms", size=9)
            for sample in self.samples(f"/output/{name}/read_back"):
                seen = sample.value.get("read_back")
                x = p.x(sample.mono_ns)
                colour = INK if seen else "#ffffff" if seen is False else TIMEOUT
                p.rect(x - 1, x + 1, row.y + row.height - 5, 5, colour, title=f"read back {seen}")

    def prooftest(self) -> None:
        phases = self.samples("/core/prooftest")
        if not phases:
            return
        p = self.p
        row = p.add_row("prooftest", "proof test")
        for start, until, phase in _spans(phases, "phase", p.end_ns):
            x0, x1 = p.x(start), p.x(until)
            p.rect(
                x0,
                x1,
                row.y,
                row.height,
                PHASE_COLOURS.get(str(phase), "#ffffff"),
                title=str(phase),
            )
            if x1 - x0 > 70:
                colour = "#ffffff" if phase == "failed" else INK
                p.text(x0 + 4, row.y + row.height - 6, str(phase), size=10, colour=colour)

    def user_heartbeats(self) -> None:
        sent = self.samples("/vsc/user_heartbeat")
        if not sent and self.t.window.config.transport.value != "serial":
            return
        p = self.p
        row = p.add_row("user_heartbeat", "user heartbeat sent")
        for sample in sent:
            x = p.x(sample.mono_ns)
            colour = ESTOP_SET if sample.value.get("e_stop_indication") else INK
            p.line(x, row.y + 3, x, row.y + row.height - 3, colour)

    def axis(self) -> None:
        p = self.p
        y = p.height + 4
        p.line(LEFT, y, WIDTH - RIGHT, y, INK)
        first_s = (p.start_ns - self.t.stop_ns) / 1e9
        last_s = (p.end_ns - self.t.stop_ns) / 1e9
        step = _step(last_s - first_s)
        tick = int(first_s / step) * step
        while tick <= last_s + 1e-9:
            if tick >= first_s - 1e-9:
                x = p.x(self.t.stop_ns + round(tick * 1e9))
                p.line(x, TOP - 4, x, y, GRID, width=0.5)
                p.line(x, y, x, y + 5, INK)
                p.text(x, y + 18, _seconds(tick, step), size=10, anchor="middle")
            tick = round(tick + step, 6)
        p.text(LEFT - 8, y + 18, "time from the stop", size=10, anchor="end")
        p.height = y + 30
        # The grid goes under the rows: move its lines to the front of the list.
        grid = [part for part in p.parts if f'stroke="{GRID}"' in part]
        rest = [part for part in p.parts if f'stroke="{GRID}"' not in part]
        p.parts[:] = grid + rest

    def marker(self) -> None:
        p, x = self.p, self.p.stop_x
        bottom = p.height - 30
        p.line(x, TOP - 18, x, bottom, MARKER, width=3)
        causes = ", ".join(self.t.cause_names()) or "stop"
        anchor = "end" if x > WIDTH - 260 else "start"
        dx = -6 if anchor == "end" else 6
        p.text(
            x + dx,
            TOP - 8,
            f"stop #{self.t.seq}: {causes}",
            size=12,
            anchor=anchor,
            colour=MARKER,
            bold=True,
        )

    def legend(self) -> None:
        p = self.p
        y = p.height + 4
        items = [
            *((colour, name) for name, colour in STATE_COLOURS.items()),
            (ESTOP_SET, "e-stop bit set"),
            (OUTPUT_ON, "output on"),
            (AGE, "time since the last heartbeat"),
            (TIMEOUT, "its timeout"),
            (MARKER, "the stop, where it was decided"),
        ]
        x = 12.0
        for colour, words in items:
            p.rect(x, x + 14, y, 10, colour)
            p.text(x + 18, y + 9, words, size=10)
            x += 34 + 6.0 * len(words)
        p.height = y + 24


def stop_picture(timeline: Timeline) -> Picture:
    """The stop's picture (SR-7.16): ``.svg`` is the file's text."""
    return _Painter(timeline).paint()

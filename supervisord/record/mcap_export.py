"""A stop's window as an MCAP file, for Foxglove and the other tools that read ROS 2's recordings
(SR-7.15; ``docs/record.md`` "Looking at a stop").

One channel per signal of :mod:`supervisord.record.timeline` (``/vsc/heartbeat``,
``/core/state``, ``/output/drive/commanded``, ...), each message a JSON object with a JSON
Schema per channel: Foxglove's convention, message encoding ``json``, schema encoding
``jsonschema``. A message's log and publish time is the wall clock of its input
(:meth:`~supervisord.record.timeline.Timeline.utc_ns`: the window's monotonic stamps mapped
by the stop record's ``utc``); every message also carries its ``mono_ns`` and ``from_stop_s``.
The stop record, the replay's verdict and the clock's mapping are the file's metadata
``srcs.stop``.

The file is written by ``srcsctl replay --mcap`` and ``srcsctl fleet replay --mcap``, never by
the daemon; its library (``mcap``, a dependency of the project) is in the robot's and the
collector's package. Pure: the caller opens the stream.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import IO, Any, Final

from mcap.well_known import MessageEncoding, SchemaEncoding
from mcap.writer import CompressionType, Writer

from supervisord import __version__
from supervisord.record.timeline import Timeline

METADATA: Final = "srcs.stop"
"""The name of the file's metadata record: the stop, the verdict, how the times were made."""
CLOCK: Final = (
    "log_time and publish_time: the window's monotonic stamps (mono_ns) mapped to the wall "
    "clock by the stop record's utc (the stop's mono_ns is its utc)"
)


def _json(value: Mapping[str, Any]) -> bytes:
    return json.dumps(value, separators=(",", ":"), ensure_ascii=False, allow_nan=False).encode()


def export_mcap(timeline: Timeline, stream: IO[bytes]) -> None:
    """Write ``timeline`` to ``stream`` as one MCAP file (SR-7.15)."""
    # Uncompressed: the robot's package carries mcap without the compression libraries it
    # names (lz4 and zstandard, compiled, 30 MB for each Python), so that --mcap works where
    # the window is (SR-7.15); a window is small, and the file is the same on robot and desk.
    writer = Writer(stream, compression=CompressionType.NONE)
    writer.start(profile="", library=f"srcs-supervisord {__version__}")
    channels: dict[str, int] = {}
    for topic, signal in timeline.signals.items():
        schema = writer.register_schema(
            name=str(signal.schema.get("title", topic)),
            encoding=SchemaEncoding.JSONSchema,
            data=_json(signal.schema),
        )
        channels[topic] = writer.register_channel(
            topic=topic, message_encoding=MessageEncoding.JSON, schema_id=schema
        )
    # In time order; at one moment, in the order the signals were made, each in its own.
    messages = sorted(
        (sample.mono_ns, order, index, topic)
        for order, (topic, signal) in enumerate(timeline.signals.items())
        for index, sample in enumerate(signal.samples)
    )
    sequences = dict.fromkeys(channels, 0)
    for mono_ns, _, index, topic in messages:
        value = timeline.signals[topic].samples[index].value
        when = timeline.utc_ns(mono_ns)
        writer.add_message(
            channel_id=channels[topic],
            log_time=when,
            publish_time=when,
            data=_json(value),
            sequence=sequences[topic],
        )
        sequences[topic] += 1
    writer.add_metadata(
        METADATA,
        {
            "seq": str(timeline.seq),
            "stop": _json(dict(timeline.stop)).decode(),
            "causes": ", ".join(timeline.cause_names()),
            "stop_mono_ns": str(timeline.stop_ns),
            "stop_utc": timeline.stop_utc.isoformat() if timeline.stop_utc else "",
            "clock": CLOCK if timeline.stop_utc else "no utc in the stop record: mono_ns",
            "replay": "matches the record" if timeline.matches else "MISMATCH",
            "srcsd": str(timeline.window.header.get("srcsd")),
        },
    )
    writer.finish()  # type: ignore[no-untyped-call]  # mcap leaves it unannotated

"""Building the daemon's parts from a validated configuration."""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

from supervisord.api.server import ApiServer, ServerConfig
from supervisord.clock import MONOTONIC, Clock
from supervisord.config import DaemonConfig, SerialPort
from supervisord.daemon.api_listener import ApiListener
from supervisord.daemon.flight import FlightSettings
from supervisord.daemon.listener import Listener
from supervisord.daemon.loop import Supervisor
from supervisord.daemon.maintenance import PeriodicTest, Schedule
from supervisord.daemon.notify import Notifier
from supervisord.links.base import Backoff, Link
from supervisord.links.registry import create_link
from supervisord.outputs import Output, create_output
from supervisord.outputs.base import OutputKind
from supervisord.record.journal import JournalSink
from supervisord.record.jsonl import RecordWriter, last_record
from supervisord.record.passes import last_passes

if TYPE_CHECKING:
    import can

# python-can (and ``links.can_link``, which imports it) is imported only when the config names
# a CAN bus: it costs a serial robot several MB resident and tens of ms of start-up for nothing
# (SR-9.4; docs/performance.md "Start-up and memory").

log = logging.getLogger("srcsd")


def build_link(config: DaemonConfig) -> Link:
    """The VSC's link, built by its transport's entry in the link registry."""
    return create_link(config.vsc)


def build_outputs(config: DaemonConfig, link: Link) -> tuple[list[Output], can.BusABC | None]:
    """The outputs, and the CAN bus opened for their enable frames when it is not the VSC's.

    CAN enable outputs send on ``[output_bus]`` when configured, else on the VSC's own bus,
    which is then opened here so that the outputs exist (off) before anything else happens.
    """
    settings = config.can_output_bus
    bus: can.BusABC | None = None
    owned: can.BusABC | None = None
    if settings is not None and any(spec.kind is OutputKind.CAN for spec in config.outputs):
        import can  # noqa: PLC0415 -- CAN only

        from supervisord.links.can_link import CanLink, bus_options  # noqa: PLC0415

        if isinstance(link, CanLink) and settings == config.vsc.link:
            link.open()
            bus = link.bus
        else:
            options = bus_options(settings.interface, settings.bitrate)
            owned = bus = can.Bus(interface=settings.interface, channel=settings.channel, **options)
    return [create_output(spec, can_bus=bus) for spec in config.outputs], owned


def build_api(config: DaemonConfig) -> ApiListener:
    api = config.api
    server = ApiServer(
        ServerConfig(
            path=api.socket,
            group=api.group,
            admin_group=api.admin_group,
            max_clients=api.max_clients,
            # The operators' own socket (SR-8.14, docs/safety.md "The client socket cannot
            # shut out a stop").
            operator_path=api.operator_path,
            operator_group=api.operator_group,
            max_line=api.max_message_bytes,
            # The bound clients' users: their names are looked up at start. Whether a hello
            # under a bound name is allowed is the safety core's to judge (ClientSpec.uid).
            known_uids=tuple(c.uid for c in config.safety.clients if c.uid is not None),
        )
    )
    return ApiListener(
        server,
        has_key85=isinstance(config.vsc.link, SerialPort),
        robot=config.robot.name,
        required={c.name: c.timeout_ms for c in config.safety.clients},
        min_remote_battery=config.safety.min_remote_battery,
        rearm_hold_ms=config.safety.rearm_hold_ms,
    )


def schedule(config: DaemonConfig) -> Schedule:
    """The periodic tests' schedule (SR-12.2), with each test's last pass from the record.
    Fail safe: a record that cannot be read is no pass (the test is overdue), never a failed
    start."""
    maintenance = config.maintenance
    result = Schedule(
        {
            PeriodicTest.STOPTEST: maintenance.stoptest_interval_days,
            PeriodicTest.PROOFTEST: maintenance.prooftest_interval_days,
        }
    )
    try:
        found = last_passes(config.record.path, [test.value for test in PeriodicTest])
    except Exception as error:  # whatever the file holds, the daemon starts
        log.warning("the periodic tests' last passes cannot be read: %s (overdue)", error)
        found = {}
    result.found = {PeriodicTest(kind): when for kind, when in found.items()}
    return result


def build_supervisor(
    config: DaemonConfig, listener: Listener | None = None, clock: Clock = MONOTONIC
) -> Supervisor:
    """The daemon from its configuration; ``clock`` is the loop's one clock (SR-2.11)."""
    for warning in config.warnings():
        log.warning("%s", warning)
    link = build_link(config)
    outputs, owned_bus = build_outputs(config, link)
    record = config.record
    writer = RecordWriter(record.path, max_bytes=record.max_bytes, keep=record.keep)
    journal = flight_journal = None
    if record.journal:
        sink = JournalSink()
        if sink.available:
            journal = sink.write
            flight_journal = sink.send  # each stop's window, after its file (SR-13.12)
        else:
            log.warning(
                "journal unavailable (%s): records go to %s only",
                sink.unavailable_reason,
                record.path,
            )
    previous = last_record(record.path)
    supervisor = Supervisor(
        config.safety,
        link,
        outputs,
        writer,
        journal=journal,
        flight_journal=flight_journal,
        flight=FlightSettings(max_bytes=record.flight_max_bytes),
        listener=listener,
        notifier=Notifier(),
        clock=clock,
        backoff=Backoff(config.vsc.reopen.min_ms, config.vsc.reopen.max_ms),
        release=[owned_bus.shutdown] if owned_bus is not None else [],
    )
    supervisor.records.sequence_offset = previous.seq if previous is not None else 0
    supervisor.schedule = schedule(config)
    return supervisor

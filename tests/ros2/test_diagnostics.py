"""The diagnostics statuses (docs/ros2.md "Diagnostics"): levels, messages and keys."""

from __future__ import annotations

import dataclasses

from supervisord.api.messages import RemoteStatusReport
from supervisord.api.status import Cause, DaemonStatus, Maintenance, PeriodicDue, StateReport
from supervisord.ros2.diagnostics import GateCounts, Level, remote_status, supervisor_status
from supervisord.vocabulary import Cause as Named
from supervisord.vocabulary import CauseKind, Severity, State
from tests.api.samples import LOOP

STATUS = StateReport(
    state=State.STOPPED,
    mono_ns=1,
    causes=(
        Cause(
            name=Named(CauseKind.VSC_ESTOP),
            severity=Severity.STOP,
            active=True,
            latched=True,
            raised_ns=1,
            cleared_ns=None,
            details={"sources": "remote"},
        ),
        Cause(
            name=Named(CauseKind.CLIENT_LOST, "ros"),
            severity=Severity.STOP,
            active=False,
            latched=True,
            raised_ns=1,
            cleared_ns=1,
        ),
    ),
    outputs={"drive": False},
    heartbeat_estop=1,
)
DAEMON = DaemonStatus(
    robot="rover-1",
    loop=dataclasses.replace(
        LOOP,
        pid=42,
        link=dataclasses.replace(
            LOOP.link, description="serial /dev/srcs-vsc", open=True, opens=2, open_failures=1
        ),
        messages=1234,
        rejections={"bad_checksum": 3, "wrong_length": 1},
    ),
    clients=(),
    connections=1,
    remote=None,
    in_state_s=None,
)


def _state(state: State) -> StateReport:
    return dataclasses.replace(STATUS, state=state, causes=())


def _status(**kw: object) -> dict[str, str]:
    status = supervisor_status(
        kw.get("status", STATUS),  # type: ignore[arg-type]
        DAEMON,
        socket="/run/srcsd/api.sock",
        client_name="ros",
        gate=GateCounts(forwarded=7),
        unreachable=str(kw.get("unreachable", "")),
        estop_available=kw.get("available"),  # type: ignore[arg-type]
    )
    return {"level": str(int(status.level)), "message": status.message, **dict(status.values)}


def test_stopped_names_every_cause_with_details() -> None:
    """STOPPED is ERROR, the message lists the causes, each cause is a key with its
    severity, flags and details; the link and the counters are there too."""
    values = _status()
    assert values["level"] == str(int(Level.ERROR))
    assert values["message"] == "STOPPED: vsc_estop, client_lost:ros"
    assert values["vsc_estop"] == "stop, active, latched; sources=remote"
    assert values["client_lost:ros"] == "stop, latched"
    assert values["link open"] == "true"
    assert values["link opens"] == "2"
    assert values["rejections"] == "4"
    assert values["rejections bad_checksum"] == "3"
    assert values["output drive"] == "false"
    assert values["cmd_vel forwarded"] == "7"


def test_estop_available_is_a_value_and_its_loss_in_run_a_warning() -> None:
    """SR-8.11: ``e-stop available`` and, when it is not, ``e-stop missing`` with each part;
    in RUN its loss makes the status WARN and says so in the message (a warning: the
    supervisor does not stop for it); in STOPPED the level stays ERROR."""
    run = _state(State.RUN)
    fine = _status(status=run, available=(True, ()))
    assert (fine["level"], fine["e-stop available"], fine["message"]) == ("0", "true", "RUN")
    assert "e-stop missing" not in fine
    parts = ("the remote's battery is 10 %, below 20 %", "no remote is linked to the VSC")
    lost = _status(status=run, available=(False, parts))
    assert lost["level"] == str(int(Level.WARN))
    assert lost["message"] == "RUN; remote e-stop not available"
    assert lost["e-stop available"] == "false"
    assert lost["e-stop missing"] == "; ".join(parts)
    assert _status(available=(False, parts))["level"] == str(int(Level.ERROR))


def test_levels_follow_the_state_and_unreachable_is_error() -> None:
    """RUN is OK, HOLD WARN; an unreachable supervisor is ERROR saying why."""
    assert _status(status=_state(State.RUN))["level"] == "0"
    assert _status(status=_state(State.HOLD))["level"] == "1"
    values = _status(status=None, unreachable="cannot connect")
    assert values["level"] == "2"
    assert values["connected"] == "false"
    assert "unreachable: cannot connect" in values["message"]


def test_remote_status_levels() -> None:
    """No remote status yet is STALE; a low battery or no radio link is WARN, else OK."""
    assert remote_status(None, "r").level is Level.STALE
    good = RemoteStatusReport(
        battery_level=87,
        battery_charging=0,
        connection_strength_vsc=4,
        connection_strength_src=4,
        rssi_vsc=200,
        rssi_src=190,
    )
    assert remote_status(good, "r").level is Level.OK
    assert dict(remote_status(good, "r").values)["battery level %"] == "87"
    low = dataclasses.replace(good, battery_level=10)
    assert remote_status(low, "r").level is Level.WARN
    no_link = dataclasses.replace(good, connection_strength_src=0)
    assert remote_status(no_link, "r").level is Level.WARN


def test_an_overdue_periodic_test_is_a_warning_in_run() -> None:
    """SR-12.2: each periodic test of the daemon's ``maintenance`` is two keys (the last
    pass's age in seconds, or ``never``, and ``overdue``); an overdue one makes RUN a WARN and
    is named in the message; STOPPED stays ERROR; none overdue, or a daemon that says nothing
    of its tests, changes nothing."""
    never = PeriodicDue(interval_days=30, last_pass_age_s=None, overdue=True)
    schedule = Maintenance(
        stoptest=never,
        prooftest=PeriodicDue(interval_days=30, last_pass_age_s=12.5, overdue=False),
    )
    run = _state(State.RUN)

    def diagnosed(status: StateReport, maintenance: Maintenance | None) -> dict[str, str]:
        loop = dataclasses.replace(DAEMON.loop, maintenance=maintenance)
        found = supervisor_status(
            status,
            dataclasses.replace(DAEMON, loop=loop),
            socket="/run/srcsd/api.sock",
            client_name="ros",
            gate=GateCounts(),
        )
        return {"level": str(int(found.level)), "message": found.message, **dict(found.values)}

    late = diagnosed(run, schedule)
    assert late["level"] == str(int(Level.WARN))
    assert late["message"] == "RUN; overdue: stop test"
    assert late["stop test last pass age s"] == "never"
    assert late["stop test overdue"] == "true"
    assert late["proof test last pass age s"] == "12.5"
    assert late["proof test overdue"] == "false"
    assert diagnosed(STATUS, schedule)["level"] == str(int(Level.ERROR))
    passed = dataclasses.replace(never, last_pass_age_s=60.0, overdue=False)
    fine = diagnosed(run, dataclasses.replace(schedule, stoptest=passed))
    assert (fine["level"], fine["message"]) == ("0", "RUN")
    older = diagnosed(run, None)
    assert (older["level"], older["message"]) == ("0", "RUN")
    assert "stop test overdue" not in older

"""The diagnostics statuses (docs/ros2.md "Diagnostics"): levels, messages and keys."""

from __future__ import annotations

from collections.abc import Mapping

from supervisord.ros2.diagnostics import GateCounts, Level, remote_status, supervisor_status

STATUS = {
    "state": "STOPPED",
    "causes": [
        {
            "name": "vsc_estop",
            "severity": "stop",
            "active": True,
            "latched": True,
            "details": {"sources": "remote"},
        },
        {"name": "client_lost:ros", "severity": "stop", "active": False, "latched": True},
    ],
    "outputs": {"drive": False},
    "heartbeat_estop": 1,
}
DAEMON = {
    "robot": "rover-1",
    "pid": 42,
    "link": {"description": "serial /dev/srcs-vsc", "open": True, "opens": 2, "open_failures": 1},
    "messages": 1234,
    "rejections": {"bad_checksum": 3, "wrong_length": 1},
    "record_errors": 0,
    "internal_faults": 0,
}


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
    run = {"state": "RUN", "causes": []}
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
    assert _status(status={"state": "RUN", "causes": []})["level"] == "0"
    assert _status(status={"state": "HOLD", "causes": []})["level"] == "1"
    values = _status(status=None, unreachable="cannot connect")
    assert values["level"] == "2"
    assert values["connected"] == "false"
    assert "unreachable: cannot connect" in values["message"]


def test_remote_status_levels() -> None:
    """No remote status yet is STALE; a low battery or no radio link is WARN, else OK."""
    assert remote_status(None, "r").level is Level.STALE
    good = {"battery_level": 87, "connection_strength_vsc": 4, "connection_strength_src": 4}
    assert remote_status(good, "r").level is Level.OK
    assert dict(remote_status(good, "r").values)["battery level %"] == "87"
    assert remote_status({**good, "battery_level": 10}, "r").level is Level.WARN
    assert remote_status({**good, "connection_strength_src": 0}, "r").level is Level.WARN


def test_an_overdue_periodic_test_is_a_warning_in_run() -> None:
    """SR-12.2: each periodic test of the daemon's ``maintenance`` is two keys (the last
    pass's age in seconds, or ``never``, and ``overdue``); an overdue one makes RUN a WARN and
    is named in the message; STOPPED stays ERROR; none overdue changes nothing."""
    schedule = {
        "stoptest": {"interval_days": 30, "last_pass_age_s": None, "overdue": True},
        "prooftest": {"interval_days": 30, "last_pass_age_s": 12.5, "overdue": False},
    }
    run = {"state": "RUN", "causes": []}

    def diagnosed(status: Mapping[str, object], maintenance: object) -> dict[str, str]:
        found = supervisor_status(
            status,
            {**DAEMON, "maintenance": maintenance},
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
    schedule["stoptest"] = {"interval_days": 30, "last_pass_age_s": 60.0, "overdue": False}
    fine = diagnosed(run, schedule)
    assert (fine["level"], fine["message"]) == ("0", "RUN")
    assert diagnosed(run, "garbage")["level"] == "0"
